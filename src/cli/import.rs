//! `dynaclay import`: a point cloud or a volume becomes a session whose clay is fitted to it.

use std::path::Path;

use super::args::{ImportArgs, RawSample};
use super::budget::MemoryBudget;
use super::run::CliError;
use crate::dynamics::Material;
use crate::field::BSplineLattice;
use crate::fit::{
    CloudFitError, CloudFitOptions, Sample, SignedBy, Volume, fit_point_cloud, fit_volume,
    read_nrrd, read_points, read_raw,
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
    let lattice = match ext.as_deref() {
        Some("raw" | "nrrd") => import_volume(args, ext.as_deref() == Some("nrrd"))?,
        _ => import_cloud(args)?,
    };
    let name = args
        .input
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or("import")
        .to_owned();
    let session = Session {
        clay: Clay::single(lattice),
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
    save_session(&args.out, &session)
        .map_err(|e| CliError::Output(format!("{}: {e}", args.out.display())))?;
    say!("wrote {}", args.out.display());
    if let Some((path, format, mesh)) = mesh {
        write_fitted_mesh(&mesh, path, format)?;
    }
    Ok(())
}

/// Reads and fits a point cloud; reports how far its points lie from the fitted surface.
fn import_cloud(args: &ImportArgs) -> Result<BSplineLattice, CliError> {
    let cloud = read_points(&args.input).map_err(|e| CliError::Usage(e.to_string()))?;
    let options = CloudFitOptions {
        resolution: args.resolution,
        gap_spans: args.gap,
        ..CloudFitOptions::default()
    };
    say!(
        "dynaclay import: {} points{} from {}, fitting a {}³ clay",
        cloud.points.len(),
        if cloud.normals.is_some() {
            " with normals"
        } else {
            ""
        },
        args.input.display(),
        options.resolution
    );
    let fit = fit_point_cloud(&cloud, &options).map_err(|e| match e {
        CloudFitError::Options(m) => CliError::Usage(m),
        other => CliError::Output(format!("{}: {other}", args.input.display())),
    })?;
    // How far the points lie from the fitted surface, to first order: |s − iso| / |∇s|.
    let (mut sum, mut worst) = (0.0f64, 0.0f32);
    for &p in &cloud.points {
        let (v, g) = fit.lattice.value_and_gradient(fit.to_field(p));
        let d = (v - fit.lattice.iso).abs() / g.length().max(1e-6);
        sum += f64::from(d);
        worst = worst.max(d);
    }
    let spans = |d: f32| d / fit.lattice.spacing;
    say!(
        "signed by {}; points lie {:.3} spans from the surface on average, {:.3} at most",
        match fit.signed_by {
            SignedBy::Normals => "the normals",
            SignedBy::Tagging => "flood tagging",
        },
        spans((sum / cloud.points.len() as f64) as f32),
        spans(worst)
    );
    Ok(fit.lattice)
}

/// Reads and fits a volume at `args.iso`.
fn import_volume(args: &ImportArgs, nrrd: bool) -> Result<BSplineLattice, CliError> {
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
    let fit = fit_volume(&volume, iso, args.resolution, crate::engine::CLAY_SPACING).map_err(
        |e| match e {
            CloudFitError::Options(m) => CliError::Usage(m),
            other => CliError::Output(format!("{}: {other}", args.input.display())),
        },
    )?;
    Ok(fit.lattice)
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
