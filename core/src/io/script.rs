//! The one script format of dynaclay (TOML): the starting clay, autosave, and an ordered list
//! of steps covering every geometric tool, force stroke, material change, CSG, undo/redo and
//! save, so any session can be scripted. `dynaclay run --script` plays it through the engine
//! (strokes become the simulated arm's hand trajectory; see `engine::ScriptPlan` for the
//! timeline; `dynaclay run --lockstep` plays it deterministically). This module holds the
//! serde types and the parser, whose errors name the file, line, column and field. The user guide's "Scripts" chapter (`docs/src/scripts.md`) is the user reference.
//!
//! ```toml
//! version = 1
//! seconds = 4.0                 # optional run length
//!
//! [clay]                        # optional starting clay
//! shape = "block"
//! resolution = 24
//!
//! [[step]]
//! do = "tool"
//! shape = { kind = "sphere", radius_fu = 0.2 }
//! action = { kind = "add", deposit_rate_per_s = 4.0 }
//! positions = [[0.5, 0.5, 0.5], [0.6, 0.5, 0.5]]
//! duration_s = 0.5
//!
//! [[step]]
//! do = "stroke"
//! tool = { kind = "chisel", depth_fu = 0.03, radius_fu = 0.05, gain = 1e6 }
//! path = [[0.9, 0.5, 0.5]]
//! duration_s = 1.0
//!
//! [[step]]
//! do = "constrain"
//! kind = "point"
//! at = [0.9, 0.5, 0.5]
//!
//! [[step]]
//! do = "undo"
//! ```

use std::path::PathBuf;

use glam::{Quat, Vec3};
use serde::{Deserialize, Serialize};

use crate::dynamics::{
    Distribution, MAX_CONSTRAINTS, MAX_CURVE_POINTS, Material, MaterialPaint, Neighbourhood,
    PaintRegion,
};
use crate::tools::{ForceTool, PinRequest, ToolAction, ToolPose, ToolShape};

/// The version of the script format this build reads.
pub const SCRIPT_VERSION: u32 = 1;

/// The largest script file read, bytes; a longer file is refused before it is read whole.
pub const MAX_SCRIPT_BYTES: u64 = 4 << 20;
/// The most steps a script may hold.
pub const MAX_STEPS: usize = 10_000;
/// The most points in one list (`positions`, `path`, `curve`, `times_s`).
pub const MAX_POINTS: usize = 10_000;
/// The longest a step, a stroke or a run may last, and the latest a step may start, seconds.
pub const MAX_SCRIPT_SECONDS: f32 = 3600.0;
/// The most undo or redo steps one `undo`/`redo` step may ask for.
pub const MAX_UNDO_COUNT: u32 = 10_000;

/// A parsed script.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Script {
    pub version: u32,
    /// Run length in seconds for a headless run (the command line may override it); default:
    /// the end of the last step plus half a second.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seconds: Option<f64>,
    /// The clay to start from when no session is given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub clay: Option<ClaySpec>,
    /// Autosave policy of a headless run (default: every 60 s or 20 strokes).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub autosave: Option<AutosaveSpec>,
    /// Whether a geometric tool on a device that renders force rests on the clay with its
    /// shape and acts where it rests as the hand presses (as in the window), instead of
    /// acting where each stroke's path puts the tip (the default: a script's path says where
    /// the tool acts).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub tool_contact: bool,
    #[serde(default, rename = "step")]
    pub steps: Vec<ScriptStep>,
    /// Keys written under a name the format renamed (read as the new name), in file order;
    /// a run prints each as a warning.
    #[serde(skip)]
    pub deprecated: Vec<DeprecatedKey>,
    /// The line each step's table starts on (0 where unknown), for messages about a step
    /// while the script runs.
    #[serde(skip)]
    pub step_lines: Vec<usize>,
}

/// Keys the format renamed when lengths on the clay got their true unit, as (old name, name
/// to write now). Lengths on the clay are field units (`_fu`), not metres; the old names are
/// still read, with a [`DeprecatedKey`] note.
pub const RENAMED_KEYS: [(&str, &str); 8] = [
    ("radius_m", "radius_fu"),
    ("radii_m", "radii_fu"),
    ("half_extents_m", "half_extents_fu"),
    ("half_height_m", "half_height_fu"),
    ("depth_m", "depth_fu"),
    ("falloff_m", "falloff_fu"),
    ("hover_m", "hover_fu"),
    ("kernel_m", "kernel_fu"),
];

/// A key written under its old name ([`RENAMED_KEYS`]): read as the new one, and noted so the
/// run can say where to change it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DeprecatedKey {
    /// The script, as named in errors.
    pub file: String,
    /// 1-based line of the key.
    pub line: usize,
    /// The key as written.
    pub key: &'static str,
    /// The key to write instead.
    pub replacement: &'static str,
}

impl Script {
    /// The files the script reads, each with what names it (`[clay] session`, or the step
    /// number and key), joined to the script's folder `base_dir` as the steps join them.
    #[must_use]
    pub fn input_files(&self, base_dir: &std::path::Path) -> Vec<(String, PathBuf)> {
        let mut inputs = Vec::new();
        if let Some(session) = self.clay.as_ref().and_then(|c| c.session.as_ref()) {
            inputs.push(("[clay] session".to_owned(), base_dir.join(session)));
        }
        for (i, step) in self.steps.iter().enumerate() {
            let (key, path) = match step {
                ScriptStep::Csg {
                    with: Some(path), ..
                } => ("with", path),
                ScriptStep::Emboss { image, .. } => ("image", image),
                ScriptStep::Points { input, .. } => ("input", input),
                _ => continue,
            };
            inputs.push((format!("step {} {key}", i + 1), base_dir.join(path)));
        }
        inputs
    }
}

impl std::fmt::Display for DeprecatedKey {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}:{}: `{}` is deprecated: lengths on the clay are in field units, not metres; write `{}`",
            self.file, self.line, self.key, self.replacement
        )
    }
}

/// The starting clay's shape.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ClayShape {
    /// A box filling the middle half of the lattice.
    #[default]
    Block,
    /// A ball of radius a quarter of the lattice.
    Sphere,
}

/// `[clay]`: the starting clay, a lattice of `resolution³` coefficients (see
/// `engine::build_clay`), or the session file `session` (relative to the script's folder;
/// `shape` and `resolution` are then not used).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ClaySpec {
    pub shape: ClayShape,
    /// Coefficients per axis, 8 to 96.
    pub resolution: usize,
    /// A session to start from instead (an imported scan, an earlier sculpt).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub session: Option<std::path::PathBuf>,
}

impl Default for ClaySpec {
    fn default() -> Self {
        Self {
            shape: ClayShape::Block,
            resolution: 24,
            session: None,
        }
    }
}

/// `[autosave]`: write a recovery file every `every_s` seconds or `every_strokes` strokes,
/// whichever comes first (0 disables that limit).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AutosaveSpec {
    pub every_s: f32,
    pub every_strokes: u32,
}

impl Default for AutosaveSpec {
    fn default() -> Self {
        let p = crate::io::AutosavePolicy::default();
        Self {
            every_s: p.every_s,
            every_strokes: p.every_strokes,
        }
    }
}

impl From<AutosaveSpec> for crate::io::AutosavePolicy {
    fn from(a: AutosaveSpec) -> Self {
        Self {
            every_s: a.every_s,
            every_strokes: a.every_strokes,
        }
    }
}

/// A tool shape as written in a script; `freeform` names a preset of the session's library.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum ShapeSpec {
    Sphere {
        #[serde(alias = "radius_m")]
        radius_fu: f32,
    },
    Ellipsoid {
        #[serde(alias = "radii_m")]
        radii_fu: [f32; 3],
    },
    Box {
        #[serde(alias = "half_extents_m")]
        half_extents_fu: [f32; 3],
    },
    Cylinder {
        #[serde(alias = "radius_m")]
        radius_fu: f32,
        #[serde(alias = "half_height_m")]
        half_height_fu: f32,
    },
    Capsule {
        #[serde(alias = "radius_m")]
        radius_fu: f32,
        #[serde(alias = "half_height_m")]
        half_height_fu: f32,
    },
    Freeform {
        preset: String,
        #[serde(default = "unit_scale")]
        scale: [f32; 3],
    },
}

fn unit_scale() -> [f32; 3] {
    [1.0; 3]
}

/// The β distribution of a force tool.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BetaSpec {
    Constant,
    Gaussian,
    Spherical,
    Cylindrical,
    Conical,
}

impl From<BetaSpec> for Distribution {
    fn from(b: BetaSpec) -> Self {
        match b {
            BetaSpec::Constant => Self::Constant,
            BetaSpec::Gaussian => Self::Gaussian,
            BetaSpec::Spherical => Self::Spherical,
            BetaSpec::Cylindrical => Self::Cylindrical,
            BetaSpec::Conical => Self::Conical,
        }
    }
}

/// A force tool as written in a script.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum ForceToolSpec {
    /// The contact push (the default tool of a stroke): while the stroke is held and the tip
    /// is inside the clay, the force vector runs from the surface above the tip to the tip.
    Push {
        #[serde(default = "default_beta")]
        beta: BetaSpec,
        #[serde(default = "default_push_radius", alias = "radius_m")]
        radius_fu: f32,
        #[serde(default = "default_push_gain")]
        gain: f32,
    },
    Grab {
        gain: f32,
    },
    Area {
        beta: BetaSpec,
        #[serde(alias = "radius_m")]
        radius_fu: f32,
        tracks: u32,
        gain: f32,
    },
    Curve {
        #[serde(alias = "radius_m")]
        radius_fu: f32,
        gain: f32,
    },
    Chisel {
        #[serde(alias = "depth_m")]
        depth_fu: f32,
        #[serde(alias = "radius_m")]
        radius_fu: f32,
        gain: f32,
    },
    Squirt {
        #[serde(alias = "depth_m")]
        depth_fu: f32,
        #[serde(alias = "radius_m")]
        radius_fu: f32,
        gain: f32,
    },
    Pull {
        beta: BetaSpec,
        #[serde(alias = "radius_m")]
        radius_fu: f32,
        gain: f32,
    },
    Bend {
        samples: u32,
        #[serde(alias = "radius_m")]
        radius_fu: f32,
        gain: f32,
    },
}

