//! Detail where the brush is fine and room where the clay goes, judged on what a run exports:
//! a script's remove brush of 1/256 of the default clay's size, with no refine step, carves a
//! groove whose width on `sculpt.obj` is within 25% of the brush's chord; a push of the arm
//! with a spread of a quarter knot span (automatic detail for force tools on) refines under
//! itself and presses a groove within 25%
//! of the chord of a ball of its spread swept along the tip's path (over twice as wide with
//! automatic detail off); a chisel of half a knot span's radius refines under itself and cuts
//! its depth within 10% along the whole stroke; and an add stroke or a pull stroke
//! of the simulated arm that leaves the starting box extends the exported clay past it,
//! rounded (no flat face where the box was).

use std::path::Path;
use std::process::Command;

use glam::Vec3;

#[path = "support/exported_mesh.rs"]
#[allow(dead_code)] // shared: this test reads a run's file and probes crossings, not profiles
mod exported_mesh;

use exported_mesh::{Exported, read_obj};

use dynaclay::dynamics::Material;
use dynaclay::engine::{
    EngineConfig, HeadlessSink, Lockstep, ScriptDriver, ScriptPlan, build_clay,
};
use dynaclay::io::parse_script;
use dynaclay_devices::{SimArmConfig, SimulatedArm};

const BIN: &str = env!("CARGO_BIN_EXE_dynaclay");

/// The default block: a 24³ lattice of knot spacing 0.1 from the origin (2.3 across); the
/// block's top face is at y = 1.725, its middle at x = z = 1.15.
const SIZE: f32 = 2.3;
const TOP_Y: f32 = 1.725;
const MID: f32 = 1.15;

/// Runs `script` in lockstep into `dir/out`; returns the exported mesh read back.
fn run(dir: &Path, script: &str) -> Exported {
    let path = dir.join("script.toml");
    std::fs::write(&path, script).unwrap();
    let out = dir.join("out");
    let run = Command::new(BIN)
        .args(["run", "--lockstep", "--no-rt", "--script"])
        .arg(&path)
        .arg("--out")
        .arg(&out)
        .output()
        .expect("binary runs");
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    read_obj(&out.join("sculpt.obj"))
}

#[test]
fn a_brush_of_a_256th_of_the_clay_carves_a_groove_of_its_width_on_the_exported_mesh() {
    let dir = tempfile::tempdir().unwrap();
    let radius = 0.5 * SIZE / 256.0;
    // Centred on the top face, along x, for 0.04 field units.
    let positions: Vec<String> = (0..=16)
        .map(|n| format!("[{}, {TOP_Y}, {MID}]", MID - 0.02 + 0.0025 * n as f32))
        .collect();
    let script = format!(
        "version = 1\n[[step]]\ndo = \"tool\"\nshape = {{ kind = \"sphere\", radius_fu = {radius} }}\n\
         action = {{ kind = \"remove\" }}\npositions = [{}]\nduration_s = 1.0\nfalloff_fu = {}\n",
        positions.join(", "),
        0.25 * radius
    );
    let mesh = run(dir.path(), &script);
    // Across the groove half a radius below the top, in the stroke's middle.
    let depth = 0.5 * radius;
    let from = Vec3::new(MID, TOP_Y - depth, MID);
    let hits = mesh.crossings(from, Vec3::Z);
    let right = hits
        .iter()
        .copied()
        .filter(|&t| t > 0.0)
        .fold(f32::INFINITY, f32::min);
    let left = hits
        .iter()
        .copied()
        .filter(|&t| t < 0.0)
        .fold(f32::NEG_INFINITY, f32::max);
    let groove = right - left;
    let chord = 2.0 * (radius * radius - depth * depth).sqrt();
    eprintln!(
        "brush {:.5} wide: groove {groove:.5} on sculpt.obj ({} triangles), chord {chord:.5}, {:+.1}%",
        2.0 * radius,
        mesh.triangles.len(),
        100.0 * (groove - chord) / chord
    );
    assert!(
        (groove - chord).abs() <= 0.25 * chord,
        "groove {groove} against the brush's chord {chord}"
    );
}

