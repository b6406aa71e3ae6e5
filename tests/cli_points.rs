//! `dynaclay points`: a cloud becomes a point-set surface, is pulled, and is written as PLY
//! with normals; the mesh of the blended field is closed; bad arguments exit 2.

use std::path::Path;
use std::process::Command;

use dynaclay::fit::read_points;

const BIN: &str = env!("CARGO_BIN_EXE_dynaclay");

/// A sphere of radius 0.5 at the origin as XYZ text, without normals.
fn write_sphere_xyz(path: &Path, count: usize) {
    let mut text = String::new();
    for i in 0..count {
        let z = 1.0 - 2.0 * (i as f32 + 0.5) / count as f32;
        let r = (1.0 - z * z).sqrt();
        let a = i as f32 * 2.399_963;
        text.push_str(&format!(
            "{} {} {}\n",
            0.5 * r * a.cos(),
            0.5 * r * a.sin(),
            0.5 * z
        ));
    }
    std::fs::write(path, text).unwrap();
}

#[test]
fn points_fits_pulls_and_writes_ply_with_outward_normals() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("ball.xyz");
    write_sphere_xyz(&input, 1500);
    let out = dir.path().join("ball.ply");
    let mesh = dir.path().join("ball.obj");
    let status = Command::new(BIN)
        .args(["points"])
        .arg(&input)
        .arg("--out")
        .arg(&out)
        .arg("--mesh")
        .arg(&mesh)
        .args(["--pull", "0.7,0,0", "--steps", "1500"])
        .output()
        .unwrap();
    assert!(
        status.status.success(),
        "{}",
        String::from_utf8_lossy(&status.stderr)
    );
    let cloud = read_points(&out).unwrap();
    let normals = cloud.normals.expect("normals written");
    assert!(
        cloud.points.len() > 1500,
        "points were inserted on the pulled tip"
    );
    // Outward normals everywhere, and the tip pulled out.
    let mut tip = 0.0f32;
    for (p, n) in cloud.points.iter().zip(&normals) {
        assert!(p.normalize().dot(*n) > 0.0, "normal {n} at {p}");
        tip = tip.max(p.x);
    }
    assert!(tip > 0.6, "tip at {tip}");
    let text = std::fs::read_to_string(&mesh).unwrap();
    assert!(text.lines().filter(|l| l.starts_with("f ")).count() > 1000);
}

#[test]
fn points_refuses_a_bad_output_name_and_a_bad_pull() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("ball.xyz");
    write_sphere_xyz(&input, 200);
    for extra in [
        vec!["--out", "x.obj"],
        vec!["--out", "x.ply", "--pull", "1,2"],
        vec!["--out", "x.ply", "--mesh", "x.txt"],
    ] {
        let status = Command::new(BIN)
            .arg("points")
            .arg(&input)
            .args(&extra)
            .current_dir(dir.path())
            .status()
            .unwrap();
        assert_eq!(status.code(), Some(2), "{extra:?}");
    }
}

/// A `points` script step builds the surface of a cloud beside the engine, pulls it and writes
/// PLY with outward normals; the clay run goes on as usual.
#[test]
fn script_points_step_pulls_and_writes_ply() {
    let dir = tempfile::tempdir().unwrap();
    write_sphere_xyz(&dir.path().join("ball.xyz"), 1500);
    let script = dir.path().join("points.toml");
    std::fs::write(
        &script,
        r#"version = 1
seconds = 0.5

[clay]
shape = "block"
resolution = 16

[[step]]
do = "points"
input = "ball.xyz"
pull = [[0.7, 0.0, 0.0]]
steps = 1500
out = "ball_pulled.ply"
"#,
    )
    .unwrap();
    let out = Command::new(BIN)
        .args(["run", "--lockstep", "--script"])
        .arg(&script)
        .arg("--out")
        .arg(dir.path().join("out"))
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        stdout.contains("script step 1: points: 1500 points from"),
        "{stdout}"
    );
    let cloud = read_points(&dir.path().join("ball_pulled.ply")).unwrap();
    let normals = cloud.normals.expect("normals written");
    assert!(cloud.points.len() > 1500, "points inserted on the tip");
    let mut tip = 0.0f32;
    for (p, n) in cloud.points.iter().zip(&normals) {
        assert!(p.normalize().dot(*n) > 0.0, "normal {n} at {p}");
        tip = tip.max(p.x);
    }
    assert!(tip > 0.6, "tip at {tip}");
    assert!(dir.path().join("out/session.dclay").exists());
}

/// Bad `points` steps are refused before the run, with their step and key (exit 2).
#[test]
fn bad_points_steps_are_refused_with_their_key() {
    let dir = tempfile::tempdir().unwrap();
    write_sphere_xyz(&dir.path().join("ball.xyz"), 200);
    let script = dir.path().join("bad.toml");
    for (step, says) in [
        (
            "do = \"points\"\ninput = \"ball.xyz\"\nout = \"b.xyz\"",
            "must end in .ply",
        ),
        (
            "do = \"points\"\ninput = \"missing.xyz\"\nout = \"b.ply\"",
            "is not a file",
        ),
        (
            "do = \"points\"\ninput = \"ball.xyz\"\nsteps = 0\nout = \"b.ply\"",
            "steps = 0 must be between 1 and",
        ),
        (
            "do = \"points\"\ninput = \"ball.xyz\"\nout = \"../b.ply\"",
            "--allow-outside",
        ),
    ] {
        std::fs::write(
            &script,
            format!("version = 1\nseconds = 0.5\n\n[[step]]\n{step}\n"),
        )
        .unwrap();
        let out = Command::new(BIN)
            .args(["run", "--lockstep", "--script"])
            .arg(&script)
            .arg("--out")
            .arg(dir.path().join("out"))
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{step}: {stderr}");
        assert!(stderr.contains(says), "{step}: {stderr}");
        assert!(stderr.contains("step 1"), "{step}: {stderr}");
    }
    assert!(!dir.path().join("b.ply").exists());
}
