//! A script ([`dynaclay_core::io::Script`], the one script format) laid out as a run: the simulated
//! hand's trajectory for its `stroke` steps, and the commands for every other step with the
//! script time at which each is sent.
//!
//! # Timeline
//!
//! Steps run in file order against one script clock (seconds; the device's clock during a
//! run, so a lockstep run is exactly reproducible):
//!
//! - A step that is not a stroke (`tool`, `preset`, `csg`, `material`, `paint_material`,
//!   `constrain`, `unconstrain`, `undo`, `redo`, `save`, `particles`, `rbf`, `points`) takes
//!   no script time. It is sent when the clock reaches the end of everything
//!   before it — after the previous stroke has ended with the hand back at hover — and the
//!   simulation applies it between two steps, in file order, before the next stroke starts.
//!   Tool steps dwell for their own `duration_s` of tool time, not script time.
//! - A stroke starts at `start_s` if given (it must leave [`SETTLE_S`] after the previous
//!   step ends), else [`TRAVEL_S`] after it. The hand moves to `hover_fu` above the path's first
//!   point by then, descends in [`APPROACH_S`], follows the path (evenly over `duration_s`, or
//!   at `times_s`), lifts in [`APPROACH_S`] and the stroke ends there. A stroke's tool is
//!   selected when the previous step ends (a change of tool ends any settling stroke first).
//! - Buttons: `buttons` (default 1, the stroke button) are held along the path. With the
//!   contact push they are held from the start of the descent, so the contact starts where
//!   the tip enters the clay; with a force or geometric tool from the first path point, so
//!   nothing is grabbed or deposited on the way down.
//! - A stroke's undo step is committed when it ends, or — while the clay it pushed still
//!   moves — when the next stroke or clay-editing step starts. So `undo` right after a stroke
//!   undoes that stroke.

use std::path::Path;

use dynaclay_devices::{Interpolation, Trajectory, Waypoint};
use glam::{Quat, Vec3};

use super::command::{PushTool, ToolChoice};
use super::tool_library::LibraryTool;
use super::workspace::WorkspaceMap;
use dynaclay_core::dynamics::Material;
use dynaclay_core::io::{
    ClaySpec, CsgSpec, ForceToolSpec, Script, ScriptError, ScriptStep, ShapeSpec, StepTool,
    ToolPreset, load_session, mask_request, paint_request, parse_script, pin_request, poses,
};
use dynaclay_core::tools::{
    Clay, EmbossParams, GeometricTool, PinRequest, Relief, ToolAction, ToolPose, resample_stroke,
    solid_clay,
};

/// Time the hand takes from hover to the path and back, seconds.
pub const APPROACH_S: f64 = 0.3;
/// Default time between the end of the previous step and a stroke's start, seconds.
pub const TRAVEL_S: f64 = 0.3;
/// Least time between the end of the previous step and a stroke's start, seconds.
pub const SETTLE_S: f64 = 0.05;

/// The script used when none is given: one push along the top of the default block.
pub const DEFAULT_SCRIPT: &str = r#"
version = 1
seconds = 3.0

[clay]
shape = "block"
resolution = 24

[[step]]
do = "stroke"
tool = { kind = "push", beta = "gaussian", radius_fu = 0.25, gain = 2e6 }
start_s = 0.2
path = [[0.85, 1.55, 1.15], [1.15, 1.5, 1.15], [1.45, 1.55, 1.15]]
duration_s = 1.6
hover_fu = 0.35
"#;

/// The sampling and fitting a `particles` or `rbf` step asks for (defaults where absent).
fn export_options(
    particles: usize,
    steps: Option<u32>,
    seed: Option<u64>,
    offset: Option<f32>,
    max_centres: Option<u32>,
) -> dynaclay_import::rbf::ExportOptions {
    let d = dynaclay_import::rbf::ExportOptions::default();
    dynaclay_import::rbf::ExportOptions {
        particles,
        steps: steps.map_or(d.steps, |k| k as usize),
        seed: seed.unwrap_or(d.seed),
        offset: offset.map(f64::from),
        max_centres: max_centres.map_or(d.max_centres, |m| m as usize),
    }
}

