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
