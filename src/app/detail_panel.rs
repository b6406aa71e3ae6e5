//! The Detail section: whether a fine brush adds detail under itself (dynamic topology), and
//! whether the push and the force strokes do too.

use super::command::EngineCommand;
use crate::engine::SimConfig;

/// Automatic detail as the window last set it: [`SimConfig::auto_detail`] and
/// [`SimConfig::auto_detail_force`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DetailSettings {
    /// A brush narrower than three knot spans of the clay under it refines under itself, and
    /// detail a later stroke wipes folds back.
    pub automatic: bool,
    /// The push and the force strokes refine under themselves too (while `automatic` is on).
    pub force_tools: bool,
}

impl Default for DetailSettings {
    /// The engine's own defaults, so a new window and its engine agree before anything is
    /// sent.
    fn default() -> Self {
        let sim = SimConfig::default();
        Self {
            automatic: sim.auto_detail,
            force_tools: sim.auto_detail_force,
        }
    }
}

impl DetailSettings {
    /// The command that gives the engine these settings.
    #[must_use]
    pub fn command(self) -> EngineCommand {
        EngineCommand::SetAutoDetail {
            automatic: self.automatic,
            force_tools: self.force_tools,
        }
    }

    /// The section's two switches; whether either changed.
    pub fn ui(&mut self, ui: &mut egui::Ui) -> bool {
        let mut changed = ui
            .checkbox(&mut self.automatic, "Automatic detail")
            .on_hover_text(
                "A brush narrower than three knot spans of the clay under it adds a finer \
                 patch under itself first, at the level its width needs; detail a later \
                 smoothing or removal wipes folds back. Off: brushes sculpt the patches there \
                 are (Refine here still adds one).",
            )
            .changed();
        ui.add_enabled_ui(self.automatic, |ui| {
            changed |= ui
                .checkbox(&mut self.force_tools, "Under force tools too")
                .on_hover_text(
                    "The push and the force strokes refine under themselves as well, so a \
                     narrow push presses a groove of its own width. On a detail patch, painted \
                     stiffness and mass act weaker than on the base.",
                )
                .changed();
        });
        changed
    }
}
