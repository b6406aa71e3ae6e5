//! A sparse scan fits without lumps: spot (Keenan Crane's closed genus-0 cartoon cow, public
//! domain, `tests/data/spot.obj`) sampled as 2 000 points spread by area, with their
//! triangles' normals and Gaussian noise of 0.25% of the diagonal (as
//! `bench/models/sample_cloud.py` samples the peers bench's sparse clouds), for twelve seeds.
//! Each cloud is imported as a file, as `dynaclay import` imports it, and the fitted clay is
//! meshed as `--mesh` meshes it (four cells per knot span, welded).
//!
//! The judge is spot's own mesh. Every fit is one closed piece of genus 0, and the 99th
//! percentile of the distances from its surface to spot's is under 3% of the diagonal. Past
//! the ears' and horns' ends the plane of one point's anchor ran on through empty space and
//! put nodes that the flood found outside inside: the clay grew lumps there. Over the seeds,
//! the median of the 99th percentile of how far the clay outside spot lies from it is under
//! 1.4% of the diagonal: twice PoissonRecon's 99th percentile (depth 8, `--samplesPerNode
//! 15`) on such a cloud, 0.70% (bench/RESULTS.md, "Sparse clouds, and a cloud that samples no
//! surface"). These are guards against lumps, not the issue's floor (1.25 times
//! PoissonRecon's), which sparse clouds do not yet all meet.
//!
//! A ball with two thin ears (three overlapping ellipsoids, judged against their own meshes)
//! is the same guard for a closed shape whose thin parts look in part like an open sheet, with
//! normals and without.
//!
//! Spot without normals at 1 000 points and 1% noise fits with no handle: before the fit's
//! small holes were closed, 3 of its 12 seeds came back with one or two (genus 1–2).

mod support;

use std::fmt::Write as _;
use std::path::Path;

use dynaclay_core::mesh::{BrickOctree, SampleGrid, TriMesh};
use dynaclay_import::fit::consensus::screen;
use dynaclay_import::fit::mesh::{read_mesh, sample_triangles};
use dynaclay_import::fit::{ImportSettings, ImportedFit, fit_import};
use glam::Vec3;
use support::{Uniform, pieces, quantile_distance};

/// The clouds sampled, one per seed.
const SEEDS: u64 = 12;
/// The clouds with strays sampled, one per seed.
const STRAY_SEEDS: u64 = 40;

/// `count` points spread by area over the triangles, each with its triangle's normal and
/// Gaussian noise of `noise` (absolute), as `x y z nx ny nz` lines.
fn sample_cloud(
    vertices: &[Vec3],
    triangles: &[[u32; 3]],
    count: usize,
    noise: f32,
    seed: u64,
) -> String {
    let mut area_to = Vec::with_capacity(triangles.len());
    let mut total = 0.0f64;
    for t in triangles {
        let [a, b, c] = t.map(|i| vertices[i as usize]);
        total += f64::from((b - a).cross(c - a).length() / 2.0);
        area_to.push(total);
    }
    let mut uniform = Uniform(seed);
    let mut text = String::new();
    for _ in 0..count {
        let at = f64::from(uniform.next()) * total;
        let t = area_to
            .partition_point(|&s| s < at)
            .min(triangles.len() - 1);
        let [a, b, c] = triangles[t].map(|i| vertices[i as usize]);
        let (mut u, mut v) = (uniform.next(), uniform.next());
        if u + v > 1.0 {
            (u, v) = (1.0 - u, 1.0 - v);
        }
        let jitter = Vec3::new(uniform.normal(), uniform.normal(), uniform.normal());
        let p = a + (b - a) * u + (c - a) * v + jitter * noise;
        let n = (b - a).cross(c - a).normalize_or(Vec3::Y);
        writeln!(text, "{} {} {} {} {} {}", p.x, p.y, p.z, n.x, n.y, n.z).unwrap();
    }
    text
}

/// Spot's mesh (`tests/data/spot.obj`) and its box.
struct Spot {
    vertices: Vec<Vec3>,
    triangles: Vec<[u32; 3]>,
    lo: Vec3,
    hi: Vec3,
}

impl Spot {
    fn read() -> Self {
        let spot = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/data/spot.obj");
        let (vertices, triangles) = read_mesh(&spot).unwrap();
        let (lo, hi) = vertices
            .iter()
            .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(a, b), &p| {
                (a.min(p), b.max(p))
            });
        Self {
            vertices,
            triangles,
            lo,
            hi,
        }
    }
}

