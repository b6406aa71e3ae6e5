//! `dynaclay run` end to end in a temporary directory, and its error messages.

use std::path::Path;
use std::process::Command;

use dynaclay::io::load_session;
use dynaclay::mesh::{BrickOctree, SampleGrid};

const BIN: &str = env!("CARGO_BIN_EXE_dynaclay");

/// Parses an OBJ and checks every edge is shared by exactly two faces, in opposite directions.
fn obj_is_closed(path: &Path) -> (usize, usize, bool) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut vertices = 0;
    let mut edges = std::collections::HashMap::<(u32, u32), i32>::new();
    let mut faces = 0;
    for line in text.lines() {
        let mut it = line.split_whitespace();
        match it.next() {
            Some("v") => vertices += 1,
            Some("f") => {
                faces += 1;
                let idx: Vec<u32> = it
                    .map(|t| t.split('/').next().unwrap().parse().unwrap())
                    .collect();
                for k in 0..idx.len() {
                    let (a, b) = (idx[k], idx[(k + 1) % idx.len()]);
                    *edges.entry((a.min(b), a.max(b))).or_default() += if a < b { 1 } else { -1 };
                }
            }
            _ => {}
        }
    }
    // Each undirected edge seen once each way sums to zero; a boundary edge sums to ±1.
    let closed = faces > 0 && edges.values().all(|&v| v == 0);
    (vertices, faces, closed)
}

#[test]
fn run_writes_meshes_session_and_latency_reports() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let status = Command::new(BIN)
        .args([
            "run",
            "--seconds",
            "2",
            "--no-rt",
            "--ply",
            "--stl",
            "--out",
        ])
        .arg(&out)
        .status()
        .expect("binary runs");
    assert!(status.success());
    for f in [
        "sculpt.obj",
        "sculpt.ply",
        "sculpt.stl",
        "session.dclay",
        "latency.json",
        "latency.md",
        "latency.svg",
    ] {
        let p = out.join(f);
        assert!(
            p.is_file() && p.metadata().unwrap().len() > 0,
            "{f} missing"
        );
    }
    let (vertices, faces, closed) = obj_is_closed(&out.join("sculpt.obj"));
    assert!(closed, "sculpt.obj is not closed");

    // The session loads back to the field the mesh was made from.
    let session = load_session(&out.join("session.dclay")).expect("session loads");
    let lattice = &session.clay.patches[0];
    let grid = SampleGrid::for_lattice(lattice, 4).unwrap();
    let mesh = BrickOctree::build(grid, lattice).weld();
    assert_eq!(
        (mesh.vertex_count(), mesh.triangle_count()),
        (vertices, faces)
    );

    let json = std::fs::read_to_string(out.join("latency.json")).unwrap();
    let loops = dynaclay_loops::summaries_from_json(&json).unwrap();
    let names: Vec<_> = loops.iter().map(|l| l.name.as_str()).collect();
    assert_eq!(names, ["haptic", "simulation", "graphics"]);
    assert!(loops[0].stats.ticks > 1000);
}

#[test]
fn bad_arguments_and_scripts_fail_with_a_clear_message() {
    let out = Command::new(BIN)
        .args(["run", "--seconds", "abc"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("--seconds") && err.contains("abc"), "{err}");

    let out = Command::new(BIN)
        .args(["run", "--device", "usb:7"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("usb:7"));

    let dir = tempfile::tempdir().unwrap();
    let script = dir.path().join("bad.toml");
    std::fs::write(
        &script,
        "version = 1\nseconds = 1\n\n[[step]]\ndo = \"stroke\"\npath = [[1, 1, 1]]\nspeed = 3\n",
    )
    .unwrap();
    let out = Command::new(BIN)
        .arg("run")
        .arg("--script")
        .arg(&script)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("bad.toml:7") && err.contains("speed"), "{err}");

    std::fs::write(
        &script,
        "version = 1\n[[step]]\ndo = \"stroke\"\npath = [[1, 1, 1]]\nduration_s = -2\n",
    )
    .unwrap();
    let out = Command::new(BIN)
        .arg("run")
        .arg("--script")
        .arg(&script)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("bad.toml:5: step 1: duration_s"), "{err}");
}
