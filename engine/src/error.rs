//! Why the engine could not start or finish, and why a command to a running engine failed.

use std::fmt;
use std::path::PathBuf;
use std::time::Duration;

use glam::Vec3;

use dynaclay_devices::DeviceError;
use dynaclay_devices::record::ScheduleGap;
use dynaclay_loops::{LoopError, WakeError};

use dynaclay_core::field::BSplineLattice;
use dynaclay_core::io::{ReplaceRefused, SessionError};
use dynaclay_core::mesh::GridError;
use dynaclay_core::tools::ToolError;

/// An engine failure, naming the part that failed.
#[derive(Debug, thiserror::Error)]
pub enum EngineError {
    /// Opening or closing the device failed.
    #[error("device: {0}")]
    Device(#[from] DeviceError),
    /// The meshing grid could not be made for the field.
    #[error("mesh grid: {0}")]
    Mesh(#[from] GridError),
    /// A loop could not start, or panicked.
    #[error("loop: {0}")]
    Loop(#[from] LoopError),
    /// The graphics loop's wake-up could not be made (its rate cap is out of range).
    #[error("graphics wake-up: {0}")]
    GraphicsWake(#[from] WakeError),
    /// A loop thread ended without handing its state back (it panicked).
    #[error("the {0} loop ended without handing back its state")]
    Lost(&'static str),
    /// A device could not be switched while running.
    #[error("device switch: {0}")]
    DeviceSwap(SwapRefused),
    /// A replay could not follow its recording's schedule.
    #[error("replay: {0}")]
    Replay(#[from] ReplayMismatch),
    /// One or more loops failed (panicked or lost their state) while running; every loop was
    /// stopped. The session is the simulation's, when its loop was not one that failed.
    #[error(
        "{failed}; every loop was stopped{}{}",
        if *device_closed { ", the device closed with zero force" } else { ", the device was lost with its loop" },
        if session.is_some() { ", the session kept" } else { ", the session lost (the last autosave holds it)" }
    )]
    LoopsFailed {
        /// Which loops failed, and how.
        failed: String,
        /// Whether the device was closed (zero force commanded) by its haptic stage.
        device_closed: bool,
        /// The simulation's session, when its stage came back.
        session: Option<Box<dynaclay_core::io::Session>>,
    },
}

/// Why a running device switch did not happen.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SwapRefused {
    /// The haptic loop did not take the new device in time; the current device stays.
    #[error(
        "the haptic loop did not take the new device within {waited:?} (it has stopped, or another change is pending); the current device stays"
    )]
    NotTaken {
        /// How long the engine waited.
        waited: Duration,
    },
    /// The haptic loop took the new device but never handed the old one back.
    #[error("the haptic loop took the new device but never returned the old one")]
    Lost,
}

/// A lattice's shape as the engine compares it: the running engine's loops hold copies of
/// exactly this shape.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LatticeShape {
    /// Coefficients per axis.
    pub dims: [usize; 3],
    /// Knot spacing, field units.
    pub spacing: f32,
    /// Position of coefficient (0, 0, 0), field units.
    pub origin: Vec3,
    /// The iso-level of the surface.
    pub iso: f32,
}

impl LatticeShape {
    /// The shape of `lattice`.
    #[must_use]
    pub fn of(lattice: &BSplineLattice) -> Self {
        Self {
            dims: lattice.dims,
            spacing: lattice.spacing,
            origin: lattice.origin,
            iso: lattice.iso,
        }
    }
}

impl fmt::Display for LatticeShape {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let [x, y, z] = self.dims;
        write!(
            f,
            "{x}×{y}×{z} coefficients at spacing {}, origin {}, iso {}",
            self.spacing, self.origin, self.iso
        )
    }
}

/// Why a session cannot replace the clay of a running engine; nothing changed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LoadRefused {
    /// The session holds no density patch.
    #[error("{}: the session has no density patch; the running engine sculpts one", file.display())]
    NoPatch {
        /// The session's file.
        file: PathBuf,
    },
    /// The sculpted patch's lattice differs from the running one.
    #[error(
        "{}: the session's lattice ({session}) differs from the running engine's ({running}); start the engine on this session instead",
        file.display()
    )]
    LatticeMismatch {
        /// The session's file.
        file: PathBuf,
        /// The session's first patch.
        session: LatticeShape,
        /// The running engine's lattice.
        running: LatticeShape,
    },
    /// The session's density patches differ from the running engine's in number or in a
    /// patch's map (the loops hold copies laid out for the running clay).
    #[error(
        "{}: the session's density patches ({session} patches) are laid out unlike the running engine's ({running}); start the engine on this session instead",
        file.display()
    )]
    PatchLayout {
        /// The session's file.
        file: PathBuf,
        /// Patches in the session.
        session: usize,
        /// Patches in the running engine.
        running: usize,
    },
    /// The base patch has a map to patch space: the engine sculpts in world coordinates.
    #[error(
        "{}: the session's base patch is mapped (not in world coordinates); the engine needs a base patch in world coordinates",
        file.display()
    )]
    MappedBase {
        /// The session's file.
        file: PathBuf,
    },
    /// A coefficient is NaN or infinite.
    #[error("{}: density coefficient {index} is {value}, not a finite number", file.display())]
    NonFinite {
        /// The session's file.
        file: PathBuf,
        /// Index of the first such coefficient.
        index: usize,
        /// Its value.
        value: f32,
    },
    /// The clay holds more dense bricks than a clay may (an import or a session made
    /// elsewhere): editing could not keep it within [`dynaclay_core::field::MAX_DENSE_BRICKS`].
    #[error("{}: {error}", file.display())]
    DenseBudget {
        /// The session's file.
        file: PathBuf,
        /// How far over it is.
        error: dynaclay_core::field::DenseBudgetError,
    },
}

