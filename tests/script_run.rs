//! A scripted headless run through the lockstep engine (deterministic): a geometric tool step,
//! a contact push, a pull with a force tool and a live geometric stroke, with undo/redo and
//! saves between them; autosave writes the recovery file during the run.

use std::path::Path;

use dynaclay::engine::ScriptDriver;
use dynaclay::field::MultiPatchField;
use dynaclay::io::{Autosave, find_recovery, load_session};
use glam::Vec3;

#[path = "support/lockstep.rs"]
mod lockstep;

use lockstep::{Scripted, scripted};

/// The default block (resolution 24) spans [0.575, 1.725] on each axis.
const SCRIPT: &str = r#"
version = 1

[clay]
shape = "block"
resolution = 24

[autosave]
every_s = 0.0
every_strokes = 1

[[step]]
do = "save"
path = "s0.dclay"

[[step]]
do = "tool"
shape = { kind = "sphere", radius_fu = 0.2 }
action = { kind = "add", deposit_rate_per_s = 10.0 }
positions = [[1.15, 1.95, 1.15]]
duration_s = 1.0
falloff_fu = 0.1

[[step]]
do = "save"
path = "s1.dclay"

[[step]]
do = "stroke"
path = [[0.8, 1.55, 0.8], [1.1, 1.55, 0.8]]
duration_s = 1.0
hover_fu = 0.3

[[step]]
do = "save"
path = "s2.dclay"

[[step]]
do = "undo"

[[step]]
do = "save"
path = "s3.dclay"

[[step]]
do = "stroke"
tool = { kind = "pull", beta = "gaussian", radius_fu = 0.15, gain = 2e6 }
path = [[1.45, 1.7, 1.45], [1.45, 1.9, 1.45]]
duration_s = 0.6
hover_fu = 0.2

[[step]]
do = "save"
path = "s4.dclay"

[[step]]
do = "stroke"
shape = { kind = "sphere", radius_fu = 0.12 }
action = { kind = "remove" }
falloff_fu = 0.1
path = [[0.8, 1.72, 1.45], [1.2, 1.72, 1.45]]
duration_s = 0.4
hover_fu = 0.3

[[step]]
do = "save"
path = "s5.dclay"

[[step]]
do = "undo"
count = 2

[[step]]
do = "save"
path = "s6.dclay"

[[step]]
do = "redo"
count = 2

[[step]]
do = "save"
path = "s7.dclay"
"#;

/// Every coefficient of the clay's patches, as bits; a detail patch that holds only zeros (one
/// a fine stroke added under itself, then undone: the room stays) contributes nothing.
fn bits(f: &MultiPatchField) -> Vec<u32> {
    f.patches
        .iter()
        .filter(|p| p.lattice.coeffs.iter().any(|&c| c != 0.0))
        .flat_map(|p| p.lattice.coeffs.iter().map(|c| c.to_bits()))
        .collect()
}

/// Volume inside the iso-surface over the lattice's box, by point sampling at `h`.
fn volume(l: &MultiPatchField, h: f32) -> f32 {
    let n = (2.3 / h) as usize;
    let mut inside = 0usize;
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let x = (Vec3::new(i as f32, j as f32, k as f32) + 0.5) * h;
                if l.is_inside(x) {
                    inside += 1;
                }
            }
        }
    }
    inside as f32 * h * h * h
}

/// The whole clay a save wrote: the base and the detail patches fine strokes added.
fn load(dir: &Path, name: &str) -> MultiPatchField {
    load_session(&dir.join(name))
        .unwrap_or_else(|e| panic!("{name}: {e}"))
        .clay
        .density
}

#[test]
fn a_scripted_run_sculpts_pushes_pulls_and_undoes_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let Scripted {
        script,
        plan,
        mut run,
    } = scripted(SCRIPT, "run.toml", dir.path());
    let session_path = dir.path().join("session.dclay");
    run.set_autosave(Autosave::new(
        &session_path,
        script.autosave.unwrap().into(),
        std::time::Instant::now(),
    ));
    let mut driver = ScriptDriver::new(&plan);
    let commands = run.commands();
    let ticks = (plan.seconds * 1000.0) as usize;
    for _ in 0..ticks {
        let sample = run.latest_tool();
        driver.dispatch(&sample, &commands);
        run.step();
    }
    assert!(driver.is_done(), "steps left: {:?}", driver.unsent_steps());
    let report = run.finish().unwrap();
    assert!(driver.failures().is_empty(), "{:?}", driver.failures());
    assert_eq!(report.io.saves, 8, "{:?}", report.io);

    let s: Vec<MultiPatchField> = (0..8)
        .map(|i| load(dir.path(), &format!("s{i}.dclay")))
        .collect();
    let iso = s[0].iso();

    // The tool step added a ball of about its volume above the block.
    let ball = Vec3::new(1.15, 1.95, 1.15);
    assert!(s[0].value(ball) < iso && s[1].value(ball) > iso);
    let grown = volume(&s[1], 0.025) - volume(&s[0], 0.025);
    let expected = 4.0 / 3.0 * std::f32::consts::PI * 0.2f32.powi(3);
    assert!(
        (grown - expected).abs() < 0.3 * expected,
        "grew {grown}, ball {expected}"
    );

    // The push dented the top along its path (at 1.55, 0.175 under the top; the effector
    // stops short of the hand where the forces balance), and nowhere far away.
    let mid = Vec3::new(0.95, 1.6, 0.8);
    assert!(s[1].value(mid) > iso && s[2].value(mid) < iso, "no dent");
    let far = Vec3::new(1.3, 0.8, 1.3);
    assert!((s[2].value(far) - s[1].value(far)).abs() < 1e-4);

    // Undo restores the state before the push bit for bit.
    assert_eq!(bits(&s[3]), bits(&s[1]), "undo of the push");

    // The pull raised the clay above where it grabbed.
    let above = Vec3::new(1.45, 1.78, 1.45);
    assert!(
        s[4].value(above) > s[3].value(above) + 0.01,
        "pull: {} → {}",
        s[3].value(above),
        s[4].value(above)
    );

    // The live remove stroke cut a groove under its path.
    let groove = Vec3::new(1.0, 1.66, 1.45);
    assert!(
        s[4].value(groove) > iso && s[5].value(groove) < iso,
        "no groove"
    );

    // Two undos give back the state before the pull; two redos the state after the groove.
    assert_eq!(bits(&s[6]), bits(&s[3]), "undo of groove and pull");
    assert_eq!(bits(&s[7]), bits(&s[5]), "redo of pull and groove");
    assert_eq!(bits(&report.session.clay.density), bits(&s[7]));
    assert!(
        report.session.clay.density.patches.iter().all(|p| p
            .lattice
            .coeffs
            .iter()
            .all(|c| c.is_finite()))
    );

    // Autosave (every stroke) wrote the recovery file during the run; it loads.
    assert!(report.io.autosaves >= 1, "{:?}", report.io);
    let found = find_recovery(&session_path).expect("recovery file offered");
    assert!(load_session(&found.path).is_ok());
}
