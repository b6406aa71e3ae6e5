//! The compact RBF clay in the live engine (Zhang et al. §5.4): a worker thread that
//! re-interpolates the clay after each contact stroke, and what the simulation stage keeps
//! about it.
//!
//! The worker is never a loop thread: it is started by whoever switches the mode on (the GUI's
//! bridge, a script driver, a test) and handed to the simulation stage inside
//! [`super::Command::SetCompactRbf`]. The stage sends it a copy of the base patch when a
//! contact stroke's undo step is committed (a non-blocking send) and polls for the answer
//! between steps (a non-blocking receive); the answer becomes one undo step through the
//! stage's history, like any tool step. Dropping the link (switching the mode off, another
//! link, the engine stopping) ends the worker after the job it is on.
//!
//! A stroke made while a re-interpolation runs is not lost: the answer is computed from an
//! older clay, so it is dropped when it arrives, and the clay as it is then (which holds both
//! strokes) is sent again. So there is at most one job in flight, and the clay the user ends
//! with is always the re-interpolation of every stroke made.

use std::time::Instant;

use crossbeam::channel::{Receiver, Sender, TryRecvError, bounded};

use dynaclay_core::field::BSplineLattice;
use dynaclay_import::rbf::{CompactClay, CompactError, CompactSettings, RbfFile, RbfFitReport};

/// A copy of the clay to re-interpolate.
#[derive(Debug)]
pub(super) struct CompactJob {
    /// The stage's clay revision the copy was taken at.
    pub revision: u64,
    /// The base patch, after the stroke.
    pub lattice: BSplineLattice,
}

/// A finished re-interpolation.
#[derive(Debug)]
pub(super) struct CompactAnswer {
    /// The revision of the clay it was computed from.
    pub revision: u64,
    /// The outcome: `I` fitted onto the lattice, and `I` itself.
    pub outcome: Result<(BSplineLattice, RbfFile, RbfFitReport), CompactError>,
    /// Wall time of the re-interpolation (for the GUI; nothing depends on it), nanoseconds.
    pub elapsed_ns: u64,
}

/// The engine's end of a compact RBF worker.
#[derive(Debug)]
pub struct CompactRbfLink {
    settings: CompactSettings,
    jobs: Sender<CompactJob>,
    answers: Receiver<CompactAnswer>,
}

impl CompactRbfLink {
    /// Starts a worker thread holding `settings.particles` particles.
    ///
    /// # Errors
    /// [`CompactStartError::Settings`] for a particle count out of range,
    /// [`CompactStartError::Thread`] when the thread cannot be started.
    pub fn spawn(settings: CompactSettings) -> Result<Self, CompactStartError> {
        let mut clay = CompactClay::new(settings)?;
        // One job and one answer at a time: the stage never has more than one in flight.
        let (jobs, job_rx) = bounded::<CompactJob>(1);
        let (answer_tx, answers) = bounded::<CompactAnswer>(1);
        std::thread::Builder::new()
            .name("compact rbf".into())
            .spawn(move || {
                while let Ok(job) = job_rx.recv() {
                    let start = Instant::now();
                    let outcome = clay
                        .reinterpolate(&job.lattice)
                        .map(|r| (r.lattice, r.file, r.report));
                    let answer = CompactAnswer {
                        revision: job.revision,
                        outcome,
                        elapsed_ns: u64::try_from(start.elapsed().as_nanos()).unwrap_or(u64::MAX),
                    };
                    if answer_tx.send(answer).is_err() {
                        break;
                    }
                }
            })
            .map_err(CompactStartError::Thread)?;
        Ok(Self {
            settings,
            jobs,
            answers,
        })
    }

    /// The settings the worker runs with.
    #[must_use]
    pub fn settings(&self) -> &CompactSettings {
        &self.settings
    }
}

