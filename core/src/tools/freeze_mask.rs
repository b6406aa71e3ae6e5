//! The freeze mask's data: how firmly each coefficient of each density patch is painted held,
//! `0` (free) to `1` (frozen), one hold lattice per patch over the patch's own nodes, and the
//! hold that tools and dynamics give each coefficient because of it
//! ([`FreezeMask::support_holds`]). What edits it and how tools and dynamics apply the hold is
//! `tools::mask`; this file holds only the value the clay carries and what follows from it, so
//! the clay can hold one without reaching the operations on it.
//!
//! The painted holds are what the user painted and sees as a tint: the mask's value at a point
//! is the B-spline blend of the painted holds around it. A point of the clay moves with every
//! coefficient whose support covers it (the 4×4×4 around its knot span), so holding only the
//! coefficients painted held would let a tinted point move with the partly painted ones at the
//! brush's soft edge. The hold applied is therefore the painted mask dilated by the basis
//! support ([`HOLD_REACH_NODES`]): each coefficient is held at least as firmly as the most
//! tinted point it moves, so fully tinted clay keeps its bits and clay tinted `m` keeps at
//! least `m` of its shape under an edit that moves its coefficients one way (a carve, a fill).

use glam::Vec3;

use crate::field::{BSplineLattice, CoeffBox, DenseBudgetError, LatticeError, MultiPatchField};

/// How far, in nodes along each axis, a painted hold reaches the coefficients it holds.
///
/// The tint at a point is a blend of the 4×4×4 painted holds around its knot span (nodes one
/// below to two above), so it is at most the largest of them (a B-spline lies within the hull
/// of its coefficients). Coefficient `i` moves the points of the knot spans `i − 2 .. i + 2`,
/// whose blends draw on the painted holds of nodes `i − 3 ..= i + 3`. Holding `i` at the
/// largest painted hold within three nodes therefore holds it at least as firmly as any point
/// it moves is tinted.
pub const HOLD_REACH_NODES: usize = 3;

/// Why a mask edit was refused.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum MaskError {
    /// The brush radius is not positive and finite.
    #[error("mask brush radius_fu = {radius_fu} must be positive and finite")]
    Radius {
        /// The radius given.
        radius_fu: f32,
    },
    /// The brush strength is outside `[0, 1]`.
    #[error("mask brush strength = {strength} must be within [0, 1]")]
    Strength {
        /// The strength given.
        strength: f32,
    },
    /// The brush centre is not finite.
    #[error("mask brush centre {centre_fu:?} is not finite")]
    Centre {
        /// The centre given.
        centre_fu: [f32; 3],
    },
    /// A mask lattice could not be made over a patch.
    #[error("mask over patch {patch}: {source}")]
    Lattice {
        /// The patch.
        patch: usize,
        /// Why its lattice was refused.
        source: LatticeError,
    },
    /// The dab could make more of the mask's bricks dense than the clay's budget leaves.
    #[error("{0}")]
    DenseBudget(#[from] DenseBudgetError),
}

/// The clay's freeze mask: one hold lattice per density patch, index for index.
#[derive(Clone, Debug, PartialEq)]
pub struct FreezeMask {
    /// Hold of each coefficient, patch by patch (`0..=1`; same dims, spacing and origin as the
    /// patch).
    pub patches: Vec<BSplineLattice>,
}