/// The cloud at `path` imported as `dynaclay import` imports it, and its clay meshed as
/// `--mesh` meshes it (four cells per knot span, welded).
fn import_and_mesh(path: &Path, seed: u64) -> (ImportedFit, TriMesh) {
    let fit = fit_import(path, &ImportSettings::default(), &mut |_| true, &mut |_| {})
        .unwrap_or_else(|e| panic!("seed {seed}: {e}"));
    let grid = SampleGrid::for_field(&fit.field, 4).unwrap();
    let fitted = BrickOctree::build(grid, &fit.field).weld();
    (fit, fitted)
}

/// Whether `p` lies inside the closed `mesh`: a ray from it crosses its triangles an odd
/// number of times (Möller–Trumbore; the ray's direction is off every axis and diagonal).
fn inside(mesh: &TriMesh, p: Vec3) -> bool {
    let dir = Vec3::new(0.5377, 0.6231, 0.5681).normalize();
    let mut crossings = 0;
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|i| mesh.positions[i as usize]);
        let (e1, e2) = (b - a, c - a);
        let q = dir.cross(e2);
        let det = e1.dot(q);
        if det.abs() < 1e-12 {
            continue;
        }
        let s = p - a;
        let u = s.dot(q) / det;
        let r = s.cross(e1);
        let v = dir.dot(r) / det;
        if u >= 0.0 && v >= 0.0 && u + v <= 1.0 && e2.dot(r) / det > 0.0 {
            crossings += 1;
        }
    }
    crossings % 2 == 1
}

/// What one seed's cloud of `count` points of spot fits to, as `dynaclay import` and `--mesh`
/// fit and mesh it: the fitted surface's pieces, and the 99th percentiles of the distances to
/// spot from points spread evenly over it, all of them and those outside spot (the clay the
/// fit added), percent of the diagonal.
struct Judged {
    pieces: Vec<(i64, bool)>,
    p99: f32,
    added_p99: f32,
}

fn fit_and_judge(spot: &Spot, dir: &Path, count: usize, seed: u64) -> Judged {
    let Spot {
        vertices,
        triangles,
        lo,
        hi,
    } = spot;
    let diagonal = (*hi - *lo).length();
    let path = dir.join(format!("spot-{count}-{seed}.xyz"));
    let cloud = sample_cloud(vertices, triangles, count, 0.0025 * diagonal, seed);
    std::fs::write(&path, cloud).unwrap();
    let (fit, fitted) = import_and_mesh(&path, seed);
    let input = TriMesh {
        positions: vertices.iter().map(|&p| fit.to_field(p)).collect(),
        normals: vec![Vec3::Y; vertices.len()],
        triangles: triangles.clone(),
    };
    let percent = 100.0 / (fit.to_field(*hi) - fit.to_field(*lo)).length();
    // Evenly over the fitted surface's area (its vertices crowd where the cells cut it into
    // small triangles), 3 000 of them.
    let on_fitted = sample_triangles(&fitted.positions, &fitted.triangles, &path)
        .unwrap()
        .points;
    let stride = on_fitted.len().div_ceil(3000).max(1);
    let on_fitted: Vec<Vec3> = on_fitted.into_iter().step_by(stride).collect();
    let added: Vec<Vec3> = on_fitted
        .iter()
        .copied()
        .filter(|&p| !inside(&input, p))
        .collect();
    let judged = Judged {
        pieces: pieces(&fitted),
        p99: percent * quantile_distance(&on_fitted, &input, 0.99),
        added_p99: percent * quantile_distance(&added, &input, 0.99),
    };
    println!(
        "{count} points, seed {seed}: pieces {:?}; p99 fitted → spot {:.3}%, of the clay outside \
         spot {:.3}%",
        judged.pieces, judged.p99, judged.added_p99
    );
    judged
}

/// [`fit_and_judge`] for each of the [`SEEDS`] clouds of `count` points, each fit asserted
/// to be one closed piece of genus 0.
fn closed_fits_of_spot(spot: &Spot, count: usize) -> Vec<(u64, Judged)> {
    let dir = tempfile::tempdir().unwrap();
    let report: Vec<(u64, Judged)> = (1..=SEEDS)
        .map(|seed| (seed, fit_and_judge(spot, dir.path(), count, seed)))
        .collect();
    for (seed, judged) in &report {
        assert_eq!(
            judged.pieces,
            vec![(2, true)],
            "{count} points, seed {seed}: one closed piece of genus 0"
        );
    }
    report
}

