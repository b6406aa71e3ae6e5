//! `dynaclay run` end to end in a temporary directory, and its error messages.

use std::path::Path;
use std::process::{Command, Output};

use dynaclay::io::load_session;
use dynaclay::mesh::{BrickOctree, SampleGrid};

const BIN: &str = env!("CARGO_BIN_EXE_dynaclay");

/// Runs `dynaclay run` with `flags`, the script at `script`, the output folder `out` and
/// `extra` arguments, and waits for it.
fn run_script(
    flags: &[&str],
    script: impl AsRef<Path>,
    out: impl AsRef<Path>,
    extra: &[&str],
) -> Output {
    Command::new(BIN)
        .arg("run")
        .args(flags)
        .arg("--script")
        .arg(script.as_ref())
        .arg("--out")
        .arg(out.as_ref())
        .args(extra)
        .output()
        .unwrap()
}

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
        "latency.png",
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
    let lattice = &session.clay.density.patches[0].lattice;
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
    // Loop rates belong in bench/: here only that each loop ran and reported.
    assert!(loops.iter().all(|l| l.stats.ticks > 0), "{loops:?}");
    // The platform probe ran around the loops and the machine was judged for 1 and 4 kHz.
    let doc = dynaclay_loops::ProfileDoc::from_json(&json).unwrap();
    assert!(doc.probe_before.is_some() && doc.probe_after.is_some());
    let rates: Vec<f64> = doc.readiness.iter().map(|v| v.rate_hz).collect();
    assert_eq!(rates, [1000.0, 4000.0]);
    // The built-in stroke reached the clay and its change was stamped to the meshes and felt
    // (the figures themselves belong in bench/).
    let motion = doc.motion_to_photon.expect("motion-to-photon figures");
    assert_eq!(motion.strokes, 1, "{motion:?}");
    assert_eq!(motion.first_visible_ms.count, 1, "{motion:?}");
    assert_eq!(motion.hand_to_force_ticks.count, 1, "{motion:?}");
    assert!(motion.presenter.contains("headless"), "{motion:?}");
    let md = std::fs::read_to_string(out.join("latency.md")).unwrap();
    for section in [
        "## Loops",
        "## Haptic loop beside the platform probe",
        "## Motion to photon",
        "## Readiness",
    ] {
        assert!(md.contains(section), "missing {section} in\n{md}");
    }
    let svg = std::fs::read_to_string(out.join("latency.svg")).unwrap();
    assert!(svg.contains("probe (sleeping thread)"));
    assert_eq!(
        png_size(&out.join("latency.png")),
        dynaclay_loops::page_size(loops.len())
    );
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

