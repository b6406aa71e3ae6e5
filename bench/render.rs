//! Rendering benchmarks: frame time of a ~200k-triangle sculpt split into octree bricks, and
//! the cost of uploading one dirty brick against re-uploading every brick (the obvious
//! alternative to dirty tracking).
//!
//! Runs on whatever adapter `GpuContext::headless` finds (lavapipe on CI). Prints
//! "skipped: no GPU adapter" and exits cleanly when there is none.
//! Short run: `cargo bench --bench render -- --warm-up-time 1 --measurement-time 3`.

use std::time::Duration;

use criterion::Criterion;
use dynaclay::render::{
    Camera, GpuContext, MeshChunk, NamedView, OFFSCREEN_FORMAT, SceneOptions, SceneRenderer,
    supported_sample_count,
};
use glam::Vec3;

/// One brick's mesh, owned.
struct Brick {
    id: u64,
    version: u64,
    positions: Vec<[f32; 3]>,
    normals: Vec<[f32; 3]>,
    indices: Vec<u32>,
}

impl Brick {
    fn view(&self) -> MeshChunk<'_> {
        MeshChunk {
            id: self.id,
            version: self.version,
            positions: &self.positions,
            normals: &self.normals,
            colors: &[],
            indices: &self.indices,
            cut: false,
        }
    }
}

/// A bumpy sphere of about `2 · segments · rings` triangles, cut into bricks on a
/// `bricks_per_axis³` grid over its bounding box (each triangle goes to its centroid's brick).
fn sculpt(segments: u32, rings: u32, bricks_per_axis: u32) -> Vec<Brick> {
    let surface = |theta: f32, phi: f32| {
        let n = Vec3::new(
            theta.sin() * phi.cos(),
            theta.cos(),
            theta.sin() * phi.sin(),
        );
        let r = 1.0 + 0.05 * (5.0 * theta).sin() * (7.0 * phi).cos();
        n * r
    };
    let mut positions = Vec::new();
    let mut normals = Vec::new();
    for r in 0..=rings {
        for s in 0..=segments {
            let theta = std::f32::consts::PI * r as f32 / rings as f32;
            let phi = std::f32::consts::TAU * s as f32 / segments as f32;
            let p = surface(theta, phi);
            // Normal from central differences of the parametrisation.
            let e = 1.0e-3;
            let dt = surface(theta + e, phi) - surface(theta - e, phi);
            let dp = surface(theta, phi + e) - surface(theta, phi - e);
            let n = dp.cross(dt).normalize_or(p.normalize());
            positions.push(p);
            normals.push(if n.dot(p) < 0.0 { -n } else { n });
        }
    }
    let at = |r: u32, s: u32| (r * (segments + 1) + s) as usize;
    let cells = bricks_per_axis as usize;
    let brick_of = |c: Vec3| {
        let q = ((c + Vec3::splat(1.1)) / 2.2 * cells as f32).floor();
        let q = q.clamp(Vec3::ZERO, Vec3::splat(cells as f32 - 1.0));
        q.x as usize + cells * (q.y as usize + cells * q.z as usize)
    };
    let mut bricks: Vec<Brick> = (0..cells * cells * cells)
        .map(|i| Brick {
            id: i as u64,
            version: 1,
            positions: Vec::new(),
            normals: Vec::new(),
            indices: Vec::new(),
        })
        .collect();
    let mut remap = std::collections::HashMap::new();
    for r in 0..rings {
        for s in 0..segments {
            let quad = [at(r, s), at(r + 1, s), at(r + 1, s + 1), at(r, s + 1)];
            for tri in [[quad[0], quad[1], quad[2]], [quad[0], quad[2], quad[3]]] {
                let c = (positions[tri[0]] + positions[tri[1]] + positions[tri[2]]) / 3.0;
                let b = brick_of(c);
                let brick = &mut bricks[b];
                for v in tri {
                    let slot = *remap.entry((b, v)).or_insert_with(|| {
                        brick.positions.push(positions[v].into());
                        brick.normals.push(normals[v].into());
                        (brick.positions.len() - 1) as u32
                    });
                    brick.indices.push(slot);
                }
            }
        }
    }
    bricks.retain(|b| !b.indices.is_empty());
    bricks
}