/// Runs `script` in the lockstep engine as `dynaclay run --lockstep` does (the simulated arm
/// on the script's path, no real-time priority), with automatic detail on (for force tools
/// too, which the default leaves off) or off (`None`: the engine's defaults, which a script's
/// `detail` step can change), and writes its outputs into `dir` as the run writes them;
/// returns `sculpt.obj` read back and the automatic refines counted.
fn run_with_detail(dir: &Path, script: &str, auto_detail: Option<bool>) -> (Exported, u64) {
    let script = parse_script(script, "push.toml").unwrap();
    let plan = ScriptPlan::new(&script, "push.toml", dir, &[], Material::PLASTIC).unwrap();
    let field = build_clay(&plan.clay).unwrap();
    let arm_config = SimArmConfig::default();
    let mut config = EngineConfig::for_field(&field, &arm_config.info);
    config.haptic_rt_priority = None;
    config.haptics.tool_contact = plan.tool_contact;
    if let Some(on) = auto_detail {
        config.sim.auto_detail = on;
        config.sim.auto_detail_force = on;
    }
    let arm = SimulatedArm::new(arm_config, plan.trajectory(&config.map).unwrap());
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
    assert!(driver.is_done());
    let refines = run.counters().snapshot().auto_refines;
    let report = run.finish().unwrap();
    let extras = dynaclay::cli::ExtraOutputs {
        ply: false,
        stl: false,
        png: None,
    };
    dynaclay::cli::write_lockstep_outputs(dir, &report, &config, &extras).unwrap();
    (read_obj(&dir.join("sculpt.obj")), refines)
}

/// The width across z of the groove in `mesh` at height `y` over `(x, MID)`: between the
/// nearest crossings either side.
fn groove_width(mesh: &Exported, x: f32, y: f32) -> f32 {
    let hits = mesh.crossings(Vec3::new(x, y, MID), Vec3::Z);
    let right = hits
        .iter()
        .copied()
        .filter(|&t| t > 0.0)
        .fold(f32::INFINITY, f32::min);
    let left = hits
        .iter()
        .copied()
        .filter(|&t| t < 0.0)
        .fold(f32::NEG_INFINITY, f32::max);
    right - left
}

#[test]
fn a_fine_push_refines_under_itself_and_presses_a_groove_of_its_spread() {
    // A push whose constant spread (a capsule of radius 0.025 around its vector, from the
    // surface above the tip down to the tip) is a quarter of the base's knot span, drawn along
    // x at 0.03 below the top. A surface point is driven down toward the tip's depth while it
    // lies within the spread of the vector; once the bottom has reached the tip the vector
    // has shrunk to the tip, and what the spread still reaches is the ball of its radius
    // around the tip: at rest the groove is the one that ball swept along the tip's path
    // carves. Its cross section half way down is the ball's chord there.
    let (radius, depth) = (0.025_f32, 0.03_f32);
    let script = format!(
        "version = 1\nseconds = 2.5\n[[step]]\ndo = \"stroke\"\n\
         tool = {{ kind = \"push\", beta = \"constant\", radius_fu = {radius}, gain = 2e6 }}\n\
         path = [[{}, {y}, {MID}], [{}, {y}, {MID}]]\nstart_s = 0.1\nduration_s = 1.2\n\
         hover_fu = 0.1\n",
        MID - 0.1,
        MID + 0.1,
        y = TOP_Y - depth,
    );
    let half_depth = 0.5 * depth;
    let ideal = 2.0 * (radius * radius - half_depth * half_depth).sqrt();
    let (fine, refines) = run_with_detail(tempfile::tempdir().unwrap().path(), &script, Some(true));
    let (coarse, none) = run_with_detail(tempfile::tempdir().unwrap().path(), &script, Some(false));
    // Half way down, over the stroke's middle stretch.
    let y = TOP_Y - half_depth;
    let widths = |mesh: &Exported| -> Vec<f32> {
        [-0.04, 0.0, 0.04]
            .iter()
            .map(|dx| groove_width(mesh, MID + dx, y))
            .collect()
    };
    let (fine_widths, coarse_widths) = (widths(&fine), widths(&coarse));
    eprintln!(
        "push of spread {radius}: groove {fine_widths:.4?} with detail ({refines} refines, \
         {} triangles), {coarse_widths:.4?} on the base alone ({} triangles); chord {ideal:.4}",
        fine.triangles.len(),
        coarse.triangles.len()
    );
    assert!(refines >= 1, "the push refined under itself");
    assert_eq!(none, 0, "automatic detail off adds no patch");
    for w in &fine_widths {
        assert!(
            (w - ideal).abs() <= 0.25 * ideal,
            "with detail the groove is {w} wide against the chord {ideal}"
        );
    }
    for (f, c) in fine_widths.iter().zip(&coarse_widths) {
        assert!(
            !c.is_finite() || *c > 2.0 * f,
            "on the base alone the groove is {c} wide, not much wider than {f}"
        );
    }
}

