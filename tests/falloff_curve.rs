//! A brush's falloff curve shapes the groove it carves: the same stroke of a round brush
//! (radius 0.3, its centre drawn along the block's top) with the sharp, smooth and constant
//! curves, measured across the groove on the exported mesh (meshed, welded, written as OBJ
//! and read back) against each curve's analytic depth `R·c(|s|/R)` at a distance `s` from the
//! path. The script runs through the lockstep engine, the brush facing the clay wherever it
//! acts (the block's top faces +y; the tool's own z is horizontal). The path begins and ends
//! just beyond the block's rounded edges, as a hand draws a groove across a face.

use dynaclay::engine::ScriptDriver;
use dynaclay::field::MultiPatchField;
use dynaclay::tools::FalloffCurve;
use glam::Vec2;

#[path = "support/lockstep.rs"]
mod lockstep;

#[path = "support/exported_mesh.rs"]
#[allow(dead_code)] // shared: this test probes profiles, not crossings
mod exported_mesh;

use lockstep::{Scripted, scripted};

/// The brush's radius, field units.
const RADIUS_FU: f32 = 0.3;
/// The block's top (the path runs on it).
const TOP_FU: f32 = 1.425;
/// The cross-section: z from 0.55 to 1.35 at x 0.95 (the middle of the path), in steps of
/// 0.005; the path is at z 0.95, index 80.
const ACROSS: (Vec2, Vec2, usize) = (Vec2::new(0.95, 0.55), Vec2::new(0.95, 1.35), 160);

/// A stroke of a round brush with `curve` (a script value, or nothing for the sphere) drawn
/// along x on the block's top.
fn script(curve: &str) -> String {
    format!(
        r#"
version = 1

[clay]
shape = "block"
resolution = 20

[[step]]
do = "stroke"
shape = {{ kind = "sphere", radius_fu = {RADIUS_FU} {curve} }}
action = {{ kind = "remove" }}
falloff_fu = 0.15
path = [[0.45, {TOP_FU}, 0.95], [1.45, {TOP_FU}, 0.95]]
duration_s = 1.5
hover_fu = 0.4
"#
    )
}

/// Runs the script and returns the clay at the end.
fn run(text: &str) -> MultiPatchField {
    let dir = tempfile::tempdir().unwrap();
    let Scripted { plan, mut run, .. } = scripted(text, "falloff.toml", dir.path());
    let mut driver = ScriptDriver::new(&plan);
    let commands = run.commands();
    for _ in 0..(plan.seconds * 1000.0) as usize {
        let sample = run.latest_tool();
        driver.dispatch(&sample, &commands);
        run.step();
    }
    assert!(driver.is_done(), "steps left: {:?}", driver.unsent_steps());
    assert!(driver.failures().is_empty(), "{:?}", driver.failures());
    run.density().clone()
}

/// The exported clay's top across the groove, with each sample's distance from the path.
fn tops_across(field: &MultiPatchField) -> Vec<(f32, f32)> {
    let dir = tempfile::tempdir().unwrap();
    let mesh = exported_mesh::export(field, dir.path(), "clay.obj");
    let (from, to, n) = ACROSS;
    mesh.profile(from, to, n)
        .into_iter()
        .map(|(p, top)| (p.y - 0.95, top))
        .collect()
}

/// The groove's depth across it: the untouched top minus the carved one.
fn depths(carved: &[(f32, f32)], untouched: &[(f32, f32)]) -> Vec<(f32, f32)> {
    carved
        .iter()
        .zip(untouched)
        .map(|(&(s, top), &(_, plain))| (s, plain - top))
        .collect()
}

/// Root-mean-square difference between a measured cross-section and `curve`'s analytic one.
fn rms_from(measured: &[(f32, f32)], curve: &FalloffCurve) -> f32 {
    let sum: f32 = measured
        .iter()
        .map(|&(s, depth)| {
            let u = s.abs() / RADIUS_FU;
            let expected = if u <= 1.0 {
                RADIUS_FU * curve.value(u)
            } else {
                0.0
            };
            (depth - expected).powi(2)
        })
        .sum();
    (sum / measured.len() as f32).sqrt()
}

