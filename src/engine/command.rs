//! Non-real-time commands to the engine, applied by the simulation thread between steps.

use std::path::PathBuf;

use crossbeam::channel::Sender;

use crate::dynamics::{Distribution, Material};
use crate::io::Session;

/// The force tool: how the push's force vector is spread over mass points (Hua & Qin §7.2.1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ForceTool {
    /// Spread shape `β`.
    pub distribution: Distribution,
    /// Spread radius around the force vector, field units.
    pub radius: f32,
    /// Density force per unit of force integral.
    pub gain: f32,
}

impl Default for ForceTool {
    fn default() -> Self {
        Self {
            distribution: Distribution::Gaussian,
            radius: 0.25,
            gain: 2.0e6,
        }
    }
}

/// A request to the simulation thread. Each is applied between two steps, in order.
#[derive(Debug)]
pub enum Command {
    /// Use this force tool from the next step on.
    SetTool(ForceTool),
    /// Use this material for regions created from now on.
    SetMaterial(Material),
    /// Arm a stroke (as if button 0 were held) until [`Command::StrokeStop`].
    StrokeStart,
    /// Disarm a stroke armed by [`Command::StrokeStart`].
    StrokeStop,
    /// Undo the latest stroke (one stroke is one step).
    Undo,
    /// Redo the latest undone stroke.
    Redo,
    /// Copy the current session (field, material) and send it on `reply`; the receiver writes
    /// files, so the simulation thread never does disk I/O.
    Snapshot {
        /// Where the copy goes.
        reply: Sender<Session>,
    },
    /// Save the session to `path` (the copy is written by the engine's I/O thread); the result
    /// comes back on `reply` if given.
    Save {
        /// Destination file.
        path: PathBuf,
        /// Optional result channel.
        reply: Option<Sender<Result<PathBuf, String>>>,
    },
    /// Replace the clay and material with `session`, already read and validated from
    /// `source` by the sender (so the simulation thread does no disk I/O). The undo history
    /// is cleared; the whole field is republished to the haptic and graphics loops. A session
    /// whose lattice differs from the running one is refused and nothing changes; `reply`
    /// gets a one-line summary or the reason.
    Load {
        /// The session to install.
        session: Box<Session>,
        /// The file it came from (for messages).
        source: PathBuf,
        /// Optional result channel.
        reply: Option<Sender<Result<String, String>>>,
    },
}
