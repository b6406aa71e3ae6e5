//! The three ways a cloud becomes a mesh in the peer comparison, each timed from the cloud to
//! the triangles, with the peak memory it added.
//!
//! * **dynaclay**: the command a user runs, `dynaclay import cloud.ply --out clay.dclay --mesh
//!   mesh.ply` with its default settings (the clay meshed at 4 cells per knot span, or
//!   `PEERS_CELLS_PER_SPAN`, within the
//!   machine's default memory budget, welded), as a child process: its time includes reading
//!   the cloud and writing the session and the mesh, and its memory is its own peak resident
//!   set (`VmHWM`, see `run_child`), the whole process, as PoissonRecon's is. The command writes its mesh in the
//!   cloud's coordinates at 4 cells per knot span; the same fit is made again in this process
//!   (`fit::fit_import`, then `cli::mesh_clay` as `--mesh` does) for the mesh at
//!   `PEERS_CELLS_PER_SPAN` cells, mapped to the cloud's units as `--mesh` maps it; that
//!   second run is not timed.
//! * **poisson_reconstruction** (crates.io): `from_points_and_normals` with the parameters of
//!   its README and demo — screening 0 and 10 relaxation iterations, the density estimated one
//!   level above the finest — at depth 8, then `reconstruct_mesh_buffers`. It is given the
//!   points in memory (it reads no file).
//! * **PoissonRecon** (Kazhdan): the binary named by `POISSON_RECON` (or `PoissonRecon` on the
//!   `PATH`), run as `PoissonRecon --in cloud.ply --out mesh.ply --depth 8 --samplesPerNode 15`
//!   (screened by default, point weight 2 × the B-spline degree). Its time includes reading
//!   the cloud and writing the mesh; its memory is its own peak resident set (`VmHWM`), the
//!   whole process rather than what it added.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use dynaclay::cli::budget::MemoryBudget;
use dynaclay::cli::mesh_clay;
use dynaclay::fit::{ImportSettings, fit_import, imported_session};
use glam::Vec3;
use nalgebra033::{Point3, Vector3};
use poisson_reconstruction::PoissonReconstruction;

use super::memory::{peak_bytes, reset_peak, resident_bytes};
use super::models::{Mesh, OrientedCloud};

/// Octree depth of both Poisson peers (a 256³ finest grid).
pub const POISSON_DEPTH: usize = 8;

/// The crate's depth: [`POISSON_DEPTH`], or `POISSON_CRATE_DEPTH` (1 to 10) where its run at
/// depth 8 takes too long for the machine (it takes minutes per cloud on two cores).
#[must_use]
pub fn poisson_crate_depth() -> usize {
    std::env::var("POISSON_CRATE_DEPTH")
        .ok()
        .and_then(|d| d.parse::<usize>().ok())
        .filter(|d| (1..=10).contains(d))
        .unwrap_or(POISSON_DEPTH)
}

/// What one reconstruction produced and cost.
pub struct Reconstruction {
    pub mesh: Mesh,
    /// Wall time from the cloud to the mesh, seconds.
    pub seconds: f64,
    /// Peak resident memory it needed, bytes (see the module docs for what is counted).
    pub peak_bytes: f64,
}

/// Runs `work` with the peak resident set reset, returning its result, its wall time and the
/// peak it added over the resident set at the start.
fn measured<T>(work: impl FnOnce() -> T) -> (T, f64, f64) {
    reset_peak();
    let before = resident_bytes();
    let start = Instant::now();
    let out = work();
    let seconds = start.elapsed().as_secs_f64();
    (out, seconds, (peak_bytes() - before).max(0.0))
}

/// How often [`run_child`] reads a child's peak resident set.
const PEAK_POLL: Duration = Duration::from_millis(2);