fn default_beta() -> BetaSpec {
    BetaSpec::Gaussian
}

fn default_push_radius() -> f32 {
    0.25
}

fn default_push_gain() -> f32 {
    2.0e6
}

impl ForceToolSpec {
    /// The default tool of a stroke: a Gaussian push of radius 0.25 and gain 2·10⁶.
    pub const DEFAULT_PUSH: Self = Self::Push {
        beta: BetaSpec::Gaussian,
        radius_fu: 0.25,
        gain: 2.0e6,
    };

    /// The dynamics force tool this names; `None` for the contact push, which the engine's
    /// haptic contact drives.
    #[must_use]
    pub fn force_tool(&self) -> Option<ForceTool> {
        Some(match *self {
            Self::Push { .. } => return None,
            Self::Grab { gain } => ForceTool::PointGrab { gain },
            Self::Area {
                beta,
                radius_fu,
                tracks,
                gain,
            } => ForceTool::Area {
                distribution: beta.into(),
                radius_fu,
                tracks,
                gain,
            },
            Self::Curve { radius_fu, gain } => ForceTool::Curve { radius_fu, gain },
            Self::Chisel {
                depth_fu,
                radius_fu,
                gain,
            } => ForceTool::Chisel {
                depth_fu,
                radius_fu,
                gain,
            },
            Self::Squirt {
                depth_fu,
                radius_fu,
                gain,
            } => ForceTool::Squirt {
                depth_fu,
                radius_fu,
                gain,
            },
            Self::Pull {
                beta,
                radius_fu,
                gain,
            } => ForceTool::Pull {
                distribution: beta.into(),
                radius_fu,
                gain,
            },
            Self::Bend {
                samples,
                radius_fu,
                gain,
            } => ForceTool::Bend {
                samples,
                radius_fu,
                gain,
            },
        })
    }

    /// Checks the parameters (radii, depths and gains positive and finite).
    ///
    /// # Errors
    /// Names the parameter.
    pub fn validate(&self) -> Result<(), String> {
        match (self, self.force_tool()) {
            (_, Some(tool)) => tool.validate().map_err(|e| e.0),
            (
                Self::Push {
                    radius_fu, gain, ..
                },
                None,
            ) => {
                for (name, v) in [("radius_fu", *radius_fu), ("gain", *gain)] {
                    if !(v.is_finite() && v > 0.0) {
                        return Err(format!("{name} must be positive and finite, got {v}"));
                    }
                }
                Ok(())
            }
            (_, None) => Ok(()),
        }
    }
}

/// How an embossed image lies on the clay (field coordinates and lengths).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum ProjectionSpec {
    /// Projected along `axis` onto the faces turned toward it, `size` wide.
    Planar {
        centre: [f32; 3],
        axis: [f32; 3],
        up: [f32; 3],
        size: f32,
    },
    /// Wrapped once around `axis` through `centre`, `height` tall.
    Cylindrical {
        centre: [f32; 3],
        axis: [f32; 3],
        up: [f32; 3],
        height: f32,
    },
    /// Longitude and latitude about `centre`, the image's top at `up`.
    Spherical { centre: [f32; 3], up: [f32; 3] },
}

impl ProjectionSpec {
    /// The tools' projection.
    #[must_use]
    pub fn projection(&self) -> crate::tools::Projection {
        use crate::tools::Projection;
        match *self {
            Self::Planar {
                centre,
                axis,
                up,
                size,
            } => Projection::Planar {
                centre: centre.into(),
                axis: axis.into(),
                up: up.into(),
                size,
            },
            Self::Cylindrical {
                centre,
                axis,
                up,
                height,
            } => Projection::Cylindrical {
                centre: centre.into(),
                axis: axis.into(),
                up: up.into(),
                height,
            },
            Self::Spherical { centre, up } => Projection::Spherical {
                centre: centre.into(),
                up: up.into(),
            },
        }
    }
}

/// CSG operations between the clay and another clay (a session file's or a solid's).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CsgSpec {
    Union,
    Intersection,
    Difference,
}

impl From<CsgSpec> for ToolAction {
    fn from(c: CsgSpec) -> Self {
        match c {
            CsgSpec::Union => Self::Union,
            CsgSpec::Intersection => Self::Intersection,
            CsgSpec::Difference => Self::Difference,
        }
    }
}

fn default_falloff() -> f32 {
    0.05
}

fn one() -> u32 {
    1
}

fn default_hover() -> f32 {
    0.35
}

/// Where a `make_tool` step takes the clay from, field coordinates.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum SelectionSpec {
    /// The box `min ..= max` (axis-aligned).
    Box { min: [f32; 3], max: [f32; 3] },
    /// The ball of `radius_fu` about `centre`.
    Ball {
        centre: [f32; 3],
        #[serde(alias = "radius_m")]
        radius_fu: f32,
    },
}

impl SelectionSpec {
    /// The tools' selection.
    #[must_use]
    pub fn selection(&self) -> crate::tools::Selection {
        match *self {
            Self::Box { min, max } => {
                let (lo, hi) = (Vec3::from_array(min), Vec3::from_array(max));
                crate::tools::Selection::Box {
                    centre: 0.5 * (lo + hi),
                    half_extents_fu: 0.5 * (hi - lo),
                }
            }
            Self::Ball { centre, radius_fu } => crate::tools::Selection::Ball {
                centre: Vec3::from_array(centre),
                radius_fu,
            },
        }
    }
}

fn default_union() -> ToolAction {
    ToolAction::Union
}