/// The median of `values` (an even count).
fn median(mut values: Vec<f32>) -> f32 {
    values.sort_by(f32::total_cmp);
    0.5 * (values[values.len() / 2 - 1] + values[values.len() / 2])
}

#[test]
fn a_sparse_scan_of_spot_fits_without_lumps_past_its_ears_and_horns() {
    let spot = Spot::read();
    let report = closed_fits_of_spot(&spot, 2000);
    for (seed, judged) in &report {
        assert!(
            judged.p99 < 3.0,
            "seed {seed}: p99 fitted → spot {:.3}%",
            judged.p99
        );
    }
    let added = median(report.iter().map(|r| r.1.added_p99).collect());
    assert!(
        added < 1.4,
        "median over the seeds of the p99 of the clay outside spot: {added:.3}%"
    );
}

/// A sparser scan keeps its points: spot sampled as 1 000 points (as above), where the
/// screening's radius, set by the spacing's grid (which cannot read points further apart than
/// its cubes), held a median of 3 neighbours: planes through so few left a third of the
/// genuine points off them, and they were dropped. Now the screening widens its radius there:
/// it keeps at least 95% of each cloud's points (it kept 613–713 of the 1 000), every fit is
/// one closed piece of genus 0, and over the seeds the median of the 99th percentile of the
/// distances from the fitted surface to spot is under 1.6% of the diagonal (1.13% now; it was
/// 2.64%, each seed's 1.82–4.07%).
#[test]
fn a_sparser_scan_of_spot_keeps_its_points_and_fits_closer() {
    let spot = Spot::read();
    let diagonal = (spot.hi - spot.lo).length();
    for seed in 1..=SEEDS {
        let cloud = sample_cloud(
            &spot.vertices,
            &spot.triangles,
            1000,
            0.0025 * diagonal,
            seed,
        );
        let points: Vec<Vec3> = cloud
            .lines()
            .map(|line| {
                let xyz: Vec<f32> = line
                    .split_whitespace()
                    .take(3)
                    .map(|v| v.parse().unwrap())
                    .collect();
                Vec3::new(xyz[0], xyz[1], xyz[2])
            })
            .collect();
        let size = (spot.hi - spot.lo).max_element();
        let kept = screen(&points, size, None).kept();
        assert!(
            kept >= 950,
            "seed {seed}: the screening kept {kept} of 1000"
        );
    }
    let report = closed_fits_of_spot(&spot, 1000);
    let p99 = median(report.iter().map(|r| r.1.p99).collect());
    assert!(
        p99 < 1.6,
        "median over the seeds of the p99 fitted → spot: {p99:.3}%"
    );
}

/// `count` strays spread evenly over the box `lo..hi` widened by a tenth of its size on every
/// side, each with a normal pointing anywhere, as `x y z nx ny nz` lines.
fn strays(lo: Vec3, hi: Vec3, count: usize, seed: u64) -> String {
    let mut uniform = Uniform(seed);
    let (centre, half) = ((lo + hi) * 0.5, (hi - lo) * 0.55);
    let mut text = String::new();
    for _ in 0..count {
        let mut at = || 2.0 * uniform.next() - 1.0;
        let p = centre + Vec3::new(at(), at(), at()) * half;
        let n = Vec3::new(at(), at(), at()).normalize_or(Vec3::Y);
        writeln!(text, "{} {} {} {} {} {}", p.x, p.y, p.z, n.x, n.y, n.z).unwrap();
    }
    text
}

