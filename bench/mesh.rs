//! Meshing benchmarks: full extraction against the `isosurface` crate's marching cubes on the
//! same samples (and `fast-surface-nets`, a different algorithm, for reference), a local
//! re-mesh of a tool-sized box, and the octree's memory for a sphere at 512³.
//!
//! Run: `cargo bench --bench mesh -- --warm-up-time 1 --measurement-time 3`
//!
//! Fairness notes. Every contender samples the same closure at the same points `i / n`
//! (`isosurface` also samples one extra layer of cells past z = 1, ~1/n more work) and
//! produces an indexed mesh with per-vertex normals from the analytic gradient
//! (`isosurface` through `IndexedInterleavedNormals`; `fast-surface-nets` estimates normals
//! by central differences). All run on one thread. "dynaclay/culled" adds a Lipschitz bound so
//! the octree skips empty space: it is the sparse path, not the like-for-like comparison.

use std::hint::black_box;
use std::time::Instant;

use criterion::{BenchmarkId, Criterion, Throughput};
use dynaclay::field::BSplineLattice;
use dynaclay::mesh::{BrickOctree, FnField, MeshStats, SampleGrid};
use fast_surface_nets::ndshape::{RuntimeShape, Shape};
use fast_surface_nets::{SurfaceNetsBuffer, surface_nets};
use glam::Vec3;
use isosurface::MarchingCubes;
use isosurface::distance::Signed;
use isosurface::extractor::IndexedInterleavedNormals;
use isosurface::sampler::Sampler;
use isosurface::source::{HermiteSource, ScalarSource};

const CENTRE: Vec3 = Vec3::splat(0.5);
const RADIUS: f32 = 0.4;
/// Gyroid frequency: four periods across the unit cube.
const OMEGA: f32 = 4.0 * std::f32::consts::TAU;

#[derive(Clone, Copy)]
enum Shape3 {
    Sphere,
    Gyroid,
}

impl Shape3 {
    /// Inside-positive value (dynaclay's convention: solid where value > 0).
    #[inline]
    fn value(self, p: Vec3) -> f32 {
        match self {
            Self::Sphere => RADIUS - (p - CENTRE).length(),
            Self::Gyroid => {
                let (sx, cx) = (OMEGA * p.x).sin_cos();
                let (sy, cy) = (OMEGA * p.y).sin_cos();
                let (sz, cz) = (OMEGA * p.z).sin_cos();
                sx * cy + sy * cz + sz * cx
            }
        }
    }

    #[inline]
    fn gradient(self, p: Vec3) -> Vec3 {
        match self {
            Self::Sphere => -(p - CENTRE).normalize_or_zero(),
            Self::Gyroid => {
                let (sx, cx) = (OMEGA * p.x).sin_cos();
                let (sy, cy) = (OMEGA * p.y).sin_cos();
                let (sz, cz) = (OMEGA * p.z).sin_cos();
                OMEGA * Vec3::new(cx * cy - sz * sx, -sx * sy + cy * cz, -sy * sz + cz * cx)
            }
        }
    }

    fn name(self) -> &'static str {
        match self {
            Self::Sphere => "sphere",
            Self::Gyroid => "gyroid",
        }
    }
}

/// The same field for `isosurface` (negative inside).
struct IsoSource(Shape3);

impl ScalarSource for IsoSource {
    fn sample_scalar(&self, p: isosurface::math::Vec3) -> Signed {
        Signed(-self.0.value(Vec3::new(p.x, p.y, p.z)))
    }
}

impl HermiteSource for IsoSource {
    fn sample_normal(&self, p: isosurface::math::Vec3) -> isosurface::math::Vec3 {
        let n = -self
            .0
            .gradient(Vec3::new(p.x, p.y, p.z))
            .normalize_or_zero();
        isosurface::math::Vec3::new(n.x, n.y, n.z)
    }
}

fn full_extraction(c: &mut Criterion) {
    for shape in [Shape3::Sphere, Shape3::Gyroid] {
        let mut group = c.benchmark_group(format!("extract_{}", shape.name()));
        for n in [64u32, 128, 256] {
            group.throughput(Throughput::Elements(u64::from(n).pow(3)));
            group.sample_size(if n >= 256 { 10 } else { 20 });
            let grid = SampleGrid::new(Vec3::ZERO, 1.0 / n as f32, [n; 3]).unwrap();
            let field = FnField {
                value: move |p| shape.value(p),
                gradient: move |p| shape.gradient(p),
                iso: 0.0,
                lipschitz: None,
            };
            group.bench_function(BenchmarkId::new("dynaclay/bricks", n), |b| {
                b.iter(|| black_box(BrickOctree::build(grid, &field)))
            });
            group.bench_function(BenchmarkId::new("dynaclay/welded", n), |b| {
                b.iter(|| black_box(BrickOctree::build(grid, &field).weld()))
            });
            if let Shape3::Sphere = shape {
                let culled = FnField {
                    lipschitz: Some(1.0),
                    ..field
                };
                group.bench_function(BenchmarkId::new("dynaclay/culled", n), |b| {
                    b.iter(|| black_box(BrickOctree::build(grid, &culled).weld()))
                });
            }
            let source = IsoSource(shape);
            group.bench_function(BenchmarkId::new("isosurface/mc", n), |b| {
                b.iter(|| {
                    let sampler = Sampler::new(&source);
                    let (mut vertices, mut indices) = (Vec::new(), Vec::new());
                    let mut out =
                        IndexedInterleavedNormals::new(&mut vertices, &mut indices, &source);
                    MarchingCubes::<Signed>::new(n as usize + 1).extract(&sampler, &mut out);
                    black_box((vertices, indices))
                })
            });
            let shape_nd = RuntimeShape::<u32, 3>::new([n + 1; 3]);
            group.bench_function(BenchmarkId::new("fast-surface-nets", n), |b| {
                let mut buffer = SurfaceNetsBuffer::default();
                b.iter(|| {
                    let mut sdf = vec![0.0f32; shape_nd.usize()];
                    for (i, s) in sdf.iter_mut().enumerate() {
                        let [x, y, z] = shape_nd.delinearize(i as u32);
                        *s = -shape.value(grid.point([x, y, z]));
                    }
                    surface_nets(&sdf, &shape_nd, [0; 3], [n; 3], &mut buffer);
                    black_box(buffer.indices.len())
                })
            });
        }
        group.finish();
    }
}

