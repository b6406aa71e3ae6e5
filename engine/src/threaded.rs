//! The threaded engine: haptic, simulation and graphics loops on their own named threads, plus
//! an I/O thread that writes saves. State crosses threads only through triple buffers (field
//! patches, tool samples), crossbeam channels (commands, saves) and relaxed counters.

use std::ops::ControlFlow;
use std::thread::JoinHandle;
use std::time::Duration;

use crossbeam::channel::{Receiver, Sender, bounded};
use dynaclay_devices::record::ScheduleLog;
use dynaclay_devices::{
    DeviceError, DeviceInfo, HapticDevice, SafetyConfig, SafetyCounters, SafetyFilter,
};
use dynaclay_loops::{
    LatencyStats, LoopConfig, LoopHandle, LoopReport, OverrunPolicy, RtOutcome, SnapshotReader,
    spawn_loop, spawn_woken_loop, wake_bell,
};
use glam::Vec3;

use super::tool_sample::ToolSample;

use super::clock::EngineClock;
use super::command::Command;
use super::config::EngineConfig;
use super::counters::{CounterSnapshot, EngineCounters};
use super::device_swap::{DeviceHandover, DeviceSwapRequest, SwapFailure};
use super::error::{CommandError, EngineError, SwapRefused};
use super::force_limit::ForceLimit;
use super::graphics::{GraphicsStage, MeshSink};
use super::haptic::HapticStage;
use super::haptic_gain::HapticGain;
use super::io_worker::{IoReport, IoWorker};
use super::motion_to_photon::MeshStamp;
use super::sim_status::SimStatus;
use super::simulation::SimulationStage;
use super::wiring::build;
use super::workspace::{WorkspaceMap, reach_box};
use dynaclay_core::field::MultiPatchField;
use dynaclay_core::io::{Autosave, Session, load_session};
use dynaclay_core::mesh::BrickOctree;

/// Sends its value back on a channel when dropped, so a loop's closure returns its stage to
/// the thread that joins it (the loop runner does not return the closure).
struct Handback<T> {
    value: Option<T>,
    tx: Sender<T>,
}

impl<T> Drop for Handback<T> {
    fn drop(&mut self) {
        if let Some(v) = self.value.take() {
            // The receiver only disappears if the engine itself was dropped; nothing to tell.
            let _ = self.tx.send(v);
        }
    }
}

fn handback<T>(value: T) -> (Handback<T>, Receiver<T>) {
    let (tx, rx) = bounded(1);
    (
        Handback {
            value: Some(value),
            tx,
        },
        rx,
    )
}

/// A running engine.
pub struct Engine {
    haptic: LoopHandle,
    sim: LoopHandle,
    graphics: LoopHandle,
    io: Option<JoinHandle<IoReport>>,
    commands: Sender<Command>,
    counters: EngineCounters,
    tool: SnapshotReader<ToolSample>,
    status: SnapshotReader<SimStatus>,
    force_limit: ForceLimit,
    haptic_gain: HapticGain,
    haptic_back: Receiver<HapticStage>,
    sim_back: Receiver<SimulationStage>,
    graphics_back: Receiver<GraphicsStage>,
    device_swaps: DeviceSwapRequest,
    /// What a replacement device is fitted with: the safety settings, the clay's box (its
    /// workspace is mapped around it) and the force scale.
    safety: SafetyConfig,
    field_box: (Vec3, Vec3),
    force_n_per_reaction: f32,
    /// The clock every loop stamps with.
    clock: EngineClock,
    /// The stamps of the graphics loop's meshes, until someone who draws frames takes them.
    mesh_stamps: Option<SnapshotReader<MeshStamp>>,
}

/// What an engine starts with besides its clay and device.
#[derive(Debug, Default)]
pub struct StartOptions {
    /// Autosave: the I/O thread writes its recovery file when its policy says so (counting
    /// committed strokes and tool steps).
    pub autosave: Option<Autosave>,
    /// The recording's schedule log: the haptic and simulation loops note each tick and step
    /// into it, so that [`super::ScheduledReplay`] can reproduce the run bit for bit.
    pub schedule: Option<ScheduleLog>,
}

