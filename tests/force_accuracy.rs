//! Force tools come to rest where the surface reaches their target, measured on the exported
//! mesh of deterministic lockstep runs on the default block (resolution 24, knot span 0.1):
//!
//! - chisel and squirt strokes along the top face cut (raise) the set depth within 10% over
//!   the middle of the stroke, at several depths, radii and gains;
//! - the built-in `dynaclay run` push groove's bottom rests at the tip's path (no deeper than
//!   the overshoot rule allows, within 10% of the push depth);
//! - a pull and an area stroke held at a cursor above the top face raise it to the cursor;
//! - an area stroke at the palette's default settings keeps the surface a height field;
//! - every force entry of the palette, at its default settings, changes the clay by at least a
//!   third of its radius in a 1 s stroke pressed in as the window's pointer presses.
//!
//! The overshoot rule (issue 28): no deeper than the target by more than
//! `max(10% of the depth, 0.1 knot span)`. Every figure is printed (`--nocapture`).

use dynaclay::app::{ForceMode, ForceSettings};
use dynaclay::engine::{Command, ScriptDriver, ToolChoice, ToolSample};
use dynaclay::field::MultiPatchField;
use dynaclay::mesh::{
    AdaptiveMeshOptions, BrickOctree, MeshFormat, SampleGrid, mesh_adaptive, write_mesh,
};
use glam::Vec3;

#[path = "support/lockstep.rs"]
mod lockstep;

/// The default block's knot span.
const SPAN: f32 = 0.1;
/// The strokes run along z = 1.15, the block's middle.
const Z: f32 = 1.15;
/// Columns over the middle 80% of the strokes' path (x from 0.85 to 1.45).
const MIDDLE: [f32; 5] = [0.95, 1.05, 1.15, 1.25, 1.35];
/// How deep the window's pointer presses below the surface by default (1.5 knot spans).
const PRESS: f32 = 1.5 * SPAN;

/// An exported mesh: vertices and triangles.
struct Mesh {
    v: Vec<Vec3>,
    f: Vec<[usize; 3]>,
}

/// Writes `field`'s welded mesh as OBJ into `dir` and reads it back: a clay of one patch meshed
/// at four cells per knot span, one with detail patches by the multi-level mesher at four cells
/// per span of each level (a fine force tool refines under itself).
fn exported(field: &MultiPatchField, dir: &std::path::Path, name: &str) -> Mesh {
    let mesh = if field.patches.len() == 1 {
        let base = field.base();
        let mut octree = BrickOctree::new(SampleGrid::for_lattice(base, 4).unwrap());
        octree.rebuild(base);
        octree.weld()
    } else {
        let options = AdaptiveMeshOptions {
            cells_per_span: 4,
            detail_cells_per_span: 4,
            ..AdaptiveMeshOptions::default()
        };
        mesh_adaptive(field, &options).unwrap()
    };
    let path = dir.join(name);
    write_mesh(&path, &mesh, MeshFormat::Obj).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    let (mut v, mut f) = (Vec::new(), Vec::new());
    for line in text.lines() {
        if let Some(r) = line.strip_prefix("v ") {
            let c: Vec<f32> = r.split_whitespace().map(|x| x.parse().unwrap()).collect();
            v.push(Vec3::new(c[0], c[1], c[2]));
        } else if let Some(r) = line.strip_prefix("f ") {
            let c: Vec<usize> = r
                .split_whitespace()
                .map(|x| x.split('/').next().unwrap().parse::<usize>().unwrap() - 1)
                .collect();
            f.push([c[0], c[1], c[2]]);
        }
    }
    Mesh { v, f }
}

/// Heights at which the vertical line through (x, z) crosses the mesh, ascending (a crossing
/// on a shared edge counted once).
fn crossings(m: &Mesh, x: f32, z: f32) -> Vec<f32> {
    let mut out = Vec::new();
    for t in &m.f {
        let [a, b, c] = [m.v[t[0]], m.v[t[1]], m.v[t[2]]];
        let d = (b.x - a.x) * (c.z - a.z) - (c.x - a.x) * (b.z - a.z);
        if d.abs() < 1e-12 {
            continue;
        }
        let u = ((x - a.x) * (c.z - a.z) - (c.x - a.x) * (z - a.z)) / d;
        let w = ((b.x - a.x) * (z - a.z) - (x - a.x) * (b.z - a.z)) / d;
        // A line through an edge or a vertex is counted by every triangle there (the
        // duplicates are merged below), never by none of them.
        const EPS: f32 = 1e-5;
        if u >= -EPS && w >= -EPS && u + w <= 1.0 + EPS {
            out.push(a.y + u * (b.y - a.y) + w * (c.y - a.y));
        }
    }
    out.sort_by(f32::total_cmp);
    out.dedup_by(|a, b| (*a - *b).abs() < 1e-4);
    out
}

