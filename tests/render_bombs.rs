//! Valid sessions that would take more memory to mesh or render than the machine has are
//! refused before anything is allocated: exit 2, a message naming the budget and the fix, and a
//! peak resident set under 64 MB for the whole process. Inputs that never end (`/dev/zero`) or
//! block (a FIFO) are refused at once, and so is a session whose bricks would pass the clay's
//! dense-brick budget (768 MiB, the real one).
//!
//! The budgets are given with `--memory-budget-mib` so the outcome does not depend on the
//! machine's memory; the default (half of `MemTotal`) is covered by the unit tests of
//! `cli::budget`.

use std::path::Path;
use std::process::{Command, Stdio};

use dynaclay::field::BSplineLattice;
use dynaclay::io::{Session, save_session};
use dynaclay::tools::Clay;
use glam::Vec3;

const BIN: &str = env!("CARGO_BIN_EXE_dynaclay");

/// Peak resident set allowed for a refused bomb, bytes.
const PEAK_LIMIT_BYTES: u64 = 64 << 20;

struct Finished {
    code: Option<i32>,
    stderr: String,
    /// The child's peak resident set, bytes (`ru_maxrss` from `wait4`).
    peak_rss_bytes: u64,
}

/// Runs the binary with `args` and reaps it with `wait4`, which gives that child's own peak
/// resident set (not the largest of all children the test process has had).
#[expect(
    clippy::zombie_processes,
    reason = "the child is reaped by wait4 below, which also gives its own rusage"
)]
fn run(args: &[&std::ffi::OsStr]) -> Finished {
    let child = Command::new(BIN)
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let pid = i32::try_from(child.id()).unwrap();
    let mut stderr_pipe = child.stderr.unwrap();
    // The child writes a line or two: reading to the end never fills the pipe first.
    let mut stderr = String::new();
    std::io::Read::read_to_string(&mut stderr_pipe, &mut stderr).unwrap();
    let mut status = 0;
    // SAFETY: `rusage` is plain data that wait4 fills; zeroed is a valid value for it.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    // SAFETY: `pid` is our own unreaped child (std's `Child` was consumed above without
    // waiting), and both out-pointers are valid for writes.
    let reaped = unsafe { libc::wait4(pid, &mut status, 0, &mut usage) };
    assert_eq!(reaped, pid, "wait4: {}", std::io::Error::last_os_error());
    let code = libc::WIFEXITED(status).then(|| libc::WEXITSTATUS(status));
    Finished {
        code,
        stderr,
        peak_rss_bytes: u64::try_from(usage.ru_maxrss).unwrap_or(0) * 1024,
    }
}

fn os(s: &str) -> &std::ffi::OsStr {
    s.as_ref()
}

fn save(dir: &Path, name: &str, patches: Vec<BSplineLattice>) -> std::path::PathBuf {
    let path = dir.join(name);
    let session = Session {
        clay: Clay {
            density: dynaclay::field::MultiPatchField {
                patches: patches
                    .into_iter()
                    .map(dynaclay::field::Patch::identity)
                    .collect(),
            },
            colour: None,
            constraints: Vec::new(),
            mask: None,
        },
        ..Session::default()
    };
    save_session(&path, &session).unwrap();
    path
}

fn assert_refused(out: &Finished, needle: &str) {
    println!(
        "peak {:.1} MB: {}",
        out.peak_rss_bytes as f64 / 1e6,
        out.stderr.trim()
    );
    assert_eq!(out.code, Some(2), "{}", out.stderr);
    assert!(out.stderr.contains(needle), "{}", out.stderr);
    assert!(out.stderr.contains("memory budget"), "{}", out.stderr);
    assert!(out.stderr.contains("--memory-budget-mib"), "{}", out.stderr);
    assert!(
        out.peak_rss_bytes < PEAK_LIMIT_BYTES,
        "peak {} MB: {}",
        out.peak_rss_bytes >> 20,
        out.stderr
    );
}

/// A ball of radius 4 spans at `spacing`, as the level set 0.5.
fn ball(dims: usize, spacing: f32, origin: Vec3) -> BSplineLattice {
    let mut l = BSplineLattice::zeros([dims; 3], spacing, origin).unwrap();
    let c = (dims as f32 - 1.0) / 2.0;
    for k in 0..dims {
        for j in 0..dims {
            for i in 0..dims {
                let d = Vec3::new(i as f32 - c, j as f32 - c, k as f32 - c).length();
                let n = l.index(i, j, k);
                l.coeffs.set_flat(n, (1.0 - d / 8.0).clamp(0.0, 1.0));
            }
        }
    }
    l
}

