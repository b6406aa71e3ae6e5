//! Profiling harness for the multi-level mesher's local re-mesh (for `perf record`): the
//! three-level clay of the `adaptive_remesh` bench (`bench/support/mesh_clays.rs`), a stroke
//! of three finest-level coefficients and its undo re-meshed locally, alternately, many
//! times. Prints the best and median time of one local re-mesh with its mesh copy, and of
//! one whole mesh, for a quick look; the figures that count come from the criterion bench.
//!
//! Run: `cargo bench --bench profile_adaptive -- [rounds] [local] [cells_per_span] [cut]
//! [window]` (with `local`, the whole mesh is not timed: for a profile of the local path; with
//! a cells per span, the mesher meshes every level at that many, 2 by default; with `cut`, the
//! local re-mesh is the graphics loop's, cut into an octree's bricks on the grid of the
//! engine's cells per span, as `bench/mesh.rs` `graphics_stroke` times it; with `window`, the
//! cells per span are the base's and the detail patches take the graphics loop's share of
//! them, `dynaclay::engine::level_mesh_options`).

use std::hint::black_box;
use std::time::Instant;

use dynaclay::engine::level_mesh_options;
use dynaclay::mesh::{
    AdaptiveBricks, AdaptiveMeshOptions, AdaptiveMesher, BrickOctree, SampleGrid, mesh_adaptive,
};

#[path = "support/mesh_clays.rs"]
mod mesh_clays;
use mesh_clays::three_level_clay;

/// The median and the least of `times_ms` (NaN for none).
fn median_and_best(mut times_ms: Vec<f64>) -> (f64, f64) {
    times_ms.sort_by(f64::total_cmp);
    match times_ms.first() {
        Some(&best) => (times_ms[times_ms.len() / 2], best),
        None => (f64::NAN, f64::NAN),
    }
}

fn main() {
    // `cargo bench` adds `--bench`: only the words without dashes are ours.
    let words: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .collect();
    let rounds: usize = words.first().and_then(|s| s.parse().ok()).unwrap_or(2000);
    let local_only = words.get(1).is_some_and(|a| a == "local");
    let cells_per_span: u32 = words.get(2).and_then(|s| s.parse().ok()).unwrap_or(2);
    let cut = words.get(3).is_some_and(|a| a == "cut");
    let window = words.get(4).is_some_and(|a| a == "window");
    let (before, after, (lo, hi)) = three_level_clay();
    let options = if window {
        level_mesh_options(cells_per_span)
    } else {
        AdaptiveMeshOptions {
            cells_per_span,
            detail_cells_per_span: cells_per_span,
            ..AdaptiveMeshOptions::default()
        }
    };
    println!("options: {options:?}");
    let mut local_ms = Vec::with_capacity(rounds);
    if cut {
        let grid = SampleGrid::for_field(&before, cells_per_span).expect("grid");
        let mut octree = BrickOctree::new(grid);
        let (mut bricks, _) = AdaptiveBricks::new(&before, &options, &mut octree).expect("cut");
        let mut last = None;
        for round in 0..rounds {
            let field = if round % 2 == 0 { &after } else { &before };
            let start = Instant::now();
            let report = bricks
                .remesh_box(field, lo, hi, &mut octree)
                .expect("re-mesh");
            local_ms.push(start.elapsed().as_secs_f64() * 1e3);
            assert!(!report.changed.is_empty());
            last = Some((report.changed.len(), report.removed.len()));
        }
        println!("last cut re-mesh: (changed, removed) bricks {last:?}");
    } else {
        let mut mesher = AdaptiveMesher::new(&before, &options).expect("mesher");
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
        println!("last local re-mesh: {last:?}");
    }
    let whole_rounds = if local_only { 1 } else { (rounds / 100).max(3) };
    let mut whole_ms = Vec::new();
    for round in 0..whole_rounds {
        let field = if round % 2 == 0 { &after } else { &before };
        let start = Instant::now();
        black_box(mesh_adaptive(field, &options).expect("whole"));
        whole_ms.push(start.elapsed().as_secs_f64() * 1e3);
    }
    // The stroke (even rounds) and its undo (odd rounds) apart: they re-mesh different
    // fields and need not cost the same.
    let (stroke_median, _) = median_and_best(local_ms.iter().copied().step_by(2).collect());
    let (undo_median, _) = median_and_best(local_ms.iter().copied().skip(1).step_by(2).collect());
    let (local_median, local_best) = median_and_best(local_ms);
    let (whole_median, whole_best) = median_and_best(whole_ms);
    println!(
        "local: median {local_median:.3} ms, best {local_best:.3} ms (medians: stroke \
         {stroke_median:.3} ms, undo {undo_median:.3} ms)"
    );
    println!("whole: median {whole_median:.3} ms, best {whole_best:.3} ms");
}