#[test]
fn autosave_leaves_a_recovery_file_that_the_next_run_offers_and_recover_loads() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let script = dir.path().join("long.toml");
    std::fs::write(
        &script,
        r#"version = 1
seconds = 60

[autosave]
every_strokes = 1

[[step]]
do = "tool"
shape = { kind = "sphere", radius_fu = 0.2 }
action = { kind = "add", deposit_rate_per_s = 10.0 }
positions = [[1.15, 1.95, 1.15]]
duration_s = 1.0
falloff_fu = 0.1

[[step]]
do = "stroke"
path = [[0.85, 1.55, 1.15], [1.45, 1.55, 1.15]]
duration_s = 50.0
"#,
    )
    .unwrap();
    // A run that crashes (is killed) after its first autosave.
    let mut child = Command::new(BIN)
        .args(["run", "--no-rt", "--script"])
        .arg(&script)
        .arg("--out")
        .arg(&out)
        .stdout(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let recovery = out.join("session.dclay.recovery");
    let started = std::time::Instant::now();
    while !recovery.exists() && started.elapsed() < std::time::Duration::from_secs(30) {
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    assert!(recovery.exists(), "no recovery file within 30 s");
    let saved = load_session(&recovery).expect("the recovery file loads");
    assert!(
        saved.clay.density.patches[0]
            .lattice
            .is_inside(glam::Vec3::new(1.15, 1.95, 1.15)),
        "the recovery holds the tool step"
    );

    // The next run names the recovery file and refuses to overwrite it.
    let run = Command::new(BIN)
        .args(["run", "--no-rt", "--seconds", "0.3", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert_eq!(run.status.code(), Some(2));
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(
        err.contains("session.dclay.recovery") && err.contains("--recover"),
        "{err}"
    );

    // --recover starts from it: with a script of no steps the session comes out unchanged.
    let idle = dir.path().join("idle.toml");
    std::fs::write(&idle, "version = 1\nseconds = 0.5\n").unwrap();
    let run = run_script(&["--no-rt", "--recover"], &idle, &out, &[]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    assert!(String::from_utf8_lossy(&run.stdout).contains("starting from recovery file"));
    let session = load_session(&out.join("session.dclay")).unwrap();
    assert_eq!(session.clay, saved.clay);
    assert!(!recovery.exists(), "a normal end removes the recovery file");

    // Without a recovery file, --recover says what it looked for.
    let run = Command::new(BIN)
        .args(["run", "--no-rt", "--recover", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert_eq!(run.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&run.stderr).contains("no recovery file"));
}

/// The highest point of the OBJ mesh above `(x, z)` (a vertical ray against every triangle).
fn top_of(vertices: &[[f32; 3]], faces: &[[usize; 3]], x: f32, z: f32) -> Option<f32> {
    let mut best: Option<f32> = None;
    for f in faces {
        let [a, b, c] = [vertices[f[0]], vertices[f[1]], vertices[f[2]]];
        let d = (b[0] - a[0]) * (c[2] - a[2]) - (b[2] - a[2]) * (c[0] - a[0]);
        if d.abs() < 1e-12 {
            continue;
        }
        let l1 = ((b[0] - x) * (c[2] - z) - (b[2] - z) * (c[0] - x)) / d;
        let l2 = ((c[0] - x) * (a[2] - z) - (c[2] - z) * (a[0] - x)) / d;
        let l3 = 1.0 - l1 - l2;
        if l1 >= 0.0 && l2 >= 0.0 && l3 >= 0.0 {
            let y = l1 * a[1] + l2 * b[1] + l3 * c[1];
            best = Some(best.map_or(y, |t| t.max(y)));
        }
    }
    best
}

#[test]
fn the_built_in_run_leaves_a_groove_along_its_path_and_nothing_elsewhere() {
    let dir = tempfile::tempdir().unwrap();
    let out = Command::new(BIN)
        .args(["run", "--lockstep", "--out"])
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(dir.path().join("sculpt.obj")).unwrap();
    let (mut vertices, mut faces) = (Vec::new(), Vec::new());
    for line in text.lines() {
        let mut it = line.split_whitespace();
        match it.next() {
            Some("v") => {
                let v: Vec<f32> = it.map(|t| t.parse().unwrap()).collect();
                vertices.push([v[0], v[1], v[2]]);
            }
            Some("f") => {
                let f: Vec<usize> = it
                    .map(|t| t.split('/').next().unwrap().parse::<usize>().unwrap() - 1)
                    .collect();
                faces.push([f[0], f[1], f[2]]);
            }
            _ => {}
        }
    }
    // The built-in script: the 24³ block spans [0.575, 1.725]; the push runs at z = 1.15
    // through (0.85, 1.55), (1.15, 1.5), (1.45, 1.55), so it goes 0.175 to 0.225 deep.
    let (top, block) = (1.725f32, 1.15f32);
    let push_depth = 0.175f32;
    for i in 0..=5 {
        let x = 0.9 + 0.1 * i as f32;
        let y = top_of(&vertices, &faces, x, 1.15).expect("clay under the path");
        assert!(
            top - y >= push_depth / 3.0,
            "at x = {x} the top is {y}: not a third of the push deep"
        );
    }
    // Away from the path the top face is where it was (the starting block's top there, on its
    // mesh: within a knot span or two of an edge the block's rounding lowers it), within 1% of
    // the block's size.
    let start = dynaclay::engine::build_clay(&dynaclay::io::ClaySpec::default()).unwrap();
    let start_mesh = BrickOctree::build(SampleGrid::for_lattice(&start, 4).unwrap(), &start).weld();
    let start_vertices: Vec<[f32; 3]> = start_mesh.positions.iter().map(|p| p.to_array()).collect();
    let start_faces: Vec<[usize; 3]> = start_mesh
        .triangles
        .iter()
        .map(|t| t.map(|i| i as usize))
        .collect();
    for (x, z) in [(0.7, 0.7), (1.15, 0.7), (1.6, 0.7), (0.7, 1.6), (1.6, 1.6)] {
        let y = top_of(&vertices, &faces, x, z).expect("clay there");
        let y0 = top_of(&start_vertices, &start_faces, x, z).expect("clay there at the start");
        assert!(
            (y - y0).abs() <= 0.01 * block,
            "the top moved at ({x}, {z}): {y0} → {y}"
        );
    }
}

/// A session holding every section: a painted sculpted patch, a second patch, a material
/// grid, a tool library and metadata.
fn session_with_every_section() -> dynaclay::io::Session {
    use dynaclay::dynamics::Material;
    use dynaclay::io::{
        ClayShape, ClaySpec, MaterialFields, MaterialGrid, SessionMeta, ToolPreset,
    };
    use dynaclay::tools::{Clay, ColourField, ToolAction, ToolShape};
    let patch = dynaclay::engine::build_clay(&ClaySpec {
        shape: ClayShape::Sphere,
        resolution: 12,
        ..ClaySpec::default()
    })
    .unwrap();
    let mut colour = ColourField::matching(&patch).unwrap();
    colour.channels[0].coeffs.update_each(|n, c| {
        *c = (n % 7) as f32 / 7.0;
    });
    colour.channels[3].coeffs.fill(1.0);
    let mut second = patch.clone();
    second.coeffs.update_each(|_, c| *c *= 0.5);
    dynaclay::io::Session {
        clay: Clay {
            density: dynaclay::field::MultiPatchField {
                patches: vec![
                    dynaclay::field::Patch::identity(patch),
                    dynaclay::field::Patch::identity(second),
                ],
            },
            colour: Some(colour),
            constraints: Vec::new(),
            mask: None,
        },
        material: MaterialFields {
            uniform: Material::PLASTIC,
            grids: vec![MaterialGrid {
                name: "stiffness".into(),
                dims: [2, 2, 2],
                values: vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0],
            }],
        },
        tools: vec![ToolPreset {
            name: "ball".into(),
            shape: ToolShape::Sphere { radius_fu: 0.2 },
            action: ToolAction::Add {
                deposit_rate_per_s: 3.0,
            },
            falloff_fu: 0.05,
        }],
        meta: SessionMeta {
            name: "every section".into(),
            created_unix_s: 1_700_000_000,
            saved_unix_s: 1_700_000_001,
            writer: "dynaclay test".into(),
        },
    }
}

#[test]
fn recover_keeps_every_section_of_the_session_paint_included() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    std::fs::create_dir_all(&out).unwrap();
    let saved = session_with_every_section();
    dynaclay::io::save_session(&out.join("session.dclay.recovery"), &saved).unwrap();
    let idle = dir.path().join("idle.toml");
    std::fs::write(&idle, "version = 1\nseconds = 0.3\n").unwrap();
    let run = run_script(&["--no-rt", "--recover"], &idle, &out, &[]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let back = load_session(&out.join("session.dclay")).unwrap();
    assert_eq!(back.clay, saved.clay, "patches and paint");
    assert_eq!(back.material, saved.material, "uniform material and grids");
    assert_eq!(back.tools, saved.tools, "tool library");
    assert_eq!(back.meta.name, saved.meta.name);
    assert_eq!(back.meta.created_unix_s, saved.meta.created_unix_s);
    assert!(
        back.meta.saved_unix_s > saved.meta.saved_unix_s,
        "the save time is the run's: {}",
        back.meta.saved_unix_s
    );
}

#[test]
fn a_run_writes_real_creation_and_save_times() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let idle = dir.path().join("idle.toml");
    std::fs::write(&idle, "version = 1\nseconds = 0.3\n").unwrap();
    let run = run_script(&["--no-rt"], &idle, &out, &[]);
    assert!(run.status.success());
    let back = load_session(&out.join("session.dclay")).unwrap();
    // 2020-01-01: any real clock is later.
    assert!(back.meta.created_unix_s > 1_577_836_800, "{:?}", back.meta);
    assert!(
        back.meta.saved_unix_s >= back.meta.created_unix_s,
        "{:?}",
        back.meta
    );
}

#[test]
fn script_saves_stay_in_their_folders_and_never_replace_other_files() {
    let dir = tempfile::tempdir().unwrap();
    let scripts = dir.path().join("scripts");
    std::fs::create_dir_all(&scripts).unwrap();
    let out = dir.path().join("out");
    let run = |save: &str, extra: &[&str]| {
        let script = scripts.join("save.toml");
        std::fs::write(
            &script,
            format!("version = 1\nseconds = 0.5\n\n[[step]]\ndo = \"save\"\npath = \"{save}\"\n"),
        )
        .unwrap();
        run_script(&["--no-rt"], &script, &out, extra)
    };
    // Outside the script's folder: refused before the run, nothing written.
    let outside = run("../escaped.dclay", &[]);
    assert_eq!(outside.status.code(), Some(2));
    let err = String::from_utf8_lossy(&outside.stderr);
    assert!(
        err.contains("--allow-outside") && err.contains("escaped"),
        "{err}"
    );
    assert!(!dir.path().join("escaped.dclay").exists());
    // With --allow-outside it is written.
    let allowed = run("../escaped.dclay", &["--allow-outside"]);
    assert!(
        allowed.status.success(),
        "{}",
        String::from_utf8_lossy(&allowed.stderr)
    );
    assert!(load_session(&dir.path().join("escaped.dclay")).is_ok());
    // A file that is not a session is never replaced.
    let precious = scripts.join("notes.txt");
    std::fs::write(&precious, "precious").unwrap();
    let refused = run("notes.txt", &[]);
    assert_eq!(refused.status.code(), Some(2));
    let err = String::from_utf8_lossy(&refused.stderr);
    assert!(err.contains("a session is written as .dclay"), "{err}");
    assert_eq!(std::fs::read_to_string(&precious).unwrap(), "precious");
    // Nor is a .dclay this program did not write.
    let foreign = scripts.join("foreign.dclay");
    std::fs::write(&foreign, "precious").unwrap();
    let refused = run("foreign.dclay", &[]);
    assert_eq!(refused.status.code(), Some(2));
    let err = String::from_utf8_lossy(&refused.stderr);
    assert!(err.contains("not a session this program wrote"), "{err}");
    assert_eq!(std::fs::read_to_string(&foreign).unwrap(), "precious");
}

#[test]
fn a_closed_stdout_does_not_stop_a_run_before_its_outputs() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    // Like `dynaclay run | head -0`: the reader is gone before the first line.
    let mut child = Command::new(BIN)
        .args(["run", "--no-rt", "--seconds", "0.3", "--out"])
        .arg(&out)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let done = child.wait_with_output().unwrap();
    assert_eq!(
        done.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&done.stderr)
    );
    assert!(load_session(&out.join("session.dclay")).is_ok());
    assert!(out.join("sculpt.obj").exists());
}

#[test]
fn out_naming_a_file_says_it_is_not_a_directory() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("plain");
    std::fs::write(&file, "keep").unwrap();
    let run = Command::new(BIN)
        .args(["run", "--no-rt", "--seconds", "0.3", "--out"])
        .arg(&file)
        .output()
        .unwrap();
    assert_eq!(run.status.code(), Some(2));
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(
        err.contains("not a directory") && err.contains("plain"),
        "{err}"
    );
    assert_eq!(std::fs::read_to_string(&file).unwrap(), "keep");
}

