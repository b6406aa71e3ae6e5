//! The headless run script: the starting clay, material, force tool and a set of strokes that
//! drive the simulated arm's hand. TOML, documented in the README; every field is optional
//! except each stroke's `path`.
//!
//! ```toml
//! seconds = 4.0                  # run length (the CLI's --seconds overrides it)
//!
//! [clay]
//! shape = "block"                # "block" or "sphere"
//! resolution = 24                # coefficients per axis (8..=96)
//!
//! [material]                     # density-spring material (defaults: plastic clay)
//! stiffness = 1000.0
//! damping = 40.0
//! mass = 1.0
//! plasticity_per_s = 8.0
//! yield_density = 0.02
//!
//! [tool]                         # how the push is spread over mass points
//! distribution = "gaussian"      # constant, gaussian, spherical, cylindrical, conical
//! radius = 0.25                  # field units
//! gain = 2000000.0
//!
//! [[stroke]]
//! start_s = 0.3                  # when the hand leaves its hover point
//! path = [[0.85, 1.55, 1.15], [1.45, 1.55, 1.15]]   # tip targets, field coordinates
//! duration_s = 1.5               # time along the path
//! hover = 0.35                   # height above the path's ends before and after, field units
//! ```
//!
//! Field coordinates: the clay lattice spans `[0, (resolution − 1) · 0.1]` on each axis and the
//! default block fills the middle half of it with its top face at `y = 1.75` (for
//! `resolution = 24`). The hand holds button 0 (stroke active) from the start of its descent to
//! the end of the path.

use std::fmt;
use std::path::Path;

use glam::Vec3;
use serde::Deserialize;

use dynaclay_devices::{Interpolation, Trajectory, Waypoint};

use super::command::ForceTool;
use super::workspace::WorkspaceMap;
use crate::dynamics::{Distribution, Material};

/// A script that could not be read or is not valid.
#[derive(Clone, Debug, PartialEq)]
pub struct ScriptError {
    /// Where: the file path (or `<built-in>`), with line and column when known.
    pub location: String,
    /// The field at fault (`stroke[1].path`), if known.
    pub field: Option<String>,
    /// What is wrong.
    pub message: String,
}

impl fmt::Display for ScriptError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.field {
            Some(field) => write!(f, "{}: {}: {}", self.location, field, self.message),
            None => write!(f, "{}: {}", self.location, self.message),
        }
    }
}

impl std::error::Error for ScriptError {}

/// The clay to start from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ClayShape {
    /// A box filling the middle half of the lattice.
    Block,
    /// A ball of radius a quarter of the lattice.
    Sphere,
}

/// `[clay]`.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ClaySpec {
    /// Starting shape.
    pub shape: ClayShape,
    /// Coefficients per axis.
    pub resolution: usize,
}

impl Default for ClaySpec {
    fn default() -> Self {
        Self {
            shape: ClayShape::Block,
            resolution: 24,
        }
    }
}

/// `[material]`.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MaterialSpec {
    /// Spring stiffness.
    pub stiffness: f32,
    /// Damping.
    pub damping: f32,
    /// Mass per mass point.
    pub mass: f32,
    /// Plastic drift rate, per second.
    pub plasticity_per_s: f32,
    /// Plastic yield threshold.
    pub yield_density: f32,
}

impl Default for MaterialSpec {
    fn default() -> Self {
        let m = Material::PLASTIC;
        Self {
            stiffness: m.stiffness,
            damping: m.damping,
            mass: m.mass,
            plasticity_per_s: m.plasticity_per_s,
            yield_density: m.yield_density,
        }
    }
}

/// `[tool]`.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ToolSpec {
    /// Spread shape name.
    pub distribution: DistributionName,
    /// Spread radius, field units.
    pub radius: f32,
    /// Force gain.
    pub gain: f32,
}

impl Default for ToolSpec {
    fn default() -> Self {
        let t = ForceTool::default();
        Self {
            distribution: DistributionName::Gaussian,
            radius: t.radius,
            gain: t.gain,
        }
    }
}

