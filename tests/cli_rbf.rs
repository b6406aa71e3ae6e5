//! `dynaclay rbf SESSION --particles N --out FILE`: the RBF of a session's clay, written and
//! read back, imported back as a clay; bad input exits 2.

use std::path::Path;
use std::process::Command;

use dynaclay::dynamics::Material;
use dynaclay::field::{BSplineLattice, Primitive, lattice_from_primitive};
use dynaclay::io::{MaterialFields, Session, SessionMeta, load_session, save_session};
use dynaclay::rbf::read_rbf;
use dynaclay::tools::Clay;
use glam::{DVec3, Vec3};

const BIN: &str = env!("CARGO_BIN_EXE_dynaclay");

const SPHERE: Primitive = Primitive::Sphere {
    centre: Vec3::splat(1.0),
    radius: 0.6,
};

fn write_sphere_session(path: &Path) {
    let lattice = lattice_from_primitive([21; 3], 0.1, Vec3::ZERO, &SPHERE, 0.2, 2).unwrap();
    write_session(path, lattice);
}

fn write_session(path: &Path, lattice: BSplineLattice) {
    let session = Session {
        clay: Clay::single(lattice),
        material: MaterialFields {
            uniform: Material::PLASTIC,
            grids: Vec::new(),
        },
        tools: Vec::new(),
        meta: SessionMeta {
            name: "sphere".into(),
            ..SessionMeta::default()
        },
    };
    save_session(path, &session).unwrap();
}

#[test]
fn writes_an_rbf_whose_zero_set_is_the_sphere_and_imports_it_back() {
    let dir = tempfile::tempdir().unwrap();
    let session = dir.path().join("in.dclay");
    write_sphere_session(&session);
    let out = dir.path().join("sphere.rbf");
    let back = dir.path().join("back.dclay");
    let status = Command::new(BIN)
        .args([
            "rbf",
            session.to_str().unwrap(),
            "--particles",
            "200",
            "--out",
        ])
        .arg(&out)
        .arg("--clay")
        .arg(&back)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&status.stdout);
    assert!(
        status.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&status.stderr)
    );
    assert!(stdout.contains("600 centres"), "{stdout}");
    let file = read_rbf(&out).unwrap();
    assert_eq!(file.rbf.len(), 600);
    // Along rays from the centre the RBF changes sign within 1% of the diameter of r = 0.6.
    for k in 0..50 {
        let (u, v) = (k as f64 * 2.399, (k as f64 + 0.5) / 50.0);
        let z = 1.0 - 2.0 * v;
        let s = (1.0 - z * z).sqrt();
        let dir = DVec3::new(s * u.cos(), s * u.sin(), z);
        let at = |r: f64| file.rbf.value(DVec3::ONE + dir * r);
        assert!(at(0.6 - 0.012) > 0.0 && at(0.6 + 0.012) < 0.0, "ray {k}");
    }
    let clay = load_session(&back).unwrap().clay;
    let p = Vec3::new(1.6, 1.0, 1.0);
    let (value, grad) = clay.density.patches[0].lattice.value_and_gradient(p);
    assert!((value - 0.5).abs() / grad.length() < 0.02);
}

#[test]
fn bad_input_exits_2() {
    let dir = tempfile::tempdir().unwrap();
    let session = dir.path().join("in.dclay");
    write_sphere_session(&session);
    let run = |args: &[&str]| Command::new(BIN).args(args).output().unwrap();
    let s = session.to_str().unwrap();
    let out = dir.path().join("x.rbf");
    let o = out.to_str().unwrap();
    // Missing session, wrong extension, zero particles, a file that is not a session, a clay
    // with no surface.
    let missing = dir.path().join("none.dclay");
    let garbage = dir.path().join("garbage.dclay");
    std::fs::write(&garbage, b"not a session").unwrap();
    // A clay with no surface: every coefficient zero.
    let empty = dir.path().join("empty.dclay");
    write_session(
        &empty,
        BSplineLattice::zeros([8; 3], 0.1, Vec3::ZERO).unwrap(),
    );
    for args in [
        vec!["rbf", missing.to_str().unwrap(), "--out", o],
        vec![
            "rbf",
            s,
            "--out",
            dir.path().join("x.txt").to_str().unwrap(),
        ],
        vec!["rbf", s, "--particles", "0", "--out", o],
        vec!["rbf", garbage.to_str().unwrap(), "--out", o],
        vec!["rbf", empty.to_str().unwrap(), "--out", o],
    ] {
        let r = run(&args);
        assert_eq!(
            r.status.code(),
            Some(2),
            "{args:?}: {}",
            String::from_utf8_lossy(&r.stderr)
        );
        assert!(!out.exists());
    }
}

