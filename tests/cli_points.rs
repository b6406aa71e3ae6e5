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

/// An 8 × 4 checkerboard PNG of `px`-pixel squares, white where `(column + row)` is even.
fn write_checkerboard_png(path: &Path, px: u32) {
    let image = image::GrayImage::from_fn(8 * px, 4 * px, |x, y| {
        image::Luma([if (x / px + y / px).is_multiple_of(2) {
            255
        } else {
            0
        }])
    });
    image.save(path).unwrap();
}

#[test]
fn points_embosses_and_engraves_an_image_along_the_normals() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("ball.xyz");
    write_sphere_xyz(&input, 3000);
    let board = dir.path().join("board.png");
    write_checkerboard_png(&board, 8);
    let radii = |extra: &[&str]| -> Vec<f32> {
        let out = dir.path().join("out.ply");
        let run = Command::new(BIN)
            .args(["points"])
            .arg(&input)
            .arg("--out")
            .arg(&out)
            .arg("--emboss")
            .arg(&board)
            .args(["--depth", "0.05"])
            .args(extra)
            .output()
            .unwrap();
        let said = format!(
            "{}{}",
            String::from_utf8_lossy(&run.stdout),
            String::from_utf8_lossy(&run.stderr)
        );
        assert!(run.status.success(), "{said}");
        assert!(said.contains("points moved"), "{said}");
        read_points(&out)
            .unwrap()
            .points
            .iter()
            .map(|p| p.length())
            .collect()
    };
    // Embossed: the white half of the points out by the depth, the black half where it was.
    let up = radii(&[]);
    let raised = up.iter().filter(|r| (**r - 0.55).abs() < 0.005).count();
    let kept = up.iter().filter(|r| (**r - 0.5).abs() < 0.005).count();
    assert!(
        raised > up.len() / 4 && kept > up.len() / 4,
        "{raised} raised, {kept} kept of {}",
        up.len()
    );
    assert!(
        up.iter().all(|r| *r > 0.495 && *r < 0.555),
        "radii {:?}",
        up.iter()
            .fold((9.0f32, 0.0f32), |(a, b), r| (a.min(*r), b.max(*r)))
    );
    // Engraved: the white half sunk instead.
    let down = radii(&["--engrave", "--projection", "cylindrical"]);
    let sunk = down.iter().filter(|r| (**r - 0.45).abs() < 0.005).count();
    assert!(sunk > down.len() / 5, "{sunk} sunk of {}", down.len());

    // Bad input: a missing image names itself; a depth without an image is refused.
    let missing = Command::new(BIN)
        .args(["points"])
        .arg(&input)
        .arg("--out")
        .arg(dir.path().join("x.ply"))
        .arg("--emboss")
        .arg(dir.path().join("none.png"))
        .output()
        .unwrap();
    assert_eq!(missing.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&missing.stderr).contains("none.png"));
    let orphan = Command::new(BIN)
        .args(["points"])
        .arg(&input)
        .arg("--out")
        .arg(dir.path().join("x.ply"))
        .args(["--depth", "0.05"])
        .output()
        .unwrap();
    assert_eq!(orphan.status.code(), Some(2));
}
