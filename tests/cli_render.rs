//! `dynaclay render` and `dynaclay run --png` end to end: real PNGs of real sessions, the
//! no-adapter path (forced with a backend this platform does not have), and argument errors.
//!
//! Tests that need a GPU adapter print "skipped: no GPU adapter" and pass on a machine without
//! one, unless `DYNACLAY_REQUIRE_GPU=1` (CI), which turns a missing adapter into a failure.

use std::path::Path;
use std::process::{Command, Output};

use dynaclay::field::BSplineLattice;
use dynaclay::io::{Session, save_session};
use dynaclay::render::{Image, gpu_required};
use dynaclay::tools::{Clay, ColourField};
use glam::Vec3;

const BIN: &str = env!("CARGO_BIN_EXE_dynaclay");

/// A wgpu backend that is never compiled in on this platform: asking only for it must find no
/// adapter, whatever the machine has.
const ABSENT_BACKEND: &str = if cfg!(target_os = "macos") {
    "dx12"
} else {
    "metal"
};

/// True (after printing why) when the command reported a missing adapter and this machine is
/// allowed to lack one; panics when an adapter is required.
fn skipped_for_no_adapter(out: &Output) -> bool {
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    if !text.contains("no GPU adapter") {
        return false;
    }
    assert!(!gpu_required(), "a GPU adapter is required: {text}");
    println!("skipped: no GPU adapter ({})", text.trim());
    true
}

/// A session holding a ball of radius 0.6 around (1, 1, 1) whose +x half is painted pure red
/// (full coverage from about x = 1.1).
fn painted_ball_session(path: &Path) {
    let n = 12;
    let mut lattice = BSplineLattice::zeros([n; 3], 0.2, Vec3::ZERO).unwrap();
    let mut colour = ColourField::matching(&lattice).unwrap();
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let p = lattice.node_position(i, j, k);
                let d = (p - Vec3::ONE).length() - 0.6;
                let at = lattice.index(i, j, k);
                lattice.coeffs.set_flat(at, (0.5 - d / 0.6).clamp(0.0, 1.0));
                if p.x > 0.9 {
                    colour.channels[0].coeffs.set_flat(at, 1.0);
                    colour.channels[3].coeffs.set_flat(at, 1.0);
                }
            }
        }
    }
    let session = Session {
        clay: Clay {
            density: dynaclay::field::MultiPatchField::new(lattice),
            colour: Some(colour),
            constraints: Vec::new(),
            mask: None,
        },
        ..Session::default()
    };
    save_session(path, &session).unwrap();
}

/// The number of pixels that differ from the top-left (background) pixel by more than a few
/// levels in some channel.
fn pixels_unlike_background(img: &Image) -> usize {
    let bg = img.pixel(0, 0).unwrap();
    img.rgba8
        .chunks_exact(4)
        .filter(|p| (0..3).any(|c| p[c].abs_diff(bg[c]) > 8))
        .count()
}

/// Mean of red minus green over the clay pixels of the columns `x0..x1`.
fn redness(img: &Image, x0: u32, x1: u32) -> f32 {
    let bg = img.pixel(0, 0).unwrap();
    let (mut sum, mut count) = (0.0, 0);
    for y in 0..img.height {
        for x in x0..x1 {
            let p = img.pixel(x, y).unwrap();
            if (0..3).any(|c| p[c].abs_diff(bg[c]) > 8) {
                sum += f32::from(p[0]) - f32::from(p[1]);
                count += 1;
            }
        }
    }
    assert!(count > 0, "no clay in columns {x0}..{x1}");
    sum / count as f32
}

#[test]
fn render_draws_a_painted_session_at_the_asked_size() {
    let dir = tempfile::tempdir().unwrap();
    let session = dir.path().join("ball.dclay");
    painted_ball_session(&session);
    let png = dir.path().join("ball.png");
    let out = Command::new(BIN)
        .arg("render")
        .arg(&session)
        .arg("--out")
        .arg(&png)
        .args(["--view", "front", "--width", "160", "--height", "120"])
        .output()
        .unwrap();
    if out.status.code() == Some(4) && skipped_for_no_adapter(&out) {
        return;
    }
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("160×120"));

    let img = Image::read_png(&png).unwrap();
    assert_eq!((img.width, img.height), (160, 120));
    // The camera frames the ball's bounding box, so the disk's radius is about half the
    // half-height (60 px): about 16% of the pixels.
    let covered = pixels_unlike_background(&img) as f32 / (160.0 * 120.0);
    assert!((0.12..0.22).contains(&covered), "clay covers {covered}");
    // Seen from the front, +x is on the right: the painted half is red, the rest clay-coloured.
    let (left, right) = (redness(&img, 0, 72), redness(&img, 88, 160));
    assert!(
        right > left + 40.0,
        "red paint not visible: {left} vs {right}"
    );
}

