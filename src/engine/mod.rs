//! The three loops wired together: haptic (1 kHz), simulation and graphics, exchanging state
//! only through lock-free triple buffers, plus a deterministic single-thread lockstep mode and
//! the headless run script.

mod command;
mod config;
mod contact;
mod counters;
mod error;
mod force_limit;
mod graphics;
mod haptic;
mod lockstep;
mod patch;
mod script;
mod sim_status;
mod simulation;
mod threaded;
mod tool_sample;
mod wiring;
mod workspace;

pub use command::{Command, ForceTool};
pub use config::{CLAY_SPACING, EngineConfig, build_clay};
pub use contact::{Contact, ContactConfig, ContactForce, MAX_PROBES};
pub use counters::{CounterSnapshot, EngineCounters};
pub use error::EngineError;
pub use force_limit::ForceLimit;
pub use graphics::{GraphicsStage, HeadlessSink, MeshSink};
pub use haptic::{HapticOutcome, HapticStage};
pub use lockstep::{Lockstep, LockstepReport};
pub use patch::{FieldPatch, union_box};
pub use script::{
    ClayShape, ClaySpec, DEFAULT_SCRIPT, MaterialSpec, Script, ScriptError, StrokeSpec, ToolSpec,
};
pub use sim_status::SimStatus;
pub use simulation::{Acks, SaveJob, SimConfig, SimOutcome, SimulationStage, check_loadable};
pub use threaded::{Engine, EngineReport};
pub use tool_sample::ToolSample;
pub use wiring::{Stages, build};
pub use workspace::WorkspaceMap;
