//! `dynaclay import`: a point cloud, a mesh or a volume becomes a session whose clay is fitted
//! to it (a cloud with colours comes painted with them).
//!
//! A cloud is fitted hierarchically (a base lattice and detail patches, [`fit_hierarchy`]);
//! a volume on one lattice. Long fits show a progress bar on a terminal (stderr). Ctrl-C
//! during the fit stops it between stages or patches and exits 130 with nothing written;
//! the session and the mesh are only written after the fit, each through the atomic writer
//! (a temporary file renamed into place), so no half-written file is ever left.

use std::io::IsTerminal;
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use super::args::{ImportArgs, RawSample};
use super::budget::MemoryBudget;
use super::error::CliError;
use crate::fit::{
    FitProgress, ImportError, ImportSettings, Sample, StageTimes, import_session_timed,
};
use crate::io::{OutputKind, OutputRule, encode, write_atomic};
use crate::mesh::{MeshFormat, write_mesh};

/// Reads `args.input`, fits a clay to it, writes the session (and the mesh when asked).
///
/// # Errors
/// A bad argument or an unreadable point file (exit 2), a failed fit or write (exit 1).
pub fn import(args: &ImportArgs) -> Result<(), CliError> {
    let mesh_format = match &args.mesh {
        Some(path) => Some(MeshFormat::from_path(path).ok_or_else(|| {
            CliError::Usage(format!(
                "--mesh {}: the extension must be .obj, .ply or .stl",
                path.display()
            ))
        })?),
        None => None,
    };
    let rule = OutputRule::new().input("INPUT", &args.input);
    rule.check("--out", &args.out, OutputKind::Session)
        .map_err(CliError::OutputRefused)?;
    if let Some(mesh) = &args.mesh {
        rule.check("--mesh", mesh, OutputKind::Mesh)
            .map_err(CliError::OutputRefused)?;
    }
    // A fit takes seconds to minutes: an output that cannot be written is said first.
    for (flag, path) in
        std::iter::once(("--out", &args.out)).chain(args.mesh.iter().map(|m| ("--mesh", m)))
    {
        let folder = match path.parent() {
            Some(p) if !p.as_os_str().is_empty() => p,
            _ => Path::new("."),
        };
        if !folder.is_dir() {
            return Err(CliError::Usage(format!(
                "{flag} {}: the folder {} does not exist",
                path.display(),
                folder.display()
            )));
        }
    }
    watch_for_ctrl_c();
    let settings = ImportSettings {
        resolution: args.resolution.unwrap_or(crate::fit::DEFAULT_RESOLUTION),
        resolution_from_points: args.resolution.is_none(),
        gap_spans: args.gap,
        error_percent: args.error,
        max_depth: args.max_depth,
        noise_percent: args.noise,
        iso: args.iso,
        midrange_iso: false,
        raw: args.dims.map(|dims| {
            let sample = match args.sample {
                RawSample::U8 => Sample::U8,
                RawSample::U16 => Sample::U16,
                RawSample::I16 => Sample::I16,
                RawSample::F32 => Sample::F32,
            };
            (dims, sample)
        }),
    };
    let bar = progress_bar();
    let mut first = true;
    let session = import_session_timed(
        &args.input,
        &settings,
        &mut |stage| show_progress(&bar, stage),
        &mut |line| {
            bar.suspend(|| {
                if std::mem::take(&mut first) {
                    say!("dynaclay import: {line}");
                } else {
                    say!("{line}");
                }
            });
        },
    );
    bar.finish_and_clear();
    let session = session.map_err(|e| match e {
        ImportError::Interrupted => interrupted(),
        // A cloud without extent, or of a size past the fit's arithmetic, or whose points
        // sample no surface, is bad input, not a failed fit.
        ImportError::Fit {
            source:
                crate::fit::CloudFitError::Degenerate
                | crate::fit::CloudFitError::ExtentOutOfRange { .. }
                | crate::fit::CloudFitError::NoSurface { .. },
            ..
        } => CliError::bad_input("import", e),
        ImportError::Fit { .. } => CliError::output("import", e),
        other => CliError::bad_input("import", other),
    })?;
    let crate::fit::TimedImport {
        session,
        mut times,
        frame,
    } = session;
    let started = Instant::now();
    let mut beside = StageTimes::default();
    // The mesh is made (within the memory budget) before anything is written, so a refused
    // mesh leaves no half-finished import. The session is encoded beside it.
    let (mesh, encoded) = std::thread::scope(|scope| {
        let encoded = scope.spawn(|| {
            let started = Instant::now();
            (encode(&session), started.elapsed())
        });
        let meshing = Instant::now();
        let mesh = match (&args.mesh, mesh_format) {
            (Some(path), Some(format)) => {
                let budget = MemoryBudget::from_flag(args.memory_budget_mib);
                // Built and welded on every core: the same mesh, bit for bit, as on one.
                let threads =
                    std::thread::available_parallelism().map_or(1, std::num::NonZeroUsize::get);
                super::mesh_clay(&session.clay, 4, &budget)
                    .map_err(|e| match e {
                        // The mesh's resolution follows the clay's here.
                        CliError::OverBudget(mut o) => {
                            o.hint = "Lower --resolution";
                            CliError::OverBudget(o)
                        }
                        other => other,
                    })
                    .map(|octree| {
                        // Back in the input's coordinates, to lay over it (normals keep: the
                        // map is a uniform scale and a shift).
                        let mut mesh = octree.weld_with_threads(threads);
                        for p in &mut mesh.positions {
                            *p = frame.to_file(*p).as_vec3();
                        }
                        Some((path, format, mesh))
                    })
            }
            _ => Ok(None),
        };
        beside.record("meshing", meshing);
        let (encoded, encoding) = encoded
            .join()
            .unwrap_or_else(|e| std::panic::resume_unwind(e));
        beside.stages.push(crate::fit::StageTime {
            name: "session's encoding",
            depth: 0,
            wall: encoding,
        });
        (mesh, encoded)
    });
    times.record_with("meshing beside the session's encoding", started, beside);
    let mesh = mesh?;
    let bytes = encoded.map_err(|e| CliError::output(args.out.display().to_string(), e))?;
    // The last moment Ctrl-C is heard: from here on the outputs are written whole.
    if INTERRUPTED.load(Ordering::Relaxed) {
        return Err(interrupted());
    }
    // The two files are written side by side: each write ends by flushing its file to disk,
    // and the two flushes wait together.
    let started = Instant::now();
    let (saved, mesh_written) = std::thread::scope(|scope| {
        let saved = scope.spawn(|| write_atomic(&args.out, &bytes));
        let mesh_written = mesh
            .as_ref()
            .map(|(path, format, mesh)| write_mesh(path, mesh, *format));
        let saved = saved
            .join()
            .unwrap_or_else(|e| std::panic::resume_unwind(e));
        (saved, mesh_written)
    });
    times.record("writing", started);
    saved.map_err(|e| CliError::output(args.out.display().to_string(), e))?;
    say!("wrote {}", args.out.display());
    if let (Some((path, _, mesh)), Some(written)) = (&mesh, mesh_written) {
        written.map_err(|e| CliError::output(path.display().to_string(), e))?;
        say!(
            "wrote {} ({} vertices, {} triangles)",
            path.display(),
            mesh.vertex_count(),
            mesh.triangle_count()
        );
    }
    if args.timings {
        // On stderr, so the log on stdout reads the same with and without it.
        use std::io::Write as _;
        let mut err = std::io::stderr().lock();
        let _ = writeln!(
            err,
            "stage wall times (a stage indented under the next one less indented ran within it):"
        );
        for line in times.lines() {
            let _ = writeln!(err, "{line}");
        }
    }
    Ok(())
}

