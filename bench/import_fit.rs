//! Fitting clays to point clouds (Hua & Qin §5, issue 14 item 6). Run with
//! `cargo bench --bench import_fit` (append `-- quick` to skip the 1M-point runs).
//!
//! 1. **Fit time against point count** (1k to 1M points, and Guo & Qin's 35,947): a ball
//!    without normals (estimated and turned outward by the flood) with the default options
//!    (32³ base, error bound 0.5% of the size, depth 2), and a box with sharp edges at a tight
//!    bound (0.15%, depth 2) that makes the octree refine. Wall time is the median of three
//!    runs (one at 1M); peak memory is the process's peak resident set (VmHWM), reset before
//!    each size through `/proc/self/clear_refs`, so it is the peak of that size's fits. Each
//!    fit is checked: a fit whose points lie off its surface fails the run.
//! 2. **Fit time against the error bound**: the sharp box at 100k points, depth 3.
//! 3. **Closed meshes** (`-- mesh` runs this part alone): a torus of about 20k and 200k
//!    triangles and an icosphere of 20k and 82k, written as binary STL and imported with the
//!    default settings through the signed-distance path: the time to weld and check the mesh
//!    and to build its signed-distance grid, and the whole import (read, check, grid, volume fit). The fitted
//!    surface is checked against the mesh's vertices.
//! 4. **Evaluation**: the value of a single 32³ patch against a two-level clay (the same base
//!    plus detail patches from the sharp-box fit), per point at random places in the object's
//!    box, and over a simulation step's worth of samples (the mass grid of a 12-span local
//!    region at two samples per span, 25³ points, as `dynamics` samples it).
//! 5. **Peers on public models** (`-- peers` runs this part alone): the scanned bunny, the
//!    fandisk, the rocker arm and spot, each as a 50 000-point cloud with normals in three
//!    variants (0.25% noise, 1% noise, 0.25% noise + 5% outliers), reconstructed by dynaclay
//!    and by screened Poisson (the `poisson_reconstruction` crate, and Kazhdan's PoissonRecon
//!    when `POISSON_RECON` names its binary): distance to the clean model both ways, pieces
//!    and genus, time and memory per point, and dynaclay's ratios to each peer, in one table.
//!    The models come from `bench/models/get.sh` (or `DYNACLAY_MODELS`); see
//!    `bench/support/peer_comparison.rs`. `POISSON_CRATE_DEPTH` lowers the crate's depth
//!    (8 by default) and `POISSON_CRATE_SKIP` leaves it out, on machines where it is too slow.

use std::time::Instant;

use dynaclay::field::{BSplineLattice, MultiPatchField};
use dynaclay::fit::{
    CloudFitOptions, FitPath, HierarchicalFit, HierarchyOptions, ImportSettings, PointCloud,
    check_closed, closed_mesh_grid, fit_hierarchy, fit_import, signed_distance,
};
use glam::Vec3;

// The bench uses the shapes and binary STL only.
#[allow(dead_code)]
#[path = "../tests/support/meshes.rs"]
mod meshes;

use meshes::{binary_stl, icosphere, torus};

#[path = "support/memory.rs"]
mod memory;
#[path = "support/models.rs"]
mod models;
#[path = "support/peer_comparison.rs"]
mod peer_comparison;
#[path = "support/reconstructors.rs"]
mod reconstructors;
#[path = "support/surface_compare.rs"]
mod surface_compare;

use memory::{peak_bytes, reset_peak};

