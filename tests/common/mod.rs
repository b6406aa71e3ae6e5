//! Shared set-up for the whole-engine tests: the default clay, a simulated arm following a
//! script, and checks on the resulting field.

#![allow(dead_code)]

use dynaclay::dynamics::Material;
use dynaclay::engine::{EngineConfig, ScriptPlan, build_clay};
use dynaclay::field::BSplineLattice;
use dynaclay::io::{Script, ScriptStep, parse_script};
use dynaclay_devices::{Fault, HapticDevice, SimArmConfig, SimulatedArm};
use glam::Vec3;

/// A push along the top of the block, 1.2 s long, starting at 0.1 s.
pub const PUSH_SCRIPT: &str = r#"
version = 1

[clay]
shape = "block"
resolution = 20

[[step]]
do = "stroke"
start_s = 0.1
path = [[0.75, 1.3, 0.95], [1.15, 1.3, 0.95]]
duration_s = 1.0
hover_fu = 0.3
"#;

pub struct Setup {
    pub script: Script,
    pub plan: ScriptPlan,
    pub field: BSplineLattice,
    pub config: EngineConfig,
    pub arm: SimulatedArm,
}

/// The script's clay, engine config and a simulated arm following its strokes.
pub fn setup(script_text: &str, faults: Vec<Fault>) -> Setup {
    let script = parse_script(script_text, "test").expect("test script parses");
    let plan = ScriptPlan::new(
        &script,
        "test",
        std::path::Path::new("."),
        &[],
        Material::PLASTIC,
    )
    .expect("script lays out");
    let field = build_clay(&plan.clay).expect("clay fits");
    let arm_config = SimArmConfig {
        faults,
        ..SimArmConfig::default()
    };
    let mut config = EngineConfig::for_field(&field, &arm_config.info);
    config.haptic_rt_priority = None;
    // A short soft start: the tests run for about two seconds.
    config.safety.soft_start_s = 0.1;
    // As a script run: the tool acts where the path puts it (unless the script asks for
    // tool-shaped contact).
    config.haptics.tool_contact = plan.tool_contact;
    let trajectory = plan.trajectory(&config.map).expect("trajectory");
    let arm = SimulatedArm::new(arm_config, trajectory);
    Setup {
        script,
        plan,
        field,
        config,
        arm,
    }
}

/// The top face of the 20³ block of [`PUSH_SCRIPT`] (the block fills the lattice's middle
/// half: its top is at three quarters of 19 knot spans of 0.1), field units.
pub const BLOCK_TOP_FU: f32 = 1.425;

/// The height of the block's top in the device's frame, metres, through `config`'s workspace
/// map (which keeps room around the clay, so it is not the workspace's own three quarters).
pub fn block_top_y_m(config: &EngineConfig) -> f32 {
    config.map.to_device(Vec3::new(0.0, BLOCK_TOP_FU, 0.0)).y
}

/// Boxed device for the engine.
pub fn boxed(arm: SimulatedArm) -> Box<dyn HapticDevice> {
    Box::new(arm)
}

/// Points along the first stroke's path (field coordinates).
pub fn path_points(script: &Script) -> Vec<Vec3> {
    let path = script
        .steps
        .iter()
        .find_map(|s| match s {
            ScriptStep::Stroke { path, .. } => Some(path),
            _ => None,
        })
        .expect("a stroke");
    let a = Vec3::from(path[0]);
    let b = Vec3::from(*path.last().unwrap());
    (0..=8).map(|i| a.lerp(b, i as f32 / 8.0)).collect()
}
