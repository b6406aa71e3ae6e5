//! Record a closed-loop session of the simulated arm through the safety filter, replay it, and
//! check that the replay is the same session call for call; damaged files are refused.

use dynaclay_devices::sim_arm::{Fault, FaultKind, Interpolation, Waypoint};
use dynaclay_devices::{
    DeviceError, DeviceState, HapticDevice, RecordError, RecorderConfig, RecordingDevice,
    ReplayDevice, SafetyConfig, SafetyFilter, SimArmConfig, SimulatedArm, Trajectory,
};
use glam::Vec3;

fn press_and_slide() -> Trajectory {
    Trajectory::new(
        vec![
            Waypoint::new(0.0, Vec3::new(0.0, 0.01, 0.0)),
            Waypoint::with_buttons(0.2, Vec3::new(0.0, -0.015, 0.0), 1),
            Waypoint::with_buttons(0.6, Vec3::new(0.04, -0.015, 0.01), 1),
            Waypoint::new(0.8, Vec3::new(0.04, 0.01, 0.01)),
        ],
        Interpolation::Smooth,
    )
    .unwrap()
}

fn faulty_arm() -> SimulatedArm {
    let config = SimArmConfig {
        seed: 77,
        faults: vec![
            Fault::new(0.0, 1.0, FaultKind::Noise { std_m: 2e-5 }),
            Fault::new(0.3, 0.02, FaultKind::Disconnect),
            Fault::new(0.5, 0.05, FaultKind::Drop { probability: 0.25 }),
            Fault::new(0.7, 0.01, FaultKind::Stall),
        ],
        ..SimArmConfig::default()
    };
    SimulatedArm::new(config, press_and_slide())
}

/// A wall at y = 0, solid below, 2 kN/m.
fn control(state: &Result<DeviceState, DeviceError>) -> Vec3 {
    match state {
        Ok(s) => Vec3::new(0.0, 2000.0 * (-s.position_m.y).max(0.0), 0.0),
        Err(_) => Vec3::ZERO,
    }
}

type Log = Vec<(
    Result<DeviceState, DeviceError>,
    Result<(), DeviceError>,
    Vec3,
)>;

/// Runs `ticks` haptic ticks; logs what each read returned, what the write returned and the
/// force the filter actually sent.
fn drive<D: HapticDevice>(filter: &mut SafetyFilter<D>, ticks: usize) -> Log {
    filter.open().unwrap();
    (0..ticks)
        .map(|_| {
            let state = filter.read();
            let written = filter.write_force(control(&state));
            (state, written, filter.output_force_n())
        })
        .collect()
}

fn safety() -> SafetyConfig {
    SafetyConfig {
        soft_start_s: 0.05,
        ..SafetyConfig::default()
    }
}

#[test]
fn replay_reproduces_the_recorded_session_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("session.dcrec");
    let recorder = RecordingDevice::with_config(
        faulty_arm(),
        &path,
        RecorderConfig {
            records_per_block: 100,
            ..RecorderConfig::default()
        },
    )
    .unwrap();
    let mut live = SafetyFilter::with_config(recorder, safety());
    let live_log = drive(&mut live, 900);
    let live_counters = live.counters();
    let (arm, summary) = live.into_inner().finish().unwrap();
    assert_eq!(summary.dropped, 0);
    // Every read and write reaches the file, including the zero the filter sends at once
    // on each read or write fault.
    assert_eq!(
        summary.records,
        1800 + live_counters.read_faults + live_counters.write_faults
    );
    assert!(summary.blocks >= 18);

    // The session did go through each fault.
    let c = arm.counters();
    assert!(
        c.disconnected > 0 && c.timeouts > 0 && c.dropped > 0 && c.noisy > 0,
        "{c:?}"
    );
    assert!(live_counters.read_faults > 0 && live_counters.soft_starts >= 3);
    // And the wall pushed back.
    assert!(live_log.iter().any(|(_, _, f)| f.y > 1.0));

    let replay = ReplayDevice::load(&path).unwrap();
    assert_eq!(replay.info(), faulty_arm().info());
    assert_eq!(replay.read_count(), 900);
    let mut replayed = SafetyFilter::with_config(replay, safety());
    let replay_log = drive(&mut replayed, 900);
    assert_eq!(replay_log.len(), live_log.len());
    for (i, (live, replay)) in live_log.iter().zip(&replay_log).enumerate() {
        assert_eq!(live.0, replay.0, "read {i}");
        assert_eq!(live.1.is_ok(), replay.1.is_ok(), "write result {i}");
        assert_eq!(
            live.2.to_array().map(f32::to_bits),
            replay.2.to_array().map(f32::to_bits),
            "force {i}"
        );
    }
    assert_eq!(replayed.counters(), live_counters);
    let d = replayed.device().divergence();
    assert_eq!(d.writes_differing, 0, "{d:?}");
    assert_eq!(d.writes_extra, 0, "{d:?}");
    assert!(d.writes_compared > 900);

    // Past the end: a clear error, and the filter sends zero.
    assert_eq!(
        replayed.read(),
        Err(DeviceError::EndOfRecording { samples: 900 })
    );
    assert!(replayed.fault_latched());
}