/// The top of the mesh over (x, z).
fn top(m: &Mesh, x: f32, z: f32) -> f32 {
    crossings(m, x, z).last().copied().unwrap_or(f32::NAN)
}

/// What a run did: the mesh before and after, and every tool sample.
struct Outcome {
    before: Mesh,
    after: Mesh,
    samples: Vec<ToolSample>,
}

/// Runs `text` in the lockstep engine; with `tool`, that tool replaces the one the script's
/// stroke selects (sent right after it).
fn run(text: &str, tool: Option<ToolChoice>) -> Outcome {
    let dir = tempfile::tempdir().unwrap();
    let lockstep::Scripted { plan, mut run, .. } = lockstep::scripted(text, "stroke", dir.path());
    let start = run.density().clone();
    let mut driver = ScriptDriver::new(&plan);
    let commands = run.commands();
    let mut tool = tool;
    let mut samples = Vec::new();
    for _ in 0..(plan.seconds * 1000.0) as usize {
        let sample = run.latest_tool();
        samples.push(sample);
        if driver.dispatch(&sample, &commands) > 0
            && let Some(t) = tool.take()
        {
            commands.send(Command::SetTool(t)).unwrap();
        }
        run.step();
        if std::env::var("TRACE").is_ok() && samples.len() % 50 == 0 {
            let h = dynaclay::dynamics::surface_point_on_ray(
                run.density(),
                Vec3::new(1.15, 1.0, Z),
                Vec3::Y,
                1.5,
                0.005,
            )
            .map_or(f32::NAN, |p| p.y);
            println!(
                "t {} tip {:.3} active {} top@1.15 {h:.4}",
                samples.len(),
                sample.tip_fu,
                sample.stroke_active
            );
        }
    }
    assert!(driver.is_done());
    let end = run.finish().unwrap().session.clay.density;
    Outcome {
        before: exported(&start, dir.path(), "before.obj"),
        after: exported(&end, dir.path(), "after.obj"),
        samples,
    }
}

/// A script with one stroke along `path` (field points) with `tool`, `duration_s` long.
fn stroke(tool: &str, path: &[[f32; 3]], duration_s: f32, seconds: f32) -> String {
    let path: Vec<String> = path
        .iter()
        .map(|p| format!("[{}, {}, {}]", p[0], p[1], p[2]))
        .collect();
    format!(
        r#"
version = 1
seconds = {seconds}
[clay]
shape = "block"
resolution = 24
[[step]]
do = "stroke"
tool = {tool}
start_s = 0.2
path = [{}]
duration_s = {duration_s}
hover_fu = 0.3
"#,
        path.join(", ")
    )
}

/// The overshoot allowed past a target `depth` deep.
fn overshoot_rule(depth: f32) -> f32 {
    (0.1 * depth).max(0.1 * SPAN)
}

/// Runs a chisel (or squirt) stroke along the top face and checks the cut (raise) over the
/// middle of the path: within 10% of `depth`, and never past it by more than the overshoot
/// rule. Returns the worst relative error.
fn penetrate(kind: &str, depth: f32, radius: f32, gain: f32) -> f32 {
    let probe = run(
        &stroke("{ kind = \"push\" }", &[[1.15, 1.7, Z]], 0.01, 0.2),
        None,
    );
    let top_y = top(&probe.before, 1.15, Z);
    let tool =
        format!("{{ kind = \"{kind}\", depth_fu = {depth}, radius_fu = {radius}, gain = {gain} }}");
    let o = run(
        &stroke(&tool, &[[0.85, top_y, Z], [1.45, top_y, Z]], 1.0, 2.2),
        None,
    );
    let sign = if kind == "squirt" { -1.0 } else { 1.0 };
    let mut worst = 0.0_f32;
    let mut line = format!("{kind} depth {depth} radius {radius} gain {gain:e}:");
    for x in MIDDLE {
        let cut = sign * (top(&o.before, x, Z) - top(&o.after, x, Z));
        line += &format!(" {cut:.4}");
        assert!(
            cut <= depth + overshoot_rule(depth),
            "{kind} at x = {x}: {cut} past the depth {depth}"
        );
        worst = worst.max((cut - depth).abs() / depth);
    }
    println!("{line} (worst {:.1}%)", 100.0 * worst);
    assert!(
        worst <= 0.1,
        "{kind} {depth} {radius} {gain}: off by {worst}"
    );
    worst
}

