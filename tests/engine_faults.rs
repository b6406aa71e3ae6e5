//! Faults: a stalled simulation fades the force to zero within the staleness limit while the
//! haptic loop keeps ticking; a device disconnect sends zero force, keeps the engine alive and
//! shows in the counters. Both run on an injected clock or in lockstep: no wall-clock rate or
//! slack is assumed, so they pass on a machine under any load. A panic injected into the
//! graphics loop (through its mesh sink) or the haptic loop (through the device) stops every
//! loop, closes the device when its loop survived, and hands back the session; so does one in
//! the simulation loop or the I/O worker (the `fault-injection` hook, on in tests). These
//! wait for the fault to have happened, an event, and assume no rate.

mod common;

use std::time::{Duration, Instant};

use dynaclay::engine::{Engine, HeadlessSink, build};
use dynaclay_devices::{Fault, FaultKind};

#[test]
fn stalled_simulation_fades_force_to_zero_and_haptic_keeps_ticking() {
    // One thread plays both loops on an injected clock: the haptic tick is told the time, so
    // the test reads the same on a machine under any load.
    let s = common::setup(common::PUSH_SCRIPT, vec![]);
    let limit = s.config.stale_limit;
    let stages = build(
        &s.config,
        s.field,
        common::boxed(s.arm),
        Box::new(HeadlessSink::default()),
        false,
    )
    .expect("stages build");
    let mut haptic = stages.haptic;
    let mut sim = stages.sim;
    let mut samples = stages.samples;
    let mut monitor = stages.tool_monitor;
    let counters = stages.counters.clone();

    // Until the arm is well into its push, every tick sees a snapshot the simulation has just
    // published: the tick's time is read before the step, so the snapshot's age is zero.
    for _ in 0..750 {
        let now = Instant::now();
        sim.apply_commands();
        let sample = samples.latest().value;
        sim.step(&sample);
        haptic.tick(now);
    }
    let at_stall = monitor.latest().value;
    assert!(
        at_stall.in_contact,
        "pushing when the simulation stalls: {at_stall:?}"
    );
    assert!(at_stall.device_force_n.length() > 0.05, "{at_stall:?}");

    // Stall: no more steps, and the clock advances 1 ms a tick from here. The snapshot ages by
    // that clock (and by no less), so the force must reach zero by the staleness limit plus
    // the few ticks the safety filter's slew takes, stay there, and every tick still runs.
    let tick = Duration::from_millis(1);
    let stalled_at = Instant::now();
    let ticks_at_stall = counters.haptic_tick_count();
    let slew_ticks = 20;
    let limit_ticks = (limit.as_millis() as u32) + slew_ticks;
    let mut zero_from = None;
    for k in 1..=limit_ticks + 200 {
        haptic.tick(stalled_at + tick * k);
        let f = monitor.latest().value.device_force_n.length();
        if f == 0.0 {
            zero_from.get_or_insert(k);
        } else {
            assert!(
                k < limit_ticks,
                "force {f} N still on {k} ms after the stall (limit {limit:?})"
            );
            zero_from = None;
        }
    }
    let zero_from = zero_from.expect("force reached zero");
    assert!(zero_from <= limit_ticks, "zero from {zero_from} ms");
    assert_eq!(
        counters.haptic_tick_count() - ticks_at_stall,
        u64::from(limit_ticks + 200),
        "every tick ran"
    );
    assert!(counters.snapshot().stale_ticks > 0);
}

#[test]
fn device_disconnect_sends_zero_force_and_the_engine_stays_alive() {
    // The link drops for 0.3 s of device time in the middle of the push; the lockstep engine
    // runs 1.6 s of it, one sample and one simulation step at a time.
    let s = common::setup(
        common::PUSH_SCRIPT,
        vec![Fault::new(0.6, 0.3, FaultKind::Disconnect)],
    );
    let mut engine = dynaclay::engine::Lockstep::new(
        &s.config,
        s.field,
        common::boxed(s.arm),
        Box::new(HeadlessSink::default()),
        16,
    )
    .expect("engine starts");
    let (mut faulted, mut after_fault_ok) = (0u32, 0u32);
    let mut fault_seen = false;
    for _ in 0..1600 {
        engine.step();
        let t = engine.latest_tool();
        if t.device_fault {
            fault_seen = true;
            faulted += 1;
            assert_eq!(
                t.device_force_n.length(),
                0.0,
                "force during a fault: {t:?}"
            );
            assert!(!t.in_contact);
        } else if fault_seen {
            after_fault_ok += 1;
        }
    }
    assert_eq!(engine.ticks(), 1600, "the haptic loop kept running");
    let report = engine.finish().expect("engine stops after a disconnect");
    // 300 ms of disconnect at one read a tick: nearly every read in it faulted.
    assert!(faulted >= 250, "the disconnect was seen ({faulted} ticks)");
    assert!(
        after_fault_ok >= 500,
        "the device came back ({after_fault_ok} ticks)"
    );
    assert!(
        report.counters.device_read_faults >= 250,
        "{:?}",
        report.counters
    );
    assert!(report.safety.read_faults >= 250, "{:?}", report.safety);
}

