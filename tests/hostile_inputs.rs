//! Bad input from the command line, as a hostile user gave it: a cloud without extent, a
//! pull or an offset far past the clay, a session with no patch or a lattice no mesher can
//! hold. Each is an input error (exit 2) that names the file or the flag, said before the
//! work, and writes nothing.

use std::path::Path;

use glam::Vec3;

#[path = "support/cli.rs"]
mod cli;

use cli::{dynaclay, refused as input_error, save_clay, zero_clay};

/// A Fibonacci sphere of `n` points and radius 1 as XYZ text.
fn sphere_xyz(path: &Path, n: usize) {
    let mut text = String::new();
    for i in 0..n {
        let y = 1.0 - 2.0 * (i as f32 + 0.5) / n as f32;
        let r = (1.0 - y * y).sqrt();
        let phi = i as f32 * 2.399_963;
        text += &format!("{} {y} {}\n", r * phi.cos(), r * phi.sin());
    }
    std::fs::write(path, text).unwrap();
}

#[test]
fn a_cloud_without_extent_is_an_input_error_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("one.xyz"), "1 2 3\n").unwrap();
    std::fs::write(dir.path().join("same.xyz"), "1 2 3\n".repeat(10_000)).unwrap();
    for name in ["one.xyz", "same.xyz"] {
        let out = dynaclay(dir.path(), &["import", name, "--out", "o.dclay"]);
        input_error(&out, &[name, "one place"]);
        assert!(!dir.path().join("o.dclay").exists());
    }
}

#[test]
fn a_pull_or_an_offset_far_past_the_clay_is_refused_before_the_work() {
    let dir = tempfile::tempdir().unwrap();
    sphere_xyz(&dir.path().join("s.xyz"), 1000);
    for pull in ["--pull=1e30,0,0", "--pull=5,0,0"] {
        let out = dynaclay(dir.path(), &["points", "s.xyz", "--out", "p.ply", pull]);
        input_error(&out, &["--pull", "box sizes"]);
        assert!(!dir.path().join("p.ply").exists());
    }
    // A pull within reach is taken.
    let near = dynaclay(
        dir.path(),
        &[
            "points",
            "s.xyz",
            "--out",
            "p.ply",
            "--pull=1.3,0,0",
            "--steps",
            "50",
        ],
    );
    assert!(
        near.status.success(),
        "{}",
        String::from_utf8_lossy(&near.stderr)
    );

    let import = dynaclay(
        dir.path(),
        &["import", "s.xyz", "--out", "s.dclay", "--resolution", "16"],
    );
    assert!(import.status.success());
    let out = dynaclay(
        dir.path(),
        &["rbf", "s.dclay", "--out", "r.rbf", "--offset=1e30"],
    );
    input_error(&out, &["--offset", "knot spans"]);
    assert!(!dir.path().join("r.rbf").exists());
}

/// A session of one zero lattice of `dims` (no surface), or of none.
fn session_of(path: &Path, dims: Option<[usize; 3]>) {
    let mut clay = zero_clay([4; 3]);
    match dims {
        Some(d) => clay = zero_clay(d),
        None => clay.density.patches.clear(),
    }
    save_clay(path, clay);
}

#[test]
fn a_session_with_nothing_to_draw_or_too_much_is_an_input_error_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    session_of(&dir.path().join("empty.dclay"), None);
    session_of(&dir.path().join("long.dclay"), Some([4, 4, 1_000_000]));
    for (name, want) in [("empty.dclay", "no density patch"), ("long.dclay", "cells")] {
        let out = dynaclay(dir.path(), &["render", name, "--out", "x.png"]);
        input_error(&out, &[name, want]);
        assert!(!dir.path().join("x.png").exists());
    }
}

/// Reads the positions back from the binary PLY `points` writes.
fn ply_positions(path: &Path) -> Vec<Vec3> {
    let bytes = std::fs::read(path).unwrap();
    dynaclay::fit::parse_ply(&bytes, path).unwrap().points
}

#[test]
fn a_cloud_in_any_units_builds_its_surface_in_those_units() {
    let dir = tempfile::tempdir().unwrap();
    for scale in [1e-30_f32, 1e30] {
        let mut text = String::new();
        for i in 0..1500 {
            let y = 1.0 - 2.0 * (i as f32 + 0.5) / 1500.0;
            let r = (1.0 - y * y).sqrt();
            let phi = i as f32 * 2.399_963;
            let p = Vec3::new(r * phi.cos(), y, r * phi.sin()) * scale;
            text += &format!("{:e} {:e} {:e}\n", p.x, p.y, p.z);
        }
        std::fs::write(dir.path().join("s.xyz"), text).unwrap();
        let out = dynaclay(dir.path(), &["points", "s.xyz", "--out", "p.ply"]);
        assert!(
            out.status.success(),
            "{scale}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let points = ply_positions(&dir.path().join("p.ply"));
        assert!(points.len() >= 1000, "{scale}: {} points", points.len());
        // Every point on the sphere of radius `scale`, in the file's units.
        let worst = points
            .iter()
            .map(|p| ((*p / scale).length() - 1.0).abs())
            .fold(0.0_f32, f32::max);
        assert!(worst < 0.01, "{scale}: off the sphere by {worst}");
    }
}
