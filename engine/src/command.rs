//! Non-real-time commands to the engine, applied by the simulation thread between steps, and
//! the tool the device holds.

use std::path::PathBuf;

use crossbeam::channel::Sender;
use glam::Vec3;

use dynaclay_core::dynamics::{Distribution, Material};
use dynaclay_core::io::Session;
use dynaclay_core::tools::{Clay, ForceTool, GeometricTool, ToolAction, ToolPose};

/// The contact push (the default tool): while a stroke is held and the tip is inside the clay,
/// the force vector from the surface above the tip to the tip (Hua & Qin §7.2.1) is spread
/// over the mass points by `distribution`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PushTool {
    /// Spread shape `β`.
    pub distribution: Distribution,
    /// Spread radius around the force vector, field units.
    pub radius_fu: f32,
    /// Density force per unit of force integral.
    pub gain: f32,
}

impl Default for PushTool {
    fn default() -> Self {
        Self {
            distribution: Distribution::Gaussian,
            radius_fu: 0.25,
            gain: 2.0e6,
        }
    }
}

/// The tool the device holds: what a stroke (button 0 held, or a stroke armed by command)
/// does. The one tool choice of the engine, the app and scripts.
#[derive(Clone, Debug, PartialEq)]
pub enum ToolChoice {
    /// The contact push, felt through the haptic contact.
    Push(PushTool),
    /// A force tool of the dynamics (grab, area, curve, chisel, squirt, pull, bend): its
    /// per-tick force vectors drive the dynamics.
    Force {
        /// The tool and its parameters.
        tool: ForceTool,
        /// The user curve of a curve tool, field coordinates (empty for the others).
        curve: Vec<Vec3>,
        /// The pivot of a bend, field coordinates (ignored by the others).
        pivot: Vec3,
    },
    /// A geometric tool applied at the tip while the stroke is held (no contact force).
    Geometric(GeometricTool),
}

impl Default for ToolChoice {
    fn default() -> Self {
        Self::Push(PushTool::default())
    }
}

impl From<PushTool> for ToolChoice {
    fn from(t: PushTool) -> Self {
        Self::Push(t)
    }
}

impl From<GeometricTool> for ToolChoice {
    fn from(t: GeometricTool) -> Self {
        Self::Geometric(t)
    }
}

impl From<ForceTool> for ToolChoice {
    /// The force tool with no curve and the pivot at the origin.
    fn from(tool: ForceTool) -> Self {
        Self::Force {
            tool,
            curve: Vec::new(),
            pivot: Vec3::ZERO,
        }
    }
}

impl ToolChoice {
    /// Short name for undo labels and messages.
    #[must_use]
    pub fn name(&self) -> &'static str {
        match self {
            Self::Push(_) => "push",
            Self::Force { tool, .. } => tool.name(),
            Self::Geometric(g) => g.action.name(),
        }
    }

    /// Whether this is a geometric tool with the contact action (Zhang's `h = f + β·g`): the
    /// strokes the compact RBF clay re-interpolates after.
    #[must_use]
    pub fn is_contact(&self) -> bool {
        matches!(self, Self::Geometric(g) if matches!(g.action, ToolAction::Contact(_)))
    }

    /// The spread radius of the push or of a force tool, field units (`None` for a tool
    /// without one: the point grab and the geometric tools).
    #[must_use]
    pub fn spread_radius_fu(&self) -> Option<f32> {
        match self {
            Self::Push(p) => Some(p.radius_fu),
            Self::Force { tool, .. } => tool.radius_fu(),
            Self::Geometric(_) => None,
        }
    }
}

/// Where a command's outcome goes: `Ok` with a short account, or what went wrong.
pub type Reply = Sender<Result<String, super::CommandError>>;

/// What a tool or CSG step did: a short account, and the share of the clay's volume it was
/// estimated to remove before it was applied (see [`super::RemovalGuard`]).
#[derive(Clone, Debug, PartialEq)]
pub struct EditOutcome {
    /// The account (`"remove: 1200 samples visited, 300 dirtied"`).
    pub note: String,
    /// Net share of the clay's volume removed, 0 to 1 (0 for a step that adds).
    pub removed_fraction: f32,
}

/// Where a tool or CSG step's outcome goes.
pub type EditReply = Sender<Result<EditOutcome, super::CommandError>>;

