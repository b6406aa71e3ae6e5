//! The engine in lockstep for 1.6 s of device time with the simulated arm pushing into the
//! block along a scripted path: a dent where it pushed and nothing elsewhere, a bounded
//! reaction that always points from the tip back toward the surface it pushed from, no NaN.
//! Lockstep makes it deterministic: no wall-clock rate, no scheduling luck.

mod common;

use dynaclay::engine::{HeadlessSink, Lockstep};
use glam::Vec3;

#[test]
fn simulated_arm_push_leaves_a_dent_and_feels_a_bounded_opposing_force() {
    // The push of the shared script, 0.2 below the top instead of 0.125: 17 mm below the top
    // at the hand, a firm press.
    let script = common::PUSH_SCRIPT.replace(
        "path = [[0.75, 1.3, 0.95], [1.15, 1.3, 0.95]]",
        "path = [[0.75, 1.225, 0.95], [1.15, 1.225, 0.95]]",
    );
    assert_ne!(script, common::PUSH_SCRIPT, "the path was deepened");
    let s = common::setup(&script, vec![]);
    let before = s.field.clone();
    let iso = before.iso;
    let max_force_n = s.arm.config().info.max_force_n;
    let mut engine = Lockstep::new(
        &s.config,
        s.field,
        common::boxed(s.arm),
        Box::new(HeadlessSink::default()),
        16,
    )
    .expect("engine starts");

    let mut contact_samples = 0u32;
    let mut opposing = 0u32;
    let mut peak_n = 0.0f32;
    for _ in 0..1600 {
        let t = engine.step().sample;
        assert!(
            t.tip_fu.is_finite() && t.device_force_n.is_finite(),
            "NaN in {t:?}"
        );
        peak_n = peak_n.max(t.device_force_n.length());
        let f = t.device_force_n;
        if t.in_contact && f.length() > 0.05 {
            contact_samples += 1;
            // The push goes in: the reaction points from the tip back toward the surface
            // point the vector starts from, and never drives the tool deeper.
            let back = t.force_from_fu - t.force_to_fu;
            if f.dot(back) > 0.0 && f.y >= -0.1 * f.length() {
                opposing += 1;
            }
        }
    }
    let report = engine.finish().expect("engine stops");
    let after = &report.session.clay.density.patches[0].lattice;

    assert!(
        contact_samples > 500,
        "the arm pushed into the clay ({contact_samples} samples)"
    );
    assert_eq!(
        opposing, contact_samples,
        "every contact force opposes the push"
    );
    assert!(peak_n > 1.0, "a firm force was felt ({peak_n} N)");
    assert!(
        peak_n <= max_force_n + 1e-3,
        "peak {peak_n} N over the device max"
    );
    assert!(
        report.counters.peak_force_milli_n as f32 <= max_force_n * 1000.0 + 1.0,
        "{:?}",
        report.counters
    );

    // A groove along the middle of the path: the field 0.05 above the hand's path (the
    // effector stops short of the hand where the forces balance) dropped below the iso-level,
    // 0.125 under the old top.
    let path = common::path_points(&s.script);
    let middle = path[1..6].iter().map(|p| *p + Vec3::Y * 0.05);
    for p in middle {
        assert!(before.value(p) > iso, "clay was there at {p}");
        assert!(after.value(p) < iso, "no dent at {p}: {}", after.value(p));
    }
    // Far away (the other side of the block, and its bottom) nothing changed.
    for far in [
        Vec3::new(0.95, 0.6, 0.95),
        Vec3::new(0.55, 0.6, 1.35),
        Vec3::new(1.35, 0.7, 0.55),
    ] {
        let d = (after.value(far) - before.value(far)).abs();
        assert!(d < 1e-3, "changed far away at {far}: {d}");
    }
    assert!(
        after.coeffs.iter().all(|c| c.is_finite()),
        "NaN in the field"
    );
}
