//! Script steps that reach the papers' remaining tools, run in the lockstep engine and measured
//! on the exported mesh: a tool made from the sculpt (`make_tool`, Ferley §4.1.2) used by later
//! `tool`, `preset` and `stroke` steps and kept in the saved session, and sharp CSG (Guo & Qin
//! Table 1) with another session's clay and with a solid (`csg`, intersection included), and
//! with a solid by a `tool` step with a CSG action.

use std::path::Path;

use dynaclay::engine::ScriptDriver;
use dynaclay::field::MultiPatchField;
use dynaclay::field::{BSplineLattice, Primitive, lattice_from_primitive};
use dynaclay::io::{Session, load_session, save_session};
use dynaclay::mesh::{TriMesh, hausdorff};
use dynaclay::tools::{Clay, ToolShape};
use glam::Vec3;

#[path = "support/exported_mesh.rs"]
#[allow(dead_code)] // shared: this test reads the mesh back but does not probe profiles
mod exported_mesh;
#[path = "support/lockstep.rs"]
mod lockstep;

use exported_mesh::{Exported, export};
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
    export(&MultiPatchField::new(field.clone()), dir, name).vertices
}

/// Highest vertex within `r` of the vertical line through (x, z).
fn top_at(vertices: &[Vec3], x: f32, z: f32, r: f32) -> f32 {
    vertices
        .iter()
        .filter(|v| (v.x - x).hypot(v.z - z) < r)
        .map(|v| v.y)
        .fold(f32::NEG_INFINITY, f32::max)
}

/// The top of `mesh` over the square of half side `half` about (x, z) (the triangles with
/// every vertex inside and above the top face's lower half span), moved by `-shift`.
fn region(mesh: &Exported, (x, z): (f32, f32), half: f32, shift: Vec3) -> TriMesh {
    let inside = |v: Vec3| (v.x - x).abs() <= half && (v.z - z).abs() <= half && v.y > TOP - 0.05;
    let mut index = vec![u32::MAX; mesh.vertices.len()];
    let mut positions = Vec::new();
    let mut triangles = Vec::new();
    for t in &mesh.triangles {
        if t.iter().all(|&i| inside(mesh.vertices[i])) {
            triangles.push(t.map(|i| {
                if index[i] == u32::MAX {
                    index[i] = positions.len() as u32;
                    positions.push(mesh.vertices[i] - shift);
                }
                index[i]
            }));
        }
    }
    TriMesh {
        normals: vec![Vec3::Y; positions.len()],
        positions,
        triangles,
    }
}

