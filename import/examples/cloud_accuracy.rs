//! How closely a point-cloud import follows the surface it was sampled from.
//!
//! `cargo run --release -p dynaclay-import --example cloud_accuracy -- MODEL.obj [options]`
//!
//! Samples `--points N` points (default 50 000) uniformly by area from the mesh's triangles,
//! each with its triangle's normal, adds Gaussian noise of `--noise P` percent of the box's
//! diagonal (per axis standard deviation, default 0.25), replaces `--outliers P` percent of
//! the points by points uniform in the box (default 0), fits with the import's defaults
//! (`--bare` drops the normals), meshes the fitted clay and prints: the distance from the
//! fitted mesh's vertices to the model's triangles (median and 99th percentile, percent of the
//! diagonal), the distance from the model's samples to the fitted mesh, the fitted mesh's
//! pieces and genus, and the fit's time.

use std::collections::HashMap;
use std::path::PathBuf;
use std::time::Instant;

use dynaclay_core::mesh::{BrickOctree, SampleGrid, TriMesh, point_triangle_distance};
use dynaclay_import::fit::{
    HierarchyOptions, ImportSettings, PointCloud, fit_hierarchy, mesh::read_mesh,
    most_resolution_for_points, resolution_for_points,
};
use glam::Vec3;

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

/// Triangles bucketed on a grid for nearest-triangle queries.
struct Nearest {
    corners: Vec<[Vec3; 3]>,
    cell: f32,
    buckets: HashMap<glam::IVec3, Vec<u32>>,
}

impl Nearest {
    fn new(corners: Vec<[Vec3; 3]>, cell: f32) -> Self {
        let key = |p: Vec3| (p / cell).floor().as_ivec3();
        let mut buckets: HashMap<glam::IVec3, Vec<u32>> = HashMap::new();
        for (n, c) in corners.iter().enumerate() {
            let (lo, hi) = (key(c[0].min(c[1]).min(c[2])), key(c[0].max(c[1]).max(c[2])));
            for z in lo.z..=hi.z {
                for y in lo.y..=hi.y {
                    for x in lo.x..=hi.x {
                        buckets
                            .entry(glam::IVec3::new(x, y, z))
                            .or_default()
                            .push(n as u32);
                    }
                }
            }
        }
        Self {
            corners,
            cell,
            buckets,
        }
    }

    /// Distance to the nearest triangle, searching rings of cells until one is found and the
    /// ring is beyond it.
    fn distance(&self, p: Vec3) -> f32 {
        let k = (p / self.cell).floor().as_ivec3();
        let mut best = f32::INFINITY;
        for ring in 0..64i32 {
            if best <= (ring - 1).max(0) as f32 * self.cell {
                break;
            }
            for dz in -ring..=ring {
                for dy in -ring..=ring {
                    for dx in -ring..=ring {
                        if dx.abs().max(dy.abs()).max(dz.abs()) != ring {
                            continue;
                        }
                        if let Some(b) = self.buckets.get(&(k + glam::IVec3::new(dx, dy, dz))) {
                            for &t in b {
                                let [a, bb, c] = self.corners[t as usize];
                                best = best.min(point_triangle_distance(p, a, bb, c));
                            }
                        }
                    }
                }
            }
        }
        best
    }
}

fn percentile(values: &mut [f32], q: f32) -> f32 {
    values.sort_by(f32::total_cmp);
    values[((values.len() - 1) as f32 * q).round() as usize]
}

