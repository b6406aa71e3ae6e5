//! Replaying a threaded run exactly: the recording's schedule decides how the loops interleave.
//!
//! A threaded run's outcome depends on more than the device's samples: which field snapshot
//! each haptic tick fetched (and how much its staleness faded the force), which tool sample
//! each simulation step took, and how many commands arrived before each step. A recorded
//! threaded run notes all of these beside the device's calls (see
//! [`dynaclay_devices::record::ScheduleNote`]). [`ScheduledReplay`] runs the same stages on one
//! thread and gives each tick and step exactly what it had, so the final field is the live
//! run's, bit for bit, however the live run's threads were scheduled.
//!
//! How the interleaving is rebuilt: before haptic tick `k`, the simulation runs recorded steps
//! until it has published the snapshot version tick `k` fetched. This is always possible in
//! order: the step that published that version ran before tick `k` fetched it, and took a
//! tool sample published before it, so from a tick earlier than `k`. Each step takes the
//! recorded tick's sample from the replay's own history of samples, and applies exactly the
//! recorded number of commands first. The graphics stage does not influence the field (its
//! acknowledgements only decide how large a snapshot's box is, never its values), so it runs
//! on its own cadence.
//!
//! Guarantee: the replay either reproduces the schedule or stops with a [`ReplayMismatch`]
//! naming the tick or step where the recording and this replay part (a different script, a
//! different starting clay, a recording from another build).

use std::time::Instant;

use crossbeam::channel::Sender;
use dynaclay_devices::record::{RecordedSchedule, ReplayDevice};

use super::command::Command;
use super::config::EngineConfig;
use super::error::{EngineError, ReplayMismatch};
use super::graphics::MeshSink;
use super::haptic::HapticOutcome;
use super::io_worker::IoWorker;
use super::lockstep::LockstepReport;
use super::tool_sample::ToolSample;
use super::wiring::{Stages, build};
use dynaclay_core::field::{BSplineLattice, MultiPatchField};

/// A replay of a recorded threaded run, one recorded haptic tick at a time.
pub struct ScheduledReplay {
    stages: Stages,
    io: IoWorker,
    schedule: RecordedSchedule,
    /// The sample each replayed tick published, by tick number (index 0: the idle sample
    /// before the first tick).
    samples: Vec<ToolSample>,
    next_step: usize,
    /// Whether the next step's commands have been applied already.
    next_step_commands_applied: bool,
    graphics_every: u64,
}

impl ScheduledReplay {
    /// Opens `device` (a recording with its schedule) and wires the stages around `field`,
    /// the clay the recorded run started from; the graphics stage runs every
    /// `graphics_every` ticks (at least 1).
    ///
    /// # Errors
    /// [`EngineError::Replay`] when the recording holds no usable schedule; otherwise as
    /// [`super::Lockstep::new`].
    pub fn new(
        config: &EngineConfig,
        field: impl Into<MultiPatchField>,
        device: ReplayDevice,
        sink: Box<dyn MeshSink>,
        graphics_every: u64,
    ) -> Result<Self, EngineError> {
        let schedule = device
            .schedule()
            .map_err(|gap| EngineError::Replay(ReplayMismatch::NoSchedule(gap)))?
            .clone();
        // The recorded run faded by staleness; the replay applies its recorded fades, so the
        // stages are built as for lockstep (no fade of their own).
        let stages = build(config, field, Box::new(device), sink, true)?;
        let io = IoWorker::new(stages.io_jobs.clone(), stages.commands.clone());
        let mut samples = Vec::with_capacity(schedule.ticks.len() + 1);
        samples.push(ToolSample::IDLE);
        Ok(Self {
            stages,
            io,
            schedule,
            samples,
            next_step: 0,
            next_step_commands_applied: false,
            graphics_every: graphics_every.max(1),
        })
    }

    /// Where to send commands: each step applies exactly as many as the recorded step did.
    #[must_use]
    pub fn commands(&self) -> Sender<Command> {
        self.stages.commands.clone()
    }