/// Why a command to the running simulation failed.
#[derive(Debug, thiserror::Error)]
pub enum CommandError {
    /// A geometric tool or a CSG operation failed (`what` names it); poses applied before the
    /// failure stay, as one undo step.
    #[error("{what}: {error}")]
    Tool {
        /// The tool or operation.
        what: String,
        /// What went wrong.
        error: ToolError,
    },
    /// The step would remove more than [`super::MOST_REMOVED_UNASKED`] of the clay and the
    /// user said no ([`super::RemovalGuard::Ask`]): nothing changed.
    #[error(
        "{what} would remove {percent:.0}% of the clay's volume: not applied (the user kept the clay)"
    )]
    WouldRemoveMost {
        /// The tool or operation.
        what: String,
        /// The share it would remove, percent.
        percent: f32,
    },
    /// The session could not be read.
    #[error(transparent)]
    Read(#[from] SessionError),
    /// The session does not fit the running engine.
    #[error(transparent)]
    Load(#[from] LoadRefused),
    /// The mask could not be edited (nothing changed).
    #[error(transparent)]
    Mask(#[from] dynaclay_core::tools::MaskError),
    /// A pin could not be made or removed (nothing changed).
    #[error(transparent)]
    Pin(#[from] dynaclay_core::tools::PinError),
    /// A detail patch could not be added (nothing changed). Transparent: the caller names
    /// the command, and the detail error already says what it refused.
    #[error(transparent)]
    Refine(#[from] dynaclay_core::field::DetailError),
    /// A material paint was refused (nothing changed).
    #[error(transparent)]
    Material(#[from] dynaclay_core::dynamics::MaterialGridError),
    /// A tool of the library could not be made or used (nothing changed).
    #[error(transparent)]
    Library(#[from] super::LibraryError),
    /// The simulation loop is no longer running.
    #[error("the simulation loop has stopped")]
    Stopped,
    /// A save was not written.
    #[error(transparent)]
    Save(#[from] SaveError),
    /// No answer came in time.
    #[error("no answer to the {what} within {waited:?}")]
    NoAnswer {
        /// The command.
        what: &'static str,
        /// How long the caller waited.
        waited: Duration,
    },
}

/// Why a save was not written; whatever was at the path is unchanged.
#[derive(Debug, thiserror::Error)]
pub enum SaveError {
    /// Something other than a session is at the path.
    #[error(transparent)]
    Refused(#[from] ReplaceRefused),
    /// Writing the session failed.
    #[error(transparent)]
    Write(#[from] SessionError),
    /// The engine was built without the I/O thread that writes saves.
    #[error("this engine has no I/O thread")]
    NoIoThread,
}

/// Where a save's outcome goes: the path written, or why not.
pub type SaveReply = crossbeam::channel::Sender<Result<PathBuf, SaveError>>;

/// Where a replay and its recorded schedule part.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ReplayMismatch {
    /// The recording cannot drive an exact replay.
    #[error("{0}")]
    NoSchedule(ScheduleGap),
    /// A tick fetched a snapshot version the recorded steps never publish.
    #[error(
        "haptic tick {tick} fetched field snapshot {recorded} in the recorded run, but the replay's simulation is at {replayed} after every recorded step it could take"
    )]
    Snapshot {
        /// The tick (1, 2, …).
        tick: u64,
        /// The version the recorded tick fetched.
        recorded: u64,
        /// The version the replay reached.
        replayed: u64,
    },
    /// A step took a tool sample from a tick that has not run yet.
    #[error(
        "simulation step {step} took the tool sample of haptic tick {sample_tick}, which the replay has not reached (tick {ticks})"
    )]
    FutureSample {
        /// The step (0, 1, …).
        step: u64,
        /// The tick whose sample it took.
        sample_tick: u64,
        /// Ticks replayed so far.
        ticks: u64,
    },
    /// Fewer commands were sent than the recorded run applied before a step.
    #[error(
        "simulation step {step} applied {recorded} command(s) in the recorded run, but only {sent} had been sent by then in the replay (replay with the script and starting session the run was recorded with)"
    )]
    Commands {
        /// The step (0, 1, …).
        step: u64,
        /// Commands the recorded step applied.
        recorded: u32,
        /// Commands available in the replay.
        sent: u32,
    },
}