/// Scripts written before lengths on the clay were named in field units still run, and the
/// run says which old key to rename on which line.
#[test]
fn a_script_with_the_old_metre_keys_runs_and_warns_with_key_and_line() {
    let dir = tempfile::tempdir().unwrap();
    let script = dir.path().join("old.toml");
    std::fs::write(
        &script,
        "version = 1\nseconds = 0.5\n\n[[step]]\ndo = \"tool\"\nshape = { kind = \"sphere\", radius_m = 0.1 }\naction = { kind = \"remove\" }\npositions = [[1.15, 1.75, 1.15]]\nfalloff_m = 0.05\n",
    )
    .unwrap();
    let out = run_script(&["--lockstep"], &script, dir.path().join("out"), &[]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let warnings: Vec<&str> = stderr
        .lines()
        .filter(|l| l.starts_with("warning:"))
        .collect();
    assert_eq!(warnings.len(), 2, "{stderr}");
    assert!(
        warnings[0].contains("old.toml:6:")
            && warnings[0].contains("`radius_m`")
            && warnings[0].contains("`radius_fu`"),
        "{stderr}"
    );
    assert!(
        warnings[1].contains("old.toml:9:") && warnings[1].contains("`falloff_m`"),
        "{stderr}"
    );
}

/// A `constrain` step through `dynaclay run`: the run says which point it moved onto the
/// surface, the session keeps the pin, and an `unconstrain` of a pin that does not exist
/// fails the run with the step and the reason.
#[test]
fn a_run_pins_a_point_says_it_was_projected_and_saves_the_pin() {
    let dir = tempfile::tempdir().unwrap();
    let script = dir.path().join("pin.toml");
    std::fs::write(
        &script,
        "version = 1\nseconds = 1.0\n\n[[step]]\ndo = \"constrain\"\nkind = \"point\"\nat = [1.15, 1.75, 1.15]\n",
    )
    .unwrap();
    let out = run_script(&["--lockstep"], &script, dir.path().join("ok"), &[]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        stdout.contains("script step 1: pinned a point")
            && stdout.contains("[1.1500, 1.7500, 1.1500] was off the surface"),
        "{stdout}"
    );
    let session = load_session(&dir.path().join("ok/session.dclay")).unwrap();
    assert_eq!(session.clay.constraints.len(), 1, "the pin is saved");

    std::fs::write(
        &script,
        "version = 1\nseconds = 1.0\n\n[[step]]\ndo = \"unconstrain\"\nindex = 3\n",
    )
    .unwrap();
    let out = run_script(&["--lockstep"], &script, dir.path().join("bad"), &[]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        stderr.contains("step 1") && stderr.contains("index = 3: the clay has 0 constraint(s)"),
        "{stderr}"
    );
}

#[test]
fn a_recording_that_cannot_be_written_is_reported_and_the_run_exits_non_zero() {
    use std::os::unix::process::CommandExt;
    // A full disk, for this process only: files may not grow past 4 MB (RLIMIT_FSIZE), and
    // SIGXFSZ is ignored (kept across exec) so a write past it fails with EFBIG instead of
    // killing the process. The mesh and session fit; a 60 s recording (7.7 MB) does not.
    let dir = tempfile::tempdir().unwrap();
    let rec = dir.path().join("rec.dcrec");
    // A previous recording (its magic, then anything): the only kind a recording replaces.
    std::fs::write(&rec, b"DCLYREC\x1aprevious recording").unwrap();
    let mut cmd = Command::new(BIN);
    cmd.args(["run", "--lockstep", "--seconds", "60", "--record"])
        .arg(&rec)
        .arg("--out")
        .arg(dir.path());
    // SAFETY: between fork and exec the closure only makes two async-signal-safe system
    // calls on plain values.
    unsafe {
        cmd.pre_exec(|| {
            let limit = libc::rlimit {
                rlim_cur: 4 << 20,
                rlim_max: 4 << 20,
            };
            if libc::setrlimit(libc::RLIMIT_FSIZE, &limit) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            libc::signal(libc::SIGXFSZ, libc::SIG_IGN);
            Ok(())
        });
    }
    let out = cmd.output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(5), "{err}");
    assert!(
        err.contains("recording") && err.contains("incomplete"),
        "{err}"
    );
    // The previous recording is whole, no temporary file is left, and every other output is
    // there all the same.
    assert_eq!(
        std::fs::read(&rec).unwrap(),
        b"DCLYREC\x1aprevious recording"
    );
    let left: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains(".tmp."))
        .collect();
    assert!(left.is_empty(), "{left:?}");
    assert!(dir.path().join("session.dclay").is_file());
    assert!(dir.path().join("sculpt.obj").is_file());
}

