//! Sculpting tools: geometric tools with their actions, the stamp and contact deformations,
//! force tools for the dynamics, and the undo history.
//!
//! Units: every length on the clay (tool positions, radii, half extents, falloff bands,
//! chisel depths) is in *field units*, the lattice's own coordinates (its knot spacing is
//! [`BSplineLattice::spacing`](crate::field::BSplineLattice::spacing) of them), and carries
//! the suffix `_fu`. Field units are not metres: the suffix `_m` is kept for lengths in the
//! device's workspace, which the engine maps to field units with
//! `dynaclay_engine::WorkspaceMap::field_per_m`.

mod action;
mod apply;
mod capture;
mod clay;
mod deform;
mod emboss;
mod falloff;
mod force;
mod freeze_mask;
mod growth;
mod history;
mod mask;
#[cfg(test)]
mod mask_tests;
mod pin;
mod projection;
mod relief;
mod removal;
mod report;
mod shape;
mod solid;
mod stroke;

pub use action::{ActionError, INTERSECTION_IS_CSG, ToolAction};
pub use apply::{
    ApplyOptions, GeometricTool, MIN_FALLOFF_SPANS, apply_csg, apply_stroke, apply_tool,
    effective_falloff_fu,
};
pub use capture::{CaptureError, MAX_CAPTURE_DIMS, Selection, capture_tool};
pub use clay::{BRICK, Clay, CoeffBox, ColourField, FieldId, sub_lattice};
pub use deform::{
    ContactParams, DEFAULT_DEFORM_RATE_PER_S, StampParams, StampParamsError, exposure, presence,
};
pub use emboss::apply_emboss;
pub use falloff::{CurveError, FalloffCurve, MAX_FALLOFF_POINTS, PRESET_NODES, facing_surface};
pub use force::{
    ForceInput, ForceTool, ForceToolError, PRESS_REACH_SPANS, PenetrationTarget, anchor_normal,
    hold_weight, nearest_solid_point, outward_normal, plan_penetration, plan_penetration_along,
    project_to_surface,
};
pub use freeze_mask::{FreezeMask, HOLD_REACH_NODES, MaskError};
pub use growth::{GROWTH_MARGIN_SPANS, Growth, GrowthError, padding_to_cover};
pub use history::{DEFAULT_BUDGET_BYTES, History, HistoryError, Step, StepRecorder};
pub use mask::{
    HeldRegion, MaskBrush, MaskEdit, MaskMode, MaskReport, clear_mask, ensure_mask,
    hold_before_edit, invert_mask, paint_mask, region_holds,
};
pub use pin::{
    ON_SURFACE_TOLERANCE, PROJECT_REACH_SPANS, PinError, PinRequest, add_pins, check_pins,
    check_room, describe_pin, describe_report, remove_pins, resolve_pin, solver_for,
};
pub use projection::{EmbossParams, EmbossParamsError, Projection};
pub use relief::{ImageError, MAX_IMAGE_BYTES, MAX_IMAGE_PIXELS, Relief};
pub use removal::{
    MOST_REMOVED_UNASKED, VolumeChange, clay_volume_fu3, csg_volume_change, removed_fraction,
    tool_volume_change,
};
pub use report::{ToolError, ToolReport};
pub use shape::{FreeformTool, ShapeError, ToolPose, ToolShape, density_from_distance};
pub use solid::{MAX_SOLID_KNOTS, SolidClayError, solid_clay, solid_spacing_fu};
pub use stroke::{MAX_SEGMENT_APPLICATIONS, MAX_STROKE_POSES, lerp, resample_stroke, steps_along};