/// What a device replacement hands back about the device it replaced.
#[derive(Debug)]
pub struct DeviceSwapReport {
    /// The device now in use, as it describes itself once open (`None` after a disconnect).
    pub connected: Option<DeviceInfo>,
    /// The replaced device (`None` when none was connected).
    pub replaced: Option<DeviceInfo>,
    /// Its safety filter's counters since it was opened.
    pub replaced_safety: SafetyCounters,
    /// The result of closing it (the swap itself succeeded either way).
    pub close: Result<(), DeviceError>,
}

/// What a stopped engine hands back.
pub struct EngineReport {
    /// The simulation's final session (field and material).
    pub session: Session,
    /// The haptic loop's own field copy at the end (equals the session's field once the last
    /// patch arrived).
    pub haptic_field: MultiPatchField,
    /// The graphics stage's final octree.
    pub octree: BrickOctree,
    /// Latency reports of the haptic, simulation and graphics loops, in that order.
    pub loops: Vec<LoopReport>,
    /// Final counters.
    pub counters: CounterSnapshot,
    /// The safety filter's counters.
    pub safety: SafetyCounters,
    /// Saves and autosaves written by the I/O thread, and their failures.
    pub io: IoReport,
    /// Closing the device at the end failed: the session is still here, whole.
    pub device_close_error: Option<dynaclay_devices::DeviceError>,
    /// The latest edit refused for the clay's budgets (`counters.budget_refusals` counts
    /// them all).
    pub budget_refusal: Option<crate::BudgetRefusal>,
}

/// A stopped engine's report and the parts a new engine can start with
/// ([`Engine::stop_keeping_parts`]).
pub struct StoppedEngine {
    /// What [`Engine::stop`] hands back.
    pub report: EngineReport,
    /// The device, closed (`None` when none was connected).
    pub device: Option<Box<dyn HapticDevice>>,
    /// The mesh sink, holding no bricks.
    pub sink: Box<dyn MeshSink>,
}

impl Engine {
    /// Opens `device` and starts the three loops around `field`.
    ///
    /// The haptic thread asks for SCHED_FIFO at `config.haptic_rt_priority`; whether it got
    /// it is [`Engine::haptic_rt`]. It never fails on a refusal.
    ///
    /// # Errors
    /// When the device does not open, the mesh grid cannot be made or a thread cannot start.
    pub fn start(
        config: &EngineConfig,
        field: impl Into<MultiPatchField>,
        device: Box<dyn HapticDevice>,
        sink: Box<dyn MeshSink>,
    ) -> Result<Self, EngineError> {
        Self::start_with(config, field, device, sink, StartOptions::default())
    }