/// A thousand points of spot with fifty strays about it (5%, as the peers bench's clouds with
/// outliers), for forty seeds. The screening drops most strays; one kept just off the surface
/// joins it by a thin neck of the signs, which the smooth fit may pinch off into a small loose
/// piece. The pieces of the fitted base that its signing grid shows are taken out as the
/// signs' are ([`dynaclay_import::fit::cloud::SignedCloud::fit_base_and_count_loose`]).
///
/// Before they were, 5 of the 40 fits had a second piece (seeds 22, 27, 29, 32 and 38); now 3
/// did (27, 29, 32): on 27 and 32 the neck pinched between the grid's nodes, finer than the
/// check sees, and on 29 a detail patch, fitted after the base, made it. With the screening's
/// radius widened at this density (see `a_sparser_scan_of_spot_keeps_its_points_and_fits_closer`)
/// those 3 are one piece and 3 others have a second (14, 34, 40). On 34 and 40 it was a
/// bubble inside the clay about a stray kept inside spot; the fit's small cavities are now
/// filled as the signs' are, and only seed 14 has a second piece. The test fails when more
/// than 1 fit has a second piece (or any fit is open or empty).
#[test]
fn strays_about_a_sparse_scan_of_spot_leave_few_loose_pieces() {
    let Spot {
        vertices,
        triangles,
        lo,
        hi,
    } = Spot::read();
    let diagonal = (hi - lo).length();
    let dir = tempfile::tempdir().unwrap();
    let mut report = Vec::new();
    for seed in 1..=STRAY_SEEDS {
        let path = dir.path().join(format!("spot-1000-strays-{seed}.xyz"));
        let mut cloud = sample_cloud(&vertices, &triangles, 1000, 0.0025 * diagonal, seed);
        cloud.push_str(&strays(lo, hi, 50, seed + 100));
        std::fs::write(&path, cloud).unwrap();
        let (_, fitted) = import_and_mesh(&path, seed);
        println!("seed {seed}: pieces {:?}", pieces(&fitted));
        report.push((seed, pieces(&fitted)));
    }
    let more: Vec<u64> = report
        .iter()
        .filter(|(_, pieces)| pieces.len() > 1)
        .map(|&(seed, _)| seed)
        .collect();
    assert!(
        more.len() <= 1,
        "{} of {STRAY_SEEDS} fits have more than one piece (seeds {more:?})",
        more.len()
    );
    for (seed, pieces) in &report {
        assert!(!pieces.is_empty(), "seed {seed}: no surface");
        assert!(pieces.iter().all(|p| p.1), "seed {seed}: not closed");
    }
}

/// A closed ellipsoid of semi-axes `radii` about `centre` as a latitude–longitude mesh of
/// `rings` bands of `segments` quads, wound outward.
fn ellipsoid(centre: Vec3, radii: Vec3, rings: u32, segments: u32) -> TriMesh {
    let at = |ring: u32, segment: u32| {
        let polar = std::f32::consts::PI * ring as f32 / rings as f32;
        let azimuth = std::f32::consts::TAU * segment as f32 / segments as f32;
        let dir = Vec3::new(
            polar.sin() * azimuth.cos(),
            polar.cos(),
            polar.sin() * azimuth.sin(),
        );
        centre + dir * radii
    };
    // Ring 0 and ring `rings` are the poles, one vertex each.
    let mut positions = vec![at(0, 0)];
    for ring in 1..rings {
        positions.extend((0..segments).map(|segment| at(ring, segment)));
    }
    positions.push(at(rings, 0));
    let south = positions.len() as u32 - 1;
    let index = |ring: u32, segment: u32| 1 + (ring - 1) * segments + segment % segments;
    let mut triangles = Vec::new();
    for s in 0..segments {
        triangles.push([0, index(1, s + 1), index(1, s)]);
        triangles.push([south, index(rings - 1, s), index(rings - 1, s + 1)]);
        for ring in 1..rings - 1 {
            let (a, b) = (index(ring, s), index(ring, s + 1));
            let (c, d) = (index(ring + 1, s), index(ring + 1, s + 1));
            triangles.push([a, b, d]);
            triangles.push([a, d, c]);
        }
    }
    TriMesh {
        normals: vec![Vec3::Y; positions.len()],
        positions,
        triangles,
    }
}

/// A ball with two thin ears: a unit sphere and two ellipsoids 0.2 thick and 0.4 wide rising
/// from it to 2.2 above its centre, as three closed meshes that overlap.
fn eared_ball() -> Vec<TriMesh> {
    let ear = |x: f32| ellipsoid(Vec3::new(x, 1.45, 0.0), Vec3::new(0.2, 0.75, 0.1), 48, 64);
    vec![
        ellipsoid(Vec3::ZERO, Vec3::ONE, 48, 96),
        ear(-0.4),
        ear(0.4),
    ]
}

/// One fit of [`eared_ball_fits`]: its seed, its pieces as [`pieces`] counts them (Euler
/// characteristic, closed) and the 99th percentile of the clay outside the shape, % of the
/// diagonal.
#[derive(Debug)]
struct EaredFit {
    seed: u64,
    pieces: Vec<(i64, bool)>,
    outside_p99_percent: f32,
}