/// One step of a script. Each tool application or stroke is one undo step.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "do", rename_all = "snake_case", deny_unknown_fields)]
pub enum ScriptStep {
    /// A geometric tool applied at each position in turn over `duration_s`.
    Tool {
        shape: ShapeSpec,
        action: ToolAction,
        positions: Vec<[f32; 3]>,
        #[serde(default = "default_falloff", alias = "falloff_m")]
        falloff_fu: f32,
        /// Quaternion `[x, y, z, w]`; identity when absent.
        #[serde(default)]
        rotation: Option<[f32; 4]>,
        #[serde(default)]
        duration_s: f32,
        #[serde(default)]
        patch: u16,
    },
    /// A tool of the session's library applied at each position.
    Preset {
        name: String,
        positions: Vec<[f32; 3]>,
        #[serde(default)]
        duration_s: f32,
    },
    /// A stroke of the device: the (simulated) hand hovers above `path`, descends, follows
    /// it holding `buttons` and lifts again; run live by the engine. The tool is a force tool
    /// (`tool`, the contact push by default) or a geometric tool (`shape` and `action`).
    Stroke {
        #[serde(default, skip_serializing_if = "Option::is_none")]
        tool: Option<ForceToolSpec>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        shape: Option<ShapeSpec>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        action: Option<ToolAction>,
        #[serde(default = "default_falloff", alias = "falloff_m")]
        falloff_fu: f32,
        /// Tip targets, field coordinates.
        path: Vec<[f32; 3]>,
        /// The hand's orientation at each path point, quaternions `[x, y, z, w]` (one per
        /// point; none: unturned). A geometric tool turns with the hand.
        #[serde(default, skip_serializing_if = "Vec::is_empty")]
        rotations: Vec<[f32; 4]>,
        /// Time along the path (default 1 s, or the last of `times_s`).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        duration_s: Option<f32>,
        /// When the tip reaches each path point, seconds from the start of the path (instead
        /// of `duration_s`, which spaces the points evenly).
        #[serde(default, skip_serializing_if = "Vec::is_empty")]
        times_s: Vec<f32>,
        /// Earliest time the hand leaves its hover point, seconds from the start of the run.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        start_s: Option<f64>,
        /// Hover height above the path's ends before and after the stroke.
        #[serde(default = "default_hover", alias = "hover_m")]
        hover_fu: f32,
        /// Device buttons held along the path (bit 0 is the stroke button).
        #[serde(default = "one")]
        buttons: u32,
        /// The user curve of a curve tool.
        #[serde(default, skip_serializing_if = "Vec::is_empty")]
        curve: Vec<[f32; 3]>,
        /// The pivot of a bend.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        pivot: Option<[f32; 3]>,
    },
    /// Make a freeform tool of the clay inside `selection` as it is when the step runs, and
    /// keep it in the session's library as `name` (saved with the session; a tool of that
    /// name is replaced). Later `tool`, `stroke` and `preset` steps use it by name. The clay
    /// does not change.
    MakeTool {
        name: String,
        selection: SelectionSpec,
        /// The action a `preset` step applies it with (default `union`).
        #[serde(default = "default_union")]
        action: ToolAction,
        #[serde(default = "default_falloff", alias = "falloff_m")]
        falloff_fu: f32,
    },
    /// Change the uniform material; absent fields keep their values.
    Material {
        #[serde(default)]
        mass: Option<f32>,
        #[serde(default)]
        damping: Option<f32>,
        #[serde(default)]
        stiffness: Option<f32>,
        #[serde(default)]
        plasticity_per_s: Option<f32>,
        #[serde(default)]
        yield_density: Option<f32>,
        /// Which grid neighbours the density springs join: 6, 18 or 26.
        #[serde(default)]
        neighbourhood: Option<u32>,
    },
    /// Paint mass, damping, stiffness or plastic drift rate (`plasticity_per_s`) into a
    /// region of the clay: a ball (`centre`,
    /// `radius_fu`) or a box (`min`, `max`), field coordinates. Values absent keep what is
    /// there; the simulation uses the painted values where they are (Hua & Qin's material
    /// distributions). Takes no script time; not an undo step.
    PaintMaterial {
        #[serde(default, skip_serializing_if = "Option::is_none")]
        centre: Option<[f32; 3]>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        radius_fu: Option<f32>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        min: Option<[f32; 3]>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        max: Option<[f32; 3]>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        mass: Option<f32>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        damping: Option<f32>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        stiffness: Option<f32>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        plasticity_per_s: Option<f32>,
    },
    /// CSG with another clay: the clay of a session file (`with`, relative to the script's
    /// folder) or a solid (`shape` centred at `position`, turned by `rotation`, its potential
    /// falling over `falloff_fu` on each side of its surface). Exactly one of `with` and
    /// `shape`.
    Csg {
        op: CsgSpec,
        #[serde(default)]
        with: Option<PathBuf>,
        #[serde(default)]
        shape: Option<ShapeSpec>,
        #[serde(default)]
        position: Option<[f32; 3]>,
        /// Quaternion `[x, y, z, w]`; identity when absent.
        #[serde(default)]
        rotation: Option<[f32; 4]>,
        #[serde(default = "default_falloff", alias = "falloff_m")]
        falloff_fu: f32,
        #[serde(default)]
        patch: u16,
    },
    Undo {
        #[serde(default = "one")]
        count: u32,
    },
    Redo {
        #[serde(default = "one")]
        count: u32,
    },
    /// Save the session (relative to the script's folder).
    Save { path: PathBuf },
    /// Emboss (or engrave) an image onto the clay: `image` (PNG or JPEG, relative to the
    /// script's folder), `projection`, `depth` (field units) and `engrave`.
    Emboss {
        image: PathBuf,
        projection: ProjectionSpec,
        depth: f32,
        #[serde(default)]
        engrave: bool,
        #[serde(default)]
        patch: u16,
    },
    /// Add a detail patch over the box `min ..= max` (field coordinates, clipped to the clay)
    /// at knot spacing `base / 2^level` (`level` 1 by default, at most 4): strokes inside it
    /// are simulated at the finer spacing.
    Refine {
        min: [f32; 3],
        max: [f32; 3],
        #[serde(default = "one")]
        level: u32,
    },
    /// Pin a place on the clay (one undo step): `kind = "point"` or `"normal"` with `at`,
    /// `kind = "curve"` with `points`. A point off the surface is moved onto it first, and the
    /// step says so.
    Constrain {
        kind: PinKind,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        at: Option<[f32; 3]>,
        #[serde(default, skip_serializing_if = "Vec::is_empty")]
        points: Vec<[f32; 3]>,
    },
    /// Settle `count` constrained particles on the clay's surface (Zhang et al. §5): later
    /// `rbf` steps use this count. With `out` (relative to the script's folder) the particles
    /// are written as a point cloud, one `x y z nx ny nz` line each. Takes no script time:
    /// the clay is copied when the step is reached and sampled beside the engine.
    Particles {
        count: u32,
        /// Particle steps from the seeded random start (default 200).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        steps: Option<u32>,
        /// Seed of the random start (default 1).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        seed: Option<u64>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        out: Option<PathBuf>,
    },
    /// Interpolate the clay's surface with an RBF (Zhang et al. §5.3) and write it to `out`
    /// (`.rbf`, relative to the script's folder): `particles` particles (default: the last
    /// `particles` step's count, else 400), normal offset `offset` (default half a knot span),
    /// at most `max_centres` centres in one solve (default 3000).
    Rbf {
        out: PathBuf,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        particles: Option<u32>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        offset: Option<f32>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        max_centres: Option<u32>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        steps: Option<u32>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        seed: Option<u64>,
    },
    /// Hold the clay as a compact RBF from here on (Zhang et al. §5.4): `particles` particles
    /// (the RBF has three centres per particle; 8 to 1000), or `particles = 0` to stop. The
    /// clay is interpolated when the step is reached, then again after every contact stroke
    /// and contact `tool` step (each time one undo step), beside the engine. Takes no script
    /// time.
    CompactRbf { particles: u32 },
    /// Build a point-set surface (Guo & Qin) from the point cloud `input` (XYZ, PLY, OBJ or
    /// STL, relative to the script's folder), pull it toward each point of `pull` in turn for
    /// `steps` simulation steps each (default 2000), and write it to `out` (`.ply` with
    /// normals, relative to the script's folder). Takes no script time and leaves the clay
    /// alone: it runs on a thread of its own.
    Points {
        input: PathBuf,
        #[serde(default, skip_serializing_if = "Vec::is_empty")]
        pull: Vec<[f32; 3]>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        steps: Option<u32>,
        out: PathBuf,
    },
    /// Remove pin `index` (counted from 0 in the order pinned), or every pin when absent (one
    /// undo step).
    Unconstrain {
        /// Signed so that a negative index is refused with its line, not as a type error.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        index: Option<i64>,
    },
}

/// What a `constrain` step pins.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PinKind {
    /// A point that stays on the surface (`at`).
    Point,
    /// A polyline the surface keeps passing through (`points`).
    Curve,
    /// A normal kept, with its point (`at`).
    Normal,
}

/// The pin a `constrain` step asks for.
///
/// # Errors
/// When the keys do not match the kind (`at` for point and normal, `points` for curve) or a
/// point is not finite.
pub fn pin_request(
    kind: PinKind,
    at: Option<[f32; 3]>,
    points: &[[f32; 3]],
) -> Result<PinRequest, StepFault> {
    match (kind, at, points.is_empty()) {
        (PinKind::Point | PinKind::Normal, Some(at), true) => {
            check_points("at", &[at], true)?;
            let at = Vec3::from_array(at);
            Ok(if kind == PinKind::Point {
                PinRequest::Point(at)
            } else {
                PinRequest::Normal(at)
            })
        }
        (PinKind::Point | PinKind::Normal, None, _) => Err(fault(
            "kind",
            format!("kind = {kind:?} needs at = [x, y, z]").to_lowercase(),
        )),
        (PinKind::Point | PinKind::Normal, Some(_), false) => Err(fault(
            "points",
            "points: a point or normal pin takes at = [x, y, z], not points",
        )),
        (PinKind::Curve, None, _) => {
            check_points("points", points, true)?;
            if points.len() < 2 {
                return Err(fault(
                    "points",
                    format!(
                        "points: a curve needs at least 2 points, got {}",
                        points.len()
                    ),
                ));
            }
            if points.len() > MAX_CURVE_POINTS {
                return Err(fault(
                    "points",
                    format!(
                        "points: a curve may have at most {MAX_CURVE_POINTS} points, got {}",
                        points.len()
                    ),
                ));
            }
            Ok(PinRequest::Curve(
                points.iter().map(|&p| Vec3::from_array(p)).collect(),
            ))
        }
        (PinKind::Curve, Some(_), _) => Err(fault(
            "at",
            "at: a curve pin takes points = [[x, y, z], ...], not at",
        )),
    }
}

/// The paint a `paint_material` step asks for.
///
/// # Errors
/// When the region is not exactly one of a ball (`centre` and `radius_fu`) or a box (`min`
/// and `max`), is not finite or is empty, or when no value is given or a value is out of
/// range (mass positive; damping, stiffness and plasticity zero or more).
pub fn paint_request(step: &ScriptStep) -> Result<Option<MaterialPaint>, StepFault> {
    let ScriptStep::PaintMaterial {
        centre,
        radius_fu,
        min,
        max,
        mass,
        damping,
        stiffness,
        plasticity_per_s,
    } = *step
    else {
        return Ok(None);
    };
    let region = match (centre, radius_fu, min, max) {
        (Some(centre), Some(radius_fu), None, None) => {
            check_points("centre", &[centre], true)?;
            if !(radius_fu.is_finite() && radius_fu > 0.0) {
                return Err(fault(
                    "radius_fu",
                    format!("radius_fu = {radius_fu} must be finite and positive"),
                ));
            }
            PaintRegion::Sphere {
                centre: Vec3::from_array(centre),
                radius_fu,
            }
        }
        (None, None, Some(min), Some(max)) => {
            check_points("min", &[min], true)?;
            check_points("max", &[max], true)?;
            if (0..3).any(|a| min[a] > max[a]) {
                return Err(fault(
                    "max",
                    format!("the box {min:?}..{max:?} is empty: max must not be below min"),
                ));
            }
            PaintRegion::Box {
                min: Vec3::from_array(min),
                max: Vec3::from_array(max),
            }
        }
        (Some(_), None, _, _) => {
            return Err(fault("centre", "centre: a ball also needs radius_fu"));
        }
        (None, Some(_), _, _) => {
            return Err(fault("radius_fu", "radius_fu: a ball also needs centre"));
        }
        (Some(_), Some(_), _, _) => {
            return Err(fault(
                "min",
                "min, max: give a ball (centre, radius_fu) or a box (min, max), not both",
            ));
        }
        (None, None, _, _) => {
            return Err(fault(
                "do",
                "paint_material needs a ball (centre, radius_fu) or a box (min, max)",
            ));
        }
    };
    for (name, v) in [
        ("mass", mass),
        ("damping", damping),
        ("stiffness", stiffness),
        ("plasticity_per_s", plasticity_per_s),
    ] {
        if let Some(v) = v {
            finite(name, v)?;
        }
    }
    if mass.is_some_and(|m| m <= 0.0) {
        return Err(fault("mass", "mass must be positive"));
    }
    if mass.is_none() && damping.is_none() && stiffness.is_none() && plasticity_per_s.is_none() {
        return Err(fault(
            "do",
            "paint_material needs at least one of mass, damping, stiffness, plasticity_per_s",
        ));
    }
    Ok(Some(MaterialPaint {
        region,
        mass,
        damping,
        stiffness,
        plasticity_per_s,
    }))
}

