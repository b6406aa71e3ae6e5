//! The reach of the boxes published since the readers' copies were made: a bound on the
//! dense bricks those copies may hold.
//!
//! The readers never compact their copies (so that the haptic loop frees nothing), so every
//! brick a published box reaches may have become dense in them. One union box per patch
//! bounds that, but the union of two small boxes far apart (a lump added far out on a grown
//! clay, then a stroke near its middle) spans most of the clay, and its bricks passed the
//! clay's dense-brick budget: the next publication sent a fresh copy of the whole clay, some
//! 70 ms of the simulation at a stroke's start on a clay grown to 930³ coefficients. A few
//! boxes per patch keep edits far apart apart.

use dynaclay_core::field::{BRICK_APRON, COEFF_BRICK, CoeffBox};

/// Boxes kept per patch before the next one is merged into the nearest.
const REACH_BOXES: usize = 8;

/// Boxes of one patch whose bricks hold every coefficient published since the readers'
/// copies were made, and every brick whose apron copies one.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub(super) struct Reach {
    boxes: Vec<CoeffBox>,
}

impl Reach {
    /// Adds box `b`: merged into a kept box when their union reaches no more bricks than
    /// the two apart, kept on its own while there is room, and otherwise merged into the
    /// box whose union with it adds the fewest bricks.
    pub(super) fn add(&mut self, b: CoeffBox) {
        let growth = |kept: &CoeffBox| bricks(&kept.union(&b)) - bricks(kept);
        let nearest = (0..self.boxes.len()).min_by_key(|&i| growth(&self.boxes[i]));
        match nearest {
            Some(i) if self.boxes.len() >= REACH_BOXES || growth(&self.boxes[i]) <= bricks(&b) => {
                self.boxes[i] = self.boxes[i].union(&b);
                // The grown box may now swallow others.
                let grown = self.boxes[i];
                let mut at = 0;
                self.boxes.retain(|kept| {
                    let keep = at == i || !grown.contains_box(kept);
                    at += 1;
                    keep
                });
            }
            _ => self.boxes.push(b),
        }
    }

    /// A reach of box `b` alone, or of nothing.
    pub(super) fn of(b: Option<CoeffBox>) -> Self {
        Self {
            boxes: b.into_iter().collect(),
        }
    }

    /// Whether some kept box contains `b`.
    #[cfg(test)]
    pub(super) fn contains_box(&self, b: &CoeffBox) -> bool {
        self.boxes.iter().any(|kept| kept.contains_box(b))
    }

    /// The bricks the kept boxes reach, as owner or through an apron (a brick reached by
    /// two boxes counts twice: a bound, not a count).
    pub(super) fn brick_bound(&self) -> usize {
        self.boxes.iter().map(bricks).fold(0, usize::saturating_add)
    }
}

/// The bricks holding box `b`'s coefficients as their own or in their apron.
fn bricks(b: &CoeffBox) -> usize {
    (0..3).fold(1_usize, |acc, a| {
        let first = b.min[a].saturating_sub(BRICK_APRON) / COEFF_BRICK;
        acc.saturating_mul(b.max[a] / COEFF_BRICK + 1 - first)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cube(min: usize, size: usize) -> CoeffBox {
        CoeffBox {
            min: [min; 3],
            max: [min + size - 1; 3],
        }
    }

    #[test]
    fn boxes_far_apart_are_bounded_apart_and_near_ones_merge() {
        let mut reach = Reach::default();
        reach.add(cube(8, 8));
        let one = reach.brick_bound();
        assert_eq!(
            one,
            2 * 2 * 2,
            "a brick-aligned 8-cube and the bricks whose aprons see it"
        );
        // Far out: the union would span some 110³ bricks; kept apart, the bound adds its own.
        reach.add(cube(880, 8));
        assert_eq!(reach.brick_bound(), 2 * one);
        assert!(reach.contains_box(&cube(8, 8)) && reach.contains_box(&cube(880, 8)));
        // Mostly over the first: merged, its union reaching no more bricks than it alone.
        reach.add(cube(9, 8));
        assert_eq!(reach.boxes.len(), 2);
        assert!(reach.contains_box(&cube(8, 9)));
        assert_eq!(reach.brick_bound(), 3 * 3 * 3 + one);
        // Beside it, where apart the two reach fewer bricks than their union: kept apart.
        reach.add(cube(20, 8));
        assert_eq!(reach.boxes.len(), 3);
        // A box that swallows a kept one replaces it.
        reach.add(cube(870, 30));
        assert_eq!(reach.boxes.len(), 3);
        assert!(reach.contains_box(&cube(870, 30)));
    }

    #[test]
    fn past_its_room_a_box_merges_into_the_nearest_and_the_bound_holds_every_box() {
        let mut reach = Reach::default();
        let added: Vec<CoeffBox> = (0..3 * REACH_BOXES).map(|i| cube(100 * i + 3, 5)).collect();
        for b in &added {
            reach.add(*b);
        }
        assert_eq!(reach.boxes.len(), REACH_BOXES);
        assert!(added.iter().all(|b| reach.contains_box(b)));
        // Never less than the union's bricks would count, never more than the bounding box's.
        let union = added.iter().skip(1).fold(added[0], |u, b| u.union(b));
        assert!(reach.brick_bound() <= bricks(&union));
        assert!(reach.brick_bound() >= added.iter().map(bricks).sum::<usize>());
    }

    #[test]
    fn a_reach_of_nothing_bounds_nothing() {
        assert_eq!(Reach::of(None).brick_bound(), 0);
        assert_eq!(Reach::of(Some(cube(0, 1))).brick_bound(), 1);
    }
}