/// One fit of a sparse scan of [`eared_ball`] per seed: 1 700 points spread by area over its
/// parts with noise of 0.25% of the diagonal, less each part's points inside another (about
/// 1 670 remain), with their triangles' normals or (`with_normals` false) without, imported as
/// a file and meshed as `--mesh` meshes it.
fn eared_ball_fits(with_normals: bool) -> Vec<EaredFit> {
    let parts = eared_ball();
    let mut all = TriMesh {
        positions: Vec::new(),
        normals: Vec::new(),
        triangles: Vec::new(),
    };
    for part in &parts {
        let base = all.positions.len() as u32;
        all.positions.extend(&part.positions);
        all.normals.extend(&part.normals);
        all.triangles
            .extend(part.triangles.iter().map(|t| t.map(|i| i + base)));
    }
    let area = |mesh: &TriMesh| -> f32 {
        mesh.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| mesh.positions[i as usize]);
                (b - a).cross(c - a).length() / 2.0
            })
            .sum()
    };
    let total_area: f32 = parts.iter().map(area).sum();
    let (lo, hi) = (Vec3::new(-1.0, -1.0, -1.0), Vec3::new(1.0, 2.2, 1.0));
    let diagonal = (hi - lo).length();
    let dir = tempfile::tempdir().unwrap();
    let mut fits = Vec::new();
    for seed in 1..=SEEDS {
        // Each part sampled by its area, its points inside another part left out.
        let mut kept = String::new();
        for (k, part) in parts.iter().enumerate() {
            let share = area(part) / total_area;
            let count = (1700.0 * share).round() as usize;
            let cloud = sample_cloud(
                &part.positions,
                &part.triangles,
                count,
                0.0025 * diagonal,
                seed * 3 + k as u64,
            );
            for line in cloud.lines() {
                let xyz: Vec<f32> = line
                    .split_whitespace()
                    .take(3)
                    .map(|v| v.parse().unwrap())
                    .collect();
                let p = Vec3::new(xyz[0], xyz[1], xyz[2]);
                let elsewhere = parts
                    .iter()
                    .enumerate()
                    .any(|(j, other)| j != k && inside(other, p));
                if elsewhere {
                    continue;
                }
                if with_normals {
                    writeln!(kept, "{line}").unwrap();
                } else {
                    writeln!(kept, "{} {} {}", xyz[0], xyz[1], xyz[2]).unwrap();
                }
            }
        }
        let path = dir.path().join(format!("eared-{seed}.xyz"));
        std::fs::write(&path, kept).unwrap();
        let (fit, fitted) = import_and_mesh(&path, seed);
        let in_field = |mesh: &TriMesh| TriMesh {
            positions: mesh.positions.iter().map(|&p| fit.to_field(p)).collect(),
            normals: mesh.normals.clone(),
            triangles: mesh.triangles.clone(),
        };
        let shape = in_field(&all);
        let parts_in_field: Vec<TriMesh> = parts.iter().map(in_field).collect();
        let percent = 100.0 / (fit.to_field(hi) - fit.to_field(lo)).length();
        let on_fitted = sample_triangles(&fitted.positions, &fitted.triangles, &path)
            .unwrap()
            .points;
        let stride = on_fitted.len().div_ceil(3000).max(1);
        let added: Vec<Vec3> = on_fitted
            .into_iter()
            .step_by(stride)
            .filter(|&p| !parts_in_field.iter().any(|part| inside(part, p)))
            .collect();
        let p99 = percent * quantile_distance(&added, &shape, 0.99);
        let pieces = pieces(&fitted);
        println!(
            "eared ball, seed {seed}, normals {with_normals}: pieces {pieces:?}, \
             p99 of the clay outside it {p99:.3}%"
        );
        fits.push(EaredFit {
            seed,
            pieces,
            outside_p99_percent: p99,
        });
    }
    fits
}

