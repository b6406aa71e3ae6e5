//! A script run in the lockstep engine (deterministic: one arm sample, then one simulation
//! step), as the script tests set it up: the simulated arm follows the script's trajectory,
//! no real-time priority, a 0.1 s soft start. Shared by `#[path]` (this folder is not a test
//! target of its own).

use std::path::Path;

use dynaclay::dynamics::Material;
use dynaclay::engine::{EngineConfig, HeadlessSink, Lockstep, ScriptPlan, build_clay};
use dynaclay::io::{Script, parse_script};
use dynaclay_devices::{SimArmConfig, SimulatedArm};

/// A script parsed and planned, and the lockstep engine that runs it.
pub struct Scripted {
    // Read by the tests that need the script's own settings (autosave).
    #[allow(dead_code)]
    pub script: Script,
    pub plan: ScriptPlan,
    pub run: Lockstep,
}

/// Parses `text` (named `name`, its files relative to `dir`), builds its clay and starts the
/// lockstep engine with the simulated arm on the script's path.
pub fn scripted(text: &str, name: &str, dir: &Path) -> Scripted {
    let script = parse_script(text, name).unwrap();
    let plan = ScriptPlan::new(&script, name, dir, &[], Material::PLASTIC).unwrap();
    let field = build_clay(&plan.clay).unwrap();
    let arm_config = SimArmConfig::default();
    let mut config = EngineConfig::for_field(&field, &arm_config.info);
    config.haptic_rt_priority = None;
    config.safety.soft_start_s = 0.1;
    // As a script run: the tool acts where the path puts it.
    config.haptics.tool_contact = plan.tool_contact;
    let arm = SimulatedArm::new(arm_config, plan.trajectory(&config.map).unwrap());
    let run = Lockstep::new(
        &config,
        field,
        Box::new(arm),
        Box::new(HeadlessSink::default()),
        64,
    )
    .unwrap();
    Scripted { script, plan, run }
}