/// The measured depth nearest to `s` from the path.
fn depth_at(measured: &[(f32, f32)], s: f32) -> f32 {
    measured
        .iter()
        .min_by(|a, b| (a.0 - s).abs().total_cmp(&(b.0 - s).abs()))
        .unwrap()
        .1
}

#[test]
fn each_curve_carves_its_own_cross_section() {
    let (untouched, spacing_fu) = {
        let dir = tempfile::tempdir().unwrap();
        let s = scripted(&script(""), "plain.toml", dir.path());
        (
            tops_across(s.run.density()),
            s.run.density().finest_spacing(),
        )
    };
    eprintln!("knot spacing {spacing_fu}");
    let (low, high) = untouched
        .iter()
        .fold((f32::MAX, f32::MIN), |(l, h), &(_, t)| (l.min(t), h.max(t)));
    eprintln!("untouched top between {low} and {high}");
    // Depths are measured from each sample's own untouched top (the block's edges round off).
    let middle_top = untouched[ACROSS.2 / 2].1;
    assert!(
        (middle_top - TOP_FU).abs() < 0.01,
        "the path runs on the top: {middle_top}"
    );
    let curves = [
        FalloffCurve::Sharp,
        FalloffCurve::Smooth,
        FalloffCurve::Constant,
        FalloffCurve::Sphere,
    ];
    let measured: Vec<Vec<(f32, f32)>> = curves
        .iter()
        .map(|curve| {
            let field = run(&script(&format!(", curve = \"{}\"", curve.name())));
            depths(&tops_across(&field), &untouched)
        })
        .collect();
    for (curve, section) in curves.iter().zip(&measured) {
        let errors: Vec<f32> = curves.iter().map(|c| rms_from(section, c)).collect();
        eprintln!(
            "{:>8}: depth at s = 0, R/4, R/2, 3R/4: {:.3} {:.3} {:.3} {:.3}; rms from \
             sharp {:.4} smooth {:.4} constant {:.4} sphere {:.4}",
            curve.name(),
            depth_at(section, 0.0),
            depth_at(section, 0.25 * RADIUS_FU),
            depth_at(section, 0.5 * RADIUS_FU),
            depth_at(section, 0.75 * RADIUS_FU),
            errors[0],
            errors[1],
            errors[2],
            errors[3],
        );
        // Each groove is nearest its own curve, within half a knot span (the lattice rounds
        // what is sharper than its span: the constant's walls, the sharp curve's tip).
        let own = rms_from(section, curve);
        assert!(
            own < 0.5 * spacing_fu,
            "{}: {own} from its own curve",
            curve.name()
        );
        for other in curves.iter().filter(|c| *c != curve) {
            assert!(
                own < rms_from(section, other),
                "{} is nearer {}",
                curve.name(),
                other.name()
            );
        }
    }
    let [sharp, smooth, constant, _] = &measured[..] else {
        unreachable!()
    };
    // The constant curve: a flat bottom (as deep halfway out as at the middle) and steep walls
    // (still most of its depth at three quarters out).
    let full = depth_at(constant, 0.0);
    assert!((depth_at(constant, 0.5 * RADIUS_FU) - full).abs() < 0.1 * full);
    assert!(depth_at(constant, 0.75 * RADIUS_FU) > 0.8 * full);
    // The sharp curve: a narrow tip, a quarter of its depth halfway out (p² at p = ½).
    let tip = depth_at(sharp, 0.0);
    assert!(depth_at(sharp, 0.5 * RADIUS_FU) < 0.4 * tip);
    // The smooth curve: half its depth halfway out (3p² − 2p³ at p = ½).
    let middle = depth_at(smooth, 0.0);
    let half = depth_at(smooth, 0.5 * RADIUS_FU) / middle;
    assert!(
        (half - 0.5).abs() < 0.15,
        "smooth at R/2: {half} of its depth"
    );
}
