//! Record a simulated-arm session through the lockstep engine, then replay the recording
//! twice: both replays end with the recorded run's field, bit for bit.

mod common;

use dynaclay::engine::{HeadlessSink, Lockstep};
use dynaclay::field::BSplineLattice;
use dynaclay_devices::HapticDevice;
use dynaclay_devices::record::{RecordingDevice, ReplayDevice};

fn run(
    config: &dynaclay::engine::EngineConfig,
    field: BSplineLattice,
    device: Box<dyn HapticDevice>,
    ticks: usize,
) -> BSplineLattice {
    let mut ls = Lockstep::new(config, field, device, Box::new(HeadlessSink::default()), 64)
        .expect("lockstep starts");
    for _ in 0..ticks {
        ls.step();
    }
    let report = ls.finish().expect("lockstep finishes");
    report.session.clay.patches[0].clone()
}

#[test]
fn replaying_a_recording_reproduces_the_field_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("push.rec");
    let s = common::setup(common::PUSH_SCRIPT, vec![]);
    let start = s.field.clone();
    let recorder = RecordingDevice::create(s.arm, &path).expect("recording starts");
    let ticks = 1500;
    // The recording device finishes its file when the lockstep run drops it.
    let recorded = run(&s.config, s.field, Box::new(recorder), ticks);
    assert_ne!(recorded, start, "the session sculpted something");

    let replay = ReplayDevice::load(&path).expect("recording loads");
    assert_eq!(replay.read_count(), ticks);
    let first = run(&s.config, start.clone(), Box::new(replay), ticks);
    let second = run(
        &s.config,
        start,
        Box::new(ReplayDevice::load(&path).unwrap()),
        ticks,
    );
    let bits = |l: &BSplineLattice| l.coeffs.iter().map(|c| c.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&first), bits(&second), "two replays differ");
    assert_eq!(
        bits(&first),
        bits(&recorded),
        "replay differs from the recorded run"
    );
}

/// A pointer (mouse) session: the app's hand-over is driven tick by tick along a drag over the
/// block's top, recorded, and replayed; the replay ends with the recorded field bit for bit.
#[test]
fn a_recorded_pointer_session_replays_bit_for_bit() {
    use dynaclay_devices::pointer::{PointerConfig, pointer_device};
    use glam::Vec3;

    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("pointer.rec");
    let s = common::setup(common::PUSH_SCRIPT, vec![]);
    let start = s.field.clone();
    let pointer = PointerConfig::default();
    let mut config = dynaclay::engine::EngineConfig::for_field(&start, &pointer.info());
    config.haptic_rt_priority = None;
    config.safety.soft_start_s = 0.1;
    let (device, mut handle) = pointer_device(pointer);
    let recorder = RecordingDevice::create(device, &path).expect("recording starts");
    let mut ls = Lockstep::new(
        &config,
        start.clone(),
        Box::new(recorder),
        Box::new(HeadlessSink::default()),
        64,
    )
    .expect("lockstep starts");
    let ticks = 1400;
    // Hover above the path, press down onto it, drag along x, lift.
    let tip = |tick: usize| -> (Vec3, bool) {
        let t = tick as f32;
        match tick {
            0..200 => (Vec3::new(0.75, 1.6, 0.95), false),
            200..300 => (Vec3::new(0.75, 1.6 - 0.3 * (t - 200.0) / 100.0, 0.95), true),
            300..1300 => (
                Vec3::new(0.75 + 0.4 * (t - 300.0) / 1000.0, 1.3, 0.95),
                true,
            ),
            _ => (Vec3::new(1.15, 1.6, 0.95), false),
        }
    };
    for tick in 0..ticks {
        let (p, pressed) = tip(tick);
        handle.set(config.map.to_device(p), pressed);
        ls.step();
    }
    let recorded = ls.finish().expect("lockstep finishes").session.clay.patches[0].clone();
    let iso = start.iso;
    let mid = Vec3::new(0.95, 1.35, 0.95);
    assert!(
        start.value(mid) > iso && recorded.value(mid) < iso,
        "the drag dented the top: {} → {}",
        start.value(mid),
        recorded.value(mid)
    );

    let replay = ReplayDevice::load(&path).expect("recording loads");
    assert_eq!(replay.read_count(), ticks);
    let replayed = run(&config, start, Box::new(replay), ticks);
    let bits = |l: &BSplineLattice| l.coeffs.iter().map(|c| c.to_bits()).collect::<Vec<_>>();
    assert_eq!(
        bits(&replayed),
        bits(&recorded),
        "replay differs from the recorded pointer session"
    );
}
