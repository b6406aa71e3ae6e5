//! The regular grid of mass points (sample points) over a box of coefficients, and the
//! per-axis factors of `d = A p` on it.
//!
//! Mapping (design trap 1): the grid spans the coefficient *nodes* of the box — mass point 0
//! sits on the node of the first coefficient and the last mass point on the node of the last
//! one — so every coefficient's support is sampled at its centre, where its weight is 2/3.
//! With `m = n` the per-axis factor is the tridiagonal `(1/6, 2/3, 1/6)` matrix, whose Gram
//! matrix has eigenvalues in `[1/9, 1]`; finer grids are better conditioned still.

use glam::Vec3;

use super::axis::AxisBasis;
use super::bricks::BrickedCoeffs;
use super::kron::{KronError, KroneckerBasis, apply_axes};
use super::lattice::BSplineLattice;

/// A box of coefficients, inclusive on both ends, in lattice indices.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CoeffBox {
    /// First coefficient index per axis.
    pub min: [usize; 3],
    /// Last coefficient index per axis (inclusive).
    pub max: [usize; 3],
}

impl CoeffBox {
    /// Coefficients per axis.
    #[must_use]
    pub fn dims(&self) -> [usize; 3] {
        [
            self.max[0] + 1 - self.min[0],
            self.max[1] + 1 - self.min[1],
            self.max[2] + 1 - self.min[2],
        ]
    }

    /// Number of coefficients in the box.
    #[must_use]
    pub fn count(&self) -> usize {
        self.dims().iter().product()
    }

    /// Whether the box is non-empty (`min <= max`) and inside a lattice of `dims`.
    #[must_use]
    pub fn fits(&self, dims: [usize; 3]) -> bool {
        (0..3).all(|a| self.min[a] <= self.max[a] && self.max[a] < dims[a])
    }

    /// Whether coefficient `(i, j, k)` lies in the box.
    #[must_use]
    pub fn contains(&self, i: usize, j: usize, k: usize) -> bool {
        let c = [i, j, k];
        (0..3).all(|a| self.min[a] <= c[a] && c[a] <= self.max[a])
    }

    /// The box of the one coefficient `p`.
    #[must_use]
    pub fn point(p: [usize; 3]) -> Self {
        Self { min: p, max: p }
    }

    /// The smallest box holding this box and coefficient `p`.
    #[must_use]
    pub fn grown_to(&self, p: [usize; 3]) -> Self {
        self.union(&Self::point(p))
    }

    /// This box moved by `offset` coefficients along each axis (onto a lattice grown by
    /// `offset` before its first coefficient).
    #[must_use]
    pub fn shifted(&self, offset: [usize; 3]) -> Self {
        Self {
            min: std::array::from_fn(|a| self.min[a] + offset[a]),
            max: std::array::from_fn(|a| self.max[a] + offset[a]),
        }
    }

    /// The smallest box holding both.
    #[must_use]
    pub fn union(&self, other: &Self) -> Self {
        Self {
            min: std::array::from_fn(|a| self.min[a].min(other.min[a])),
            max: std::array::from_fn(|a| self.max[a].max(other.max[a])),
        }
    }

    /// This box clipped to a lattice of the given dimensions (`None` if nothing is left, or
    /// the box is empty).
    #[must_use]
    pub fn clipped(&self, dims: [usize; 3]) -> Option<Self> {
        let b = Self {
            min: self.min,
            max: std::array::from_fn(|a| self.max[a].min(dims[a].saturating_sub(1))),
        };
        b.fits(dims).then_some(b)
    }

    /// The world box (min, max corners) where a change of these coefficients can show.
    #[must_use]
    pub fn world_support(&self, lattice: &BSplineLattice) -> (Vec3, Vec3) {
        let lo = Vec3::new(self.min[0] as f32, self.min[1] as f32, self.min[2] as f32);
        let hi = Vec3::new(self.max[0] as f32, self.max[1] as f32, self.max[2] as f32);
        (
            lattice.origin + (lo - 2.0) * lattice.spacing,
            lattice.origin + (hi + 2.0) * lattice.spacing,
        )
    }

