//! The simulation stage's side of geometric constraints: pinning and unpinning (each one undo
//! step, recorded with the clay's constraint list) and the constraint stage of the live
//! dynamics region, rebuilt whenever the region or the pins change.

use super::SimulationStage;
use crate::Command;
use dynaclay_core::dynamics::ConstraintSolver;
use dynaclay_core::tools::{PinError, PinRequest, StepRecorder, add_pins, remove_pins, solver_for};

/// Whether `cmd` may change the clay's pin list.
pub(super) fn may_change_pins(cmd: &Command) -> bool {
    matches!(
        cmd,
        Command::Constrain { .. }
            | Command::Unconstrain { .. }
            | Command::Undo
            | Command::Redo
            | Command::Load { .. }
    )
}

impl SimulationStage {
    /// Pins `request` on the clay (one undo step). Returns what was pinned, saying which
    /// points were first moved onto the surface.
    pub(super) fn pin(&mut self, request: &PinRequest) -> Result<String, PinError> {
        // A held stroke ends first (its region retires): the pin is its own undo step.
        self.end_stroke_now();
        let mut rec = StepRecorder::new("pin");
        rec.touch_constraints(&self.clay);
        let result = add_pins(&mut self.clay, request);
        self.commit(rec);
        result
    }

    /// Removes pin `index`, or every pin with `None` (one undo step).
    pub(super) fn unpin(&mut self, index: Option<usize>) -> Result<String, PinError> {
        self.end_stroke_now();
        let mut rec = StepRecorder::new("unpin");
        rec.touch_constraints(&self.clay);
        let result = remove_pins(&mut self.clay, index);
        self.commit(rec);
        result
    }

    /// Rebuilds the live region's constraint stage from the clay's pins (after the region
    /// was made or reloaded), on whichever patch the region moves: the pins hold the sum of
    /// the patches there. Pins that make no rows (outside the clay) cannot be held; they
    /// stay in the list so that saving loses nothing.
    pub(super) fn rebuild_pins(&mut self) {
        self.region_pins = match &self.region {
            Some(region) => {
                solver_for(
                    &self.clay.constraints,
                    &self.clay.density,
                    self.region_patch,
                    region,
                )
                .0
            }
            None => ConstraintSolver::empty(),
        };
    }
}
