//! The headless script format (TOML): every geometric tool, force stroke, material change,
//! CSG, undo/redo and save, so any session can be replayed without a device. This module
//! holds the serde types and the parser, whose errors name the line, column and field.
//!
//! ```toml
//! version = 1
//!
//! [[step]]
//! do = "tool"
//! shape = { kind = "sphere", radius_m = 0.2 }
//! action = { kind = "add", deposit_rate_per_s = 4.0 }
//! positions = [[0.5, 0.5, 0.5], [0.6, 0.5, 0.5]]
//! duration_s = 0.5
//!
//! [[step]]
//! do = "stroke"
//! tool = { kind = "chisel", depth_m = 0.03, radius_m = 0.05, gain = 1e6 }
//! path = [[0.9, 0.5, 0.5]]
//! duration_s = 1.0
//!
//! [[step]]
//! do = "undo"
//! ```

use std::path::PathBuf;

use glam::{Quat, Vec3};
use serde::{Deserialize, Serialize};

use crate::dynamics::{Distribution, Material};
use crate::tools::{ForceTool, ToolAction, ToolPose, ToolShape};

/// The version of the script format this build reads.
pub const SCRIPT_VERSION: u32 = 1;

/// A parsed script.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Script {
    pub version: u32,
    #[serde(default, rename = "step")]
    pub steps: Vec<ScriptStep>,
}

/// A tool shape as written in a script; `freeform` names a preset of the session's library.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum ShapeSpec {
    Sphere {
        radius_m: f32,
    },
    Ellipsoid {
        radii_m: [f32; 3],
    },
    Box {
        half_extents_m: [f32; 3],
    },
    Cylinder {
        radius_m: f32,
        half_height_m: f32,
    },
    Capsule {
        radius_m: f32,
        half_height_m: f32,
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
    Grab {
        gain: f32,
    },
    Area {
        beta: BetaSpec,
        radius_m: f32,
        tracks: u32,
        gain: f32,
    },
    Curve {
        radius_m: f32,
        gain: f32,
    },
    Chisel {
        depth_m: f32,
        radius_m: f32,
        gain: f32,
    },
    Squirt {
        depth_m: f32,
        radius_m: f32,
        gain: f32,
    },
    Pull {
        beta: BetaSpec,
        radius_m: f32,
        gain: f32,
    },
    Bend {
        samples: u32,
        radius_m: f32,
        gain: f32,
    },
}

impl From<ForceToolSpec> for ForceTool {
    fn from(s: ForceToolSpec) -> Self {
        match s {
            ForceToolSpec::Grab { gain } => Self::PointGrab { gain },
            ForceToolSpec::Area {
                beta,
                radius_m,
                tracks,
                gain,
            } => Self::Area {
                distribution: beta.into(),
                radius_m,
                tracks,
                gain,
            },
            ForceToolSpec::Curve { radius_m, gain } => Self::Curve { radius_m, gain },
            ForceToolSpec::Chisel {
                depth_m,
                radius_m,
                gain,
            } => Self::Chisel {
                depth_m,
                radius_m,
                gain,
            },
            ForceToolSpec::Squirt {
                depth_m,
                radius_m,
                gain,
            } => Self::Squirt {
                depth_m,
                radius_m,
                gain,
            },
            ForceToolSpec::Pull {
                beta,
                radius_m,
                gain,
            } => Self::Pull {
                distribution: beta.into(),
                radius_m,
                gain,
            },
            ForceToolSpec::Bend {
                samples,
                radius_m,
                gain,
            } => Self::Bend {
                samples,
                radius_m,
                gain,
            },
        }
    }
}

/// CSG operations between the clay and another session file.
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

