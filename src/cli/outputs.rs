//! The files a headless run leaves behind: meshes, the session, latency reports, and on
//! request a PNG of the sculpt.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use dynaclay_loops::{LoopSummary, ProfileDoc, latency_png, latency_svg, profile_report};

use super::args::ImageArgs;
use super::error::CliError;
use super::platform::PlatformJudged;
use super::sculpt::{describe_outcome, render_sculpt};
use crate::engine::{EngineConfig, EngineReport, LockstepReport};
use crate::io::{Session, save_session, write_atomic};
use crate::mesh::{
    AdaptiveMeshError, AdaptiveMeshOptions, BrickOctree, MeshFormat, MeshStats, SampleGrid,
    mesh_adaptive, write_mesh,
};
use crate::render::RenderOutcome;

/// The optional outputs of a run, besides `sculpt.obj`, the session and the latency reports.
#[derive(Clone, Debug)]
pub struct ExtraOutputs {
    /// Also write `sculpt.ply`.
    pub ply: bool,
    /// Also write `sculpt.stl`.
    pub stl: bool,
    /// Render the final sculpt to this PNG with these settings.
    pub png: Option<(PathBuf, ImageArgs)>,
}

/// Paths written by a run, and the final mesh's statistics.
#[derive(Clone, Debug)]
pub struct RunOutputs {
    /// Every file written.
    pub files: Vec<PathBuf>,
    /// Statistics of the exported mesh.
    pub mesh: MeshStats,
    /// Loop summaries.
    pub loops: Vec<LoopSummary>,
    /// The PNG of the sculpt, when one was asked for and rendered.
    pub image: Option<RenderOutcome>,
    /// Outputs that were asked for but skipped, each with the reason (no GPU adapter).
    pub skipped: Vec<String>,
}

impl RunOutputs {
    /// A short human-readable account.
    #[must_use]
    pub fn describe(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(
            s,
            "mesh: {} vertices, {} triangles, closed: {}",
            self.mesh.vertices,
            self.mesh.triangles,
            self.mesh.is_closed_manifold()
        );
        for f in &self.files {
            match &self.image {
                Some(image) if &image.path == f => {
                    let _ = writeln!(s, "{}", describe_outcome(image));
                }
                _ => {
                    let _ = writeln!(s, "wrote {}", f.display());
                }
            }
        }
        for reason in &self.skipped {
            let _ = writeln!(s, "{reason}");
        }
        s
    }
}

fn out_err(path: &Path, e: impl Into<Box<dyn std::error::Error + Send + Sync>>) -> CliError {
    CliError::output(path.display().to_string(), e)
}

/// Writes the meshes and the session of a lockstep (replay) run, then the PNG if asked; a
/// lockstep run has no loop latencies to report.
///
/// # Errors
/// [`CliError::Output`] naming the file that could not be written; [`CliError::Render`] when
/// the PNG was asked for and rendering failed for a reason other than a missing GPU adapter.
pub fn write_lockstep_outputs(
    dir: &Path,
    report: &LockstepReport,
    config: &EngineConfig,
    extras: &ExtraOutputs,
) -> Result<RunOutputs, CliError> {
    let mut files = Vec::new();
    let (stats, octree) = write_field_outputs(dir, &report.session, config, extras, &mut files)?;
    let mut outputs = RunOutputs {
        files,
        mesh: stats,
        loops: Vec::new(),
        image: None,
        skipped: Vec::new(),
    };
    write_png(&mut outputs, &octree, &report.session, extras)?;
    Ok(outputs)
}

/// Renders the sculpt when `extras` asks for a PNG. A missing GPU adapter is not an error
/// here: the reason goes to [`RunOutputs::skipped`] and the run succeeds.
fn write_png(
    outputs: &mut RunOutputs,
    octree: &BrickOctree,
    session: &Session,
    extras: &ExtraOutputs,
) -> Result<(), CliError> {
    let Some((path, image)) = &extras.png else {
        return Ok(());
    };
    match render_sculpt(octree, session.clay.colour.as_ref(), image, path) {
        Ok(outcome) => {
            outputs.files.push(outcome.path.clone());
            outputs.image = Some(outcome);
            Ok(())
        }
        Err(e) if e.is_no_adapter() => {
            // The same wording as `dynaclay render`, but the run itself succeeds.
            let reason = CliError::Render(e, path.clone()).to_string();
            outputs.skipped.push(reason);
            Ok(())
        }
        Err(e) => Err(CliError::Render(e, path.clone())),
    }
}