/// A stroke asked to start before the previous step has settled.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
#[error(
    "start_s = {start_s} is too early: the previous step ends at {previous_end_s:.3} s and a \
     stroke needs {SETTLE_S} s after it"
)]
struct StartTooEarly {
    /// The stroke's `start_s`, script seconds.
    start_s: f64,
    /// When the previous step ends, script seconds.
    previous_end_s: f64,
}

/// When a stroke starts: at `start_s` (at least [`SETTLE_S`] after `clock`, the end of the
/// previous step) or [`TRAVEL_S`] after `clock`.
fn stroke_start(start_s: Option<f64>, clock: f64) -> Result<f64, StartTooEarly> {
    match start_s {
        Some(s) if s < clock + SETTLE_S => Err(StartTooEarly {
            start_s: s,
            previous_end_s: clock,
        }),
        Some(s) => Ok(s),
        None => Ok(clock + TRAVEL_S),
    }
}

/// When the tip reaches each point of a stroke's path, seconds from the path's start:
/// `times_s` if given, else evenly over `duration_s` (1 s by default).
fn path_times(path: &[[f32; 3]], duration_s: Option<f32>, times_s: &[f32]) -> Vec<f64> {
    if !times_s.is_empty() {
        return times_s.iter().map(|t| f64::from(*t)).collect();
    }
    let d = f64::from(duration_s.unwrap_or(1.0));
    let k = path.len();
    (0..k)
        .map(|i| {
            if k > 1 {
                d * i as f64 / (k - 1) as f64
            } else {
                d
            }
        })
        .collect()
}

/// The built-in default script.
#[must_use]
pub fn builtin_script() -> Script {
    parse_script(DEFAULT_SCRIPT, "<built-in>")
        .unwrap_or_else(|e| unreachable!("the built-in script is valid: {e}"))
}

/// What a non-stroke step does, resolved (tool presets looked up, CSG operands loaded).
#[derive(Clone, Debug, PartialEq)]
pub enum PlannedAction {
    /// Hold this tool for the following strokes.
    SetTool(ToolChoice),
    /// Use this material from now on.
    SetMaterial(Material),
    /// Switch automatic detail under brushes and under force tools (`None` keeps a setting).
    SetAutoDetail {
        /// Under brushes (and folding wiped detail back).
        automatic: Option<bool>,
        /// Under the push and the force strokes too.
        force_tools: Option<bool>,
    },
    /// Paint mass, damping, stiffness or plastic drift rate into a region.
    PaintMaterial(dynaclay_core::dynamics::MaterialPaint),
    /// Paint, invert or clear the freeze mask.
    Mask(dynaclay_core::tools::MaskEdit),
    /// A geometric tool step.
    ApplyTool {
        tool: GeometricTool,
        poses: Vec<ToolPose>,
        duration_s: f32,
        patch: u16,
    },
    /// Make a freeform tool of the clay inside a selection and store it in the library.
    MakeTool {
        name: String,
        selection: dynaclay_core::tools::Selection,
        action: ToolAction,
        falloff_fu: f32,
    },
    /// A geometric tool step with a tool an earlier `make_tool` step made (looked up when it
    /// runs).
    ApplyLibraryTool {
        tool: super::LibraryTool,
        poses: Vec<ToolPose>,
        duration_s: f32,
        patch: u16,
    },
    /// Hold a tool an earlier `make_tool` step made for the following strokes.
    SetLibraryTool(super::LibraryTool),
    /// CSG with a loaded clay.
    Csg {
        op: ToolAction,
        other: Box<Clay>,
        patch: u16,
    },
    /// Undo this many steps.
    Undo(u32),
    /// Redo this many steps.
    Redo(u32),
    /// Save the session to this path (already joined to the script's folder).
    Save(std::path::PathBuf),
    /// Emboss or engrave a loaded image.
    Emboss {
        relief: std::sync::Arc<Relief>,
        params: EmbossParams,
        patch: u16,
    },
    /// Add a detail patch over a box at a level.
    Refine {
        lo: glam::Vec3,
        hi: glam::Vec3,
        level: u32,
    },
    /// Pin a place on the clay.
    Constrain(PinRequest),
    /// Remove one pin, or all.
    Unconstrain(Option<usize>),
    /// Copy the clay and settle particles on it (beside the engine); write them to `out`.
    Particles {
        options: dynaclay_import::rbf::ExportOptions,
        out: Option<std::path::PathBuf>,
    },
    /// Copy the clay, sample and interpolate it (beside the engine), and write the RBF.
    Rbf {
        options: dynaclay_import::rbf::ExportOptions,
        out: std::path::PathBuf,
    },
    /// Hold the clay as a compact RBF with these settings from now on, or stop (`None`).
    CompactRbf(Option<dynaclay_import::rbf::CompactSettings>),
    /// Build a point-set surface from a cloud, pull it, and write it as PLY (beside the
    /// engine; the clay is not touched). Paths are joined to the script's folder.
    Points {
        input: std::path::PathBuf,
        pulls: Vec<Vec3>,
        steps: u32,
        out: std::path::PathBuf,
    },
}

