//! Session files (versioned, checksummed, written atomically), autosave and recovery, and the
//! headless script format.

mod atomic;
mod autosave;
mod error;
mod format;
mod session;

pub use atomic::{load_session, save_session, write_atomic};
pub use autosave::{Autosave, AutosavePolicy, Recovery, find_recovery, recovery_path_for};
pub use error::SessionError;
pub use format::{FORMAT_VERSION, MAGIC, decode, encode};
pub use session::{MaterialFields, MaterialGrid, Session, SessionMeta, ToolPreset};
