//! A headless push stroke, exported as a mesh.
//!
//! The simulated arm follows a script's stroke (one push along the top of the default block),
//! the lockstep engine turns each haptic sample into simulation steps and re-meshing, and the
//! sculpt is exported as an OBJ. Run with
//!
//! ```text
//! cargo run --release --example push_stroke [OUT.obj]
//! ```
//!
//! Without `OUT.obj` the mesh goes to a new file in the system's temporary folder. `OUT.obj`
//! may replace only a mesh this program wrote (the output rule every command follows).

use std::error::Error;
use std::path::PathBuf;

use dynaclay::dynamics::Material;
use dynaclay::engine::{EngineConfig, HeadlessSink, Lockstep, ScriptPlan, build_clay};
use dynaclay::io::{OutputKind, OutputRule, parse_script};
use dynaclay::mesh::{BrickOctree, MeshFormat, SampleGrid, write_mesh};
use dynaclay_devices::{SimArmConfig, SimulatedArm};

/// One push, 1 s long, across the top of a 20³ block (positions in field units).
const SCRIPT: &str = r#"
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

fn main() {
    if let Err(e) = run() {
        eprintln!("push_stroke: {e}");
        std::process::exit(1);
    }
}

fn run() -> Result<(), Box<dyn Error>> {
    let out = match std::env::args_os().nth(1) {
        Some(path) => PathBuf::from(path),
        None => std::env::temp_dir().join(format!("dynaclay-push-{}.obj", std::process::id())),
    };
    // As every dynaclay output: a mesh file, never over a file of another kind, checked first.
    OutputRule::new().check("OUT.obj", &out, OutputKind::Mesh)?;

    // The script lays out the clay and the arm's path.
    let script = parse_script(SCRIPT, "push_stroke")?;
    let plan = ScriptPlan::new(
        &script,
        "push_stroke",
        std::path::Path::new("."),
        &[],
        Material::PLASTIC,
    )?;
    let clay = build_clay(&plan.clay)?;
    let arm_config = SimArmConfig::default();
    let mut config = EngineConfig::for_field(&clay, &arm_config.info);
    // A headless run needs no real-time priority.
    config.haptic_rt_priority = None;
    config.haptics.tool_contact = plan.tool_contact;
    let arm = SimulatedArm::new(arm_config, plan.trajectory(&config.map)?);

    // One simulated millisecond per step: the run is the same on any machine.
    let mut run = Lockstep::new(
        &config,
        clay,
        Box::new(arm),
        Box::new(HeadlessSink::default()),
        16,
    )?;
    let ticks = (plan.seconds * 1000.0).ceil() as u64 + 200;
    let mut peak_force_n = 0.0f32;
    for _ in 0..ticks {
        run.step();
        peak_force_n = peak_force_n.max(run.latest_tool().device_force_n.length());
    }
    let report = run.finish()?;

    // Mesh the sculpt at 4 cells per knot span and export it.
    let density = &report.session.clay.density;
    let octree = BrickOctree::build(SampleGrid::for_field(density, 4)?, density);
    let mesh = octree.weld();
    write_mesh(&out, &mesh, MeshFormat::Obj)?;

    // The groove, measured on the exported mesh: the top face's height away from the stroke
    // against the lowest point of the surface along its middle.
    let top_y = mesh
        .positions
        .iter()
        .filter(|p| (p.z - 0.95).abs() > 0.3)
        .map(|p| p.y)
        .fold(f32::MIN, f32::max);
    let groove_y = mesh
        .positions
        .iter()
        .filter(|p| (p.z - 0.95).abs() < 0.05 && (0.85..1.05).contains(&p.x) && p.y > top_y - 0.3)
        .map(|p| p.y)
        .fold(f32::MAX, f32::min);
    println!(
        "ran {:.1} s: peak force {peak_force_n:.2} N, groove {:.3} deep under a top face at {top_y:.3}",
        plan.seconds,
        top_y - groove_y
    );
    println!(
        "wrote {} ({} vertices, {} triangles)",
        out.display(),
        mesh.positions.len(),
        mesh.triangles.len()
    );
    Ok(())
}
