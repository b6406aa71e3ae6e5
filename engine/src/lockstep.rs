//! Deterministic single-thread mode: each haptic sample is followed by a fixed number of
//! simulation steps, then a graphics update. Used when driving from a replay file, so the same
//! recording gives the same final field bit for bit (the simulation depends only on the tool
//! samples, and the device's own clock drives the safety filter).

use std::time::Instant;

use crossbeam::channel::Sender;
use dynaclay_devices::{HapticDevice, SafetyCounters};

use super::command::Command;
use super::config::EngineConfig;
use super::counters::{CounterSnapshot, EngineCounters};
use super::error::EngineError;
use super::graphics::MeshSink;
use super::haptic::HapticOutcome;
use super::io_worker::{IoReport, IoWorker};
use super::simulation::SimulationStage;
use super::tool_sample::ToolSample;
use super::wiring::{Stages, build};
use dynaclay_core::field::{BSplineLattice, MultiPatchField};
use dynaclay_core::io::{Autosave, Session};
use dynaclay_core::mesh::BrickOctree;

/// A lockstep run in progress.
pub struct Lockstep {
    stages: Stages,
    io: IoWorker,
    steps_per_sample: u32,
    graphics_every: u64,
    ticks: u64,
}

/// What a finished lockstep run hands back.
pub struct LockstepReport {
    /// The simulation's final session.
    pub session: Session,
    /// Counters.
    pub counters: CounterSnapshot,
    /// The safety filter's counters.
    pub safety: SafetyCounters,
    /// The graphics stage's final octree.
    pub octree: BrickOctree,
    /// Saves and autosaves written, and their failures.
    pub io: IoReport,
    /// Closing the device at the end failed: the session is still here, whole.
    pub device_close_error: Option<dynaclay_devices::DeviceError>,
}

impl Lockstep {
    /// Opens `device` and wires the stages around `field`; the graphics stage runs every
    /// `graphics_every` samples (at least 1).
    ///
    /// # Errors
    /// When the device does not open or the mesh grid cannot be made.
    pub fn new(
        config: &EngineConfig,
        field: impl Into<MultiPatchField>,
        device: Box<dyn HapticDevice>,
        sink: Box<dyn MeshSink>,
        graphics_every: u64,
    ) -> Result<Self, EngineError> {
        let stages = build(config, field, device, sink, true)?;
        let io = IoWorker::new(stages.io_jobs.clone(), stages.commands.clone());
        Ok(Self {
            stages,
            io,
            steps_per_sample: config.lockstep_steps_per_sample.max(1),
            graphics_every: graphics_every.max(1),
            ticks: 0,
        })
    }

    /// Where to send commands (applied before the next simulation step).
    #[must_use]
    pub fn commands(&self) -> Sender<Command> {
        self.stages.commands.clone()
    }

    /// Autosaves with `autosave` from now on (checked after every sample).
    pub fn set_autosave(&mut self, autosave: Autosave) {
        self.io.set_autosave(autosave);
    }

    /// The live counters.
    #[must_use]
    pub fn counters(&self) -> &EngineCounters {
        &self.stages.counters
    }

    /// One haptic sample, then the simulation steps, then (every `graphics_every`) graphics.
    ///
    /// The three loop bodies run as marked ticks, as on their own threads: a blocking path in
    /// one trips [`dynaclay_loops::assert_not_in_tick`] here too. The I/O poll is not a tick.
    pub fn step(&mut self) -> HapticOutcome {
        let out = {
            let _tick = dynaclay_loops::enter_tick();
            self.stages.haptic.tick(Instant::now())
        };
        for _ in 0..self.steps_per_sample {
            let _tick = dynaclay_loops::enter_tick();
            self.stages.sim.apply_commands();
            let sample = self.stages.samples.latest().value;
            self.stages.sim.step(&sample);
        }
        // Outside the ticks: a re-interpolation asked for by these steps is in before the
        // next sample, however fast the worker is, so the run stays deterministic.
        self.stages.sim.wait_compact();
        self.ticks += 1;
        if self.ticks.is_multiple_of(self.graphics_every) {
            let _tick = dynaclay_loops::enter_tick();
            self.stages.graphics.tick();
        }
        self.io.poll(Instant::now());
        out
    }

    /// The newest tool sample (for script drivers: its device time is the script clock).
    pub fn latest_tool(&mut self) -> ToolSample {
        self.stages.tool_monitor.latest().value
    }

    /// The simulation stage (its clay, history and tool).
    #[must_use]
    pub fn sim(&self) -> &SimulationStage {
        &self.stages.sim
    }

    /// The simulation's current base patch (see [`Self::density`] for every patch).
    #[must_use]
    pub fn field(&self) -> &BSplineLattice {
        self.stages.sim.lattice()
    }

    /// The haptic loop's copy of the density (what the arm feels).
    #[must_use]
    pub fn haptic_density(&self) -> &MultiPatchField {
        self.stages.haptic.field()
    }

    /// The simulation's current density: every patch of the clay.
    #[must_use]
    pub fn density(&self) -> &MultiPatchField {
        self.stages.sim.field()
    }

    /// Samples taken so far.
    #[must_use]
    pub fn ticks(&self) -> u64 {
        self.ticks
    }

    /// Ends the run: a last graphics update, the last undo step recorded, the device closed.
    ///
    /// A device that fails to close is reported in [`LockstepReport::device_close_error`];
    /// the session is handed back all the same.
    ///
    /// # Errors
    /// None today; kept for the engine's other end-of-run failures.
    pub fn finish(mut self) -> Result<LockstepReport, EngineError> {
        self.stages.sim.apply_commands();
        Ok(end_single_thread_run(&mut self.stages, &mut self.io))
    }
}

/// Ends a single-thread run (lockstep or replayed): the region retired and the last undo step
/// recorded, a last publication and graphics update, the haptic copy synced, the device closed
/// (a failure is reported in the report, the session handed back all the same).
pub(super) fn end_single_thread_run(stages: &mut Stages, io: &mut IoWorker) -> LockstepReport {
    stages.sim.finish();
    stages.sim.settle_compact();
    stages.sim.publish_now();
    stages.graphics.tick();
    stages.haptic.sync_field();
    io.poll(Instant::now());
    let safety = stages.haptic.device().counters();
    let device_close_error = stages.haptic.device_mut().close().err();
    LockstepReport {
        session: stages.sim.session(),
        counters: stages.counters.snapshot(),
        safety,
        octree: stages.graphics.octree().clone(),
        io: io.report().clone(),
        device_close_error,
    }
}
