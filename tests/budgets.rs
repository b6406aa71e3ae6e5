//! One budget for the whole clay, from the command line: patches (at most 256), coefficients
//! and pins are counted before the work starts, whether they come from a script's steps, an
//! import's detail or a session file, and going over exits 2 naming the step or the file.

use std::path::Path;

use dynaclay::field::{BSplineLattice, MAX_PATCHES};
use glam::{Affine3A, Vec3};

#[path = "support/cli.rs"]
mod cli;

use cli::{dynaclay, refused, save_clay, stderr, zero_clay};

/// A script of the default block with `count` copies of `step` (TOML keys after `do`).
fn script_of(dir: &Path, step: &str, count: usize) {
    let mut text =
        String::from("version = 1\nseconds = 0.1\n\n[clay]\nshape = \"block\"\nresolution = 24\n");
    for _ in 0..count {
        text += &format!("\n[[step]]\n{step}\n");
    }
    std::fs::write(dir.join("s.toml"), text).unwrap();
}

#[test]
fn refine_steps_past_the_patch_budget_are_refused_before_the_run() {
    let dir = tempfile::tempdir().unwrap();
    // The hostile case: 300 refines at level 3 over a 24³ clay.
    script_of(
        dir.path(),
        "do = \"refine\"\nmin = [0.6, 0.6, 0.6]\nmax = [1.7, 1.7, 1.7]\nlevel = 3",
        300,
    );
    let out = dynaclay(
        dir.path(),
        &["run", "--script", "s.toml", "--lockstep", "--out", "run"],
    );
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("s.toml") && err.contains("refine"), "{err}");
    assert!(
        err.contains("coefficients") || err.contains("patches"),
        "{err}"
    );
    assert!(!dir.path().join("run").exists(), "the run started");
    // Small refines past the patch count, too.
    script_of(
        dir.path(),
        "do = \"refine\"\nmin = [1.0, 1.0, 1.0]\nmax = [1.1, 1.1, 1.1]\nlevel = 1",
        MAX_PATCHES,
    );
    let out = dynaclay(
        dir.path(),
        &["run", "--script", "s.toml", "--lockstep", "--out", "run"],
    );
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("257 patches") && err.contains(&format!("step {}", MAX_PATCHES)),
        "{err}"
    );
}

#[test]
fn constrain_steps_past_the_pin_budget_are_refused_before_the_run() {
    let dir = tempfile::tempdir().unwrap();
    script_of(
        dir.path(),
        "do = \"constrain\"\nkind = \"point\"\nat = [1.15, 1.73, 1.15]",
        4097,
    );
    let out = dynaclay(
        dir.path(),
        &["run", "--script", "s.toml", "--lockstep", "--out", "run"],
    );
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("4097") && err.contains("4096 pins"), "{err}");
    assert!(!dir.path().join("run").exists(), "the run started");
}

/// A session of a 12³ base and `details` 4³ patches (each with `map`).
fn session_with(path: &Path, details: usize, spacing: f32, map: Affine3A) {
    let mut clay = zero_clay([12; 3]);
    for _ in 0..details {
        let mut l = BSplineLattice::zeros([4; 3], 0.1, Vec3::splat(0.3)).unwrap();
        l.spacing = spacing;
        clay.density.push(l, map);
    }
    save_clay(path, clay);
}

#[test]
fn a_session_past_the_budget_or_with_a_wild_patch_is_refused_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    for (name, details, spacing, map, want) in [
        (
            "many.dclay",
            10_000,
            0.1,
            Affine3A::IDENTITY,
            "more than 256 patches",
        ),
        (
            "spacing.dclay",
            1,
            f32::INFINITY,
            Affine3A::IDENTITY,
            "spacing inf",
        ),
        (
            "scaled.dclay",
            1,
            0.1,
            Affine3A::from_scale(Vec3::splat(1e4)),
            "scales by",
        ),
    ] {
        session_with(&dir.path().join(name), details, spacing, map);
        let out = dynaclay(dir.path(), &["render", name, "--out", "x.png"]);
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(2), "{name}: {err}");
        assert!(err.contains(name) && err.contains(want), "{name}: {err}");
        assert!(!dir.path().join("x.png").exists());
    }
    // Exactly at the budget it reads.
    session_with(
        &dir.path().join("full.dclay"),
        MAX_PATCHES - 1,
        0.1,
        Affine3A::IDENTITY,
    );
    let read = dynaclay::io::load_session(&dir.path().join("full.dclay")).unwrap();
    assert_eq!(read.clay.density.patches.len(), MAX_PATCHES);
}

#[test]
fn an_import_asking_for_endless_detail_stays_within_the_patch_budget_and_says_so() {
    let dir = tempfile::tempdir().unwrap();
    // A bumpy sphere of 6000 points, which no error bound of 1e-7 % is met on. The cloud is
    // clean, but its bumps are sampled sparsely enough that the estimate takes them for 0.13%
    // of noise (and would raise the bound to it), so the command says it is clean.
    let mut text = String::new();
    for i in 0..6000 {
        let y = 1.0 - 2.0 * (i as f32 + 0.5) / 6000.0;
        let r = (1.0 - y * y).sqrt();
        let phi = i as f32 * 2.399_963;
        let bump = 1.0 + 0.05 * (7.0 * phi).sin() * (5.0 * y).cos();
        let p = Vec3::new(r * phi.cos(), y, r * phi.sin()) * bump;
        text += &format!("{} {} {}\n", p.x, p.y, p.z);
    }
    std::fs::write(dir.path().join("bumpy.xyz"), text).unwrap();
    let out = dynaclay(
        dir.path(),
        &[
            "import",
            "bumpy.xyz",
            "--out",
            "b.dclay",
            "--resolution",
            "16",
            "--error",
            "1e-7",
            "--max-depth",
            "4",
            "--noise",
            "0",
        ],
    );
    let said = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(said.contains("the clay's budget"), "{said}");
    let session = dynaclay::io::load_session(&dir.path().join("b.dclay")).unwrap();
    let patches = session.clay.density.patches.len();
    println!("{patches} patches");
    assert!(patches <= MAX_PATCHES && patches > 100, "{patches}");
}

