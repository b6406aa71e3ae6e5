//! The mouse as the sculpting tool: what the window spends per frame on it.
//!
//! - `pick/96`: one view ray against the default block at 96³ coefficients (march and
//!   bisect, `dynaclay::field::pick_surface`), averaged over rays spread across the block and
//!   past its edge (misses included), from an oblique camera.
//! - `pointer_frame/96`: the pointer path of one frame while hovering: the ray through the
//!   pointer, the pick, the tip placed and handed to the pointer device
//!   (`dynaclay::app::PointerTool::hover`), plus the brush cursor's screen radius.
//! - `pick_mesh_peer/96`: the obvious alternative, a ray against every triangle of the
//!   clay's mesh (what a picker without the field would do), on the same rays.
//!
//! Run: `cargo bench --bench pointer`.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use dynaclay::app::PointerTool;
use dynaclay::engine::{EngineConfig, build_clay};
use dynaclay::field::{BSplineLattice, pick_surface};
use dynaclay::io::{ClayShape, ClaySpec};
use dynaclay::mesh::{BrickOctree, SampleGrid};
use dynaclay::render::{Camera, NamedView};
use dynaclay_devices::{PointerFeed, SimArmConfig};
use glam::{Vec2, Vec3};

fn clay() -> BSplineLattice {
    build_clay(&ClaySpec {
        shape: ClayShape::Block,
        resolution: 96,
    })
    .expect("clay")
}

/// A camera framing the block (the middle half of the lattice), as the window frames it.
fn block_camera(field: &BSplineLattice) -> Camera {
    let extent = (field.dims[0] - 1) as f32 * field.spacing;
    Camera::named(
        NamedView::Iso,
        Vec3::splat(0.25 * extent),
        Vec3::splat(0.75 * extent),
    )
}

/// Rays from an oblique camera through a 16 × 16 grid of pixels over the view.
fn rays(field: &BSplineLattice) -> Vec<(Vec3, Vec3)> {
    let mut camera = block_camera(field);
    camera.orbit(0.2, -0.1);
    let size = Vec2::new(1280.0, 800.0);
    let mut out = Vec::new();
    for j in 0..16 {
        for i in 0..16 {
            let px = Vec2::new((i as f32 + 0.5) / 16.0, (j as f32 + 0.5) / 16.0) * size;
            out.push(camera.pointer_ray(px, size));
        }
    }
    out
}

fn pick(c: &mut Criterion) {
    let field = clay();
    let rays = rays(&field);
    let hits = rays
        .iter()
        .filter(|r| pick_surface(&field, r.0, r.1).is_some())
        .count();
    println!("pick/96: {hits} of {} rays hit the clay", rays.len());
    let mut i = 0;
    c.bench_function("pick/96", |b| {
        b.iter(|| {
            let r = rays[i % rays.len()];
            i += 1;
            black_box(pick_surface(&field, r.0, r.1))
        });
    });

    let info = SimArmConfig::default_info();
    let map = EngineConfig::for_field(&field, &info).map;
    let mut tool = PointerTool::new(PointerFeed::new(), map);
    let camera = block_camera(&field);
    let size = Vec2::new(1280.0, 800.0);
    let mut k = 0u32;
    c.bench_function("pointer_frame/96", |b| {
        b.iter(|| {
            k = k.wrapping_add(1);
            let px = Vec2::new(640.0 + (k % 200) as f32, 400.0);
            let ray = camera.pointer_ray(px, size);
            let hit = tool.hover(ray, &field);
            // The brush cursor: the footprint's radius on screen.
            let radius = hit.and_then(|h| {
                let (right, _) = camera.right_up();
                let a = camera.to_screen(h.point, size)?;
                let b = camera.to_screen(h.point + right * 0.25, size)?;
                Some(a.distance(b))
            });
            black_box(radius)
        });
    });

    // The peer: every triangle of the mesh (Möller–Trumbore), same rays.
    let grid = SampleGrid::for_lattice(&field, 2).expect("grid");
    let mesh = BrickOctree::build(grid, &field).weld();
    let tris: Vec<[Vec3; 3]> = mesh
        .triangles
        .iter()
        .map(|t| t.map(|v| mesh.positions[v as usize]))
        .collect();
    println!("pick_mesh_peer/96: {} triangles", tris.len());
    let mut j = 0;
    c.bench_function("pick_mesh_peer/96", |b| {
        b.iter(|| {
            let (o, d) = rays[j % rays.len()];
            j += 1;
            let mut best = f32::INFINITY;
            for [a, b2, c2] in &tris {
                let (e1, e2) = (*b2 - *a, *c2 - *a);
                let p = d.cross(e2);
                let det = e1.dot(p);
                if det.abs() < 1e-12 {
                    continue;
                }
                let inv = 1.0 / det;
                let s = o - *a;
                let u = s.dot(p) * inv;
                if !(0.0..=1.0).contains(&u) {
                    continue;
                }
                let q = s.cross(e1);
                let v = d.dot(q) * inv;
                if v < 0.0 || u + v > 1.0 {
                    continue;
                }
                let t = e2.dot(q) * inv;
                if t > 0.0 && t < best {
                    best = t;
                }
            }
            black_box(best)
        });
    });
}

criterion_group!(benches, pick);
criterion_main!(benches);
