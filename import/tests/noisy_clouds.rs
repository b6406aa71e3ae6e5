//! Noisy clouds with strays fit the surface, not the noise: a sphere and a torus sampled with
//! Gaussian noise of 1% of their size, with and without 5% of the points replaced by strays
//! uniform in their box, fitted with the import's defaults. The fitted zero set is meshed and
//! judged against the analytic surface: one piece of the shape's genus, the mesh's vertices
//! within a bound of the surface (99th percentile and worst), every part of the surface
//! reached by the mesh, and the strays counted as dropped.

use dynaclay_core::mesh::{BrickOctree, SampleGrid, TriMesh};
use dynaclay_import::fit::consensus::screen;
use dynaclay_import::fit::{HierarchicalFit, HierarchyOptions, PointCloud, fit_hierarchy};
use glam::Vec3;

/// A shape with an exact signed distance (positive outside), in file units.
#[derive(Clone, Copy, Debug)]
enum Shape {
    Sphere { radius: f32 },
    Torus { ring: f32, tube: f32 },
}

impl Shape {
    fn sdf(self, p: Vec3) -> f32 {
        match self {
            Self::Sphere { radius } => p.length() - radius,
            Self::Torus { ring, tube } => {
                Vec3::new(Vec3::new(p.x, 0.0, p.z).length() - ring, p.y, 0.0).length() - tube
            }
        }
    }

    fn half_extent(self) -> Vec3 {
        match self {
            Self::Sphere { radius } => Vec3::splat(radius),
            Self::Torus { ring, tube } => Vec3::new(ring + tube, tube, ring + tube),
        }
    }

    /// The box's longest side.
    fn size(self) -> f32 {
        2.0 * self.half_extent().max_element()
    }

    fn genus(self) -> i64 {
        match self {
            Self::Sphere { .. } => 0,
            Self::Torus { .. } => 1,
        }
    }

    /// A point of the surface and its outward normal, from two uniforms (area-uniform on the
    /// sphere; uniform in the torus's angles, a little denser on the inner side).
    fn point(self, u: f32, v: f32) -> (Vec3, Vec3) {
        match self {
            Self::Sphere { radius } => {
                let z = 2.0 * u - 1.0;
                let r = (1.0 - z * z).sqrt();
                let a = std::f32::consts::TAU * v;
                let n = Vec3::new(r * a.cos(), z, r * a.sin());
                (n * radius, n)
            }
            Self::Torus { ring, tube } => {
                let (a, b) = (std::f32::consts::TAU * u, std::f32::consts::TAU * v);
                let around = Vec3::new(a.cos(), 0.0, a.sin());
                let n = around * b.cos() + Vec3::Y * b.sin();
                (around * ring + n * tube, n)
            }
        }
    }
}

/// A small deterministic generator (LCG), so the tests are the same every run.
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

/// `count` points of `shape` with Gaussian noise of `noise` times its size (per axis), the
/// first `strays` of them replaced by points uniform in its box grown by a tenth.
fn cloud(shape: Shape, count: usize, noise: f32, strays: usize, normals: bool) -> PointCloud {
    let mut rng = Rng(0x0dd_ba11);
    let sigma = noise * shape.size();
    let half = shape.half_extent() * 1.1;
    let (mut points, mut given) = (Vec::with_capacity(count), Vec::with_capacity(count));
    for k in 0..count {
        if k < strays {
            let p = Vec3::new(rng.unit(), rng.unit(), rng.unit()) * 2.0 * half - half;
            points.push(p);
            given.push(Vec3::new(rng.gauss(), rng.gauss(), rng.gauss()).normalize_or(Vec3::X));
        } else {
            let (p, n) = shape.point(rng.unit(), rng.unit());
            points.push(p + Vec3::new(rng.gauss(), rng.gauss(), rng.gauss()) * sigma);
            given.push(n);
        }
    }
    PointCloud {
        points,
        normals: normals.then_some(given),
    }
}

/// The fitted zero set, meshed at a third of the base spacing (or the finest patch's), welded.
fn mesh_of(fit: &HierarchicalFit) -> TriMesh {
    let base = &fit.field.patches[0].lattice;
    let finest = fit
        .field
        .patches
        .iter()
        .map(|p| p.lattice.spacing)
        .fold(base.spacing, f32::min);
    let (lo, hi) = base.support();
    let grid = SampleGrid::covering(lo, hi, (base.spacing / 3.0).min(finest)).unwrap();
    BrickOctree::build(grid, &fit.field).weld()
}

/// Connected pieces, whether every edge has two faces, and the total genus.
fn pieces_closed_genus(mesh: &TriMesh) -> (usize, bool, i64) {
    let mut parent: Vec<usize> = (0..mesh.positions.len()).collect();
    fn root(parent: &mut [usize], mut a: usize) -> usize {
        while parent[a] != a {
            parent[a] = parent[parent[a]];
            a = parent[a];
        }
        a
    }
    let mut edges = std::collections::HashMap::new();
    for t in &mesh.triangles {
        for k in 0..3 {
            let (a, b) = (t[k] as usize, t[(k + 1) % 3] as usize);
            let (ra, rb) = (root(&mut parent, a), root(&mut parent, b));
            parent[ra] = rb;
            *edges.entry((a.min(b), a.max(b))).or_insert(0u32) += 1;
        }
    }
    let mut roots = std::collections::HashSet::new();
    for t in &mesh.triangles {
        roots.insert(root(&mut parent, t[0] as usize));
    }
    let closed = edges.values().all(|&n| n == 2);
    let euler = mesh.positions.len() as i64 - edges.len() as i64 + mesh.triangles.len() as i64;
    let pieces = roots.len();
    (pieces, closed, (2 * pieces as i64 - euler) / 2)
}

