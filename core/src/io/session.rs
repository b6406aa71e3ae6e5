//! The session model the engine saves and loads: the clay (patches and colour), the material
//! fields, the tool library and metadata. Plain data; the byte format lives in `format`.

use serde::{Deserialize, Serialize};

use crate::dynamics::Material;
pub use crate::dynamics::MaterialGrid;
use crate::tools::{Clay, ToolAction, ToolShape};

/// Descriptive metadata stored with a session.
#[derive(Clone, Debug, PartialEq, Default, Serialize, Deserialize)]
pub struct SessionMeta {
    /// The session's display name.
    pub name: String,
    /// When the session was created, seconds since the Unix epoch.
    pub created_unix_s: u64,
    /// When it was last saved, seconds since the Unix epoch (set by the saver).
    pub saved_unix_s: u64,
    /// The program that wrote the file (e.g. `dynaclay 0.1.0`).
    pub writer: String,
}

/// Seconds since the Unix epoch now (0 on a clock set before 1970): the stamp for
/// [`SessionMeta::created_unix_s`] and [`SessionMeta::saved_unix_s`].
#[must_use]
pub fn unix_now_s() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::SystemTime::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs())
}

/// The material: uniform defaults for the density-spring dynamics (and the springs'
/// neighbourhood), overridden where grids of mass, damping, stiffness or plasticity are
/// painted (the simulation applies them at its mass points; see [`MaterialGrid`]).
#[derive(Clone, Debug, PartialEq, Default)]
pub struct MaterialFields {
    /// The region's uniform material (mass, damping, stiffness, plasticity, yield).
    pub uniform: Material,
    /// Spatially varying overrides over the base patch.
    pub grids: Vec<MaterialGrid>,
}

/// The longest name a tool of the library may have, bytes.
pub const MAX_TOOL_NAME_BYTES: usize = 128;

/// A named tool in the session's library.
#[derive(Clone, Debug, PartialEq)]
pub struct ToolPreset {
    pub name: String,
    pub shape: ToolShape,
    pub action: ToolAction,
    /// Width of the tool potential's falloff band on each side of its surface.
    pub falloff_fu: f32,
}

/// Everything a session file holds.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Session {
    pub clay: Clay,
    pub material: MaterialFields,
    pub tools: Vec<ToolPreset>,
    pub meta: SessionMeta,
}

impl Session {
    /// The tool preset called `name`, if any.
    #[must_use]
    pub fn tool(&self, name: &str) -> Option<&ToolPreset> {
        self.tools.iter().find(|t| t.name == name)
    }
}