impl PlannedAction {
    /// The file this action writes, if any, with its step's name (`save`, `particles` with
    /// `out`, `rbf`, `points`) and what it writes there.
    #[must_use]
    pub fn output(&self) -> Option<(&'static str, &Path, dynaclay_core::io::OutputKind)> {
        use dynaclay_core::io::OutputKind;
        match self {
            Self::Save(path) => Some(("save", path, OutputKind::Session)),
            Self::Rbf { out, .. } => Some(("rbf", out, OutputKind::Rbf)),
            Self::Points { out, .. } => Some(("points", out, OutputKind::PointSet)),
            Self::Particles { out, .. } => out
                .as_deref()
                .map(|p| ("particles", p, OutputKind::Particles)),
            _ => None,
        }
    }
}

/// One timed action.
#[derive(Clone, Debug, PartialEq)]
pub struct PlannedEvent {
    /// Script time at which it is sent, seconds.
    pub at_s: f64,
    /// The 1-based step it comes from.
    pub step: usize,
    /// What it does.
    pub action: PlannedAction,
}

/// One stroke's hand motion, field coordinates.
#[derive(Clone, Debug, PartialEq)]
pub struct PlannedStroke {
    /// The 1-based step it comes from.
    pub step: usize,
    /// When the hand leaves its hover point, seconds.
    pub start_s: f64,
    /// When it is back at hover, seconds.
    pub end_s: f64,
    /// Hand waypoints, field coordinates.
    pub waypoints: Vec<HandWaypoint>,
}

/// A waypoint of the simulated hand in field coordinates; [`ScriptPlan::trajectory`] maps it to
/// the device's [`Waypoint`] (metres).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HandWaypoint {
    /// Time the hand reaches this point, seconds from the start of the script.
    pub time_s: f64,
    /// Hand position, field units.
    pub position_fu: Vec3,
    /// Buttons held from this waypoint until the next (bit 0: the stroke button).
    pub buttons: u32,
    /// The hand's orientation (`None`: unturned; a script's `rotations`).
    pub rotation: Option<Quat>,
}

impl HandWaypoint {
    fn new(time_s: f64, position_fu: Vec3, buttons: u32, rotation: Option<Quat>) -> Self {
        Self {
            time_s,
            position_fu,
            buttons,
            rotation,
        }
    }
}

/// A script laid out on the script clock.
#[derive(Clone, Debug, PartialEq)]
pub struct ScriptPlan {
    /// Whether geometric tools rest on the clay with their shape (the script's
    /// `tool_contact`; see [`dynaclay_core::haptics::HapticConfig::tool_contact`]).
    pub tool_contact: bool,
    /// The script's name in messages (its path, or `<built-in>`).
    pub file: String,
    /// The starting clay.
    pub clay: ClaySpec,
    /// Run length, seconds: the script's `seconds`, else the end of its last step plus 0.5.
    pub seconds: f64,
    /// When the last step ends, seconds.
    pub end_s: f64,
    /// Non-stroke actions in time (and file) order.
    pub events: Vec<PlannedEvent>,
    /// Strokes in time order.
    pub strokes: Vec<PlannedStroke>,
    /// The line each step starts on in the script (0 where unknown), by 0-based step.
    pub step_lines: Vec<usize>,
}