    /// Whether every coefficient of `inner` lies in this box.
    #[must_use]
    pub fn contains_box(&self, inner: &CoeffBox) -> bool {
        (0..3).all(|a| self.min[a] <= inner.min[a] && inner.max[a] <= self.max[a])
    }

    /// The whole lattice.
    #[must_use]
    pub fn whole(dims: [usize; 3]) -> Self {
        Self {
            min: [0; 3],
            max: [dims[0] - 1, dims[1] - 1, dims[2] - 1],
        }
    }
}

/// A regular grid of mass points spanning the nodes of a coefficient box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MassGrid {
    /// The coefficient box whose nodes the grid spans.
    pub coeffs: CoeffBox,
    /// Mass points per axis (at least 1; at least the box's coefficient count for a fit).
    pub dims: [usize; 3],
}

impl MassGrid {
    /// `samples_per_span` mass points per knot span: `(n − 1) · r + 1` per axis.
    #[must_use]
    pub fn with_samples_per_span(coeffs: CoeffBox, samples_per_span: usize) -> Self {
        let r = samples_per_span.max(1);
        let n = coeffs.dims();
        Self {
            coeffs,
            dims: [(n[0] - 1) * r + 1, (n[1] - 1) * r + 1, (n[2] - 1) * r + 1],
        }
    }

    /// Number of mass points.
    #[must_use]
    pub fn count(&self) -> usize {
        self.dims.iter().product()
    }

    /// Lattice-coordinate step between neighbouring mass points along `axis`.
    #[must_use]
    pub fn step(&self, axis: usize) -> f64 {
        let n = self.coeffs.dims()[axis];
        if self.dims[axis] <= 1 {
            0.0
        } else {
            (n - 1) as f64 / (self.dims[axis] - 1) as f64
        }
    }

    /// Lattice coordinate of mass point `j` along `axis`.
    #[must_use]
    pub fn coord(&self, axis: usize, j: usize) -> f64 {
        self.coeffs.min[axis] as f64 + j as f64 * self.step(axis)
    }

    /// World position of mass point `(i, j, k)` on `lattice`.
    #[must_use]
    pub fn position(&self, lattice: &BSplineLattice, i: usize, j: usize, k: usize) -> Vec3 {
        lattice.origin
            + lattice.spacing
                * Vec3::new(
                    self.coord(0, i) as f32,
                    self.coord(1, j) as f32,
                    self.coord(2, k) as f32,
                )
    }

    /// The factor along `axis` against the coefficients `c0 ..= c1` (lattice indices).
    #[must_use]
    pub fn axis_basis(&self, axis: usize, c0: usize, c1: usize) -> AxisBasis {
        AxisBasis::uniform(
            c0 as f64,
            c1 + 1 - c0,
            self.coeffs.min[axis] as f64,
            self.step(axis),
            self.dims[axis],
        )
    }

    /// `A` restricted to the grid's own coefficient box.
    ///
    /// # Errors
    /// When an axis has fewer mass points than coefficients (the Gram matrix is singular).
    pub fn basis(&self) -> Result<KroneckerBasis, KronError> {
        let b = &self.coeffs;
        KroneckerBasis::new([
            self.axis_basis(0, b.min[0], b.max[0]),
            self.axis_basis(1, b.min[1], b.max[1]),
            self.axis_basis(2, b.min[2], b.max[2]),
        ])
    }

    /// `A` against the coefficients in the box grown by one on every side (clamped to a
    /// lattice of `dims`): everything that influences a mass point of this grid. Returns the
    /// grown box too. Built without a Gram factor; only `apply` may be used.
    #[must_use]
    pub fn influence_axes(&self, dims: [usize; 3]) -> ([AxisBasis; 3], CoeffBox) {
        let b = &self.coeffs;
        let grown = CoeffBox {
            min: [
                b.min[0].saturating_sub(1),
                b.min[1].saturating_sub(1),
                b.min[2].saturating_sub(1),
            ],
            max: [
                (b.max[0] + 1).min(dims[0] - 1),
                (b.max[1] + 1).min(dims[1] - 1),
                (b.max[2] + 1).min(dims[2] - 1),
            ],
        };
        (
            [
                self.axis_basis(0, grown.min[0], grown.max[0]),
                self.axis_basis(1, grown.min[1], grown.max[1]),
                self.axis_basis(2, grown.min[2], grown.max[2]),
            ],
            grown,
        )
    }

