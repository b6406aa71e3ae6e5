//! The haptic path end to end over the simulated arm: closed loop through the safety filter,
//! fault handling as the engine sees it, and no allocation per tick (counted by a global
//! allocator, per thread, so the recorder's writer thread does not count).

mod common;

use common::allocations;
use dynaclay_devices::sim_arm::{Fault, FaultKind, Interpolation, Waypoint};
use dynaclay_devices::{
    HapticDevice, RecordingDevice, ReplayDevice, SafetyConfig, SafetyFilter, SimArmConfig,
    SimulatedArm, Trajectory,
};
use glam::Vec3;

fn press() -> Trajectory {
    Trajectory::new(
        vec![
            Waypoint::new(0.0, Vec3::new(0.0, 0.01, 0.0)),
            Waypoint::with_buttons(0.3, Vec3::new(0.0, -0.02, 0.0), 1),
        ],
        Interpolation::Smooth,
    )
    .unwrap()
}

fn arm_with(faults: Vec<Fault>) -> SimulatedArm {
    SimulatedArm::new(
        SimArmConfig {
            faults,
            ..SimArmConfig::default()
        },
        press(),
    )
}

/// One haptic tick: read, a stiff wall at y = 0, write.
fn tick<D: HapticDevice>(f: &mut SafetyFilter<D>) -> Vec3 {
    let force = match f.read() {
        Ok(s) => Vec3::new(0.0, 2500.0 * (-s.position_m.y).max(0.0), 0.0),
        Err(_) => Vec3::ZERO,
    };
    // A failed write latches the filter to zero; the loop keeps running either way.
    let _ = f.write_force(force);
    f.output_force_n()
}

#[test]
fn disconnect_zeroes_force_and_recovery_soft_starts() {
    let faults = vec![Fault::new(1.0, 0.1, FaultKind::Disconnect)];
    let mut f = SafetyFilter::new(arm_with(faults));
    f.open().unwrap();
    let mut forces = Vec::new();
    for _ in 0..3000 {
        forces.push(tick(&mut f));
    }
    // In contact (still inside the 2 s soft start) just before the disconnect.
    let before = forces[990].y;
    assert!(before > 0.1, "pressing into the wall: {before}");
    // During the disconnect: the filter sends zero, the arm's motors are off.
    assert!(forces[1000..1100].iter().all(|f| *f == Vec3::ZERO));
    assert_eq!(f.counters().read_faults, 100);
    // After: a fresh soft start, so force comes back gradually, not in one step.
    let after = &forces[1100..1200];
    assert_eq!(after[0], Vec3::ZERO);
    assert!(
        after
            .windows(2)
            .all(|w| (w[1] - w[0]).length() <= 1.0 + 1e-4)
    );
    assert!(after[99].y < before, "{} vs {before}", after[99].y);
    assert_eq!(f.counters().soft_starts, 2);
    // The effector ends held at the wall, not at the hand's target 2 cm inside.
    let y = f.device().effector_position_m().y;
    assert!(y > -0.004, "{y}");
    assert!(forces.iter().all(|f| f.length() <= 8.0 + 1e-4));
}

#[test]
fn haptic_ticks_allocate_nothing() {
    let faults = vec![
        Fault::new(0.1, 0.05, FaultKind::Disconnect),
        Fault::new(0.2, 0.05, FaultKind::Stall),
        Fault::new(0.3, 0.1, FaultKind::Noise { std_m: 1e-4 }),
        Fault::new(0.4, 0.1, FaultKind::Drop { probability: 0.3 }),
        Fault::new(0.5, 0.1, FaultKind::Freeze),
    ];

    // Simulated arm behind the filter.
    let mut f = SafetyFilter::new(arm_with(faults.clone()));
    f.open().unwrap();
    let before = allocations();
    for _ in 0..700 {
        tick(&mut f);
    }
    assert_eq!(allocations() - before, 0, "sim arm + filter");

    // Recording on top: the haptic thread only encodes and pushes.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("a.dcrec");
    let recorder = RecordingDevice::create(arm_with(faults), &path).unwrap();
    let mut f = SafetyFilter::with_config(recorder, SafetyConfig::default());
    f.open().unwrap();
    let before = allocations();
    for _ in 0..700 {
        tick(&mut f);
    }
    assert_eq!(allocations() - before, 0, "recording");
    f.into_inner().finish().unwrap();

    // Replay.
    let mut f = SafetyFilter::new(ReplayDevice::load(&path).unwrap());
    f.open().unwrap();
    let before = allocations();
    for _ in 0..700 {
        tick(&mut f);
    }
    assert_eq!(allocations() - before, 0, "replay");
    assert_eq!(f.device().divergence().writes_differing, 0);
}
