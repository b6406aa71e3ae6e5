//! Profiling harness for extraction (not a criterion bench): `profile_mesh SHAPE N THREADS
//! REPS` builds the `N³` sphere or gyroid of `bench/mesh.rs` (the same closures, no Lipschitz
//! bound) REPS times on THREADS threads (the build and the weld) and prints the best time of
//! the build, of the weld, and of sampling the closure alone at every grid point (the least
//! any extractor of these samples pays), with the mesh's counts; then the same extraction into kept buffers (a rebuild of a kept tree
//! and a weld into a kept mesh), as fast-surface-nets runs with its kept buffer. Meant for
//! `perf record` and quick same-session comparisons (`PROFILE_KEPT_ONLY=1` times only the
//! kept rebuild and weld, for a profile of them alone; `PROFILE_FRESH_ONLY=1` only a new
//! tree built and welded, into a new mesh and into a kept one):
//! `cargo build --release --bench profile_mesh`, then
//! `perf record target/release/deps/profile_mesh-* gyroid 128 1 20`.
use std::hint::black_box;
use std::time::Instant;

use dynaclay::mesh::{BrickOctree, FnField, SampleGrid, TriMesh, WeldScratch};
use fast_surface_nets::ndshape::{RuntimeShape, Shape};
use fast_surface_nets::{SurfaceNetsBuffer, surface_nets};
use glam::Vec3;

const CENTRE: Vec3 = Vec3::splat(0.5);
const RADIUS: f32 = 0.4;
const OMEGA: f32 = 4.0 * std::f32::consts::TAU;

fn gyroid(p: Vec3) -> f32 {
    let (sx, cx) = (OMEGA * p.x).sin_cos();
    let (sy, cy) = (OMEGA * p.y).sin_cos();
    let (sz, cz) = (OMEGA * p.z).sin_cos();
    sx * cy + sy * cz + sz * cx
}

fn gyroid_gradient(p: Vec3) -> Vec3 {
    let (sx, cx) = (OMEGA * p.x).sin_cos();
    let (sy, cy) = (OMEGA * p.y).sin_cos();
    let (sz, cz) = (OMEGA * p.z).sin_cos();
    OMEGA * Vec3::new(cx * cy - sz * sx, -sx * sy + cy * cz, -sy * sz + cz * cx)
}

fn sphere(p: Vec3) -> f32 {
    RADIUS - (p - CENTRE).length()
}

fn sphere_gradient(p: Vec3) -> Vec3 {
    -(p - CENTRE).normalize_or_zero()
}

/// CPU time of the whole process so far, in milliseconds (all threads).
fn cpu_ms() -> f64 {
    // SAFETY: `clock_gettime` writes one `timespec` into the zeroed struct we own.
    let t = unsafe {
        let mut t: libc::timespec = std::mem::zeroed();
        libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut t);
        t
    };
    t.tv_sec as f64 * 1e3 + t.tv_nsec as f64 / 1e6
}

/// Best wall time and best CPU time (process, all threads) of `reps` runs, in ms. On a
/// loaded machine the CPU time is the steadier figure for one thread.
fn best(reps: usize, mut f: impl FnMut()) -> (f64, f64) {
    (0..reps)
        .map(|_| {
            let (t, c) = (Instant::now(), cpu_ms());
            f();
            (t.elapsed().as_secs_f64() * 1e3, cpu_ms() - c)
        })
        .fold((f64::INFINITY, f64::INFINITY), |a, b| {
            (a.0.min(b.0), a.1.min(b.1))
        })
}

