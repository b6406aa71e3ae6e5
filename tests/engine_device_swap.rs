//! Switching devices while the engine runs: the haptic loop keeps ticking through a switch, a
//! disconnect and a reconnect; the replaced device gets zero force and is closed; a device
//! that fails to open leaves the current one in place.

mod common;

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::time::{Duration, Instant};

use dynaclay::engine::{Command, Engine, EngineError, HeadlessSink};
use dynaclay_devices::{
    DeviceError, DeviceInfo, DeviceState, HapticDevice, Interpolation, SimArmConfig, SimulatedArm,
    Trajectory, Waypoint,
};
use glam::Vec3;

/// A simulated arm that reports, through shared flags, whether it was closed and the last
/// force it was sent (bits of its magnitude).
struct Watched {
    arm: SimulatedArm,
    closed: Arc<AtomicBool>,
    last_force_bits: Arc<AtomicU32>,
}

impl Watched {
    fn holding(position_m: Vec3) -> (Self, Arc<AtomicBool>, Arc<AtomicU32>) {
        Self::following(Trajectory::hold(position_m))
    }

    /// An arm whose hand comes down from above the block into it (2 cm deep at the centre).
    fn pressing_in() -> (Self, Arc<AtomicBool>, Arc<AtomicU32>) {
        let path = vec![
            Waypoint::new(0.0, Vec3::new(0.0, 0.08, 0.0)),
            Waypoint::new(0.5, Vec3::new(0.0, 0.03, 0.0)),
        ];
        Self::following(Trajectory::new(path, Interpolation::Linear).expect("trajectory"))
    }

    fn following(trajectory: Trajectory) -> (Self, Arc<AtomicBool>, Arc<AtomicU32>) {
        let closed = Arc::new(AtomicBool::new(false));
        let last = Arc::new(AtomicU32::new(0));
        let arm = SimulatedArm::new(SimArmConfig::default(), trajectory);
        (
            Self {
                arm,
                closed: Arc::clone(&closed),
                last_force_bits: Arc::clone(&last),
            },
            closed,
            last,
        )
    }
}

impl HapticDevice for Watched {
    fn info(&self) -> DeviceInfo {
        self.arm.info()
    }
    fn open(&mut self) -> Result<(), DeviceError> {
        self.arm.open()
    }
    fn close(&mut self) -> Result<(), DeviceError> {
        self.closed.store(true, Ordering::SeqCst);
        self.arm.close()
    }
    fn is_open(&self) -> bool {
        self.arm.is_open()
    }
    fn read(&mut self) -> Result<DeviceState, DeviceError> {
        self.arm.read()
    }
    fn write_force(&mut self, force_n: Vec3) -> Result<(), DeviceError> {
        self.last_force_bits
            .store(force_n.length().to_bits(), Ordering::SeqCst);
        self.arm.write_force(force_n)
    }
}

/// A device whose port cannot be opened.
struct Unpluggable;

impl HapticDevice for Unpluggable {
    fn info(&self) -> DeviceInfo {
        SimArmConfig::default().info
    }
    fn open(&mut self) -> Result<(), DeviceError> {
        Err(DeviceError::Disconnected)
    }
    fn close(&mut self) -> Result<(), DeviceError> {
        Ok(())
    }
    fn is_open(&self) -> bool {
        false
    }
    fn read(&mut self) -> Result<DeviceState, DeviceError> {
        Err(DeviceError::NotOpen)
    }
    fn write_force(&mut self, _force_n: Vec3) -> Result<(), DeviceError> {
        Err(DeviceError::NotOpen)
    }
}

/// Waits until `cond` holds (10 s at most), reading the engine's newest tool sample.
fn wait_for(engine: &mut Engine, what: &str, cond: impl Fn(&dynaclay::engine::ToolSample) -> bool) {
    let start = Instant::now();
    loop {
        let s = engine.latest_tool();
        if cond(&s) {
            return;
        }
        assert!(
            start.elapsed() < Duration::from_secs(10),
            "timed out: {what}; last {s:?}"
        );
        std::thread::sleep(Duration::from_millis(2));
    }
}

