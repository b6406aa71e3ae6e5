//! The particle division structure: space cut into `2ᵏ × 2ᵏ × 2ᵏ` cubes (`k ≤ 6`), each holding
//! the particles inside it (Zhang et al. §4.1, after Heckbert).
//!
//! The paper keeps a linked list per cube; here the particles are counting-sorted by cube
//! (one pass to count, one to place), which gives the same lists as contiguous runs and keeps
//! each cube's positions together in memory. `k` is chosen from the repulsion radius: the
//! finest level whose cube is still at least the query radius, so a query visits only the
//! `3 × 3 × 3` cubes around the particle's own, every one of which intersects the query ball's
//! bounding cube. Building allocates only when the particle count or `k` grows past what an
//! earlier build needed.

use glam::Vec3;

/// The finest subdivision level (the paper: "k should be no more than 6").
pub const MAX_LEVEL: u32 = 6;

/// Particles sorted into `2ᵏ` cubes per axis over a box.
#[derive(Clone, Debug, Default)]
pub struct Pds {
    level: u32,
    origin: Vec3,
    cell_size: f32,
    /// Cubes per axis, `2ᵏ`.
    side: usize,
    /// `cell_start[c] .. cell_start[c + 1]` indexes `order` and `sorted` for cube `c`.
    cell_start: Vec<u32>,
    /// Particle index of each sorted slot.
    order: Vec<u32>,
    /// Particle positions in sorted order.
    sorted: Vec<Vec3>,
    cell_of: Vec<u32>,
}

impl Pds {
    /// The level `k` for a box of largest side `extent` and a query radius `radius`: the
    /// largest `k ≤ MAX_LEVEL` with `extent / 2ᵏ ≥ radius` (0 when the radius exceeds the box).
    #[must_use]
    pub fn level_for(extent: f32, radius: f32) -> u32 {
        if !(radius.is_finite() && radius > 0.0 && extent.is_finite() && extent > 0.0) {
            return 0;
        }
        let ratio = extent / radius;
        if ratio < 2.0 {
            return 0;
        }
        (ratio.log2().floor() as u32).min(MAX_LEVEL)
    }

    /// Sort `positions` into the cubes of the box `lo ..= hi` at the level chosen for a query
    /// radius of `radius`. Positions outside the box are clamped into its border cubes (a query
    /// still finds them: it visits their cube and checks the true distance).
    pub fn build(&mut self, positions: &[Vec3], lo: Vec3, hi: Vec3, radius: f32) {
        let extent = (hi - lo).max_element().max(f32::MIN_POSITIVE);
        self.level = Self::level_for(extent, radius);
        self.side = 1usize << self.level;
        self.origin = lo;
        self.cell_size = extent / self.side as f32;
        let cells = self.side * self.side * self.side;
        self.cell_start.clear();
        self.cell_start.resize(cells + 1, 0);
        self.cell_of.clear();
        for &p in positions {
            let c = self.cell_index(self.cell_coords(p));
            self.cell_of.push(c as u32);
            self.cell_start[c + 1] += 1;
        }
        for c in 0..cells {
            self.cell_start[c + 1] += self.cell_start[c];
        }
        self.order.clear();
        self.order.resize(positions.len(), 0);
        self.sorted.clear();
        self.sorted.resize(positions.len(), Vec3::ZERO);
        // Place each particle at the running end of its cube's run; `cell_start[c]` is restored
        // afterwards by walking the runs back.
        for (i, &p) in positions.iter().enumerate() {
            let c = self.cell_of[i] as usize;
            let slot = self.cell_start[c] as usize;
            self.order[slot] = i as u32;
            self.sorted[slot] = p;
            self.cell_start[c] += 1;
        }
        for c in (1..=cells).rev() {
            self.cell_start[c] = self.cell_start[c - 1];
        }
        self.cell_start[0] = 0;
    }

    /// The subdivision level `k` of the last build.
    #[must_use]
    pub fn level(&self) -> u32 {
        self.level
    }

