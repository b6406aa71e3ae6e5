//! Meshing benchmarks: full extraction against the `isosurface` crate's marching cubes on the
//! same samples (its 0.0.4 release, with and without normals, and the 0.1.0 alpha), and
//! `fast-surface-nets` (a different algorithm, for reference), a local re-mesh of a tool-sized
//! box, a re-mesh by the multi-level mesher after a stroke-sized change on a three-level clay
//! (local around the change, and whole for the ratio), the graphics loop's re-mesh of a
//! stroke-sized change with and without detail patches (`graphics_stroke`: marching cubes of
//! the one-level clay's bricks against the multi-level mesh cut into bricks, both at the
//! engine's four cells per span; and a new patch layout, re-meshed over the new patch alone
//! beside the whole clay meshed and cut again),
//! and the resident memory of building a sphere at 512³ (measured in a child process).
//!
//! Run: `cargo bench --bench mesh -- --warm-up-time 1 --measurement-time 3`
//! (`threads_(sphere|gyroid)_256` compares one thread with two in the same run).
//!
//! Fairness notes. Every contender samples the same closure at the same points `i / n`
//! (both `isosurface` releases also march one extra layer of cells past z = 1, ~1/n more
//! work) and produces an indexed mesh with per-vertex normals from the analytic gradient
//! (`isosurface` 0.0.4 through `extract_with_normals`, the alpha through
//! `IndexedInterleavedNormals`; `fast-surface-nets` estimates normals by central differences).
//! `isosurface-0.0.4/mc_positions` is the same marching cubes without normals (less work than
//! the others). Every extractor and buffer that its authors mean to be reused is made once,
//! outside the timed loop: the 0.0.4 `MarchingCubes` (it keeps two layers of samples) and the
//! output vectors (cleared per run), `fast-surface-nets`' sample array and output buffer.
//! All run on one thread. Before timing, the marching-cubes contenders' triangle counts are
//! checked to agree within 2% (the same algorithm on the same samples; the extra layer is
//! under 2% at 64³), and so are the vertex counts of those that share every edge's vertex
//! (dynaclay welded and the alpha); 0.0.4's index cache shares only some edges, so it emits
//! most vertices twice and its vertex count is printed, not compared.
//! "dynaclay/culled" adds a Lipschitz bound so the octree skips empty space: it is the sparse
//! path, not the like-for-like comparison.

use std::hint::black_box;
use std::time::Instant;

use criterion::{BenchmarkId, Criterion, Throughput};
use dynaclay::engine::level_mesh_options;
use dynaclay::field::MultiPatchField;
use dynaclay::mesh::{
    AdaptiveBricks, AdaptiveMeshOptions, AdaptiveMesher, BrickOctree, FnField, SampleGrid, TriMesh,
    WeldScratch, adaptive_cell_count, mesh_adaptive,
};
use fast_surface_nets::ndshape::{RuntimeShape, Shape};
use fast_surface_nets::{SurfaceNetsBuffer, surface_nets};
use glam::Vec3;
use isosurface::MarchingCubes;

#[path = "support/mesh_clays.rs"]
mod mesh_clays;
use isosurface::distance::Signed;
use isosurface::extractor::IndexedInterleavedNormals;
use isosurface::sampler::Sampler;
use isosurface::source::{HermiteSource, ScalarSource};
use isosurface004::marching_cubes::MarchingCubes as MarchingCubes004;
use mesh_clays::{sphere_lattice, three_level_clay};

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

/// The same field for `isosurface` 0.0.4 (negative inside).
struct IsoSource004(Shape3);

impl isosurface004::source::Source for IsoSource004 {
    fn sample(&self, x: f32, y: f32, z: f32) -> f32 {
        -self.0.value(Vec3::new(x, y, z))
    }
}

impl isosurface004::source::HermiteSource for IsoSource004 {
    fn sample_normal(&self, x: f32, y: f32, z: f32) -> isosurface004::math::Vec3 {
        let n = -self.0.gradient(Vec3::new(x, y, z)).normalize_or_zero();
        isosurface004::math::Vec3::new(n.x, n.y, n.z)
    }
}

/// Vertex and triangle counts of one contender's mesh.
#[derive(Clone, Copy, Debug)]
struct Counts {
    vertices: usize,
    triangles: usize,
}