#[test]
fn replay_detects_a_diverging_controller() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.dcrec");
    let mut rec =
        RecordingDevice::create(SimulatedArm::with_trajectory(press_and_slide()), &path).unwrap();
    rec.open().unwrap();
    for _ in 0..100 {
        let s = rec.read();
        rec.write_force(control(&s)).unwrap();
    }
    rec.finish().unwrap();
    let mut replay = ReplayDevice::load(&path).unwrap();
    replay.open().unwrap();
    for _ in 0..100 {
        let s = replay.read();
        replay.write_force(control(&s) + Vec3::X * 0.5).unwrap();
    }
    replay.write_force(Vec3::ZERO).unwrap();
    let d = replay.divergence();
    assert_eq!(d.writes_compared, 100);
    assert_eq!(d.writes_differing, 100);
    assert_eq!(d.writes_extra, 1);
    assert!((d.max_difference_n - 0.5).abs() < 1e-6);
    replay.rewind();
    assert_eq!(replay.reads_remaining(), 100);
}

#[test]
fn recorder_dropped_without_finish_leaves_a_valid_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("dropped.dcrec");
    {
        let mut rec = RecordingDevice::create(faulty_arm(), &path).unwrap();
        rec.open().unwrap();
        for _ in 0..50 {
            let _ = rec.read();
        }
    }
    let replay = ReplayDevice::load(&path).unwrap();
    assert_eq!(replay.read_count(), 50);
    assert_eq!(replay.dropped_while_recording(), 0);
}

#[test]
fn never_opened_recorder_writes_an_empty_recording() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("empty.dcrec");
    let rec = RecordingDevice::create(faulty_arm(), &path).unwrap();
    let (_, summary) = rec.finish().unwrap();
    assert_eq!(summary.records, 0);
    let mut replay = ReplayDevice::load(&path).unwrap();
    replay.open().unwrap();
    assert_eq!(
        replay.read(),
        Err(DeviceError::EndOfRecording { samples: 0 })
    );
}

#[test]
fn a_full_queue_drops_and_counts_instead_of_waiting() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("tiny.dcrec");
    let mut rec = RecordingDevice::with_config(
        SimulatedArm::with_trajectory(press_and_slide()),
        &path,
        RecorderConfig {
            queue_capacity: 4,
            ..RecorderConfig::default()
        },
    )
    .unwrap();
    rec.open().unwrap();
    // Far faster than the writer's 1 ms poll: the 4-slot queue must overflow.
    for _ in 0..5000 {
        let _ = rec.read();
    }
    let dropped = rec.dropped();
    assert!(dropped > 0);
    let (_, summary) = rec.finish().unwrap();
    assert_eq!(summary.records + summary.dropped, 5000);
    let replay = ReplayDevice::load(&path).unwrap();
    assert_eq!(replay.dropped_while_recording(), summary.dropped);
}

