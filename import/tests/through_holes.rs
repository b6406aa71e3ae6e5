//! A sparse cloud without normals of a part with a narrow hole through it fits with the hole
//! open: a block 2 × 2 × 1 with a round hole of radius 0.15 through its thickness (a tunnel
//! three times as long as it is wide, as a rocker arm's or a bracket's bolt hole is), sampled
//! as 4 000 points spread by area with Gaussian noise of 0.25% of the diagonal and no normals,
//! for six seeds. Each cloud is imported as a file, as `dynaclay import` imports it, and the
//! fitted clay is meshed as `--mesh` meshes it.
//!
//! The judge is the block itself: every fit is one closed piece of genus 1, the clay is
//! outside along the hole's axis, and the fitted surface lies near the block's.
//!
//! The closing that finds a sparse cloud's outside shuts so narrow a hole, and the points on
//! its wall find no outside along their probes either way: each took the side less deep under
//! the outside, through the wall to the block's faces, and pointed into the wall. Before their
//! sides were carried in from the hole's mouths the same clouds fitted with handles (genus 7
//! on four seeds, 2 on one) and a 99th percentile of 3.3–6.2% of the diagonal, against
//! 0.94–1.18% now (bench/RESULTS.md, "A shut tunnel's walls oriented from its mouths"); the
//! bar, 1.5%, is over the block's sharp edges, which a cloud without normals rounds.

mod support;

use std::fmt::Write as _;
use std::path::Path;

use dynaclay_core::mesh::{BrickOctree, SampleGrid, TriMesh};
use dynaclay_import::fit::{ImportSettings, ImportedFit, fit_import};
use glam::Vec3;
use support::{Uniform, pieces};

/// The block's half sides.
const HALF: Vec3 = Vec3::new(1.0, 1.0, 0.5);
/// The hole's radius; its axis is the z axis.
const HOLE_RADIUS: f32 = 0.15;
/// The points sampled per cloud.
const POINTS: usize = 4000;
/// The clouds sampled, one per seed.
const SEEDS: u64 = 6;

/// The block's signed distance, positive outside: the box less the hole's cylinder (exact
/// off the hole's rims, where it is a lower bound).
fn block_distance(p: Vec3) -> f32 {
    let q = p.abs() - HALF;
    let to_box = q.max(Vec3::ZERO).length() + q.max_element().min(0.0);
    let to_hole = HOLE_RADIUS - Vec3::new(p.x, p.y, 0.0).length();
    to_box.max(to_hole)
}

/// A point of the block's surface, spread by area: the top and bottom less the hole's
/// disc, the four sides, and the hole's wall.
fn surface_point(uniform: &mut Uniform) -> Vec3 {
    let faces = 4.0 * HALF.x * HALF.y - std::f32::consts::PI * HOLE_RADIUS * HOLE_RADIUS;
    let sides = 4.0 * (2.0 * HALF.x) * (2.0 * HALF.z);
    let wall = std::f32::consts::TAU * HOLE_RADIUS * 2.0 * HALF.z;
    let at = uniform.next() * (2.0 * faces + sides + wall);
    if at < 2.0 * faces {
        let z = if at < faces { HALF.z } else { -HALF.z };
        loop {
            let (x, y) = (
                uniform.between(-HALF.x, HALF.x),
                uniform.between(-HALF.y, HALF.y),
            );
            if x * x + y * y > HOLE_RADIUS * HOLE_RADIUS {
                return Vec3::new(x, y, z);
            }
        }
    } else if at < 2.0 * faces + sides {
        let (s, z) = (uniform.between(-1.0, 1.0), uniform.between(-HALF.z, HALF.z));
        match uniform.next() {
            k if k < 0.25 => Vec3::new(HALF.x, s * HALF.y, z),
            k if k < 0.5 => Vec3::new(-HALF.x, s * HALF.y, z),
            k if k < 0.75 => Vec3::new(s * HALF.x, HALF.y, z),
            _ => Vec3::new(s * HALF.x, -HALF.y, z),
        }
    } else {
        let a = uniform.between(0.0, std::f32::consts::TAU);
        let z = uniform.between(-HALF.z, HALF.z);
        Vec3::new(HOLE_RADIUS * a.cos(), HOLE_RADIUS * a.sin(), z)
    }
}

/// Writes `text` (a cloud's `x y z` lines) to `path`, imports it as `dynaclay import` does
/// and meshes the fitted clay as `--mesh` does.
fn import_and_mesh(path: &Path, text: &str) -> (ImportedFit, TriMesh) {
    std::fs::write(path, text).unwrap();
    let fit = fit_import(path, &ImportSettings::default(), &mut |_| true, &mut |_| {})
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let grid = SampleGrid::for_field(&fit.field, 4).unwrap();
    let fitted = BrickOctree::build(grid, &fit.field).weld();
    (fit, fitted)
}

/// [`POINTS`] points of the block with Gaussian noise of 0.25% of its diagonal, as `x y z`
/// lines (no normals).
fn block_cloud(seed: u64) -> String {
    let sigma = 0.0025 * (2.0 * HALF).length();
    let mut uniform = Uniform(seed);
    let mut text = String::new();
    for _ in 0..POINTS {
        let p = surface_point(&mut uniform);
        let jitter = Vec3::new(uniform.normal(), uniform.normal(), uniform.normal());
        let p = p + jitter * sigma;
        writeln!(text, "{} {} {}", p.x, p.y, p.z).unwrap();
    }
    text
}