impl ScriptPlan {
    /// Lays out `script` (named `file` in errors); relative paths are taken from `base_dir`,
    /// `preset` and freeform shapes are looked up in `library`, and material steps change
    /// `material`, the material the run starts with.
    ///
    /// # Errors
    /// A [`ScriptError`] naming the step: an unknown preset, a CSG file that does not load,
    /// or a `start_s` before the previous step ends.
    pub fn new(
        script: &Script,
        file: &str,
        base_dir: &Path,
        library: &[ToolPreset],
        mut material: Material,
    ) -> Result<Self, ScriptError> {
        let lookup = |name: &str| library.iter().find(|t| t.name == name);
        let mut events = Vec::new();
        let mut strokes = Vec::new();
        let mut clock = 0.0_f64;
        let mut held: Option<ToolChoice> = None;
        // Tools made by `make_tool` steps so far: steps naming them are resolved when they
        // run, against the library as it is then.
        let mut made: Vec<String> = Vec::new();
        // The count `rbf` steps use when they name none: the last `particles` step's.
        let mut particle_count = dynaclay_import::rbf::ExportOptions::default().particles;
        for (n, step) in script.steps.iter().enumerate() {
            let at = n + 1;
            let fail = |message: String| ScriptError {
                file: file.to_owned(),
                line: None,
                column: None,
                step: Some(at),
                message,
            };
            let mut event = |action| {
                events.push(PlannedEvent {
                    at_s: clock,
                    step: at,
                    action,
                });
            };
            match step {
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
                    buttons,
                    curve,
                    pivot,
                } => {
                    let hand = StrokePath {
                        path,
                        rotations,
                        hover_fu: *hover_fu,
                        buttons: *buttons,
                    };
                    if let (Some(ShapeSpec::Freeform { preset, scale }), Some(action)) =
                        (shape, action)
                        && made.contains(preset)
                    {
                        event(PlannedAction::SetLibraryTool(LibraryTool {
                            name: preset.clone(),
                            scale: Vec3::from_array(*scale),
                            action: Some(*action),
                            falloff_fu: Some(*falloff_fu),
                        }));
                        held = None;
                        let start =
                            stroke_start(*start_s, clock).map_err(|e| fail(e.to_string()))?;
                        let times = path_times(path, *duration_s, times_s);
                        let stroke = stroke_waypoints(at, start, &hand, &times, false);
                        clock = stroke.end_s;
                        strokes.push(stroke);
                        continue;
                    }
                    let choice = match (tool, shape, action) {
                        (_, Some(shape), Some(action)) => ToolChoice::Geometric(GeometricTool {
                            shape: shape
                                .resolve(|name| lookup(name).map(|t| &t.shape))
                                .map_err(|e| fail(e.to_string()))?,
                            action: *action,
                            falloff_fu: *falloff_fu,
                        }),
                        (Some(spec), _, _) => tool_choice(spec, curve, *pivot),
                        _ => tool_choice(&ForceToolSpec::DEFAULT_PUSH, curve, *pivot),
                    };
                    if held.as_ref() != Some(&choice) {
                        event(PlannedAction::SetTool(choice.clone()));
                    }
                    let start = stroke_start(*start_s, clock).map_err(|e| fail(e.to_string()))?;
                    let push = matches!(choice, ToolChoice::Push(_));
                    let times = path_times(path, *duration_s, times_s);
                    let stroke = stroke_waypoints(at, start, &hand, &times, push);
                    clock = stroke.end_s;
                    strokes.push(stroke);
                    held = Some(choice);
                }
                ScriptStep::Tool { .. } | ScriptStep::Preset { .. } => {
                    let Some(tool_step) = step.tool_step() else {
                        continue;
                    };
                    if let Some((name, scale)) = tool_step.library_tool()
                        && made.iter().any(|m| m == name)
                    {
                        // A tool the script made itself: the engine looks it up when it runs.
                        let (action, falloff_fu) = match tool_step.tool {
                            StepTool::Given {
                                action, falloff_fu, ..
                            } => (Some(action), Some(falloff_fu)),
                            StepTool::Preset { .. } => (None, None),
                        };
                        event(PlannedAction::ApplyLibraryTool {
                            tool: LibraryTool {
                                name: name.to_owned(),
                                scale,
                                action,
                                falloff_fu,
                            },
                            poses: tool_step.poses.clone(),
                            duration_s: tool_step.duration_s,
                            patch: tool_step.patch,
                        });
                        continue;
                    }
                    let tool = tool_step
                        .geometric_tool(lookup)
                        .map_err(|e| fail(e.to_string()))?;
                    if let StepTool::Preset { name } = tool_step.tool {
                        tool.action
                            .validate()
                            .map_err(|e| fail(format!("tool preset {name:?}: {}", e.0)))?;
                    }
                    event(PlannedAction::ApplyTool {
                        // Along the positions' path, a quarter of the tool's size apart.
                        poses: resample_stroke(&tool_step.poses, &tool.shape),
                        tool,
                        duration_s: tool_step.duration_s,
                        patch: tool_step.patch,
                    });
                }
                ScriptStep::MakeTool {
                    name,
                    selection,
                    action,
                    falloff_fu,
                } => {
                    event(PlannedAction::MakeTool {
                        name: name.clone(),
                        selection: selection.selection(),
                        action: *action,
                        falloff_fu: *falloff_fu,
                    });
                    if !made.contains(name) {
                        made.push(name.clone());
                    }
                }
                ScriptStep::Csg {
                    op,
                    with,
                    shape,
                    position,
                    rotation,
                    falloff_fu,
                    patch,
                } => {
                    let other = match (with, shape, position) {
                        (Some(with), _, _) => {
                            let path = base_dir.join(with);
                            load_session(&path)
                                .map_err(|e| fail(format!("with: {e}")))?
                                .clay
                        }
                        (None, Some(shape), Some(position)) => {
                            let shape = shape
                                .resolve(|name| lookup(name).map(|t| &t.shape))
                                .map_err(|e| fail(e.to_string()))?;
                            let solid = GeometricTool {
                                shape,
                                action: csg_action(*op),
                                falloff_fu: *falloff_fu,
                            };
                            let pose = poses(&[*position], *rotation)[0];
                            solid_clay(&solid, &pose).map_err(|e| fail(format!("shape: {e}")))?
                        }
                        _ => return Err(fail("a csg step needs `with` or a solid".into())),
                    };
                    event(PlannedAction::Csg {
                        op: csg_action(*op),
                        other: Box::new(other),
                        patch: *patch,
                    });
                }
                ScriptStep::Material { .. } => {
                    material = step.updated_material(material);
                    event(PlannedAction::SetMaterial(material));
                }
                ScriptStep::PaintMaterial { .. } => {
                    if let Some(paint) = paint_request(step).map_err(|f| fail(f.message))? {
                        event(PlannedAction::PaintMaterial(paint));
                    }
                }
                ScriptStep::Mask { .. } | ScriptStep::MaskInvert | ScriptStep::MaskClear => {
                    if let Some(edit) = mask_request(step).map_err(|f| fail(f.message))? {
                        event(PlannedAction::Mask(edit));
                    }
                }
                ScriptStep::Undo { count } => event(PlannedAction::Undo(*count)),
                ScriptStep::Refine { min, max, level } => event(PlannedAction::Refine {
                    lo: glam::Vec3::from_array(*min),
                    hi: glam::Vec3::from_array(*max),
                    level: *level,
                }),
                ScriptStep::Detail {
                    automatic,
                    force_tools,
                } => event(PlannedAction::SetAutoDetail {
                    automatic: *automatic,
                    force_tools: *force_tools,
                }),
                ScriptStep::Redo { count } => event(PlannedAction::Redo(*count)),
                ScriptStep::Save { path } => event(PlannedAction::Save(base_dir.join(path))),
                ScriptStep::Emboss { image, patch, .. } => {
                    let relief = dynaclay_core::io::load_relief(&base_dir.join(image))
                        .map_err(|e| fail(format!("image: {e}")))?;
                    if let Some(params) = step.emboss_params() {
                        event(PlannedAction::Emboss {
                            relief: std::sync::Arc::new(relief),
                            params,
                            patch: *patch,
                        });
                    }
                }
                ScriptStep::Constrain { kind, at, points } => {
                    let request = pin_request(*kind, *at, points).map_err(|f| fail(f.message))?;
                    event(PlannedAction::Constrain(request));
                }
                ScriptStep::Particles {
                    count,
                    steps,
                    seed,
                    out,
                } => {
                    particle_count = *count as usize;
                    event(PlannedAction::Particles {
                        options: export_options(particle_count, *steps, *seed, None, None),
                        out: out.as_ref().map(|p| base_dir.join(p)),
                    });
                }
                ScriptStep::Rbf {
                    out,
                    particles,
                    offset,
                    max_centres,
                    steps,
                    seed,
                } => {
                    let count = particles.map_or(particle_count, |n| n as usize);
                    event(PlannedAction::Rbf {
                        options: export_options(count, *steps, *seed, *offset, *max_centres),
                        out: base_dir.join(out),
                    });
                }
                ScriptStep::CompactRbf { particles } => {
                    let settings = (*particles > 0)
                        .then(|| dynaclay_import::rbf::CompactSettings::new(*particles as usize));
                    event(PlannedAction::CompactRbf(settings));
                }
                ScriptStep::Points {
                    input,
                    pull,
                    steps,
                    out,
                } => {
                    let input = base_dir.join(input);
                    if !input.is_file() {
                        return Err(fail(format!("input: {} is not a file", input.display())));
                    }
                    event(PlannedAction::Points {
                        input,
                        pulls: pull.iter().map(|p| Vec3::from(*p)).collect(),
                        steps: steps.unwrap_or(dynaclay_core::io::DEFAULT_POINTS_PULL_STEPS),
                        out: base_dir.join(out),
                    });
                }
                ScriptStep::Unconstrain { index } => {
                    // Checked non-negative and bounded when the script was parsed.
                    let index = index.map(|i| usize::try_from(i).unwrap_or(usize::MAX));
                    event(PlannedAction::Unconstrain(index));
                }
            }
        }
        Ok(Self {
            file: file.to_owned(),
            clay: script.clay.clone().unwrap_or_default(),
            seconds: script.seconds.unwrap_or(clock + 0.5),
            end_s: clock,
            events,
            strokes,
            step_lines: script.step_lines.clone(),
            tool_contact: script.tool_contact,
        })
    }

    /// Checks that the script cannot take the clay `clay` past its budgets, before anything
    /// runs: every `refine` step together with the patches already there stays within
    /// [`MAX_PATCHES`](dynaclay_core::field::MAX_PATCHES) patches and
    /// [`MAX_CLAY_BOX_COEFFS`](dynaclay_core::field::MAX_CLAY_BOX_COEFFS) coefficients of box (each step counted at
    /// the size it asks for, as if none were undone), and every `constrain` step together
    /// with the pins already there within [`MAX_CONSTRAINTS`](dynaclay_core::dynamics::MAX_CONSTRAINTS).
    /// A `refine` step whose box or level is refused anyway is not counted (it adds nothing).
    ///
    /// # Errors
    /// The step that first goes over, with what it would reach.
    pub fn check_budget(&self, clay: &dynaclay_core::tools::Clay) -> Result<(), ScriptError> {
        use dynaclay_core::dynamics::MAX_CONSTRAINTS;
        use dynaclay_core::field::{MAX_CLAY_BOX_COEFFS, MAX_PATCHES};
        let mut patches = clay.density.patches.len();
        let mut coefficients = clay.density.coefficient_count();
        let mut pins = clay.constraints.len();
        for e in &self.events {
            let over = match &e.action {
                PlannedAction::Refine { lo, hi, level } => {
                    let Ok(n) = clay.density.detail_coefficients(*lo, *hi, *level) else {
                        continue;
                    };
                    patches += 1;
                    coefficients = coefficients.saturating_add(n);
                    if patches > MAX_PATCHES {
                        Some(format!(
                            "refine: the script's refine steps would give the clay {patches} \
                             patches; a clay holds at most {MAX_PATCHES}"
                        ))
                    } else if coefficients > MAX_CLAY_BOX_COEFFS {
                        Some(format!(
                            "refine: the script's refine steps would give the clay \
                             {coefficients} coefficients of box; a clay spans at most \
                             {MAX_CLAY_BOX_COEFFS}"
                        ))
                    } else {
                        None
                    }
                }
                PlannedAction::Constrain(_) => {
                    pins += 1;
                    (pins > MAX_CONSTRAINTS).then(|| {
                        format!(
                            "constrain: the script's constrain steps would pin {pins} places; a \
                             clay holds at most {MAX_CONSTRAINTS} pins"
                        )
                    })
                }
                _ => None,
            };
            if let Some(message) = over {
                return Err(ScriptError {
                    file: self.file.clone(),
                    line: self.step_line(e.step),
                    column: None,
                    step: Some(e.step),
                    message,
                });
            }
        }
        Ok(())
    }

    /// The line 1-based step `step` starts on, when known.
    #[must_use]
    pub fn step_line(&self, step: usize) -> Option<usize> {
        step.checked_sub(1)
            .and_then(|n| self.step_lines.get(n))
            .copied()
            .filter(|&l| l > 0)
    }

    /// The built-in default script, laid out.
    #[must_use]
    pub fn builtin() -> Self {
        Self::new(
            &builtin_script(),
            "<built-in>",
            Path::new("."),
            &[],
            Material::PLASTIC,
        )
        .unwrap_or_else(|e| unreachable!("the built-in script lays out: {e}"))
    }

    /// The simulated hand's trajectory in device metres through `map`. Before the first
    /// stroke the hand hovers above its first point (above the clay's centre when there is no
    /// stroke); between strokes it travels from one hover point to the next.
    ///
    /// # Errors
    /// When the waypoints do not make a trajectory (not after a successful layout).
    pub fn trajectory(&self, map: &WorkspaceMap) -> Result<Trajectory, ScriptError> {
        let first = self
            .strokes
            .first()
            .and_then(|s| s.waypoints.first())
            .map_or(map.field_centre + Vec3::Y * map.field_centre.y, |w| {
                w.position_fu
            });
        let mut w = vec![Waypoint::new(0.0, map.to_device(first))];
        for s in &self.strokes {
            for p in &s.waypoints {
                let waypoint =
                    Waypoint::with_buttons(p.time_s, map.to_device(p.position_fu), p.buttons);
                // The workspace map does not turn: the hand's rotation is the tool's.
                w.push(match p.rotation {
                    Some(q) => waypoint.turned(q),
                    None => waypoint,
                });
            }
        }
        Trajectory::new(w, Interpolation::Smooth).map_err(|e| ScriptError {
            file: self.file.clone(),
            line: None,
            column: None,
            step: None,
            message: e.to_string(),
        })
    }
}

