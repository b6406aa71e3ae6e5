//! The compact RBF clay on the stage's side (see [`super::super::compact_rbf`]): a contact
//! stroke's committed step sends the clay to the worker; its answer, polled between steps,
//! replaces the base patch's coefficients as one undo step.

#[allow(clippy::wildcard_imports)] // the stage's own module: its types and imports
use super::*;
use crate::compact_rbf::{CompactRbfLink, CompactState, CompactStatus};
use dynaclay_import::rbf::RbfFile;

/// How many times a single-thread run's end waits for a re-interpolation that was re-run on a
/// newer clay (each wait can start at most one more job).
const SETTLE_ROUNDS: usize = 4;

impl SimulationStage {
    /// Switches the compact RBF clay on with the worker behind `link` (the current clay is
    /// interpolated at once: `I⁰`), or off with `None` (the worker ends after its job).
    pub(super) fn set_compact(&mut self, link: Option<CompactRbfLink>) {
        self.compact = link.map(CompactState::new);
        self.request_compact();
    }

    /// Sends the clay as it is now to the worker (or marks it to be sent when the job in
    /// flight ends). A clay of several patches is not held as an RBF: counted as a failure.
    pub(super) fn request_compact(&mut self) {
        let Some(c) = self.compact.as_mut() else {
            return;
        };
        c.cancelled = false;
        if self.clay.density.patches.len() != 1 || !self.clay.density.patches[0].is_identity() {
            c.status.failed += 1;
            return;
        }
        c.request(self.clay_revision, &self.clay.density.patches[0].lattice);
    }

    /// An undo, redo or load: an answer in flight is for a clay the user left; it is dropped
    /// and not re-run (re-running would clear the redo steps).
    pub(super) fn cancel_compact(&mut self) {
        if let Some(c) = self.compact.as_mut() {
            c.cancelled = true;
            c.rerun = false;
        }
    }

    /// Applies the worker's answer if it has arrived (never blocks): as one undo step when it
    /// was computed from the clay as it still is, else dropped and the newer clay sent again.
    /// An answer that arrives while a stroke is held or its region is settling waits for it.
    pub(super) fn poll_compact(&mut self) {
        let Some(mut c) = self.compact.take() else {
            return;
        };
        if let Some(answer) = c.poll() {
            if self.recorder.is_some() || self.region.is_some() {
                c.ready = Some(answer);
            } else {
                c.in_flight = None;
                c.status.busy = false;
                c.status.last_s = answer.elapsed_ns as f32 * 1e-9;
                if answer.revision != self.clay_revision {
                    c.status.superseded += 1;
                    c.rerun |= !c.cancelled;
                } else {
                    match answer.outcome {
                        Ok((lattice, file, report)) => {
                            if self.replace_base(&lattice) {
                                c.status.applied += 1;
                                c.status.centres = Some(report.centres);
                                c.status.last_residual_fu = report.max_residual as f32;
                                c.last = Some(file);
                            } else {
                                c.status.failed += 1;
                            }
                        }
                        Err(_) => c.status.failed += 1,
                    }
                }
                let rerun = c.rerun;
                self.compact = Some(c);
                if rerun {
                    self.request_compact();
                }
                return;
            }
        }
        self.compact = Some(c);
    }

    /// Writes `lattice`'s coefficients into the base patch as one undo step ("rbf
    /// re-interpolation"), marking it all for publication. `false` when the geometry differs.
    fn replace_base(&mut self, lattice: &BSplineLattice) -> bool {
        let base = &self.clay.density.patches[0].lattice;
        if base.dims != lattice.dims || base.coeffs.len() != lattice.coeffs.len() {
            return false;
        }
        // The new base must fit the clay's dense-brick budget in place of the old one.
        let dense = self.clay.dense_brick_count() - base.coeffs.dense_brick_count();
        let more = lattice.coeffs.dense_brick_count();
        if let Err(refused) = dynaclay_core::field::check_dense_room(dense, more, None) {
            self.refuse_for_budget(refused);
            return false;
        }
        let mut rec = StepRecorder::new("rbf re-interpolation");
        rec.touch(&self.clay, density_id(0), CoeffBox::whole(base.dims));
        self.clay.density.patches[0]
            .lattice
            .coeffs
            .clone_from(&lattice.coeffs);
        self.commit(rec);
        self.mark_all_changed();
        true
    }

    /// A contact stroke or tool step was committed: re-interpolate.
    pub(super) fn contact_committed(&mut self) {
        if let Some(c) = self.compact.as_mut() {
            c.rerun = true;
        }
        self.request_compact();
    }

    /// Whether a re-interpolation is running.
    #[must_use]
    pub fn compact_in_flight(&self) -> bool {
        self.compact
            .as_ref()
            .is_some_and(|c| c.in_flight.is_some() && c.ready.is_none())
    }

    /// Waits for the re-interpolation in flight (single-thread runs only: the lockstep engine
    /// waits between samples, so what it computes does not depend on the worker's speed). The
    /// answer is applied by the next step's commands.
    pub fn wait_compact(&mut self) {
        if let Some(c) = self.compact.as_mut() {
            c.wait();
        }
    }

    /// Waits for and applies every re-interpolation still due (the end of a single-thread
    /// run, after the last stroke's step was committed).
    pub fn settle_compact(&mut self) {
        for _ in 0..SETTLE_ROUNDS {
            if !self.compact_in_flight() {
                break;
            }
            self.wait_compact();
            self.poll_compact();
        }
    }

    /// The compact RBF clay's state as observers see it (all zero when off).
    #[must_use]
    pub fn compact_status(&self) -> CompactStatus {
        self.compact.as_ref().map(|c| c.status).unwrap_or_default()
    }

    /// The RBF the clay was last re-interpolated from, if the mode is on and one was applied.
    #[must_use]
    pub fn compact_rbf(&self) -> Option<&RbfFile> {
        self.compact.as_ref().and_then(|c| c.last.as_ref())
    }
}