/// The Hausdorff distance (both ways) between the exported surface over the square of half
/// side `half` about `source` and over the same square moved by `offset`, moved back.
fn copy_distance(mesh: &Exported, source: (f32, f32), offset: (f32, f32), half: f32) -> f32 {
    let at = region(mesh, source, half, Vec3::ZERO);
    let shift = Vec3::new(offset.0, 0.0, offset.1);
    let copy = region(
        mesh,
        (source.0 + offset.0, source.1 + offset.1),
        half,
        shift,
    );
    hausdorff(&at, &copy).expect("both regions meshed").max()
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
positions = [[0.95, 1.725, 0.95]]

[[step]]                     # the clay around it becomes a tool
do = "make_tool"
name = "bump"
selection = { kind = "box", min = [0.7, 1.55, 0.7], max = [1.2, 2.05, 1.2] }

[[step]]                     # a copy 0.4 along +x and +z (the box's centre moved there)
do = "tool"
shape = { kind = "freeform", preset = "bump" }
action = { kind = "union" }
positions = [[1.35, 1.8, 1.35]]

[[step]]                     # another with the preset's own action, 0.4 along +x
do = "preset"
name = "bump"
positions = [[1.35, 1.8, 0.95]]

[[step]]                     # a live stroke holding it, 0.4 along +z
do = "stroke"
shape = { kind = "freeform", preset = "bump" }
action = { kind = "union" }
path = [[0.95, 1.8, 1.35]]
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
    let field = session.clay.density.clone();
    let mesh = export(&field, dir.path(), "sculpt.obj");
    let source = (0.95, 0.95);
    let height = top_at(&mesh.vertices, source.0, source.1, 0.03) - TOP;
    assert!(height > 0.1, "the source bump is {height} high");
    // Each copy's surface over the bump's square (half side 0.18: the bump and its falloff,
    // on the flat top at both places) against the source's, moved back.
    for (what, offset) in [
        ("tool step", (0.4, 0.4)),
        ("preset step", (0.4, 0.0)),
        ("stroke", (0.0, 0.4)),
    ] {
        let copy = top_at(
            &mesh.vertices,
            source.0 + offset.0,
            source.1 + offset.1,
            0.03,
        ) - TOP;
        let distance = copy_distance(&mesh, source, offset, 0.18);
        eprintln!(
            "{what}: bump {height:.4} high, copy {copy:.4}; the surfaces over the bump are \
             {distance:.4} apart (Hausdorff)"
        );
        // The stroke's copy is the union of the copies along the arm's effector, which
        // settles onto the point from 0.004 below it over the first applications: its flanks
        // are a little wider (measured 0.0164 against 0.0116 and 0.0125 for the steps).
        let bound = if what == "stroke" { 0.11 } else { 0.1 };
        assert!(
            distance < bound * height,
            "{what}: the copy is {distance} from the source"
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
    // Below the top face and over the cavity's circle (a little beyond it): the block's own
    // rounded edges, 0.375 from the centre across, are not the cavity's wall.
    let wall: Vec<f32> = vertices
        .iter()
        .filter(|v| {
            v.y < TOP - 0.05
                && v.distance(centre) < radius + 0.15
                && (v.x - centre.x).hypot(v.z - centre.z) < radius + 0.03
        })
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
    // Each cavity alone, at the middle of the top face: the face is too small for two away
    // from its rounded edges.
    let centre = Vec3::new(1.15, TOP, 1.15);
    let radius = 0.3;
    let ball = lattice_from_primitive(
        start.dims,
        start.spacing,
        start.origin,
        &Primitive::Sphere { centre, radius },
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
    let head = "version = 1\nseconds = 0.5\n\n[clay]\nshape = \"block\"\nresolution = 24\n";
    let with_session = "[[step]]\ndo = \"csg\"\nop = \"difference\"\nwith = \"ball.dclay\"\n";
    let with_solid = "[[step]]\ndo = \"tool\"\nshape = { kind = \"sphere\", radius_fu = 0.25 }\n\
                      action = { kind = \"difference\" }\nfalloff_fu = 0.05\n\
                      positions = [[1.15, 1.725, 1.15]]\n";
    for (what, step, r) in [
        ("csg with a session", with_session, radius),
        ("tool difference", with_solid, 0.25),
    ] {
        let (session, _) = run_script(&format!("{head}\n{step}"), dir.path());
        let v = exported_vertices(
            &session.clay.density.patches[0].lattice,
            dir.path(),
            "csg.obj",
        );
        let (mean, worst, n) = cavity(&v, centre, r);
        eprintln!("{what}: cavity radius {mean:.4} (asked {r}), worst {worst:.4}, {n} vertices");
        assert!(n > 50, "{what}: {n} wall vertices");
        assert!((mean - r).abs() < 0.05 * r, "{what}: radius {mean}");
        assert!(worst < 0.1 * r, "{what}: worst {worst}");
    }
}

#[test]
fn an_intersection_with_a_solid_from_a_script_keeps_the_clay_inside_it() {
    // The block ∩ a ball of radius 0.4 inside it: the ball.
    let dir = tempfile::tempdir().unwrap();
    let centre = Vec3::new(1.15, 1.15, 1.15);
    let radius = 0.4;
    let text = "version = 1\nseconds = 0.5\n\n[clay]\nshape = \"block\"\nresolution = 24\n\n\
                [[step]]\ndo = \"csg\"\nop = \"intersection\"\n\
                shape = { kind = \"sphere\", radius_fu = 0.4 }\nposition = [1.15, 1.15, 1.15]\n\
                falloff_fu = 0.1\n";
    let (session, _) = run_script(text, dir.path());
    let v = exported_vertices(
        &session.clay.density.patches[0].lattice,
        dir.path(),
        "ball.obj",
    );
    let distances: Vec<f32> = v.iter().map(|p| p.distance(centre)).collect();
    let mean = distances.iter().sum::<f32>() / distances.len() as f32;
    let worst = distances
        .iter()
        .map(|d| (d - radius).abs())
        .fold(0.0f32, f32::max);
    eprintln!(
        "block ∩ ball of radius {radius}: {} vertices, mean radius {mean:.4}, worst {worst:.4}",
        v.len()
    );
    assert!(v.len() > 500, "{} vertices", v.len());
    assert!((mean - radius).abs() < 0.02 * radius, "mean radius {mean}");
    assert!(worst < 0.05 * radius, "worst {worst}");
}

#[test]
fn a_csg_step_names_what_it_lacks_or_has_twice() {
    let head = "version = 1\n\n[[step]]\ndo = \"csg\"\nop = \"intersection\"\n";
    for (body, key) in [
        ("", "with"),
        (
            "shape = { kind = \"sphere\", radius_fu = 0.4 }\n",
            "position",
        ),
        (
            "with = \"a.dclay\"\nshape = { kind = \"sphere\", radius_fu = 0.4 }\n\
             position = [1, 1, 1]\n",
            "with",
        ),
        (
            "shape = { kind = \"sphere\", radius_fu = 0.4 }\nposition = [1, 1, 1]\n\
             falloff_fu = 0\n",
            "falloff_fu",
        ),
    ] {
        let e = dynaclay::io::parse_script(&format!("{head}{body}"), "csg.toml").unwrap_err();
        let text = e.to_string();
        assert!(text.contains("csg.toml") && text.contains(key), "{text}");
    }
}