/// The `β` names accepted in scripts.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
#[allow(missing_docs)]
pub enum DistributionName {
    Constant,
    Gaussian,
    Spherical,
    Cylindrical,
    Conical,
}

impl From<DistributionName> for Distribution {
    fn from(d: DistributionName) -> Self {
        match d {
            DistributionName::Constant => Self::Constant,
            DistributionName::Gaussian => Self::Gaussian,
            DistributionName::Spherical => Self::Spherical,
            DistributionName::Cylindrical => Self::Cylindrical,
            DistributionName::Conical => Self::Conical,
        }
    }
}

/// One `[[stroke]]`.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StrokeSpec {
    /// When the hand leaves its hover point, seconds.
    #[serde(default)]
    pub start_s: f64,
    /// Tip targets along the stroke, field coordinates.
    pub path: Vec<[f32; 3]>,
    /// Time along the path, seconds.
    #[serde(default = "default_duration")]
    pub duration_s: f64,
    /// Hover height above the path's ends, field units.
    #[serde(default = "default_hover")]
    pub hover: f32,
}

fn default_duration() -> f64 {
    1.0
}
fn default_hover() -> f32 {
    0.35
}

/// A whole script.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Script {
    /// Run length, seconds (the CLI may override).
    #[serde(default)]
    pub seconds: Option<f64>,
    /// Starting clay.
    #[serde(default)]
    pub clay: ClaySpec,
    /// Material.
    #[serde(default)]
    pub material: MaterialSpec,
    /// Force tool.
    #[serde(default)]
    pub tool: ToolSpec,
    /// Strokes, in any order.
    #[serde(default, rename = "stroke")]
    pub strokes: Vec<StrokeSpec>,
}

/// The script used when none is given: one push along the top of the default block.
pub const DEFAULT_SCRIPT: &str = r#"
seconds = 3.0

[clay]
shape = "block"
resolution = 24

[[stroke]]
start_s = 0.2
path = [[0.85, 1.55, 1.15], [1.15, 1.5, 1.15], [1.45, 1.55, 1.15]]
duration_s = 1.6
hover = 0.35
"#;

/// Time the hand takes from hover to the path and back, seconds.
const APPROACH_S: f64 = 0.3;

impl Script {
    /// Parses and validates a script; `location` names it in errors (a path).
    ///
    /// # Errors
    /// A [`ScriptError`] with the line and column of a syntax or type error, or the field of
    /// a value out of range.
    pub fn parse(text: &str, location: &str) -> Result<Self, ScriptError> {
        let script: Self = toml::from_str(text).map_err(|e| {
            let at = e
                .span()
                .map(|s| {
                    let (line, col) = line_col(text, s.start);
                    format!("{location}:{line}:{col}")
                })
                .unwrap_or_else(|| location.to_owned());
            ScriptError {
                location: at,
                field: None,
                message: e.message().trim().to_owned(),
            }
        })?;
        script.validate(location)?;
        Ok(script)
    }