#[test]
fn a_chisel_cuts_its_depth_at_several_depths_and_radii() {
    for (depth, radius, gain) in [
        (0.06, 0.1, 2e6),
        (0.03, 0.1, 2e6),
        (0.06, 0.05, 2e6),
        (0.06, 0.3, 2e6),
    ] {
        penetrate("chisel", depth, radius, gain);
    }
}

#[test]
fn a_chisel_cuts_its_depth_from_a_weak_to_a_huge_gain() {
    for (depth, radius, gain) in [(0.06, 0.1, 2e5), (0.1, 0.2, 2e7), (0.06, 0.1, 2e9)] {
        penetrate("chisel", depth, radius, gain);
    }
}

#[test]
fn a_squirt_raises_its_height() {
    for (depth, radius, gain) in [(0.06, 0.1, 2e6), (0.1, 0.2, 2e7), (0.03, 0.05, 2e6)] {
        penetrate("squirt", depth, radius, gain);
    }
}

#[test]
fn the_builtin_push_groove_rests_at_the_tips_path() {
    let o = run(dynaclay::engine::DEFAULT_SCRIPT, None);
    let mut line = String::from("push groove (x: bottom, lowest tip, depth, error):");
    for x in MIDDLE {
        // The lowest the tip went while it pushed within half a knot span of this column.
        let tip = o
            .samples
            .iter()
            .filter(|s| s.in_contact && (s.tip_fu.x - x).abs() <= 0.5 * SPAN)
            .map(|s| s.tip_fu.y)
            .fold(f32::INFINITY, f32::min);
        let (top0, bottom) = (top(&o.before, x, Z), top(&o.after, x, Z));
        let depth = top0 - tip;
        let error = bottom - tip;
        line += &format!(" ({x}: {bottom:.3}, {tip:.3}, {depth:.3}, {error:+.4})");
        assert!(depth > SPAN, "the tip pushed {depth} deep at {x}");
        assert!(
            -error <= overshoot_rule(depth),
            "at x = {x} the groove's bottom {bottom} is below the tip's {tip} by {}",
            -error
        );
        assert!(
            error <= 0.1 * depth,
            "at x = {x} the groove's bottom {bottom} stopped {error} above the tip's {tip}"
        );
    }
    println!("{line}");
}

/// Pulls the top face up to a cursor held `height` above it with `tool`; returns how far
/// the surface under the cursor rose and how high the cursor was held.
fn pull_up(tool: &str, height: f32) -> (f32, f32) {
    let probe = run(
        &stroke("{ kind = \"push\" }", &[[1.15, 1.7, Z]], 0.01, 0.2),
        None,
    );
    let top_y = top(&probe.before, 1.15, Z);
    let up = top_y + height;
    let text = stroke(
        tool,
        &[[1.15, top_y, Z], [1.15, up, Z], [1.15, up, Z]],
        1.2,
        2.6,
    );
    let o = run(&text, None);
    // The cursor as the hand held it at the end of the stroke.
    let held = o
        .samples
        .iter()
        .rev()
        .find(|s| s.stroke_active)
        .map(|s| s.tip_fu)
        .unwrap();
    let risen = top(&o.after, held.x, held.z) - top(&o.before, held.x, held.z);
    (risen, held.y - top_y)
}

#[test]
fn a_pull_and_an_area_bring_the_surface_to_a_held_cursor() {
    for tool in [
        "{ kind = \"pull\", beta = \"gaussian\", radius_fu = 0.25, gain = 2e6 }",
        "{ kind = \"area\", beta = \"gaussian\", radius_fu = 0.15, tracks = 6, gain = 2e6 }",
    ] {
        let (risen, held) = pull_up(tool, 0.15);
        println!("{tool}: cursor {held:.4} above the face, surface rose {risen:.4}");
        assert!(
            risen <= held + overshoot_rule(held),
            "{tool}: rose {risen} past the cursor {held}"
        );
        assert!(
            (risen - held).abs() <= 0.1 * held,
            "{tool}: rose {risen} for a cursor {held} above"
        );
    }
}

/// A 1 s stroke along the top face pressed in as the window's pointer presses (1.5 knot
/// spans below the surface), with `choice` in the hand; `script_tool` selects how the
/// script holds the buttons (the push from the descent, force tools from the path).
fn pointer_stroke(script_tool: &str, choice: ToolChoice) -> Outcome {
    let y = 1.725 - PRESS;
    run(
        &stroke(script_tool, &[[0.85, y, Z], [1.45, y, Z]], 1.0, 2.2),
        Some(choice),
    )
}

