//! Pointer benchmarks: the GUI thread's work per frame when the mouse is the tool.
//!
//! - `pick_96/*`: one view ray against a 96³ block (the clay `dynaclay gui` starts with, at
//!   four times the resolution): a ray that hits the top face near the middle, one that hits
//!   a side face after crossing a quarter of the support box, and a grazing ray that misses after marching the whole
//!   support box (the worst case).
//! - `pointer_frame_96/*`: the whole pointer path of one frame: the pick, the wait-free
//!   hand-over to the pointer device, and the brush cursor's two projections; hovering and
//!   pressing (the stroke's frozen copy of the clay is taken once per stroke, outside the
//!   loop). Optimistic in that the field is already in cache from the previous iteration, as
//!   it is when the pointer moves a little between frames.

use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use dynaclay::app::PointerTool;
use dynaclay::engine::{WorkspaceMap, build_clay};
use dynaclay::field::{Ray, pick_surface};
use dynaclay::io::{ClayShape, ClaySpec};
use dynaclay::render::{Camera, NamedView};
use dynaclay_devices::pointer::{PointerConfig, pointer_device};
use glam::{Vec2, Vec3};

fn clay_96() -> dynaclay::field::BSplineLattice {
    build_clay(&ClaySpec {
        shape: ClayShape::Block,
        resolution: 96,
        ..ClaySpec::default()
    })
    .expect("the 96³ block fits")
}

fn pick(c: &mut Criterion) {
    let field = clay_96();
    let (lo, hi) = field.support();
    let mid = (lo + hi) * 0.5;
    let top = hi.y;
    let mut group = c.benchmark_group("pick_96");
    group.measurement_time(Duration::from_secs(3));
    let rays = [
        (
            "hit_middle",
            Ray {
                origin: Vec3::new(mid.x, top + 1.0, mid.z),
                direction: Vec3::new(0.05, -1.0, 0.02),
            },
        ),
        (
            "hit_side",
            Ray {
                origin: Vec3::new(lo.x - 0.5, mid.y, mid.z),
                direction: Vec3::new(1.0, 0.02, 0.01),
            },
        ),
        (
            "miss_grazing",
            Ray {
                origin: Vec3::new(lo.x - 0.5, top - 0.01, lo.z - 0.5),
                direction: (hi - lo).with_y(0.0),
            },
        ),
    ];
    for (name, ray) in rays {
        let hit = pick_surface(&dynaclay::field::MultiPatchField::new(field.clone()), ray);
        println!("pick_96/{name}: {:?}", hit.map(|h| h.point));
        group.bench_function(name, |b| {
            let density = dynaclay::field::MultiPatchField::new(field.clone());
            b.iter(|| pick_surface(black_box(&density), ray));
        });
    }
    group.finish();
}

fn pointer_frame(c: &mut Criterion) {
    let field = clay_96();
    let (lo, hi) = (
        field.origin,
        field.node_position(field.dims[0] - 1, field.dims[1] - 1, field.dims[2] - 1),
    );
    let config = PointerConfig::default();
    let map = WorkspaceMap::fitting(config.workspace_min_m, config.workspace_max_m, lo, hi, 30.0);
    let (_device, handle) = pointer_device(config);
    let mut tool = PointerTool::new(handle, map);
    let camera = Camera::named(NamedView::Iso, lo, hi);
    let aspect = 1.6;
    let mut group = c.benchmark_group("pointer_frame_96");
    group.measurement_time(Duration::from_secs(3));
    let density = dynaclay::field::MultiPatchField::new(field.clone());
    let frame = |tool: &mut PointerTool, pressing: bool, i: u32| {
        // The pointer wanders a few pixels around the middle of the view.
        let ndc = Vec2::new(0.01 * (i % 7) as f32, 0.01 * (i % 5) as f32);
        let pose = tool.aim(&density, &camera, ndc, aspect, pressing, 1.0);
        // The brush cursor: the surface point and its rim, projected to the screen.
        let vp = camera.view_projection(aspect);
        let (right, _) = camera.right_up();
        black_box((
            vp.project_point3(pose.surface),
            vp.project_point3(pose.surface + right * 0.25),
        ))
    };
    let on_clay = frame(&mut tool, false, 0);
    println!(
        "pointer_frame_96: tip on the clay: {:?}",
        tool.pose.map(|p| p.on_clay)
    );
    black_box(on_clay);
    let mut i = 0;
    group.bench_function("hover", |b| {
        b.iter(|| {
            i += 1;
            frame(&mut tool, false, i)
        })
    });
    frame(&mut tool, true, 0);
    group.bench_function("press", |b| {
        b.iter(|| {
            i += 1;
            frame(&mut tool, true, i)
        })
    });
    group.finish();
}

criterion_group!(benches, pick, pointer_frame);
criterion_main!(benches);