#[test]
fn two_patches_of_spacing_1e_3_and_37_are_refused_at_once() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("out.png");
    let render = |session: &Path| {
        run(&[
            os("render"),
            session.as_os_str(),
            os("--out"),
            png.as_os_str(),
            os("--memory-budget-mib"),
            os("1024"),
        ])
    };
    // A 4³ coarse patch: its support (7 × 37 m) fits the mesher's grid at the fine spacing,
    // and its surface at that spacing is counted past the budget.
    let mut coarse = ball(4, 37.0, Vec3::splat(-100.0));
    coarse.coeffs.update_each(|_, c| *c = 0.3 + 0.4 * *c);
    let fine = ball(12, 1e-3, Vec3::ZERO);
    let session = save(dir.path(), "spacings.dclay", vec![fine.clone(), coarse]);
    assert_refused(&render(&session), "meshing the clay");
    // A 6³ coarse patch: the grid itself is past what the mesher can address.
    let mut coarse = ball(6, 37.0, Vec3::splat(-100.0));
    coarse.coeffs.update_each(|_, c| *c = 0.3 + 0.4 * *c);
    let session = save(dir.path(), "wider.dclay", vec![fine, coarse]);
    let out = render(&session);
    assert_eq!(out.code, Some(2), "{}", out.stderr);
    assert!(out.stderr.contains("past the mesher"), "{}", out.stderr);
    assert!(out.peak_rss_bytes < PEAK_LIMIT_BYTES);
    assert!(!png.exists());
}

#[test]
fn a_4_by_4_by_200000_lattice_is_refused_at_once() {
    let dir = tempfile::tempdir().unwrap();
    let mut rod = BSplineLattice::zeros([4, 4, 200_000], 0.01, Vec3::ZERO).unwrap();
    rod.coeffs.fill(1.0);
    let session = save(dir.path(), "rod.dclay", vec![rod]);
    let png = dir.path().join("out.png");
    let out = run(&[
        os("render"),
        session.as_os_str(),
        os("--out"),
        png.as_os_str(),
        os("--memory-budget-mib"),
        os("2048"),
    ]);
    assert_refused(&out, "meshing the clay");
    assert!(!png.exists());
}

#[test]
fn a_16384_square_image_is_refused_before_the_session_is_read() {
    let dir = tempfile::tempdir().unwrap();
    let session = save(dir.path(), "ball.dclay", vec![ball(12, 0.1, Vec3::ZERO)]);
    let png = dir.path().join("out.png");
    for budget in ["1024", "8192"] {
        let out = run(&[
            os("render"),
            session.as_os_str(),
            os("--out"),
            png.as_os_str(),
            os("--width"),
            os("16384"),
            os("--height"),
            os("16384"),
            os("--memory-budget-mib"),
            os(budget),
        ]);
        assert_refused(&out, "16384×16384");
    }
    // `run --png` refuses it before the run, so no output folder is made.
    let out_dir = dir.path().join("run");
    let out = run(&[
        os("run"),
        os("--seconds"),
        os("0.2"),
        os("--no-rt"),
        os("--png"),
        os("--width"),
        os("16384"),
        os("--height"),
        os("16384"),
        os("--memory-budget-mib"),
        os("1024"),
        os("--out"),
        out_dir.as_os_str(),
    ]);
    assert_refused(&out, "16384×16384");
    assert!(!out_dir.exists());
}

#[test]
fn endless_and_blocking_inputs_are_refused_at_once() {
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("fifo");
    let made = Command::new("mkfifo").arg(&fifo).status().unwrap();
    assert!(made.success());
    let out_dir = dir.path().join("out");
    let imported = dir.path().join("i.dclay");
    for (n, input) in [Path::new("/dev/zero"), fifo.as_path()]
        .into_iter()
        .enumerate()
    {
        let png = dir.path().join("x.png");
        // `import` picks its reader by extension: a link named like a point cloud.
        let cloud = dir.path().join(format!("cloud{n}.xyz"));
        std::os::unix::fs::symlink(input, &cloud).unwrap();
        let cases: Vec<Vec<&std::ffi::OsStr>> = vec![
            vec![
                os("render"),
                input.as_os_str(),
                os("--out"),
                png.as_os_str(),
            ],
            vec![
                os("run"),
                os("--script"),
                input.as_os_str(),
                os("--out"),
                out_dir.as_os_str(),
            ],
            vec![os("gui"), input.as_os_str()],
            vec![
                os("profile"),
                os("--compare"),
                input.as_os_str(),
                input.as_os_str(),
            ],
            vec![
                os("import"),
                cloud.as_os_str(),
                os("--out"),
                imported.as_os_str(),
            ],
        ];
        for args in cases {
            let out = run(&args);
            assert!(
                matches!(out.code, Some(1..=3)),
                "{args:?}: {:?} {}",
                out.code,
                out.stderr
            );
            assert!(
                out.stderr.contains("not a regular file"),
                "{args:?}: {}",
                out.stderr
            );
            assert!(out.peak_rss_bytes < PEAK_LIMIT_BYTES, "{args:?}");
        }
        let replay = format!("replay:{}", input.display());
        let out = run(&[
            os("run"),
            os("--device"),
            os(&replay),
            os("--out"),
            out_dir.as_os_str(),
        ]);
        assert!(out.stderr.contains("not a regular file"), "{}", out.stderr);
        assert!(out.peak_rss_bytes < PEAK_LIMIT_BYTES);
    }
}

