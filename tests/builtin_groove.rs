//! The built-in `dynaclay run` script on the default material leaves a groove along its path:
//! measured on the exported mesh of a lockstep run (deterministic), the top face is at least a
//! third of the push depth below where it started along the path, and unchanged (within 1% of
//! the block's size) away from it.

use dynaclay::dynamics::Material;
use dynaclay::engine::{
    EngineConfig, HeadlessSink, Lockstep, ScriptDriver, ScriptPlan, build_clay,
};
use dynaclay::field::BSplineLattice;
use dynaclay::io::MaterialFields;
use dynaclay::mesh::{BrickOctree, MeshFormat, SampleGrid, write_mesh};
use dynaclay_devices::{SimArmConfig, SimulatedArm};
use glam::Vec3;

/// The default block (resolution 24) spans [0.575, 1.725] on each axis.
const BLOCK_MIN: f32 = 0.575;
const BLOCK_MAX: f32 = 1.725;
/// The built-in stroke's path (x, y) at z = 1.15.
const PATH: [(f32, f32); 3] = [(0.85, 1.55), (1.15, 1.5), (1.45, 1.55)];
const PATH_Z: f32 = 1.15;

/// Writes `field`'s mesh as OBJ and reads its vertex positions back.
fn exported_vertices(field: &BSplineLattice, dir: &std::path::Path, name: &str) -> Vec<Vec3> {
    let mut octree = BrickOctree::new(SampleGrid::for_lattice(field, 4).unwrap());
    octree.rebuild(field);
    let path = dir.join(name);
    write_mesh(&path, &octree.weld(), MeshFormat::Obj).unwrap();
    std::fs::read_to_string(&path)
        .unwrap()
        .lines()
        .filter_map(|l| l.strip_prefix("v "))
        .map(|l| {
            let v: Vec<f32> = l.split_whitespace().map(|x| x.parse().unwrap()).collect();
            Vec3::new(v[0], v[1], v[2])
        })
        .collect()
}

/// Highest vertex within `r` of the vertical line through (x, z).
fn top_at(vertices: &[Vec3], x: f32, z: f32, r: f32) -> f32 {
    vertices
        .iter()
        .filter(|v| (v.x - x).hypot(v.z - z) < r)
        .map(|v| v.y)
        .fold(f32::NEG_INFINITY, f32::max)
}

/// The path's height at `x` (piecewise linear between its points).
fn path_y(x: f32) -> f32 {
    let [(x0, y0), (x1, y1), (x2, y2)] = PATH;
    if x <= x1 {
        y0 + (y1 - y0) * (x - x0) / (x1 - x0)
    } else {
        y1 + (y2 - y1) * (x - x1) / (x2 - x1)
    }
}

#[test]
fn the_builtin_run_leaves_a_groove_along_its_path_and_nothing_elsewhere() {
    let plan = ScriptPlan::builtin();
    let field = build_clay(&plan.clay).unwrap();
    let arm_config = SimArmConfig::default();
    let mut config = EngineConfig::for_field(&field, &arm_config.info);
    config.haptics.tool_contact = plan.tool_contact;
    config.haptic_rt_priority = None;
    // The material `dynaclay run` starts a new sculpt with.
    config.sim.material = MaterialFields::default().uniform;
    assert_eq!(config.sim.material, Material::PLASTIC);
    let arm = SimulatedArm::new(arm_config, plan.trajectory(&config.map).unwrap());
    let start = field.clone();
    let mut run = Lockstep::new(
        &config,
        field,
        Box::new(arm),
        Box::new(HeadlessSink::default()),
        64,
    )
    .unwrap();
    let mut driver = ScriptDriver::new(&plan);
    let commands = run.commands();
    for _ in 0..(plan.seconds * 1000.0) as usize {
        let sample = run.latest_tool();
        driver.dispatch(&sample, &commands);
        run.step();
    }
    let end = run.finish().unwrap().session.clay.density.patches[0]
        .lattice
        .clone();

    let dir = tempfile::tempdir().unwrap();
    let before = exported_vertices(&start, dir.path(), "before.obj");
    let after = exported_vertices(&end, dir.path(), "after.obj");
    let r = 0.04;
    for x in [0.95, 1.05, 1.15, 1.25, 1.35] {
        let top0 = top_at(&before, x, PATH_Z, r);
        let top1 = top_at(&after, x, PATH_Z, r);
        let push_depth = top0 - path_y(x);
        assert!(
            top0 - top1 >= push_depth / 3.0,
            "at x = {x}: top {top0} → {top1}, push depth {push_depth}"
        );
    }
    let size = BLOCK_MAX - BLOCK_MIN;
    for (x, z) in [(0.7, 0.7), (1.6, 0.7), (0.7, 1.6), (1.6, 1.6), (1.15, 0.65)] {
        let top0 = top_at(&before, x, z, r);
        let top1 = top_at(&after, x, z, r);
        assert!(
            (top1 - top0).abs() <= 0.01 * size,
            "at ({x}, {z}) away from the path: top {top0} → {top1}"
        );
    }
}
