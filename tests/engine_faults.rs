//! Faults: a stalled simulation fades the force to zero within the staleness limit while the
//! haptic loop keeps ticking; a device disconnect sends zero force, keeps the engine alive and
//! shows in the counters. Both run on an injected clock or in lockstep: no wall-clock rate or
//! slack is assumed, so they pass on a machine under any load.

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
