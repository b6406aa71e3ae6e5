//! The three loops wired together: haptic (1 kHz), simulation and graphics, exchanging state
//! only through lock-free triple buffers, plus the I/O worker (saves, autosave), a
//! deterministic single-thread lockstep mode, and the layout and driver that play a script
//! (the one format of [`dynaclay_core::io::Script`]) through the engine.

mod clock;
mod command;
mod compact_rbf;
mod config;
mod counters;
mod device_swap;
mod error;
mod force_limit;
mod graphics;
mod haptic;
mod haptic_gain;
mod io_worker;
mod layout;
mod live_tool;
mod lockstep;
mod motion_to_photon;
mod plan;
mod removal_guard;
mod replay;
mod script_driver;
mod sim_status;
mod simulation;
mod symmetry;
mod threaded;
mod tool_library;
mod tool_sample;
mod update;
mod wiring;
mod workspace;

pub use clock::EngineClock;
#[cfg(feature = "fault-injection")]
pub use command::PanicSite;
pub use command::{Command, EditOutcome, EditReply, PushTool, Reply, ToolChoice};
pub use compact_rbf::{CompactRbfLink, CompactStartError, CompactStatus};
pub use config::{
    CLAY_SIZE_RANGE, CLAY_SPACING, DEFAULT_CLAY_SIZE, DEFAULT_FORCE_N_PER_UNIT, EngineConfig,
    build_clay, build_clay_sized,
};
pub use counters::{CounterSnapshot, EngineCounters};
pub use device_swap::{
    DeviceHandover, DeviceSwapPort, DeviceSwapRequest, SwapFailure, device_swap_channel,
};
pub use error::{
    CommandError, EngineError, LatticeShape, LoadRefused, ReplayMismatch, SaveError, SaveReply,
    SwapRefused,
};
pub use force_limit::{ForceLimit, InvalidForceLimit};
pub use graphics::{
    DEFERRED_COEFF_TOLERANCE, GraphicsStage, HeadlessSink, MeshSink, level_mesh_options,
};
pub use haptic::{HapticOutcome, HapticStage};
pub use haptic_gain::{HapticGain, InvalidHapticGain, MAX_HAPTIC_GAIN};
pub use io_worker::{IoReport, IoWorker};
pub use layout::{HAPTIC_SPARE_BRICKS, HAPTIC_SPARE_BYTES};
pub use live_tool::{GeometricDue, LiveTool, MAX_FORCES, MAX_TARGETS};
pub use lockstep::{Lockstep, LockstepReport};
pub use motion_to_photon::{
    ChangeStamp, FeltChange, MeshStamp, MotionToPhoton, SETTLED_COEFF_TOLERANCE, StagePath,
    StrokeLatency, StrokeStamps, summarize,
};
pub use plan::{
    APPROACH_S, DEFAULT_SCRIPT, HandWaypoint, PlannedAction, PlannedEvent, PlannedStroke, SETTLE_S,
    ScriptPlan, TRAVEL_S, builtin_script,
};
pub use removal_guard::{MOST_REMOVED_UNASKED, RemovalGuard, RemovalQuestion, StrokeRemoval};
pub use replay::ScheduledReplay;
pub use script_driver::ScriptDriver;
pub use sim_status::{BudgetRefusal, SimStatus};
pub use simulation::{
    Acks, IoJob, SaveJob, SimConfig, SimOutcome, SimulationStage, check_loadable,
};
pub use symmetry::{Symmetry, clay_centre, mirror, mirror_force};
pub use threaded::{DeviceSwapReport, Engine, EngineReport, StartOptions, StoppedEngine};
pub use tool_library::{
    LibraryError, LibraryTool, check_name, describe_preset, make_preset, store_preset,
};
pub use tool_sample::ToolSample;
pub use update::{AppliedChange, ChangedBox, FieldUpdate, MAX_UPDATE_COEFFS};
pub use wiring::{Stages, build};
pub use workspace::{REACH_MARGIN, WorkspaceMap, reach_box};
