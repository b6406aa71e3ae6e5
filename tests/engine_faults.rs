//! Faults: a stalled simulation fades the force to zero within the staleness limit while the
//! haptic loop keeps ticking; a device disconnect sends zero force, keeps the engine alive and
//! shows in the counters.

mod common;

use std::ops::ControlFlow;
use std::time::{Duration, Instant};

use dynaclay::engine::{Engine, HeadlessSink, build};
use dynaclay_devices::{Fault, FaultKind};
use dynaclay_loops::{LoopConfig, spawn_loop};

#[test]
fn stalled_simulation_fades_force_to_zero_and_haptic_keeps_ticking() {
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
    let handle = spawn_loop(LoopConfig::new("haptic-test"), move |tick| {
        haptic.tick(tick.woke);
        ControlFlow::Continue(())
    })
    .expect("haptic loop starts");

    // This thread is the simulation until the arm is well into its push.
    let deadline = Instant::now() + Duration::from_secs(5);
    while counters.haptic_tick_count() < 750 && Instant::now() < deadline {
        sim.apply_commands();
        let sample = samples.latest().value;
        sim.step(&sample);
        std::thread::sleep(Duration::from_micros(900));
    }
    let at_stall = monitor.latest().value;
    assert!(
        at_stall.in_contact,
        "pushing when the simulation stalls: {at_stall:?}"
    );
    assert!(at_stall.device_force_n.length() > 0.05, "{at_stall:?}");

    // Stall: no more steps. Force must reach zero by the staleness limit (plus scheduling
    // slack), and the haptic loop must keep ticking meanwhile (half the nominal rate is the
    // functional floor here: CI machines are shared).
    let stalled_at = Instant::now();
    let ticks_at_stall = counters.haptic_tick_count();
    let mut zero_since: Option<Instant> = None;
    while stalled_at.elapsed() < limit + Duration::from_millis(200) {
        let f = monitor.latest().value.device_force_n.length();
        if f == 0.0 {
            zero_since.get_or_insert_with(Instant::now);
        } else {
            assert!(
                stalled_at.elapsed() < limit + Duration::from_millis(20),
                "force {f} N still on {:?} after the stall",
                stalled_at.elapsed()
            );
            zero_since = None;
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    let zero_since = zero_since.expect("force reached zero");
    assert!(zero_since.duration_since(stalled_at) <= limit + Duration::from_millis(20));
    let ticked = counters.haptic_tick_count() - ticks_at_stall;
    let elapsed_ms = stalled_at.elapsed().as_millis() as u64;
    assert!(
        ticked >= elapsed_ms / 2,
        "haptic ticked {ticked} times in {elapsed_ms} ms of stall"
    );
    assert!(counters.snapshot().stale_ticks > 0);
    handle.stop_and_join().expect("haptic loop stops");
}

#[test]
fn device_disconnect_sends_zero_force_and_the_engine_stays_alive() {
    // The link drops for 0.3 s in the middle of the push.
    let s = common::setup(
        common::PUSH_SCRIPT,
        vec![Fault::new(0.6, 0.3, FaultKind::Disconnect)],
    );
    let mut engine = Engine::start(
        &s.config,
        s.field,
        common::boxed(s.arm),
        Box::new(HeadlessSink::default()),
    )
    .expect("engine starts");
    let started = Instant::now();
    let (mut faulted, mut after_fault_ok) = (0u32, 0u32);
    let mut fault_seen = false;
    while started.elapsed() < Duration::from_millis(1600) {
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
        assert!(engine.is_alive(), "a loop died");
        std::thread::sleep(Duration::from_millis(1));
    }
    let ticks = engine.haptic_ticks();
    let report = engine.stop().expect("engine stops after a disconnect");
    assert!(faulted > 50, "the disconnect was seen ({faulted} samples)");
    assert!(
        after_fault_ok > 20,
        "the device came back ({after_fault_ok} samples)"
    );
    assert!(ticks > 1000, "the haptic loop kept running ({ticks} ticks)");
    assert!(
        report.counters.device_read_faults >= 200,
        "{:?}",
        report.counters
    );
    assert!(report.safety.read_faults >= 200, "{:?}", report.safety);
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
    assert_eq!(report.session.clay.patches[0].dims, field.dims);
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
    assert_eq!(report.session.clay.patches[0].dims, field.dims);
}
