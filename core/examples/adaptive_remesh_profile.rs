//! Profiling harness for the multi-level mesher's local re-mesh (for `perf record`): the
//! three-level clay of `bench/mesh.rs` (`adaptive_remesh`), a stroke of three finest-level
//! coefficients and its undo re-meshed locally, alternately, many times. Prints the best and
//! median time of one local re-mesh with its mesh copy, and of one whole mesh, for a quick
//! look; the figures that count come from the criterion bench.
//!
//! Run: `cargo run --release -p dynaclay-core --example adaptive_remesh_profile [rounds]
//! [local]` (with `local`, the whole mesh is not timed: for a profile of the local path).

use std::hint::black_box;
use std::time::Instant;

use dynaclay_core::field::{BSplineLattice, MultiPatchField};
use dynaclay_core::mesh::{AdaptiveMeshOptions, AdaptiveMesher, mesh_adaptive};
use glam::Vec3;

/// The sphere of `bench/mesh.rs`: an `n³` lattice of unit spacing, radius in spans.
fn sphere_lattice(n: usize, radius_spans: f32) -> BSplineLattice {
    let mut lattice = BSplineLattice::zeros([n; 3], 1.0, Vec3::ZERO).expect("lattice");
    let centre = Vec3::splat((n - 1) as f32 / 2.0);
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let d = radius_spans - (lattice.node_position(i, j, k) - centre).length();
                let idx = lattice.index(i, j, k);
                lattice.coeffs[idx] = (0.5 + d / 6.0).clamp(0.0, 1.0);
            }
        }
    }
    lattice
}

/// The three-level clay before and after a stroke of three finest coefficients, and the
/// stroke's change box (as `bench/mesh.rs` builds it).
fn three_level_clay() -> (MultiPatchField, MultiPatchField, (Vec3, Vec3)) {
    let centre = Vec3::splat(11.5);
    let pole = centre + Vec3::X * 8.0;
    let mut field = MultiPatchField::new(sphere_lattice(24, 8.0));
    let mut finest = 0;
    for level in 1..=3_u32 {
        let spacing = 1.0 / (1 << level) as f32;
        let half = Vec3::splat(3.0 / (1 << (level - 1)) as f32);
        finest = field
            .refine(pole - half, pole + half, level)
            .expect("refine");
        let lattice = &mut field.patches[finest].lattice;
        let [nx, ny, nz] = lattice.dims;
        let width = 2.0 * spacing;
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    let x = lattice.node_position(i, j, k);
                    let bump = 0.01 * (-(x - pole).length_squared() / (width * width)).exp();
                    let idx = lattice.index(i, j, k);
                    lattice.coeffs[idx] = bump;
                }
            }
        }
    }
    let before = field.clone();
    let mut after = field;
    let patch = &mut after.patches[finest];
    let node = ((pole - patch.lattice.origin) / patch.lattice.spacing).round();
    let first = [node.x as usize, node.y as usize, node.z as usize];
    for step in 0..3 {
        let idx = patch.lattice.index(first[0] + step, first[1], first[2]);
        patch.lattice.coeffs[idx] -= 0.05;
    }
    let change = patch.coefficient_change_box(first, [first[0] + 2, first[1], first[2]]);
    (before, after, change)
}

fn median_and_best(mut times_ms: Vec<f64>) -> (f64, f64) {
    times_ms.sort_by(f64::total_cmp);
    (times_ms[times_ms.len() / 2], times_ms[0])
}

fn main() {
    let rounds: usize = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(2000);
    let (before, after, (lo, hi)) = three_level_clay();
    let options = AdaptiveMeshOptions::default();
    let mut mesher = AdaptiveMesher::new(&before, &options).expect("mesher");
    let mut local_ms = Vec::with_capacity(rounds);
    let mut last = None;
    for round in 0..rounds {
        let field = if round % 2 == 0 { &after } else { &before };
        let start = Instant::now();
        let report = mesher.remesh_box(field, lo, hi).expect("re-mesh");
        let mesh = black_box(mesher.mesh());
        local_ms.push(start.elapsed().as_secs_f64() * 1e3);
        assert!(!report.whole && report.polygons_made > 0, "{report:?}");
        last = Some((report, mesh.triangles.len()));
    }
    let local_only = std::env::args().nth(2).is_some_and(|a| a == "local");
    let whole_rounds = if local_only { 1 } else { (rounds / 100).max(3) };
    let mut whole_ms = Vec::new();
    for round in 0..whole_rounds {
        let field = if round % 2 == 0 { &after } else { &before };
        let start = Instant::now();
        black_box(mesh_adaptive(field, &options).expect("whole"));
        whole_ms.push(start.elapsed().as_secs_f64() * 1e3);
    }
    let (local_median, local_best) = median_and_best(local_ms);
    let (whole_median, whole_best) = median_and_best(whole_ms);
    println!("last local re-mesh: {last:?}");
    println!("local: median {local_median:.3} ms, best {local_best:.3} ms");
    println!("whole: median {whole_median:.3} ms, best {whole_best:.3} ms");
}