/// Runs `command` to its end with its output discarded: its wall time, seconds, and its peak
/// resident set, bytes: the largest `VmHWM` of its `/proc/<pid>/status`, read every
/// [`PEAK_POLL`] while it runs (growth in its last poll interval can be missed). `wait4`'s
/// `ru_maxrss` is not used: a child's `exec` records the resident set of the process it was
/// forked from (this bench, tens of megabytes by its later rows) in that maximum, so every
/// child would report at least the bench's own size. Or why it failed, with its stderr.
fn run_child(mut command: Command) -> Result<(f64, f64), String> {
    let name = format!("{:?}", command.get_program());
    let start = Instant::now();
    // `spawn` returns once the child has exec'd: from here its status is its own process's.
    let mut child = command
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| format!("{name}: {e}"))?;
    // Drained on its own thread, so a chatty child never blocks on a full pipe.
    let pipe = child.stderr.take();
    let stderr = std::thread::spawn(move || {
        let mut text = String::new();
        if let Some(mut pipe) = pipe {
            let _ = std::io::Read::read_to_string(&mut pipe, &mut text);
        }
        text
    });
    let status_path = PathBuf::from(format!("/proc/{}/status", child.id()));
    let mut peak_kib = 0_u64;
    let status = loop {
        if let Some(kib) = peak_resident_kib(&status_path) {
            peak_kib = peak_kib.max(kib);
        }
        match child.try_wait() {
            Ok(Some(status)) => break status,
            Ok(None) => std::thread::sleep(PEAK_POLL),
            Err(e) => return Err(format!("{name}: waiting: {e}")),
        }
    };
    let seconds = start.elapsed().as_secs_f64();
    let stderr = stderr.join().unwrap_or_default();
    if !status.success() {
        return Err(format!("{name} failed ({status}): {}", stderr.trim()));
    }
    if peak_kib == 0 {
        return Err(format!("{name}: no VmHWM in {}", status_path.display()));
    }
    Ok((seconds, peak_kib as f64 * 1024.0))
}

/// The `VmHWM` line of a `/proc/<pid>/status` file, KiB; `None` when the file or the line
/// cannot be read (the process has exited).
fn peak_resident_kib(status_path: &Path) -> Option<u64> {
    let text = std::fs::read_to_string(status_path).ok()?;
    text.lines()
        .find_map(|line| line.strip_prefix("VmHWM:"))
        .and_then(|rest| rest.trim().trim_end_matches("kB").trim().parse().ok())
}

/// Cells per knot span of the mesh dynaclay's fit is judged by: 4, as `--mesh` exports it,
/// unless `PEERS_CELLS_PER_SPAN` sets another (1 to 16; a finer mesh tells how much of the
/// distance is the marching cubes' chords rather than the fit). The timed child always
/// exports at its default.
fn mesh_cells_per_span() -> u32 {
    let Some(text) = std::env::var_os("PEERS_CELLS_PER_SPAN") else {
        return 4;
    };
    let text = text.to_string_lossy();
    match text.trim().parse::<u32>() {
        Ok(cells) if (1..=16).contains(&cells) => cells,
        _ => panic!("PEERS_CELLS_PER_SPAN is {text:?}: expected 1 to 16 cells per span"),
    }
}

/// `dynaclay import <ply>` with the default settings and `--mesh`, run as a child process in
/// `scratch` for its time and memory, and the same fit made here for its mesh in the cloud's
/// units (see the module docs).
pub fn dynaclay(ply: &Path, scratch: &Path) -> Result<Reconstruction, String> {
    let (session, mesh) = (
        scratch.join("dynaclay-clay.dclay"),
        scratch.join("dynaclay-mesh.ply"),
    );
    let mut command = Command::new(env!("CARGO_BIN_EXE_dynaclay"));
    command
        .arg("import")
        .arg(ply)
        .arg("--out")
        .arg(&session)
        .arg("--mesh")
        .arg(&mesh);
    let (seconds, peak_bytes) = run_child(command)?;
    let fit = fit_import(ply, &ImportSettings::default(), &mut |_| true, &mut |_| {})
        .map_err(|e| format!("dynaclay import: {e}"))?;
    let (scale, offset) = (fit.scale, fit.offset);
    let session = imported_session(fit.field, ply, 0);
    let welded = mesh_clay(
        &session.clay,
        mesh_cells_per_span(),
        &MemoryBudget::machine_default(),
    )
    .map_err(|e| format!("dynaclay meshing: {e}"))?
    .weld();
    Ok(Reconstruction {
        // Back from field units to the cloud's.
        mesh: Mesh {
            positions: welded
                .positions
                .iter()
                .map(|&p| (p - offset) / scale)
                .collect(),
            triangles: welded.triangles,
        },
        seconds,
        peak_bytes,
    })
}