fn write_field_outputs(
    dir: &Path,
    session: &Session,
    config: &EngineConfig,
    extras: &ExtraOutputs,
    files: &mut Vec<PathBuf>,
) -> Result<(MeshStats, BrickOctree), CliError> {
    // The session first: a mesh that cannot be made never costs the sculpt.
    let session_path = dir.join("session.dclay");
    let mut session = session.clone();
    session.meta.saved_unix_s = crate::io::unix_now_s();
    crate::io::check_replaceable(&session_path)
        .map_err(|e| CliError::output(session_path.display().to_string(), e))?;
    save_session(&session_path, &session).map_err(|e| out_err(&session_path, e))?;
    files.push(session_path);

    let density = &session.clay.density;
    // Mesh the final field afresh (every patch, summed): the export is exactly the
    // simulation's last state. The octree (for the picture) follows one grid; a clay with
    // patches finer than that grid is exported from the adaptive mesh, each level at its own
    // spacing.
    let grid =
        SampleGrid::for_field(density, config.cells_per_span).map_err(|e| out_err(dir, e))?;
    let octree = BrickOctree::build(grid, density);
    let mesh = if density.finest_spacing() < SampleGrid::uniform_spacing(density) {
        // Two cells per span of each level: the dual vertices sit on the surface (projected
        // along the gradient), so the coarse levels stay true at two.
        match mesh_adaptive(density, &AdaptiveMeshOptions::default()) {
            Ok(mesh) => mesh,
            Err(e @ AdaptiveMeshError::OverBudget { .. }) => {
                // The mesh still comes out, on the one grid, and says what it lost.
                eprintln!(
                    "dynaclay: warning: {e}; exporting on one grid {} levels below the base \
                     instead (finer detail is drawn at that grid's size)",
                    SampleGrid::UNIFORM_LEVELS
                );
                octree.weld()
            }
            Err(e) => return Err(out_err(dir, e)),
        }
    } else {
        octree.weld()
    };
    let stats = MeshStats::of(&mesh);
    let mut formats = vec![("sculpt.obj", MeshFormat::Obj)];
    if extras.ply {
        formats.push(("sculpt.ply", MeshFormat::Ply));
    }
    if extras.stl {
        formats.push(("sculpt.stl", MeshFormat::Stl));
    }
    for (name, format) in formats {
        let path = dir.join(name);
        write_mesh(&path, &mesh, format).map_err(|e| out_err(&path, e))?;
        files.push(path);
    }

    Ok((stats, octree))
}

/// Writes `sculpt.obj` (and `.ply`/`.stl`), `session.dclay`, `latency.json`, `latency.md`,
/// `latency.svg` and `latency.png` into `dir`, then the PNG if asked. With `platform` (the
/// probe run around the loops), `latency.json` and `latency.md` hold the probe beside the
/// haptic loop and the readiness verdict, and the plots draw the probe over the loops; with
/// `motion`, both hold the motion-to-photon figures (hand → force, first visible change,
/// settled shape, per stroke). Every
/// file goes through the one atomic writer ([`dynaclay_files::write_atomic`]): a full disk
/// leaves the old file whole, and a link, device, FIFO or directory at an output's name is
/// refused, never written through.
///
/// # Errors
/// [`CliError::Output`] naming the file that could not be written; [`CliError::Render`] when
/// the PNG was asked for and rendering failed for a reason other than a missing GPU adapter.
pub fn write_outputs(
    dir: &Path,
    report: &EngineReport,
    config: &EngineConfig,
    extras: &ExtraOutputs,
    platform: Option<&PlatformJudged>,
    motion: Option<&dynaclay_loops::MotionToPhotonSummary>,
) -> Result<RunOutputs, CliError> {
    let mut files = Vec::new();
    let (stats, octree) = write_field_outputs(dir, &report.session, config, extras, &mut files)?;

    let summaries: Vec<LoopSummary> = report.loops.iter().map(|r| r.summary()).collect();
    let doc = match platform {
        Some(judged) => ProfileDoc {
            loops: summaries.clone(),
            ..judged.doc.clone()
        },
        None => ProfileDoc {
            loops: summaries.clone(),
            ..ProfileDoc::default()
        },
    };
    let doc = ProfileDoc {
        motion_to_photon: motion.cloned(),
        ..doc
    };
    let json_path = dir.join("latency.json");
    let json = doc.to_json().map_err(|e| out_err(&json_path, e))?;
    write_atomic(&json_path, json.as_bytes()).map_err(|e| out_err(&json_path, e))?;
    files.push(json_path);

    let md_path = dir.join("latency.md");
    let mut md = String::from("# dynaclay run: loop latency\n\n");
    md.push_str(&profile_report(&doc));
    let c = report.counters;
    let _ = write!(
        md,
        "\n## Engine counters\n\n| counter | value |\n| --- | ---: |\n\
         | haptic ticks | {} |\n| contact ticks | {} |\n| stale ticks | {} |\n\
         | device read faults | {} |\n| device write faults | {} |\n\
         | peak force (mN) | {} |\n| simulation steps | {} |\n| rejected steps | {} |\n\
         | snapshots published | {} |\n| graphics updates | {} |\n| bricks re-meshed | {} |\n\
         | haptic ticks awaiting spare bricks | {} |\n",
        c.haptic_ticks,
        c.contact_ticks,
        c.stale_ticks,
        c.device_read_faults,
        c.device_write_faults,
        c.peak_force_milli_n,
        c.sim_steps,
        c.sim_nonfinite_rejected,
        c.snapshots_published,
        c.graphics_updates,
        c.bricks_remeshed,
        c.haptic_updates_awaiting_bricks
    );
    write_atomic(&md_path, md.as_bytes()).map_err(|e| out_err(&md_path, e))?;
    files.push(md_path);

    let svg_path = dir.join("latency.svg");
    let recorders: Vec<(&str, &dynaclay_loops::LatencyRecorder)> = report
        .loops
        .iter()
        .map(|r| (r.config.name.as_str(), &r.recorder))
        .collect();
    let probe = platform.map(PlatformJudged::worse_probe);
    let svg = latency_svg(&recorders, probe).map_err(|e| out_err(&svg_path, e))?;
    write_atomic(&svg_path, svg.as_bytes()).map_err(|e| out_err(&svg_path, e))?;
    files.push(svg_path);
    let png_path = dir.join("latency.png");
    let png = latency_png(&recorders, probe).map_err(|e| out_err(&png_path, e))?;
    write_atomic(&png_path, &png).map_err(|e| out_err(&png_path, e))?;
    files.push(png_path);

    let mut outputs = RunOutputs {
        files,
        mesh: stats,
        loops: summaries,
        image: None,
        skipped: Vec::new(),
    };
    write_png(&mut outputs, &octree, &report.session, extras)?;
    Ok(outputs)
}
