//! Record and replay: any device session to a checksummed file, and back as a device.
//!
//! [`RecordingDevice`] wraps a device and logs every read and write without blocking the
//! haptic loop; [`ReplayDevice`] plays a file back call by call, deterministically; the
//! [`format`](mod@format) module is the pure codec between them (documented layout, fuzzed parser).

mod error;
pub mod format;
mod recorder;
mod replay;

pub use error::RecordError;
pub use format::{FORMAT_VERSION, Record, Recording, ScheduleNote, WriteSummary};
pub use recorder::{RecorderConfig, RecordingDevice, ScheduleLog};
pub use replay::{
    MAX_RECORDING_BYTES, RecordedSchedule, RecordedStep, RecordedTick, ReplayDevice,
    ReplayDivergence, SampleProblem, ScheduleGap,
};