/// Panics unless `b`'s triangle count (and, with `vertices`, its vertex count) is within 2%
/// of `a`'s.
fn assert_counts_agree(what: &str, a: (&str, Counts), b: (&str, Counts), vertices: bool) {
    let close = |x: usize, y: usize| (x as f64 - y as f64).abs() <= 0.02 * x.max(y) as f64;
    assert!(
        close(a.1.triangles, b.1.triangles) && (!vertices || close(a.1.vertices, b.1.vertices)),
        "{what}: {} gives {:?} but {} gives {:?} (more than 2% apart)",
        a.0,
        a.1,
        b.0,
        b.1
    );
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
            // The tree and the welded mesh kept and refilled, as fast-surface-nets' buffer is.
            group.bench_function(BenchmarkId::new("dynaclay/welded_kept", n), |b| {
                let mut tree = BrickOctree::build(grid, &field);
                let mut out = TriMesh::default();
                let mut scratch = WeldScratch::default();
                b.iter(|| {
                    tree.rebuild(&field);
                    tree.weld_into(&mut out, &mut scratch);
                    black_box(out.triangles.len())
                })
            });
            // A new tree each time (every brick's buffers allocated, the tree dropped), welded
            // into a kept mesh: the tree's own cost, without the first touch of a new mesh's
            // pages that `dynaclay/welded` also pays.
            group.bench_function(BenchmarkId::new("dynaclay/fresh_tree_kept_mesh", n), |b| {
                let mut out = TriMesh::default();
                let mut scratch = WeldScratch::default();
                b.iter(|| {
                    BrickOctree::build(grid, &field).weld_into(&mut out, &mut scratch);
                    black_box(out.triangles.len())
                })
            });
            group.bench_function(BenchmarkId::new("dynaclay/bricks_2_threads", n), |b| {
                b.iter(|| black_box(BrickOctree::build_with_threads(grid, &field, 2)))
            });
            group.bench_function(BenchmarkId::new("dynaclay/welded_2_threads", n), |b| {
                b.iter(|| {
                    black_box(BrickOctree::build_with_threads(grid, &field, 2).weld_with_threads(2))
                })
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
            // Counts of each marching-cubes contender, checked before any timing.
            let welded = BrickOctree::build(grid, &field).weld();
            let ours = Counts {
                vertices: welded.vertex_count(),
                triangles: welded.triangle_count(),
            };
            let source = IsoSource(shape);
            let alpha = |vertices: &mut Vec<f32>, indices: &mut Vec<u32>| {
                let sampler = Sampler::new(&source);
                let mut out = IndexedInterleavedNormals::new(vertices, indices, &source);
                MarchingCubes::<Signed>::new(n as usize + 1).extract(&sampler, &mut out);
            };
            let source004 = IsoSource004(shape);
            let mut mc004 = MarchingCubes004::new(n as usize + 1);
            let (mut vertices, mut indices) = (Vec::new(), Vec::new());
            mc004.extract_with_normals(&source004, &mut vertices, &mut indices);
            // Its index cache shares only some of the edges between cells, so it emits most
            // vertices twice: only its triangles are compared.
            let counts004 = Counts {
                vertices: vertices.len() / 6,
                triangles: indices.len() / 3,
            };
            vertices.clear();
            indices.clear();
            mc004.extract(&source004, &mut vertices, &mut indices);
            let counts004_positions = Counts {
                vertices: vertices.len() / 3,
                triangles: indices.len() / 3,
            };
            let what = format!("{} {n}^3", shape.name());
            println!("{what}: dynaclay welded {ours:?}, isosurface 0.0.4 {counts004:?}");
            let ours = ("dynaclay/welded", ours);
            assert_counts_agree(&what, ours, ("isosurface-0.0.4/mc", counts004), false);
            assert_counts_agree(
                &what,
                ours,
                ("isosurface-0.0.4/mc_positions", counts004_positions),
                false,
            );

            group.bench_function(BenchmarkId::new("isosurface-0.0.4/mc", n), |b| {
                b.iter(|| {
                    vertices.clear();
                    indices.clear();
                    mc004.extract_with_normals(&source004, &mut vertices, &mut indices);
                    black_box((vertices.len(), indices.len()))
                })
            });
            group.bench_function(BenchmarkId::new("isosurface-0.0.4/mc_positions", n), |b| {
                b.iter(|| {
                    vertices.clear();
                    indices.clear();
                    mc004.extract(&source004, &mut vertices, &mut indices);
                    black_box((vertices.len(), indices.len()))
                })
            });
            // The alpha's extractor borrows its output for one run, so it is made per run.
            // Its counts are checked when it is first run (it is slow at 256³, so only when
            // the filter selects it).
            let mut alpha_checked = false;
            group.bench_function(BenchmarkId::new("isosurface-alpha/mc", n), |b| {
                if !alpha_checked {
                    vertices.clear();
                    indices.clear();
                    alpha(&mut vertices, &mut indices);
                    let counts = Counts {
                        vertices: vertices.len() / 6,
                        triangles: indices.len() / 3,
                    };
                    println!("{what}: isosurface alpha {counts:?}");
                    assert_counts_agree(&what, ours, ("isosurface-alpha/mc", counts), true);
                    alpha_checked = true;
                }
                b.iter(|| {
                    vertices.clear();
                    indices.clear();
                    alpha(&mut vertices, &mut indices);
                    black_box((vertices.len(), indices.len()))
                })
            });
            let shape_nd = RuntimeShape::<u32, 3>::new([n + 1; 3]);
            group.bench_function(BenchmarkId::new("fast-surface-nets", n), |b| {
                let mut buffer = SurfaceNetsBuffer::default();
                let mut sdf = vec![0.0f32; shape_nd.usize()];
                b.iter(|| {
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

/// One thread against two in the same run: a kept tree rebuilt (the bricks) and then
/// welded into a kept mesh on as many threads (one thread: the one-pass weld; two: the
/// two-pass weld over runs of bricks), sphere and gyroid at 256³. On a machine with fewer
/// than two idle cores the ratio says nothing.
fn threads(c: &mut Criterion) {
    let n = 256u32;
    let grid = SampleGrid::new(Vec3::ZERO, 1.0 / n as f32, [n; 3]).unwrap();
    for shape in [Shape3::Sphere, Shape3::Gyroid] {
        let field = FnField {
            value: move |p| shape.value(p),
            gradient: move |p| shape.gradient(p),
            iso: 0.0,
            lipschitz: None,
        };
        let mut group = c.benchmark_group(format!("threads_{}_{n}", shape.name()));
        group.sample_size(10);
        let mut tree = BrickOctree::build(grid, &field);
        let mut out = TriMesh::default();
        let mut scratch = WeldScratch::default();
        for threads in [1usize, 2] {
            group.bench_function(BenchmarkId::new("rebuild", threads), |b| {
                b.iter(|| black_box(tree.rebuild_with_threads(&field, threads)))
            });
            group.bench_function(BenchmarkId::new("rebuild_and_weld", threads), |b| {
                b.iter(|| {
                    tree.rebuild_with_threads(&field, threads);
                    tree.weld_into_with_threads(&mut out, &mut scratch, threads);
                    black_box(out.triangles.len())
                })
            });
        }
        group.finish();
    }
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
    after.coeffs.add_flat(idx, -0.4);
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

/// The multi-level mesher after one stroke-sized change on a three-level clay: the kept
/// mesh re-meshed locally around the stroke's change box (and the kept mesh copied out), and
/// for the ratio the whole clay meshed again. Before timing, the local path's meshes are
/// checked to hold the same triangles as whole meshes of the clay, after the stroke and after
/// its undo; each timed local re-mesh is checked to be local and to make polygons.
fn adaptive_remesh(c: &mut Criterion) {
    let (before, after, (lo, hi)) = three_level_clay();
    let options = AdaptiveMeshOptions::default();
    let leaves = adaptive_cell_count(&after, &options).unwrap();
    let (a, b) = (
        mesh_adaptive(&before, &options).unwrap(),
        mesh_adaptive(&after, &options).unwrap(),
    );
    assert_ne!(a.positions, b.positions, "the stroke changed the mesh");
    let mut mesher = AdaptiveMesher::new(&before, &options).unwrap();
    let stroke = mesher.remesh_box(&after, lo, hi).unwrap();
    assert!(!stroke.whole);
    assert_eq!(mesher.mesh().canonical_triangles(), b.canonical_triangles());
    let undo = mesher.remesh_box(&before, lo, hi).unwrap();
    assert_eq!(mesher.mesh().canonical_triangles(), a.canonical_triangles());
    println!(
        "three-level clay: {} patches, {leaves} leaves, {} triangles after the stroke; \
         local re-mesh of the stroke: {stroke:?}; of its undo: {undo:?}",
        after.patches.len(),
        b.triangles.len()
    );
    let mut group = c.benchmark_group("adaptive_remesh_three_levels");
    group.sample_size(20);
    let mut flip = false;
    group.bench_function("dynaclay/local_after_stroke", |bench| {
        bench.iter(|| {
            // Alternate the stroke and its undo, so every re-mesh has real work.
            flip = !flip;
            let field = if flip { &after } else { &before };
            let report = mesher.remesh_box(field, lo, hi).unwrap();
            assert!(!report.whole && report.polygons_made > 0, "{report:?}");
            black_box(mesher.mesh())
        })
    });
    let mut flip = false;
    group.bench_function("dynaclay/whole_clay_after_stroke", |bench| {
        bench.iter(|| {
            flip = !flip;
            let field = if flip { &after } else { &before };
            let mesh = mesh_adaptive(field, &options).unwrap();
            assert!(!mesh.triangles.is_empty());
            black_box(mesh)
        })
    });
    group.finish();
}

/// `field` (the three-level clay) with one more patch of its finest level, as wide as its
/// finest patch, at the sphere's +y pole: a new layout that keeps the mesher's frame.
fn refined_elsewhere(field: &MultiPatchField) -> MultiPatchField {
    let finest = field.patches.last().unwrap();
    let level = (field.patches[0].lattice.spacing / finest.lattice.spacing)
        .log2()
        .round() as u32;
    let (lo, hi) = finest.world_support();
    let half = 0.5 * (hi - lo) - Vec3::splat(2.0 * finest.lattice.spacing);
    let pole = Vec3::splat(11.5) + Vec3::Y * 8.0;
    let mut refined = field.clone();
    refined.refine(pole - half, pole + half, level).unwrap();
    refined
}

/// The engine's cells per knot span (`EngineConfig::cells_per_span`'s default).
const ENGINE_CELLS_PER_SPAN: u32 = 4;

/// The graphics loop's work for one stroke-sized change, as `GraphicsStage` does it: on the
/// clay of one patch (the three-level clay's base sphere, a stroke of three base
/// coefficients at the pole) marching cubes refresh the bricks of the change box; on the
/// three-level clay (the stroke of three finest coefficients of `three_level_clay`) the
/// multi-level mesher re-meshes around the change box and the changed triangles' bricks are
/// cut again. Both alternate the stroke and its undo and return the bricks for the sink.
/// Before timing, the cut bricks are checked to weld into the whole multi-level mesh. For
/// the split of the cost: the mesher's local re-mesh alone, and the cut path at the export's
/// two cells per span and with every level at the window's four (its detail takes two,
/// `level_mesh_options`).
fn graphics_stroke(c: &mut Criterion) {
    let (before, after, (lo, hi)) = three_level_clay();
    // One level: the base alone, dented by three of its own coefficients at the pole.
    let base_before = MultiPatchField::new(before.patches[0].lattice.clone());
    let mut base_after = base_before.clone();
    let lattice = &mut base_after.patches[0].lattice;
    let node = [20, 12, 12];
    for step in 0..3 {
        let idx = lattice.index(node[0] + step, node[1], node[2]);
        lattice.coeffs.add_flat(idx, -0.3);
    }
    let (base_lo, base_hi) =
        BrickOctree::coefficient_change_box(lattice, node, [node[0] + 2, node[1], node[2]]);
    let grid = SampleGrid::for_field(&base_before, ENGINE_CELLS_PER_SPAN).unwrap();
    let mut one_level = BrickOctree::build(grid, &base_before);

    let options = level_mesh_options(ENGINE_CELLS_PER_SPAN);
    let grid = SampleGrid::for_field(&before, ENGINE_CELLS_PER_SPAN).unwrap();
    let mut levels_tree = BrickOctree::new(grid);
    let (mut levels, _) = AdaptiveBricks::new(&before, &options, &mut levels_tree).unwrap();
    let stroke = levels.remesh_box(&after, lo, hi, &mut levels_tree).unwrap();
    assert_eq!(
        levels_tree.weld().canonical_triangles(),
        AdaptiveMesher::new(&after, &options)
            .unwrap()
            .mesh()
            .canonical_triangles(),
        "the cut bricks weld into the whole multi-level mesh"
    );
    let undo = levels
        .remesh_box(&before, lo, hi, &mut levels_tree)
        .unwrap();
    // A new layout: a patch of the finest level at the +y pole, as a refine adds it (holding
    // nothing yet). Re-meshed over its support alone, the cut bricks still weld into the
    // whole multi-level mesh, and the bricks changed all lie near the new patch.
    let refined = refined_elsewhere(&before);
    let layout = levels.remesh_layout(&refined, &mut levels_tree).unwrap();
    assert_eq!(
        levels_tree.weld().canonical_triangles(),
        AdaptiveMesher::new(&refined, &options)
            .unwrap()
            .mesh()
            .canonical_triangles(),
        "after a new layout the cut bricks weld into the whole multi-level mesh"
    );
    let unrefined = levels.remesh_layout(&before, &mut levels_tree).unwrap();
    println!(
        "new layout (a finest-level patch at the +y pole): {} bricks re-meshed and {}          removed, {} and {} when it goes again, of {} bricks",
        layout.changed.len(),
        layout.removed.len(),
        unrefined.changed.len(),
        unrefined.removed.len(),
        levels_tree.brick_count()
    );
    println!(
        "graphics stroke: one level {} bricks; three levels {} bricks, {} leaves, {} \
         triangles; the stroke re-meshed {} bricks and removed {}, its undo {} and {}",
        one_level.brick_count(),
        levels_tree.brick_count(),
        levels.mesher().leaf_count(),
        levels_tree.triangle_count(),
        stroke.changed.len(),
        stroke.removed.len(),
        undo.changed.len(),
        undo.removed.len()
    );

    let mut group = c.benchmark_group("graphics_stroke");
    group.sample_size(10);
    let mut flip = false;
    group.bench_function("one_level/marching_cubes_bricks", |bench| {
        bench.iter(|| {
            flip = !flip;
            let field = if flip { &base_after } else { &base_before };
            let report = one_level.refresh_box(field, base_lo, base_hi);
            assert!(!report.changed.is_empty());
            black_box(report)
        })
    });
    let mut flip = false;
    group.bench_function("three_levels/multi_level_bricks", |bench| {
        bench.iter(|| {
            flip = !flip;
            let field = if flip { &after } else { &before };
            let report = levels.remesh_box(field, lo, hi, &mut levels_tree).unwrap();
            assert!(!report.changed.is_empty());
            black_box(report)
        })
    });
    // The mesher's share: the same local re-mesh without the cut into bricks.
    let mut mesher = AdaptiveMesher::new(&before, &options).unwrap();
    let mut flip = false;
    group.bench_function("three_levels/mesher_alone", |bench| {
        bench.iter(|| {
            flip = !flip;
            let field = if flip { &after } else { &before };
            let report = mesher.remesh_box(field, lo, hi).unwrap();
            assert!(!report.whole && report.polygons_made > 0, "{report:?}");
            black_box(report)
        })
    });
    // A new patch layout (a refine, a fold) re-meshed whole and cut: what the window did
    // before a layout was re-meshed locally (and still does where the frame moves).
    group.bench_function("three_levels/whole_clay_cut_after_new_layout", |bench| {
        bench.iter(|| {
            let mut tree = BrickOctree::new(*levels_tree.grid());
            black_box(AdaptiveBricks::new(&refined, &options, &mut tree).unwrap())
        })
    });
    // The same new layout re-meshed over the new patch's support alone; alternately the
    // patch comes and goes, so every call has a new layout.
    let mut flip = false;
    group.bench_function("three_levels/new_layout_local", |bench| {
        bench.iter(|| {
            flip = !flip;
            let field = if flip { &refined } else { &before };
            let report = levels.remesh_layout(field, &mut levels_tree).unwrap();
            assert!(!report.changed.is_empty());
            black_box(report)
        })
    });
    // The export's two cells per span (a quarter of the cells), cut into the same bricks.
    let (mut coarser, _) =
        AdaptiveBricks::new(&before, &level_mesh_options(2), &mut levels_tree).unwrap();
    let mut flip = false;
    group.bench_function(
        "three_levels/multi_level_bricks_2_cells_per_span",
        |bench| {
            bench.iter(|| {
                flip = !flip;
                let field = if flip { &after } else { &before };
                let report = coarser.remesh_box(field, lo, hi, &mut levels_tree).unwrap();
                assert!(!report.changed.is_empty());
                black_box(report)
            })
        },
    );
    // Every level at the window's four cells per span (the window before its detail took
    // half the base's cells per span), cut into the same bricks.
    let every_level_4 = AdaptiveMeshOptions {
        detail_cells_per_span: options.cells_per_span,
        ..options
    };
    let (mut finer, _) = AdaptiveBricks::new(&before, &every_level_4, &mut levels_tree).unwrap();
    let mut flip = false;
    group.bench_function(
        "three_levels/multi_level_bricks_every_level_4_cells_per_span",
        |bench| {
            bench.iter(|| {
                flip = !flip;
                let field = if flip { &after } else { &before };
                let report = finer.remesh_box(field, lo, hi, &mut levels_tree).unwrap();
                assert!(!report.changed.is_empty());
                black_box(report)
            })
        },
    );
    group.finish();
}

/// Peak resident memory of this process so far (`VmHWM`), in bytes (Linux).
fn peak_rss_bytes() -> usize {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    status
        .lines()
        .find(|l| l.starts_with("VmHWM:"))
        .and_then(|l| l.split_whitespace().nth(1))
        .and_then(|kb| kb.parse::<usize>().ok())
        .map_or(0, |kb| kb * 1024)
}

/// The environment variable that makes this binary the child of [`memory_at_512`].
const MEMORY_CHILD: &str = "DYNACLAY_MESH_BENCH_MEMORY_CHILD";

/// Floor on the peak resident memory of the child that builds the 512³ sphere.
const MEMORY_FLOOR_BYTES: usize = 200_000_000;

/// In the child: builds the 512³ sphere's octree in a fresh process and prints its peak
/// resident memory before and after the build, and what the octree says it holds.
fn memory_child() {
    // 125 + 3 spans × 4 cells = 512 cells per axis; radius 56 spans = 224 voxels.
    let lattice = sphere_lattice(125, 56.0);
    let grid = SampleGrid::for_lattice(&lattice, 4).unwrap();
    assert_eq!(grid.cells, [512; 3]);
    let peak_before = peak_rss_bytes();
    let start = Instant::now();
    let tree = BrickOctree::build(grid, &lattice);
    let seconds = start.elapsed().as_secs_f64();
    let peak_after_build = peak_rss_bytes();
    let m = tree.memory();
    assert!(tree.triangle_count() > 0, "the 512^3 sphere has a surface");
    println!(
        "sphere 512^3 (radius 224 voxels): {} bricks, {} triangles",
        tree.brick_count(),
        tree.triangle_count(),
    );
    println!(
        "  child: peak RSS {:.1} MB before the build (lattice and binary), {:.1} MB after it; \
         the octree's own estimate {:.1} MB (meshes {} B + structure {} B); \
         one-shot build {seconds:.2} s",
        peak_before as f64 / 1e6,
        peak_after_build as f64 / 1e6,
        m.total_bytes() as f64 / 1e6,
        m.mesh_bytes,
        m.structure_bytes,
    );
}

/// Runs [`memory_child`] in a child process (this binary again) and checks its peak resident
/// memory, as the kernel counts it for the waited-for child (`getrusage(RUSAGE_CHILDREN)`),
/// against the floor. The child only builds (no welded copy), so the figure is the build's:
/// the lattice, the binary and the octree with its transient scratch.
fn memory_at_512() {
    let exe = std::env::current_exe().expect("benchmark binary path");
    let status = std::process::Command::new(exe)
        .env(MEMORY_CHILD, "1")
        .status()
        .expect("memory child starts");
    assert!(status.success(), "memory child failed: {status}");
    // SAFETY: `getrusage` writes one `rusage` into the zeroed struct we own.
    let usage = unsafe {
        let mut usage: libc::rusage = std::mem::zeroed();
        assert_eq!(libc::getrusage(libc::RUSAGE_CHILDREN, &mut usage), 0);
        usage
    };
    // Linux reports `ru_maxrss` in kilobytes.
    let peak = usage.ru_maxrss as usize * 1024;
    println!(
        "  peak RSS of the child (getrusage RUSAGE_CHILDREN): {:.1} MB (floor {:.0} MB)",
        peak as f64 / 1e6,
        MEMORY_FLOOR_BYTES as f64 / 1e6
    );
    assert!(
        peak <= MEMORY_FLOOR_BYTES,
        "building the 512^3 sphere peaks at {peak} B resident, over the {MEMORY_FLOOR_BYTES} B floor"
    );
}

fn main() {
    if std::env::var_os(MEMORY_CHILD).is_some() {
        memory_child();
        return;
    }
    memory_at_512();
    let mut c = Criterion::default().configure_from_args();
    local_remesh(&mut c);
    graphics_stroke(&mut c);
    adaptive_remesh(&mut c);
    full_extraction(&mut c);
    threads(&mut c);
    c.final_summary();
}