/// A script's `detail` step switches automatic detail for the steps after it, as the window's
/// Detail switches do: the fine push of the test above refines under itself by default (force
/// tools refine as brushes do) but not after `force_tools = false`, and the fine
/// remove brush of the first test refines under itself by default but not after
/// `automatic = false`.
#[test]
fn a_detail_step_switches_automatic_detail_for_the_steps_after_it() {
    let push = |detail: &str| {
        format!(
            "version = 1\nseconds = 1.5\n{detail}[[step]]\ndo = \"stroke\"\n\
             tool = {{ kind = \"push\", beta = \"constant\", radius_fu = 0.025, gain = 2e6 }}\n\
             path = [[{}, {y}, {MID}], [{}, {y}, {MID}]]\nstart_s = 0.1\nduration_s = 1.0\n\
             hover_fu = 0.1\n",
            MID - 0.1,
            MID + 0.1,
            y = TOP_Y - 0.03,
        )
    };
    let radius = 0.5 * SIZE / 256.0;
    let brush = |detail: &str| {
        format!(
            "version = 1\n{detail}[[step]]\ndo = \"tool\"\n\
             shape = {{ kind = \"sphere\", radius_fu = {radius} }}\naction = {{ kind = \"remove\" }}\n\
             positions = [[{MID}, {TOP_Y}, {MID}], [{}, {TOP_Y}, {MID}]]\nduration_s = 0.2\n",
            MID + 0.01
        )
    };
    let refines = |script: String| {
        let dir = tempfile::tempdir().unwrap();
        run_with_detail(dir.path(), &script, None).1
    };
    let force_off = "[[step]]\ndo = \"detail\"\nforce_tools = false\n";
    let all_off = "[[step]]\ndo = \"detail\"\nautomatic = false\n";
    let counts = [
        refines(push("")),
        refines(push(force_off)),
        refines(brush("")),
        refines(brush(all_off)),
    ];
    eprintln!(
        "automatic refines: push {} / {} with force tools off; brush {} / {} with automatic off",
        counts[0], counts[1], counts[2], counts[3]
    );
    assert!(counts[0] >= 1, "the push refined under itself by default");
    assert_eq!(
        counts[1], 0,
        "the push stays on the base after force_tools = false"
    );
    assert!(counts[2] >= 1, "the fine brush refined by default");
    assert_eq!(counts[3], 0, "no brush refines after automatic = false");
}

/// The top of the clay in `mesh` over `(x, z)`: the highest crossing of the vertical line.
fn top_at(mesh: &Exported, x: f32, z: f32) -> f32 {
    let from = Vec3::new(x, 0.0, z);
    mesh.crossings(from, Vec3::Y)
        .into_iter()
        .fold(f32::NEG_INFINITY, f32::max)
}

#[test]
fn a_narrow_chisel_refines_under_itself_and_cuts_its_depth_along_the_whole_stroke() {
    // A chisel of radius half a base knot span, set 0.06 deep, drawn along x over the top
    // face. Automatic detail for force tools refines under it as it starts; on the finer
    // patch the clay's springs close a cut this narrow over its targets (a skin of clay over
    // a hole cut to the full depth) unless the chisel, like the push, keeps the clay out of
    // the cut it has made. Measured on the exported mesh from above, as a user sees it.
    let (radius, depth) = (0.05_f32, 0.06_f32);
    let script = format!(
        "version = 1\nseconds = 2.2\n[[step]]\ndo = \"stroke\"\n\
         tool = {{ kind = \"chisel\", depth_fu = {depth}, radius_fu = {radius}, gain = 2e6 }}\n\
         path = [[0.85, {TOP_Y}, {MID}], [1.45, {TOP_Y}, {MID}]]\nstart_s = 0.2\n\
         duration_s = 1.0\nhover_fu = 0.3\n"
    );
    let (cut, refines) = run_with_detail(tempfile::tempdir().unwrap().path(), &script, Some(true));
    let depths: Vec<f32> = [0.95, 1.05, 1.15, 1.25, 1.35]
        .iter()
        .map(|&x| TOP_Y - top_at(&cut, x, MID))
        .collect();
    eprintln!("chisel of radius {radius} set {depth} deep: cut {depths:.4?} ({refines} refines)");
    assert!(refines >= 1, "the chisel refined under itself");
    for (x, d) in [0.95, 1.05, 1.15, 1.25, 1.35].iter().zip(&depths) {
        assert!(
            (d - depth).abs() <= 0.1 * depth,
            "at x = {x} the cut is {d} deep against {depth}"
        );
    }
}

