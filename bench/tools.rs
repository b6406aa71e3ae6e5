//! Tool, undo and session benchmarks.
//!
//! - `tool_apply/{small,medium,large}`: one application of a sphere tool (add) on a 128³ clay,
//!   as in Ferley et al.'s table; the visited/computed/dirtied counts and the refitted box are
//!   printed once per size. Compared in the same run with `csg_union_box`, the same edit done
//!   as a whole-box CSG (tool potential evaluated at every sample, no local-box rejection).
//! - `undo_redo_256/*`: undo + redo of a tool step and of a whole-lattice step on a 256³ clay,
//!   against restoring a full copy of the lattice (the snapshot alternative).
//! - `session_256/*`: atomic save and validated load of a 256³ session, against a bare
//!   `std::fs::write` / `std::fs::read` of the same bytes (the I/O floor).

use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use dynaclay::field::{BSplineLattice, Primitive, fit_primitive};
use dynaclay::io::{Session, encode, load_session, save_session};
use dynaclay::tools::{
    ApplyOptions, Clay, FieldId, GeometricTool, History, StepRecorder, ToolAction, ToolPose,
    ToolShape, apply_tool,
};
use glam::Vec3;

fn sculpt(n: usize) -> Clay {
    let h = 1.0 / 64.0;
    let mut l = BSplineLattice::zeros([n; 3], h, Vec3::ZERO).unwrap();
    let c = Vec3::splat(0.5 * (n - 1) as f32 * h);
    let s = Primitive::Sphere {
        centre: c,
        radius: 0.3 * n as f32 * h,
    };
    fit_primitive(&mut l, &s, 2.0 * h, 1).unwrap();
    Clay::single(l)
}

fn tool_apply(c: &mut Criterion) {
    let clay = sculpt(128);
    let h = clay.density.patches[0].lattice.spacing;
    let centre = Vec3::splat(63.5 * h) + Vec3::X * (0.3 * 128.0 * h);
    let mut group = c.benchmark_group("tool_apply");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(3));
    for (name, radius_spans) in [("small", 2.0), ("medium", 6.0), ("large", 16.0)] {
        let tool = GeometricTool {
            shape: ToolShape::Sphere {
                radius_fu: radius_spans * h,
            },
            action: ToolAction::Add {
                deposit_rate_per_s: 1.0,
            },
            falloff_fu: 2.0 * h,
        };
        let pose = ToolPose::at(centre);
        let mut probe = clay.clone();
        let r = apply_tool(
            &mut probe,
            &tool,
            &pose,
            1.0,
            &ApplyOptions::default(),
            None,
        )
        .unwrap();
        let b = r.coeff_box.unwrap();
        eprintln!(
            "tool_apply/{name}: radius {radius_spans} spans, coefficients refitted {} ({:?}), samples visited {}, computed {}, dirtied {}",
            b.count(),
            b.dims(),
            r.visited,
            r.computed,
            r.dirtied
        );
        group.bench_function(name, |bench| {
            let mut work = clay.clone();
            bench.iter(|| {
                apply_tool(&mut work, &tool, &pose, 1.0, &ApplyOptions::default(), None).unwrap()
            });
        });
        let union = GeometricTool {
            action: ToolAction::Union,
            shape: ToolShape::Box {
                half_extents_fu: Vec3::splat(radius_spans * h),
            },
            ..tool.clone()
        };
        group.bench_function(format!("{name}_csg_union_box"), |bench| {
            let mut work = clay.clone();
            bench.iter(|| {
                apply_tool(
                    &mut work,
                    &union,
                    &pose,
                    1.0,
                    &ApplyOptions::default(),
                    None,
                )
                .unwrap()
            });
        });
    }
    group.finish();
}

fn undo_redo(c: &mut Criterion) {
    let mut clay = sculpt(256);
    let h = clay.density.patches[0].lattice.spacing;
    let mut history = History::default();
    let tool = GeometricTool {
        shape: ToolShape::Sphere {
            radius_fu: 16.0 * h,
        },
        action: ToolAction::Remove,
        falloff_fu: 2.0 * h,
    };
    let mut rec = StepRecorder::new("remove");
    let pose = ToolPose::at(Vec3::splat(127.5 * h) + Vec3::X * (0.3 * 256.0 * h));
    apply_tool(
        &mut clay,
        &tool,
        &pose,
        1.0,
        &ApplyOptions::default(),
        Some(&mut rec),
    )
    .unwrap();
    history.commit(rec, &clay);
    eprintln!(
        "undo_redo_256/tool_step: {} coefficients in the step",
        history_step_size(&history)
    );

    let mut group = c.benchmark_group("undo_redo_256");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(3));
    group.bench_function("tool_step", |bench| {
        bench.iter(|| {
            history.undo(&mut clay).unwrap();
            history.redo(&mut clay).unwrap();
        });
    });
    // A step that changed every coefficient.
    let mut whole = History::default();
    let mut rec = StepRecorder::new("everything");
    rec.touch_all(&clay);
    clay.density.patches[0].lattice.coeffs.update_each(|_, v| {
        *v = 1.0 - *v;
    });
    whole.commit(rec, &clay);
    group.bench_function("whole_lattice_step", |bench| {
        bench.iter(|| {
            whole.undo(&mut clay).unwrap();
            whole.redo(&mut clay).unwrap();
        });
    });
    let snapshot = clay.density.patches[0].lattice.coeffs.clone();
    group.bench_function("restore_full_copy_twice", |bench| {
        bench.iter(|| {
            clay.density.patches[0]
                .lattice
                .coeffs
                .clone_from(black_box(&snapshot));
            clay.density.patches[0]
                .lattice
                .coeffs
                .clone_from(black_box(&snapshot));
        });
    });
    let _ = FieldId::Density(0);
    group.finish();
}

fn history_step_size(history: &History) -> usize {
    history.used_bytes() / 4
}

fn session_io(c: &mut Criterion) {
    let session = Session {
        clay: sculpt(256),
        ..Session::default()
    };
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.dclay");
    let raw = dir.path().join("raw.bin");
    let bytes = encode(&session).unwrap();
    eprintln!("session_256: {} bytes", bytes.len());
    let mut group = c.benchmark_group("session_256");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(5));
    group.bench_function("save_atomic", |bench| {
        bench.iter(|| save_session(&path, &session).unwrap());
    });
    group.bench_function("load_validated", |bench| {
        bench.iter(|| black_box(load_session(&path).unwrap()));
    });
    group.bench_function("std_fs_write_same_bytes", |bench| {
        bench.iter(|| std::fs::write(&raw, &bytes).unwrap());
    });
    group.bench_function("std_fs_read_same_bytes", |bench| {
        bench.iter(|| black_box(std::fs::read(&raw).unwrap()));
    });
    group.finish();
}

criterion_group!(benches, tool_apply, undo_redo, session_io);
criterion_main!(benches);
