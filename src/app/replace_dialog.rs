//! The question before Open, Import or New replaces a clay that has an undo history: keep
//! that history (the replacement becomes one more undo step, so Undo brings the old clay
//! back) or drop it. Nothing is replaced, and nothing dropped, until the user answers.

use std::path::Path;

use super::command::{ClaySource, EngineCommand};

/// Whether `path` names a session file (`.dclay`), which Open takes (Import takes the rest).
#[must_use]
pub fn is_session_path(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("dclay"))
}

/// The replacement waiting for the user's answer.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ReplaceDialog {
    /// What would replace the clay, and the undo steps it would drop.
    pending: Option<(ClaySource, usize)>,
}

impl ReplaceDialog {
    /// The command that replaces the clay with `source` at once when there is no history to
    /// lose (`undo_steps` and `redo_steps` both 0); otherwise `None`, and the question is
    /// shown until answered.
    pub fn ask(
        &mut self,
        source: ClaySource,
        undo_steps: usize,
        redo_steps: usize,
    ) -> Option<EngineCommand> {
        if undo_steps + redo_steps == 0 {
            return Some(EngineCommand::Replace {
                with: source,
                keep_history: false,
            });
        }
        self.pending = Some((source, undo_steps + redo_steps));
        None
    }

    /// Whether the question is showing.
    #[must_use]
    pub fn is_open(&self) -> bool {
        self.pending.is_some()
    }

    /// Shows the question while one is pending; returns the command once answered (none
    /// for Cancel).
    pub fn show(&mut self, ctx: &egui::Context) -> Option<EngineCommand> {
        let (source, steps) = self.pending.as_ref()?;
        let what = match source {
            ClaySource::File(path) => path.display().to_string(),
            ClaySource::New(spec) => format!("a new clay ({})", spec.describe()),
        };
        let mut answer = None;
        let mut cancel = false;
        egui::Window::new("Replace the clay?")
            .collapsible(false)
            .resizable(false)
            .show(ctx, |ui| {
                ui.label(format!(
                    "{what} replaces the clay on screen, which has {steps} undo step(s)."
                ));
                ui.label(
                    "Keep: the replacement is one more undo step, and Undo brings this clay \
                     back (a clay of another resolution starts a new engine, which cannot \
                     keep it; this clay is then written beside the session). Drop: the \
                     history goes.",
                );
                ui.horizontal(|ui| {
                    if ui.button("Keep undo history").clicked() {
                        answer = Some(true);
                    }
                    if ui.button("Drop undo history").clicked() {
                        answer = Some(false);
                    }
                    cancel = ui.button("Cancel").clicked();
                });
            });
        if cancel {
            self.pending = None;
            return None;
        }
        let keep_history = answer?;
        let (with, _) = self.pending.take()?;
        Some(EngineCommand::Replace { with, keep_history })
    }
}