#[test]
fn an_add_stroke_past_the_box_extends_the_exported_clay_beyond_it_rounded() {
    let dir = tempfile::tempdir().unwrap();
    // From the block's +x face out to 0.6 past the lattice's last node (x = 2.3).
    let positions: Vec<String> = (0..=30)
        .map(|n| format!("[{}, {MID}, {MID}]", 1.7 + 0.04 * n as f32))
        .collect();
    let script = format!(
        "version = 1\n[[step]]\ndo = \"tool\"\nshape = {{ kind = \"sphere\", radius_fu = 0.2 }}\n\
         action = {{ kind = \"add\", deposit_rate_per_s = 4.0 }}\npositions = [{}]\n\
         duration_s = 6.0\nfalloff_fu = 0.05\n",
        positions.join(", ")
    );
    let mesh = run(dir.path(), &script);
    let vertices = &mesh.vertices;
    let reach = vertices
        .iter()
        .map(|v| v.x)
        .fold(f32::NEG_INFINITY, f32::max);
    // Where the support of the 24³ lattice ended, the clay would have been cut flat.
    let old_support_x = SIZE + 0.2;
    assert!(
        reach > SIZE + 0.6,
        "the clay reaches x = {reach}, past the old support at {old_support_x}"
    );
    // Rounded: near the far end, the clay narrows (no flat face where the box was).
    let width_at = |x: f32| {
        let ys: Vec<f32> = vertices
            .iter()
            .filter(|v| (v.x - x).abs() < 0.02)
            .map(|v| v.y)
            .collect();
        ys.iter().copied().fold(f32::NEG_INFINITY, f32::max)
            - ys.iter().copied().fold(f32::INFINITY, f32::min)
    };
    let (middle, end) = (width_at(SIZE + 0.2), width_at(reach - 0.05));
    eprintln!(
        "clay reaches x = {reach:.3}; height {middle:.3} at the old support, {end:.3} near the end"
    );
    assert!(
        end < middle,
        "the end is rounded: {end} near the tip against {middle} further in"
    );
}

#[test]
fn a_pull_stroke_of_the_arm_past_the_box_extends_the_exported_clay_beyond_it_rounded() {
    let dir = tempfile::tempdir().unwrap();
    // The arm grabs the block's +x face and pulls out past the lattice's last node (x = 2.3)
    // to the arm's end stop, room the workspace keeps around the clay.
    let script = "version = 1\nseconds = 6\n[[step]]\ndo = \"stroke\"\n\
         tool = { kind = \"pull\", beta = \"gaussian\", radius_fu = 0.3, gain = 2e6 }\n\
         path = [[1.72, 1.15, 1.15], [2.2, 1.15, 1.15], [2.7, 1.15, 1.15]]\n\
         duration_s = 3.0\nhover_fu = 0.05\n";
    let mesh = run(dir.path(), script);
    let vertices = &mesh.vertices;
    let reach = vertices
        .iter()
        .map(|v| v.x)
        .fold(f32::NEG_INFINITY, f32::max);
    let last_node_x = SIZE;
    assert!(
        reach > last_node_x + 0.15,
        "the pulled clay reaches x = {reach}; the starting lattice's last node is at {last_node_x}"
    );
    // Rounded: the pulled arm narrows toward its tip (a flat clipping face would keep its
    // width to the end).
    let height_at = |x: f32| {
        let ys: Vec<f32> = vertices
            .iter()
            .filter(|v| (v.x - x).abs() < 0.01)
            .map(|v| v.y)
            .collect();
        ys.iter().copied().fold(f32::NEG_INFINITY, f32::max)
            - ys.iter().copied().fold(f32::INFINITY, f32::min)
    };
    let (middle, end) = (height_at(last_node_x), height_at(reach - 0.01));
    eprintln!(
        "pulled clay reaches x = {reach:.3}; height {middle:.3} at x = 2.3, {end:.3} at its tip"
    );
    assert!(
        end < 0.5 * middle,
        "the tip is rounded: {end} at the tip against {middle} at the old box"
    );
}
