//! Pins through the whole engine (lockstep, deterministic): a `constrain` step pins a point
//! just off the top of the block (it is moved onto the surface and the step says so), a push
//! stroke dents the top right through it, the pinned point stays on the surface; undo removes
//! the stroke and then the pin, and the same push without the pin dents the point.

use dynaclay::dynamics::{Constraint, Material};
use dynaclay::engine::{
    EngineConfig, HeadlessSink, Lockstep, ScriptDriver, ScriptPlan, build_clay,
};
use dynaclay::io::{load_session, parse_script};
use dynaclay::tools::{PinRequest, resolve_pin};
use dynaclay_devices::{SimArmConfig, SimulatedArm};
use glam::Vec3;

/// The default block (resolution 24) has its top face near y = 1.725.
const SCRIPT: &str = r#"
version = 1

[clay]
shape = "block"
resolution = 24

[[step]]
do = "constrain"
kind = "point"
at = [0.95, 1.74, 0.8]

[[step]]
do = "stroke"
path = [[0.8, 1.55, 0.8], [1.1, 1.55, 0.8]]
duration_s = 1.0
hover_fu = 0.3

[[step]]
do = "save"
path = "pinned.dclay"

[[step]]
do = "undo"

[[step]]
do = "undo"

[[step]]
do = "save"
path = "unpinned.dclay"

[[step]]
do = "stroke"
path = [[0.8, 1.55, 0.8], [1.1, 1.55, 0.8]]
duration_s = 1.0
hover_fu = 0.3

[[step]]
do = "save"
path = "free.dclay"
"#;

#[test]
fn a_pinned_point_holds_through_a_push_and_undo_removes_the_pin() {
    let dir = tempfile::tempdir().unwrap();
    let script = parse_script(SCRIPT, "pins.toml").unwrap();
    let plan = ScriptPlan::new(&script, "pins.toml", dir.path(), &[], Material::PLASTIC).unwrap();
    let field = build_clay(&plan.clay).unwrap();
    let arm_config = SimArmConfig::default();
    let mut config = EngineConfig::for_field(&field, &arm_config.info);
    config.haptic_rt_priority = None;
    config.safety.soft_start_s = 0.1;
    let arm = SimulatedArm::new(arm_config, plan.trajectory(&config.map).unwrap());
    let mut run = Lockstep::new(
        &config,
        field,
        Box::new(arm),
        Box::new(HeadlessSink::default()),
        64,
    )
    .unwrap();
    // Where the engine will pin: the same projection on the same starting clay.
    let (expected, _) =
        resolve_pin(run.field(), &PinRequest::Point(Vec3::new(0.95, 1.74, 0.8))).unwrap();
    let [Constraint::Point { at: pin }] = expected[..] else {
        panic!("{expected:?}");
    };
    let mut driver = ScriptDriver::new(&plan);
    let commands = run.commands();
    let (mut checked, mut worst) = (0, 0.0_f32);
    for _ in 0..(plan.seconds * 1000.0) as usize {
        let sample = run.latest_tool();
        driver.dispatch(&sample, &commands);
        run.step();
        // During the pinned push: from the pin's answer until the first undo is sent.
        let pinned = !driver.notes().is_empty();
        let undone = !driver.unsent_steps().contains(&4);
        if pinned && !undone {
            let l = run.field();
            worst = worst.max((l.value(pin) - l.iso).abs());
            checked += 1;
        }
    }
    assert!(checked > 1000, "checked {checked} steps");
    assert!(
        worst < 1e-4,
        "the pinned point left the surface by {worst} during the push"
    );
    assert!(driver.is_done(), "steps left: {:?}", driver.unsent_steps());
    run.finish().unwrap();
    assert!(driver.failures().is_empty(), "{:?}", driver.failures());
    let notes = driver.notes().to_vec();
    assert_eq!(notes.len(), 1, "{notes:?}");
    assert_eq!(notes[0].0, 1);
    assert!(
        notes[0].1.contains("off the surface") && notes[0].1.contains("pinned a point"),
        "{}",
        notes[0].1
    );

    let pinned = load_session(&dir.path().join("pinned.dclay")).unwrap();
    let [Constraint::Point { at }] = pinned.clay.constraints[..] else {
        panic!("one point pin saved: {:?}", pinned.clay.constraints);
    };
    assert_eq!(at, pin, "pinned where the projection puts it");
    assert!(
        (at - Vec3::new(0.95, 1.74, 0.8)).length() < 0.05,
        "moved to {at}"
    );
    let l = &pinned.clay.density.patches[0].lattice;
    assert!(
        (l.value(at) - l.iso).abs() < 1e-4,
        "pinned point is {} off the iso-value after the push",
        l.value(at) - l.iso
    );
    // The push still dented the top beside the pin.
    let beside = Vec3::new(1.1, at.y - 0.03, 0.8);
    assert!(l.value(beside) < l.iso, "no dent beside the pin");

    let unpinned = load_session(&dir.path().join("unpinned.dclay")).unwrap();
    assert!(unpinned.clay.constraints.is_empty(), "undo removed the pin");
    let free = load_session(&dir.path().join("free.dclay")).unwrap();
    let lf = &free.clay.density.patches[0].lattice;
    assert!(
        lf.iso - lf.value(at) > 0.05,
        "without the pin the push dents the point: {} vs iso {}",
        lf.value(at),
        lf.iso
    );
}