impl ShapeSpec {
    /// The tool shape; `freeform` looks up `preset` with `library` (name → shape).
    ///
    /// # Errors
    /// When the preset does not exist.
    pub fn resolve<'a>(
        &self,
        library: impl Fn(&str) -> Option<&'a ToolShape>,
    ) -> Result<ToolShape, String> {
        Ok(match self {
            Self::Sphere { radius_fu } => ToolShape::Sphere {
                radius_fu: *radius_fu,
            },
            Self::Ellipsoid { radii_fu } => ToolShape::Ellipsoid {
                radii_fu: Vec3::from_array(*radii_fu),
            },
            Self::Box { half_extents_fu } => ToolShape::Box {
                half_extents_fu: Vec3::from_array(*half_extents_fu),
            },
            Self::Cylinder {
                radius_fu,
                half_height_fu,
            } => ToolShape::Cylinder {
                radius_fu: *radius_fu,
                half_height_fu: *half_height_fu,
            },
            Self::Capsule {
                radius_fu,
                half_height_fu,
            } => ToolShape::Capsule {
                radius_fu: *radius_fu,
                half_height_fu: *half_height_fu,
            },
            Self::Freeform { preset, scale } => match library(preset) {
                Some(ToolShape::Freeform(f)) => {
                    let mut f = f.clone();
                    f.scale *= Vec3::from_array(*scale);
                    ToolShape::Freeform(f)
                }
                Some(_) => return Err(format!("tool preset {preset:?} is not a freeform shape")),
                None => return Err(format!("no tool preset named {preset:?}")),
            },
        })
    }
}

/// The poses of a tool step.
#[must_use]
pub fn poses(positions: &[[f32; 3]], rotation: Option<[f32; 4]>) -> Vec<ToolPose> {
    let rotation = rotation.map_or(Quat::IDENTITY, |q| Quat::from_array(q).normalize());
    positions
        .iter()
        .map(|p| ToolPose {
            position_fu: Vec3::from_array(*p),
            rotation,
        })
        .collect()
}

impl ScriptStep {
    /// The material after this step's changes (for `material` steps; others return `m`).
    #[must_use]
    pub fn updated_material(&self, m: Material) -> Material {
        match *self {
            Self::Material {
                mass,
                damping,
                stiffness,
                plasticity_per_s,
                yield_density,
                neighbourhood,
            } => Material {
                mass: mass.unwrap_or(m.mass),
                damping: damping.unwrap_or(m.damping),
                stiffness: stiffness.unwrap_or(m.stiffness),
                plasticity_per_s: plasticity_per_s.unwrap_or(m.plasticity_per_s),
                yield_density: yield_density.unwrap_or(m.yield_density),
                // Checked to be 6, 18 or 26 when the script was parsed.
                neighbourhood: neighbourhood
                    .and_then(Neighbourhood::from_count)
                    .unwrap_or(m.neighbourhood),
            },
            _ => m,
        }
    }
}

/// Why a script could not be read or run: where (file, line, column, step) and what.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{file}{}: {message}", Location { line: *line, column: *column, step: *step })]
pub struct ScriptError {
    pub file: String,
    /// 1-based line and column, when known.
    pub line: Option<usize>,
    pub column: Option<usize>,
    /// 1-based index of the failing step, when known.
    pub step: Option<usize>,
    pub message: String,
}

/// The `:line:column: step N` between a script error's file and message (each part only
/// when known; the column only with a line).
struct Location {
    line: Option<usize>,
    column: Option<usize>,
    step: Option<usize>,
}

impl std::fmt::Display for Location {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if let Some(l) = self.line {
            write!(f, ":{l}")?;
            if let Some(c) = self.column {
                write!(f, ":{c}")?;
            }
        }
        if let Some(s) = self.step {
            write!(f, ": step {s}")?;
        }
        Ok(())
    }
}

/// 1-based line and column of a byte offset.
fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let before = &text[..offset.min(text.len())];
    let line = before.matches('\n').count() + 1;
    let column = before.len() - before.rfind('\n').map_or(0, |n| n + 1) + 1;
    (line, column)
}

/// Parses and checks a script; `file` names it in errors.
///
/// # Errors
/// TOML syntax or type errors with their line, column and the offending field (from the
/// parser's message; for a field inside a step the position is the step's `[[step]]` header,
/// because tagged steps are read as a whole); then semantic errors (wrong version, bad tool parameters, empty paths)
/// naming the step and its line.
pub fn parse_script(text: &str, file: &str) -> Result<Script, ScriptError> {
    let spans = Spans::new(text);
    let mut script: Script = toml::from_str(text).map_err(|e| {
        let message = e.message().trim().to_string();
        let (line, column) = match e.span() {
            Some(span) => {
                let (l, c) = line_col(text, span.start);
                // Inside a step the parser points at the step's table (tagged steps are read
                // as a whole); point at the named field's own line when the step has it.
                let field_line = backticked(&message).and_then(|key| {
                    let n = spans.step_at(span.start)?;
                    spans.step_key_line(n, key)
                });
                match field_line {
                    Some(field_line) => (Some(field_line), None),
                    None => (Some(l), Some(c)),
                }
            }
            None => (None, None),
        };
        ScriptError {
            file: file.to_string(),
            line,
            column,
            step: None,
            message,
        }
    })?;
    let at = |n: usize, fault: StepFault| ScriptError {
        file: file.to_string(),
        line: spans
            .step_key_line(n, fault.key)
            .or_else(|| spans.step_line(n)),
        column: None,
        step: Some(n + 1),
        message: fault.message,
    };
    let top = |path: &[&str], message: String| ScriptError {
        file: file.to_string(),
        line: spans.key_line(path),
        column: None,
        step: None,
        message,
    };
    if script.version != SCRIPT_VERSION {
        return Err(top(
            &["version"],
            format!(
                "version = {} is not supported (this build reads version {SCRIPT_VERSION})",
                script.version
            ),
        ));
    }
    if let Some(s) = script.seconds
        && !(s.is_finite() && s > 0.0 && s <= 3600.0)
    {
        return Err(top(
            &["seconds"],
            format!("seconds = {s} must be in (0, 3600]"),
        ));
    }
    if let Some(c) = &script.clay
        && !(8..=96).contains(&c.resolution)
    {
        return Err(top(
            &["clay", "resolution"],
            format!(
                "clay.resolution = {} must be between 8 and 96",
                c.resolution
            ),
        ));
    }
    if let Some(a) = script.autosave
        && !(a.every_s.is_finite() && a.every_s >= 0.0)
    {
        return Err(top(
            &["autosave", "every_s"],
            format!("autosave.every_s = {} must be finite and ≥ 0", a.every_s),
        ));
    }
    if script.steps.len() > MAX_STEPS {
        return Err(top(
            &["step"],
            format!(
                "the script has {} steps; at most {MAX_STEPS} are allowed",
                script.steps.len()
            ),
        ));
    }
    for (n, step) in script.steps.iter().enumerate() {
        check_step(step).map_err(|f| at(n, f))?;
    }
    script.deprecated = spans
        .renamed_keys()
        .into_iter()
        .map(|(line, key, replacement)| DeprecatedKey {
            file: file.to_string(),
            line,
            key,
            replacement,
        })
        .collect();
    script.step_lines = (0..script.steps.len())
        .map(|n| spans.step_line(n).unwrap_or(0))
        .collect();
    Ok(script)
}

/// Where keys and steps are written in a script's text, from the TOML parser's spans (no
/// searching of the text or of messages). Built from text that may not parse; then nothing
/// is found and errors fall back to the parser's own position.
struct Spans<'t> {
    text: &'t str,
    document: Option<toml::Spanned<toml::de::DeTable<'t>>>,
}

impl<'t> Spans<'t> {
    fn new(text: &'t str) -> Self {
        Self {
            text,
            document: toml::de::DeTable::parse(text).ok(),
        }
    }

    fn line(&self, offset: usize) -> usize {
        line_col(self.text, offset).0
    }

    /// The `[[step]]` tables, in order.
    fn steps(&self) -> &[toml::Spanned<toml::de::DeValue<'t>>] {
        match self.document.as_ref().and_then(|d| d.get_ref().get("step")) {
            Some(v) => match v.get_ref() {
                toml::de::DeValue::Array(a) => a,
                _ => &[],
            },
            None => &[],
        }
    }

    /// Line of the key at `path` (a top-level key, or a key of a table).
    fn key_line(&self, path: &[&str]) -> Option<usize> {
        let mut table = self.document.as_ref()?.get_ref();
        let (last, parents) = path.split_last()?;
        for key in parents {
            match table.get(*key)?.get_ref() {
                toml::de::DeValue::Table(t) => table = t,
                toml::de::DeValue::Array(a) => match a.first()?.get_ref() {
                    toml::de::DeValue::Table(t) => table = t,
                    _ => return None,
                },
                _ => return None,
            }
        }
        let (key, _) = table.iter().find(|(k, _)| k.get_ref() == last)?;
        Some(self.line(key.span().start))
    }

    /// Every key written under an old name of [`RENAMED_KEYS`], as (line, old name, new
    /// name), in file order.
    fn renamed_keys(&self) -> Vec<(usize, &'static str, &'static str)> {
        let mut found = Vec::new();
        if let Some(document) = &self.document {
            self.collect_renamed(document.get_ref(), &mut found);
        }
        // In file order (a table's keys may come back in another order).
        found.sort_by_key(|&(offset, ..)| offset);
        found
            .into_iter()
            .map(|(offset, old, new)| (self.line(offset), old, new))
            .collect()
    }