/// A simulated arm whose peer vanishes at the very end: closing fails.
struct FailsToClose(dynaclay_devices::SimulatedArm);

impl dynaclay_devices::HapticDevice for FailsToClose {
    fn info(&self) -> dynaclay_devices::DeviceInfo {
        self.0.info()
    }
    fn open(&mut self) -> Result<(), dynaclay_devices::DeviceError> {
        self.0.open()
    }
    fn close(&mut self) -> Result<(), dynaclay_devices::DeviceError> {
        let _ = self.0.close();
        Err(dynaclay_devices::DeviceError::Disconnected)
    }
    fn is_open(&self) -> bool {
        self.0.is_open()
    }
    fn read(&mut self) -> Result<dynaclay_devices::DeviceState, dynaclay_devices::DeviceError> {
        self.0.read()
    }
    fn write_force(&mut self, force_n: glam::Vec3) -> Result<(), dynaclay_devices::DeviceError> {
        self.0.write_force(force_n)
    }
}

#[test]
fn a_device_that_fails_to_close_still_hands_back_the_sculpt() {
    let s = common::setup(common::PUSH_SCRIPT, Vec::new());
    let field = s.field.clone();
    let engine = Engine::start(
        &s.config,
        s.field,
        Box::new(FailsToClose(s.arm)),
        Box::new(HeadlessSink::default()),
    )
    .expect("engine starts");
    std::thread::sleep(Duration::from_millis(50));
    let report = engine
        .stop()
        .expect("a failed close does not cost the session");
    assert_eq!(
        report.device_close_error,
        Some(dynaclay_devices::DeviceError::Disconnected)
    );
    assert_eq!(
        report.session.clay.density.patches[0].lattice.dims,
        field.dims
    );
}

#[test]
fn a_lockstep_run_whose_device_fails_to_close_still_hands_back_the_sculpt() {
    let s = common::setup(common::PUSH_SCRIPT, Vec::new());
    let field = s.field.clone();
    let mut lockstep = dynaclay::engine::Lockstep::new(
        &s.config,
        s.field,
        Box::new(FailsToClose(s.arm)),
        Box::new(HeadlessSink::default()),
        16,
    )
    .expect("lockstep starts");
    for _ in 0..20 {
        lockstep.step();
    }
    let report = lockstep
        .finish()
        .expect("a failed close does not cost the session");
    assert!(report.device_close_error.is_some());
    assert_eq!(
        report.session.clay.density.patches[0].lattice.dims,
        field.dims
    );
}

/// What a [`Watched`] device saw.
#[derive(Default)]
struct Seen {
    reads: u64,
    last_force_n: Option<glam::Vec3>,
    closed: bool,
}

/// The simulated arm, watched: it counts reads, keeps the last force and whether it was
/// closed, and panics on read number `panic_at_read` (the fault injected into the haptic
/// loop).
struct Watched {
    arm: dynaclay_devices::SimulatedArm,
    seen: std::sync::Arc<std::sync::Mutex<Seen>>,
    panic_at_read: Option<u64>,
}

impl dynaclay_devices::HapticDevice for Watched {
    fn info(&self) -> dynaclay_devices::DeviceInfo {
        self.arm.info()
    }
    fn open(&mut self) -> Result<(), dynaclay_devices::DeviceError> {
        self.arm.open()
    }
    fn close(&mut self) -> Result<(), dynaclay_devices::DeviceError> {
        self.seen.lock().unwrap().closed = true;
        self.arm.close()
    }
    fn is_open(&self) -> bool {
        self.arm.is_open()
    }
    fn read(&mut self) -> Result<dynaclay_devices::DeviceState, dynaclay_devices::DeviceError> {
        let reads = {
            let mut seen = self.seen.lock().unwrap();
            seen.reads += 1;
            seen.reads
        };
        assert!(
            Some(reads) != self.panic_at_read,
            "injected: the haptic loop panics"
        );
        self.arm.read()
    }
    fn write_force(&mut self, force_n: glam::Vec3) -> Result<(), dynaclay_devices::DeviceError> {
        self.seen.lock().unwrap().last_force_n = Some(force_n);
        self.arm.write_force(force_n)
    }
}

