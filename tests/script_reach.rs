//! Script steps that reach the papers' remaining tools, run in the lockstep engine and measured
//! on the exported mesh: a tool made from the sculpt (`make_tool`, Ferley §4.1.2) used by later
//! `tool`, `preset` and `stroke` steps and kept in the saved session, and sharp CSG (Guo & Qin
//! Table 1) with another session's clay (`csg`) and with a solid (`tool` with a CSG action).

use std::path::Path;

use dynaclay::engine::ScriptDriver;
use dynaclay::field::{BSplineLattice, Primitive, lattice_from_primitive};
use dynaclay::io::{Session, load_session, save_session};
use dynaclay::mesh::{BrickOctree, MeshFormat, SampleGrid, write_mesh};
use dynaclay::tools::{Clay, ToolShape};
use glam::Vec3;

#[path = "support/lockstep.rs"]
mod lockstep;

use lockstep::{Scripted, scripted};

/// The default block's top face (resolution 24: the block spans [0.575, 1.725]).
const TOP: f32 = 1.725;

/// Runs `text` (its files in `dir`) to its end; returns the final session and the notes.
fn run_script(text: &str, dir: &Path) -> (Session, Vec<(usize, String)>) {
    let Scripted { plan, mut run, .. } = scripted(text, "reach.toml", dir);
    let mut driver = ScriptDriver::new(&plan);
    let commands = run.commands();
    for _ in 0..(plan.seconds * 1000.0) as usize {
        let sample = run.latest_tool();
        driver.dispatch(&sample, &commands);
        run.step();
    }
    assert!(driver.is_done(), "steps left: {:?}", driver.unsent_steps());
    let report = run.finish().unwrap();
    assert!(driver.failures().is_empty(), "{:?}", driver.failures());
    (report.session, driver.notes().to_vec())
}

