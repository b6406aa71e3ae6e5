//! The freeze mask's data: how firmly each coefficient of each density patch is held, `0`
//! (free) to `1` (frozen), one hold lattice per patch over the patch's own nodes. What edits it
//! and how tools and dynamics respect it is `tools::mask`; this file holds only the value the
//! clay carries, so the clay can hold one without reaching the operations on it.

use glam::Vec3;

use crate::field::{BSplineLattice, LatticeError, MultiPatchField};

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

    /// The mask's value at a world point over the base patch (for a tint): the blend of the
    /// base's coefficient holds, clamped to `[0, 1]`.
    #[must_use]
    pub fn value_at(&self, x: Vec3) -> f32 {
        self.patches
            .first()
            .map_or(0.0, |m| m.value(x).clamp(0.0, 1.0))
    }
}
