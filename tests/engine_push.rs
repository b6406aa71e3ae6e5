//! The threaded engine for about two seconds with the simulated arm pushing into the block
//! along a scripted path: a dent where it pushed and nothing elsewhere, a bounded reaction
//! opposing the push, the haptic rate kept, no NaN.

mod common;

use std::time::{Duration, Instant};

use dynaclay::engine::{Engine, HeadlessSink};
use glam::Vec3;

#[test]
fn simulated_arm_push_leaves_a_dent_and_feels_a_bounded_opposing_force() {
    let s = common::setup(common::PUSH_SCRIPT, vec![]);
    let before = s.field.clone();
    let iso = before.iso;
    let max_force_n = s.arm.config().info.max_force_n;
    let mut engine = Engine::start(
        &s.config,
        s.field,
        common::boxed(s.arm),
        Box::new(HeadlessSink::default()),
    )
    .expect("engine starts");

    let started = Instant::now();
    let mut contact_samples = 0u32;
    let mut opposing = 0u32;
    let mut peak_n = 0.0f32;
    while started.elapsed() < Duration::from_millis(2000) {
        let t = engine.latest_tool();
        assert!(
            t.tip.is_finite() && t.device_force_n.is_finite(),
            "NaN in {t:?}"
        );
        peak_n = peak_n.max(t.device_force_n.length());
        if t.in_contact && t.device_force_n.length() > 0.05 {
            contact_samples += 1;
            // The push goes down (−y): the reaction must point up, back out of the clay.
            if t.device_force_n.y > 0.0 && t.device_force_n.y.abs() >= t.device_force_n.x.abs() {
                opposing += 1;
            }
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    let elapsed = started.elapsed().as_secs_f64();
    let ticks = engine.haptic_ticks();
    let report = engine.stop().expect("engine stops");
    let after = &report.session.clay.patches[0];

    assert!(
        contact_samples > 50,
        "the arm touched the clay ({contact_samples} samples)"
    );
    assert_eq!(
        opposing, contact_samples,
        "every contact force opposes the push"
    );
    assert!(peak_n > 0.1, "a force was felt ({peak_n} N)");
    assert!(
        peak_n <= max_force_n + 1e-3,
        "peak {peak_n} N over the device max"
    );
    assert!(
        report.counters.peak_force_milli_n as f32 <= max_force_n * 1000.0 + 1.0,
        "{:?}",
        report.counters
    );

    // Functional rate check with slack, not a benchmark: ≥ 900 Hz on average.
    let rate = ticks as f64 / elapsed;
    assert!(rate >= 900.0, "haptic ran at {rate:.0} Hz");

    // A dent along the middle of the path: the field there dropped below the iso-level.
    let path = common::path_points(&s.script);
    let middle = &path[2..7];
    for p in middle {
        assert!(before.value(*p) > iso, "clay was there at {p}");
        assert!(after.value(*p) < iso, "no dent at {p}: {}", after.value(*p));
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
    // The haptic loop saw the final field too.
    assert_eq!(&report.haptic_field, after);
}
