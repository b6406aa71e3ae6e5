//! The sculpting app (`dynaclay gui`): an egui window on wgpu that shows the engine's meshes,
//! navigates the camera, and sends the engine commands without ever blocking its loops.

mod bridge;
mod camera_input;
mod command;
mod csg_panel;
mod detail_panel;
mod device_maker;
mod device_panel;
mod edit_requests;
mod emboss_panel;
mod falloff_curve_panel;
mod file_dialog;
mod file_menu;
mod force_path_panel;
mod latency;
mod launch;
mod library_panel;
mod link;
mod mask_panel;
mod material_panel;
mod meshes;
mod new_clay;
mod palette;
mod palette_panel;
mod pin_panel;
mod pointer_tool;
mod probe_panel;
mod recent_files;
mod redraw;
mod removal_dialog;
mod replace_dialog;
mod run;
mod sculpt_panels;
mod state;
mod stroke_smoothing;
mod view;
mod view_image;
mod viewport;

pub use bridge::{
    ChunkExportError, DeviceInUse, EngineBridge, GuiMeshSink, RestartSettings, export_chunks,
    start_bridge,
};
pub use camera_input::{
    SpaceMouseCamera, camera_pose_config, drag_pan, drag_rotate, scroll_zoom, spacemouse_move,
};
pub use command::{ClaySource, CsgOperand, EngineCommand, EngineEvent, ForceMode, LoadProgress};
pub use csg_panel::{CSG_OPS, CsgPanel, OperandKind, SolidKind};
pub use device_maker::MakeDeviceError;
pub use device_panel::{DeviceAction, DevicePanel, SPEC_KINDS};
pub use emboss_panel::{BrushFrame, EmbossPanel, ProjectionKind};
pub use falloff_curve_panel::falloff_curve_ui;
pub use file_dialog::{DIALOG_ENV, DialogBackend, FilePurpose, NativePick, PickState};
pub use file_menu::{FileMenu, FileRequest};
pub use force_path_panel::{ForcePathPanel, MAX_CURVE_POINTS, PATH_STEP_SPANS, PathPick, thin};
pub use latency::{HISTORY_LEN, LatencyHistory, LatencySample, histogram_bars};
pub use launch::{GuiArgs, LaunchError, gui_main, parse_gui_args};
pub use library_panel::{LibraryPanel, SelectionKind, freeform_ui};
pub use link::{
    COMMAND_QUEUE_LEN, EngineEndpoint, EngineLink, EventSendError, EventSender, RepaintSignal,
    SendError, engine_link,
};
pub use mask_panel::{MASK_DAB_SPACING, MaskPanel};
pub use material_panel::{MaterialBrush, material_ui};
pub use meshes::{ChunkMesh, MeshSet, brick_id};
pub use new_clay::{MaterialPreset, NewClay, NewClayError, RESOLUTION_RANGE};
pub use palette::{
    ActionKind, ForceSettings, FreeformChoice, PaletteEntry, ShapeKind, ToolPalette, entry_label,
};
pub use pin_panel::{CLICK_SPANS, CURVE_STEP_SPANS, MAX_TRACED_POINTS, PinPanel};
pub use pointer_tool::{MAX_DEPTH_SPANS, PointerTool, TipPose, raising_choice};
pub use probe_panel::{PROBE_EACH, ProbeOutcome, ProbePanel, ProbeSettings, StallFigures, judge};
pub use recent_files::{
    MAX_RECENT, MAX_RECENT_FILE_BYTES, RECENT_FILE_NAME, RecentFiles, RecentFilesError,
    settings_dir,
};
pub use redraw::{FrameStats, InFlight, POLL_PERIOD};
pub use removal_dialog::RemovalDialog;
pub use replace_dialog::{ReplaceDialog, is_session_path};
pub use run::{GuiError, GuiOptions, run_gui};
pub use state::{
    CONTROLS_WIDTH_PT, DisplaySettings, FilePaths, LATENCY_WIDTH_PT, PointsDisplay, SceneInput,
    SculptApp, event_line, window_clear_color,
};
pub use stroke_smoothing::{MAX_STRING_PT, StrokeSmoothing};
pub use view::{DeviceLinkState, DeviceStatus, EngineView, LoopId, WorldBox};
pub use view_image::{ViewBlit, ViewImage};
pub use viewport::SceneView;

#[cfg(test)]
mod file_tests;
#[cfg(test)]
mod gui_tests;
#[cfg(test)]
mod mask_tests;
#[cfg(test)]
mod reach_tests;
#[cfg(test)]
mod stroke_smoothing_tests;
#[cfg(test)]
mod window_tests;