/// Set by the Ctrl-C handler; the fit's progress callback and the last step before writing
/// read it. Relaxed: it is a lone flag, nothing is published through it.
static INTERRUPTED: AtomicBool = AtomicBool::new(false);

/// Installs the Ctrl-C handler that sets [`INTERRUPTED`] (once per process; when a handler
/// cannot be installed, Ctrl-C ends the process as usual, which still writes nothing half).
fn watch_for_ctrl_c() {
    static INSTALLED: std::sync::Once = std::sync::Once::new();
    INSTALLED.call_once(|| {
        let _ = ctrlc::set_handler(|| INTERRUPTED.store(true, Ordering::Relaxed));
    });
}

fn interrupted() -> CliError {
    CliError::Interrupted("Ctrl-C during the fit; nothing was written".into())
}

/// A progress display on stderr when it is a terminal, silent otherwise.
fn progress_bar() -> indicatif::ProgressBar {
    if !std::io::stderr().is_terminal() {
        return indicatif::ProgressBar::hidden();
    }
    let bar = indicatif::ProgressBar::new_spinner();
    bar.enable_steady_tick(Duration::from_millis(120));
    bar
}

/// Shows `stage` on `bar`; `false` (stop) once Ctrl-C was pressed.
fn show_progress(bar: &indicatif::ProgressBar, stage: FitProgress) -> bool {
    match stage {
        FitProgress::Signing => bar.set_message("signing the points"),
        FitProgress::Base => bar.set_message("fitting the base lattice"),
        FitProgress::Detail { depth, done, of } => {
            bar.set_message(format!("depth {depth}: detail patch {} of {of}", done + 1));
        }
    }
    !INTERRUPTED.load(Ordering::Relaxed)
}