/// One step of a script. Each tool application or stroke is one undo step.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "do", rename_all = "snake_case", deny_unknown_fields)]
pub enum ScriptStep {
    /// A geometric tool applied at each position in turn over `duration_s`.
    Tool {
        shape: ShapeSpec,
        action: ToolAction,
        positions: Vec<[f32; 3]>,
        #[serde(default = "default_falloff")]
        falloff_m: f32,
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
    /// A force stroke: the cursor follows `path` over `duration_s` (run by the engine).
    Stroke {
        tool: ForceToolSpec,
        path: Vec<[f32; 3]>,
        duration_s: f32,
        /// The user curve of a curve tool.
        #[serde(default)]
        curve: Vec<[f32; 3]>,
        /// The pivot of a bend.
        #[serde(default)]
        pivot: Option<[f32; 3]>,
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
    },
    /// CSG with the clay of another session file (relative to the script's folder).
    Csg {
        op: CsgSpec,
        with: PathBuf,
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
            Self::Sphere { radius_m } => ToolShape::Sphere {
                radius_m: *radius_m,
            },
            Self::Ellipsoid { radii_m } => ToolShape::Ellipsoid {
                radii_m: Vec3::from_array(*radii_m),
            },
            Self::Box { half_extents_m } => ToolShape::Box {
                half_extents_m: Vec3::from_array(*half_extents_m),
            },
            Self::Cylinder {
                radius_m,
                half_height_m,
            } => ToolShape::Cylinder {
                radius_m: *radius_m,
                half_height_m: *half_height_m,
            },
            Self::Capsule {
                radius_m,
                half_height_m,
            } => ToolShape::Capsule {
                radius_m: *radius_m,
                half_height_m: *half_height_m,
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
            position_m: Vec3::from_array(*p),
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
            } => Material {
                mass: mass.unwrap_or(m.mass),
                damping: damping.unwrap_or(m.damping),
                stiffness: stiffness.unwrap_or(m.stiffness),
                plasticity_per_s: plasticity_per_s.unwrap_or(m.plasticity_per_s),
                yield_density: yield_density.unwrap_or(m.yield_density),
            },
            _ => m,
        }
    }
}

/// Why a script could not be read or run: where (file, line, column, step) and what.
#[derive(Clone, Debug, PartialEq)]
pub struct ScriptError {
    pub file: String,
    /// 1-based line and column, when known.
    pub line: Option<usize>,
    pub column: Option<usize>,
    /// 1-based index of the failing step, when known.
    pub step: Option<usize>,
    pub message: String,
}

impl std::fmt::Display for ScriptError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}", self.file)?;
        if let Some(l) = self.line {
            write!(f, ":{l}")?;
            if let Some(c) = self.column {
                write!(f, ":{c}")?;
            }
        }
        if let Some(s) = self.step {
            write!(f, ": step {s}")?;
        }
        write!(f, ": {}", self.message)
    }
}

impl std::error::Error for ScriptError {}

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
    let script: Script = toml::from_str(text).map_err(|e| {
        let (line, column) = match e.span() {
            Some(span) => {
                let (l, c) = line_col(text, span.start);
                (Some(l), Some(c))
            }
            None => (None, None),
        };
        ScriptError {
            file: file.to_string(),
            line,
            column,
            step: None,
            message: e.message().to_string(),
        }
    })?;
    // Steps begin at their `[[step]]` headers; find them for semantic errors.
    let step_lines: Vec<usize> = text
        .lines()
        .enumerate()
        .filter(|(_, l)| l.trim_start().starts_with("[[step]]"))
        .map(|(n, _)| n + 1)
        .collect();
    let at = |n: usize, message: String| ScriptError {
        file: file.to_string(),
        line: step_lines.get(n).copied(),
        column: None,
        step: Some(n + 1),
        message,
    };
    if script.version != SCRIPT_VERSION {
        return Err(ScriptError {
            file: file.to_string(),
            line: text
                .lines()
                .position(|l| l.trim_start().starts_with("version"))
                .map(|n| n + 1),
            column: None,
            step: None,
            message: format!(
                "version = {} is not supported (this build reads version {SCRIPT_VERSION})",
                script.version
            ),
        });
    }
    for (n, step) in script.steps.iter().enumerate() {
        check_step(step).map_err(|m| at(n, m))?;
    }
    Ok(script)
}

fn finite(name: &str, v: f32) -> Result<(), String> {
    if v.is_finite() && v >= 0.0 {
        Ok(())
    } else {
        Err(format!("{name} = {v} must be finite and non-negative"))
    }
}

fn check_points(name: &str, points: &[[f32; 3]], need_one: bool) -> Result<(), String> {
    if need_one && points.is_empty() {
        return Err(format!("{name} needs at least one point"));
    }
    match points.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
        Some(i) => Err(format!("{name}[{i}] is not finite")),
        None => Ok(()),
    }
}

