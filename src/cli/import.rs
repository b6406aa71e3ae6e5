//! `dynaclay import`: a point cloud or a volume becomes a session whose clay is fitted to it.
//!
//! A cloud is fitted hierarchically (a base lattice and detail patches, [`fit_hierarchy`]);
//! a volume on one lattice. Long fits show a progress bar on a terminal (stderr). Ctrl-C
//! during the fit stops it between stages or patches and exits 130 with nothing written;
//! the session and the mesh are only written after the fit, each through the atomic writer
//! (a temporary file renamed into place), so no half-written file is ever left.

use std::io::IsTerminal;
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use super::args::{ImportArgs, RawSample};
use super::budget::MemoryBudget;
use super::run::CliError;
use crate::dynamics::Material;
use crate::field::MultiPatchField;
use crate::fit::{
    CloudFitError, CloudFitOptions, FitProgress, HierarchyOptions, Sample, SignedBy, Volume,
    fit_hierarchy, fit_volume_hierarchy, read_nrrd, read_points, read_raw,
};
use crate::io::{MaterialFields, Session, SessionMeta, save_session};
use crate::mesh::{MeshFormat, TriMesh, write_mesh};
use crate::tools::Clay;

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
    if args.out.extension().and_then(|e| e.to_str()) != Some("dclay") {
        return Err(CliError::Usage(format!(
            "--out {}: a session file ends in .dclay",
            args.out.display()
        )));
    }
    let ext = args
        .input
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    watch_for_ctrl_c();
    let clay = match ext.as_deref() {
        Some("raw" | "nrrd") => {
            clay_from_field(import_volume(args, ext.as_deref() == Some("nrrd"))?)
        }
        _ => clay_from_field(import_cloud(args)?),
    };
    let name = args
        .input
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or("import")
        .to_owned();
    let session = Session {
        clay,
        material: MaterialFields {
            uniform: Material::PLASTIC,
            grids: Vec::new(),
        },
        tools: Vec::new(),
        meta: SessionMeta {
            name,
            created_unix_s: super::run::unix_now_s(),
            ..SessionMeta::default()
        },
    };
    // The mesh is made (within the memory budget) before anything is written, so a refused
    // mesh leaves no half-finished import.
    let mesh = match (&args.mesh, mesh_format) {
        (Some(path), Some(format)) => {
            let budget = MemoryBudget::from_flag(args.memory_budget_mib);
            Some((
                path,
                format,
                super::mesh_clay(&session.clay, 4, &budget)
                    .map_err(|e| match e {
                        // The mesh's resolution follows the clay's here.
                        CliError::OverBudget(mut o) => {
                            o.hint = "Lower --resolution";
                            CliError::OverBudget(o)
                        }
                        other => other,
                    })?
                    .weld(),
            ))
        }
        _ => None,
    };
    // The last moment Ctrl-C is heard: from here on the outputs are written whole.
    if INTERRUPTED.load(Ordering::Relaxed) {
        return Err(interrupted());
    }
    save_session(&args.out, &session)
        .map_err(|e| CliError::Output(format!("{}: {e}", args.out.display())))?;
    say!("wrote {}", args.out.display());
    if let Some((path, format, mesh)) = mesh {
        write_fitted_mesh(&mesh, path, format)?;
    }
    Ok(())
}