/// Closed meshes through the signed-distance path, default import settings.
fn closed_meshes() {
    let settings = ImportSettings::default();
    println!(
        "\nclosed meshes (binary STL), default settings: {}³ base, error bound {}%, depth {}",
        settings.resolution, settings.error_percent, settings.max_depth
    );
    println!(
        "| mesh | triangles | grid | weld + check | signed-distance grid | whole import (median of 3) | peak RSS | patches | mean / worst vertex distance (% of size) |"
    );
    println!("| --- | --- | --- | --- | --- | --- | --- | --- | --- |");
    let dir = std::env::temp_dir().join(format!("dynaclay-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("a temporary folder");
    let cases: [(&str, meshes::Mesh); 4] = [
        ("torus", torus(3.0, 1.0, 142, 71)),
        ("torus", torus(3.0, 1.0, 448, 224)),
        ("icosphere", icosphere(5)),
        ("icosphere", icosphere(6)),
    ];
    for (name, mesh) in &cases {
        let path = dir.join(format!("{name}.stl"));
        std::fs::write(&path, binary_stl(mesh)).expect("the STL is written");
        reset_peak();
        let mut times = Vec::new();
        let mut fit = None;
        for _ in 0..3 {
            let start = Instant::now();
            let f =
                fit_import(&path, &settings, &mut |_| true, &mut |_| {}).expect("the import runs");
            times.push(start.elapsed().as_secs_f64());
            fit = Some(f);
        }
        let peak = peak_mib();
        times.sort_by(f64::total_cmp);
        let fit = fit.expect("one run");
        assert!(
            matches!(fit.path, FitPath::ClosedMesh(_)),
            "{name}: {:?}",
            fit.path
        );
        // Weld + check, and the grid, timed on their own with the import's grid.
        let start = Instant::now();
        let (welded, check) = check_closed(&mesh.0, &mesh.1);
        let check_s = start.elapsed().as_secs_f64();
        assert!(check.is_closed());
        let (lo, hi) = welded
            .positions
            .iter()
            .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(a, b), &p| {
                (a.min(p), b.max(p))
            });
        let (grid, _) = closed_mesh_grid(&settings, lo, hi).expect("the grid fits");
        let mut grid_times = Vec::new();
        for _ in 0..3 {
            let start = Instant::now();
            let sdf = signed_distance(&welded, &grid, &mut || false).expect("not stopped");
            grid_times.push(start.elapsed().as_secs_f64());
            std::hint::black_box(sdf.inside);
        }
        grid_times.sort_by(f64::total_cmp);
        // The mesh's vertices against the fitted surface, to first order.
        let size = (hi - lo).max_element() * fit.scale;
        let (mut sum, mut worst) = (0.0f64, 0.0f32);
        for &p in &mesh.0 {
            let (v, g) = fit.field.value_and_gradient(fit.to_field(p));
            let d = (v - fit.field.iso()).abs() / g.length().max(1e-6) / size * 100.0;
            sum += f64::from(d);
            worst = worst.max(d);
        }
        let mean = sum / mesh.0.len() as f64;
        assert!(
            mean < 0.5 && worst < 1.0,
            "{name}: the vertices lie {mean}% (worst {worst}%) of the size off the surface"
        );
        println!(
            "| {name} | {} | {}×{}×{} | {check_s:.3} s | {:.3} s | {:.3} s | {peak:.0} MiB | {} | {mean:.3}% / {worst:.3}% |",
            mesh.1.len(),
            grid.dims[0],
            grid.dims[1],
            grid.dims[2],
            grid_times[1],
            times[1],
            fit.field.patches.len()
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

fn ball(count: usize) -> PointCloud {
    let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
    let points = (0..count)
        .map(|i| {
            let y = 1.0 - 2.0 * (i as f32 + 0.5) / count as f32;
            let r = (1.0 - y * y).sqrt();
            let phi = golden * i as f32;
            Vec3::new(r * phi.cos(), y, r * phi.sin()) * 40.0
        })
        .collect();
    PointCloud {
        points,
        normals: None,
    }
}

/// A 2 × 1.4 × 1 box with edges rounded by 0.03 (a tenth of a knot span at 32³): points
/// spread over its faces, edges and corners by projecting a fixed scatter onto it.
fn sharp_box(count: usize) -> PointCloud {
    let (half, round) = (Vec3::new(1.0, 0.7, 0.5), 0.03f32);
    let sdf = |p: Vec3| {
        let q = p.abs() - (half - Vec3::splat(round));
        q.max(Vec3::ZERO).length() + q.max_element().min(0.0) - round
    };
    let mut seed = 0x9e37_79b9_u32;
    let mut unit = move || {
        seed ^= seed << 13;
        seed ^= seed >> 17;
        seed ^= seed << 5;
        seed as f32 / u32::MAX as f32 * 2.0 - 1.0
    };
    let mut points = Vec::with_capacity(count);
    while points.len() < count {
        let mut p = Vec3::new(unit(), unit(), unit()) * half * 1.2;
        for _ in 0..4 {
            let h = 1e-3;
            let g = Vec3::new(
                sdf(p + Vec3::X * h) - sdf(p - Vec3::X * h),
                sdf(p + Vec3::Y * h) - sdf(p - Vec3::Y * h),
                sdf(p + Vec3::Z * h) - sdf(p - Vec3::Z * h),
            )
            .normalize_or_zero();
            p -= g * sdf(p);
        }
        if sdf(p).abs() < 1e-4 {
            points.push(p);
        }
    }
    PointCloud {
        points,
        normals: None,
    }
}

/// The peak resident set since the last reset, MiB.
fn peak_mib() -> f64 {
    peak_bytes() / (1024.0 * 1024.0)
}

/// Mean and worst first-order distance of the points from the fitted surface, percent of the
/// size.
fn point_error(fit: &HierarchicalFit, cloud: &PointCloud) -> (f64, f32) {
    let (mut sum, mut worst) = (0.0f64, 0.0f32);
    for &p in &cloud.points {
        let (v, g) = fit.field.value_and_gradient(fit.to_field(p));
        let d = (v - fit.field.iso()).abs() / g.length().max(1e-6) / fit.size * 100.0;
        sum += f64::from(d);
        worst = worst.max(d);
    }
    (sum / cloud.points.len() as f64, worst)
}

fn timed_fit(
    cloud: &PointCloud,
    options: &HierarchyOptions,
    runs: usize,
) -> (f64, HierarchicalFit) {
    let mut times = Vec::new();
    let mut fit = None;
    for _ in 0..runs {
        let start = Instant::now();
        let f = fit_hierarchy(cloud, options, &mut |_| true).expect("the fit runs");
        times.push(start.elapsed().as_secs_f64());
        fit = Some(f);
    }
    times.sort_by(f64::total_cmp);
    (times[times.len() / 2], fit.expect("one run at least"))
}

fn counts_table(
    name: &str,
    make: fn(usize) -> PointCloud,
    options: &HierarchyOptions,
    quick: bool,
) {
    println!(
        "\n{name}: error bound {}% of the size, depth {}",
        options.error * 100.0,
        options.max_depth
    );
    println!(
        "| points | fit time (median) | peak RSS | patches | RMS error (base alone) | mean / worst point distance |"
    );
    println!("| --- | --- | --- | --- | --- | --- |");
    let only_big = std::env::args().any(|a| a == "big");
    for count in [1_000usize, 10_000, 35_947, 100_000, 1_000_000] {
        if (quick && count >= 1_000_000) || (only_big && count < 1_000_000) {
            continue;
        }
        let cloud = make(count);
        reset_peak();
        let runs = if count >= 1_000_000 { 1 } else { 3 };
        let (time, fit) = timed_fit(&cloud, options, runs);
        let peak = peak_mib();
        let (mean, worst) = point_error(&fit, &cloud);
        // A fit that misses its points fails the run (a sparse cloud's corners are allowed
        // a few percent).
        assert!(
            mean < 0.5 && worst < 5.0,
            "{count} points: the points lie {mean}% (worst {worst}%) of the size off the surface"
        );
        println!(
            "| {count} | {time:.3} s | {peak:.0} MiB | {} | {:.3}% ({:.3}%) | {mean:.3}% / {worst:.3}% |",
            fit.field.patches.len(),
            fit.rms * 100.0,
            fit.rms_base * 100.0
        );
    }
}

/// Nanoseconds per call of `f` over `points`, the best of five passes.
fn ns_per(points: &[Vec3], f: impl Fn(Vec3) -> f32) -> f64 {
    let mut best = f64::INFINITY;
    for _ in 0..5 {
        let start = Instant::now();
        let mut sum = 0.0f32;
        for &p in points {
            sum += f(p);
        }
        std::hint::black_box(sum);
        best = best.min(start.elapsed().as_secs_f64() * 1e9 / points.len() as f64);
    }
    best
}

fn evaluation(quick: bool) {
    let cloud = sharp_box(100_000);
    let options = HierarchyOptions {
        error: 0.0015,
        max_depth: 2,
        ..HierarchyOptions::default()
    };
    let fit = fit_hierarchy(&cloud, &options, &mut |_| true).expect("the fit runs");
    let single = MultiPatchField::new(fit.field.patches[0].lattice.clone());
    let two_level = &fit.field;
    let lattices: Vec<BSplineLattice> = two_level
        .patches
        .iter()
        .map(|p| p.lattice.clone())
        .collect();
    // Random points in the object's box.
    let (lo, hi) = (
        fit.to_field(Vec3::new(-1.0, -0.7, -0.5)),
        fit.to_field(Vec3::new(1.0, 0.7, 0.5)),
    );
    let mut seed = 12345u32;
    let mut unit = move || {
        seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        (seed >> 8) as f32 / (1u32 << 24) as f32
    };
    let n = if quick { 100_000 } else { 1_000_000 };
    let random: Vec<Vec3> = (0..n)
        .map(|_| lo + (hi - lo) * Vec3::new(unit(), unit(), unit()))
        .collect();
    // A local region's mass grid: 12 spans at two samples per span around an edge of the box.
    let base = &fit.field.patches[0].lattice;
    let corner = fit.to_field(Vec3::new(1.0, 0.7, 0.0)) - Vec3::splat(6.0 * base.spacing);
    let step: Vec<Vec3> = (0..25 * 25 * 25)
        .map(|i| {
            let (x, y, z) = (i % 25, (i / 25) % 25, i / 625);
            corner + Vec3::new(x as f32, y as f32, z as f32) * 0.5 * base.spacing
        })
        .collect();
    println!(
        "\nevaluation: a single 32³ patch against the two-level clay of the sharp box (base + {} detail patches, {} coefficients in all)",
        two_level.patches.len() - 1,
        lattices.iter().map(|l| l.coeffs.len()).sum::<usize>()
    );
    println!(
        "| evaluation | single patch | two-level clay (MultiPatchField) | two-level clay (its lattices summed, maps skipped) |"
    );
    println!("| --- | --- | --- | --- |");
    let summed = |x: Vec3| lattices.iter().map(|l| l.value(x)).sum::<f32>();
    println!(
        "| value at random points in the box | {:.1} ns | {:.1} ns | {:.1} ns |",
        ns_per(&random, |x| single.value(x)),
        ns_per(&random, |x| two_level.value(x)),
        ns_per(&random, summed)
    );
    println!(
        "| value and gradient, random points | {:.1} ns | {:.1} ns | – |",
        ns_per(&random, |x| single.value_and_gradient(x).0),
        ns_per(&random, |x| two_level.value_and_gradient(x).0),
    );
    let per_step = |ns: f64| ns * step.len() as f64 / 1e3;
    println!(
        "| a step's mass grid (25³ samples at an edge) | {:.0} µs | {:.0} µs | {:.0} µs |",
        per_step(ns_per(&step, |x| single.value(x))),
        per_step(ns_per(&step, |x| two_level.value(x))),
        per_step(ns_per(&step, summed))
    );
}

fn main() {
    let quick = std::env::args().any(|a| a == "quick");
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    println!("import_fit: load average {}", load.trim());
    if std::env::args().any(|a| a == "peers") {
        peer_comparison::run(quick);
        let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
        println!("load average after: {}", load.trim());
        return;
    }
    if std::env::args().any(|a| a == "mesh") {
        closed_meshes();
        let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
        println!("load average after: {}", load.trim());
        return;
    }
    counts_table(
        "ball without normals, default options",
        ball,
        &HierarchyOptions::default(),
        quick,
    );
    let tight = HierarchyOptions {
        error: 0.0015,
        max_depth: 2,
        ..HierarchyOptions::default()
    };
    counts_table(
        "sharp box without normals, tight bound",
        sharp_box,
        &tight,
        quick,
    );

    println!("\nerror bound (sharp box, 100k points, depth 3)");
    println!(
        "| bound (% of size) | fit time (median of 3) | patches per depth | RMS error (base alone) |"
    );
    println!("| --- | --- | --- | --- |");
    let cloud = sharp_box(100_000);
    for error in [0.01f32, 0.005, 0.0025, 0.0015, 0.001] {
        let options = HierarchyOptions {
            base: CloudFitOptions::default(),
            error,
            max_depth: 3,
        };
        let (time, fit) = timed_fit(&cloud, &options, 3);
        let per_depth: Vec<String> = fit.levels.iter().map(|l| l.refined.to_string()).collect();
        println!(
            "| {:.2} | {time:.3} s | {} | {:.3}% ({:.3}%) |",
            error * 100.0,
            if per_depth.is_empty() {
                "–".to_string()
            } else {
                per_depth.join(" / ")
            },
            fit.rms * 100.0,
            fit.rms_base * 100.0
        );
    }
    closed_meshes();
    evaluation(quick);
    peer_comparison::run(quick);
}
