//! Nothing destructive by surprise: a step that would remove more than half the clay's volume
//! waits for the user's yes in the window (the engine in its `Ask` mode, as `dynaclay gui`
//! starts it: a stroke's applications are withheld, a CSG is refused, and nothing changes
//! until the answer), is reported by scripts (a warning line on stderr naming the file, line
//! and step), and an intersection is a CSG with another clay, never a brush. Volumes are
//! measured on exported meshes of lockstep runs.

#[path = "support/window_stroke.rs"]
mod window_stroke;

use std::process::Command as Process;

use crossbeam::channel::bounded;
use dynaclay::app::{ActionKind, PaletteEntry, ToolPalette};
use dynaclay::engine::{Command, CommandError, EngineConfig, RemovalGuard};
use dynaclay::field::{Primitive, lattice_from_primitive};
use dynaclay::tools::{Clay, ToolAction};
use glam::Vec3;
use window_stroke::{Stroke, config_for, default_clay, device_samples, export, lockstep};

const BIN: &str = env!("CARGO_BIN_EXE_dynaclay");
const TOP: f32 = 1.725;

fn ask_config(field: &dynaclay::field::BSplineLattice) -> EngineConfig {
    let mut config = config_for(field);
    config.sim.removal_guard = RemovalGuard::Ask;
    config
}

/// The exported mesh's volume of `clay`.
fn mesh_volume(clay: &Clay) -> f32 {
    let dir = tempfile::tempdir().unwrap();
    export(clay, dir.path(), "clay.obj").volume()
}

#[test]
fn a_stroke_that_would_remove_most_of_the_clay_waits_for_the_users_yes() {
    let field = default_clay();
    let config = ask_config(&field);
    // The largest remove brush the window offers, dragged across the top.
    let palette = ToolPalette {
        selected: PaletteEntry::Geometric(ActionKind::Remove),
        radius_fu: 1.0,
        ..ToolPalette::default()
    };
    let stroke = Stroke::one_second(Vec3::new(0.9, TOP, 1.15), Vec3::new(1.4, TOP, 1.15));
    let one = device_samples(&field, &config, &stroke);
    let n = one.len();
    let mut run = lockstep(&field, &config, one.repeat(2));
    run.commands()
        .send(Command::SetTool(palette.choice()))
        .unwrap();
    let start = mesh_volume(&Clay::single(field.clone()));
    for _ in 0..n {
        run.step();
    }
    let question = run.sim().removal_question().expect("the stroke was held");
    assert!(question.stroke && question.what == "remove" && question.percent > 50.0);
    let held = mesh_volume(run.sim().clay());
    println!("volume {start:.4} → {held:.4} while held ({question:?})");
    assert!(
        (held - start).abs() <= 0.01 * start,
        "the held stroke removed {start} → {held}"
    );
    // The user says yes: the next stroke goes ahead.
    run.commands().send(Command::AnswerRemoval(true)).unwrap();
    for _ in 0..n {
        run.step();
    }
    assert_eq!(run.sim().removal_question(), None);
    let after = mesh_volume(run.sim().clay());
    println!("volume {start:.4} → {after:.4} after the yes");
    assert!(after < 0.5 * start, "{start} → {after}");
}

#[test]
fn a_small_stroke_is_not_asked_about() {
    let field = default_clay();
    let config = ask_config(&field);
    let palette = ToolPalette {
        selected: PaletteEntry::Geometric(ActionKind::Remove),
        ..ToolPalette::default()
    };
    let stroke = Stroke::one_second(Vec3::new(0.9, TOP, 1.15), Vec3::new(1.4, TOP, 1.15));
    let samples = device_samples(&field, &config, &stroke);
    let n = samples.len();
    let mut run = lockstep(&field, &config, samples);
    run.commands()
        .send(Command::SetTool(palette.choice()))
        .unwrap();
    for _ in 0..n {
        run.step();
    }
    assert_eq!(run.sim().removal_question(), None);
    let (start, after) = (
        mesh_volume(&Clay::single(field)),
        mesh_volume(run.sim().clay()),
    );
    assert!(
        after < 0.97 * start && after > 0.5 * start,
        "{start} → {after}"
    );
}