fn main() {
    let gpu = match GpuContext::headless() {
        Ok(g) => g,
        Err(e) if e.is_no_adapter() => {
            println!("skipped: {e}");
            return;
        }
        Err(e) => panic!("{e}"),
    };
    let mut criterion = Criterion::default()
        .sample_size(10)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(5))
        .configure_from_args();

    let mut bricks = sculpt(448, 224, 8);
    let triangles: usize = bricks.iter().map(|b| b.indices.len() / 3).sum();
    let samples = supported_sample_count(&gpu.adapter, OFFSCREEN_FORMAT);
    println!(
        "adapter: {}; sculpt: {triangles} triangles in {} bricks; MSAA {samples}x",
        gpu.summary,
        bricks.len()
    );
    let (device, queue) = (&gpu.device, &gpu.queue);
    let (width, height) = (1280, 720);
    let mut renderer = SceneRenderer::new(device, queue, OFFSCREEN_FORMAT, samples, width, height);
    let views: Vec<MeshChunk<'_>> = bricks.iter().map(Brick::view).collect();
    renderer
        .sync_chunks(device, queue, &views)
        .expect("valid bricks");
    drop(views);
    let camera = Camera::named(NamedView::Iso, Vec3::splat(-1.1), Vec3::splat(1.1));
    let options = SceneOptions::default();

    let finish = |encoder: wgpu::CommandEncoder| {
        queue.submit([encoder.finish()]);
        device
            .poll(wgpu::PollType::wait_indefinitely())
            .expect("GPU finished");
    };

    let mut group = criterion.benchmark_group("render");
    group.bench_function(
        format!("frame {triangles} tris {width}x{height} msaa{samples}"),
        |b| {
            b.iter(|| {
                let mut encoder = device.create_command_encoder(&Default::default());
                renderer.render(device, queue, &mut encoder, &camera, &options);
                finish(encoder);
            });
        },
    );
    if samples > 1 {
        // The same frame without multisampling: what MSAA costs on this adapter.
        let mut single = SceneRenderer::new(device, queue, OFFSCREEN_FORMAT, 1, width, height);
        let views: Vec<MeshChunk<'_>> = bricks.iter().map(Brick::view).collect();
        single
            .sync_chunks(device, queue, &views)
            .expect("valid bricks");
        drop(views);
        group.bench_function(
            format!("frame {triangles} tris {width}x{height} msaa1"),
            |b| {
                b.iter(|| {
                    let mut encoder = device.create_command_encoder(&Default::default());
                    single.render(device, queue, &mut encoder, &camera, &options);
                    finish(encoder);
                });
            },
        );
    }

    // The brick with the median triangle count stands for "one dirty brick".
    let mut order: Vec<usize> = (0..bricks.len()).collect();
    order.sort_by_key(|&i| bricks[i].indices.len());
    let median = order[order.len() / 2];
    let brick_tris = bricks[median].indices.len() / 3;
    group.bench_function(format!("upload one dirty brick ({brick_tris} tris)"), |b| {
        b.iter(|| {
            bricks[median].version += 1;
            let views: Vec<MeshChunk<'_>> = bricks.iter().map(Brick::view).collect();
            let report = renderer
                .sync_chunks(device, queue, &views)
                .expect("valid bricks");
            assert_eq!(report.uploaded, 1);
            finish(device.create_command_encoder(&Default::default()));
        });
    });
    group.bench_function(format!("re-upload all {} bricks", bricks.len()), |b| {
        b.iter(|| {
            for brick in &mut bricks {
                brick.version += 1;
            }
            let views: Vec<MeshChunk<'_>> = bricks.iter().map(Brick::view).collect();
            renderer
                .sync_chunks(device, queue, &views)
                .expect("valid bricks");
            finish(device.create_command_encoder(&Default::default()));
        });
    });
    group.finish();
    criterion.final_summary();
}