/// A sphere of `radius_spans` knot spans as a B-spline lattice (ramp of the signed
/// distance, 6 spans wide), sized so that the support spans `n + 3` spans.
fn sphere_lattice(n: usize, radius_spans: f32) -> BSplineLattice {
    let spacing = 1.0;
    let mut lattice = BSplineLattice::zeros([n; 3], spacing, Vec3::ZERO).unwrap();
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

fn local_remesh(c: &mut Criterion) {
    // 61 + 3 spans × 4 cells = 256 cells per axis.
    let before = sphere_lattice(61, 24.0);
    let grid = SampleGrid::for_lattice(&before, 4).unwrap();
    assert_eq!(grid.cells, [256; 3]);
    // A tool-sized edit on the surface: one coefficient dented, which changes the field
    // within two knot spans = 8 voxels of its node: a box of radius 8 voxels.
    let node = [30 + 24, 30, 30];
    let mut after = before.clone();
    let idx = after.index(node[0], node[1], node[2]);
    after.coeffs[idx] -= 0.4;
    let (min, max) = BrickOctree::coefficient_change_box(&after, node, node);
    assert!(
        ((max - min) / grid.cell_size - Vec3::splat(16.0))
            .abs()
            .max_element()
            < 1e-3
    );

    let mut tree = BrickOctree::build(grid, &before);
    let mut group = c.benchmark_group("local_remesh_256");
    group.sample_size(50);
    let mut flip = false;
    group.bench_function("dynaclay/refresh_box_r8", |b| {
        b.iter(|| {
            // Alternate the edit and its undo, so every refresh has real work.
            flip = !flip;
            let field = if flip { &after } else { &before };
            black_box(tree.refresh_lattice(field, min, max))
        })
    });
    group.bench_function("dynaclay/full_rebuild", |b| {
        b.iter(|| black_box(tree.rebuild(&after)))
    });
    group.finish();
    let report = tree.refresh_lattice(&after, min, max);
    println!(
        "local re-mesh: {} bricks sampled, {} re-meshed, {} removed (of {} bricks)",
        report.bricks_sampled,
        report.changed.len(),
        report.removed.len(),
        tree.brick_count()
    );
}

/// Resident and peak resident memory of this process, in bytes (Linux).
fn rss_bytes() -> (usize, usize) {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    let field = |name: &str| {
        status
            .lines()
            .find(|l| l.starts_with(name))
            .and_then(|l| l.split_whitespace().nth(1))
            .and_then(|kb| kb.parse::<usize>().ok())
            .map_or(0, |kb| kb * 1024)
    };
    (field("VmRSS:"), field("VmHWM:"))
}

fn memory_at_512() {
    // 125 + 3 spans × 4 cells = 512 cells per axis; radius 56 spans = 224 voxels.
    let lattice = sphere_lattice(125, 56.0);
    let grid = SampleGrid::for_lattice(&lattice, 4).unwrap();
    assert_eq!(grid.cells, [512; 3]);
    let (rss_before, _) = rss_bytes();
    let start = Instant::now();
    let tree = BrickOctree::build(grid, &lattice);
    let seconds = start.elapsed().as_secs_f64();
    let (rss_after, peak) = rss_bytes();
    let m = tree.memory();
    let stats = MeshStats::of(&tree.weld());
    println!(
        "sphere 512^3 (radius 224 voxels): {} bricks, {} triangles, chi {}, closed {}",
        tree.brick_count(),
        tree.triangle_count(),
        stats.euler_characteristic,
        stats.is_closed_manifold()
    );
    println!(
        "  octree memory: samples {} B + meshes {} B + structure {} B = {} B ({:.1} MB); \
         RSS grew {:.1} MB during the build (peak RSS {:.1} MB); one-shot build {seconds:.2} s",
        m.sample_bytes,
        m.mesh_bytes,
        m.structure_bytes,
        m.total_bytes(),
        m.total_bytes() as f64 / 1e6,
        (rss_after.saturating_sub(rss_before)) as f64 / 1e6,
        peak as f64 / 1e6,
    );
}

fn main() {
    memory_at_512();
    let mut c = Criterion::default().configure_from_args();
    local_remesh(&mut c);
    full_extraction(&mut c);
    c.final_summary();
}
