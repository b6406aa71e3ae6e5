//! The question the window asks before any one step removes more than half the clay: the
//! engine holds the step (a stroke's applications are withheld, a tool or CSG step waits
//! unapplied) and publishes a [`RemovalQuestion`]; the answer goes back as
//! [`EngineCommand::AnswerRemoval`].

use super::command::EngineCommand;
use crate::engine::RemovalQuestion;

/// The dialog's state: the question last answered, not shown again while the engine still
/// publishes it (the answer takes a frame or two to arrive).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RemovalDialog {
    answered: Option<RemovalQuestion>,
}

impl RemovalDialog {
    /// Shows `question` (the engine's, if any) as a window in the middle of the screen; the
    /// answer to send once the user clicked.
    pub fn show(
        &mut self,
        ctx: &egui::Context,
        question: Option<RemovalQuestion>,
    ) -> Option<EngineCommand> {
        let Some(q) = question else {
            self.answered = None;
            return None;
        };
        if self.answered == Some(q) {
            return None;
        }
        let mut answer = None;
        egui::Window::new("Remove more than half of the clay?")
            .collapsible(false)
            .resizable(false)
            .anchor(egui::Align2::CENTER_CENTER, [0.0, 0.0])
            .show(ctx, |ui| {
                let kind = if q.stroke { "stroke" } else { "step" };
                ui.label(format!(
                    "This {} {kind} would remove about {:.0}% of the clay's volume.",
                    q.what, q.percent
                ));
                ui.label(if q.stroke {
                    "The stroke is held: it removes nothing more until you answer."
                } else {
                    "It waits, unapplied, for your answer."
                });
                ui.horizontal(|ui| {
                    if ui.button("Remove it").clicked() {
                        answer = Some(true);
                    }
                    if ui.button("Keep the clay").clicked() {
                        answer = Some(false);
                    }
                });
            });
        let yes = answer?;
        self.answered = Some(q);
        Some(EngineCommand::AnswerRemoval { yes })
    }
}
