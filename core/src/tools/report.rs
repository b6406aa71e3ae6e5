//! What applying a tool reports: the box it refitted with Ferley's counts, or why it could
//! not be applied.

use glam::Vec3;

use super::action::ActionError;
use super::clay::CoeffBox;
use super::freeze_mask::MaskError;
use super::growth::GrowthError;
use super::projection::EmbossParamsError;
use super::shape::ShapeError;
use crate::field::{DenseBudgetError, FitError, LatticeError};

/// What an application touched.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct ToolReport {
    /// The density patch edited (paint edits the colour over patch 0).
    pub patch: u16,
    /// The refitted coefficient box of the edited lattice (density, or colour for paint);
    /// `None` when the tool missed the lattice.
    pub coeff_box: Option<CoeffBox>,
    /// World box (min, max) outside which the field did not change.
    pub dirty_world: Option<(Vec3, Vec3)>,
    /// Sample points in the tool's world-axis-aligned box.
    pub visited: usize,
    /// Of those, points inside the tool's local box (its potential was evaluated).
    pub computed: usize,
    /// Of those, points whose target value differs from the clay's.
    pub dirtied: usize,
}

impl ToolReport {
    pub(super) fn merge(&mut self, other: &Self) {
        self.coeff_box = match (self.coeff_box, other.coeff_box) {
            (Some(a), Some(b)) => Some(a.union(&b)),
            (a, b) => a.or(b),
        };
        self.dirty_world = match (self.dirty_world, other.dirty_world) {
            (Some(a), Some(b)) => Some((a.0.min(b.0), a.1.max(b.1))),
            (a, b) => a.or(b),
        };
        self.visited += other.visited;
        self.computed += other.computed;
        self.dirtied += other.dirtied;
    }
}

/// Why a tool could not be applied.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ToolError {
    #[error("{0}")]
    Shape(ShapeError),
    #[error("{0}")]
    Action(ActionError),
    /// The falloff band must be positive for analytic shapes.
    #[error("falloff_fu = {falloff_fu} must be positive and finite")]
    BadFalloff { falloff_fu: f32 },
    /// The clay has no patch with this index.
    #[error("the clay has no patch {patch}")]
    NoPatch { patch: u16 },
    /// A painting action needs a colour field, and its geometry was invalid.
    #[error("colour field: {0}")]
    Colour(LatticeError),
    /// The refit failed (e.g. a non-finite target).
    #[error("refit failed: {0}")]
    Fit(FitError),
    /// The freeze mask could not be fitted to the patch layout.
    #[error("{0}")]
    Mask(#[from] MaskError),
    /// An emboss's parameters are invalid.
    #[error("{0}")]
    Emboss(#[from] EmbossParamsError),
    /// The edit could make more bricks dense than the clay's budget leaves; nothing changed.
    #[error("{0}")]
    DenseBudget(#[from] DenseBudgetError),
    /// The edit reached past the clay's box and the clay could not grow to take it (its box
    /// budget, [`crate::field::MAX_CLAY_BOX_COEFFS`]): it was applied clipped to the box.
    #[error("{0}")]
    Growth(GrowthError),
}

impl From<FitError> for ToolError {
    fn from(e: FitError) -> Self {
        Self::Fit(e)
    }
}