#[test]
fn a_sparse_cloud_of_a_block_without_normals_fits_with_its_narrow_hole_open() {
    let dir = tempfile::tempdir().unwrap();
    let diagonal = (2.0 * HALF).length();
    let mut failures = Vec::new();
    for seed in 1..=SEEDS {
        let path = dir.path().join(format!("block-{seed}.xyz"));
        let (fit, fitted) = import_and_mesh(&path, &block_cloud(seed));
        let found = pieces(&fitted);
        // Along the hole's axis, between its mouths, the clay is outside.
        let filled = (-8..=8)
            .map(|k| Vec3::new(0.0, 0.0, 0.05 * k as f32))
            .filter(|&p| fit.field.value(fit.to_field(p)) > fit.field.iso())
            .count();
        // How far the fitted surface lies from the block, % of the diagonal (the mesh's
        // vertices, back in file units).
        let to_file = |p: Vec3| (p - fit.offset) / fit.scale;
        let mut distances: Vec<f32> = fitted
            .positions
            .iter()
            .map(|&p| 100.0 * block_distance(to_file(p)).abs() / diagonal)
            .collect();
        distances.sort_by(f32::total_cmp);
        let p99 = distances[(distances.len() - 1) * 99 / 100];
        println!("seed {seed}: pieces {found:?}, axis points filled {filled} of 17, p99 {p99:.3}%");
        if found != vec![(0, true)] || filled > 0 || p99 > 1.5 {
            failures.push(seed);
        }
    }
    assert!(
        failures.is_empty(),
        "seeds {failures:?}: not one closed piece of genus 1 with its hole open, near the block"
    );
}

/// The drilled cylinder's radius, half height and hole radius (its axis the z axis).
const CYLINDER: (f32, f32, f32) = (1.0, 1.0, 0.2);

/// A point of the drilled cylinder's surface, spread by area: the two caps less the hole's
/// disc, the side and the hole's wall.
fn cylinder_point(uniform: &mut Uniform) -> Vec3 {
    let (radius, half, hole) = CYLINDER;
    let pi = std::f32::consts::PI;
    let cap = pi * (radius * radius - hole * hole);
    let side = 2.0 * pi * radius * 2.0 * half;
    let wall = 2.0 * pi * hole * 2.0 * half;
    let at = uniform.next() * (2.0 * cap + side + wall);
    let around = uniform.between(0.0, 2.0 * pi);
    if at < 2.0 * cap {
        // Even in area over the annulus: the radius squared is uniform.
        let r = uniform.between(hole * hole, radius * radius).sqrt();
        let z = if at < cap { half } else { -half };
        Vec3::new(r * around.cos(), r * around.sin(), z)
    } else {
        let r = if at < 2.0 * cap + side { radius } else { hole };
        Vec3::new(
            r * around.cos(),
            r * around.sin(),
            uniform.between(-half, half),
        )
    }
}

#[test]
fn a_sparse_cloud_of_a_tall_drilled_cylinder_without_normals_keeps_the_outside_out() {
    // A cylinder as tall as it is wide with a narrow hole along its axis, 1 000 points with
    // noise of 0.25% of the diagonal and no normals, four seeds. The outside got in between
    // the points of its side at the default gap and lay on both sides of 83-92% of them:
    // they were oriented as an open sheet, in some 500 pieces, and the fit came back as a
    // hollow shell (every place of its body outside) with genus 137-159. Closed again at
    // the widest gap, the outside stays out: one closed piece whose body is clay all round
    // (its genus is not yet right, 6-16: the hole's walls; bench/RESULTS.md, "The outside
    // closed out of a sparse cloud without normals").
    let (radius, half, _) = CYLINDER;
    let sigma = 0.0025 * Vec3::new(2.0 * radius, 2.0 * radius, 2.0 * half).length();
    let dir = tempfile::tempdir().unwrap();
    let mut failures = Vec::new();
    for seed in 1..=4u64 {
        let mut uniform = Uniform(seed);
        let mut text = String::new();
        for _ in 0..1000 {
            let p = cylinder_point(&mut uniform);
            let jitter = Vec3::new(uniform.normal(), uniform.normal(), uniform.normal());
            let p = p + jitter * sigma;
            writeln!(text, "{} {} {}", p.x, p.y, p.z).unwrap();
        }
        let path = dir.path().join(format!("cylinder-{seed}.xyz"));
        let (fit, fitted) = import_and_mesh(&path, &text);
        let found = pieces(&fitted);
        // The body: a ring of 8 × 5 places midway between the hole and the side; and the
        // open space round it.
        let inside = |p: Vec3| fit.field.value(fit.to_field(p)) > fit.field.iso();
        let ring = |r: f32, z: f32| {
            (0..8).map(move |k| {
                let a = k as f32 * std::f32::consts::FRAC_PI_4;
                Vec3::new(r * a.cos(), r * a.sin(), z)
            })
        };
        let body_out = [-0.6f32, -0.3, 0.0, 0.3, 0.6]
            .iter()
            .flat_map(|&z| ring(0.6, z))
            .filter(|&p| !inside(p))
            .count();
        let around_in = [-0.6f32, 0.0, 0.6]
            .iter()
            .flat_map(|&z| ring(1.3, z))
            .filter(|&p| inside(p))
            .count();
        println!(
            "seed {seed}: pieces {found:?}, body places outside {body_out} of 40, \
             places round it inside {around_in} of 24"
        );
        if found.len() != 1 || !found[0].1 || body_out > 0 || around_in > 0 {
            failures.push(seed);
        }
    }
    assert!(
        failures.is_empty(),
        "seeds {failures:?}: not one closed piece with its body clay and the outside out"
    );
}