    /// Reads and parses the script at `path`.
    ///
    /// # Errors
    /// When the file cannot be read, or as [`Script::parse`].
    pub fn load(path: &Path) -> Result<Self, ScriptError> {
        let location = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| ScriptError {
            location: location.clone(),
            field: None,
            message: format!("cannot read the script: {e}"),
        })?;
        Self::parse(&text, &location)
    }

    /// The built-in default script.
    #[must_use]
    pub fn builtin() -> Self {
        Self::parse(DEFAULT_SCRIPT, "<built-in>")
            .unwrap_or_else(|e| unreachable!("the built-in script is valid: {e}"))
    }

    fn validate(&self, location: &str) -> Result<(), ScriptError> {
        let bad = |field: String, message: &str| ScriptError {
            location: location.to_owned(),
            field: Some(field),
            message: message.to_owned(),
        };
        if let Some(s) = self.seconds
            && !(s.is_finite() && s > 0.0 && s <= 3600.0)
        {
            return Err(bad("seconds".into(), "must be in (0, 3600]"));
        }
        if !(8..=96).contains(&self.clay.resolution) {
            return Err(bad("clay.resolution".into(), "must be between 8 and 96"));
        }
        let m = &self.material;
        for (name, v, min) in [
            ("material.stiffness", m.stiffness, 0.0),
            ("material.damping", m.damping, 0.0),
            ("material.plasticity_per_s", m.plasticity_per_s, 0.0),
            ("material.yield_density", m.yield_density, 0.0),
        ] {
            if !(v.is_finite() && v >= min) {
                return Err(bad(name.into(), "must be a finite number ≥ 0"));
            }
        }
        if !(m.mass.is_finite() && m.mass > 0.0) {
            return Err(bad("material.mass".into(), "must be positive"));
        }
        if !(self.tool.radius.is_finite() && self.tool.radius > 0.0) {
            return Err(bad("tool.radius".into(), "must be positive"));
        }
        if !(self.tool.gain.is_finite() && self.tool.gain >= 0.0) {
            return Err(bad("tool.gain".into(), "must be a finite number ≥ 0"));
        }
        for (i, s) in self.strokes.iter().enumerate() {
            if s.path.is_empty() {
                return Err(bad(format!("stroke[{i}].path"), "needs at least one point"));
            }
            if s.path.iter().flatten().any(|v| !v.is_finite()) {
                return Err(bad(
                    format!("stroke[{i}].path"),
                    "has a non-finite coordinate",
                ));
            }
            if !(s.start_s.is_finite() && s.start_s >= 0.0) {
                return Err(bad(format!("stroke[{i}].start_s"), "must be ≥ 0"));
            }
            if !(s.duration_s.is_finite() && s.duration_s > 0.0) {
                return Err(bad(format!("stroke[{i}].duration_s"), "must be positive"));
            }
            if !(s.hover.is_finite() && s.hover > 0.0) {
                return Err(bad(format!("stroke[{i}].hover"), "must be positive"));
            }
        }
        let mut order: Vec<&StrokeSpec> = self.strokes.iter().collect();
        order.sort_by(|a, b| a.start_s.total_cmp(&b.start_s));
        for w in order.windows(2) {
            let end = w[0].start_s + w[0].duration_s + 2.0 * APPROACH_S;
            if w[1].start_s < end {
                let i = self
                    .strokes
                    .iter()
                    .position(|s| std::ptr::eq(s, w[1]))
                    .unwrap_or(0);
                return Err(bad(
                    format!("stroke[{i}].start_s"),
                    "overlaps the previous stroke (each stroke needs its duration plus 0.6 s)",
                ));
            }
        }
        Ok(())
    }

    /// The material.
    #[must_use]
    pub fn material(&self) -> Material {
        let m = &self.material;
        Material {
            mass: m.mass,
            damping: m.damping,
            stiffness: m.stiffness,
            plasticity_per_s: m.plasticity_per_s,
            yield_density: m.yield_density,
        }
    }

    /// The force tool.
    #[must_use]
    pub fn tool(&self) -> ForceTool {
        ForceTool {
            distribution: self.tool.distribution.into(),
            radius: self.tool.radius,
            gain: self.tool.gain,
        }
    }

    /// When the last stroke ends (hand back at hover), seconds.
    #[must_use]
    pub fn strokes_end_s(&self) -> f64 {
        self.strokes
            .iter()
            .map(|s| s.start_s + s.duration_s + 2.0 * APPROACH_S)
            .fold(0.0, f64::max)
    }

    /// The simulated hand's trajectory in device metres through `map`: hover above each
    /// stroke's first point, descend holding button 0, follow the path, release and lift.
    /// With no strokes the hand hovers above the clay's centre.
    ///
    /// # Errors
    /// When the waypoints do not make a trajectory (should not happen after validation).
    pub fn trajectory(&self, map: &WorkspaceMap) -> Result<Trajectory, ScriptError> {
        let mut strokes: Vec<&StrokeSpec> = self.strokes.iter().collect();
        strokes.sort_by(|a, b| a.start_s.total_cmp(&b.start_s));
        let dev = |p: Vec3| map.to_device(p);
        let mut w = Vec::new();
        let Some(first) = strokes.first() else {
            let rest = Waypoint::new(0.0, dev(map.field_centre + Vec3::Y * map.field_centre.y));
            return Trajectory::new(vec![rest], Interpolation::Smooth).map_err(|e| ScriptError {
                location: "<script>".into(),
                field: None,
                message: e.to_string(),
            });
        };
        let up = |p: [f32; 3], h: f32| Vec3::from(p) + Vec3::Y * h;
        w.push(Waypoint::new(0.0, dev(up(first.path[0], first.hover))));
        for s in strokes {
            let t0 = s.start_s.max(1e-3);
            let hover_in = up(s.path[0], s.hover);
            if w.last().is_some_and(|l: &Waypoint| l.time_s < t0) {
                w.push(Waypoint::new(t0, dev(hover_in)));
            }
            // Button held from the start of the descent to the end of the path.
            if let Some(l) = w.last_mut() {
                l.buttons = 1;
            }
            let n = s.path.len();
            for (i, p) in s.path.iter().enumerate() {
                let frac = if n > 1 {
                    i as f64 / (n - 1) as f64
                } else {
                    0.0
                };
                let t = t0 + APPROACH_S + frac * s.duration_s;
                w.push(Waypoint::with_buttons(t, dev(Vec3::from(*p)), 1));
            }
            if n == 1 {
                let t = t0 + APPROACH_S + s.duration_s;
                w.push(Waypoint::with_buttons(t, dev(Vec3::from(s.path[0])), 1));
            }
            if let Some(l) = w.last_mut() {
                l.buttons = 0;
            }
            let t_end = t0 + 2.0 * APPROACH_S + s.duration_s;
            w.push(Waypoint::new(t_end, dev(up(s.path[n - 1], s.hover))));
        }
        Trajectory::new(w, Interpolation::Smooth).map_err(|e| ScriptError {
            location: "<script>".into(),
            field: Some(format!("stroke waypoint {}", e.index)),
            message: e.to_string(),
        })
    }
}