#[test]
fn a_link_placed_at_an_output_name_is_neither_written_through_nor_replaced() {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().join("out");
    std::fs::create_dir(&out_dir).unwrap();
    let victim = dir.path().join("victim.txt");
    std::fs::write(&victim, "keep").unwrap();
    let json = out_dir.join("latency.json");
    std::os::unix::fs::symlink(&victim, &json).unwrap();
    let out = Command::new(BIN)
        .args(["run", "--seconds", "0.3", "--no-rt", "--out"])
        .arg(&out_dir)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("latency.json"), "{stderr}");
    assert!(stderr.contains("symbolic link"), "{stderr}");
    assert_eq!(std::fs::read_to_string(&victim).unwrap(), "keep");
    assert!(json.symlink_metadata().unwrap().file_type().is_symlink());
    // The session and mesh come first and are written all the same.
    assert!(out_dir.join("session.dclay").is_file());
}

#[test]
fn a_recording_onto_a_device_or_into_a_file_is_refused_and_keeps_the_previous_one() {
    let dir = tempfile::tempdir().unwrap();
    // `/dev/full` would take the bytes and fail them; it is refused before the run (exit 2,
    // by the output rule).
    let out = Command::new(BIN)
        .args([
            "run",
            "--seconds",
            "0.2",
            "--no-rt",
            "--record",
            "/dev/full",
            "--out",
        ])
        .arg(dir.path().join("a"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("/dev/full"), "{stderr}");
    assert!(stderr.contains("not a regular file"), "{stderr}");
    // A folder that is a file: an error naming it.
    let blocker = dir.path().join("blocker");
    std::fs::write(&blocker, "keep").unwrap();
    let out = Command::new(BIN)
        .args(["run", "--seconds", "0.2", "--no-rt", "--record"])
        .arg(blocker.join("rec.dcrec"))
        .arg("--out")
        .arg(dir.path().join("b"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.to_lowercase().contains("not a directory"),
        "{stderr}"
    );
    assert_eq!(std::fs::read_to_string(&blocker).unwrap(), "keep");
    // A good recording replaces the previous one whole, and leaves no temporary file.
    let rec = dir.path().join("rec.dcrec");
    std::fs::write(&rec, b"DCLYREC\x1aprevious").unwrap();
    let out = Command::new(BIN)
        .args([
            "run",
            "--seconds",
            "0.2",
            "--no-rt",
            "--lockstep",
            "--record",
        ])
        .arg(&rec)
        .arg("--out")
        .arg(dir.path().join("c"))
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(std::fs::read(&rec).unwrap().starts_with(b"DCLYREC"));
    let left: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains(".tmp."))
        .collect();
    assert!(left.is_empty(), "{left:?}");
}

#[test]
fn a_device_path_that_is_not_a_serial_port_is_refused_with_why() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("not-a-port");
    std::fs::write(&file, "x").unwrap();
    for path in [std::path::Path::new("/dev/null"), file.as_path()] {
        if !path.exists() {
            continue;
        }
        let out = Command::new(BIN)
            .args(["run", "--seconds", "0.2", "--no-rt", "--device"])
            .arg(format!("serial:{}", path.display()))
            .arg("--out")
            .arg(dir.path().join("out"))
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(3), "{err}");
        assert!(
            err.contains("cannot set it up as a serial port")
                && err.contains(&*path.to_string_lossy()),
            "{err}"
        );
    }
}