/// The clay of a fitted multi-patch field: its density is the field, with no paint and no pins.
fn clay_from_field(field: MultiPatchField) -> Clay {
    Clay {
        density: field,
        colour: None,
        constraints: Vec::new(),
    }
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

/// Reads a point cloud and fits it hierarchically; reports the levels and how far the
/// points lie from the fitted surface.
fn import_cloud(args: &ImportArgs) -> Result<MultiPatchField, CliError> {
    let cloud = read_points(&args.input).map_err(|e| CliError::Usage(e.to_string()))?;
    let options = HierarchyOptions {
        base: CloudFitOptions {
            resolution: args.resolution,
            gap_spans: args.gap,
            ..CloudFitOptions::default()
        },
        error: args.error / 100.0,
        max_depth: args.max_depth,
    };
    say!(
        "dynaclay import: {} points{} from {}, fitting a {}³ clay with detail patches down to \
         depth {} where the error is above {}% of its size",
        cloud.points.len(),
        if cloud.normals.is_some() {
            " with normals"
        } else {
            ""
        },
        args.input.display(),
        options.base.resolution,
        options.max_depth,
        args.error
    );
    let bar = progress_bar();
    let fit = fit_hierarchy(&cloud, &options, &mut |stage| show_progress(&bar, stage));
    bar.finish_and_clear();
    let fit = fit.map_err(|e| match e {
        CloudFitError::Options(m) => CliError::Usage(m),
        CloudFitError::Interrupted => interrupted(),
        other => CliError::Output(format!("{}: {other}", args.input.display())),
    })?;
    for level in &fit.levels {
        say!(
            "depth {}: {} of {} octree nodes refined",
            level.depth,
            level.refined,
            level.nodes
        );
    }
    // How far the points lie from the fitted surface, to first order: |F − iso| / |∇F|.
    let (mut sum, mut worst) = (0.0f64, 0.0f32);
    for &p in &cloud.points {
        let (v, g) = fit.field.value_and_gradient(fit.to_field(p));
        let d = (v - fit.field.iso()).abs() / g.length().max(1e-6);
        sum += f64::from(d);
        worst = worst.max(d);
    }
    let percent = |d: f32| 100.0 * d / fit.size;
    say!(
        "signed by {}; {} patches; RMS error {:.3}% of the size ({:.3}% with the base alone); \
         points lie {:.3}% of the size from the surface on average, {:.3}% at most",
        match fit.signed_by {
            SignedBy::Normals => "the normals",
            SignedBy::Tagging => "flood tagging",
        },
        fit.field.patches.len(),
        100.0 * fit.rms,
        100.0 * fit.rms_base,
        percent((sum / cloud.points.len() as f64) as f32),
        percent(worst)
    );
    Ok(fit.field)
}

/// Reads and fits a volume at `args.iso`, hierarchically as a cloud is.
fn import_volume(args: &ImportArgs, nrrd: bool) -> Result<MultiPatchField, CliError> {
    let iso = args.iso.ok_or_else(|| {
        CliError::Usage("a volume needs --iso V: the intensity of its surface".into())
    })?;
    let volume: Volume = if nrrd {
        read_nrrd(&args.input)
    } else {
        let dims = args.dims.ok_or_else(|| {
            CliError::Usage("a raw volume needs --dims X,Y,Z (voxels per axis)".into())
        })?;
        let sample = match args.sample {
            RawSample::U8 => Sample::U8,
            RawSample::U16 => Sample::U16,
            RawSample::I16 => Sample::I16,
            RawSample::F32 => Sample::F32,
        };
        read_raw(&args.input, dims, sample)
    }
    .map_err(|e| CliError::Usage(e.to_string()))?;
    say!(
        "dynaclay import: a {}×{}×{} volume from {}, surface at {iso}, fitting a {}³ clay",
        volume.dims[0],
        volume.dims[1],
        volume.dims[2],
        args.input.display(),
        args.resolution
    );
    let options = HierarchyOptions {
        error: args.error / 100.0,
        max_depth: args.max_depth,
        ..HierarchyOptions::default()
    };
    let bar = progress_bar();
    let fit = fit_volume_hierarchy(
        &volume,
        iso,
        args.resolution,
        crate::engine::CLAY_SPACING,
        &options,
        &mut |stage| show_progress(&bar, stage),
    );
    bar.finish_and_clear();
    let fit = fit.map_err(|e| match e {
        CloudFitError::Options(m) => CliError::Usage(m),
        CloudFitError::Interrupted => interrupted(),
        other => CliError::Output(format!("{}: {other}", args.input.display())),
    })?;
    for level in &fit.levels {
        say!(
            "depth {}: {} of {} octree nodes refined",
            level.depth,
            level.refined,
            level.nodes
        );
    }
    say!(
        "{} patches; RMS error near the surface {:.3}% of the volume's size ({:.3}% with the \
         base alone)",
        fit.field.patches.len(),
        100.0 * fit.rms,
        100.0 * fit.rms_base
    );
    Ok(fit.field)
}

fn write_fitted_mesh(mesh: &TriMesh, path: &Path, format: MeshFormat) -> Result<(), CliError> {
    write_mesh(path, mesh, format)
        .map_err(|e| CliError::Output(format!("{}: {e}", path.display())))?;
    say!(
        "wrote {} ({} vertices, {} triangles)",
        path.display(),
        mesh.vertex_count(),
        mesh.triangle_count()
    );
    Ok(())
}