/// A sparse scan of a closed shape with thin parts ([`eared_ball_fits`], with normals).
///
/// Across an ear's thickness the tagging's probe reaches the outside on both sides, so 1.6–3.8%
/// of such a cloud's points look like an open sheet's; the flood signed the nodes beyond the
/// moving planes' reach only under 1% (a partial scan's open sheet has 17–100%), and past and
/// beside the ears one anchor's plane ran on through empty space: the clay grew balls there
/// (the Stanford bunny's ears at 1 000–2 000 points: p99 4.9–5.0% of the diagonal). The
/// flood now signs them under [`dynaclay_import::fit::cloud::FLOOD_OPEN_SHEET_SHARE`] (10%).
/// Beside the ears, within the widest point's reach but beyond every point's own, the anchor's
/// plane still signed and balls remained (a median of 1.99%, each seed's 0.95–4.39%); where
/// it puts such a node inside and the flood found it outside, the node is now signed outside
/// by its distance to the point (1.34%, 0.85–2.54%), and so is a node at the edge of the
/// moving planes' reach ([`dynaclay_import::fit::cloud::EXTRAPOLATED_SPACINGS`]) with no far
/// rim of a hole ahead.
/// Every fit is one closed piece of genus 0, and over the seeds the median of the 99th
/// percentile of how far the clay outside the shape lies from it is under 1.2% of the
/// diagonal: 1.06% now (each seed's 0.82–1.55%); 2.98% with none of the three rules
/// (0.94–6.67%).
#[test]
fn a_sparse_scan_of_thin_ears_fits_without_balls_past_their_tips() {
    let fits = eared_ball_fits(true);
    for EaredFit { seed, pieces, .. } in &fits {
        assert_eq!(
            *pieces,
            vec![(2, true)],
            "seed {seed}: one closed piece of genus 0"
        );
    }
    let added = median(fits.iter().map(|fit| fit.outside_p99_percent).collect());
    assert!(
        added < 1.2,
        "median over the seeds of the p99 of the clay outside the eared ball: {added:.3}%"
    );
}

/// The same scan without normals, as a depth camera's cloud comes: each point's normal is the
/// least-variance direction of its neighbours, turned toward the flooded exterior. Across an
/// ear the probe finds the exterior at both ends, and with 1–10% of the points so, the
/// normals were oriented as an open sheet's, by a spanning tree from neighbour to neighbour:
/// it crossed from one face of an ear to the other and the pieces' vote turned whole faces in.
/// Two fits of twelve were one closed piece of genus 0 (the others 1–5 handles, or 3 pieces),
/// and the 99th percentile of the clay outside the shape was 4.7–5.2% of the diagonal on every
/// seed. A sparse cloud under a tenth open is taken for a closed scan, each point keeping its
/// own side: now 11 of 12 are one closed piece of genus 0 (the other has one handle), and the
/// 99th percentile is 1.9–3.2% (a median of 2.4%).
#[test]
fn a_sparse_scan_of_thin_ears_without_normals_keeps_its_ears_faces_apart() {
    let fits = eared_ball_fits(false);
    let right = fits
        .iter()
        .filter(|fit| fit.pieces == vec![(2, true)])
        .count();
    assert!(
        right >= 11,
        "one closed piece of genus 0 on {right} of {} seeds: {fits:?}",
        fits.len()
    );
    let worst = fits
        .iter()
        .map(|fit| fit.outside_p99_percent)
        .fold(0.0, f32::max);
    let added = median(fits.iter().map(|fit| fit.outside_p99_percent).collect());
    assert!(
        added < 3.0 && worst < 4.0,
        "p99 of the clay outside the eared ball without normals: median {added:.3}%, \
         worst {worst:.3}%"
    );
}

/// Spot without normals at 1 000 points and 1% noise, as a handheld scan of a small object
/// comes. Where a thin part's points lie further apart than it is thick, the fit left a small
/// tunnel through it that no point holds open: seeds 8, 10 and 12 fitted with one, two and one
/// handles (spot is genus 0). The fit's small holes are now closed (bench/RESULTS.md, "Small
/// holes of a sparse fit closed"), and every fit is one closed piece of genus 0.
#[test]
fn a_sparse_scan_of_spot_without_normals_fits_without_handles() {
    let spot = Spot::read();
    let diagonal = (spot.hi - spot.lo).length();
    let dir = tempfile::tempdir().unwrap();
    let fits: Vec<(u64, Vec<(i64, bool)>)> = (1..=SEEDS)
        .map(|seed| {
            let with_normals =
                sample_cloud(&spot.vertices, &spot.triangles, 1000, 0.01 * diagonal, seed);
            // The positions alone: `x y z` per line.
            let cloud: String = with_normals
                .lines()
                .map(|line| {
                    let xyz: Vec<&str> = line.split_whitespace().take(3).collect();
                    format!("{}\n", xyz.join(" "))
                })
                .collect();
            let path = dir.path().join(format!("spot-nn-{seed}.xyz"));
            std::fs::write(&path, cloud).unwrap();
            let (_, fitted) = import_and_mesh(&path, seed);
            (seed, pieces(&fitted))
        })
        .collect();
    println!("spot without normals, 1 000 points, 1% noise: {fits:?}");
    let right = fits
        .iter()
        .filter(|(_, pieces)| *pieces == vec![(2, true)])
        .count();
    assert_eq!(
        right,
        fits.len(),
        "one closed piece of genus 0 on {right} of {} seeds: {fits:?}",
        fits.len()
    );
}