/// A script's `add` far past the clay: growth is symmetric about the lattice's centre, so a
/// lump 90 field units out on every axis asks for a base of about 1 800³ coefficients, past
/// the box budget of 1 Gi. The step fails naming the script, the step and the budget; the run
/// still writes the sculpt, with the clay in its box (the lump clipped away), and a lump 30
/// out on one axis grows the clay as before.
#[test]
fn a_tool_step_past_the_box_budget_fails_naming_it_and_the_sculpt_is_kept() {
    let dir = tempfile::tempdir().unwrap();
    let script = |at: &str| {
        format!(
            "version = 1\nseconds = 0.3\n\n[clay]\nshape = \"sphere\"\nresolution = 24\n\n\
             [[step]]\ndo = \"tool\"\nshape = {{ kind = \"sphere\", radius_fu = 0.3 }}\n\
             action = {{ kind = \"add\", deposit_rate_per_s = 4.0 }}\npositions = [{at}]\n\
             duration_s = 0.2\n"
        )
    };
    std::fs::write(dir.path().join("far.toml"), script("[90.0, 90.0, 90.0]")).unwrap();
    let out = dynaclay(
        dir.path(),
        &[
            "run",
            "--script",
            "far.toml",
            "--lockstep",
            "--no-rt",
            "--out",
            "far",
        ],
    );
    let err = refused(
        &out,
        &[
            "far.toml",
            "step 1",
            "clipped to the clay's box",
            "1073741824",
        ],
    );
    assert!(
        err.contains("growing the clay to [1800, 1800, 1800]"),
        "{err}"
    );
    let max_x = largest_x(&dir.path().join("far/sculpt.obj"));
    assert!(
        max_x > 1.0 && max_x < 2.4,
        "the clay stays in its box: {max_x}"
    );

    std::fs::write(dir.path().join("near.toml"), script("[30.0, 1.15, 1.15]")).unwrap();
    let out = dynaclay(
        dir.path(),
        &[
            "run",
            "--script",
            "near.toml",
            "--lockstep",
            "--no-rt",
            "--out",
            "near",
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let max_x = largest_x(&dir.path().join("near/sculpt.obj"));
    assert!(max_x > 30.0, "the lump 30 out is there: {max_x}");
}

/// The largest x of the vertices of the OBJ file at `path` (which must exist).
fn largest_x(path: &Path) -> f32 {
    let obj = std::fs::read_to_string(path).expect("the sculpt is written");
    obj.lines()
        .filter_map(|l| l.strip_prefix("v "))
        .filter_map(|v| v.split_whitespace().next()?.parse::<f32>().ok())
        .fold(f32::MIN, f32::max)
}

/// A pull stroke whose spread (30 field units on a clay 2.3 across) reaches about 600
/// coefficients each way: the clay could grow to take it (its box would fit the box budget),
/// but the stroke's simulated region would make some 427 000 bricks dense, past the real
/// budget of 151 259 (768 MiB). The region is refused before the clay grows for it and before
/// anything is allocated for it, the run goes on and writes the sculpt as it was, and stderr
/// says what was refused and why (a headless run has no window to show it in).
#[test]
fn a_stroke_whose_region_would_pass_the_dense_budget_is_refused_and_said_and_the_sculpt_is_kept() {
    let dir = tempfile::tempdir().unwrap();
    // Runs the pull stroke of spread `radius_fu` as script `name`.toml into folder `name`.
    let pull = |name: &str, radius_fu: f32| {
        let script = format!(
            "version = 1\nseconds = 1.5\n\n[clay]\nshape = \"sphere\"\nresolution = 24\n\n\
             [[step]]\ndo = \"stroke\"\n\
             tool = {{ kind = \"pull\", beta = \"gaussian\", radius_fu = {radius_fu}, gain = 2e6 }}\n\
             path = [[1.72, 1.15, 1.15], [2.0, 1.15, 1.15]]\nduration_s = 1.0\nhover_fu = 0.05\n"
        );
        let file = format!("{name}.toml");
        std::fs::write(dir.path().join(&file), script).unwrap();
        let out = dynaclay(
            dir.path(),
            &[
                "run",
                "--script",
                &file,
                "--lockstep",
                "--no-rt",
                "--out",
                name,
            ],
        );
        let err = stderr(&out);
        assert!(out.status.success(), "{err}");
        (err, largest_x(&dir.path().join(name).join("sculpt.obj")))
    };
    let (err, max_x) = pull("wide", 30.0);
    for needle in [
        "the clay's budgets refused",
        "more bricks dense",
        "at most 151259 dense bricks (768 MiB)",
        "nothing changed",
    ] {
        assert!(err.contains(needle), "{needle}: {err}");
    }
    assert!(max_x < 1.8, "the sphere is as it was: {max_x}");
    // Refused before the clay grew for it: the saved clay keeps its starting box.
    let saved = dynaclay::io::load_session(&dir.path().join("wide/session.dclay")).unwrap();
    let dims = saved.clay.base().dims;
    assert!(dims.iter().all(|&n| n <= 32), "the clay's box: {dims:?}");
    // The same stroke with a spread its region can hold pulls the clay out, and says nothing.
    let (err, max_x) = pull("narrow", 0.3);
    assert!(!err.contains("budgets"), "{err}");
    assert!(max_x > 1.8, "the pull drew the clay out: {max_x}");
}