/// Why a compact RBF worker could not start.
#[derive(Debug, thiserror::Error)]
pub enum CompactStartError {
    /// The settings were refused.
    #[error(transparent)]
    Settings(#[from] CompactError),
    /// The thread could not be started.
    #[error("cannot start the compact RBF thread: {0}")]
    Thread(std::io::Error),
}

/// What observers see of the compact RBF clay (plain data, published with [`super::SimStatus`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CompactStatus {
    /// Whether the mode is on.
    pub on: bool,
    /// Its particle count `N`.
    pub particles: usize,
    /// The RBF's centre count, once the first interpolation is in (fixed from then on).
    pub centres: Option<usize>,
    /// Whether a re-interpolation is running.
    pub busy: bool,
    /// Re-interpolations applied to the clay.
    pub applied: u64,
    /// Answers dropped because the clay changed while they were computed (re-run on the
    /// newer clay).
    pub superseded: u64,
    /// Re-interpolations that failed (the clay was left as it was).
    pub failed: u64,
    /// Wall time of the last re-interpolation, seconds (informative only).
    pub last_s: f32,
    /// Largest interpolation residual of the last one, field units.
    pub last_residual_fu: f32,
}

/// The stage's side: the link, the job in flight and whether the clay must be sent again.
#[derive(Debug)]
pub(super) struct CompactState {
    pub link: CompactRbfLink,
    /// The revision of the job in flight.
    pub in_flight: Option<u64>,
    /// A contact stroke was committed while a job ran: send the clay again when it ends.
    pub rerun: bool,
    /// An undo, redo or load happened since the job was sent: its answer is dropped and not
    /// re-run.
    pub cancelled: bool,
    /// An answer received while a stroke was held, applied or dropped after it.
    pub ready: Option<CompactAnswer>,
    /// The last applied RBF (for tests and exports).
    pub last: Option<RbfFile>,
    pub status: CompactStatus,
}

impl CompactState {
    pub fn new(link: CompactRbfLink) -> Self {
        let status = CompactStatus {
            on: true,
            particles: link.settings.particles,
            ..CompactStatus::default()
        };
        Self {
            link,
            in_flight: None,
            rerun: false,
            cancelled: false,
            ready: None,
            last: None,
            status,
        }
    }

    /// Sends `lattice` (a copy of the clay at `revision`) unless a job is in flight, in which
    /// case the clay is sent again when that one ends. Never blocks.
    pub fn request(&mut self, revision: u64, lattice: &BSplineLattice) {
        if self.in_flight.is_some() {
            self.rerun = true;
            return;
        }
        let job = CompactJob {
            revision,
            lattice: lattice.clone(),
        };
        // The channel holds one job and none is in flight, so this does not fail unless the
        // worker has stopped (then the mode does nothing more).
        if self.link.jobs.try_send(job).is_ok() {
            self.in_flight = Some(revision);
            self.rerun = false;
            self.status.busy = true;
        } else {
            self.status.failed += 1;
        }
    }

    /// The answer if it has arrived (never blocks).
    pub fn poll(&mut self) -> Option<CompactAnswer> {
        if let Some(a) = self.ready.take() {
            return Some(a);
        }
        self.in_flight?;
        match self.link.answers.try_recv() {
            Ok(a) => Some(a),
            Err(TryRecvError::Empty) => None,
            Err(TryRecvError::Disconnected) => {
                self.in_flight = None;
                self.status.busy = false;
                self.status.failed += 1;
                None
            }
        }
    }

    /// Waits for the job in flight to end (single-thread runs only: lockstep and replays,
    /// where a loop waiting is how the run stays independent of the worker's speed).
    pub fn wait(&mut self) {
        if self.in_flight.is_none() || self.ready.is_some() {
            return;
        }
        dynaclay_loops::assert_not_in_tick("a lockstep run waiting for its RBF re-interpolation");
        match self.link.answers.recv() {
            Ok(a) => self.ready = Some(a),
            Err(_) => {
                self.in_flight = None;
                self.status.busy = false;
                self.status.failed += 1;
            }
        }
    }
}