/// 1-based line and column of byte `offset` in `text`.
fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let before = &text[..offset.min(text.len())];
    let line = before.matches('\n').count() + 1;
    let col = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, col)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builtin_script_parses_and_makes_a_trajectory() {
        let s = Script::builtin();
        assert_eq!(s.strokes.len(), 1);
        let map = WorkspaceMap::fitting(
            Vec3::splat(-0.1),
            Vec3::splat(0.1),
            Vec3::ZERO,
            Vec3::splat(2.3),
            30.0,
        );
        let t = s.trajectory(&map).unwrap();
        // Button held during the push, released after.
        let mid = s.strokes[0].start_s + APPROACH_S + 0.5 * s.strokes[0].duration_s;
        assert_eq!(t.sample(mid).buttons & 1, 1);
        assert_eq!(t.sample(s.strokes_end_s() + 0.1).buttons & 1, 0);
    }

    #[test]
    fn syntax_errors_name_the_line() {
        let e = Script::parse("seconds = 2\n[clay]\nshape = 5\n", "x.toml").unwrap_err();
        assert!(e.location.starts_with("x.toml:3:"), "{e}");
        let e = Script::parse("[[stroke]]\npath = [[1,2,3]]\ncolour = 1\n", "y.toml").unwrap_err();
        assert!(e.location.starts_with("y.toml:3:"), "{e}");
        assert!(e.message.contains("colour"), "{e}");
    }

    #[test]
    fn range_errors_name_the_field() {
        let e = Script::parse("[[stroke]]\npath = []\n", "z.toml").unwrap_err();
        assert_eq!(e.field.as_deref(), Some("stroke[0].path"));
        let e = Script::parse("[tool]\nradius = -1.0\n", "z.toml").unwrap_err();
        assert_eq!(e.field.as_deref(), Some("tool.radius"));
        let e = Script::parse(
            "[[stroke]]\npath=[[1,1,1]]\n[[stroke]]\nstart_s = 0.5\npath=[[1,1,1]]\n",
            "z.toml",
        )
        .unwrap_err();
        assert_eq!(e.field.as_deref(), Some("stroke[1].start_s"));
    }
}