    /// Recorded haptic ticks.
    #[must_use]
    pub fn tick_count(&self) -> usize {
        self.schedule.ticks.len()
    }

    /// Ticks replayed so far.
    #[must_use]
    pub fn ticks(&self) -> u64 {
        self.samples.len() as u64 - 1
    }

    /// Whether every recorded tick has been replayed.
    #[must_use]
    pub fn ticks_done(&self) -> bool {
        self.samples.len() > self.schedule.ticks.len()
    }

    /// The newest tool sample (its device time is the script clock).
    #[must_use]
    pub fn latest_tool(&self) -> ToolSample {
        self.samples.last().copied().unwrap_or(ToolSample::IDLE)
    }

    /// The simulation's current base patch (see [`Self::density`] for every patch).
    #[must_use]
    pub fn field(&self) -> &BSplineLattice {
        self.stages.sim.lattice()
    }

    /// The simulation's current density: every patch of the clay.
    #[must_use]
    pub fn density(&self) -> &MultiPatchField {
        self.stages.sim.field()
    }

    /// The next recorded haptic tick, after the simulation steps that ran before it in the
    /// recorded run; `None` once every tick has been replayed.
    ///
    /// # Errors
    /// The [`ReplayMismatch`] where the replay cannot follow the recording.
    pub fn tick(&mut self) -> Result<Option<HapticOutcome>, EngineError> {
        let tick_number = self.ticks() + 1;
        let Some(recorded) = self.schedule.ticks.get(self.samples.len() - 1).copied() else {
            return Ok(None);
        };
        if let Some(version) = recorded.snapshot_version {
            while self.stages.sim.snapshot_version() < version {
                if !self.recorded_step()? {
                    break;
                }
            }
            let replayed = self.stages.sim.snapshot_version();
            if replayed != version {
                return Err(EngineError::Replay(ReplayMismatch::Snapshot {
                    tick: tick_number,
                    recorded: version,
                    replayed,
                }));
            }
        }
        let out = self
            .stages
            .haptic
            .tick_as_recorded(Instant::now(), recorded.fade);
        self.samples.push(out.sample);
        if self.ticks().is_multiple_of(self.graphics_every) {
            self.stages.graphics.tick();
        }
        self.io.poll(Instant::now());
        Ok(Some(out))
    }

    /// Runs the next recorded step (its commands first, if not applied yet); `false` when
    /// every recorded step has run.
    fn recorded_step(&mut self) -> Result<bool, EngineError> {
        let Some(step) = self.schedule.steps.get(self.next_step).copied() else {
            return Ok(false);
        };
        let index = self.next_step as u64;
        if !self.next_step_commands_applied {
            let sent = self.stages.sim.apply_commands_at_most(step.commands);
            if sent < step.commands {
                return Err(EngineError::Replay(ReplayMismatch::Commands {
                    step: index,
                    recorded: step.commands,
                    sent,
                }));
            }
            self.next_step_commands_applied = true;
        }
        let Some(sample) = usize::try_from(step.sample_tick)
            .ok()
            .and_then(|t| self.samples.get(t))
            .copied()
        else {
            return Err(EngineError::Replay(ReplayMismatch::FutureSample {
                step: index,
                sample_tick: step.sample_tick,
                ticks: self.ticks(),
            }));
        };
        self.stages.sim.step(&sample);
        self.next_step += 1;
        self.next_step_commands_applied = false;
        Ok(true)
    }

    /// Ends the replay as the recorded run ended: the recorded steps left (they ran after the
    /// last tick), then the last undo step recorded, a last graphics update and the device
    /// closed. Commands the recorded run never applied stay unapplied.
    ///
    /// # Errors
    /// The [`ReplayMismatch`] of a step left over that cannot run.
    pub fn finish(mut self) -> Result<LockstepReport, EngineError> {
        while self.recorded_step()? {}
        Ok(super::lockstep::end_single_thread_run(
            &mut self.stages,
            &mut self.io,
        ))
    }
}