/// Connected pieces of `mesh` and the total genus (from each piece's Euler characteristic).
fn pieces_and_genus(mesh: &TriMesh) -> (usize, i64, bool) {
    let n = mesh.positions.len();
    let mut parent: Vec<usize> = (0..n).collect();
    fn find(parent: &mut [usize], mut a: usize) -> usize {
        while parent[a] != a {
            parent[a] = parent[parent[a]];
            a = parent[a];
        }
        a
    }
    let mut edges = HashMap::new();
    for t in &mesh.triangles {
        for k in 0..3 {
            let (a, b) = (t[k] as usize, t[(k + 1) % 3] as usize);
            let (ra, rb) = (find(&mut parent, a), find(&mut parent, b));
            parent[ra] = rb;
            *edges.entry((a.min(b), a.max(b))).or_insert(0u32) += 1;
        }
    }
    let closed = edges.values().all(|&c| c == 2);
    let mut roots = std::collections::HashSet::new();
    for t in &mesh.triangles {
        roots.insert(find(&mut parent, t[0] as usize));
    }
    let euler = n as i64 - edges.len() as i64 + mesh.triangles.len() as i64;
    let pieces = roots.len();
    (pieces, (2 * pieces as i64 - euler) / 2, closed)
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut model = None;
    let (mut count, mut noise_percent, mut outlier_percent, mut bare) =
        (50_000usize, 0.25f32, 0.0f32, false);
    let mut settings = ImportSettings::default();
    let mut i = 0;
    while i < args.len() {
        let value = |i: usize| args.get(i + 1).expect("a value after the option").clone();
        match args[i].as_str() {
            "--points" => count = value(i).parse().expect("--points N"),
            "--noise" => noise_percent = value(i).parse().expect("--noise P"),
            "--outliers" => outlier_percent = value(i).parse().expect("--outliers P"),
            "--resolution" => {
                settings.resolution = value(i).parse().expect("--resolution N");
                settings.resolution_from_points = false;
            }
            "--error" => settings.error_percent = value(i).parse().expect("--error P"),
            "--depth" => settings.max_depth = value(i).parse().expect("--depth N"),
            "--bare" => {
                bare = true;
                i += 1;
                continue;
            }
            other if model.is_none() => {
                model = Some(PathBuf::from(other));
                i += 1;
                continue;
            }
            other => panic!("unknown option {other}"),
        }
        i += 2;
    }
    let model = model.expect("a model .obj");
    let (vertices, triangles) = read_mesh(&model).expect("a readable mesh");
    let corners: Vec<[Vec3; 3]> = triangles
        .iter()
        .map(|t| t.map(|i| vertices[i as usize]))
        .collect();
    let (lo, hi) = vertices
        .iter()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(a, b), &p| {
            (a.min(p), b.max(p))
        });
    let diagonal = (hi - lo).length();
    let mut rng = Rng(0x005e_ed0f_c10d);
    // Area-weighted sampling.
    let mut cumulative = Vec::with_capacity(corners.len());
    let mut area = 0.0f64;
    for [a, b, c] in &corners {
        area += f64::from((*b - *a).cross(*c - *a).length());
        cumulative.push(area);
    }
    let sample = |rng: &mut Rng| {
        let r = f64::from(rng.unit()) * area;
        let t = cumulative
            .partition_point(|&c| c < r)
            .min(corners.len() - 1);
        let [a, b, c] = corners[t];
        let (mut u, mut v) = (rng.unit(), rng.unit());
        if u + v > 1.0 {
            (u, v) = (1.0 - u, 1.0 - v);
        }
        (
            a + (b - a) * u + (c - a) * v,
            (b - a).cross(c - a).normalize_or_zero(),
        )
    };
    let truth: Vec<Vec3> = (0..20_000).map(|_| sample(&mut rng).0).collect();
    let sigma = noise_percent / 100.0 * diagonal;
    let outliers = (count as f32 * outlier_percent / 100.0).round() as usize;
    let (mut points, mut normals) = (Vec::with_capacity(count), Vec::with_capacity(count));
    for k in 0..count {
        if k < outliers {
            points.push(lo + (hi - lo) * Vec3::new(rng.unit(), rng.unit(), rng.unit()));
            let n = Vec3::new(rng.gauss(), rng.gauss(), rng.gauss()).normalize_or(Vec3::X);
            normals.push(n);
        } else {
            let (p, n) = sample(&mut rng);
            points.push(p + Vec3::new(rng.gauss(), rng.gauss(), rng.gauss()) * sigma);
            normals.push(if n == Vec3::ZERO { Vec3::Y } else { n });
        }
    }
    let cloud = PointCloud {
        points,
        normals: (!bare).then_some(normals),
    };
    let options = HierarchyOptions {
        base: dynaclay_import::fit::CloudFitOptions {
            // As the import chooses it (set by the noise within the count's bounds) unless
            // given.
            resolution: if settings.resolution_from_points {
                most_resolution_for_points(count)
            } else {
                settings.resolution
            },
            fewest_knots_by_noise: settings
                .resolution_from_points
                .then(|| resolution_for_points(count)),
            gap_spans: settings.gap_spans,
            ..Default::default()
        },
        error: settings.error_percent / 100.0,
        max_depth: settings.max_depth,
    };
    let started = Instant::now();
    let fit = fit_hierarchy(&cloud, &options, &mut |_| true).expect("the fit");
    let seconds = started.elapsed().as_secs_f32();
    let base = &fit.field.patches[0].lattice;
    let (slo, shi) = base.support();
    let finest = fit
        .field
        .patches
        .iter()
        .map(|p| p.lattice.spacing)
        .fold(base.spacing, f32::min);
    let grid = SampleGrid::covering(slo, shi, (base.spacing / 3.0).min(finest)).expect("a grid");
    let mesh = BrickOctree::build(grid, &fit.field).weld();
    let to_file = |v: Vec3| (v - fit.offset) / fit.scale;
    let reference = Nearest::new(corners, diagonal / 64.0);
    let mut to_model: Vec<f32> = mesh
        .positions
        .iter()
        .map(|&v| 100.0 * reference.distance(to_file(v)) / diagonal)
        .collect();
    let fitted = Nearest::new(
        mesh.triangles
            .iter()
            .map(|t| t.map(|i| to_file(mesh.positions[i as usize])))
            .collect(),
        diagonal / 64.0,
    );
    let mut to_fit: Vec<f32> = truth
        .iter()
        .map(|&p| 100.0 * fitted.distance(p) / diagonal)
        .collect();
    let (pieces, genus, closed) = pieces_and_genus(&mesh);
    println!(
        "{}: {} points{}, noise {noise_percent}% outliers {outlier_percent}% | fit→model p50 {:.3} p99 {:.3} max {:.3} | model→fit p50 {:.3} p99 {:.3} | {} pieces, genus {}{}, {} triangles, {} patches | {:.2} s",
        model.file_stem().and_then(|s| s.to_str()).unwrap_or("?"),
        count,
        if bare { " (no normals)" } else { "" },
        percentile(&mut to_model, 0.5),
        percentile(&mut to_model, 0.99),
        percentile(&mut to_model, 1.0),
        percentile(&mut to_fit, 0.5),
        percentile(&mut to_fit, 0.99),
        pieces,
        genus,
        if closed { "" } else { " (open)" },
        mesh.triangles.len(),
        fit.field.patches.len(),
        seconds
    );
}