/// Replaces the payload of the first section tagged `tag` in session file bytes `file`,
/// making its length and checksum match, as a hostile writer can (the layout is the one
/// `dynaclay::io` documents: a 24-byte header, then sections of tag, `u64` length, payload
/// and the CRC32 of the three).
fn with_section_payload(file: &[u8], tag: &[u8; 4], payload: &[u8]) -> Vec<u8> {
    let mut pos = 24;
    loop {
        assert!(pos + 12 <= file.len(), "no {tag:?} section");
        let len = usize::try_from(u64::from_le_bytes(
            file[pos + 4..pos + 12].try_into().unwrap(),
        ))
        .unwrap();
        let end = pos + 12 + len + 4;
        if &file[pos..pos + 4] == tag {
            let mut out = file[..pos].to_vec();
            out.extend_from_slice(tag);
            out.extend_from_slice(&(payload.len() as u64).to_le_bytes());
            out.extend_from_slice(payload);
            let crc = crc32fast::hash(&out[pos..]);
            out.extend_from_slice(&crc.to_le_bytes());
            out.extend_from_slice(&file[end..]);
            return out;
        }
        pos = end;
    }
}

/// A session whose base lattice is 512 × 512 × 320 coefficients stored as uniform bricks
/// whose values alternate along x (9 bytes a brick, 1.5 MB): every brick but the last of each
/// row has an apron that differs from it, so loading it would make 161 280 dense bricks, past
/// the clay's 151 259 (768 MiB). It is refused at the real budget having allocated no dense
/// brick: the apron bricks are counted before any is made.
#[test]
fn a_session_whose_uniform_bricks_would_pass_the_dense_budget_is_refused_at_once() {
    use dynaclay::field::MAX_DENSE_BRICKS;
    let dir = tempfile::tempdir().unwrap();
    let small = save(dir.path(), "small.dclay", vec![ball(12, 0.1, Vec3::ZERO)]);
    let bricks_per_axis = [64_u32, 64, 40];
    let bricks: u32 = bricks_per_axis.iter().product();
    let would_be_dense = (bricks_per_axis[0] - 1) * bricks_per_axis[1] * bricks_per_axis[2];
    assert!(would_be_dense as usize > MAX_DENSE_BRICKS);
    let mut payload = Vec::new();
    for n in bricks_per_axis {
        payload.extend_from_slice(&(n * 8).to_le_bytes());
    }
    // Spacing, origin, iso.
    for v in [0.01_f32, 0.0, 0.0, 0.0, 0.5] {
        payload.extend_from_slice(&v.to_le_bytes());
    }
    payload.extend_from_slice(&u64::from(bricks).to_le_bytes());
    for n in 0..bricks {
        // A run of one uniform brick.
        payload.push(0);
        payload.extend_from_slice(&1_u32.to_le_bytes());
        payload.extend_from_slice(&((n % 2) as f32).to_le_bytes());
    }
    // The identity map: the linear part column by column, then the translation.
    for v in glam::Affine3A::IDENTITY.to_cols_array() {
        payload.extend_from_slice(&v.to_le_bytes());
    }
    let hostile = dir.path().join("stripes.dclay");
    let bytes = with_section_payload(&std::fs::read(&small).unwrap(), b"PTCH", &payload);
    std::fs::write(&hostile, bytes).unwrap();
    let png = dir.path().join("out.png");
    let out = run(&[
        os("render"),
        hostile.as_os_str(),
        os("--out"),
        png.as_os_str(),
    ]);
    println!(
        "peak {:.1} MB: {}",
        out.peak_rss_bytes as f64 / 1e6,
        out.stderr.trim()
    );
    assert_eq!(out.code, Some(2), "{}", out.stderr);
    for needle in ["stripes.dclay", "PTCH", "dense bricks", "768 MiB"] {
        assert!(out.stderr.contains(needle), "{needle}: {}", out.stderr);
    }
    assert!(
        out.peak_rss_bytes < PEAK_LIMIT_BYTES,
        "peak {} MB: {}",
        out.peak_rss_bytes >> 20,
        out.stderr
    );
    assert!(!png.exists());
}
