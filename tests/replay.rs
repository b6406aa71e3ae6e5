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
