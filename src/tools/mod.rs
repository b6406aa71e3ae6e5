//! Sculpting tools: geometric tools with their actions, the stamp and contact deformations,
//! force tools for the dynamics, and the undo history.

mod action;
mod apply;
mod clay;
mod deform;
mod history;
mod shape;

pub use action::{ActionError, ToolAction};
pub use apply::{ApplyOptions, GeometricTool, ToolError, ToolReport, apply_stroke, apply_tool};
pub use clay::{Clay, CoeffBox, ColourField, FieldId, sub_lattice};
pub use deform::{ContactParams, StampParams, StampParamsError};
pub use history::{BRICK, DEFAULT_BUDGET_BYTES, History, HistoryError, Step, StepRecorder};
pub use shape::{FreeformTool, ShapeError, ToolPose, ToolShape, density_from_distance};
