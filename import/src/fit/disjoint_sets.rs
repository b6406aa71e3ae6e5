//! Disjoint sets over `0..count` (union–find): which of a stage's items are linked, whatever
//! order the links come in.

/// Each item's parent toward its set's root; a root is its own parent. Joining keeps the
/// lower root, and a look-up halves the path it walks, so the sets' roots are the same for
/// any order of the same links.
pub(crate) struct DisjointSets {
    parent: Vec<u32>,
}

impl DisjointSets {
    /// `count` items, each alone in its set.
    pub(crate) fn new(count: usize) -> Self {
        Self {
            parent: (0..count as u32).collect(),
        }
    }

    /// The root of `at`'s set (the set's lowest item).
    pub(crate) fn root(&mut self, mut at: u32) -> u32 {
        while self.parent[at as usize] != at {
            let up = self.parent[self.parent[at as usize] as usize];
            self.parent[at as usize] = up;
            at = up;
        }
        at
    }

    /// Joins the sets of `a` and `b`; the lower root stays the root.
    pub(crate) fn join(&mut self, a: u32, b: u32) {
        let (ra, rb) = (self.root(a), self.root(b));
        if ra < rb {
            self.parent[rb as usize] = ra;
        } else if rb < ra {
            self.parent[ra as usize] = rb;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn linked_items_share_the_lowest_root_in_any_order() {
        for links in [[(4, 2), (2, 7), (5, 6)], [(5, 6), (7, 2), (2, 4)]] {
            let mut sets = DisjointSets::new(8);
            for (a, b) in links {
                sets.join(a, b);
            }
            let roots: Vec<u32> = (0..8).map(|i| sets.root(i)).collect();
            assert_eq!(roots, [0, 1, 2, 3, 2, 5, 5, 2]);
        }
    }
}
