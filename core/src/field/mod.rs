//! The implicit solid: a uniform cubic B-spline field and the operators on it.

/// Knot spacing of the starting clay and of imported clays, field units.
pub const CLAY_SPACING: f32 = 0.1;

mod axis;
mod band;
mod band_limited;
mod basis;
mod bricks;
mod budget;
mod coarsen;
mod implicit;
mod kron;
mod lattice;
mod mass_grid;
mod multipatch;
mod pick;
mod primitive;
mod refit;
mod snapshot;
mod sweep;

pub use axis::{AxisBasis, BandedCholesky, NotPositiveDefinite, centred_cubic};
pub use band_limited::{band_limited_lattice, smooth_block_lattice, smooth_step};
pub use basis::{cubic_weights, cubic_weights_and_derivatives};
// The NaN-skipping maximum and minimum the bricks' box summary and the mesher share.
pub use bricks::{
    AllocatingSpares, BRICK_APRON, BRICK_SPAN, BoxSummary, BrickedCoeffs, COEFF_BRICK,
    COEFF_BRICK_VALUES, DENSE_BRICK_BYTES, DENSE_BRICK_VALUES, OwnedBrick, OwnedBricksError,
    SPARE_GROUP_BYTES, SpareBrick, SpareGroup, SpareStorage, Values,
};
pub(crate) use bricks::{larger, smaller};
pub use budget::{
    DENSE_BRICK_BUDGET_BYTES, DenseBudgetError, MAX_CLAY_BOX_COEFFS, MAX_DENSE_BRICKS,
    MAX_DIRECTORY_BYTES, check_dense_room,
};
pub use coarsen::{
    COARSEN_MAX_PATCH_COEFFS, COARSEN_TOLERANCE_SPANS, CoarsenError, CoarsenPlan, RefusedFolds,
    apply_coarsening, plan_coarsening, plan_coarsening_remembering,
};
pub use implicit::ImplicitField;
pub(crate) use kron::PassShape;
pub use kron::{KronError, KronScratch, KroneckerBasis, LANES, apply_axes};
pub use lattice::{BSplineLattice, LatticeError};
pub use mass_grid::{CoeffBox, MassGrid, sub_lattice};
pub use multipatch::{
    DetailError, MAX_CLAY_COEFFS, MAX_DETAIL_COEFFS, MAX_DETAIL_LEVEL, MAX_PATCHES,
    MultiPatchField, OtherPatches, Patch, shared_ends, sum_value_and_gradient,
};
pub use pick::{BISECTION_STEPS, MARCH_STEP_SPANS, Ray, SurfaceHit, pick_surface};
pub use primitive::{Primitive, density_profile, fit_primitive, lattice_from_primitive};
pub use refit::{
    FitError, SampleRow, coeff_box_around, fit_lattice, refit_box, refit_box_edit,
    refit_box_edit_rows,
};
pub use snapshot::{RegionSnapshot, SnapshotError};
pub(crate) use sweep::{
    AxisOp, SharedOut, avx2_dispatch, split_range, sweep_strided, sweep_strided_with, sweep_x_with,
    wide_lanes, with_blocks,
};
