//! Survey (exploratory): prints what force-tool strokes do to the default block.

use dynaclay::engine::{ScriptDriver, ToolSample};
use dynaclay::field::BSplineLattice;
use dynaclay::mesh::{BrickOctree, MeshFormat, SampleGrid, write_mesh};
use glam::Vec3;

#[path = "support/lockstep.rs"]
mod lockstep;

struct Outcome {
    before: Mesh,
    after: Mesh,
    tips: Vec<ToolSample>,
}

struct Mesh {
    v: Vec<Vec3>,
    f: Vec<[usize; 3]>,
}

fn exported(field: &BSplineLattice, dir: &std::path::Path, name: &str) -> Mesh {
    let mut octree = BrickOctree::new(SampleGrid::for_lattice(field, 4).unwrap());
    octree.rebuild(field);
    let path = dir.join(name);
    write_mesh(&path, &octree.weld(), MeshFormat::Obj).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    let mut v = Vec::new();
    let mut f = Vec::new();
    for l in text.lines() {
        if let Some(r) = l.strip_prefix("v ") {
            let c: Vec<f32> = r.split_whitespace().map(|x| x.parse().unwrap()).collect();
            v.push(Vec3::new(c[0], c[1], c[2]));
        } else if let Some(r) = l.strip_prefix("f ") {
            let c: Vec<usize> = r
                .split_whitespace()
                .map(|x| x.split('/').next().unwrap().parse::<usize>().unwrap() - 1)
                .collect();
            f.push([c[0], c[1], c[2]]);
        }
    }
    Mesh { v, f }
}

/// Heights where the vertical line through (x, z) crosses the mesh, sorted.
fn crossings(m: &Mesh, x: f32, z: f32) -> Vec<f32> {
    let mut out = Vec::new();
    for t in &m.f {
        let [a, b, c] = [m.v[t[0]], m.v[t[1]], m.v[t[2]]];
        // Barycentric in the xz plane.
        let d = (b.x - a.x) * (c.z - a.z) - (c.x - a.x) * (b.z - a.z);
        if d.abs() < 1e-12 {
            continue;
        }
        let u = ((x - a.x) * (c.z - a.z) - (c.x - a.x) * (z - a.z)) / d;
        let w = ((b.x - a.x) * (z - a.z) - (x - a.x) * (b.z - a.z)) / d;
        if u >= 0.0 && w >= 0.0 && u + w <= 1.0 {
            out.push(a.y + u * (b.y - a.y) + w * (c.y - a.y));
        }
    }
    out.sort_by(f32::total_cmp);
    out.dedup_by(|a, b| (*a - *b).abs() < 1e-5);
    out
}

fn top(m: &Mesh, x: f32, z: f32) -> f32 {
    crossings(m, x, z).last().copied().unwrap_or(f32::NAN)
}

fn run(text: &str) -> Outcome {
    let dir = tempfile::tempdir().unwrap();
    let lockstep::Scripted { plan, mut run, .. } = lockstep::scripted(text, "survey", dir.path());
    let start = run.field().clone();
    let mut driver = ScriptDriver::new(&plan);
    let commands = run.commands();
    let mut tips = Vec::new();
    let trace = std::env::var("TRACE").is_ok();
    for n in 0..(plan.seconds * 1000.0) as usize {
        let sample = run.latest_tool();
        tips.push(sample);
        driver.dispatch(&sample, &commands);
        run.step();
        if trace && n % 25 == 0 {
            let l = run.field();
            let h = |x: f32| {
                dynaclay::dynamics::surface_point_on_ray(
                    l,
                    Vec3::new(x, 1.0, 1.15),
                    Vec3::Y,
                    1.0,
                    0.005,
                )
                .map_or(f32::NAN, |p| p.y)
            };
            println!(
                "t {n} tip ({:.3} {:.3}) act {} touch {} from {:.3} surf@tip {:.3} @1.05 {:.3} @1.15 {:.3} @1.35 {:.3}",
                sample.tip.x,
                sample.tip.y,
                sample.stroke_active,
                sample.in_contact,
                sample.force_from.y,
                h(sample.tip.x),
                h(1.05),
                h(1.15),
                h(1.35)
            );
        }
    }
    let end = run.finish().unwrap().session.clay.density.patches[0]
        .lattice
        .clone();
    Outcome {
        before: exported(&start, dir.path(), "before.obj"),
        after: exported(&end, dir.path(), "after.obj"),
        tips,
    }
}

fn script(tool: &str, path: &str, seconds: f32) -> String {
    script_m(tool, path, seconds, "")
}

fn script_m(tool: &str, path: &str, seconds: f32, material: &str) -> String {
    format!(
        r#"
version = 1
seconds = {seconds}
[clay]
shape = "block"
resolution = 24
{material}
[[step]]
do = "stroke"
tool = {tool}
start_s = 0.2
path = {path}
duration_s = 1.0
hover_fu = 0.3
"#
    )
}

