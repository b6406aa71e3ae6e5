//! Sends a [`ScriptPlan`]'s commands to a running engine when the script clock reaches them,
//! and collects the outcome of each tool, CSG and save step.
//!
//! The script clock is the device's clock (the tool sample's `device_time_us`, counted from
//! the first sample seen), so the simulated arm's strokes and the commands between them stay
//! in the order the plan defines, in the threaded engine and — exactly — in lockstep.

use std::path::PathBuf;

use crossbeam::channel::{Receiver, Sender, TryRecvError, bounded};
use glam::Vec3;

use super::command::{Command, EditOutcome, Reply};
use super::compact_rbf::CompactRbfLink;
use super::plan::{PlannedAction, PlannedEvent, PlannedStroke, ScriptPlan};
use super::removal_guard::{MOST_REMOVED_UNASKED, StrokeRemoval};
use super::tool_sample::ToolSample;
use dynaclay_core::io::{ScriptError, Session};
use dynaclay_files::WriteError;
use dynaclay_import::fit::{PointsError, read_points};
use dynaclay_import::particles::ParticleError;
use dynaclay_import::pointset::{
    PointSet, PointSetError, PointSetOptions, UnitFrame, pull, write_point_ply,
};
use dynaclay_import::rbf::{
    ExportError, ExportOptions, RbfFileError, clay_to_rbf, flatten_clay, settle_particles,
    write_particles, write_rbf,
};