    fn collect_renamed(
        &self,
        table: &toml::de::DeTable<'t>,
        found: &mut Vec<(usize, &'static str, &'static str)>,
    ) {
        // Byte offsets here; `renamed_keys` turns them into lines.
        for (k, v) in table.iter() {
            if let Some(&(old, new)) = RENAMED_KEYS.iter().find(|(old, _)| k.get_ref() == *old) {
                found.push((k.span().start, old, new));
            }
            self.collect_renamed_in(v.get_ref(), found);
        }
    }

    fn collect_renamed_in(
        &self,
        value: &toml::de::DeValue<'t>,
        found: &mut Vec<(usize, &'static str, &'static str)>,
    ) {
        match value {
            toml::de::DeValue::Table(t) => self.collect_renamed(t, found),
            toml::de::DeValue::Array(a) => {
                for v in a {
                    self.collect_renamed_in(v.get_ref(), found);
                }
            }
            _ => {}
        }
    }

    /// Which step's table holds byte `offset`.
    fn step_at(&self, offset: usize) -> Option<usize> {
        self.steps().iter().position(|s| s.span().contains(&offset))
    }

    /// Line where step `n`'s table starts.
    fn step_line(&self, n: usize) -> Option<usize> {
        Some(self.line(self.steps().get(n)?.span().start))
    }

    /// Line of `key` in step `n`, looked up in the step's table and then in the inline tables
    /// it holds (`shape = { radius_fu = … }`).
    fn step_key_line(&self, n: usize, key: &str) -> Option<usize> {
        let toml::de::DeValue::Table(table) = self.steps().get(n)?.get_ref() else {
            return None;
        };
        // A renamed key may be written under its old name.
        let old = RENAMED_KEYS
            .iter()
            .find(|(_, new)| *new == key)
            .map(|(old, _)| *old);
        let is_key = |k: &str| k == key || Some(k) == old;
        let direct = table.iter().find(|(k, _)| is_key(k.get_ref()));
        let nested = || {
            table.iter().find_map(|(_, v)| match v.get_ref() {
                toml::de::DeValue::Table(inner) => inner.iter().find(|(k, _)| is_key(k.get_ref())),
                _ => None,
            })
        };
        let (k, _) = direct.or_else(nested)?;
        Some(self.line(k.span().start))
    }
}

/// Reads and parses the script at `path` (named by its path in errors).
///
/// # Errors
/// When the file cannot be read (no line), or as [`parse_script`].
pub fn load_script(path: &std::path::Path) -> Result<Script, ScriptError> {
    let file = path.display().to_string();
    let fail = |message: String| ScriptError {
        file: file.clone(),
        line: None,
        column: None,
        step: None,
        message,
    };
    let bytes = super::bounded_read::read_regular_file(path, MAX_SCRIPT_BYTES)
        .map_err(|e| fail(format!("cannot read the script: {e}")))?;
    let text = String::from_utf8(bytes).map_err(|e| {
        fail(format!(
            "the script is not UTF-8 text (invalid byte at offset {})",
            e.utf8_error().valid_up_to()
        ))
    })?;
    parse_script(&text, &file)
}

/// The first `` `name` `` in a parser message.
fn backticked(message: &str) -> Option<&str> {
    let start = message.find('`')? + 1;
    let len = message[start..].find('`')?;
    Some(&message[start..start + len]).filter(|k| !k.is_empty())
}

/// A step's parameter at fault: the key it is written under (whose line the error names)
/// and what is wrong with it.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{message}")]
pub struct StepFault {
    /// The step's key, as written in the script.
    pub key: &'static str,
    /// What is wrong, naming the value.
    pub message: String,
}

fn fault(key: &'static str, message: impl Into<String>) -> StepFault {
    StepFault {
        key,
        message: message.into(),
    }
}

fn finite(name: &'static str, v: f32) -> Result<(), StepFault> {
    if v.is_finite() && v >= 0.0 {
        Ok(())
    } else {
        Err(fault(
            name,
            format!("{name} = {v} must be finite and non-negative"),
        ))
    }
}

/// A duration or time of day on the script clock: finite, non-negative, at most
/// [`MAX_SCRIPT_SECONDS`].
fn seconds(name: &'static str, v: f32) -> Result<(), StepFault> {
    seconds_shown(name, name, v)
}

/// [`seconds`] for the value `shown` (such as `times_s[2]`) written under `key`.
fn seconds_shown(key: &'static str, shown: &str, v: f32) -> Result<(), StepFault> {
    if !(v.is_finite() && v >= 0.0) {
        return Err(fault(
            key,
            format!("{shown} = {v} must be finite and non-negative"),
        ));
    }
    if v > MAX_SCRIPT_SECONDS {
        return Err(fault(
            key,
            format!("{shown} = {v} s is longer than the {MAX_SCRIPT_SECONDS} s a script may last"),
        ));
    }
    Ok(())
}

/// Most particles a `particles` or `rbf` step may ask for.
pub const MAX_PARTICLES: u32 = 100_000;
/// Most particle steps a `particles` or `rbf` step may ask for.
pub const MAX_PARTICLE_STEPS: u32 = 100_000;
/// Most simulation steps per pull of a `points` step.
pub const MAX_POINTS_PULL_STEPS: u32 = 1_000_000;
/// Simulation steps per pull of a `points` step that names none.
pub const DEFAULT_POINTS_PULL_STEPS: u32 = 2000;
/// Most centres one dense RBF solve may take (`max_centres`).
pub const MAX_RBF_CENTRES: u32 = 6000;

/// The fewest particles a compact RBF clay (`compact_rbf`) holds.
pub const MIN_COMPACT_PARTICLES: usize = 8;
/// The most particles a compact RBF clay holds: its `3N` centres fit one dense solve of the
/// RBF's default size (3000 centres; `dynaclay_import::rbf::CompactSettings` checks it).
pub const MAX_COMPACT_PARTICLES: usize = 1000;

fn check_particle_count(key: &'static str, n: u32) -> Result<(), StepFault> {
    if (4..=MAX_PARTICLES).contains(&n) {
        Ok(())
    } else {
        Err(fault(
            key,
            format!("{key} = {n} must be between 4 and {MAX_PARTICLES}"),
        ))
    }
}

fn check_particle_steps(steps: Option<u32>) -> Result<(), StepFault> {
    match steps {
        Some(k) if !(1..=MAX_PARTICLE_STEPS).contains(&k) => Err(fault(
            "steps",
            format!("steps = {k} must be between 1 and {MAX_PARTICLE_STEPS}"),
        )),
        _ => Ok(()),
    }
}

fn check_points(name: &'static str, points: &[[f32; 3]], need_one: bool) -> Result<(), StepFault> {
    if need_one && points.is_empty() {
        return Err(fault(name, format!("{name} needs at least one point")));
    }
    if points.len() > MAX_POINTS {
        return Err(fault(
            name,
            format!(
                "{name} has {} points; at most {MAX_POINTS} are allowed",
                points.len()
            ),
        ));
    }
    match points.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
        Some(i) => Err(fault(name, format!("{name}[{i}] is not finite"))),
        None => Ok(()),
    }
}

/// A quaternion `[x, y, z, w]` that turns something: finite and not near zero (it is
/// normalised when used).
fn check_rotation(key: &'static str, shown: &str, q: [f32; 4]) -> Result<(), StepFault> {
    let norm_sq: f32 = q.iter().map(|c| c * c).sum();
    if q.iter().all(|c| c.is_finite()) && norm_sq > 0.25 && norm_sq.is_finite() {
        Ok(())
    } else {
        Err(fault(
            key,
            format!(
                "{shown} = {q:?} is not a rotation (a finite quaternion [x, y, z, w] of length 1)"
            ),
        ))
    }
}