/// A mesh sink that panics on its `panic_at`-th update (the fault injected into the graphics
/// loop).
struct PanickingSink {
    updates: u32,
    panic_at: u32,
}

impl dynaclay::mesh::MeshSink for PanickingSink {
    fn update(&mut self, _: &dynaclay::mesh::BrickOctree, _: &dynaclay::mesh::RefreshReport) {
        self.updates += 1;
        assert!(
            self.updates != self.panic_at,
            "injected: the graphics loop panics"
        );
    }
}

/// What a faulted run gives back: the error and what the device saw.
type Faulted = (
    dynaclay::engine::EngineError,
    std::sync::Arc<std::sync::Mutex<Seen>>,
);

/// Starts the threaded engine on the push script with the watched arm (panicking on read
/// `panic_at_read`, if any) and `sink`, sends `inject` (a panic asked of the simulation loop
/// or the I/O worker) once it runs, waits for the fault to have happened, and stops the
/// engine. Waiting is for an event, not a rate.
fn run_injected(
    panic_at_read: Option<u64>,
    sink: Box<dyn dynaclay::mesh::MeshSink>,
    inject: Option<dynaclay::engine::PanicSite>,
) -> Faulted {
    use dynaclay::engine::{Command, PanicSite};
    let s = common::setup(common::PUSH_SCRIPT, vec![]);
    let seen = std::sync::Arc::new(std::sync::Mutex::new(Seen::default()));
    let device = Box::new(Watched {
        arm: s.arm,
        seen: seen.clone(),
        panic_at_read,
    });
    let engine = Engine::start(&s.config, s.field, device, sink).expect("engine starts");
    // A failsafe only: every injected panic comes within the first second.
    let give_up = Instant::now() + Duration::from_secs(120);
    if let Some(site) = inject {
        engine.commands().send(Command::InjectPanic(site)).unwrap();
    }
    if inject == Some(PanicSite::Io) {
        // The I/O worker is not a loop: it has taken the job once a save goes unanswered. The
        // save is queued behind the injected job, so a dead worker drops its reply at once; the
        // long wait is a failsafe only.
        let probe = tempfile::tempdir().unwrap();
        while engine
            .save(&probe.path().join("probe.dclay"), Duration::from_secs(120))
            .is_ok()
        {
            assert!(Instant::now() < give_up, "the I/O worker kept answering");
        }
    } else {
        while engine.is_alive() {
            assert!(Instant::now() < give_up, "no loop died");
            std::thread::sleep(Duration::from_millis(5));
        }
    }
    let Err(e) = engine.stop() else {
        panic!("a stop after a loop panicked reported success")
    };
    (e, seen)
}

/// The parts of an [`EngineError::LoopsFailed`](dynaclay::engine::EngineError), with its
/// message.
struct LoopsFailed {
    failed: String,
    device_closed: bool,
    session: Option<Box<dynaclay::io::Session>>,
    text: String,
}

/// `e` as a [`LoopsFailed`]; panics (failing the test) on any other error.
fn loops_failed(e: dynaclay::engine::EngineError) -> LoopsFailed {
    let text = e.to_string();
    let dynaclay::engine::EngineError::LoopsFailed {
        failed,
        device_closed,
        session,
    } = e
    else {
        panic!("not a failure of the loops: {text}")
    };
    LoopsFailed {
        failed,
        device_closed,
        session,
        text,
    }
}

/// [`run_injected`] with the fault in the device or the sink alone.
fn run_until_a_loop_dies(
    panic_at_read: Option<u64>,
    sink: Box<dyn dynaclay::mesh::MeshSink>,
) -> Faulted {
    run_injected(panic_at_read, sink, None)
}

#[test]
fn a_panic_in_the_graphics_loop_stops_every_loop_closes_the_device_and_keeps_the_session() {
    let (e, seen) = run_until_a_loop_dies(
        None,
        Box::new(PanickingSink {
            updates: 0,
            panic_at: 3,
        }),
    );
    let LoopsFailed {
        failed,
        device_closed,
        session,
        text,
    } = loops_failed(e);
    assert!(
        failed.contains("graphics") && !failed.contains("haptic"),
        "{text}"
    );
    assert!(device_closed, "{text}");
    let seen = seen.lock().unwrap();
    assert!(seen.closed, "the device was closed");
    let session = session.expect("the simulation handed back its session");
    assert!(!session.clay.density.patches.is_empty());
    assert!(
        text.contains("zero force") && text.contains("session kept"),
        "{text}"
    );
}