/// Why a `points`, `particles` or `rbf` step's job failed.
#[derive(Debug, thiserror::Error)]
enum StepJobError {
    /// The point file could not be read.
    #[error("points: {0}")]
    ReadPoints(#[source] PointsError),
    /// The point-set surface could not be built from the cloud.
    #[error("points: {input}: {source}")]
    BuildPoints {
        /// The point file.
        input: PathBuf,
        /// Why.
        source: PointSetError,
    },
    /// A pull of the point set failed.
    #[error("points: pull to {target}: {source}")]
    Pull {
        /// Where the pull went, the file's coordinates.
        target: Vec3,
        /// Why.
        source: PointSetError,
    },
    /// The pulled points could not be written.
    #[error("points: {0}")]
    WritePoints(#[source] WriteError),
    /// The clay could not be flattened or interpolated.
    #[error("{0}")]
    Export(#[source] ExportError),
    /// The particles would not settle.
    #[error("particles: {0}")]
    Settle(#[source] ParticleError),
    /// The particles could not be written.
    #[error("particles: {0}")]
    WriteParticles(#[source] WriteError),
    /// The RBF could not be written.
    #[error("rbf: {0}")]
    WriteRbf(#[source] RbfFileError),
}

/// A `particles` or `rbf` step: what it computes from the clay's copy.
#[derive(Debug)]
enum ExportJob {
    Particles {
        options: ExportOptions,
        out: Option<std::path::PathBuf>,
    },
    Rbf {
        options: ExportOptions,
        out: std::path::PathBuf,
    },
}

/// A `points` step: a point-set surface built from a cloud, pulled, and written as PLY. It
/// needs no copy of the clay, so its thread starts when the step is sent.
fn points_job(
    input: &std::path::Path,
    pulls: &[glam::Vec3],
    steps: u32,
    out: &std::path::Path,
) -> Result<String, StepJobError> {
    let cloud = read_points(input).map_err(StepJobError::ReadPoints)?;
    // Built in the cloud's unit frame, so that any file units work; the output goes back.
    let frame = UnitFrame::of(&cloud.points);
    let (mut set, times) =
        PointSet::build(&frame.cloud_to_unit(&cloud), &PointSetOptions::default()).map_err(
            |source| StepJobError::BuildPoints {
                input: input.to_path_buf(),
                source,
            },
        )?;
    let mut note = format!(
        "points: {} points from {}, built in {:.3} s",
        set.len(),
        input.display(),
        times.total_ns() as f64 * 1e-9
    );
    for &target in pulls {
        let report = pull(&mut set, frame.to_unit(target), steps)
            .map_err(|source| StepJobError::Pull { target, source })?;
        note += &format!("; pulled to {target} ({} points)", report.points);
    }
    let points: Vec<glam::Vec3> = set.points.iter().map(|&p| frame.to_file(p)).collect();
    write_point_ply(out, &points, &set.normals, &set.colours).map_err(StepJobError::WritePoints)?;
    note += &format!("; wrote {}", out.display());
    Ok(note)
}

/// Where a `particles` or `rbf` step is: waiting for the engine's copy of the session, or
/// running on a thread of its own (never on a loop: sampling and solving take seconds).
enum ExportState {
    Waiting(ExportJob, Receiver<Session>),
    Running(Receiver<Result<String, StepJobError>>),
}

impl ExportJob {
    /// Samples (and interpolates) `session`'s clay and writes the result; the note to tell.
    fn run(self, session: &Session) -> Result<String, StepJobError> {
        match self {
            Self::Particles { options, out } => {
                let lattice = flatten_clay(&session.clay).map_err(StepJobError::Export)?;
                let particles =
                    settle_particles(&lattice, &options).map_err(StepJobError::Settle)?;
                let mut note = format!("{} particles settled", particles.len());
                if let Some(out) = out {
                    write_particles(&out, &lattice, particles.positions())
                        .map_err(StepJobError::WriteParticles)?;
                    note += &format!("; wrote {}", out.display());
                }
                Ok(note)
            }
            Self::Rbf { options, out } => {
                let fitted = clay_to_rbf(&session.clay, &options).map_err(StepJobError::Export)?;
                write_rbf(&out, &fitted.file).map_err(StepJobError::WriteRbf)?;
                Ok(format!(
                    "rbf: {} particles, {} centres of {} constraints, largest residual {:.2e}; \
                     wrote {}",
                    fitted.particles.len(),
                    fitted.report.centres,
                    fitted.report.constraints,
                    fitted.report.max_residual,
                    out.display()
                ))
            }
        }
    }
}

/// A plan being played.
pub struct ScriptDriver {
    file: String,
    events: std::vec::IntoIter<PlannedEvent>,
    next: Option<PlannedEvent>,
    origin_us: Option<u64>,
    /// Outcomes still to come: (step, receiver).
    waiting: Vec<(usize, Receiver<Result<String, super::CommandError>>)>,
    /// Tool and CSG outcomes still to come: (step, receiver).
    edits: Vec<(usize, Receiver<Result<EditOutcome, super::CommandError>>)>,
    /// Strokes that removed more than half the clay, as the simulation reports them; the
    /// sender goes to the simulation with the first dispatch.
    removals: Receiver<StrokeRemoval>,
    removals_to: Option<crossbeam::channel::Sender<StrokeRemoval>>,
    /// The plan's strokes (their steps and times), to find a reported stroke's step.
    strokes: Vec<PlannedStroke>,
    /// The line each step starts on, by 0-based step (0: unknown).
    step_lines: Vec<usize>,
    /// Steps that removed more than half the clay.
    warnings: Vec<ScriptError>,
    saves: Vec<(
        usize,
        Receiver<Result<std::path::PathBuf, super::SaveError>>,
    )>,
    /// Outcomes worth telling the user (pins: which points were moved onto the surface).
    telling: Vec<(usize, Receiver<Result<String, super::CommandError>>)>,
    /// `particles`, `rbf` and `points` steps not finished: (step, state).
    exports: Vec<(usize, ExportState)>,
    notes: Vec<(usize, String)>,
    failures: Vec<ScriptError>,
    sent: usize,
}

impl ScriptDriver {
    /// A driver for `plan`'s events.
    #[must_use]
    pub fn new(plan: &ScriptPlan) -> Self {
        let mut events = plan.events.clone().into_iter();
        let next = events.next();
        // One report per stroke at most: room for every stroke the plan has.
        let (removals_to, removals) = bounded(plan.strokes.len().max(1));
        Self {
            file: plan.file.clone(),
            events,
            next,
            origin_us: None,
            waiting: Vec::new(),
            edits: Vec::new(),
            removals,
            removals_to: Some(removals_to),
            strokes: plan.strokes.clone(),
            step_lines: plan.step_lines.clone(),
            warnings: Vec::new(),
            saves: Vec::new(),
            telling: Vec::new(),
            exports: Vec::new(),
            notes: Vec::new(),
            failures: Vec::new(),
            sent: 0,
        }
    }

    /// The script clock at device time `device_time_us`, seconds (zero at the first call).
    pub fn clock_s(&mut self, device_time_us: u64) -> f64 {
        let origin = *self.origin_us.get_or_insert(device_time_us);
        device_time_us.saturating_sub(origin) as f64 / 1e6
    }

    /// Sends every event due at the time of `sample` (the newest tool sample) on `commands`,
    /// in order. Returns how many were sent. Before the first haptic tick (tick 0) the clock
    /// has not started and nothing is sent.
    pub fn dispatch(&mut self, sample: &ToolSample, commands: &Sender<Command>) -> usize {
        if sample.tick == 0 {
            return 0;
        }
        if let Some(to) = self.removals_to.take() {
            // Before any stroke or step: every stroke over the limit is reported.
            let _ = commands.send(Command::ReportRemovals(to));
        }
        let now = self.clock_s(sample.device_time_us);
        let mut n = 0;
        while self.next.as_ref().is_some_and(|e| e.at_s <= now) {
            let Some(event) = self.next.take() else { break };
            self.send(event, commands);
            self.next = self.events.next();
            n += 1;
        }
        self.collect();
        n
    }

    /// Whether every event was sent.
    #[must_use]
    pub fn is_done(&self) -> bool {
        self.next.is_none()
    }

    /// Events sent so far.
    #[must_use]
    pub fn sent(&self) -> usize {
        self.sent
    }

    /// Steps not sent yet (the run ended before them).
    #[must_use]
    pub fn unsent_steps(&self) -> Vec<usize> {
        self.next
            .iter()
            .chain(self.events.as_slice())
            .map(|e| e.step)
            .collect()
    }

    /// Collects the outcomes that arrived and returns every failure so far, naming the file
    /// and the step. Outcomes of commands the simulation never applied are not failures.
    pub fn failures(&mut self) -> &[ScriptError] {
        self.collect();
        &self.failures
    }

    fn send(&mut self, event: PlannedEvent, commands: &Sender<Command>) {
        let step = event.step;
        let mut reply = || -> Reply {
            let (tx, rx) = bounded(1);
            self.waiting.push((step, rx));
            tx
        };
        let mut edit_reply = || {
            let (tx, rx) = bounded(1);
            self.edits.push((step, rx));
            tx
        };
        let batch: Vec<Command> = match event.action {
            PlannedAction::SetTool(t) => vec![Command::SetTool(t)],
            PlannedAction::SetMaterial(m) => vec![Command::SetMaterial(m)],
            PlannedAction::SetAutoDetail {
                automatic,
                force_tools,
            } => vec![Command::SetAutoDetail {
                automatic,
                force_tools,
            }],
            PlannedAction::PaintMaterial(paint) => {
                vec![Command::PaintMaterial { paint, reply: None }]
            }
            PlannedAction::Mask(edit) => vec![Command::Mask { edit, reply: None }],
            PlannedAction::ApplyTool {
                tool,
                poses,
                duration_s,
                patch,
            } => vec![Command::ApplyTool {
                tool,
                poses,
                duration_s,
                patch,
                reply: Some(edit_reply()),
            }],
            PlannedAction::MakeTool {
                name,
                selection,
                action,
                falloff_fu,
            } => {
                let (tx, rx) = bounded(1);
                self.telling.push((step, rx));
                vec![Command::MakeTool {
                    name,
                    selection,
                    action,
                    falloff_fu,
                    reply: Some(tx),
                }]
            }
            PlannedAction::ApplyLibraryTool {
                tool,
                poses,
                duration_s,
                patch,
            } => vec![Command::ApplyLibraryTool {
                tool,
                poses,
                duration_s,
                patch,
                reply: Some(edit_reply()),
            }],
            PlannedAction::SetLibraryTool(tool) => vec![Command::SetLibraryTool {
                tool,
                reply: Some(reply()),
            }],
            PlannedAction::Csg { op, other, patch } => vec![Command::Csg {
                op,
                other,
                patch,
                reply: Some(edit_reply()),
            }],
            PlannedAction::Emboss {
                relief,
                params,
                patch,
            } => vec![Command::Emboss {
                relief,
                params,
                patch,
                reply: Some(reply()),
            }],
            PlannedAction::Constrain(request) => {
                let (tx, rx) = bounded(1);
                self.telling.push((step, rx));
                vec![Command::Constrain {
                    request,
                    reply: Some(tx),
                }]
            }
            PlannedAction::Unconstrain(index) => {
                let (tx, rx) = bounded(1);
                self.telling.push((step, rx));
                vec![Command::Unconstrain {
                    index,
                    reply: Some(tx),
                }]
            }
            PlannedAction::Refine { lo, hi, level } => vec![Command::Refine {
                lo,
                hi,
                level,
                reply: Some(reply()),
            }],
            PlannedAction::Undo(k) => (0..k).map(|_| Command::Undo).collect(),
            PlannedAction::Redo(k) => (0..k).map(|_| Command::Redo).collect(),
            PlannedAction::Save(path) => {
                let (tx, rx) = bounded(1);
                self.saves.push((step, rx));
                vec![Command::Save {
                    path,
                    as_session: false,
                    reply: Some(tx),
                }]
            }
            PlannedAction::Particles { options, out } => {
                self.export(step, ExportJob::Particles { options, out })
            }
            PlannedAction::Rbf { options, out } => {
                self.export(step, ExportJob::Rbf { options, out })
            }
            PlannedAction::CompactRbf(settings) => match settings.map(CompactRbfLink::spawn) {
                None => vec![Command::SetCompactRbf(None)],
                Some(Ok(link)) => vec![Command::SetCompactRbf(Some(Box::new(link)))],
                Some(Err(e)) => {
                    self.fail(step, format!("compact_rbf: {e}"));
                    return;
                }
            },
            PlannedAction::Points {
                input,
                pulls,
                steps,
                out,
            } => {
                self.spawn_job(step, move || points_job(&input, &pulls, steps, &out));
                Vec::new()
            }
        };
        for cmd in batch {
            if commands.send(cmd).is_err() {
                self.fail(step, "the simulation loop has stopped".into());
                return;
            }
        }
        self.sent += 1;
    }

    /// Asks the engine for a copy of the session; `job` starts when it arrives.
    fn export(&mut self, step: usize, job: ExportJob) -> Vec<Command> {
        let (tx, rx) = bounded(1);
        self.exports.push((step, ExportState::Waiting(job, rx)));
        vec![Command::Snapshot { reply: tx }]
    }

    /// Runs `job` on a thread of its own; its outcome is gathered with the exports'.
    fn spawn_job(
        &mut self,
        step: usize,
        job: impl FnOnce() -> Result<String, StepJobError> + Send + 'static,
    ) {
        let (tx, done) = bounded(1);
        let spawned = std::thread::Builder::new()
            .name(format!("script step {step}"))
            .spawn(move || {
                let _ = tx.send(job());
            });
        match spawned {
            Ok(_) => self.exports.push((step, ExportState::Running(done))),
            Err(e) => self.fail(step, format!("cannot start its thread: {e}")),
        }
    }

    /// Starts the exports whose copy arrived, and gathers the finished ones. With `block`,
    /// waits for every copy and every job (the engine must have stopped or be running).
    fn collect_exports(&mut self, block: bool) {
        let mut told = Vec::new();
        let mut failed = Vec::new();
        for (step, state) in std::mem::take(&mut self.exports) {
            let state = match state {
                ExportState::Waiting(job, rx) => {
                    let copy = if block {
                        rx.recv().ok()
                    } else {
                        match rx.try_recv() {
                            Ok(session) => Some(session),
                            Err(TryRecvError::Empty) => {
                                self.exports.push((step, ExportState::Waiting(job, rx)));
                                continue;
                            }
                            Err(TryRecvError::Disconnected) => None,
                        }
                    };
                    // A copy the engine never made: the run ended first (not a failure, as
                    // for the other steps).
                    let Some(session) = copy else { continue };
                    let (tx, done) = bounded(1);
                    let spawned = std::thread::Builder::new()
                        .name(format!("script step {step}"))
                        .spawn(move || {
                            let _ = tx.send(job.run(&session));
                        });
                    if let Err(e) = spawned {
                        failed.push((step, format!("cannot start its thread: {e}")));
                        continue;
                    }
                    ExportState::Running(done)
                }
                running @ ExportState::Running(_) => running,
            };
            let ExportState::Running(done) = state else {
                continue;
            };
            let outcome = if block {
                done.recv().map_err(|_| TryRecvError::Disconnected)
            } else {
                done.try_recv()
            };
            match outcome {
                Ok(Ok(note)) => told.push((step, note)),
                Ok(Err(e)) => failed.push((step, e.to_string())),
                Err(TryRecvError::Empty) => self.exports.push((step, ExportState::Running(done))),
                Err(TryRecvError::Disconnected) => {
                    failed.push((step, "its thread stopped without an answer".into()));
                }
            }
        }
        self.notes.extend(told);
        for (step, e) in failed {
            self.fail(step, e);
        }
    }

    /// Waits for every `particles`, `rbf` and `points` step sent so far to finish (their files written
    /// or their failures recorded). Call it once the engine has stopped: a copy it never
    /// made is not waited for.
    pub fn wait_for_exports(&mut self) {
        if !self.exports.is_empty() {
            dynaclay_loops::assert_not_in_tick(
                "a script waiting for its particles, rbf and points steps",
            );
        }
        self.collect_exports(true);
    }

    fn collect(&mut self) {
        self.collect_exports(false);
        let mut failed = Vec::new();
        self.waiting.retain(|(step, rx)| match rx.try_recv() {
            Ok(Ok(_)) | Err(TryRecvError::Disconnected) => false,
            Ok(Err(e)) => {
                failed.push((*step, e.to_string()));
                false
            }
            Err(TryRecvError::Empty) => true,
        });
        self.saves.retain(|(step, rx)| match rx.try_recv() {
            Ok(Ok(_)) | Err(TryRecvError::Disconnected) => false,
            Ok(Err(e)) => {
                failed.push((*step, format!("save: {e}")));
                false
            }
            Err(TryRecvError::Empty) => true,
        });
        let mut large = Vec::new();
        self.edits.retain(|(step, rx)| match rx.try_recv() {
            Ok(Ok(outcome)) => {
                if outcome.removed_fraction > MOST_REMOVED_UNASKED {
                    large.push((
                        *step,
                        format!(
                            "this step removed about {:.0}% of the clay's volume (more than half) \
                             [{}]",
                            100.0 * outcome.removed_fraction,
                            outcome.note
                        ),
                    ));
                }
                false
            }
            Ok(Err(e)) => {
                failed.push((*step, e.to_string()));
                false
            }
            Err(TryRecvError::Disconnected) => false,
            Err(TryRecvError::Empty) => true,
        });
        while let Ok(r) = self.removals.try_recv() {
            let t = self.clock_s(r.started_us);
            // The stroke that had begun by then (its buttons go down after it leaves hover).
            let step = self
                .strokes
                .iter()
                .rev()
                .find(|s| s.start_s <= t + 1e-6)
                .map_or(0, |s| s.step);
            large.push((
                step,
                format!(
                    "the {} stroke removed about {:.0}% of the clay's volume (more than half)",
                    r.what, r.percent
                ),
            ));
        }
        for (step, message) in large {
            let line = self.line_of(step);
            self.warnings.push(ScriptError {
                file: self.file.clone(),
                line,
                column: None,
                step: (step > 0).then_some(step),
                message,
            });
        }
        let mut told = Vec::new();
        self.telling.retain(|(step, rx)| match rx.try_recv() {
            Ok(Ok(note)) => {
                told.push((*step, note));
                false
            }
            Ok(Err(e)) => {
                failed.push((*step, e.to_string()));
                false
            }
            Err(TryRecvError::Disconnected) => false,
            Err(TryRecvError::Empty) => true,
        });
        self.notes.extend(told);
        for (step, e) in failed {
            self.fail(step, e);
        }
    }

    /// What the steps that report their outcome said (step, message), in the order they
    /// arrived: each `constrain` step says what it pinned and which points it first moved
    /// onto the surface.
    pub fn notes(&mut self) -> &[(usize, String)] {
        self.collect();
        &self.notes
    }

    /// The steps that removed more than half the clay's volume (a tool or CSG step, or a
    /// stroke), each as file, line and step with what it removed, in the order they were
    /// reported. A run prints each as a warning.
    pub fn warnings(&mut self) -> &[ScriptError] {
        self.collect();
        &self.warnings
    }

    /// The line 1-based `step` starts on, when known.
    fn line_of(&self, step: usize) -> Option<usize> {
        step.checked_sub(1)
            .and_then(|n| self.step_lines.get(n))
            .copied()
            .filter(|&l| l > 0)
    }

    fn fail(&mut self, step: usize, message: String) {
        self.failures.push(ScriptError {
            file: self.file.clone(),
            line: None,
            column: None,
            step: Some(step),
            message,
        });
    }
}