/// `field`'s mesh written as OBJ and read back: its vertex positions.
fn exported_vertices(field: &BSplineLattice, dir: &Path, name: &str) -> Vec<Vec3> {
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

/// The largest height difference between the mesh around (x, z) and around (x, z) + offset,
/// over a 9 × 9 grid 0.05 apart.
fn worst_copy_error(vertices: &[Vec3], (x, z): (f32, f32), offset: (f32, f32)) -> f32 {
    let mut worst = 0.0f32;
    for i in -4..=4 {
        for k in -4..=4 {
            let (dx, dz) = (0.05 * i as f32, 0.05 * k as f32);
            let source = top_at(vertices, x + dx, z + dz, 0.03);
            let copy = top_at(vertices, x + offset.0 + dx, z + offset.1 + dz, 0.03);
            worst = worst.max((copy - source).abs());
        }
    }
    worst
}

const MAKE_AND_USE: &str = r#"
version = 1
seconds = 3.5

[clay]
shape = "block"
resolution = 24

[[step]]                     # a bump on the top face
do = "tool"
shape = { kind = "sphere", radius_fu = 0.15 }
action = { kind = "union" }
positions = [[0.85, 1.725, 0.85]]

[[step]]                     # the clay around it becomes a tool
do = "make_tool"
name = "bump"
selection = { kind = "box", min = [0.6, 1.55, 0.6], max = [1.1, 2.05, 1.1] }

[[step]]                     # a copy 0.6 along +x and +z (the box's centre moved there)
do = "tool"
shape = { kind = "freeform", preset = "bump" }
action = { kind = "union" }
positions = [[1.45, 1.8, 1.45]]

[[step]]                     # another with the preset's own action, 0.6 along +x
do = "preset"
name = "bump"
positions = [[1.45, 1.8, 0.85]]

[[step]]                     # a live stroke holding it, 0.6 along +z
do = "stroke"
shape = { kind = "freeform", preset = "bump" }
action = { kind = "union" }
path = [[0.85, 1.8, 1.45]]
duration_s = 0.3

[[step]]
do = "save"
path = "with_tool.dclay"
"#;

#[test]
fn a_tool_made_from_a_sculpted_bump_reproduces_the_bump_and_is_saved() {
    let dir = tempfile::tempdir().unwrap();
    let (session, notes) = run_script(MAKE_AND_USE, dir.path());
    assert!(
        notes
            .iter()
            .any(|(step, note)| *step == 2 && note.contains("\"bump\" added")),
        "{notes:?}"
    );
    let field = &session.clay.density.patches[0].lattice;
    let v = exported_vertices(field, dir.path(), "sculpt.obj");
    let source = (0.85, 0.85);
    let height = top_at(&v, source.0, source.1, 0.03) - TOP;
    assert!(height > 0.1, "the source bump is {height} high");
    for (what, offset) in [
        ("tool step", (0.6, 0.6)),
        ("preset step", (0.6, 0.0)),
        ("stroke", (0.0, 0.6)),
    ] {
        let copy = top_at(&v, source.0 + offset.0, source.1 + offset.1, 0.03) - TOP;
        let worst = worst_copy_error(&v, source, offset);
        eprintln!(
            "{what}: bump {height:.4} high, copy {copy:.4}; heights over 0.4 × 0.4 differ by up \
             to {worst:.4}"
        );
        assert!(
            worst < 0.1 * height,
            "{what}: copy differs by up to {worst}"
        );
    }
    // The library is saved with the session, the tool a freeform lattice.
    let saved = load_session(&dir.path().join("with_tool.dclay")).unwrap();
    let tool = saved
        .tool("bump")
        .expect("the tool is in the saved library");
    assert!(matches!(tool.shape, ToolShape::Freeform(_)));
    assert_eq!(session.tools, saved.tools);
}

#[test]
fn a_script_naming_a_tool_no_step_makes_is_refused_before_the_run() {
    let text = r#"
version = 1
[[step]]
do = "preset"
name = "nowhere"
positions = [[1.0, 1.0, 1.0]]
"#;
    let script = dynaclay::io::parse_script(text, "bad.toml").unwrap();
    let e = dynaclay::engine::ScriptPlan::new(
        &script,
        "bad.toml",
        Path::new("."),
        &[],
        dynaclay::dynamics::Material::PLASTIC,
    )
    .unwrap_err();
    assert!(
        e.to_string().contains("no tool preset named \"nowhere\""),
        "{e}"
    );
    let empty = r#"
version = 1
[[step]]
do = "make_tool"
name = "x"
selection = { kind = "box", min = [1.0, 1.0, 1.0], max = [1.0, 2.0, 2.0] }
"#;
    let e = dynaclay::io::parse_script(empty, "empty.toml").unwrap_err();
    assert!(
        e.to_string().contains("empty.toml:6: step 1: selection"),
        "{e}"
    );
}

/// The cavity a difference with a ball of `radius` about `centre` leaves: the mean distance
/// of the wall's vertices from the centre, and the largest error from `radius`.
fn cavity(vertices: &[Vec3], centre: Vec3, radius: f32) -> (f32, f32, usize) {
    let wall: Vec<f32> = vertices
        .iter()
        .filter(|v| v.y < TOP - 0.05 && v.distance(centre) < radius + 0.15)
        .map(|v| v.distance(centre))
        .collect();
    let mean = wall.iter().sum::<f32>() / wall.len().max(1) as f32;
    let worst = wall
        .iter()
        .map(|d| (d - radius).abs())
        .fold(0.0f32, f32::max);
    (mean, worst, wall.len())
}

#[test]
fn csg_differences_with_a_session_and_with_a_solid_leave_spherical_cavities() {
    let dir = tempfile::tempdir().unwrap();
    let start = dynaclay::engine::build_clay(&dynaclay::io::ClaySpec::default()).unwrap();
    let radius = 0.3;
    let a = Vec3::new(0.95, TOP, 0.95);
    let ball = lattice_from_primitive(
        start.dims,
        start.spacing,
        start.origin,
        &Primitive::Sphere { centre: a, radius },
        2.0 * start.spacing,
        2,
    )
    .unwrap();
    save_session(
        &dir.path().join("ball.dclay"),
        &Session {
            clay: Clay::single(ball),
            ..Session::default()
        },
    )
    .unwrap();
    let text = r#"
version = 1
seconds = 0.5

[clay]
shape = "block"
resolution = 24

[[step]]
do = "csg"
op = "difference"
with = "ball.dclay"

[[step]]
do = "tool"
shape = { kind = "sphere", radius_fu = 0.25 }
action = { kind = "difference" }
falloff_fu = 0.05
positions = [[1.4, 1.725, 1.4]]
"#;
    let (session, _) = run_script(text, dir.path());
    let v = exported_vertices(
        &session.clay.density.patches[0].lattice,
        dir.path(),
        "csg.obj",
    );
    for (what, centre, r) in [
        ("csg with a session", a, radius),
        ("tool difference", Vec3::new(1.4, TOP, 1.4), 0.25),
    ] {
        let (mean, worst, n) = cavity(&v, centre, r);
        eprintln!("{what}: cavity radius {mean:.4} (asked {r}), worst {worst:.4}, {n} vertices");
        assert!(n > 50, "{what}: {n} wall vertices");
        assert!((mean - r).abs() < 0.05 * r, "{what}: radius {mean}");
        assert!(worst < 0.1 * r, "{what}: worst {worst}");
    }
}