/// A request to the simulation thread. Each is applied between two steps, in order.
#[derive(Debug)]
pub enum Command {
    /// Test-only (the `fault-injection` feature): makes the simulation loop or the I/O
    /// worker panic where it takes this command, so that tests can prove a failed loop costs
    /// neither the device nor the sculpt.
    #[cfg(feature = "fault-injection")]
    InjectPanic(PanicSite),
    /// Use this tool from the next step on (a held stroke ends first).
    SetTool(ToolChoice),
    /// Use this material for regions created from now on.
    SetMaterial(Material),
    /// Switch automatic detail ([`crate::SimConfig::auto_detail`],
    /// [`crate::SimConfig::auto_detail_force`]) from the next step on; `None` keeps a
    /// setting. Patches already made stay.
    SetAutoDetail {
        /// Under brushes, and folding wiped detail back.
        automatic: Option<bool>,
        /// Under the push and the force strokes too (while `automatic` is on).
        force_tools: Option<bool>,
    },
    /// Paint mass, damping, stiffness or plastic drift rate into a region of the clay (the
    /// session's material grids; a parameter without a grid gets one, filled with the uniform
    /// material's value).
    /// The live region takes the new values at once; regions made later take them too. Not
    /// an undo step: the clay's shape is unchanged.
    PaintMaterial {
        /// What to paint where.
        paint: dynaclay_core::dynamics::MaterialPaint,
        /// Where the outcome goes.
        reply: Option<Reply>,
    },
    /// Remove every painted material grid: the uniform material applies
    /// everywhere again (the live region at once).
    ClearMaterialPaint,
    /// Paint, invert or clear the freeze mask (one undo step). The live region holds the new
    /// mask at once.
    Mask {
        /// The edit.
        edit: dynaclay_core::tools::MaskEdit,
        /// Where the outcome goes.
        reply: Option<Sender<Result<dynaclay_core::tools::MaskReport, super::CommandError>>>,
    },
    /// Arm a stroke (as if button 0 were held) until [`Command::StrokeStop`].
    StrokeStart,
    /// Disarm a stroke armed by [`Command::StrokeStart`].
    StrokeStop,
    /// Mirror strokes across these planes through the clay's centre, from the next step on
    /// (a held stroke ends first).
    SetSymmetry(super::Symmetry),
    /// Apply a geometric tool at each pose in turn over `duration_s` of tool dwell (one undo
    /// step), as a script's `tool` step does.
    ApplyTool {
        /// The tool.
        tool: GeometricTool,
        /// Where it is applied, field coordinates.
        poses: Vec<ToolPose>,
        /// Total dwell time, seconds (split evenly over the poses).
        duration_s: f32,
        /// Which density patch.
        patch: u16,
        /// Where the outcome goes.
        reply: Option<EditReply>,
    },
    /// CSG between the clay and another clay (one undo step): `op` is
    /// [`ToolAction::Union`], [`ToolAction::Intersection`] or [`ToolAction::Difference`].
    Csg {
        /// The operation.
        op: ToolAction,
        /// The other operand (loaded by the caller: the simulation thread does no file I/O).
        other: Box<Clay>,
        /// Which density patch.
        patch: u16,
        /// Where the outcome goes.
        reply: Option<EditReply>,
    },
    /// The user's answer to the published [`super::RemovalQuestion`]. With `true` the held
    /// step goes ahead: a held tool or CSG step is applied now, a held stroke goes on (a
    /// stroke already over lets the next stroke over the limit through). With `false` the
    /// question is dropped, a held tool or CSG step is answered
    /// [`super::CommandError::WouldRemoveMost`], and nothing is applied.
    AnswerRemoval(bool),
    /// Where each stroke that removed more than [`super::MOST_REMOVED_UNASKED`] of the clay is
    /// reported when it ends ([`super::RemovalGuard::Warn`] mode; a script driver's warnings).
    ReportRemovals(Sender<super::StrokeRemoval>),
    /// Make a freeform tool of the clay inside `selection` and store it in the session's
    /// library as `name` (replacing one of that name), with `action` and `falloff_fu` as its
    /// defaults. The clay is unchanged (not an undo step).
    MakeTool {
        /// The preset's name.
        name: String,
        /// Where the clay to capture is.
        selection: dynaclay_core::tools::Selection,
        /// The preset's action.
        action: ToolAction,
        /// The preset's falloff band, field units.
        falloff_fu: f32,
        /// Where the outcome goes.
        reply: Option<Reply>,
    },
    /// Store `preset` in the session's library (replacing one of the same name), as the
    /// window does with a tool it made from the clay it shows.
    AddTool {
        /// The preset.
        preset: Box<dynaclay_core::io::ToolPreset>,
        /// Where the outcome goes.
        reply: Option<Reply>,
    },
    /// Apply a tool of the library, looked up when the command is applied, at each pose in
    /// turn (one undo step), as [`Command::ApplyTool`] does.
    ApplyLibraryTool {
        /// Which preset, and what changes.
        tool: super::LibraryTool,
        /// Where it is applied, field coordinates.
        poses: Vec<ToolPose>,
        /// Total dwell time, seconds.
        duration_s: f32,
        /// Which density patch.
        patch: u16,
        /// Where the outcome goes.
        reply: Option<EditReply>,
    },
    /// Hold a tool of the library, looked up when the command is applied, as a geometric
    /// stroke tool (as [`Command::SetTool`] does; a held stroke ends first).
    SetLibraryTool {
        /// Which preset, and what changes.
        tool: super::LibraryTool,
        /// Where the outcome goes.
        reply: Option<Reply>,
    },
    /// Emboss (or engrave) an image onto the clay (one undo step).
    Emboss {
        /// The image's brightness (loaded by the caller).
        relief: std::sync::Arc<dynaclay_core::tools::Relief>,
        /// Projection, depth and direction.
        params: dynaclay_core::tools::EmbossParams,
        /// Which density patch.
        patch: u16,
        /// Where the outcome goes.
        reply: Option<Reply>,
    },
    /// Add a detail patch over the world box `lo ..= hi` (field coordinates, clipped to the
    /// clay) at knot spacing `base / 2^level`: strokes inside it are simulated there, at the
    /// finer spacing, and the other patches take part through the sum. Not an undo step: the
    /// new patch holds zeros, so the clay is unchanged; edits in it are undone as any others.
    Refine {
        /// The box's low corner.
        lo: glam::Vec3,
        /// The box's high corner.
        hi: glam::Vec3,
        /// Halvings of the base's knot spacing (1 to [`dynaclay_core::field::MAX_DETAIL_LEVEL`]).
        level: u32,
        /// Where the outcome goes.
        reply: Option<Reply>,
    },
    /// Pin a point, curve or normal on the clay (one undo step); points off the surface are
    /// moved onto it first and the outcome on `reply` says so.
    Constrain {
        /// What to pin.
        request: dynaclay_core::tools::PinRequest,
        /// Where the outcome goes.
        reply: Option<Reply>,
    },
    /// Remove pin `index`, or every pin when `None` (one undo step).
    Unconstrain {
        /// Which pin (its place in the clay's list).
        index: Option<usize>,
        /// Where the outcome goes.
        reply: Option<Reply>,
    },
    /// Send the clay's pins (in order: the index `Unconstrain` takes) on `reply`.
    ListPins {
        /// Where the list goes.
        reply: Sender<Vec<dynaclay_core::dynamics::Constraint>>,
    },
    /// Hold the clay as a compact RBF (Zhang et al. §5.4) with the worker behind the link, or
    /// stop with `None`: the clay is interpolated at once, then again after every contact
    /// stroke or contact tool step, each time as one undo step (a held stroke ends first).
    SetCompactRbf(Option<Box<super::CompactRbfLink>>),
    /// Undo the latest stroke or tool step (one stroke is one step); nothing to undo is not
    /// an error.
    Undo,
    /// Redo the latest undone step.
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
        /// Whether the file becomes the session being worked on, so autosave writes its
        /// recovery file beside it from now on (a window's Save, possibly under a new name);
        /// a script's save is a snapshot and leaves autosave where it was.
        as_session: bool,
        /// Optional result channel.
        reply: Option<super::SaveReply>,
    },
    /// Replace the clay and material with `session`, already read and validated from
    /// `source` by the sender (so the simulation thread does no disk I/O). The undo history
    /// is cleared, or with `keep_history` kept with the replacement as one more undo step;
    /// the whole field is republished to the haptic and graphics loops. A session whose
    /// lattice differs from the running one is refused and nothing changes; `reply` gets a
    /// one-line summary (saying what became of the history) or the reason.
    Load {
        /// The session to install.
        session: Box<Session>,
        /// The file it came from (for messages).
        source: PathBuf,
        /// Keep the replaced clay's undo history, the replacement being one undo step (so
        /// Undo brings the replaced clay back); `false` clears it.
        keep_history: bool,
        /// Optional result channel.
        reply: Option<Reply>,
    },
}

/// Where [`Command::InjectPanic`] makes the engine panic (test-only).
#[cfg(feature = "fault-injection")]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PanicSite {
    /// The simulation loop, as it applies the command.
    Simulation,
    /// The I/O worker, as it takes the job the simulation hands it.
    Io,
}