/// Script steps: `particles` settles N particles on the clay as it stands and writes them,
/// `rbf` interpolates it and writes the function; both run beside the engine.
#[test]
fn script_particles_and_rbf_steps_write_their_files() {
    let dir = tempfile::tempdir().unwrap();
    let script = dir.path().join("export.toml");
    std::fs::write(
        &script,
        r#"version = 1
seconds = 0.5

[clay]
shape = "block"
resolution = 16

[[step]]
do = "particles"
count = 300
out = "block.xyz"

[[step]]
do = "rbf"
out = "block.rbf"
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
        stdout.contains("script step 1: 300 particles settled")
            && stdout.contains("script step 2: rbf: 300 particles, 900 centres"),
        "{stdout}"
    );
    // The point cloud: one `x y z nx ny nz` line per particle, unit normals.
    let cloud = std::fs::read_to_string(dir.path().join("block.xyz")).unwrap();
    let rows: Vec<Vec<f32>> = cloud
        .lines()
        .map(|l| l.split(' ').map(|v| v.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), 300);
    for r in &rows {
        assert_eq!(r.len(), 6);
        let n = Vec3::new(r[3], r[4], r[5]).length();
        assert!((n - 1.0).abs() < 1e-4, "normal length {n}");
    }
    // The RBF of the count the `particles` step set: positive inside the block, negative
    // outside, zero at the particles.
    let file = read_rbf(&dir.path().join("block.rbf")).unwrap();
    assert_eq!(file.rbf.len(), 900);
    let session = load_session(&dir.path().join("out/session.dclay")).unwrap();
    let lattice = session.clay.base();
    let (lo, hi) = lattice.support();
    let centre = (0.5 * (lo + hi)).as_dvec3();
    assert!(file.rbf.value(centre) > 0.0);
    assert!(file.rbf.value(lo.as_dvec3()) < 0.0);
    for r in &rows {
        let p = DVec3::new(f64::from(r[0]), f64::from(r[1]), f64::from(r[2]));
        assert!(
            file.rbf.value(p).abs() < 0.25 * f64::from(lattice.spacing),
            "I = {} at particle {p}",
            file.rbf.value(p)
        );
    }
}

/// Bad `particles` and `rbf` steps are refused before the run, with their step and key.
#[test]
fn bad_particles_and_rbf_steps_are_refused_with_their_key() {
    let dir = tempfile::tempdir().unwrap();
    let script = dir.path().join("bad.toml");
    for (step, says) in [
        (
            "do = \"particles\"\ncount = 2",
            "count = 2 must be between 4 and",
        ),
        ("do = \"rbf\"\nout = \"clay.txt\"", "must end in .rbf"),
        (
            "do = \"rbf\"\nout = \"c.rbf\"\noffset = -1.0",
            "offset = -1 must be positive",
        ),
        (
            "do = \"rbf\"\nout = \"c.rbf\"\nmax_centres = 2",
            "max_centres = 2 must be between",
        ),
        ("do = \"rbf\"\nout = \"../c.rbf\"", "--allow-outside"),
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
    }
    assert!(!dir.path().join("c.rbf").exists());
}

/// `--sculpt SCRIPT`: the script's contact tool steps are applied to the clay held as the
/// RBF, which keeps its centres; any other step is refused with its number (exit 2).
#[test]
fn sculpt_applies_contact_steps_to_the_rbf_and_refuses_others() {
    let dir = tempfile::tempdir().unwrap();
    let session = dir.path().join("in.dclay");
    write_sphere_session(&session);
    let script = dir.path().join("edits.toml");
    let out = dir.path().join("sculpted.rbf");
    let run = |steps: &str| {
        std::fs::write(&script, format!("version = 1\n{steps}")).unwrap();
        Command::new(BIN)
            .args([
                "rbf",
                session.to_str().unwrap(),
                "--particles",
                "100",
                "--out",
            ])
            .arg(&out)
            .arg("--sculpt")
            .arg(&script)
            .output()
            .unwrap()
    };
    let contact = "\n[[step]]\ndo = \"tool\"\nshape = { kind = \"sphere\", radius_m = 0.3 }\n\
                   action = { kind = \"contact\", alpha = -1.0 }\npositions = [[1.0, 1.0, 1.6], \
                   [1.0, 1.6, 1.0]]\nfalloff_m = 0.1\nduration_s = 0.004\n";
    let done = run(contact);
    let stdout = String::from_utf8_lossy(&done.stdout);
    assert!(
        done.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&done.stderr)
    );
    assert!(
        stdout.contains("2 contact actions applied to the clay as the RBF (300 centres)"),
        "{stdout}"
    );
    let file = read_rbf(&out).unwrap();
    assert_eq!(file.rbf.len(), 300);
    // The dent: the surface under the first position moved inward.
    assert!(file.rbf.value(DVec3::new(1.0, 1.0, 1.58)) < 0.0);
    std::fs::remove_file(&out).unwrap();

    let refused = run(&format!(
        "{contact}\n[[step]]\ndo = \"tool\"\nshape = {{ kind = \"sphere\", radius_m = 0.2 }}\n\
         action = {{ kind = \"remove\" }}\npositions = [[1.0, 1.0, 1.6]]\n"
    ));
    let stderr = String::from_utf8_lossy(&refused.stderr);
    assert_eq!(refused.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("step 2: the RBF clay takes contact tools only, not the remove action")
            && stderr.contains("edits.toml"),
        "{stderr}"
    );
    assert!(!out.exists());
}
