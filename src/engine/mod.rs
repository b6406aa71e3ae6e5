//! The three loops wired together: haptic (1 kHz), simulation and graphics, exchanging state
//! only through lock-free triple buffers, plus a deterministic single-thread lockstep mode.

mod contact;
mod counters;
mod haptic;
mod patch;
mod tool_sample;
mod workspace;

pub use contact::{Contact, ContactConfig, ContactForce, MAX_PROBES, force_integral};
pub use counters::{CounterSnapshot, EngineCounters};
pub use haptic::{HapticOutcome, HapticStage};
pub use patch::{FieldPatch, union_box};
pub use tool_sample::ToolSample;
pub use workspace::WorkspaceMap;