/// The deepest cut into and the highest raise of the top face over the stroke's region, and
/// the lowest the top face ends anywhere there.
fn extremes(o: &Outcome) -> (f32, f32, f32) {
    let (mut cut, mut raise, mut lowest) = (0.0_f32, 0.0_f32, f32::INFINITY);
    for i in 0..=30 {
        for k in 0..=20 {
            let (x, z) = (0.6513 + 0.035 * i as f32, 0.8013 + 0.035 * k as f32);
            let (before, after) = (top(&o.before, x, z), top(&o.after, x, z));
            assert!(
                before.is_finite() && after.is_finite(),
                "no top face over ({x}, {z})"
            );
            cut = cut.max(before - after);
            raise = raise.max(after - before);
            lowest = lowest.min(after);
        }
    }
    (cut, raise, lowest)
}

/// Checks that the palette's `mode` at its default settings changes the clay by at least a
/// third of the default radius, toward its target and not past it.
fn default_visibly_works(mode: ForceMode, script_tool: &str) {
    let settings = ForceSettings::default();
    let o = pointer_stroke(script_tool, settings.choice(mode));
    let (cut, raise, lowest) = extremes(&o);
    let (changed, past) = match mode {
        // These bring the surface to the cursor pressed into it: no lower than the tip went.
        ForceMode::PointGrab | ForceMode::Area | ForceMode::Pull => {
            let tip = o
                .samples
                .iter()
                .filter(|s| s.stroke_active)
                .map(|s| s.tip_fu.y)
                .fold(f32::INFINITY, f32::min);
            let depth = 1.725 - tip;
            (cut, (tip - lowest) - overshoot_rule(depth))
        }
        ForceMode::Chisel => (
            cut,
            cut - settings.depth_fu - overshoot_rule(settings.depth_fu),
        ),
        ForceMode::Squirt => (
            raise,
            raise - settings.depth_fu - overshoot_rule(settings.depth_fu),
        ),
        ForceMode::Curve | ForceMode::Bend => {
            panic!("{mode:?} acts on a curve or about a pivot the user picks first")
        }
    };
    println!(
        "{mode:?} at its defaults: cut {cut:.4}, raised {raise:.4}, lowest top {lowest:.4} \
         (radius {})",
        settings.radius_fu
    );
    assert!(
        changed >= settings.radius_fu / 3.0,
        "{mode:?}: the clay changed by {changed}, under a third of the radius {}",
        settings.radius_fu
    );
    assert!(past <= 0.0, "{mode:?}: went {past} past the overshoot rule");
}

const FORCE_SCRIPT_TOOL: &str = "{ kind = \"grab\", gain = 1.0 }";

#[test]
fn the_point_grab_default_visibly_works() {
    default_visibly_works(ForceMode::PointGrab, "{ kind = \"push\" }");
}

#[test]
fn the_area_default_visibly_works_and_keeps_the_surface_a_height_field() {
    default_visibly_works(ForceMode::Area, FORCE_SCRIPT_TOOL);
    let o = pointer_stroke(
        FORCE_SCRIPT_TOOL,
        ForceSettings::default().choice(ForceMode::Area),
    );
    // Every vertical line over the stroke's region (the top face, clear of its rounded
    // edges) crosses the surface twice, the top face and the bottom face, after the stroke as
    // before it: the swept surface is a height field over the top face.
    let mut folds = Vec::new();
    for i in 0..=40 {
        for k in 0..=30 {
            let (x, z) = (0.6513 + 0.025 * i as f32, 0.7513 + 0.025 * k as f32);
            let (n0, n1) = (
                crossings(&o.before, x, z).len(),
                crossings(&o.after, x, z).len(),
            );
            assert_eq!(n0, 2, "the block before the stroke over ({x}, {z})");
            if n1 != 2 {
                folds.push((x, z, n1));
            }
        }
    }
    println!(
        "Area at its defaults: {} of 1271 vertical lines cross other than twice",
        folds.len()
    );
    assert!(
        folds.is_empty(),
        "the surface folds over itself at {folds:?}"
    );
}

#[test]
fn the_chisel_default_visibly_works() {
    default_visibly_works(ForceMode::Chisel, FORCE_SCRIPT_TOOL);
}

#[test]
fn the_squirt_default_visibly_works() {
    default_visibly_works(ForceMode::Squirt, FORCE_SCRIPT_TOOL);
}

#[test]
fn the_pull_default_visibly_works() {
    default_visibly_works(ForceMode::Pull, FORCE_SCRIPT_TOOL);
}