impl FreezeMask {
    /// A mask holding nothing over every patch of `density`.
    ///
    /// # Errors
    /// When a patch's geometry is refused for a lattice (never for a valid clay).
    pub fn matching(density: &MultiPatchField) -> Result<Self, MaskError> {
        let patches = density
            .patches
            .iter()
            .enumerate()
            .map(|(patch, p)| {
                let l = &p.lattice;
                BSplineLattice::zeros(l.dims, l.spacing, l.origin)
                    .map_err(|source| MaskError::Lattice { patch, source })
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Self { patches })
    }

    /// The holds of patch `patch` when they fit it (same dims as `lattice`, the patch's own):
    /// a patch the mask does not fit is free.
    #[must_use]
    pub fn for_patch(&self, patch: usize, lattice: &BSplineLattice) -> Option<&BSplineLattice> {
        self.patches
            .get(patch)
            .filter(|m| m.dims == lattice.dims && m.coeffs.len() == lattice.coeffs.len())
    }

    /// Whether any coefficient is held at all.
    #[must_use]
    pub fn any(&self) -> bool {
        self.patches
            .iter()
            .any(|m| m.coeffs.iter().any(|&h| h > 0.0))
    }

    /// The holds that tools and dynamics apply over `region` of patch `patch` (whose lattice is
    /// `lattice`), x fastest, written into `out` (cleared first): each coefficient's hold is the
    /// largest painted hold within [`HOLD_REACH_NODES`] nodes of it along every axis (a box
    /// dilation of the painted mask by the basis support). So the field at a point tinted `t`
    /// changes by at most `1 − t` of the blended size of its coefficients' free changes (for
    /// an edit that moves them all one way, `1 − t` of its free change), and at a fully tinted
    /// point not at all. `out` is left empty when the mask does not fit the patch, the region
    /// does not fit the lattice, or nothing there is held.
    ///
    /// Computed from the painted holds each time (they change through paints, undo, growth and
    /// loads alike), as a window maximum seven nodes wide along x, then y, then z, over the
    /// region grown by the reach: about `21 ×` the grown region's size in work and two scratch
    /// buffers of about its size. For the simulation thread's edits, never the haptic tick.
    pub fn support_holds(
        &self,
        patch: usize,
        lattice: &BSplineLattice,
        region: CoeffBox,
        out: &mut Vec<f32>,
    ) {
        out.clear();
        let Some(painted) = self.for_patch(patch, lattice) else {
            return;
        };
        if !region.fits(painted.dims) {
            return;
        }
        let dims = painted.dims;
        let reach = HOLD_REACH_NODES;
        // The region grown by the reach, clipped to the lattice: the painted holds it draws on.
        let lo: [usize; 3] = std::array::from_fn(|a| region.min[a].saturating_sub(reach));
        let hi: [usize; 3] = std::array::from_fn(|a| (region.max[a] + reach).min(dims[a] - 1));
        let n = region.dims();
        let grown_y = hi[1] - lo[1] + 1;
        // Along x: the region's columns, over the grown box's rows and planes.
        let mut along_x = Vec::with_capacity(n[0] * grown_y * (hi[2] - lo[2] + 1));
        let mut row = vec![0.0; dims[0]];
        for k in lo[2]..=hi[2] {
            for j in lo[1]..=hi[1] {
                painted.coeffs.read_row_at([0, j, k], &mut row);
                for i in region.min[0]..=region.max[0] {
                    along_x.push(window_max(&row, i, reach));
                }
            }
        }
        // Along y: the region's rows, over the grown box's planes.
        let mut along_y = Vec::with_capacity(n[0] * n[1] * (hi[2] - lo[2] + 1));
        for k in 0..=hi[2] - lo[2] {
            let plane = &along_x[n[0] * grown_y * k..][..n[0] * grown_y];
            for j in region.min[1]..=region.max[1] {
                let (from, to) = (j.saturating_sub(reach).max(lo[1]), (j + reach).min(hi[1]));
                for i in 0..n[0] {
                    along_y.push(
                        (from..=to).fold(0.0, |m: f32, y| m.max(plane[i + n[0] * (y - lo[1])])),
                    );
                }
            }
        }
        // Along z: the region itself.
        out.reserve(region.count());
        let plane_len = n[0] * n[1];
        for k in region.min[2]..=region.max[2] {
            let (from, to) = (k.saturating_sub(reach).max(lo[2]), (k + reach).min(hi[2]));
            for at in 0..plane_len {
                out.push((from..=to).fold(0.0, |m: f32, z| {
                    m.max(along_y[at + plane_len * (z - lo[2])])
                }));
            }
        }
        if out.iter().all(|&h| h <= 0.0) {
            out.clear();
        }
    }

    /// The mask's value at a world point over the base patch (for a tint): the blend of the
    /// base's coefficient holds, clamped to `[0, 1]`.
    #[must_use]
    pub fn value_at(&self, x: Vec3) -> f32 {
        self.patches
            .first()
            .map_or(0.0, |m| m.value(x).clamp(0.0, 1.0))
    }
}

/// The largest of `values[at − reach ..= at + reach]` (clipped to the slice), or 0 for none.
fn window_max(values: &[f32], at: usize, reach: usize) -> f32 {
    let end = (at + reach + 1).min(values.len());
    values[at.saturating_sub(reach).min(end)..end]
        .iter()
        .fold(0.0, |m, &h| m.max(h))
}
