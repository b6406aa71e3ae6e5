//! Session files (versioned, checksummed, written atomically), autosave and recovery, and the
//! headless script format.

mod atomic;
mod autosave;
mod error;
mod format;
mod output_rule;
mod relief;
mod script;
mod session;

pub use atomic::{ReplaceRefused, check_replaceable, load_session, save_session, write_atomic};
pub use autosave::{
    Autosave, AutosavePolicy, Recovery, RecoveryRefused, find_recovery, recovery_path_for,
    recovery_to_use,
};
pub use dynaclay_files::bounded_read;
pub use error::SessionError;
pub use format::{FORMAT_VERSION, MAGIC, decode, encode, encode_version};
pub use output_rule::{OutputKind, OutputRefused, OutputRule, real_path};
pub use relief::load_relief;
pub use script::{
    AutosaveSpec, BetaSpec, ClayShape, ClaySpec, CsgSpec, DEFAULT_POINTS_PULL_STEPS, DeprecatedKey,
    ForceToolSpec, MAX_COMPACT_PARTICLES, MAX_POINTS_PULL_STEPS, MIN_COMPACT_PARTICLES, PinKind,
    PresetError, RENAMED_KEYS, SCRIPT_VERSION, Script, ScriptError, ScriptStep, SelectionSpec,
    ShapeSpec, StepTool, ToolStep, ToolStepError, load_script, mask_request, paint_request,
    parse_script, pin_request, poses,
};
pub use session::{
    MAX_TOOL_NAME_BYTES, MaterialFields, MaterialGrid, Session, SessionMeta, ToolPreset, unix_now_s,
};
