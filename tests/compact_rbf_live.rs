//! The compact RBF clay in the live engine (Zhang et al. §5.4), run in lockstep from a script:
//! a `compact_rbf` step, then contact strokes with the simulated arm. After each stroke the
//! clay is the lattice fit of an RBF whose centre count is the first's, each re-interpolation
//! is one undo step, and the surface stays within 1% of the diagonal (Hausdorff on meshes,
//! both ways) of the same strokes on the plain B-spline clay.

use std::path::Path;

use dynaclay::engine::ScriptDriver;
use dynaclay::field::BSplineLattice;
use dynaclay::mesh::{BrickOctree, SampleGrid, hausdorff};
use glam::Vec3;

#[path = "support/lockstep.rs"]
mod lockstep;

use lockstep::{Scripted, scripted};

/// Particles of the compact clay (three centres each).
/// Particles of the compact clay (three centres each). Measured on this test (worst of both
/// directions, % of the diagonal): 250 → 1.25, 400 → 1.09, 600 → 0.88; one stroke with 400
/// → 0.42, two → 0.63. Each re-interpolation alone moves the surface by at most 0.005
/// (0.3%); the errors add up over the re-interpolations, as in Zhang's mode.
const N: usize = 600;
/// Radius of the contact tool, field units (two knot spans).
const TOOL_RADIUS_FU: f32 = 0.2;
/// Whole applications per second of the contact rule: 0.6 over each 0.3 s stroke.
const RATE_PER_S: f32 = 2.0;

/// The clay: a sphere of radius 0.475 about (0.95, 0.95, 0.95) on a 20³ lattice.
const CENTRE: f32 = 0.95;
const RADIUS: f32 = 0.475;

/// Four contact strokes across the sphere's surface, dents and bulges in turn, with the
/// compact clay on (`compact` true) or not.
fn script(compact: bool) -> String {
    let mut text = String::from("version = 1\n\n[clay]\nshape = \"sphere\"\nresolution = 20\n");
    if compact {
        text += &format!("\n[[step]]\ndo = \"compact_rbf\"\nparticles = {N}\n");
    }
    let strokes = [
        (Vec3::new(0.0, 1.0, 0.0), Vec3::X, -1.0),
        (Vec3::new(1.0, 0.0, 0.0), Vec3::Z, 1.0),
        (Vec3::new(0.0, 0.0, 1.0), Vec3::Y, -1.0),
        (Vec3::new(-0.6, 0.6, 0.5).normalize(), Vec3::Z, 1.0),
    ];
    for (normal, along, alpha) in strokes {
        let on = Vec3::splat(CENTRE) + normal * RADIUS;
        let (a, b) = (on - along * 0.12, on + along * 0.12);
        text += &format!(
            "\n[[step]]\ndo = \"stroke\"\nshape = {{ kind = \"sphere\", radius_fu = {TOOL_RADIUS_FU} }}\n\
             action = {{ kind = \"contact\", alpha = {alpha:.1}, rate_per_s = {RATE_PER_S} }}\n\
             path = [[{}, {}, {}], [{}, {}, {}]]\nduration_s = 0.3\n",
            a.x, a.y, a.z, b.x, b.y, b.z
        );
    }
    text
}

/// What a run saw: the final base patch, and per applied re-interpolation (centres, whether
/// the clay then equalled the lattice fit of that RBF, undo depth).
struct Run {
    clay: BSplineLattice,
    applied: Vec<(usize, f32, usize)>,
    strokes_done: usize,
}

fn run(compact: bool) -> Run {
    let text = script(compact);
    let Scripted { plan, mut run, .. } = scripted(&text, "compact.toml", Path::new("."));
    let mut driver = ScriptDriver::new(&plan);
    let commands = run.commands();
    let ticks = (plan.seconds * 1000.0) as usize;
    let mut applied = Vec::new();
    for _ in 0..ticks {
        let sample = run.latest_tool();
        driver.dispatch(&sample, &commands);
        run.step();
        let status = run.sim().compact_status();
        if status.applied as usize > applied.len() {
            assert_eq!(status.applied as usize, applied.len() + 1, "one at a time");
            let rbf = run.sim().compact_rbf().expect("the applied RBF");
            let fit = rbf.to_clay(2).unwrap();
            let worst = fit
                .coeffs
                .iter()
                .zip(&run.field().coeffs)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0f32, f32::max);
            applied.push((status.centres.unwrap(), worst, run.sim().undo_len()));
        }
    }
    assert!(driver.is_done(), "steps left: {:?}", driver.unsent_steps());
    let strokes_done = run.sim().undo_len();
    let report = run.finish().unwrap();
    assert!(driver.failures().is_empty(), "{:?}", driver.failures());
    Run {
        clay: report.session.clay.base().clone(),
        applied,
        strokes_done,
    }
}

#[test]
fn contact_strokes_on_the_compact_clay_keep_its_centre_count_and_follow_the_plain_clay() {
    let plain = run(false);
    let compact = run(true);
    assert_eq!(plain.strokes_done, 4, "four strokes, four undo steps");
    // I⁰ when the step is reached, then one re-interpolation after each stroke.
    assert_eq!(compact.applied.len(), 5, "{:?}", compact.applied);
    let first = compact.applied[0].0;
    assert_eq!(first, 3 * N);
    for (k, &(centres, worst, undo)) in compact.applied.iter().enumerate() {
        assert_eq!(centres, first, "re-interpolation {k}");
        assert!(
            worst <= 1e-6,
            "after re-interpolation {k} the clay is {worst} from the RBF's lattice fit"
        );
        // I⁰ is one undo step; then each stroke and its re-interpolation are two.
        assert_eq!(undo, 1 + 2 * k, "undo depth after re-interpolation {k}");
    }

    let diag = 2.0 * f64::from(RADIUS) * 3f64.sqrt();
    let grid = SampleGrid::for_lattice(&plain.clay, 4).unwrap();
    let a = BrickOctree::build_with_threads(grid, &plain.clay, 2).weld();
    let b = BrickOctree::build_with_threads(grid, &compact.clay, 2).weld();
    let h = hausdorff(&a, &b).expect("both meshes");
    eprintln!(
        "compact ({N} particles, {first} centres) vs plain clay after four strokes: worst {:.4} \
         / {:.4}, mean {:.5} / {:.5} ({:.2}% of the diagonal {diag:.3})",
        h.a_to_b,
        h.b_to_a,
        h.mean_a_to_b,
        h.mean_b_to_a,
        100.0 * f64::from(h.max()) / diag
    );
    assert!(f64::from(h.max()) <= 0.01 * diag, "{h:?}");
    assert_ne!(
        plain.clay.coeffs, compact.clay.coeffs,
        "the compact clay is the RBF's fit, not the plain clay"
    );
}