/// `run --record` on the threaded engine, then `run --device replay:` with the same script:
/// the replay's session and its script save equal the live run's bit for bit.
#[test]
fn a_recorded_threaded_run_replays_to_the_same_session_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let script = dir.path().join("s.toml");
    std::fs::write(
        &script,
        r#"
version = 1

[clay]
shape = "block"
resolution = 16

[[step]]
do = "stroke"
path = [[0.8, 1.3, 0.95], [1.1, 1.3, 0.95]]
duration_s = 0.5
hover_fu = 0.3

[[step]]
do = "save"
path = "mid.dclay"

[[step]]
do = "tool"
shape = { kind = "sphere", radius_fu = 0.12 }
action = { kind = "remove" }
positions = [[1.0, 1.45, 1.0]]
duration_s = 0.2
falloff_fu = 0.1
"#,
    )
    .unwrap();
    let run = |extra: &[&str], out: &str| {
        let o = Command::new(BIN)
            .args(["run", "--no-rt", "--script"])
            .arg(&script)
            .args(extra)
            .arg("--out")
            .arg(dir.path().join(out))
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "{extra:?}: {err}");
        String::from_utf8_lossy(&o.stdout).into_owned()
    };
    let rec = dir.path().join("live.rec");
    let rec_arg = rec.to_str().unwrap();
    run(&["--record", rec_arg], "live");
    // On a loaded machine the live run may end (on the wall clock) before the script's save;
    // the replay then must not reach it either.
    let live_mid = std::fs::read(dir.path().join("mid.dclay")).ok();
    let _ = std::fs::remove_file(dir.path().join("mid.dclay"));
    let replay_arg = format!("replay:{rec_arg}");
    let said = run(&["--device", &replay_arg], "replayed");
    assert!(said.contains("as scheduled in the recorded run"), "{said}");
    let replayed_mid = std::fs::read(dir.path().join("mid.dclay")).ok();

    let field = |bytes: &[u8]| {
        let session = dynaclay::io::decode(bytes, Path::new("s.dclay")).unwrap();
        session.clay.density.patches[0]
            .lattice
            .coeffs
            .iter()
            .map(|c| c.to_bits())
            .collect::<Vec<_>>()
    };
    assert_eq!(
        replayed_mid.as_deref().map(field),
        live_mid.as_deref().map(field),
        "the script's save"
    );
    let session = |out: &str| std::fs::read(dir.path().join(out).join("session.dclay")).unwrap();
    assert_eq!(
        field(&session("replayed")),
        field(&session("live")),
        "the final session"
    );

    // The same recording tampered with (its checksums made valid again): the schedule is
    // checked whole before anything replays, and a replay that cannot be exact is refused
    // naming the file and the record, or runs in lockstep when asked and says so last.
    use dynaclay_devices::record::{Record, Recording, ScheduleNote};
    let recording = Recording::parse(&std::fs::read(&rec).unwrap()).unwrap();
    let is_tick = |r: &Record| matches!(r, Record::Schedule(ScheduleNote::Tick { .. }));
    let ticks: Vec<usize> = (0..recording.records.len())
        .filter(|&i| is_tick(&recording.records[i]))
        .collect();
    // Enough for the swap below, on however loaded a machine the live run ran.
    assert!(ticks.len() >= 12, "{} ticks", ticks.len());
    let mut cut = recording.clone();
    let half = ticks[ticks.len() / 2];
    let mut index = 0;
    cut.records.retain(|r| {
        index += 1;
        index <= half || !is_tick(r)
    });
    let mut swapped = recording.clone();
    swapped.records.swap(ticks[10], ticks[11]);
    let mut absurd = recording.clone();
    let last_step = absurd
        .records
        .iter()
        .rposition(|r| matches!(r, Record::Schedule(ScheduleNote::Step { .. })))
        .unwrap();
    if let Record::Schedule(ScheduleNote::Step { sample_tick, .. }) = &mut absurd.records[last_step]
    {
        *sample_tick = 1 << 40;
    }
    let mut none = recording.clone();
    none.records.retain(|r| !matches!(r, Record::Schedule(_)));
    for (name, bad, want) in [
        ("cut.rec", &cut, "the schedule holds"),
        ("swapped.rec", &swapped, &*format!("record {}", ticks[10])),
        ("absurd.rec", &absurd, "1099511627776"),
        ("none.rec", &none, "holds no schedule"),
    ] {
        let path = dir.path().join(name);
        std::fs::write(&path, bad.to_bytes(64)).unwrap();
        let device = format!("replay:{}", path.display());
        let o = Command::new(BIN)
            .args(["run", "--no-rt", "--script"])
            .arg(&script)
            .args(["--device", &device, "--out"])
            .arg(dir.path().join("refused"))
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{name}: {err}");
        assert!(
            err.contains(name) && err.contains(want) && err.contains("--lockstep"),
            "{name}: {err}"
        );
        assert!(
            !dir.path().join("refused").exists(),
            "{name}: the run started"
        );
        let said = run(&["--device", &device, "--lockstep"], "lockstep");
        let last = said.lines().last().unwrap_or_default();
        assert!(
            last.contains("replayed in lockstep") && last.contains(want),
            "{name}: {said}"
        );
    }
}