#[test]
fn run_with_png_renders_the_final_sculpt() {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().join("out");
    let out = Command::new(BIN)
        .args(["run", "--seconds", "1", "--no-rt", "--png"])
        .args(["--view", "top", "--width", "128", "--height", "96", "--out"])
        .arg(&out_dir)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for f in ["sculpt.obj", "session.dclay", "latency.json"] {
        assert!(out_dir.join(f).is_file(), "{f} missing");
    }
    if skipped_for_no_adapter(&out) {
        return;
    }
    let img = Image::read_png(&out_dir.join("sculpt.png")).unwrap();
    assert_eq!((img.width, img.height), (128, 96));
    let covered = pixels_unlike_background(&img);
    assert!(
        covered > 128 * 96 / 10 && covered < 128 * 96,
        "{covered} clay pixels"
    );
}

#[test]
fn without_an_adapter_render_exits_4_and_run_still_succeeds() {
    let dir = tempfile::tempdir().unwrap();
    let session = dir.path().join("ball.dclay");
    painted_ball_session(&session);
    let png = dir.path().join("never.png");
    let out = Command::new(BIN)
        .env("WGPU_BACKEND", ABSENT_BACKEND)
        .arg("render")
        .arg(&session)
        .arg("--out")
        .arg(&png)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(4));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("no GPU adapter") && err.contains("skipped rendering"),
        "{err}"
    );
    assert!(err.contains("never.png"), "{err}");
    assert!(!png.exists());

    let out_dir = dir.path().join("out");
    let out = Command::new(BIN)
        .env("WGPU_BACKEND", ABSENT_BACKEND)
        .args(["run", "--seconds", "0.3", "--no-rt", "--out"])
        .arg(&out_dir)
        .arg("--png")
        .arg(&png)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("no GPU adapter") && text.contains("skipped rendering"),
        "{text}"
    );
    assert!(text.contains("never.png"), "{text}");
    assert!(!png.exists());
    for f in ["sculpt.obj", "session.dclay", "latency.json", "latency.svg"] {
        assert!(out_dir.join(f).is_file(), "{f} missing");
    }
}

#[test]
fn bad_views_and_unreadable_sessions_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("x.png");
    let render = |session: &Path, view: &str| {
        Command::new(BIN)
            .arg("render")
            .arg(session)
            .arg("--out")
            .arg(&png)
            .args(["--view", view])
            .output()
            .unwrap()
    };

    let session = dir.path().join("ball.dclay");
    painted_ball_session(&session);
    let out = render(&session, "sideways");
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("sideways") && err.contains("front, back, left, right, top, bottom, iso"),
        "{err}"
    );

    let missing = dir.path().join("missing.dclay");
    let out = render(&missing, "iso");
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("cannot read session") && err.contains("missing.dclay"),
        "{err}"
    );

    let garbage = dir.path().join("garbage.dclay");
    std::fs::write(&garbage, "not a session at all").unwrap();
    let out = render(&garbage, "iso");
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("garbage.dclay") && err.contains("not a dynaclay session"),
        "{err}"
    );
    assert!(!png.exists());
}

#[test]
fn gui_and_render_refuse_a_bad_session_with_the_same_exit_code() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.dclay");
    std::fs::write(&bad, b"not a session at all").unwrap();
    for args in [
        vec!["gui".to_owned(), bad.display().to_string()],
        vec![
            "render".to_owned(),
            bad.display().to_string(),
            "--out".to_owned(),
            dir.path().join("x.png").display().to_string(),
        ],
    ] {
        let run = std::process::Command::new(env!("CARGO_BIN_EXE_dynaclay"))
            .args(&args)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(2), "{args:?}: {err}");
        assert!(
            err.contains("bad.dclay") && err.contains("not a dynaclay session"),
            "{err}"
        );
    }
}