#[test]
fn a_panic_in_the_haptic_loop_stops_every_loop_and_keeps_the_session() {
    let (e, seen) = run_until_a_loop_dies(Some(200), Box::new(HeadlessSink::default()));
    let LoopsFailed {
        failed,
        session,
        text,
        ..
    } = loops_failed(e);
    assert!(failed.contains("haptic"), "{text}");
    assert!(session.is_some(), "{text}");
    // The haptic stage is handed back as the panic unwinds, and closes the device.
    assert!(seen.lock().unwrap().closed, "{text}");
    // The haptic loop is gone: no read after the injected one.
    assert_eq!(seen.lock().unwrap().reads, 200);
}

#[test]
fn a_panic_in_the_simulation_loop_stops_every_loop_and_closes_the_device() {
    let (e, seen) = run_injected(
        None,
        Box::new(HeadlessSink::default()),
        Some(dynaclay::engine::PanicSite::Simulation),
    );
    let LoopsFailed {
        failed,
        device_closed,
        session,
        text,
    } = loops_failed(e);
    assert!(
        failed.contains("simulation") && !failed.contains("haptic"),
        "{text}"
    );
    assert!(device_closed && seen.lock().unwrap().closed, "{text}");
    // The stage is handed back as the panic unwinds (it panicked between commands), so the
    // sculpt up to the panic is kept.
    assert!(
        session.is_some_and(|s| !s.clay.density.patches.is_empty()),
        "{text}"
    );
    assert!(text.contains("session kept"), "{text}");
}

#[test]
fn a_panic_in_the_io_worker_still_closes_the_device_and_keeps_the_session() {
    let (e, seen) = run_injected(
        None,
        Box::new(HeadlessSink::default()),
        Some(dynaclay::engine::PanicSite::Io),
    );
    let LoopsFailed {
        failed,
        device_closed,
        session,
        text,
    } = loops_failed(e);
    assert!(failed.contains("I/O worker"), "{text}");
    assert!(device_closed && seen.lock().unwrap().closed, "{text}");
    assert!(
        session.is_some_and(|s| !s.clay.density.patches.is_empty()),
        "{text}"
    );
}

/// A start that fails after the haptic loop started (here the simulation loop's rate is
/// refused) stops the haptic loop and closes the device: no thread is left holding it.
#[test]
fn a_start_that_fails_after_the_haptic_loop_started_leaves_no_loop_holding_the_device() {
    let mut s = common::setup(common::PUSH_SCRIPT, vec![]);
    s.config.sim_rate_hz = f64::NAN;
    let seen = std::sync::Arc::new(std::sync::Mutex::new(Seen::default()));
    let device = Box::new(Watched {
        arm: s.arm,
        seen: seen.clone(),
        panic_at_read: None,
    });
    let Err(e) = Engine::start(
        &s.config,
        s.field,
        device,
        Box::new(HeadlessSink::default()),
    ) else {
        panic!("an engine with a NaN simulation rate started");
    };
    assert!(e.to_string().contains("rate_hz"), "{e}");
    assert!(seen.lock().unwrap().closed, "the device was closed");
    // The haptic loop was joined before the error came back: no read after it.
    let reads = seen.lock().unwrap().reads;
    std::thread::sleep(Duration::from_millis(20));
    assert_eq!(seen.lock().unwrap().reads, reads);
}

/// An engine dropped without being stopped (an owner that returned early or panicked) stops
/// every loop and closes the device before the drop returns: the haptic loop reads the arm no
/// more, and the device was closed (its driver commands zero force on close).
#[test]
fn an_engine_dropped_without_stop_stops_its_loops_and_closes_the_device() {
    let s = common::setup(common::PUSH_SCRIPT, vec![]);
    let seen = std::sync::Arc::new(std::sync::Mutex::new(Seen::default()));
    let device = Box::new(Watched {
        arm: s.arm,
        seen: seen.clone(),
        panic_at_read: None,
    });
    let engine = Engine::start(
        &s.config,
        s.field,
        device,
        Box::new(HeadlessSink::default()),
    )
    .expect("engine starts");
    // Wait for the haptic loop to be running (an event; the deadline is a failsafe only).
    let give_up = Instant::now() + Duration::from_secs(120);
    while seen.lock().unwrap().reads < 10 {
        assert!(
            Instant::now() < give_up,
            "the haptic loop never read the arm"
        );
        std::thread::sleep(Duration::from_millis(1));
    }
    drop(engine);
    let reads = seen.lock().unwrap().reads;
    assert!(seen.lock().unwrap().closed, "the device was closed");
    std::thread::sleep(Duration::from_millis(20));
    assert_eq!(
        seen.lock().unwrap().reads,
        reads,
        "a loop still reads the arm"
    );
}
