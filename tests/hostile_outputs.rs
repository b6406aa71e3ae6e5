//! The output rule, from the command line, on the cases a hostile user tried: no command or
//! script step may replace one of its inputs, the running script or a file of another kind,
//! or write outside the allowed folders through a link. Each is refused before any work with
//! exit 2, naming the flag or step, and every file is left byte for byte as it was.

use std::path::{Path, PathBuf};
use std::process::Output;

#[path = "support/cli.rs"]
mod cli;

use cli::{dynaclay, refused};

/// A PLY point cloud of a sphere (ASCII, with normals): a valid input for `import` and
/// `points`.
fn sphere_cloud(path: &Path) {
    let mut text = String::from(
        "ply\nformat ascii 1.0\nelement vertex 400\nproperty float x\nproperty float y\n\
         property float z\nproperty float nx\nproperty float ny\nproperty float nz\nend_header\n",
    );
    for i in 0..400 {
        // A Fibonacci sphere of radius 1.
        let y = 1.0 - 2.0 * (i as f32 + 0.5) / 400.0;
        let r = (1.0 - y * y).sqrt();
        let phi = i as f32 * 2.399_963;
        let (x, z) = (r * phi.cos(), r * phi.sin());
        text += &format!("{x} {y} {z} {x} {y} {z}\n");
    }
    std::fs::write(path, text).unwrap();
}

/// The bytes of every file in `dir` (recursively), to show nothing changed.
fn snapshot(dir: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    let mut files = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            let meta = std::fs::symlink_metadata(&p).unwrap();
            if meta.is_dir() {
                stack.push(p);
            } else if meta.is_file() {
                files.push((p.clone(), std::fs::read(&p).unwrap()));
            }
        }
    }
    files.sort();
    files
}

#[test]
fn import_never_writes_its_mesh_over_its_input() {
    let dir = tempfile::tempdir().unwrap();
    sphere_cloud(&dir.path().join("in.ply"));
    let before = snapshot(dir.path());
    let out = dynaclay(
        dir.path(),
        &["import", "in.ply", "--out", "o.dclay", "--mesh", "in.ply"],
    );
    refused(&out, &["--mesh", "INPUT", "never replaces an input"]);
    // Spelled another way, too.
    let out = dynaclay(
        dir.path(),
        &[
            "import",
            "in.ply",
            "--out",
            "o.dclay",
            "--mesh",
            "./x/../in.ply",
        ],
    );
    refused(&out, &["--mesh"]);
    // An output folder that does not exist is said before the fit, not after it.
    let out = dynaclay(
        dir.path(),
        &["import", "in.ply", "--out", "missing/o.dclay"],
    );
    refused(&out, &["--out", "missing", "does not exist"]);
    assert_eq!(snapshot(dir.path()), before);
}

#[test]
fn points_never_writes_over_its_input_or_a_file_it_did_not_write() {
    let dir = tempfile::tempdir().unwrap();
    sphere_cloud(&dir.path().join("in.ply"));
    std::fs::write(
        dir.path().join("scan.ply"),
        "ply\nformat ascii 1.0\ncomment scanner\n",
    )
    .unwrap();
    let before = snapshot(dir.path());
    for args in [
        &["points", "in.ply", "--out", "in.ply"][..],
        &["points", "in.ply", "--out", "p.ply", "--mesh", "in.ply"],
        &["points", "in.ply", "--out", "p.ply", "--mesh", "p.ply"],
        &["points", "in.ply", "--out", "scan.ply"],
    ] {
        let out = dynaclay(dir.path(), args);
        refused(&out, &[args[args.len() - 2]]);
    }
    assert_eq!(snapshot(dir.path()), before);
    // A file it wrote itself it may replace.
    let ok = dynaclay(dir.path(), &["points", "in.ply", "--out", "p.ply"]);
    assert!(
        ok.status.success(),
        "{}",
        String::from_utf8_lossy(&ok.stderr)
    );
    let again = dynaclay(dir.path(), &["points", "in.ply", "--out", "p.ply"]);
    assert!(
        again.status.success(),
        "{}",
        String::from_utf8_lossy(&again.stderr)
    );
}

#[test]
fn rbf_never_writes_its_clay_over_the_source_session() {
    let dir = tempfile::tempdir().unwrap();
    sphere_cloud(&dir.path().join("in.ply"));
    let import = dynaclay(
        dir.path(),
        &["import", "in.ply", "--out", "s.dclay", "--resolution", "16"],
    );
    assert!(
        import.status.success(),
        "{}",
        String::from_utf8_lossy(&import.stderr)
    );
    let before = snapshot(dir.path());
    let out = dynaclay(
        dir.path(),
        &["rbf", "s.dclay", "--out", "o.rbf", "--clay", "s.dclay"],
    );
    refused(&out, &["--clay", "SESSION"]);
    assert_eq!(snapshot(dir.path()), before);
}