fn recorded_bytes(dir: &std::path::Path) -> (std::path::PathBuf, Vec<u8>) {
    let path = dir.join("r.dcrec");
    let mut rec = RecordingDevice::with_config(
        faulty_arm(),
        &path,
        RecorderConfig {
            records_per_block: 10,
            ..RecorderConfig::default()
        },
    )
    .unwrap();
    rec.open().unwrap();
    for _ in 0..100 {
        let s = rec.read();
        let _ = rec.write_force(control(&s));
    }
    rec.finish().unwrap();
    let bytes = std::fs::read(&path).unwrap();
    (path, bytes)
}

#[test]
fn corrupt_file_is_refused_naming_path_block_and_offset() {
    let dir = tempfile::tempdir().unwrap();
    let (path, mut bytes) = recorded_bytes(dir.path());
    // Flip a bit in the middle of the file: some block's checksum must catch it.
    let at = bytes.len() / 2;
    bytes[at] ^= 0x10;
    std::fs::write(&path, &bytes).unwrap();
    let err = ReplayDevice::load(&path).unwrap_err();
    let RecordError::InFile { path: p, error } = &err else {
        panic!("{err}")
    };
    assert_eq!(p, &path);
    assert!(
        matches!(**error, RecordError::Checksum { block: Some(_), .. }),
        "{err}"
    );
    let offset = err.offset().unwrap() as usize;
    assert!(offset <= at && at < offset + 20 + 10 * 64, "{err}");
    let text = err.to_string();
    assert!(
        text.contains("r.dcrec") && text.contains("checksum") && text.contains("block"),
        "{text}"
    );
}

#[test]
fn truncated_file_is_refused_naming_the_offset() {
    let dir = tempfile::tempdir().unwrap();
    let (path, bytes) = recorded_bytes(dir.path());
    let cut = bytes.len() - 100;
    std::fs::write(&path, &bytes[..cut]).unwrap();
    let err = ReplayDevice::load(&path).unwrap_err();
    assert!(matches!(err.root(), RecordError::Truncated { .. }), "{err}");
    assert!(err.offset().unwrap() as usize <= cut);
    assert!(err.to_string().contains("truncated at byte"), "{err}");
}

#[test]
fn unwritable_path_is_an_io_error_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("missing-dir").join("x.dcrec");
    let Err(err) = RecordingDevice::create(faulty_arm(), &path) else {
        panic!("created a file in a missing directory")
    };
    assert!(matches!(err, RecordError::Io { .. }));
    assert!(err.to_string().contains("missing-dir"), "{err}");
    let err = ReplayDevice::load(&path).unwrap_err();
    assert!(err.to_string().contains("missing-dir"), "{err}");
}

#[test]
fn a_recording_appears_at_its_name_only_when_complete() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("take.dcrec");
    std::fs::write(&path, b"previous take").unwrap();
    let mut rec = RecordingDevice::create(faulty_arm(), &path).unwrap();
    rec.open().unwrap();
    for _ in 0..50 {
        let _ = rec.read();
    }
    // Still recording: the previous file is what a reader sees.
    assert_eq!(std::fs::read(&path).unwrap(), b"previous take");
    let (_, summary) = rec.finish().unwrap();
    assert_eq!(summary.records, 50);
    assert_eq!(ReplayDevice::load(&path).unwrap().read_count(), 50);
    let names: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
    assert_eq!(names.len(), 1, "no temporary file left");
}

#[test]
fn links_devices_and_endless_inputs_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let victim = dir.path().join("victim");
    std::fs::write(&victim, b"keep").unwrap();
    let link = dir.path().join("link.dcrec");
    std::os::unix::fs::symlink(&victim, &link).unwrap();
    for path in [link.as_path(), std::path::Path::new("/dev/full")] {
        let Err(err) = RecordingDevice::create(faulty_arm(), path) else {
            panic!("recorded into {}", path.display())
        };
        assert!(err.to_string().contains("refusing"), "{err}");
    }
    assert_eq!(std::fs::read(&victim).unwrap(), b"keep");
    let err = ReplayDevice::load("/dev/zero").unwrap_err();
    assert!(err.to_string().contains("not a regular file"), "{err}");
    let err = dynaclay_devices::profile::DeviceProfile::load("/dev/zero").unwrap_err();
    assert!(err.to_string().contains("not a regular file"), "{err}");
}