fn tool_choice(spec: &ForceToolSpec, curve: &[[f32; 3]], pivot: Option<[f32; 3]>) -> ToolChoice {
    match (spec, spec.force_tool()) {
        (_, Some(tool)) => ToolChoice::Force {
            tool,
            curve: curve.iter().map(|p| Vec3::from_array(*p)).collect(),
            pivot: pivot.map_or(Vec3::ZERO, Vec3::from_array),
        },
        (
            ForceToolSpec::Push {
                beta,
                radius_fu,
                gain,
            },
            None,
        ) => ToolChoice::Push(PushTool {
            distribution: (*beta).into(),
            radius_fu: *radius_fu,
            gain: *gain,
        }),
        (_, None) => ToolChoice::default(),
    }
}

fn csg_action(op: CsgSpec) -> ToolAction {
    op.into()
}

/// One stroke's hand path as the script gives it.
struct StrokePath<'a> {
    path: &'a [[f32; 3]],
    /// One quaternion per path point, or none.
    rotations: &'a [[f32; 4]],
    hover_fu: f32,
    buttons: u32,
}

impl StrokePath<'_> {
    /// The hand's orientation at path point `i` (`None` when the stroke is unturned).
    fn rotation(&self, i: usize) -> Option<Quat> {
        self.rotations
            .get(i)
            .map(|q| Quat::from_array(*q).normalize())
    }
}