/// A script of one `particles` step writing `out`, run with `extra` arguments.
fn run_particles(dir: &Path, script: &str, out: &str, extra: &[&str]) -> Output {
    std::fs::write(
        dir.join(script),
        format!(
            "version = 1\nseconds = 0.2\n\n[[step]]\ndo = \"particles\"\ncount = 50\nsteps = 5\nout = \"{out}\"\n"
        ),
    )
    .unwrap();
    let mut args = vec!["run", "--script", script, "--lockstep", "--out", "run"];
    args.extend_from_slice(extra);
    dynaclay(dir, &args)
}

#[test]
fn a_script_step_never_replaces_another_kind_of_file_or_the_script() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("notes.txt"), "precious").unwrap();
    std::fs::write(dir.path().join("other.toml"), "[precious]").unwrap();
    std::fs::write(dir.path().join("theirs.xyz"), "a scan's notes\n").unwrap();
    for (out, names) in [
        ("notes.txt", &["particles", "notes.txt", ".xyz"][..]),
        ("other.toml", &["particles", "other.toml"]),
        ("s.toml", &["particles", "s.toml"]),
        (
            "theirs.xyz",
            &["particles", "theirs.xyz", "this program wrote"],
        ),
    ] {
        let before = snapshot(dir.path());
        let out_run = run_particles(dir.path(), "s.toml", out, &[]);
        refused(&out_run, names);
        // Nothing was written: not even the run's folder.
        let mut after = snapshot(dir.path());
        after.retain(|(p, _)| !p.ends_with("s.toml"));
        let mut before = before;
        before.retain(|(p, _)| !p.ends_with("s.toml"));
        assert_eq!(after, before, "{out}");
        assert!(!dir.path().join("run").exists(), "{out}: the run started");
    }
    // The script itself is an input even when it is named as the step's kind.
    let out_run = run_particles(dir.path(), "s.xyz", "s.xyz", &[]);
    refused(&out_run, &["particles", "SCRIPT"]);
}

#[test]
fn a_script_step_cannot_leave_its_folder_through_a_link() {
    let outside = tempfile::tempdir().unwrap();
    let dir = tempfile::tempdir().unwrap();
    std::os::unix::fs::symlink(outside.path(), dir.path().join("away")).unwrap();
    let out_run = run_particles(dir.path(), "s.toml", "away/p.xyz", &[]);
    refused(&out_run, &["particles", "away/p.xyz", "--allow-outside"]);
    assert!(snapshot(outside.path()).is_empty());
    for (step, key, file) in [
        ("save", "path", "away/s.dclay"),
        ("rbf", "out", "away/s.rbf"),
    ] {
        std::fs::write(
            dir.path().join("t.toml"),
            format!(
                "version = 1\nseconds = 0.2\n\n[[step]]\ndo = \"{step}\"\n{key} = \"{file}\"\n"
            ),
        )
        .unwrap();
        let out = dynaclay(
            dir.path(),
            &["run", "--script", "t.toml", "--lockstep", "--out", "run"],
        );
        refused(&out, &[step, file, "--allow-outside"]);
        assert!(snapshot(outside.path()).is_empty());
    }
    // Allowed, it writes there.
    let allowed = run_particles(dir.path(), "s.toml", "away/p.xyz", &["--allow-outside"]);
    assert!(
        allowed.status.success(),
        "{}",
        String::from_utf8_lossy(&allowed.stderr)
    );
    assert!(outside.path().join("p.xyz").is_file());
}

#[test]
fn a_recording_never_replaces_another_kind_of_file_or_the_script() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("notes.txt"), "precious").unwrap();
    std::fs::write(dir.path().join("s.toml"), "version = 1\nseconds = 0.2\n").unwrap();
    let before = snapshot(dir.path());
    for (record, names) in [
        (
            "notes.txt",
            &["--record", "notes.txt", "device recording"][..],
        ),
        ("s.toml", &["--record", "s.toml"]),
    ] {
        let out = dynaclay(
            dir.path(),
            &[
                "run",
                "--script",
                "s.toml",
                "--lockstep",
                "--out",
                "run",
                "--record",
                record,
            ],
        );
        refused(&out, names);
    }
    assert_eq!(snapshot(dir.path()), before);
    // A recording it wrote it may replace.
    for _ in 0..2 {
        let out = dynaclay(
            dir.path(),
            &[
                "run",
                "--script",
                "s.toml",
                "--lockstep",
                "--out",
                "run",
                "--record",
                "r.rec",
            ],
        );
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
}