fn run<V: Fn(Vec3) -> f32 + Sync, G: Fn(Vec3) -> Vec3 + Sync>(
    name: &str,
    value: V,
    gradient: G,
    n: u32,
    threads: usize,
    reps: usize,
) {
    let grid = SampleGrid::new(Vec3::ZERO, 1.0 / n as f32, [n; 3]).unwrap();
    let field = FnField {
        value: &value,
        gradient: &gradient,
        iso: 0.0,
        lipschitz: None,
    };
    if std::env::var_os("PROFILE_FRESH_ONLY").is_some() {
        let fresh = best(reps, || {
            black_box(
                BrickOctree::build_with_threads(grid, &field, threads).weld_with_threads(threads),
            );
        });
        let (mut out, mut scratch) = (TriMesh::default(), WeldScratch::default());
        let kept_mesh = best(reps, || {
            BrickOctree::build_with_threads(grid, &field, threads).weld_into_with_threads(
                &mut out,
                &mut scratch,
                threads,
            );
            black_box(out.triangles.len());
        });
        println!(
            "{name} {n}^3, {threads} thread(s), fresh tree, build + weld, wall / CPU: {:.2} / \
             {:.2} ms; welded into a kept mesh {:.2} / {:.2} ms",
            fresh.0, fresh.1, kept_mesh.0, kept_mesh.1
        );
        return;
    }
    let mut tree = BrickOctree::build_with_threads(grid, &field, threads);
    let mesh = tree.weld();
    assert_eq!(
        tree.weld_with_threads(threads),
        mesh,
        "the same mesh on any thread count"
    );
    // Kept buffers: the tree rebuilt in place, welded into a kept mesh.
    let mut out = TriMesh::default();
    let mut scratch = WeldScratch::default();
    let rebuild = best(reps, || {
        black_box(tree.rebuild_with_threads(&field, threads));
    });
    let weld_into = best(reps, || {
        tree.weld_into_with_threads(&mut out, &mut scratch, threads);
        black_box(out.triangles.len());
    });
    assert_eq!(out, mesh, "the kept buffers give the same mesh");
    let kept = (rebuild.0 + weld_into.0, rebuild.1 + weld_into.1);
    println!(
        "{name} {n}^3, {threads} thread(s), kept buffers, wall / CPU: rebuild {:.2} / {:.2} ms, \
         weld_into {:.2} / {:.2} ms, welded {:.2} / {:.2} ms",
        rebuild.0, rebuild.1, weld_into.0, weld_into.1, kept.0, kept.1
    );
    if std::env::var_os("PROFILE_KEPT_ONLY").is_some() {
        return;
    }
    let build = best(reps, || {
        black_box(BrickOctree::build_with_threads(grid, &field, threads));
    });
    let weld = best(reps, || {
        black_box(tree.weld_with_threads(threads));
    });
    let samples = best(reps, || {
        let mut sum = 0.0f32;
        for k in 0..=n {
            for j in 0..=n {
                for i in 0..=n {
                    sum += value(grid.point([i, j, k]));
                }
            }
        }
        black_box(sum);
    });
    // fast-surface-nets as `bench/mesh.rs` runs it: its buffers made once, the sampling timed.
    let shape_nd = RuntimeShape::<u32, 3>::new([n + 1; 3]);
    let mut buffer = SurfaceNetsBuffer::default();
    let mut sdf = vec![0.0f32; shape_nd.usize()];
    let peer = best(reps, || {
        for (i, s) in sdf.iter_mut().enumerate() {
            let [x, y, z] = shape_nd.delinearize(i as u32);
            *s = -value(grid.point([x, y, z]));
        }
        surface_nets(&sdf, &shape_nd, [0; 3], [n; 3], &mut buffer);
        black_box(buffer.indices.len());
    });
    let welded = (build.0 + weld.0, build.1 + weld.1);
    println!(
        "  fast-surface-nets {:.2} / {:.2} ms; welded (build + weld) {:.2} / {:.2} ms: \
         {:.2}x the peer by wall time, {:.2}x by CPU time",
        peer.0,
        peer.1,
        welded.0,
        welded.1,
        peer.0 / welded.0,
        peer.1 / welded.1
    );
    println!(
        "  kept buffers: {:.2}x the peer by wall time, {:.2}x by CPU time",
        peer.0 / kept.0,
        peer.1 / kept.1
    );
    println!(
        "{name} {n}^3, {threads} thread(s), wall / CPU: build {:.2} / {:.2} ms, weld {:.2} / \
         {:.2} ms, sampling alone {:.2} / {:.2} ms; {} bricks, {} vertices, {} triangles",
        build.0,
        build.1,
        weld.0,
        weld.1,
        samples.0,
        samples.1,
        tree.brick_count(),
        mesh.vertex_count(),
        mesh.triangle_count()
    );
}

fn main() {
    let a: Vec<String> = std::env::args().skip(1).collect();
    let shape = a.first().map_or("gyroid", String::as_str);
    let n: u32 = a.get(1).map_or(128, |s| s.parse().unwrap());
    let threads: usize = a.get(2).map_or(1, |s| s.parse().unwrap());
    let reps: usize = a.get(3).map_or(10, |s| s.parse().unwrap());
    match shape {
        "sphere" => run("sphere", sphere, sphere_gradient, n, threads, reps),
        _ => run("gyroid", gyroid, gyroid_gradient, n, threads, reps),
    }
}