/// Fits `points` of `shape` with the defaults and checks the mesh: one closed piece of the
/// shape's genus, vertices within `p99` (99th percentile) and `worst` of the surface and the
/// surface within `worst` of a vertex everywhere (fractions of the size), and at least as many
/// points dropped as there are points farther than five noise levels (`noise`, fraction of
/// the size) from the surface.
fn check(name: &str, shape: Shape, points: PointCloud, noise: f32, p99: f32, worst: f32) {
    let strays_found = points
        .points
        .iter()
        .filter(|&&p| shape.sdf(p).abs() > 5.0 * noise * shape.size())
        .count();
    let fit = fit_hierarchy(&points, &HierarchyOptions::default(), &mut |_| true).unwrap();
    let mesh = mesh_of(&fit);
    let (pieces, closed, genus) = pieces_closed_genus(&mesh);
    assert_eq!(
        (pieces, closed, genus),
        (1, true, shape.genus()),
        "{name}: pieces, closed, genus"
    );
    let to_file = |v: Vec3| (v - fit.offset) / fit.scale;
    let mut off: Vec<f32> = mesh
        .positions
        .iter()
        .map(|&v| shape.sdf(to_file(v)).abs() / shape.size())
        .collect();
    off.sort_by(f32::total_cmp);
    let at99 = off[(off.len() - 1) * 99 / 100];
    let max = off[off.len() - 1];
    assert!(at99 <= p99, "{name}: p99 {:.3}% of the size", 100.0 * at99);
    assert!(
        max <= worst,
        "{name}: worst {:.3}% of the size",
        100.0 * max
    );
    // Every part of the surface is reached: the nearest vertex to each of a spread of
    // surface points is within the bound.
    let mut rng = Rng(7);
    let vertices: Vec<Vec3> = mesh.positions.iter().map(|&v| to_file(v)).collect();
    for _ in 0..400 {
        let (p, _) = shape.point(rng.unit(), rng.unit());
        let nearest = vertices
            .iter()
            .map(|v| (*v - p).length())
            .fold(f32::INFINITY, f32::min);
        assert!(
            nearest / shape.size() <= worst,
            "{name}: the surface at {p} is {:.3}% of the size from the mesh",
            100.0 * nearest / shape.size()
        );
    }
    let dropped = fit.screening.isolated + fit.screening.far;
    assert!(
        dropped >= strays_found,
        "{name}: {dropped} points dropped, {strays_found} strays expected"
    );
    // The noise was estimated near what was added, and the refinement bound never went below
    // it.
    assert!(
        (0.6 * noise..1.6 * noise).contains(&fit.screening.noise),
        "{name}: noise estimated at {:.3}% of the size",
        100.0 * fit.screening.noise
    );
    assert!(fit.bound >= fit.screening.noise);
}

const SPHERE: Shape = Shape::Sphere { radius: 1.0 };
const TORUS: Shape = Shape::Torus {
    ring: 3.0,
    tube: 1.0,
};

#[test]
fn a_sphere_with_one_percent_noise_is_one_round_piece() {
    let points = cloud(SPHERE, 20_000, 0.01, 0, true);
    check("sphere", SPHERE, points, 0.01, 0.008, 0.012);
}

#[test]
fn a_sphere_with_noise_and_five_percent_strays_is_one_round_piece() {
    let points = cloud(SPHERE, 20_000, 0.01, 1_000, true);
    check("sphere with strays", SPHERE, points, 0.01, 0.008, 0.012);
}

#[test]
fn a_torus_with_one_percent_noise_keeps_one_hole_without_normals() {
    let points = cloud(TORUS, 30_000, 0.01, 0, false);
    check("torus", TORUS, points, 0.01, 0.012, 0.02);
}

#[test]
fn a_torus_with_noise_and_five_percent_strays_keeps_one_hole_without_normals() {
    let points = cloud(TORUS, 30_000, 0.01, 1_500, false);
    check("torus with strays", TORUS, points, 0.01, 0.012, 0.02);
}

#[test]
fn every_stray_beyond_five_noise_levels_is_dropped_and_the_surface_points_are_kept() {
    let points = cloud(TORUS, 30_000, 0.01, 1_500, false).points;
    let sigma = 0.01 * TORUS.size();
    let screened = screen(&points, TORUS.size(), None);
    let (mut far_kept, mut far) = (0, 0);
    for (p, &c) in points[..1_500].iter().zip(&screened.confidence) {
        if TORUS.sdf(*p).abs() > 5.0 * sigma {
            far += 1;
            far_kept += usize::from(c > 0.0);
        }
    }
    assert!(far > 500, "{far} strays beyond five noise levels");
    assert_eq!(far_kept, 0, "{far_kept} of {far} far strays kept");
    let surface_dropped = screened.confidence[1_500..]
        .iter()
        .filter(|&&c| c == 0.0)
        .count();
    assert!(
        surface_dropped * 200 < points.len(),
        "{surface_dropped} surface points dropped"
    );
}