fn check_step(step: &ScriptStep) -> Result<(), StepFault> {
    match step {
        ScriptStep::Tool {
            shape,
            action,
            positions,
            falloff_fu,
            rotation,
            duration_s,
            ..
        } => {
            check_points("positions", positions, true)?;
            if let Some(q) = rotation {
                check_rotation("rotation", "rotation", *q)?;
            }
            seconds("duration_s", *duration_s)?;
            finite("falloff_fu", *falloff_fu)?;
            action
                .validate()
                .map_err(|e| fault("action", format!("action: {}", e.0)))?;
            // Freeform shapes are checked against the library when run.
            if let Ok(shape) = shape.resolve(|_| None) {
                shape
                    .validate()
                    .map_err(|e| fault("shape", format!("shape: {}", e.0)))?;
            }
            Ok(())
        }
        ScriptStep::Preset {
            positions,
            duration_s,
            ..
        } => {
            check_points("positions", positions, true)?;
            seconds("duration_s", *duration_s)
        }
        ScriptStep::Stroke {
            tool,
            shape,
            action,
            falloff_fu,
            path,
            rotations,
            duration_s,
            times_s,
            start_s,
            hover_fu,
            curve,
            pivot,
            ..
        } => {
            check_points("path", path, true)?;
            if !rotations.is_empty() {
                if rotations.len() != path.len() {
                    return Err(fault(
                        "rotations",
                        format!(
                            "rotations has {} entries but path has {} points",
                            rotations.len(),
                            path.len()
                        ),
                    ));
                }
                for (i, q) in rotations.iter().enumerate() {
                    check_rotation("rotations", &format!("rotations[{i}]"), *q)?;
                }
            }
            check_points("curve", curve, false)?;
            if let Some(d) = duration_s {
                seconds("duration_s", *d)?;
                if !times_s.is_empty() {
                    return Err(fault(
                        "duration_s",
                        "duration_s: give either duration_s or times_s, not both",
                    ));
                }
            }
            if !times_s.is_empty() {
                if times_s.len() != path.len() {
                    return Err(fault(
                        "times_s",
                        format!(
                            "times_s has {} entries but path has {} points",
                            times_s.len(),
                            path.len()
                        ),
                    ));
                }
                for (i, t) in times_s.iter().enumerate() {
                    seconds_shown("times_s", &format!("times_s[{i}]"), *t)?;
                    if i > 0 && *t <= times_s[i - 1] {
                        return Err(fault(
                            "times_s",
                            format!("times_s[{i}] = {t} must be after times_s[{}]", i - 1),
                        ));
                    }
                }
            }
            if let Some(t) = start_s
                && !(t.is_finite() && *t >= 0.0 && *t <= f64::from(MAX_SCRIPT_SECONDS))
            {
                return Err(fault(
                    "start_s",
                    format!("start_s = {t} must be between 0 and {MAX_SCRIPT_SECONDS} s"),
                ));
            }
            if !(hover_fu.is_finite() && *hover_fu > 0.0) {
                return Err(fault(
                    "hover_fu",
                    format!("hover_fu = {hover_fu} must be positive"),
                ));
            }
            if let Some(p) = pivot {
                check_points("pivot", std::slice::from_ref(p), true)?;
            }
            match (tool, shape, action) {
                (Some(_), Some(_), _) | (Some(_), _, Some(_)) => Err(fault(
                    "tool",
                    "tool: give either tool (a force tool) or shape and action (a geometric \
                     tool), not both",
                )),
                (Some(tool), None, None) => tool
                    .validate()
                    .map_err(|e| fault("tool", format!("tool: {e}"))),
                (None, Some(_), None) => Err(fault("shape", "shape needs an action")),
                (None, None, Some(_)) => Err(fault("action", "action needs a shape")),
                (None, Some(shape), Some(action)) => {
                    action
                        .validate()
                        .map_err(|e| fault("action", format!("action: {}", e.0)))?;
                    finite("falloff_fu", *falloff_fu)?;
                    if let Ok(shape) = shape.resolve(|_| None) {
                        shape
                            .validate()
                            .map_err(|e| fault("shape", format!("shape: {}", e.0)))?;
                    }
                    Ok(())
                }
                (None, None, None) => Ok(()),
            }
        }
        ScriptStep::Material {
            mass,
            damping,
            stiffness,
            plasticity_per_s,
            yield_density,
            neighbourhood,
        } => {
            if let Some(n) = neighbourhood
                && Neighbourhood::from_count(*n).is_none()
            {
                return Err(fault(
                    "neighbourhood",
                    format!("neighbourhood = {n}: the springs join 6, 18 or 26 neighbours"),
                ));
            }
            for (name, v) in [
                ("mass", mass),
                ("damping", damping),
                ("stiffness", stiffness),
                ("plasticity_per_s", plasticity_per_s),
                ("yield_density", yield_density),
            ] {
                if let Some(v) = v {
                    finite(name, *v)?;
                }
            }
            if mass.is_some_and(|m| m <= 0.0) {
                return Err(fault("mass", "mass must be positive"));
            }
            Ok(())
        }
        ScriptStep::PaintMaterial { .. } => paint_request(step).map(|_| ()),
        ScriptStep::Undo { count } | ScriptStep::Redo { count } if *count > MAX_UNDO_COUNT => {
            Err(fault(
                "count",
                format!(
                    "count = {count} is more than the {MAX_UNDO_COUNT} steps one undo or redo may take"
                ),
            ))
        }
        ScriptStep::Constrain { kind, at, points } => pin_request(*kind, *at, points).map(|_| ()),
        ScriptStep::Unconstrain { index: Some(i) } if *i < 0 || *i >= MAX_CONSTRAINTS as i64 => {
            Err(fault(
                "index",
                format!("index = {i} must be between 0 and {}", MAX_CONSTRAINTS - 1),
            ))
        }
        ScriptStep::Emboss {
            projection,
            depth,
            engrave,
            ..
        } => {
            if !(depth.is_finite() && *depth > 0.0) {
                return Err(fault("depth", format!("depth = {depth} must be positive")));
            }
            crate::tools::EmbossParams {
                projection: projection.projection(),
                depth: *depth,
                engrave: *engrave,
            }
            .validate()
            .map_err(|m| fault("projection", format!("projection: {m}")))
        }
        ScriptStep::Refine { min, max, level } => {
            for (name, corner) in [("min", min), ("max", max)] {
                for v in corner {
                    finite(name, *v)?;
                }
            }
            if (0..3).any(|a| min[a] >= max[a]) {
                return Err(fault(
                    "max",
                    format!("the box {min:?}..{max:?} is empty: max must exceed min on every axis"),
                ));
            }
            if !(1..=crate::field::MAX_DETAIL_LEVEL).contains(level) {
                return Err(fault(
                    "level",
                    format!(
                        "level = {level} must be between 1 and {} (each level halves the knot spacing)",
                        crate::field::MAX_DETAIL_LEVEL
                    ),
                ));
            }
            Ok(())
        }
        ScriptStep::Particles {
            count, steps, out, ..
        } => {
            check_particle_count("count", *count)?;
            check_particle_steps(*steps)?;
            match out {
                Some(path) if path.as_os_str().is_empty() => {
                    Err(fault("out", "out must name a file"))
                }
                _ => Ok(()),
            }
        }
        ScriptStep::Points {
            input,
            pull,
            steps,
            out,
        } => {
            if input.as_os_str().is_empty() {
                return Err(fault("input", "input must name a point cloud file"));
            }
            if out
                .extension()
                .and_then(|e| e.to_str())
                .map(str::to_ascii_lowercase)
                .as_deref()
                != Some("ply")
            {
                return Err(fault(
                    "out",
                    format!("out = {:?} must end in .ply", out.display().to_string()),
                ));
            }
            check_points("pull", pull, false)?;
            match steps {
                Some(k) if !(1..=MAX_POINTS_PULL_STEPS).contains(k) => Err(fault(
                    "steps",
                    format!("steps = {k} must be between 1 and {MAX_POINTS_PULL_STEPS}"),
                )),
                _ => Ok(()),
            }
        }
        ScriptStep::Rbf {
            out,
            particles,
            offset,
            max_centres,
            steps,
            ..
        } => {
            if out.extension().and_then(|e| e.to_str()) != Some("rbf") {
                return Err(fault(
                    "out",
                    format!("out = {:?} must end in .rbf", out.display().to_string()),
                ));
            }
            if let Some(n) = particles {
                check_particle_count("particles", *n)?;
            }
            check_particle_steps(*steps)?;
            if let Some(d) = offset
                && !(d.is_finite() && *d > 0.0)
            {
                return Err(fault("offset", format!("offset = {d} must be positive")));
            }
            if let Some(m) = max_centres
                && !(4..=MAX_RBF_CENTRES).contains(m)
            {
                return Err(fault(
                    "max_centres",
                    format!("max_centres = {m} must be between 4 and {MAX_RBF_CENTRES}"),
                ));
            }
            Ok(())
        }
        ScriptStep::CompactRbf { particles } => {
            let (lo, hi) = (MIN_COMPACT_PARTICLES, MAX_COMPACT_PARTICLES);
            if *particles == 0 || (lo..=hi).contains(&(*particles as usize)) {
                Ok(())
            } else {
                Err(fault(
                    "particles",
                    format!("particles = {particles} must be 0 (off) or between {lo} and {hi}"),
                ))
            }
        }
        ScriptStep::MakeTool {
            name,
            selection,
            action,
            falloff_fu,
        } => {
            if name.is_empty() || name.len() > super::MAX_TOOL_NAME_BYTES {
                return Err(fault(
                    "name",
                    format!(
                        "name must be 1 to {} bytes, got {}",
                        super::MAX_TOOL_NAME_BYTES,
                        name.len()
                    ),
                ));
            }
            match selection {
                SelectionSpec::Box { min, max } => {
                    check_points("selection", &[*min, *max], true)?;
                    if (0..3).any(|a| min[a] >= max[a]) {
                        return Err(fault(
                            "selection",
                            format!(
                                "selection: the box {min:?}..{max:?} is empty: max must exceed \
                                 min on every axis"
                            ),
                        ));
                    }
                }
                SelectionSpec::Ball { centre, radius_fu } => {
                    check_points("selection", &[*centre], true)?;
                    if !(radius_fu.is_finite() && *radius_fu > 0.0) {
                        return Err(fault(
                            "selection",
                            format!("selection: radius_fu = {radius_fu} must be positive"),
                        ));
                    }
                }
            }
            finite("falloff_fu", *falloff_fu)?;
            action
                .validate()
                .map_err(|e| fault("action", format!("action: {}", e.0)))
        }
        ScriptStep::Csg {
            with,
            shape,
            position,
            falloff_fu,
            ..
        } => match (with, shape, position) {
            (Some(_), None, None) => Ok(()),
            (None, Some(_), Some(p)) => {
                check_points("position", &[*p], true)?;
                if falloff_fu.is_finite() && *falloff_fu > 0.0 {
                    Ok(())
                } else {
                    Err(fault(
                        "falloff_fu",
                        format!("falloff_fu = {falloff_fu} must be positive for a solid"),
                    ))
                }
            }
            (None, Some(_), None) => Err(fault(
                "position",
                "a csg step with a solid `shape` needs its `position`",
            )),
            _ => Err(fault(
                "with",
                "a csg step takes either `with` (a session file) or `shape` and `position` \
                 (a solid), not both and not neither",
            )),
        },
        ScriptStep::Unconstrain { .. }
        | ScriptStep::Undo { .. }
        | ScriptStep::Redo { .. }
        | ScriptStep::Save { .. } => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_compact_rbf_step_takes_0_or_a_count_one_solve_holds() {
        let step =
            |n: u32| format!("version = 1\n\n[[step]]\ndo = \"compact_rbf\"\nparticles = {n}\n");
        for n in [0, 8, 400, 1000] {
            let script = parse_script(&step(n), "c.toml").unwrap();
            assert_eq!(script.steps, vec![ScriptStep::CompactRbf { particles: n }]);
        }
        for n in [3, 1001] {
            let shown = parse_script(&step(n), "c.toml").unwrap_err().to_string();
            assert!(
                shown.contains(&format!(
                    "particles = {n} must be 0 (off) or between 8 and 1000"
                )),
                "{shown}"
            );
        }
    }

    #[test]
    fn unbounded_values_are_refused_with_their_line() {
        let stroke = |field: &str| {
            format!("version = 1\n\n[[step]]\ndo = \"stroke\"\npath = [[0.1, 0.2, 0.3]]\n{field}\n")
        };
        let many: Vec<String> = (0..=MAX_POINTS).map(|_| "[0.1, 0.2, 0.3]".into()).collect();
        let cases = [
            (
                "version = 1\n\n[[step]]\ndo = \"undo\"\ncount = 4294967295\n".to_owned(),
                "count = 4294967295",
                5,
            ),
            (stroke("duration_s = 1e9"), "duration_s = 1000000000", 6),
            (stroke("start_s = 1e30"), "start_s = 1", 6),
            (
                format!(
                    "version = 1\n\n[[step]]\ndo = \"tool\"\nshape = {{ kind = \"sphere\", radius_fu = 0.2 }}\naction = {{ kind = \"add\", deposit_rate_per_s = 1.0 }}\npositions = [{}]\n",
                    many.join(", ")
                ),
                "positions has 10001 points",
                7,
            ),
        ];
        for (text, expected, line) in cases {
            let err = parse_script(&text, "bomb.toml").unwrap_err();
            let shown = err.to_string();
            assert!(shown.contains(expected), "{shown}");
            assert_eq!(err.line, Some(line), "{shown}");
            assert!(shown.contains("bomb.toml"), "{shown}");
        }
    }

    #[test]
    fn a_device_or_an_oversized_file_is_not_read_as_a_script() {
        let err = load_script(std::path::Path::new("/dev/zero")).unwrap_err();
        assert!(err.to_string().contains("not a regular file"), "{err}");
        let dir = tempfile::tempdir().unwrap();
        let big = dir.path().join("big.toml");
        let file = std::fs::File::create(&big).unwrap();
        file.set_len(MAX_SCRIPT_BYTES + 1).unwrap();
        let err = load_script(&big).unwrap_err();
        assert!(err.to_string().contains("more than the"), "{err}");
    }

    const EXAMPLE: &str = r#"
version = 1

[[step]]
do = "tool"
shape = { kind = "sphere", radius_fu = 0.2 }
action = { kind = "add", deposit_rate_per_s = 4.0 }
positions = [[0.5, 0.5, 0.5], [0.6, 0.5, 0.5]]
duration_s = 0.5

[[step]]
do = "tool"
shape = { kind = "ellipsoid", radii_fu = [0.1, 0.2, 0.1] }
action = { kind = "stamp", s = 0.5, m = 0.15, r = 0.25, k = -2.0, n = 0.3 }
positions = [[0.5, 0.7, 0.5]]
rotation = [0.0, 0.0, 0.0, 1.0]

[[step]]
do = "tool"
shape = { kind = "capsule", radius_fu = 0.05, half_height_fu = 0.1 }
action = { kind = "contact", alpha = -2.0 }
positions = [[0.5, 0.7, 0.5]]

[[step]]
do = "stroke"
tool = { kind = "area", beta = "gaussian", radius_fu = 0.05, tracks = 5, gain = 1e6 }
path = [[0.9, 0.5, 0.5], [1.0, 0.5, 0.5]]
duration_s = 1.0

[[step]]
do = "material"
stiffness = 500.0
plasticity_per_s = 4.0

[[step]]
do = "csg"
op = "difference"
with = "other.dclay"

[[step]]
do = "undo"
count = 2

[[step]]
do = "redo"

[[step]]
do = "save"
path = "out.dclay"
"#;

    #[test]
    fn the_example_parses_into_every_kind_of_step() {
        let s = parse_script(EXAMPLE, "ex.toml").unwrap();
        assert_eq!(s.steps.len(), 9);
        assert!(matches!(
            s.steps[1],
            ScriptStep::Tool {
                action: ToolAction::Stamp(_),
                ..
            }
        ));
        assert_eq!(s.steps[6], ScriptStep::Undo { count: 2 });
        assert_eq!(s.steps[7], ScriptStep::Redo { count: 1 });
        let m = s.steps[4].updated_material(Material::ELASTIC);
        assert_eq!((m.stiffness, m.plasticity_per_s, m.mass), (500.0, 4.0, 1.0));
        // Round trip through the serde types (where each step is written is not carried).
        let text = toml::to_string(&s).unwrap();
        let again = parse_script(&text, "again").unwrap();
        assert_eq!(again.steps.len(), again.step_lines.len());
        assert_eq!(
            Script {
                step_lines: s.step_lines.clone(),
                ..again
            },
            s
        );
    }

    #[test]
    fn syntax_and_type_errors_name_line_and_field() {
        let bad = "version = 1\n\n[[step]]\ndo = \"tool\"\nshape = { kind = \"sphere\", radius = 0.2 }\naction = { kind = \"remove\" }\npositions = [[0, 0, 0]]\n";
        let e = parse_script(bad, "bad.toml").unwrap_err();
        // The parser points at the step's header; the error names the field's own line.
        assert_eq!(e.line, Some(5), "{e}");
        assert!(e.message.contains("`radius`"), "{e}");
        assert!(e.to_string().starts_with("bad.toml:5"), "{e}");
        let bad = "version = 1\n[[step]]\ndo = \"undo\"\nspeed = 3\n";
        let e = parse_script(bad, "u.toml").unwrap_err();
        assert_eq!(e.line, Some(4), "{e}");
        let e = parse_script("version = \"one\"\n", "v.toml").unwrap_err();
        assert_eq!(e.line, Some(1), "{e}");

        let bad = "version = 1\n[[step]]\ndo = \"teleport\"\n";
        let e = parse_script(bad, "x").unwrap_err();
        assert!(e.message.contains("teleport"), "{e}");
        assert!(e.line.is_some());
    }

    #[test]
    fn lines_come_from_the_parser_not_from_the_text_or_the_message() {
        // A header written with spaces, a comment that looks like one, and a value that
        // looks like the key: only the parser's spans find the right line.
        let text = "version = 1\n# [[step]] duration_s = 5\n[[ step ]]\ndo = \"stroke\"\npath = [[1, 1, 1]]\nduration_s = -2\n";
        let e = parse_script(text, "x").unwrap_err();
        assert_eq!((e.step, e.line), (Some(1), Some(6)), "{e}");
        let text = "version = 1\n[[step]]\ndo = \"save\"\npath = \"a\"\n[[step]]\ndo = \"undo\"\ncount = 4000000000\n";
        let e = parse_script(text, "x").unwrap_err();
        assert_eq!((e.step, e.line), (Some(2), Some(7)), "{e}");
        let text = "version = 1\n[autosave]\nevery_s = -1.0\n";
        assert_eq!(parse_script(text, "x").unwrap_err().line, Some(3));
    }

    #[test]
    fn semantic_errors_name_the_step_and_its_line() {
        let bad = "version = 1\n\n[[step]]\ndo = \"undo\"\n\n[[step]]\ndo = \"tool\"\nshape = { kind = \"sphere\", radius_fu = -1.0 }\naction = { kind = \"remove\" }\npositions = [[0, 0, 0]]\n";
        let e = parse_script(bad, "x").unwrap_err();
        assert_eq!((e.step, e.line), (Some(2), Some(8)), "{e}");
        assert!(e.message.contains("radius_fu"), "{e}");
        let e = parse_script("version = 7\n", "x").unwrap_err();
        assert!(e.message.contains("version = 7"), "{e}");
        let bad = "version = 1\n[[step]]\ndo = \"stroke\"\ntool = { kind = \"chisel\", depth_fu = 0.0, radius_fu = 0.1, gain = 1.0 }\npath = []\nduration_s = 1.0\n";
        let e = parse_script(bad, "x").unwrap_err();
        assert!(e.message.contains("path"), "{e}");
        assert_eq!(e.line, Some(5), "{e}");
        // A material a session could not load back is refused here already.
        let bad = "version = 1\n[[step]]\ndo = \"material\"\ndamping = -2.0\n";
        let e = parse_script(bad, "x").unwrap_err();
        assert!(
            e.message
                .contains("damping = -2 must be finite and non-negative"),
            "{e}"
        );
    }

    #[test]
    fn strokes_take_a_force_or_a_geometric_tool_and_optional_timing() {
        let good = r#"
version = 1
seconds = 2.5
[clay]
shape = "sphere"
resolution = 16
[autosave]
every_strokes = 1

[[step]]
do = "stroke"
path = [[1, 1, 1], [1.2, 1, 1]]
times_s = [0.0, 0.4]
buttons = 1

[[step]]
do = "stroke"
shape = { kind = "sphere", radius_fu = 0.1 }
action = { kind = "remove" }
path = [[1, 1, 1]]
start_s = 3.0
"#;
        let s = parse_script(good, "g.toml").unwrap();
        assert_eq!(s.clay.as_ref().unwrap().shape, ClayShape::Sphere);
        assert_eq!(s.autosave.unwrap().every_strokes, 1);
        assert_eq!(s.seconds, Some(2.5));
        assert_eq!(s.step_lines, vec![10, 16], "each step's table starts there");
        let text = toml::to_string(&s).unwrap();
        assert_eq!(
            Script {
                step_lines: s.step_lines.clone(),
                ..parse_script(&text, "again").unwrap()
            },
            s
        );

        let stroke = |body: &str| format!("version = 1\n[[step]]\ndo = \"stroke\"\n{body}");
        for (body, field, line) in [
            ("path = [[1, 1, 1]]\nduration_s = -2\n", "duration_s", 5),
            (
                "path = [[1, 1, 1], [2, 1, 1]]\ntimes_s = [0.0, 0.0]\n",
                "times_s[1]",
                5,
            ),
            ("path = [[1, 1, 1]]\ntimes_s = [0.0, 1.0]\n", "times_s", 5),
            ("path = [[1, 1, 1]]\nhover_m = 0\n", "hover_fu", 5),
            (
                "tool = { kind = \"push\", radius_fu = -1 }\npath = [[1, 1, 1]]\n",
                "radius_fu",
                4,
            ),
            (
                "tool = { kind = \"grab\", gain = 1 }\nshape = { kind = \"sphere\", radius_fu = 0.1 }\npath = [[1, 1, 1]]\n",
                "not both",
                4,
            ),
            (
                "shape = { kind = \"sphere\", radius_fu = 0.1 }\npath = [[1, 1, 1]]\n",
                "action",
                4,
            ),
        ] {
            let e = parse_script(&stroke(body), "s.toml").unwrap_err();
            assert!(e.message.contains(field), "{body}: {e}");
            assert_eq!(e.line, Some(line), "{body}: {e}");
        }
        let e = parse_script("version = 1\n[clay]\nresolution = 200\n", "c.toml").unwrap_err();
        assert_eq!(e.line, Some(3), "{e}");
        assert!(e.message.contains("clay.resolution"), "{e}");
    }

    #[test]
    fn constrain_keys_must_match_their_kind() {
        let step = |keys: &str| format!("version = 1\n\n[[step]]\ndo = \"constrain\"\n{keys}\n");
        let ok = [
            "kind = \"point\"\nat = [1.0, 2.0, 3.0]",
            "kind = \"normal\"\nat = [1.0, 2.0, 3.0]",
            "kind = \"curve\"\npoints = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]",
        ];
        for keys in ok {
            parse_script(&step(keys), "pins.toml").unwrap_or_else(|e| panic!("{keys}: {e}"));
        }
        parse_script("version = 1\n\n[[step]]\ndo = \"unconstrain\"\n", "u.toml").unwrap();
        parse_script(
            "version = 1\n\n[[step]]\ndo = \"unconstrain\"\nindex = 2\n",
            "u.toml",
        )
        .unwrap();
        let bad = [
            ("kind = \"point\"", "needs at"),
            ("kind = \"curve\"\nat = [1.0, 2.0, 3.0]", "not at"),
            ("kind = \"curve\"\npoints = [[0.0, 0.0, 0.0]]", "at least 2"),
            ("kind = \"normal\"\nat = [1.0, 2.0, nan]", "not finite"),
            ("kind = \"edge\"\nat = [1.0, 2.0, 3.0]", "edge"),
        ];
        for (keys, expected) in bad {
            let err = parse_script(&step(keys), "pins.toml").unwrap_err();
            let shown = err.to_string();
            assert!(
                shown.contains(expected) && shown.contains("pins.toml"),
                "{keys}: {shown}"
            );
        }
        let err = parse_script(
            "version = 1\n\n[[step]]\ndo = \"unconstrain\"\nindex = -1\n",
            "u.toml",
        )
        .unwrap_err();
        assert_eq!(err.line, Some(5), "{err}");
    }

    #[test]
    fn material_steps_take_a_neighbourhood_and_paints_a_ball_or_a_box() {
        let step = |keys: &str| format!("version = 1\n\n[[step]]\n{keys}\n");
        let s = parse_script(&step("do = \"material\"\nneighbourhood = 26"), "m.toml").unwrap();
        let m = s.steps[0].updated_material(Material::PLASTIC);
        assert_eq!(m.neighbourhood, Neighbourhood::TwentySix);
        assert_eq!(m.stiffness, Material::PLASTIC.stiffness);
        let err =
            parse_script(&step("do = \"material\"\nneighbourhood = 12"), "m.toml").unwrap_err();
        assert!(
            err.to_string().contains("6, 18 or 26") && err.line == Some(5),
            "{err}"
        );

        let paint = |keys: &str| step(&format!("do = \"paint_material\"\n{keys}"));
        let s = parse_script(
            &paint("centre = [1.0, 1.5, 1.0]\nradius_fu = 0.2\nstiffness = 5000.0"),
            "p.toml",
        )
        .unwrap();
        assert_eq!(
            paint_request(&s.steps[0]).unwrap(),
            Some(MaterialPaint {
                region: PaintRegion::Sphere {
                    centre: Vec3::new(1.0, 1.5, 1.0),
                    radius_fu: 0.2
                },
                mass: None,
                damping: None,
                stiffness: Some(5000.0),
                plasticity_per_s: None,
            })
        );
        let s = parse_script(
            &paint("min = [0.0, 0.0, 0.0]\nmax = [1.0, 2.0, 3.0]\nmass = 4.0\ndamping = 0.0"),
            "p.toml",
        )
        .unwrap();
        let p = paint_request(&s.steps[0]).unwrap().unwrap();
        assert_eq!(
            (p.mass, p.damping, p.stiffness, p.plasticity_per_s),
            (Some(4.0), Some(0.0), None, None)
        );
        let s = parse_script(
            &paint("min = [0.0, 0.0, 0.0]\nmax = [1.0, 2.0, 3.0]\nplasticity_per_s = 0.0"),
            "p.toml",
        )
        .unwrap();
        let p = paint_request(&s.steps[0]).unwrap().unwrap();
        assert_eq!((p.mass, p.plasticity_per_s), (None, Some(0.0)));
        assert!(matches!(p.region, PaintRegion::Box { .. }));
        // Round trip through the serde types.
        let text = toml::to_string(&s).unwrap();
        assert_eq!(parse_script(&text, "again").unwrap(), s);
        let bad = [
            ("stiffness = 5.0", "needs a ball"),
            (
                "centre = [1.0, 1.0, 1.0]\nstiffness = 5.0",
                "also needs radius_fu",
            ),
            (
                "centre = [1.0, 1.0, 1.0]\nradius_fu = 0.2\nmin = [0.0, 0.0, 0.0]\nmax = [1.0, 1.0, 1.0]\nmass = 1.0",
                "not both",
            ),
            (
                "centre = [1.0, 1.0, 1.0]\nradius_fu = 0.0\nmass = 1.0",
                "radius_fu = 0",
            ),
            (
                "min = [0.0, 2.0, 0.0]\nmax = [1.0, 1.0, 1.0]\nmass = 1.0",
                "empty",
            ),
            (
                "centre = [1.0, 1.0, 1.0]\nradius_fu = 0.2\nmass = 0.0",
                "mass must be positive",
            ),
            (
                "centre = [1.0, 1.0, 1.0]\nradius_fu = 0.2\nstiffness = -1.0",
                "stiffness = -1",
            ),
            (
                "centre = [1.0, 1.0, 1.0]\nradius_fu = 0.2\nplasticity_per_s = -2.0",
                "plasticity_per_s = -2 must be finite and non-negative",
            ),
            (
                "centre = [1.0, 1.0, 1.0]\nradius_fu = 0.2",
                "at least one of",
            ),
            (
                "centre = [1.0, nan, 1.0]\nradius_fu = 0.2\nmass = 1.0",
                "not finite",
            ),
        ];
        for (keys, expected) in bad {
            let err = parse_script(&paint(keys), "paint.toml").unwrap_err();
            let shown = err.to_string();
            assert!(
                shown.contains(expected) && shown.contains("paint.toml") && err.line.is_some(),
                "{keys}: {shown}"
            );
        }
    }

    #[test]
    fn old_metre_keys_read_as_field_unit_keys_with_a_note_per_key() {
        let new = "version = 1\n\n[[step]]\ndo = \"tool\"\nshape = { kind = \"capsule\", radius_fu = 0.05, half_height_fu = 0.1 }\naction = { kind = \"smooth\", rate_per_s = 1.0, kernel_fu = 0.1 }\npositions = [[0, 0, 0]]\nfalloff_fu = 0.02\n\n[[step]]\ndo = \"stroke\"\ntool = { kind = \"chisel\", depth_fu = 0.03, radius_fu = 0.05, gain = 1e6 }\npath = [[1, 1, 1]]\nhover_fu = 0.2\n";
        let old = new.replace("_fu", "_m");
        let read_new = parse_script(new, "new.toml").unwrap();
        let read_old = parse_script(&old, "old.toml").unwrap();
        assert!(read_new.deprecated.is_empty());
        assert_eq!(read_old.steps, read_new.steps);
        let noted: Vec<(usize, &str, &str)> = read_old
            .deprecated
            .iter()
            .map(|d| (d.line, d.key, d.replacement))
            .collect();
        assert_eq!(
            noted,
            [
                (5, "radius_m", "radius_fu"),
                (5, "half_height_m", "half_height_fu"),
                (6, "kernel_m", "kernel_fu"),
                (8, "falloff_m", "falloff_fu"),
                (12, "depth_m", "depth_fu"),
                (12, "radius_m", "radius_fu"),
                (14, "hover_m", "hover_fu"),
            ]
        );
        let shown = read_old.deprecated[0].to_string();
        assert!(
            shown.starts_with("old.toml:5: `radius_m` is deprecated")
                && shown.contains("`radius_fu`"),
            "{shown}"
        );
        // A fault in an old key still names its line.
        let bad = old.replace("depth_m = 0.03", "depth_m = -1");
        let e = parse_script(&bad, "old.toml").unwrap_err();
        assert_eq!(e.line, Some(12), "{e}");
    }
}
