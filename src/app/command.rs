//! What the app asks of the engine, and what the engine answers: plain values sent over a
//! crossbeam channel and applied by the simulation thread between steps.
//!
//! Nothing here is on a real-time path; commands may own heap data (paths, tool lattices).

use std::path::PathBuf;

use dynaclay_devices::spec::DeviceSpec;

use crate::dynamics::Material;
use crate::engine::ToolChoice;

/// Which force tool the palette offers (Hua & Qin §7.2, design notes "Force tools"); the
/// palette makes the engine's [`ToolChoice`] for it ([`super::ToolPalette::choice`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum ForceMode {
    /// One force vector from the surface point to the cursor, spread by the distribution.
    #[default]
    PointGrab,
    /// Like the point grab with a wide β-distributed footprint.
    Area,
    /// A fixed shallow penetration along the tool normal (cuts a groove).
    Chisel,
    /// The chisel's opposite: pushes material out along the tool normal.
    Squirt,
    /// Pulls the surface toward the cursor (bending and drawing out).
    Pull,
    /// Every point of a user curve moves with the cursor's displacement from where the
    /// stroke began (the curve: the last stroke's path or points clicked on the clay).
    Curve,
    /// Bends about a pivot (clicked on the clay): the clay between the pivot and where the
    /// stroke took hold turns with the cursor.
    Bend,
}

impl ForceMode {
    /// Every mode, in palette order.
    pub const ALL: [ForceMode; 7] = [
        Self::PointGrab,
        Self::Area,
        Self::Chisel,
        Self::Squirt,
        Self::Pull,
        Self::Curve,
        Self::Bend,
    ];

    /// Label for menus.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::PointGrab => "point grab",
            Self::Area => "area",
            Self::Chisel => "chisel",
            Self::Squirt => "squirt",
            Self::Pull => "pull",
            Self::Curve => "curve",
            Self::Bend => "bend",
        }
    }
}

/// A request from the app to the engine.
#[derive(Clone, Debug, PartialEq)]
pub enum EngineCommand {
    /// Use this tool for the next strokes.
    SelectTool(ToolChoice),
    /// Replace the material of the simulated region.
    SetMaterial(Material),
    /// Switch automatic detail under brushes and under force tools.
    SetAutoDetail {
        automatic: bool,
        force_tools: bool,
    },
    /// Paint mass, damping, stiffness or plastic drift rate into a region of the clay.
    PaintMaterial(crate::dynamics::MaterialPaint),
    /// Remove the painted material: the uniform material applies everywhere.
    ClearMaterialPaint,
    /// Paint, invert or clear the freeze mask (one undo step).
    Mask(crate::tools::MaskEdit),
    /// Start applying the tool (as if the device button went down).
    StrokeStart,
    /// Stop applying the tool; the stroke becomes one undo step.
    StrokeStop,
    /// Mirror strokes across the x, y and z planes through the clay's centre (each on or off).
    SetSymmetry(crate::engine::Symmetry),
    Undo,
    Redo,
    /// Pin a point, curve or normal on the clay (one undo step).
    Pin(crate::tools::PinRequest),
    /// Add a detail patch over the box `lo ..= hi` (field coordinates) at knot spacing
    /// `base / 2^level`.
    Refine {
        lo: glam::Vec3,
        hi: glam::Vec3,
        level: u32,
    },
    /// Remove pin `index`, or every pin with `None` (one undo step).
    Unpin {
        index: Option<usize>,
    },
    /// Write the session to `path` (atomically).
    Save {
        path: PathBuf,
    },
    /// Replace the session with the one at `path` (a session is read, a point cloud, mesh or
    /// volume fitted, in the background), dropping the undo history: the launch's load.
    Load {
        path: PathBuf,
    },
    /// Replace the clay with `with`, read or fitted in the background while the old clay
    /// stays in use; with `keep_history` the old clay's undo history is kept and the
    /// replacement is one more undo step (where the new clay has the running clay's layout;
    /// a clay of another layout needs a new engine, and the history cannot follow it).
    Replace {
        with: ClaySource,
        keep_history: bool,
    },
    /// The user's answer to the engine's question whether a step may remove more than half
    /// the clay ([`crate::engine::RemovalQuestion`]).
    AnswerRemoval {
        yes: bool,
    },
    /// Write the welded surface mesh to `path`; the format follows the extension.
    Export {
        path: PathBuf,
    },
    /// Close the current device (if any) and open `spec`, limiting force to `max_force_n`.
    ConnectDevice {
        spec: DeviceSpec,
        max_force_n: f32,
    },
    /// Close the device; the engine keeps running with zero force.
    DisconnectDevice,
    /// Change the force limit of the connected device's safety filter.
    SetMaxForce {
        max_force_n: f32,
    },
    /// Change how strongly sculpting is felt (the haptic gain, 0 to
    /// [`crate::engine::MAX_HAPTIC_GAIN`]).
    SetHapticGain {
        gain: f32,
    },
    /// CSG (Guo & Qin Table 1) of the clay with `operand`: `op` is [`ToolAction::Union`],
    /// [`ToolAction::Intersection`] or [`ToolAction::Difference`] (one undo step).
    ///
    /// [`ToolAction::Union`]: crate::tools::ToolAction::Union
    /// [`ToolAction::Intersection`]: crate::tools::ToolAction::Intersection
    /// [`ToolAction::Difference`]: crate::tools::ToolAction::Difference
    Csg {
        op: crate::tools::ToolAction,
        operand: CsgOperand,
    },
    /// Emboss (or engrave) the image at `image` (PNG or JPEG) onto the clay (one undo step).
    Emboss {
        image: PathBuf,
        params: crate::tools::EmbossParams,
    },
    /// Store a tool made from the sculpt in the session's library (replacing one of the same
    /// name); it is saved with the session.
    AddTool(Box<crate::io::ToolPreset>),
    /// Hold the clay as a compact RBF of `particles` particles (Zhang et al. §5.4: the clay is
    /// re-interpolated after each contact stroke), or stop with `None`.
    SetCompactRbf {
        particles: Option<usize>,
    },
}

