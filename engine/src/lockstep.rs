//! Deterministic single-thread mode: each haptic sample is followed by a fixed number of
//! simulation steps, then a graphics update. Used when driving from a replay file, so the same
//! recording gives the same final field bit for bit (the simulation depends only on the tool
//! samples, and the device's own clock drives the safety filter).
//!
//! The engine's clock is stepped: each sample sets it to the sample's haptic period times the
//! samples taken before it, so every stamp of a lockstep run (see
//! [`super::motion_to_photon`]) follows the schedule, not the machine. Whoever drives the run
//! may move it further between samples ([`Lockstep::clock`]).

use std::time::Instant;

use crossbeam::channel::Sender;
use dynaclay_devices::{HapticDevice, SafetyCounters};

use super::clock::EngineClock;
use super::command::Command;
use super::config::EngineConfig;
use super::counters::{CounterSnapshot, EngineCounters};
use super::error::EngineError;
use super::graphics::MeshSink;
use super::haptic::HapticOutcome;
use super::io_worker::{IoReport, IoWorker};
use super::motion_to_photon::MeshStamp;
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
    /// The haptic period, nanoseconds of the stepped clock.
    period_ns: u64,
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
    /// The latest edit refused for the clay's budgets (`counters.budget_refusals` counts
    /// them all).
    pub budget_refusal: Option<crate::BudgetRefusal>,
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
            period_ns: period_ns(config.haptic_rate_hz),
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
        self.stages.clock.set_ns(self.ticks * self.period_ns);
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

    /// The run's stepped clock (every stage stamps with it; see [`super::motion_to_photon`]).
    #[must_use]
    pub fn clock(&self) -> &EngineClock {
        &self.stages.clock
    }

    /// The graphics stage's octree: the meshes a frame drawn now would show.
    #[must_use]
    pub fn octree(&self) -> &BrickOctree {
        self.stages.graphics.octree()
    }

    /// The stamp of the graphics stage's newest meshes (what a frame drawn now would show).
    pub fn mesh_stamp(&mut self) -> MeshStamp {
        self.stages.mesh_stamps.latest().value
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

/// The period of `rate_hz`, nanoseconds (1 ms for a rate that is not a positive number).
fn period_ns(rate_hz: f64) -> u64 {
    if rate_hz.is_finite() && rate_hz > 0.0 {
        (1.0e9 / rate_hz).round() as u64
    } else {
        1_000_000
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
        budget_refusal: stages.sim.last_budget_refusal(),
    }
}

#[cfg(test)]
mod tests {
    use dynaclay_devices::{SimArmConfig, SimulatedArm};

    use super::super::{HeadlessSink, MotionToPhoton, ScriptDriver, ScriptPlan, build_clay};
    use super::*;

    /// Samples between two graphics updates, and between two frames, in the run below: the
    /// two never line up for long, so a change waits for both.
    const GRAPHICS_EVERY: u64 = 16;
    const FRAME_EVERY: u64 = 20;

    /// The built-in stroke in lockstep, a frame "drawn" every [`FRAME_EVERY`] samples at the
    /// stepped clock's time: every stamp is in order, the first visible change is the first
    /// sample whose step changed the clay, drawn by the first frame after the first graphics
    /// update after it, and the haptic loop felt it one tick later.
    #[test]
    fn the_builtin_stroke_is_stamped_in_order_and_its_first_change_is_its_first_pushing_sample() {
        let plan = ScriptPlan::builtin();
        let field = build_clay(&plan.clay).unwrap();
        let arm_config = SimArmConfig::default();
        let mut config = EngineConfig::for_field(&field, &arm_config.info);
        config.haptics.tool_contact = plan.tool_contact;
        let arm = SimulatedArm::new(arm_config, plan.trajectory(&config.map).unwrap());
        let mut run = Lockstep::new(
            &config,
            field,
            Box::new(arm),
            Box::new(HeadlessSink::default()),
            GRAPHICS_EVERY,
        )
        .unwrap();
        let mut driver = ScriptDriver::new(&plan);
        let commands = run.commands();
        let mut ledger = MotionToPhoton::new();
        let mut before = run.density().clone();
        // The first sample whose step changed the clay, found by comparing the fields.
        let mut first_change: Option<(u64, u64)> = None;
        let mut first_graphics_after: Option<u64> = None;
        let mut first_frame_after: Option<u64> = None;
        for _ in 0..(plan.seconds * 1000.0) as usize {
            let sample = run.latest_tool();
            driver.dispatch(&sample, &commands);
            let out = run.step();
            let now = run.clock().now_ns();
            if first_change.is_none() && *run.density() != before {
                first_change = Some((out.sample.tick, now));
            }
            before.clone_from(run.density());
            if first_change.is_some()
                && first_graphics_after.is_none()
                && run.ticks().is_multiple_of(GRAPHICS_EVERY)
            {
                first_graphics_after = Some(now);
            }
            if run.ticks().is_multiple_of(FRAME_EVERY) {
                let drawn = run.mesh_stamp();
                ledger.frame(now, &drawn);
                if first_graphics_after.is_some() && first_frame_after.is_none() {
                    first_frame_after = Some(now);
                }
            }
        }
        let (change_tick, change_ns) = first_change.expect("the stroke changed the clay");
        let strokes: Vec<_> = ledger.strokes().copied().collect();
        assert_eq!(strokes.len(), 1, "one stroke: {strokes:?}");
        let stroke = strokes[0];
        assert_eq!(stroke.first_change_tick, Some(change_tick));
        let first = stroke.first_visible.expect("the change was drawn");
        assert!(first.is_ordered(), "{first:?}");
        assert_eq!(
            first.sample_ns, change_ns,
            "read at the changing sample's tick"
        );
        assert_eq!(
            first.step_ns, change_ns,
            "one step per sample, at the sample's time"
        );
        assert_eq!(Some(first.meshed_ns), first_graphics_after);
        assert_eq!(Some(first.frame_ns), first_frame_after);
        assert!(first.frame_ns > first.sample_ns, "{first:?}");
        assert_eq!(
            stroke.hand_to_force_ticks,
            Some(1),
            "the next haptic tick applies the step's snapshot"
        );
        let settled = stroke
            .settled
            .expect("the clay settled before the run ended");
        assert!(settled.is_ordered(), "{settled:?}");
        assert!(settled.frame_ns >= first.frame_ns);
        let m = ledger.summary("lockstep");
        assert_eq!(m.strokes, 1);
        assert_eq!(m.first_visible_ms.p50, first.total_ms());
    }

    /// The built-in stroke in lockstep with a graphics update after every sample: while the
    /// clay relaxes, snapshots whose change is too small to see are held back (the graphics
    /// stage re-meshes fewer snapshots than changed the clay), and once the motion has
    /// stopped the meshes are, brick for brick, those of a full re-mesh of the final clay.
    #[test]
    fn changes_too_small_to_see_are_held_back_and_the_clay_at_rest_is_meshed_exactly() {
        let plan = ScriptPlan::builtin();
        let field = build_clay(&plan.clay).unwrap();
        let arm_config = SimArmConfig::default();
        let mut config = EngineConfig::for_field(&field, &arm_config.info);
        config.haptics.tool_contact = plan.tool_contact;
        let arm = SimulatedArm::new(arm_config, plan.trajectory(&config.map).unwrap());
        let mut run = Lockstep::new(
            &config,
            field,
            Box::new(arm),
            Box::new(HeadlessSink::default()),
            1,
        )
        .unwrap();
        let mut driver = ScriptDriver::new(&plan);
        let commands = run.commands();
        let mut before = run.density().clone();
        let mut changing_samples = 0u64;
        let script_samples = (plan.seconds * 1000.0) as usize;
        // The script, then until the stroke is known settled (its region retired), then a
        // few samples more.
        let mut settled_at: Option<usize> = None;
        for i in 0..script_samples + 10_000 {
            let sample = run.latest_tool();
            driver.dispatch(&sample, &commands);
            run.step();
            if *run.density() != before {
                changing_samples += 1;
            }
            before.clone_from(run.density());
            if i >= script_samples
                && settled_at.is_none()
                && run.mesh_stamp().stroke.settled.is_some()
            {
                settled_at = Some(i);
            }
            if settled_at.is_some_and(|at| i >= at + 20) {
                break;
            }
        }
        assert!(settled_at.is_some(), "the stroke settled within the run");
        let counters = run.counters().snapshot();
        assert!(
            counters.graphics_deferred > 0,
            "some re-meshes were held back: {counters:?}"
        );
        assert!(
            counters.graphics_updates < changing_samples,
            "{} re-meshes for {changing_samples} samples that changed the clay",
            counters.graphics_updates
        );
        let full = BrickOctree::build(*run.octree().grid(), run.density());
        let kept = run.octree();
        assert_eq!(kept.brick_count(), full.brick_count());
        for brick in full.bricks() {
            let mine = kept
                .brick(brick.coord)
                .unwrap_or_else(|| panic!("brick {:?} missing", brick.coord));
            assert!(
                mine.mesh == brick.mesh,
                "brick {:?} differs from a full re-mesh",
                brick.coord
            );
        }
    }
}