    /// [`Engine::start`] with `options` (autosave, a schedule log).
    ///
    /// # Errors
    /// As [`Engine::start`].
    pub fn start_with(
        config: &EngineConfig,
        field: impl Into<MultiPatchField>,
        device: Box<dyn HapticDevice>,
        sink: Box<dyn MeshSink>,
        options: StartOptions,
    ) -> Result<Self, EngineError> {
        let StartOptions { autosave, schedule } = options;
        // Before the device opens: a refused rate cap leaves nothing to close.
        let (graphics_bell, graphics_waiter) = wake_bell(config.graphics_max_rate_hz)?;
        let density = field.into();
        let field_box = reach_box(density.base());
        let mut stages = build(config, density, device, sink, false)?;
        stages.sim.set_graphics_wake(graphics_bell);
        if let Some(log) = schedule {
            stages.haptic.set_schedule_log(log.clone());
            stages.sim.set_schedule_log(log);
        }
        let status = stages
            .sim
            .take_status_reader()
            .ok_or(EngineError::Lost("simulation status"))?;
        let force_limit = stages.haptic.force_limit();
        let haptic_gain = stages.haptic.haptic_gain();
        let counters = stages.counters.clone();
        let commands = stages.commands.clone();
        let tool = stages.tool_monitor;
        let clock = stages.clock.clone();
        let mesh_stamps = Some(stages.mesh_stamps);
        let mut worker = IoWorker::new(stages.io_jobs, commands.clone());
        if let Some(a) = autosave {
            worker.set_autosave(a);
        }
        let io = std::thread::Builder::new()
            .name("dynaclay-io".into())
            .spawn(move || worker.run(Duration::from_millis(50)))
            .map_err(|source| {
                EngineError::Loop(dynaclay_loops::LoopError::Spawn {
                    loop_name: "io".into(),
                    source,
                })
            })?;

        let mut haptic_cfg = LoopConfig::new("haptic").with_rate_hz(config.haptic_rate_hz);
        if let Some(p) = config.haptic_rt_priority {
            haptic_cfg = haptic_cfg.with_rt_priority(p);
        }
        let (mut hb, haptic_back) = handback(stages.haptic);
        let haptic = spawn_loop(haptic_cfg, move |tick| {
            if let Some(stage) = hb.value.as_mut() {
                stage.tick(tick.woke);
            }
            ControlFlow::Continue(())
        })?;

        let (mut sb, sim_back) = handback(stages.sim);
        let mut samples = stages.samples;
        let sim_cfg = LoopConfig::new("simulation")
            .with_rate_hz(config.sim_rate_hz)
            .with_overrun(OverrunPolicy::Skip);
        let sim = match spawn_loop(sim_cfg, move |_| {
            if let Some(stage) = sb.value.as_mut() {
                stage.apply_commands();
                let sample = samples.latest().value;
                stage.step(&sample);
            }
            ControlFlow::Continue(())
        }) {
            Ok(sim) => sim,
            Err(e) => return Err(stop_started_loops(e, [haptic], &haptic_back)),
        };

        let (mut gb, graphics_back) = handback(stages.graphics);
        let gfx_cfg = LoopConfig::new("graphics")
            .with_rate_hz(config.graphics_rate_hz)
            .with_stats_every_ticks(60);
        // Woken by the simulation's publications of a change, no faster than the rate cap.
        let graphics = match spawn_woken_loop(gfx_cfg, graphics_waiter, move |_| {
            if let Some(stage) = gb.value.as_mut() {
                stage.tick();
            }
            ControlFlow::Continue(())
        }) {
            Ok(graphics) => graphics,
            Err(e) => return Err(stop_started_loops(e, [haptic, sim], &haptic_back)),
        };

        Ok(Self {
            haptic,
            sim,
            graphics,
            io: Some(io),
            commands,
            counters,
            tool,
            status,
            force_limit,
            haptic_gain,
            haptic_back,
            sim_back,
            graphics_back,
            device_swaps: stages.device_swaps,
            safety: config.safety,
            field_box,
            force_n_per_reaction: config.map.force_n_per_reaction,
            clock,
            mesh_stamps,
        })
    }

    /// The clock every loop of this engine stamps with (a frame's time must be read on it).
    #[must_use]
    pub fn clock(&self) -> EngineClock {
        self.clock.clone()
    }

    /// The stamps of the graphics loop's meshes, for whoever draws frames (there is one; the
    /// second call gets `None`). Fetch the stamp before the meshes: see
    /// [`super::motion_to_photon`].
    pub fn take_mesh_stamps(&mut self) -> Option<SnapshotReader<MeshStamp>> {
        self.mesh_stamps.take()
    }

    /// Switches the haptic loop to `device` while everything keeps running: opens it here
    /// behind a fresh safety filter (the engine's safety settings and the force limit in
    /// effect, so forces soft-start again), maps its workspace around the clay, hands it to
    /// the haptic loop, which installs it at its next tick after sending zero to the old
    /// device, and then closes the old device on this thread.
    ///
    /// # Errors
    /// When `device` does not open ([`EngineError::Device`]), or the haptic loop does not take
    /// it within `timeout` ([`EngineError::DeviceSwap`]; `device` is closed again). The old
    /// device stays in use in both cases.
    pub fn replace_device(
        &self,
        device: Box<dyn HapticDevice>,
        timeout: Duration,
    ) -> Result<DeviceSwapReport, EngineError> {
        let mut safety = self.safety;
        safety.max_force_n = self.force_limit.requested_n();
        let mut filter = SafetyFilter::with_config(device, safety);
        filter.open()?;
        let info = filter.device().info();
        let (lo, hi) = self.field_box;
        let map = WorkspaceMap::fitting(
            info.workspace_min_m,
            info.workspace_max_m,
            lo,
            hi,
            self.force_n_per_reaction,
        );
        self.swap(
            DeviceHandover {
                device: filter,
                map,
                connected: true,
            },
            timeout,
        )
    }