impl EngineCommand {
    /// Short name for status messages.
    #[must_use]
    pub fn name(&self) -> &'static str {
        match self {
            Self::SelectTool(_) => "select tool",
            Self::SetMaterial(_) => "set material",
            Self::SetAutoDetail { .. } => "set automatic detail",
            Self::PaintMaterial(_) => "paint material",
            Self::ClearMaterialPaint => "clear painted material",
            Self::Mask(edit) => edit.name(),
            Self::StrokeStart => "stroke start",
            Self::StrokeStop => "stroke stop",
            Self::SetSymmetry(_) => "symmetry",
            Self::Undo => "undo",
            Self::Redo => "redo",
            Self::Pin(_) => "pin",
            Self::Refine { .. } => "refine",
            Self::Unpin { .. } => "unpin",
            Self::Save { .. } => "save",
            Self::Load { .. } | Self::Replace { .. } => "load",
            Self::AnswerRemoval { .. } => "answer removal",
            Self::Export { .. } => "export",
            Self::ConnectDevice { .. } => "connect device",
            Self::DisconnectDevice => "disconnect device",
            Self::SetMaxForce { .. } => "set max force",
            Self::SetHapticGain { .. } => "set haptic gain",
            Self::SetCompactRbf { .. } => "compact RBF clay",
            Self::AddTool(_) => "make tool",
            Self::Csg { .. } => "csg",
            Self::Emboss { .. } => "emboss",
        }
    }
}

/// What a replacement clay is made from.
#[derive(Clone, Debug, PartialEq)]
pub enum ClaySource {
    /// A session file (`.dclay`), or a point cloud, mesh or volume to fit.
    File(PathBuf),
    /// A new clay of one of the starting shapes.
    New(super::new_clay::NewClay),
}

/// How far a background load has come, for the window's progress bar.
#[derive(Clone, Debug, PartialEq)]
pub struct LoadProgress {
    /// The file read or fitted (or "new clay").
    pub source: String,
    /// Of the whole load, 0 to 1.
    pub fraction: f32,
    /// What it is doing now.
    pub stage: String,
}

/// The other operand of a CSG operation.
#[derive(Clone, Debug, PartialEq)]
pub enum CsgOperand {
    /// The clay of a session file, in its own field coordinates (read on the bridge thread).
    Session(PathBuf),
    /// An analytic solid at a pose, its potential falling over `falloff_fu` on each side of
    /// its surface.
    Solid {
        /// Boxed: a shape (a freeform one holds a lattice) is far larger than a path.
        shape: Box<crate::tools::ToolShape>,
        pose: crate::tools::ToolPose,
        falloff_fu: f32,
    },
}

/// The engine's answer to a command that can fail or takes a while (save, load, export,
/// connect), shown in the app's status line and log.
#[derive(Clone, Debug, PartialEq)]
pub enum EngineEvent {
    /// `what` finished; `detail` says what happened (for example the path written).
    Done { what: String, detail: String },
    /// `what` failed with `error` (the error's own message, naming file and field).
    Failed { what: String, error: String },
    /// A session was loaded: its tool library, for the library panel and the palette.
    Library(Vec<crate::io::ToolPreset>),
    /// A background load moved on (`Some`), or ended, well or not (`None`).
    Progress(Option<LoadProgress>),
    /// A file was opened or saved: `path` joins the recent files, and with `is_session`
    /// it is now the session worked on (Save writes it, autosave writes beside it).
    FileDone { path: PathBuf, is_session: bool },
}