/// The `poisson_reconstruction` crate at [`poisson_crate_depth`], as its README calls it.
#[must_use]
pub fn poisson_crate(cloud: &OrientedCloud) -> Reconstruction {
    let (mesh, seconds, peak) = measured(|| {
        let points: Vec<Point3<f64>> = cloud
            .points
            .iter()
            .map(|p| Point3::new(f64::from(p.x), f64::from(p.y), f64::from(p.z)))
            .collect();
        let normals: Vec<Vector3<f64>> = cloud
            .normals
            .iter()
            .map(|n| Vector3::new(f64::from(n.x), f64::from(n.y), f64::from(n.z)))
            .collect();
        let depth = poisson_crate_depth();
        let implicit = PoissonReconstruction::from_points_and_normals(
            &points,
            &normals,
            0.0,
            depth - 1,
            depth,
            10,
        );
        let buffers = implicit.reconstruct_mesh_buffers();
        Mesh {
            positions: buffers
                .vertices()
                .iter()
                .map(|p| Vec3::new(p.x as f32, p.y as f32, p.z as f32))
                .collect(),
            triangles: buffers
                .indices()
                .chunks_exact(3)
                .map(|t| [t[0], t[1], t[2]])
                .collect(),
        }
    });
    Reconstruction {
        mesh,
        seconds,
        peak_bytes: peak,
    }
}

/// The PoissonRecon binary: `POISSON_RECON`, else `PoissonRecon` found on the `PATH`; `Err`
/// says how to build it.
pub fn find_poisson_recon() -> Result<PathBuf, String> {
    let how = "build it with `bench/peers/build_poissonrecon.sh <source>` from a clone of \
               https://github.com/mkazhdan/PoissonRecon and set POISSON_RECON to the binary";
    if let Some(path) = std::env::var_os("POISSON_RECON") {
        let path = PathBuf::from(path);
        return if path.is_file() {
            Ok(path)
        } else {
            Err(format!(
                "POISSON_RECON={} is not a file; {how}",
                path.display()
            ))
        };
    }
    std::env::var_os("PATH")
        .and_then(|paths| {
            std::env::split_paths(&paths)
                .map(|dir| dir.join("PoissonRecon"))
                .find(|p| p.is_file())
        })
        .ok_or_else(|| format!("PoissonRecon is not on the PATH and POISSON_RECON is unset; {how}"))
}

/// Runs PoissonRecon on `ply`, writing `out`, and reads the mesh back; its time and its own
/// peak resident set are [`run_child`]'s.
pub fn poisson_recon(binary: &Path, ply: &Path, out: &Path) -> Result<Reconstruction, String> {
    let mut command = Command::new(binary);
    command.arg("--in").arg(ply).arg("--out").arg(out).args([
        "--depth",
        &POISSON_DEPTH.to_string(),
        "--samplesPerNode",
        "15",
    ]);
    let (seconds, peak_bytes) = run_child(command)?;
    Ok(Reconstruction {
        mesh: read_ply_mesh(out)?,
        seconds,
        peak_bytes,
    })
}

/// A PLY triangle mesh (`vertex` with `x y z`, `face` with a `vertex_indices` list).
fn read_ply_mesh(path: &Path) -> Result<Mesh, String> {
    use ply_rs_bw::ply::{DefaultElement, Property};
    let file = std::fs::File::open(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let ply = ply_rs_bw::parser::Parser::<DefaultElement>::new()
        .read_ply(&mut std::io::BufReader::new(file))
        .map_err(|e| format!("{}: {e}", path.display()))?;
    let scalar = |row: &DefaultElement, name: &str| match row.get(name) {
        Some(Property::Float(v)) => Ok(*v),
        Some(Property::Double(v)) => Ok(*v as f32),
        other => Err(format!("{}: vertex {name} is {other:?}", path.display())),
    };
    let mut mesh = Mesh::default();
    for row in ply.payload.get("vertex").map_or(&[][..], Vec::as_slice) {
        mesh.positions.push(Vec3::new(
            scalar(row, "x")?,
            scalar(row, "y")?,
            scalar(row, "z")?,
        ));
    }
    for row in ply.payload.get("face").map_or(&[][..], Vec::as_slice) {
        let corners: Vec<u32> = match row.get("vertex_indices") {
            Some(Property::ListInt(v)) => v.iter().map(|&i| i as u32).collect(),
            Some(Property::ListUInt(v)) => v.clone(),
            other => return Err(format!("{}: face is {other:?}", path.display())),
        };
        if corners.iter().any(|&i| i as usize >= mesh.positions.len()) {
            return Err(format!("{}: a face names a missing vertex", path.display()));
        }
        // A polygon as a fan (PoissonRecon writes triangles unless asked for polygons).
        for k in 1..corners.len().saturating_sub(1) {
            mesh.triangles
                .push([corners[0], corners[k], corners[k + 1]]);
        }
    }
    Ok(mesh)
}