/// A script's emboss step raises the clay's top under the image's white half by the depth and
/// leaves it under the black half; an engrave cuts in; a missing image is named.
#[test]
fn a_script_embosses_and_engraves_an_image_onto_the_clay() {
    let dir = tempfile::tempdir().unwrap();
    // 8×8: white on the left half, black on the right.
    let mut png_bytes = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut png_bytes, 8, 8);
        enc.set_color(png::ColorType::Grayscale);
        enc.set_depth(png::BitDepth::Eight);
        let mut w = enc.write_header().unwrap();
        let pixels: Vec<u8> = (0..64).map(|i| if i % 8 < 4 { 255 } else { 0 }).collect();
        w.write_image_data(&pixels).unwrap();
    }
    std::fs::write(dir.path().join("half.png"), &png_bytes).unwrap();
    let script = |engrave: bool, image: &str| {
        format!(
            r#"
version = 1

[clay]
shape = "block"
resolution = 24

[[step]]
do = "emboss"
image = "{image}"
projection = {{ kind = "planar", centre = [1.15, 1.725, 1.15], axis = [0, 1, 0], up = [0, 0, -1], size = 0.8 }}
depth = 0.05
engrave = {engrave}
"#
        )
    };
    let top = |session: &Path, x: f32| {
        let l = load_session(session).unwrap().clay.density.patches[0]
            .lattice
            .clone();
        // Bisect the surface height above (x, 1.15).
        let (mut lo, mut hi) = (1.3f32, 2.1f32);
        for _ in 0..40 {
            let m = 0.5 * (lo + hi);
            if l.value(glam::Vec3::new(x, m, 1.15)) > l.iso {
                lo = m;
            } else {
                hi = m;
            }
        }
        0.5 * (lo + hi)
    };
    let run = |name: &str, text: String| {
        std::fs::write(dir.path().join(format!("{name}.toml")), text).unwrap();
        run_script(
            &["--lockstep", "--seconds", "0.2"],
            dir.path().join(format!("{name}.toml")),
            dir.path().join(name),
            &[],
        )
    };
    let clay_only = "version = 1\n\n[clay]\nshape = \"block\"\nresolution = 24\n";
    let plain = run("plain", clay_only.to_string());
    assert!(
        plain.status.success(),
        "{}",
        String::from_utf8_lossy(&plain.stderr)
    );
    let out = run("emboss", script(false, "half.png"));
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let out = run("engrave", script(true, "half.png"));
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let session = |name: &str| dir.path().join(name).join("session.dclay");
    // Seen from +y looking down with −z up, the image's left (white) is −x.
    let (white_x, black_x) = (0.95, 1.35);
    let raised = top(&session("emboss"), white_x) - top(&session("plain"), white_x);
    let kept = top(&session("emboss"), black_x) - top(&session("plain"), black_x);
    let cut = top(&session("plain"), white_x) - top(&session("engrave"), white_x);
    assert!((raised - 0.05).abs() < 0.015, "embossed by {raised}");
    assert!(kept.abs() < 0.01, "black moved by {kept}");
    assert!((cut - 0.05).abs() < 0.015, "engraved by {cut}");

    let out = run("missing", script(false, "nowhere.png"));
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("image:") && err.contains("nowhere.png"),
        "{err}"
    );
}

/// The width and height in a PNG's header, after decoding the whole image.
fn png_size(path: &std::path::Path) -> (u32, u32) {
    let file = std::io::BufReader::new(std::fs::File::open(path).expect("png opens"));
    let mut reader = png::Decoder::new(file).read_info().expect("png header");
    let mut buf = vec![0; reader.output_buffer_size().expect("buffer size")];
    let info = reader.next_frame(&mut buf).expect("png decodes");
    (info.width, info.height)
}