fn check_step(step: &ScriptStep) -> Result<(), String> {
    match step {
        ScriptStep::Tool {
            shape,
            action,
            positions,
            falloff_m,
            duration_s,
            ..
        } => {
            check_points("positions", positions, true)?;
            finite("duration_s", *duration_s)?;
            finite("falloff_m", *falloff_m)?;
            action.validate().map_err(|e| format!("action: {}", e.0))?;
            // Freeform shapes are checked against the library when run.
            if let Ok(shape) = shape.resolve(|_| None) {
                shape.validate().map_err(|e| format!("shape: {}", e.0))?;
            }
            Ok(())
        }
        ScriptStep::Preset {
            positions,
            duration_s,
            ..
        } => {
            check_points("positions", positions, true)?;
            finite("duration_s", *duration_s)
        }
        ScriptStep::Stroke {
            tool,
            path,
            duration_s,
            curve,
            pivot,
        } => {
            check_points("path", path, true)?;
            check_points("curve", curve, false)?;
            finite("duration_s", *duration_s)?;
            if let Some(p) = pivot {
                check_points("pivot", std::slice::from_ref(p), true)?;
            }
            ForceTool::from(*tool)
                .validate()
                .map_err(|e| format!("tool: {}", e.0))
        }
        ScriptStep::Material {
            mass,
            damping,
            stiffness,
            plasticity_per_s,
            yield_density,
        } => {
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
                return Err("mass must be positive".into());
            }
            Ok(())
        }
        ScriptStep::Csg { .. }
        | ScriptStep::Undo { .. }
        | ScriptStep::Redo { .. }
        | ScriptStep::Save { .. } => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const EXAMPLE: &str = r#"
version = 1

[[step]]
do = "tool"
shape = { kind = "sphere", radius_m = 0.2 }
action = { kind = "add", deposit_rate_per_s = 4.0 }
positions = [[0.5, 0.5, 0.5], [0.6, 0.5, 0.5]]
duration_s = 0.5

[[step]]
do = "tool"
shape = { kind = "ellipsoid", radii_m = [0.1, 0.2, 0.1] }
action = { kind = "stamp", s = 0.5, m = 0.15, r = 0.25, k = -2.0, n = 0.3 }
positions = [[0.5, 0.7, 0.5]]
rotation = [0.0, 0.0, 0.0, 1.0]

[[step]]
do = "tool"
shape = { kind = "capsule", radius_m = 0.05, half_height_m = 0.1 }
action = { kind = "contact", alpha = -2.0 }
positions = [[0.5, 0.7, 0.5]]

[[step]]
do = "stroke"
tool = { kind = "area", beta = "gaussian", radius_m = 0.05, tracks = 5, gain = 1e6 }
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
        // Round trip through the serde types.
        let text = toml::to_string(&s).unwrap();
        assert_eq!(parse_script(&text, "again").unwrap(), s);
    }

    #[test]
    fn syntax_and_type_errors_name_line_and_field() {
        let bad = "version = 1\n\n[[step]]\ndo = \"tool\"\nshape = { kind = \"sphere\", radius = 0.2 }\naction = { kind = \"remove\" }\npositions = [[0, 0, 0]]\n";
        let e = parse_script(bad, "bad.toml").unwrap_err();
        // Inside a step the span is the step's table (its `[[step]]` header); the message
        // names the field.
        assert_eq!(e.line, Some(3), "{e}");
        assert!(e.message.contains("`radius`"), "{e}");
        assert!(e.to_string().starts_with("bad.toml:3:"), "{e}");
        let e = parse_script("version = \"one\"\n", "v.toml").unwrap_err();
        assert_eq!(e.line, Some(1), "{e}");

        let bad = "version = 1\n[[step]]\ndo = \"teleport\"\n";
        let e = parse_script(bad, "x").unwrap_err();
        assert!(e.message.contains("teleport"), "{e}");
        assert!(e.line.is_some());
    }

    #[test]
    fn semantic_errors_name_the_step_and_its_line() {
        let bad = "version = 1\n\n[[step]]\ndo = \"undo\"\n\n[[step]]\ndo = \"tool\"\nshape = { kind = \"sphere\", radius_m = -1.0 }\naction = { kind = \"remove\" }\npositions = [[0, 0, 0]]\n";
        let e = parse_script(bad, "x").unwrap_err();
        assert_eq!((e.step, e.line), (Some(2), Some(6)), "{e}");
        assert!(e.message.contains("radius_m"), "{e}");
        let e = parse_script("version = 7\n", "x").unwrap_err();
        assert!(e.message.contains("version = 7"), "{e}");
        let bad = "version = 1\n[[step]]\ndo = \"stroke\"\ntool = { kind = \"chisel\", depth_m = 0.0, radius_m = 0.1, gain = 1.0 }\npath = []\nduration_s = 1.0\n";
        let e = parse_script(bad, "x").unwrap_err();
        assert!(e.message.contains("path"), "{e}");
    }
}
