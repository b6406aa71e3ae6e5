//! A dense scan chooses a base lattice fine enough for its sharp features: a cube (side 2)
//! sampled as a 50 000-point cloud with normals and Gaussian noise of 0.25% of its side,
//! imported from a file with the defaults (the knots set by its noise, within what its count
//! affords), lies closer to the cube along its edges (the 99th
//! percentile of the distance) than the same file imported on the fixed 32-knot lattice, which
//! rounds its edges over a wider span; both are one closed piece of genus 0.

use std::fmt::Write as _;
use std::path::Path;

use dynaclay_core::mesh::{BrickOctree, SampleGrid};
use dynaclay_import::fit::import::MAX_POINTS_RESOLUTION;
use dynaclay_import::fit::{
    DEFAULT_RESOLUTION, ImportSettings, ImportedFit, fit_import, most_resolution_for_points,
    resolution_for_points,
};
use glam::Vec3;

/// The cube's half side, file units (its size, the box's longest side, is twice this).
const HALF_SIDE: f32 = 1.0;

/// Exact distance to the cube's surface, positive outside.
fn cube_distance(p: Vec3) -> f32 {
    let q = p.abs() - Vec3::splat(HALF_SIDE);
    q.max(Vec3::ZERO).length() + q.max_element().min(0.0)
}

/// A small deterministic generator (LCG), so the test is the same every run.
struct Rng(u64);

impl Rng {
    fn unit(&mut self) -> f32 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        ((self.0 >> 40) as f32 + 0.5) / (1u64 << 24) as f32
    }

    /// A standard normal deviate (Box–Muller).
    fn gauss(&mut self) -> f32 {
        let (a, b) = (self.unit(), self.unit());
        (-2.0 * a.ln()).sqrt() * (std::f32::consts::TAU * b).cos()
    }
}

/// `count` points uniform on the cube's faces with their normals, `x y z nx ny nz` per line,
/// with Gaussian noise of `noise` times its side (per axis).
fn cube_xyz(count: usize, noise: f32) -> String {
    let mut rng = Rng(0x00c0_be5e);
    let sigma = noise * 2.0 * HALF_SIDE;
    let mut text = String::with_capacity(count * 64);
    for _ in 0..count {
        let face = ((rng.unit() * 6.0) as usize).min(5);
        let (axis, sign) = (face % 3, if face < 3 { 1.0 } else { -1.0 });
        let mut n = Vec3::ZERO;
        n[axis] = sign;
        let mut p = Vec3::new(rng.unit(), rng.unit(), rng.unit()) * 2.0 * HALF_SIDE
            - Vec3::splat(HALF_SIDE);
        p[axis] = sign * HALF_SIDE;
        let p = p + Vec3::new(rng.gauss(), rng.gauss(), rng.gauss()) * sigma;
        writeln!(text, "{} {} {} {} {} {}", p.x, p.y, p.z, n.x, n.y, n.z).unwrap();
    }
    text
}

/// The fitted surface's vertices (meshed at a third of the base spacing), file units: their
/// 99th-percentile distance to the cube as a fraction of its size, and the mesh's Euler
/// characteristic (2 for one closed piece of genus 0).
fn p99_distance_and_euler(fit: &ImportedFit) -> (f32, i64) {
    let base = &fit.field.patches[0].lattice;
    let (lo, hi) = base.support();
    let grid = SampleGrid::covering(lo, hi, base.spacing / 3.0).unwrap();
    let mesh = BrickOctree::build(grid, &fit.field).weld();
    let mut distances: Vec<f32> = mesh
        .positions
        .iter()
        .map(|&v| cube_distance((v - fit.offset) / fit.scale).abs())
        .collect();
    distances.sort_by(f32::total_cmp);
    let size = 2.0 * HALF_SIDE;
    let at = |q: f32| 100.0 * distances[((distances.len() - 1) as f32 * q) as usize] / size;
    eprintln!(
        "{}³: distance to the cube, % of its size: p50 {:.4} p90 {:.4} p99 {:.4}",
        base.dims[0],
        at(0.5),
        at(0.9),
        at(0.99)
    );
    let mut edges = std::collections::HashSet::new();
    for t in &mesh.triangles {
        for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            edges.insert((a.min(b), a.max(b)));
        }
    }
    let euler = mesh.positions.len() as i64 - edges.len() as i64 + mesh.triangles.len() as i64;
    (at(0.99) / 100.0, euler)
}

fn import(path: &Path, settings: &ImportSettings) -> ImportedFit {
    fit_import(path, settings, &mut |_| true, &mut |_| {}).expect("the cloud imports")
}

#[test]
fn a_dense_scan_of_a_cube_keeps_its_edges_closer_on_the_lattice_its_count_chooses() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cube.xyz");
    let count = 50_000;
    std::fs::write(&path, cube_xyz(count, 0.0025)).unwrap();
    let defaults = import(&path, &ImportSettings::default());
    // The count bounds the knots; a quarter of a percent of noise on a cube's 50 000 points
    // (a span of 0.9 (σ s)^(1/3) would be some 37 across it) takes the most it affords.
    let chosen = defaults.field.patches[0].lattice.dims[0];
    assert!(chosen > DEFAULT_RESOLUTION, "{chosen} knots");
    assert!(chosen >= resolution_for_points(count), "{chosen} knots");
    assert_eq!(chosen, most_resolution_for_points(count));
    assert_eq!(defaults.field.patches[0].lattice.dims, [chosen; 3]);
    let fixed = import(
        &path,
        &ImportSettings {
            resolution_from_points: false,
            ..ImportSettings::default()
        },
    );
    assert_eq!(fixed.field.patches[0].lattice.dims, [DEFAULT_RESOLUTION; 3]);

    let (chosen_p99, chosen_euler) = p99_distance_and_euler(&defaults);
    let (fixed_p99, fixed_euler) = p99_distance_and_euler(&fixed);
    assert_eq!(chosen_euler, 2, "the chosen lattice's surface");
    assert_eq!(fixed_euler, 2, "the fixed lattice's surface");
    // The edges follow the cube more closely by a clear margin, and within half a percent
    // of its size (the noise is a quarter of a percent).
    assert!(
        chosen_p99 < 0.75 * fixed_p99,
        "{chosen_p99} against {fixed_p99}"
    );
    assert!(chosen_p99 < 0.005, "{chosen_p99}");
}

#[test]
fn the_point_count_chooses_more_knots_for_more_points_within_bounds() {
    let mut last = 0;
    for points in [0, 1_000, 26_000, 50_000, 100_000, 1_000_000, usize::MAX] {
        let knots = resolution_for_points(points);
        assert!(
            (DEFAULT_RESOLUTION..=MAX_POINTS_RESOLUTION).contains(&knots),
            "{points} points: {knots}"
        );
        let most = most_resolution_for_points(points);
        assert!(
            (knots..=MAX_POINTS_RESOLUTION).contains(&most),
            "{points} points: at most {most}, at least {knots}"
        );
        assert!(knots >= last, "{points} points: {knots} after {last}");
        last = knots;
    }
    assert_eq!(resolution_for_points(1_000), DEFAULT_RESOLUTION);
    assert_eq!(resolution_for_points(usize::MAX), MAX_POINTS_RESOLUTION);
}