    /// Side of one cube in world units.
    #[must_use]
    pub fn cell_size(&self) -> f32 {
        self.cell_size
    }

    #[inline]
    fn cell_coords(&self, p: Vec3) -> [usize; 3] {
        let u = (p - self.origin) / self.cell_size;
        let max = (self.side - 1) as f32;
        // NOTE: `as usize` of a NaN is 0, so a non-finite position lands in cube 0.
        [
            u.x.clamp(0.0, max) as usize,
            u.y.clamp(0.0, max) as usize,
            u.z.clamp(0.0, max) as usize,
        ]
    }

    #[inline]
    fn cell_index(&self, c: [usize; 3]) -> usize {
        c[0] + self.side * (c[1] + self.side * c[2])
    }

    /// Call `visit(j, position_j, distance²)` for every particle `j` within `radius` of `p`
    /// (the particle at `p` itself included, at distance 0). `radius` must not exceed the
    /// radius given to [`Pds::build`] (the cubes visited are the 27 around `p`'s own).
    #[inline]
    pub fn for_each_within(&self, p: Vec3, radius: f32, mut visit: impl FnMut(usize, Vec3, f32)) {
        let r2 = radius * radius;
        let c = self.cell_coords(p);
        let lo = |a: usize| c[a].saturating_sub(1);
        let hi = |a: usize| (c[a] + 1).min(self.side - 1);
        for z in lo(2)..=hi(2) {
            for y in lo(1)..=hi(1) {
                // Cubes along x are adjacent in the sorted order: one run for the whole row.
                let first = self.cell_index([lo(0), y, z]);
                let last = self.cell_index([hi(0), y, z]);
                let (a, b) = (
                    self.cell_start[first] as usize,
                    self.cell_start[last + 1] as usize,
                );
                for s in a..b {
                    let q = self.sorted[s];
                    let d2 = (q - p).length_squared();
                    if d2 <= r2 {
                        visit(self.order[s] as usize, q, d2);
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lcg_points(n: usize, seed: u64) -> Vec<Vec3> {
        let mut s = seed;
        let mut next = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((s >> 40) as f32) / (1u64 << 24) as f32
        };
        (0..n)
            .map(|_| Vec3::new(next(), next(), next()) * 2.0)
            .collect()
    }

    #[test]
    fn level_is_the_finest_whose_cube_holds_the_radius() {
        assert_eq!(Pds::level_for(1.0, 0.3), 1);
        assert_eq!(Pds::level_for(1.0, 0.25), 2);
        assert_eq!(Pds::level_for(1.0, 0.001), MAX_LEVEL);
        assert_eq!(Pds::level_for(1.0, 2.0), 0);
        assert_eq!(Pds::level_for(1.0, f32::NAN), 0);
    }

    #[test]
    fn queries_match_all_pairs() {
        let pts = lcg_points(2000, 7);
        let mut pds = Pds::default();
        let r = 0.17;
        pds.build(&pts, Vec3::ZERO, Vec3::splat(2.0), r);
        assert!(pds.level() >= 3);
        for (i, &p) in pts.iter().enumerate().step_by(37) {
            let mut got: Vec<usize> = Vec::new();
            pds.for_each_within(p, r, |j, q, d2| {
                assert_eq!(q, pts[j]);
                assert!((d2 - (q - p).length_squared()).abs() < 1e-6);
                got.push(j);
            });
            got.sort_unstable();
            let want: Vec<usize> = (0..pts.len())
                .filter(|&j| (pts[j] - p).length() <= r)
                .collect();
            assert_eq!(got, want, "particle {i}");
        }
    }

    #[test]
    fn points_outside_the_box_are_still_found() {
        let pts = vec![Vec3::new(-0.5, 0.0, 0.0), Vec3::new(-0.45, 0.0, 0.0)];
        let mut pds = Pds::default();
        pds.build(&pts, Vec3::ZERO, Vec3::ONE, 0.1);
        let mut n = 0;
        pds.for_each_within(pts[0], 0.1, |_, _, _| n += 1);
        assert_eq!(n, 2);
    }
}