#[test]
fn an_intersection_that_would_remove_most_waits_unapplied_for_the_answer() {
    let field = default_clay();
    let config = ask_config(&field);
    // A ball at one corner of the block: the intersection keeps only the corner.
    let ball = Primitive::Sphere {
        centre: Vec3::splat(0.8),
        radius: 0.3,
    };
    let other = Clay::single(
        lattice_from_primitive(field.dims, field.spacing, field.origin, &ball, 0.2, 2).unwrap(),
    );
    // The hand hovers far above the clay.
    let hover = (config.map.to_device(Vec3::new(1.15, 2.2, 1.15)), false);
    let mut run = lockstep(&field, &config, vec![hover]);
    let start = mesh_volume(&Clay::single(field.clone()));
    let csg = |reply| Command::Csg {
        op: ToolAction::Intersection,
        other: Box::new(other.clone()),
        patch: 0,
        reply: Some(reply),
    };
    let (tx, rx) = bounded(1);
    run.commands().send(csg(tx)).unwrap();
    for _ in 0..3 {
        run.step();
    }
    let question = run.sim().removal_question().expect("asked");
    assert!(!question.stroke && question.what == "intersection" && question.percent > 90.0);
    assert!(rx.try_recv().is_err(), "no answer before the user's");
    assert!((mesh_volume(run.sim().clay()) - start).abs() <= 1e-3 * start);
    assert_eq!(run.sim().undo_len(), 0, "nothing was recorded");

    // Yes: the held step is applied.
    run.commands().send(Command::AnswerRemoval(true)).unwrap();
    run.step();
    let outcome = rx.try_recv().unwrap().expect("applied after the yes");
    assert!(outcome.removed_fraction > 0.9, "{outcome:?}");
    assert_eq!(run.sim().removal_question(), None);
    let after = mesh_volume(run.sim().clay());
    println!("intersection: volume {start:.4} → {after:.4}");
    assert!(after > 0.0 && after < 0.1 * start, "{start} → {after}");

    // The yes was spent: the same step again is held again, and a no refuses it.
    run.commands().send(Command::Undo).unwrap();
    let (tx, rx) = bounded(1);
    run.commands().send(csg(tx)).unwrap();
    run.step();
    assert!(run.sim().removal_question().is_some());
    run.commands().send(Command::AnswerRemoval(false)).unwrap();
    run.step();
    assert!(matches!(
        rx.try_recv().unwrap(),
        Err(CommandError::WouldRemoveMost { .. })
    ));
    assert_eq!(run.sim().removal_question(), None);
    assert!((mesh_volume(run.sim().clay()) - start).abs() <= 1e-3 * start);
}

/// Runs `dynaclay run --lockstep` on `script`; (exit code, stderr).
fn run_script(script: &str) -> (Option<i32>, String) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("carve.toml");
    std::fs::write(&path, script).unwrap();
    let out = Process::new(BIN)
        .args(["run", "--lockstep", "--script"])
        .arg(&path)
        .arg("--out")
        .arg(dir.path().join("out"))
        .output()
        .unwrap();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into(),
    )
}

#[test]
fn a_script_warns_of_each_step_that_removed_more_than_half_the_clay() {
    let script = "version = 1\nseconds = 4\n\n\
        [[step]]\n\
        do = \"tool\"\n\
        shape = { kind = \"sphere\", radius_fu = 0.2 }\n\
        action = { kind = \"remove\" }\n\
        positions = [[1.15, 1.725, 1.15]]\n\n\
        [[step]]\n\
        do = \"stroke\"\n\
        shape = { kind = \"sphere\", radius_fu = 0.9 }\n\
        action = { kind = \"remove\" }\n\
        path = [[0.9, 1.725, 1.15], [1.4, 1.725, 1.15]]\n\n\
        [[step]]\n\
        do = \"tool\"\n\
        shape = { kind = \"sphere\", radius_fu = 1.0 }\n\
        action = { kind = \"remove\" }\n\
        positions = [[1.15, 1.15, 1.15]]\n";
    let (code, err) = run_script(script);
    println!("{err}");
    assert_eq!(code, Some(0), "{err}");
    let warnings: Vec<&str> = err.lines().filter(|l| l.contains("warning:")).collect();
    // The small cut (step 1) is not reported; the stroke (step 2, line 10) and the last tool
    // step (step 3, line 16; it takes what the stroke left) are.
    assert!(
        warnings
            .iter()
            .any(|l| l.contains("carve.toml:10: step 2: the remove stroke removed about")),
        "{err}"
    );
    assert!(
        warnings
            .iter()
            .any(|l| l.contains("carve.toml:16: step 3: this step removed about")),
        "{err}"
    );
    assert!(!err.contains("step 1:"), "{err}");
}

#[test]
fn a_script_using_intersection_as_a_brush_is_told_to_use_a_csg_step() {
    for step in [
        "do = \"tool\"\nshape = { kind = \"sphere\", radius_fu = 0.2 }\n\
         action = { kind = \"intersection\" }\npositions = [[1.15, 1.15, 1.15]]\n",
        "do = \"stroke\"\nshape = { kind = \"sphere\", radius_fu = 0.2 }\n\
         action = { kind = \"intersection\" }\npath = [[1.15, 1.725, 1.15]]\n",
    ] {
        let (code, err) = run_script(&format!("version = 1\n\n[[step]]\n{step}"));
        assert_eq!(code, Some(2), "{err}");
        assert!(
            err.contains("carve.toml:6: step 1: action: intersection is a CSG operation")
                && err.contains("use a `csg` step"),
            "{err}"
        );
    }
}
