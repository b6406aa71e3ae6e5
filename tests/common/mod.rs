//! Shared set-up for the whole-engine tests: the default clay, a simulated arm following a
//! script, and checks on the resulting field.

#![allow(dead_code)]

use dynaclay::engine::{EngineConfig, Script, build_clay};
use dynaclay::field::BSplineLattice;
use dynaclay_devices::{Fault, HapticDevice, SimArmConfig, SimulatedArm};
use glam::Vec3;

/// A push along the top of the block, 1.2 s long, starting at 0.1 s.
pub const PUSH_SCRIPT: &str = r#"
[clay]
shape = "block"
resolution = 20

[[stroke]]
start_s = 0.1
path = [[0.75, 1.3, 0.95], [1.15, 1.3, 0.95]]
duration_s = 1.0
hover = 0.3
"#;

pub struct Setup {
    pub script: Script,
    pub field: BSplineLattice,
    pub config: EngineConfig,
    pub arm: SimulatedArm,
}

/// The script's clay, engine config and a simulated arm following its strokes.
pub fn setup(script_text: &str, faults: Vec<Fault>) -> Setup {
    let script = Script::parse(script_text, "test").expect("test script parses");
    let field = build_clay(&script.clay).expect("clay fits");
    let arm_config = SimArmConfig {
        faults,
        ..SimArmConfig::default()
    };
    let mut config = EngineConfig::for_script(&field, &arm_config.info, &script);
    config.haptic_rt_priority = None;
    // A short soft start: the tests run for about two seconds.
    config.safety.soft_start_s = 0.1;
    let trajectory = script.trajectory(&config.map).expect("trajectory");
    let arm = SimulatedArm::new(arm_config, trajectory);
    Setup {
        script,
        field,
        config,
        arm,
    }
}

/// Boxed device for the engine.
pub fn boxed(arm: SimulatedArm) -> Box<dyn HapticDevice> {
    Box::new(arm)
}

/// Points along the stroke's path (field coordinates).
pub fn path_points(script: &Script) -> Vec<Vec3> {
    let s = &script.strokes[0];
    let a = Vec3::from(s.path[0]);
    let b = Vec3::from(*s.path.last().unwrap());
    (0..=8).map(|i| a.lerp(b, i as f32 / 8.0)).collect()
}
