//! The script's schema: the starting clay, autosave, the tool, force-tool, projection, CSG and
//! selection specs, and the steps (serde types), with the requests they make of the engine.

use super::*;

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
    /// A round brush: a sphere, or with `curve` a brush whose depth from centre to edge
    /// follows a falloff curve (`"smooth"`, `"sphere"`, `"root"`, `"sharp"`, `"linear"`,
    /// `"constant"` or `{ custom = [[u, depth], …] }`), hanging along the tool's local z.
    Sphere {
        #[serde(alias = "radius_m")]
        radius_fu: f32,
        #[serde(default, skip_serializing_if = "FalloffCurve::is_sphere")]
        curve: FalloffCurve,
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

pub(super) fn unit_scale() -> [f32; 3] {
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

pub(super) fn default_beta() -> BetaSpec {
    BetaSpec::Gaussian
}

pub(super) fn default_push_radius() -> f32 {
    0.25
}

pub(super) fn default_push_gain() -> f32 {
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
    pub fn validate(&self) -> Result<(), ForceToolError> {
        match (self, self.force_tool()) {
            (_, Some(tool)) => tool.validate(),
            (
                Self::Push {
                    radius_fu, gain, ..
                },
                None,
            ) => {
                for (name, v) in [("radius_fu", *radius_fu), ("gain", *gain)] {
                    if !(v.is_finite() && v > 0.0) {
                        return Err(ForceToolError(format!(
                            "{name} must be positive and finite, got {v}"
                        )));
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
                size_fu: size,
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
                height_fu: height,
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

pub(super) fn default_falloff() -> f32 {
    0.05
}

pub(super) fn one() -> u32 {
    1
}

pub(super) fn default_hover() -> f32 {
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

pub(super) fn default_union() -> ToolAction {
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
    /// Paint the freeze mask: one dab of a soft round brush at each of `positions` (field
    /// coordinates), `strength` (0 to 1, default 1) over the inner half of `radius_fu`, fading
    /// to nothing at it; `free = true` unfreezes instead. Held clay moves under no tool and
    /// not in the dynamics. One undo step; takes no script time.
    Mask {
        positions: Vec<[f32; 3]>,
        radius_fu: f32,
        #[serde(default = "full_strength")]
        strength: f32,
        #[serde(default)]
        free: bool,
    },
    /// Invert the freeze mask (held clay becomes free, free clay held). One undo step.
    MaskInvert,
    /// Clear the freeze mask (every part free). One undo step.
    MaskClear,
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
    /// Switch automatic detail (absent keys keep their setting): `automatic`, whether a brush
    /// narrower than three knot spans of the patch under it adds a detail patch under itself
    /// first, at the level its width needs, and wiped detail folds back (on by default);
    /// `force_tools`, whether the push and the force strokes follow the same rule while
    /// `automatic` is on (off by default: on a detail patch painted stiffness and mass act
    /// weaker than on the base). Takes no script time; not an undo step.
    Detail {
        #[serde(default, skip_serializing_if = "Option::is_none")]
        automatic: Option<bool>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        force_tools: Option<bool>,
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

/// Default mask strength: a dab freezes fully.
fn full_strength() -> f32 {
    1.0
}

/// The mask edit a `mask`, `mask_invert` or `mask_clear` step asks for.
///
/// # Errors
/// When a position is not finite, there is none or too many, or the brush's radius or
/// strength is out of range.
pub fn mask_request(step: &ScriptStep) -> Result<Option<MaskEdit>, StepFault> {
    match step {
        ScriptStep::Mask {
            positions,
            radius_fu,
            strength,
            free,
        } => {
            check_points("positions", positions, true)?;
            let brush = MaskBrush {
                radius_fu: *radius_fu,
                strength: *strength,
                mode: if *free {
                    MaskMode::Free
                } else {
                    MaskMode::Freeze
                },
            };
            brush.validate().map_err(|e| match e {
                MaskError::Strength { .. } => fault("strength", e.to_string()),
                _ => fault("radius_fu", e.to_string()),
            })?;
            Ok(Some(MaskEdit::Paint {
                brush,
                centres_fu: positions.iter().map(|p| Vec3::from_array(*p)).collect(),
            }))
        }
        ScriptStep::MaskInvert => Ok(Some(MaskEdit::Invert)),
        ScriptStep::MaskClear => Ok(Some(MaskEdit::Clear)),
        _ => Ok(None),
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

/// Why a `freeform` shape's preset could not be used.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum PresetError {
    /// The library has no tool of this name.
    #[error("no tool preset named {name:?}")]
    Missing {
        /// The name asked for.
        name: String,
    },
    /// The library's tool of this name is not a freeform shape.
    #[error("tool preset {name:?} is not a freeform shape")]
    NotFreeform {
        /// The name asked for.
        name: String,
    },
}

impl ShapeSpec {
    /// The tool shape; `freeform` looks up `preset` with `library` (name → shape).
    ///
    /// # Errors
    /// When the preset does not exist or is not a freeform shape.
    pub fn resolve<'a>(
        &self,
        library: impl Fn(&str) -> Option<&'a ToolShape>,
    ) -> Result<ToolShape, PresetError> {
        Ok(match self {
            Self::Sphere { radius_fu, curve } => ToolShape::round(*radius_fu, curve.clone()),
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
                Some(_) => {
                    return Err(PresetError::NotFreeform {
                        name: preset.clone(),
                    });
                }
                None => {
                    return Err(PresetError::Missing {
                        name: preset.clone(),
                    });
                }
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
    /// The step's `do = …` name, as a script writes it.
    #[must_use]
    pub fn name(&self) -> &'static str {
        match self {
            ScriptStep::Tool { .. } => "tool",
            ScriptStep::Preset { .. } => "preset",
            ScriptStep::Stroke { .. } => "stroke",
            ScriptStep::Material { .. } => "material",
            ScriptStep::PaintMaterial { .. } => "paint_material",
            ScriptStep::Mask { .. } => "mask",
            ScriptStep::MaskInvert => "mask_invert",
            ScriptStep::MaskClear => "mask_clear",
            ScriptStep::Csg { .. } => "csg",
            ScriptStep::MakeTool { .. } => "make_tool",
            ScriptStep::Undo { .. } => "undo",
            ScriptStep::Redo { .. } => "redo",
            ScriptStep::Save { .. } => "save",
            ScriptStep::Emboss { .. } => "emboss",
            ScriptStep::Constrain { .. } => "constrain",
            ScriptStep::Unconstrain { .. } => "unconstrain",
            ScriptStep::Refine { .. } => "refine",
            ScriptStep::Detail { .. } => "detail",
            ScriptStep::Particles { .. } => "particles",
            ScriptStep::Rbf { .. } => "rbf",
            ScriptStep::CompactRbf { .. } => "compact_rbf",
            ScriptStep::Points { .. } => "points",
        }
    }

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