    /// Closes the device while the engine keeps running: the haptic loop sends it zero,
    /// parks (ticking, publishing an idle tool sample, keeping its field current) until
    /// [`Engine::replace_device`] connects another, and the device is closed on this thread.
    ///
    /// # Errors
    /// As [`Engine::replace_device`].
    pub fn disconnect_device(&self, timeout: Duration) -> Result<DeviceSwapReport, EngineError> {
        let (lo, hi) = self.field_box;
        let map = WorkspaceMap::fitting(lo, hi, lo, hi, self.force_n_per_reaction);
        self.swap(DeviceHandover::parked(map), timeout)
    }

    fn swap(
        &self,
        handover: DeviceHandover,
        timeout: Duration,
    ) -> Result<DeviceSwapReport, EngineError> {
        let connected = handover.connected.then(|| handover.device.device().info());
        match self.device_swaps.swap(handover, timeout) {
            Ok(mut old) => {
                // A parked slot holds the empty device: nothing was connected.
                let replaced = old.connected.then(|| old.device.device().info());
                let replaced_safety = old.device.counters();
                let close = old.device.close();
                Ok(DeviceSwapReport {
                    connected,
                    replaced,
                    replaced_safety,
                    close,
                })
            }
            Err(SwapFailure::NotTaken(mut new) | SwapFailure::Busy(mut new)) => {
                let _ = new.device.close();
                Err(EngineError::DeviceSwap(SwapRefused::NotTaken {
                    waited: timeout,
                }))
            }
            Err(SwapFailure::Lost) => Err(EngineError::DeviceSwap(SwapRefused::Lost)),
        }
    }

    /// Where to send commands.
    #[must_use]
    pub fn commands(&self) -> Sender<Command> {
        self.commands.clone()
    }

    /// The live counters.
    #[must_use]
    pub fn counters(&self) -> &EngineCounters {
        &self.counters
    }

    /// The newest tool sample from the haptic loop (wait-free).
    pub fn latest_tool(&mut self) -> ToolSample {
        self.tool.latest().value
    }

