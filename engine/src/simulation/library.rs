//! The tool library on the running stage: making a tool from the clay, storing a tool the
//! window made, and resolving a script's library tool by name when its step runs. The
//! library is carried with the session ([`CarriedSections::tools`]), so a save keeps it.

#[allow(clippy::wildcard_imports)] // the stage's own module: its types and imports
use super::*;
use crate::tool_library::{LibraryTool, describe_preset, make_preset, store_preset};
use dynaclay_core::io::ToolPreset;
use dynaclay_core::tools::{GeometricTool, Selection};

impl SimulationStage {
    /// The session's tool library as it stands.
    #[must_use]
    pub fn tool_library(&self) -> &[ToolPreset] {
        &self.carried.tools
    }

    /// Makes the preset `name` of the clay inside `selection` and stores it; returns what
    /// was stored. The clay does not change.
    pub(super) fn make_tool(
        &mut self,
        name: &str,
        selection: &Selection,
        action: ToolAction,
        falloff_fu: f32,
    ) -> Result<String, CommandError> {
        let preset = make_preset(&self.clay.density, name, selection, action, falloff_fu)?;
        Ok(self.add_tool(preset))
    }

    /// Stores `preset` (replacing one of the same name); returns what was stored.
    pub(super) fn add_tool(&mut self, preset: ToolPreset) -> String {
        let line = describe_preset(&preset, false);
        let replaced = store_preset(&mut self.carried.tools, preset);
        if replaced {
            line.replacen(" added ", " replaced ", 1)
        } else {
            line
        }
    }

    /// The library tool `tool` names, resolved against the library as it stands.
    pub(super) fn library_tool(&self, tool: &LibraryTool) -> Result<GeometricTool, CommandError> {
        Ok(tool.resolve(&self.carried.tools)?)
    }
}