#[test]
fn devices_switch_disconnect_and_reconnect_while_the_haptic_loop_keeps_ticking() {
    let s = common::setup(common::PUSH_SCRIPT, vec![]);
    let map = s.config.map;
    // The first arm comes down into the block: with a stroke armed it pushes and feels a force
    // when the switch comes.
    let (first, first_closed, first_force) = Watched::pressing_in();
    let mut engine = Engine::start(
        &s.config,
        s.field,
        Box::new(first),
        Box::new(HeadlessSink::default()),
    )
    .expect("engine starts");
    engine.commands().send(Command::StrokeStart).unwrap();
    wait_for(&mut engine, "a force on the first arm", |t| {
        t.in_contact && t.device_force_n.length() > 0.05
    });
    assert!(f32::from_bits(first_force.load(Ordering::SeqCst)) > 0.0);

    // Switch to a second arm held elsewhere.
    let (second, second_closed, _) = Watched::holding(Vec3::new(0.05, 0.0, 0.0));
    let report = engine
        .replace_device(Box::new(second), Duration::from_secs(5))
        .expect("switch");
    assert_eq!(
        report.replaced.as_ref().map(|d| d.name.as_str()),
        Some(SimArmConfig::default().info.name.as_str())
    );
    assert!(report.close.is_ok(), "{:?}", report.close);
    assert!(
        first_closed.load(Ordering::SeqCst),
        "the replaced arm was closed"
    );
    assert_eq!(
        f32::from_bits(first_force.load(Ordering::SeqCst)),
        0.0,
        "the replaced arm's last command was zero force"
    );
    engine.commands().send(Command::StrokeStop).unwrap();
    let at_second = map.to_field(Vec3::new(0.05, 0.0, 0.0));
    wait_for(&mut engine, "the second arm's position", |t| {
        t.tip_fu.distance(at_second) < 0.05 && !t.device_fault
    });

    // A device that will not open: an error, and the second arm stays in use.
    match engine.replace_device(Box::new(Unpluggable), Duration::from_secs(5)) {
        Err(EngineError::Device(DeviceError::Disconnected)) => {}
        other => panic!("expected the open error, got {other:?}"),
    }
    assert!(!second_closed.load(Ordering::SeqCst), "still connected");

    // Disconnect: the loop keeps ticking, idle, and counts no device faults.
    let report = engine
        .disconnect_device(Duration::from_secs(5))
        .expect("disconnect");
    assert!(
        second_closed.load(Ordering::SeqCst),
        "the second arm was closed"
    );
    assert_eq!(
        report.replaced.as_ref().map(|d| d.name.as_str()),
        Some(SimArmConfig::default().info.name.as_str())
    );
    let parked_at = engine.haptic_ticks();
    std::thread::sleep(Duration::from_millis(200));
    let parked = engine.latest_tool();
    assert!(
        engine.haptic_ticks() > parked_at + 50,
        "the haptic loop ticks while no device is connected"
    );
    assert_eq!(parked.device_force_n, Vec3::ZERO);
    assert!(!parked.device_fault && !parked.in_contact, "{parked:?}");

    // Reconnect a third arm: the empty slot comes back.
    let (third, third_closed, _) = Watched::holding(Vec3::new(0.0, 0.05, 0.0));
    let report = engine
        .replace_device(Box::new(third), Duration::from_secs(5))
        .expect("reconnect");
    assert_eq!(report.replaced, None, "nothing was connected");
    let at_third = map.to_field(Vec3::new(0.0, 0.05, 0.0));
    wait_for(&mut engine, "the third arm's position", |t| {
        t.tip_fu.distance(at_third) < 0.05
    });

    let done = engine.stop().expect("engine stops");
    assert!(
        third_closed.load(Ordering::SeqCst),
        "stop closes the device in use"
    );
    assert_eq!(done.counters.device_swaps, 3);
    assert_eq!(
        (
            done.counters.device_read_faults,
            done.counters.device_write_faults
        ),
        (0, 0),
        "switching is not a fault"
    );
}