    /// The latest latency figures each loop published, named, in the order haptic,
    /// simulation, graphics (the order of [`EngineReport::loops`]). Wait-free: reads each
    /// loop's statistics triple buffer; a loop publishes them every `stats_every_ticks`
    /// ticks (about once a second at the default settings), zeros before the first time.
    pub fn loop_stats(&mut self) -> [(&'static str, LatencyStats); 3] {
        [
            ("haptic", self.haptic.monitor().latest_stats().value),
            ("simulation", self.sim.monitor().latest_stats().value),
            ("graphics", self.graphics.monitor().latest_stats().value),
        ]
    }

    /// The simulation's latest published status (undo and redo depth, material, region);
    /// `None` until its first step. Wait-free.
    pub fn sim_status(&mut self) -> Option<SimStatus> {
        let stamped = self.status.latest();
        (stamped.version != 0).then_some(stamped.value)
    }

    /// The force limit: [`ForceLimit::request`] reaches the safety filter at the next haptic
    /// tick (never above the device's own maximum); [`ForceLimit::applied_n`] is the bound in
    /// effect.
    #[must_use]
    pub fn force_limit(&self) -> &ForceLimit {
        &self.force_limit
    }

    /// The haptic gain: how strongly the sculpting reaction is felt (1: a 5 mm press into the
    /// fresh clay feels 2 N); a change applies from the next haptic tick.
    #[must_use]
    pub fn haptic_gain(&self) -> &HapticGain {
        &self.haptic_gain
    }

    /// Reads and validates the session at `path` on the calling thread, then asks the
    /// simulation to install it between two steps (see [`Command::Load`]). Returns the channel
    /// on which the simulation answers.
    ///
    /// # Errors
    /// The file's error (unreadable, not a session, corrupt: naming the path, section and
    /// offset) or a stopped simulation; the engine is unchanged then.
    pub fn request_load(
        &self,
        path: &std::path::Path,
    ) -> Result<Receiver<Result<String, CommandError>>, CommandError> {
        let session = load_session(path)?;
        let (tx, rx) = bounded(1);
        self.commands
            .send(Command::Load {
                session: Box::new(session),
                source: path.to_path_buf(),
                keep_history: false,
                reply: Some(tx),
            })
            .map_err(|_| CommandError::Stopped)?;
        Ok(rx)
    }

    /// [`Engine::request_load`], waiting up to `timeout` for the simulation's answer.
    ///
    /// # Errors
    /// As [`Engine::request_load`], the simulation's refusal (a lattice that does not fit),
    /// or a timeout.
    pub fn load(&self, path: &std::path::Path, timeout: Duration) -> Result<String, CommandError> {
        let rx = self.request_load(path)?;
        dynaclay_loops::assert_not_in_tick("Engine::load waiting for the simulation");
        rx.recv_timeout(timeout)
            .unwrap_or(Err(CommandError::NoAnswer {
                what: "load",
                waited: timeout,
            }))
    }

    /// Haptic ticks run so far.
    #[must_use]
    pub fn haptic_ticks(&self) -> u64 {
        self.counters.haptic_tick_count()
    }

    /// Whether the haptic thread got SCHED_FIFO.
    #[must_use]
    pub fn haptic_rt(&self) -> RtOutcome {
        self.haptic.rt_outcome()
    }

    /// Whether every loop thread is still running.
    #[must_use]
    pub fn is_alive(&self) -> bool {
        !(self.haptic.is_finished() || self.sim.is_finished() || self.graphics.is_finished())
    }

    /// Asks the simulation to save the session to `path` and waits up to `timeout` for the
    /// I/O thread's answer.
    ///
    /// # Errors
    /// Why the save was not written ([`CommandError::Save`]), a stopped simulation, or a
    /// timeout.
    pub fn save(&self, path: &std::path::Path, timeout: Duration) -> Result<(), CommandError> {
        let (tx, rx) = bounded(1);
        self.commands
            .send(Command::Save {
                path: path.to_path_buf(),
                as_session: false,
                reply: Some(tx),
            })
            .map_err(|_| CommandError::Stopped)?;
        dynaclay_loops::assert_not_in_tick("Engine::save waiting for the I/O thread");
        match rx.recv_timeout(timeout) {
            Ok(r) => Ok(r.map(|_| ())?),
            Err(_) => Err(CommandError::NoAnswer {
                what: "save",
                waited: timeout,
            }),
        }
    }

    /// Stops the loops (simulation and graphics first, then haptic), closes the device
    /// (commanding zero force) and hands back the final state and the latency reports.
    ///
    /// # Errors
    /// When a loop panicked or the device fails to close.
    pub fn stop(self) -> Result<EngineReport, EngineError> {
        self.stop_keeping_parts().map(|parts| parts.report)
    }

    /// [`Engine::stop`], handing back what a new engine on another clay can start with: the
    /// device (closed, zero force commanded; `None` when none was connected) and the mesh
    /// sink, told to forget its bricks ([`MeshSink::restart`]).
    ///
    /// # Errors
    /// As [`Engine::stop`].
    pub fn stop_keeping_parts(mut self) -> Result<StoppedEngine, EngineError> {
        dynaclay_loops::assert_not_in_tick("Engine::stop joining the loops");
        // Every loop is stopped and joined even when one of them failed, so none is left
        // running (the haptic one holding the device); the stages that came back are then
        // wound down as far as they can be.
        let sim = self.sim.stop_and_join();
        let graphics = self.graphics.stop_and_join();
        let haptic = self.haptic.stop_and_join();
        // The threads are joined: a stage is in its channel or was lost with its thread.
        let sim_stage = self.sim_back.try_recv().ok();
        let graphics_stage = self.graphics_back.try_recv().ok();
        let haptic_stage = self.haptic_back.try_recv().ok();
        let failed: Vec<String> = [
            ("simulation", sim.as_ref().err(), sim_stage.is_none()),
            (
                "graphics",
                graphics.as_ref().err(),
                graphics_stage.is_none(),
            ),
            ("haptic", haptic.as_ref().err(), haptic_stage.is_none()),
        ]
        .into_iter()
        .filter(|(_, err, lost)| err.is_some() || *lost)
        .map(|(name, err, _)| match err {
            Some(e) => format!("the {name} loop: {e}"),
            None => format!("the {name} loop ended without handing back its state"),
        })
        .collect();
        let (sim, graphics, haptic, mut sim_stage, mut graphics_stage, mut haptic_stage) = match (
            sim,
            graphics,
            haptic,
            sim_stage,
            graphics_stage,
            haptic_stage,
        ) {
            (Ok(s), Ok(g), Ok(h), Some(ss), Some(gs), Some(hs)) => (s, g, h, ss, gs, hs),
            (_, _, _, sim_stage, _, haptic_stage) => {
                return Err(wind_down_after_failure(
                    failed.join("; "),
                    sim_stage,
                    haptic_stage,
                    self.commands,
                    self.io.take(),
                ));
            }
        };
        sim_stage.finish();
        // The loops have stopped: a compact RBF re-interpolation still running is waited for
        // and applied, so the session handed back holds every stroke's.
        sim_stage.settle_compact();
        sim_stage.publish_now();
        graphics_stage.tick();
        haptic_stage.sync_field();
        let safety = haptic_stage.device().counters();
        // A device that fails to close (unplugged, peer gone) costs nothing: the session
        // is handed back and the failure reported beside it.
        let device_close_error = haptic_stage.device_mut().close().err();
        let session = sim_stage.session();
        let budget_refusal = sim_stage.last_budget_refusal();
        drop(sim_stage);
        drop(self.commands);
        let io = match self.io.take().map(JoinHandle::join) {
            Some(Ok(report)) => report,
            None => IoReport::default(),
            // Every loop has stopped and the device is closed: the session is handed back
            // with the failure.
            Some(Err(_)) => {
                return Err(EngineError::LoopsFailed {
                    failed: "the I/O worker panicked (saves and autosaves after it were lost)"
                        .to_owned(),
                    device_closed: device_close_error.is_none(),
                    session: Some(Box::new(session)),
                });
            }
        };
        let haptic_field = haptic_stage.field().clone();
        let octree = graphics_stage.octree().clone();
        let connected = haptic_stage.is_connected();
        let mut sink = graphics_stage.into_sink();
        sink.restart();
        Ok(StoppedEngine {
            report: EngineReport {
                session,
                haptic_field,
                octree,
                loops: vec![haptic, sim, graphics],
                counters: self.counters.snapshot(),
                safety,
                io,
                device_close_error,
                budget_refusal,
            },
            device: connected.then(|| haptic_stage.into_device()),
            sink,
        })
    }
}

/// A start that failed after some loops started: those are stopped and joined (the
/// simulation first, the haptic loop last), and the haptic stage, handed back, closes its
/// device (zero force commanded), so no thread is left holding it.
fn stop_started_loops<const N: usize>(
    error: dynaclay_loops::LoopError,
    started: [LoopHandle; N],
    haptic_back: &Receiver<HapticStage>,
) -> EngineError {
    for handle in started.into_iter().rev() {
        let _ = handle.stop_and_join();
    }
    if let Ok(mut haptic) = haptic_back.try_recv() {
        let _ = haptic.device_mut().close();
    }
    EngineError::Loop(error)
}

/// After a loop failed: the haptic stage, if it came back, closes its device (zero force
/// commanded); the simulation stage, if it came back, hands over its session; the I/O thread
/// is let finish. The error names every loop that failed and carries the session.
fn wind_down_after_failure(
    failed: String,
    sim_stage: Option<SimulationStage>,
    haptic_stage: Option<HapticStage>,
    commands: Sender<Command>,
    io: Option<JoinHandle<IoReport>>,
) -> EngineError {
    let device_closed = haptic_stage.map(|mut h| h.device_mut().close());
    let session = sim_stage.map(|mut s| {
        s.finish();
        s.settle_compact();
        Box::new(s.session())
    });
    drop(commands);
    // The I/O thread ends once every sender is gone; a panic there is already lost.
    if let Some(io) = io {
        let _ = io.join();
    }
    EngineError::LoopsFailed {
        failed,
        device_closed: device_closed.is_some_and(|r| r.is_ok()),
        session,
    }
}