    /// The fixed part of the densities at this grid's mass points: what the lattice's
    /// coefficients *outside* the grid's box contribute (`A_outside p_outside`), written into
    /// `out` (one value per mass point, x fastest). A region's dynamics add it to `A' p_R`; a
    /// local refit subtracts it from the target before fitting the box.
    ///
    /// # Panics
    /// When `out` is not [`MassGrid::count`] long or the box does not fit the lattice.
    pub fn fixed_outside(&self, lattice: &BSplineLattice, out: &mut [f32]) {
        self.fixed_outside_with(lattice, out, None);
    }

    /// [`MassGrid::fixed_outside`] with the caller's scratch arrays for its passes (used when
    /// both are long enough, else it allocates its own).
    ///
    /// # Panics
    /// As [`MassGrid::fixed_outside`].
    pub(crate) fn fixed_outside_with(
        &self,
        lattice: &BSplineLattice,
        out: &mut [f32],
        scratch: Option<(&mut [f32], &mut [f32])>,
    ) {
        assert_eq!(out.len(), self.count(), "one value per mass point");
        let b = self.coeffs;
        let (axes, grown) = self.influence_axes(lattice.dims);
        let gd = grown.dims();
        let mut outside = vec![0.0_f32; grown.count()];
        for k in 0..gd[2] {
            for j in 0..gd[1] {
                for i in 0..gd[0] {
                    let (gi, gj, gk) = (grown.min[0] + i, grown.min[1] + j, grown.min[2] + k);
                    if !b.contains(gi, gj, gk) {
                        outside[i + gd[0] * (j + gd[1] * k)] = lattice.coeffs.get(gi, gj, gk);
                    }
                }
            }
        }
        let len = self.fixed_scratch_len(gd);
        match scratch {
            Some((sa, sb)) if sa.len() >= len && sb.len() >= len => {
                apply_axes(&axes, &outside, out, sa, sb);
            }
            _ => {
                let (mut sa, mut sb) = (vec![0.0; len], vec![0.0; len]);
                apply_axes(&axes, &outside, out, &mut sa, &mut sb);
            }
        }
    }

    /// Scratch length each of [`MassGrid::fixed_outside`]'s two passes needs, for the grown
    /// box's dimensions `gd`.
    fn fixed_scratch_len(&self, gd: [usize; 3]) -> usize {
        let m = self.dims;
        m[0] * m[1].max(gd[1]) * m[2].max(gd[2])
    }
}

/// A copy of the coefficients of `lattice` in `region` grown by `margin` on every side
/// (clipped to the lattice, and to at least 4 per axis), as a lattice of its own placed at the
/// same world position. Inside the world box of `region` grown by `margin − 2` knot spans it
/// evaluates as `lattice` does (up to the rounding of its shifted origin); tools read the pre-edit clay from it while the
/// original is being refitted.
#[must_use]
pub fn sub_lattice(lattice: &BSplineLattice, region: &CoeffBox, margin: usize) -> BSplineLattice {
    let mut min = [0; 3];
    let mut dims = [0; 3];
    for a in 0..3 {
        let n = lattice.dims[a];
        let mut lo = region.min[a].saturating_sub(margin);
        let mut hi = (region.max[a] + margin).min(n - 1);
        while hi + 1 - lo < 4.min(n) {
            if lo > 0 {
                lo -= 1;
            } else {
                hi = (hi + 1).min(n - 1);
            }
        }
        min[a] = lo;
        dims[a] = hi + 1 - lo;
    }
    let mut coeffs = Vec::with_capacity(dims.iter().product());
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            let row = lattice.index(min[0], min[1] + j, min[2] + k);
            lattice.coeffs.extend_row_into(row, dims[0], &mut coeffs);
        }
    }
    BSplineLattice {
        dims,
        spacing: lattice.spacing,
        origin: lattice.node_position(min[0], min[1], min[2]),
        iso: lattice.iso,
        coeffs: BrickedCoeffs::from_vec(dims, coeffs),
    }
}
