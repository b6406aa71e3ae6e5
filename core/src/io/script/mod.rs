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
use crate::tools::{
    FalloffCurve, ForceTool, ForceToolError, MaskBrush, MaskEdit, MaskError, MaskMode, PinRequest,
    ToolAction, ToolPose, ToolShape,
};

mod check;
mod parse;
mod schema;
mod steps;
#[cfg(test)]
mod tests;

pub use check::*;
pub use parse::*;
pub use schema::*;
pub use steps::{StepTool, ToolStep, ToolStepError};

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