/// The waypoints of one stroke (field coordinates, absolute script times).
fn stroke_waypoints(
    step: usize,
    start: f64,
    hand: &StrokePath,
    times: &[f64],
    push: bool,
) -> PlannedStroke {
    let (path, buttons) = (hand.path, hand.buttons);
    let up = |p: [f32; 3]| Vec3::from_array(p) + Vec3::Y * hand.hover_fu;
    let down = start + APPROACH_S;
    let last = path.len() - 1;
    let mut w = vec![HandWaypoint::new(
        start,
        up(path[0]),
        if push { buttons } else { 0 },
        hand.rotation(0),
    )];
    for (i, (p, t)) in path.iter().zip(times).enumerate() {
        // Released from the last path point on.
        let held = if i == last && path.len() > 1 {
            0
        } else {
            buttons
        };
        w.push(HandWaypoint::new(
            down + t,
            Vec3::from_array(*p),
            held,
            hand.rotation(i),
        ));
    }
    if path.len() == 1 {
        // A single point is held for the whole duration (its one time is the duration).
        let hold = times[0].max(1e-3);
        w[1].time_s = down;
        w.push(HandWaypoint::new(
            down + hold,
            Vec3::from_array(path[0]),
            0,
            hand.rotation(0),
        ));
    }
    let path_end = w.last().map_or(down, |l| l.time_s);
    let end = path_end + APPROACH_S;
    w.push(HandWaypoint::new(
        end,
        up(path[last]),
        0,
        hand.rotation(last),
    ));
    PlannedStroke {
        step,
        start_s: start,
        end_s: end,
        waypoints: w,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use dynaclay_core::io::parse_script;

    fn plan(text: &str) -> Result<ScriptPlan, ScriptError> {
        let script = parse_script(text, "t.toml")?;
        ScriptPlan::new(&script, "t.toml", Path::new("."), &[], Material::PLASTIC)
    }

    fn map() -> WorkspaceMap {
        WorkspaceMap::fitting(
            Vec3::splat(-0.1),
            Vec3::splat(0.1),
            Vec3::ZERO,
            Vec3::splat(2.3),
            30.0,
        )
    }

    #[test]
    fn the_builtin_script_is_one_push_with_the_button_held_along_it() {
        let p = ScriptPlan::builtin();
        assert_eq!((p.strokes.len(), p.events.len()), (1, 1));
        assert!(matches!(
            p.events[0].action,
            PlannedAction::SetTool(ToolChoice::Push(_))
        ));
        let t = p.trajectory(&map()).unwrap();
        let s = &p.strokes[0];
        assert_eq!(s.start_s, 0.2);
        let mid = s.start_s + APPROACH_S + 0.8;
        assert_eq!(t.sample(mid).buttons & 1, 1);
        // Pressed during the descent (push), released after the path.
        assert_eq!(t.sample(s.start_s + 0.1).buttons & 1, 1);
        assert_eq!(t.sample(s.end_s + 0.1).buttons & 1, 0);
        assert_eq!(p.seconds, 3.0);
    }

    #[test]
    fn steps_between_strokes_are_sent_when_the_stroke_before_them_ends() {
        let p = plan(
            r#"
version = 1
[[step]]
do = "tool"
shape = { kind = "sphere", radius_fu = 0.2 }
action = { kind = "add", deposit_rate_per_s = 4.0 }
positions = [[1, 1, 1]]

[[step]]
do = "stroke"
tool = { kind = "grab", gain = 1e6 }
path = [[1, 1.5, 1], [1, 1.7, 1]]
times_s = [0.0, 0.5]

[[step]]
do = "undo"

[[step]]
do = "stroke"
tool = { kind = "grab", gain = 1e6 }
path = [[1, 1.5, 1]]
duration_s = 0.2
"#,
        )
        .unwrap();
        let kinds: Vec<(usize, f64)> = p.events.iter().map(|e| (e.step, e.at_s)).collect();
        let first = &p.strokes[0];
        // Tool step and the grab's tool at 0; the undo when the first stroke ends; the second
        // stroke keeps the same tool (no second SetTool).
        assert_eq!(kinds, [(1, 0.0), (2, 0.0), (3, first.end_s)]);
        assert_eq!(first.start_s, TRAVEL_S);
        assert!((first.end_s - (TRAVEL_S + 2.0 * APPROACH_S + 0.5)).abs() < 1e-9);
        assert_eq!(p.strokes[1].start_s, first.end_s + TRAVEL_S);
        assert!((p.seconds - (p.end_s + 0.5)).abs() < 1e-9);
        // A grab presses at the first path point, not during the descent.
        let t = p.trajectory(&map()).unwrap();
        assert_eq!(t.sample(first.start_s + 0.1).buttons, 0);
        assert_eq!(t.sample(first.start_s + APPROACH_S + 0.2).buttons, 1);
    }

    #[test]
    fn a_start_before_the_previous_step_ends_names_the_step() {
        let e = plan(
            "version = 1\n[[step]]\ndo = \"stroke\"\npath = [[1, 1, 1]]\n\
             [[step]]\ndo = \"stroke\"\npath = [[1, 1, 1]]\nstart_s = 0.5\n",
        )
        .unwrap_err();
        assert_eq!(e.step, Some(2));
        assert!(e.message.contains("start_s"), "{e}");
        let e = plan(
            "version = 1\n[[step]]\ndo = \"preset\"\nname = \"pot\"\npositions = [[1, 1, 1]]\n",
        )
        .unwrap_err();
        assert_eq!(e.step, Some(1));
        assert!(e.message.contains("pot"), "{e}");
    }
}