#[test]
#[ignore]
fn survey() {
    let top_y = 1.725;
    let z = 1.15;
    let want = |part: &str| std::env::var("SURVEY").map_or(true, |v| v.contains(part));
    for (name, depth, r, g, m) in [
        (
            "chisel",
            0.06,
            0.1,
            2e6,
            "[[step]]\ndo = \"material\"\nstiffness = 10.0\n",
        ),
        (
            "chisel",
            0.06,
            0.1,
            2e6,
            "[[step]]\ndo = \"material\"\nplasticity_per_s = 0.0\nyield_density = 0.0\n",
        ),
        (
            "chisel",
            0.06,
            0.1,
            2e6,
            "[[step]]\ndo = \"material\"\nmass = 10.0\n",
        ),
        (
            "chisel",
            0.06,
            0.1,
            2e6,
            "[[step]]\ndo = \"material\"\ndamping = 1.0\n",
        ),
        (
            "chisel",
            0.06,
            0.1,
            2e6,
            "[[step]]\ndo = \"material\"\nstiffness = 30000.0\n",
        ),
        ("chisel", 0.06, 0.1, 2e3, ""),
        (
            "chisel",
            0.06,
            0.1,
            2e6,
            "[[step]]\ndo = \"material\"\nyield_density = 0.0\n",
        ),
        ("chisel", 0.06, 0.1, 2e9, ""),
        ("chisel", 0.06, 0.3, 2e6, ""),
        ("chisel", 0.06, 0.05, 2e6, ""),
        ("chisel", 0.06, 0.1, 2e6, ""),
        ("squirt", 0.06, 0.1, 2e6, ""),
        ("chisel", 0.03, 0.1, 2e6, ""),
        ("chisel", 0.1, 0.2, 2e7, ""),
        ("chisel", 0.06, 0.1, 2e5, ""),
    ] {
        if !want(&format!("{name}{g}{m}")) {
            continue;
        }
        let tool =
            format!("{{ kind = \"{name}\", depth_fu = {depth}, radius_fu = {r}, gain = {g} }}");
        let path = format!("[[0.85, {top_y}, {z}], [1.45, {top_y}, {z}]]");
        let o = run(&script_m(&tool, &path, 2.5, m));
        let mut line = format!("{name} d {depth} r {r} g {g} {}:", m.replace('\n', " "));
        for x in [0.95, 1.05, 1.15, 1.25, 1.35] {
            let t0 = top(&o.before, x, z);
            let t1 = top(&o.after, x, z);
            line += &format!(" {:.4}", t0 - t1);
        }
        println!("{line}");
    }
    // Builtin push.
    for (label, text) in [
        ("builtin", dynaclay::engine::DEFAULT_SCRIPT.to_string()),
        (
            "stiff10",
            dynaclay::engine::DEFAULT_SCRIPT.replace(
                "resolution = 24\n",
                "resolution = 24\n[[step]]\ndo = \"material\"\nstiffness = 10.0\n",
            ),
        ),
        (
            "r0.1",
            dynaclay::engine::DEFAULT_SCRIPT.replace("radius_fu = 0.25", "radius_fu = 0.1"),
        ),
        (
            "still",
            dynaclay::engine::DEFAULT_SCRIPT.replace(
                "path = [[0.85, 1.55, 1.15], [1.15, 1.5, 1.15], [1.45, 1.55, 1.15]]",
                "path = [[1.15, 1.55, 1.15], [1.15, 1.55, 1.15]]",
            ),
        ),
        (
            "vee",
            dynaclay::engine::DEFAULT_SCRIPT.replace(
                "path = [[0.85, 1.55, 1.15], [1.15, 1.5, 1.15], [1.45, 1.55, 1.15]]",
                "path = [[0.85, 1.65, 1.15], [1.15, 1.45, 1.15], [1.45, 1.65, 1.15]]",
            ),
        ),
        (
            "g2e7",
            dynaclay::engine::DEFAULT_SCRIPT.replace("gain = 2e6", "gain = 2e7"),
        ),
        (
            "g2e8",
            dynaclay::engine::DEFAULT_SCRIPT.replace("gain = 2e6", "gain = 2e8"),
        ),
        (
            "g2e8r0.1",
            dynaclay::engine::DEFAULT_SCRIPT
                .replace("gain = 2e6", "gain = 2e8")
                .replace("radius_fu = 0.25", "radius_fu = 0.1"),
        ),
    ] {
        if !want(label) {
            continue;
        }
        let o = run(&text);
        let mut line = format!("push {label}: (x, top0, top1, tip_y_min, groove-below-tip)");
        for x in [0.95, 1.05, 1.15, 1.25, 1.35] {
            let t0 = top(&o.before, x, 1.15);
            let t1 = top(&o.after, x, 1.15);
            let tip = o
                .tips
                .iter()
                .filter(|s| s.stroke_active && (s.tip.x - x).abs() < 0.01)
                .map(|s| s.tip.y)
                .fold(f32::INFINITY, f32::min);
            line += &format!(" ({x}: {t0:.3} {t1:.3} {tip:.3} {:.3})", tip - t1);
        }
        println!("{line}");
    }
    // Area, pull, grab at the palette defaults along the top, 1.5 spans deep.
    for tool in [
        "{ kind = \"area\", beta = \"gaussian\", radius_fu = 0.25, tracks = 8, gain = 2e6 }",
        "{ kind = \"pull\", beta = \"gaussian\", radius_fu = 0.25, gain = 2e6 }",
        "{ kind = \"grab\", gain = 2e6 }",
    ] {
        if !want(tool) {
            continue;
        }
        let y = top_y - 0.15;
        let path = format!("[[0.85, {y}, {z}], [1.45, {y}, {z}]]");
        let o = run(&script(tool, &path, 2.5));
        let mut line = format!("{tool}:");
        for x in [0.8, 0.9, 1.0, 1.1, 1.2, 1.3, 1.4, 1.5] {
            let c0 = crossings(&o.before, x, z);
            let c1 = crossings(&o.after, x, z);
            line += &format!(
                " ({x}: {:.3}->{:.3} n{})",
                c0.last().unwrap(),
                c1.last().unwrap_or(&f32::NAN),
                c1.len()
            );
        }
        println!("{line}");
    }
}
