//! `dynaclay points`: a point cloud becomes a point-set surface (Guo & Qin), is optionally
//! pulled by the density-spring dynamics with dynamic sampling, and is written as PLY with
//! normals (and, when asked, the blended surface as a mesh); an image can be embossed or
//! engraved onto it first.

use std::path::Path;

use glam::Vec3;

use super::args::{EmbossProjection, PointsArgs};
use super::error::CliError;
use crate::fit::read_points;
use crate::io::{OutputKind, OutputRule};
use crate::mesh::{BrickOctree, MeshFormat, SampleGrid, write_mesh};
use crate::pointset::{PointSet, PointSetOptions, UnitFrame, write_point_ply};
use crate::tools::{EmbossParams, Projection};

/// How far a `--pull` target may lie from the points' box, in sizes of the box (its longest
/// side).
const MAX_PULL_REACH: f32 = 1.0;

/// Most mesh cells per axis.
const MAX_MESH_CELLS: u32 = 512;

/// What `dynaclay points` made.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointsOutcome {
    /// Points read.
    pub read: usize,
    /// Points written.
    pub written: usize,
    /// The sampling spacing.
    pub spacing_file_units: f32,
    /// Construction time, seconds.
    pub build_s: f64,
}

/// Runs `dynaclay points`.
///
/// # Errors
/// A bad argument or unreadable input (exit 2), a failed build, sculpt or write (exit 1).
pub fn points(args: &PointsArgs) -> Result<PointsOutcome, CliError> {
    let mut rule = OutputRule::new().input("INPUT", &args.input);
    if let Some(image) = &args.emboss {
        rule = rule.input("--emboss", image);
    }
    rule.check("--out", &args.out, OutputKind::PointSet)
        .map_err(CliError::OutputRefused)?;
    if let Some(mesh) = &args.mesh {
        // Both may be .ply: the mesh must not take the points' file either.
        rule.input("--out", &args.out)
            .check("--mesh", mesh, OutputKind::Mesh)
            .map_err(CliError::OutputRefused)?;
    }
    let mesh_format = match &args.mesh {
        Some(path) => Some(MeshFormat::from_path(path).ok_or_else(|| {
            CliError::Usage(format!(
                "--mesh {}: the extension must be .obj, .ply or .stl",
                path.display()
            ))
        })?),
        None => None,
    };
    let cloud = read_points(&args.input).map_err(|e| CliError::bad_input("points", e))?;
    let options = PointSetOptions {
        neighbours: args.neighbours as usize,
        ..PointSetOptions::default()
    };
    // Built in the cloud's unit frame, so that any file units work; every output goes back.
    let frame = UnitFrame::of(&cloud.points);
    let (mut set, times) = PointSet::build(&frame.cloud_to_unit(&cloud), &options)
        .map_err(|e| CliError::bad_input(args.input.display().to_string(), e))?;
    let build_s = times.total_ns() as f64 * 1e-9;
    say!(
        "{}: {} points, spacing {:.4e}, built in {:.3} s",
        args.input.display(),
        set.len(),
        set.spacing_fu * frame.scale,
        build_s
    );
    // A pull reaches at most MAX_PULL_REACH of the cloud's sizes from its box, checked for
    // every pull before the first.
    let (lo, hi) = set.bounds();
    let size = (hi - lo).max_element();
    for target in &args.pull {
        let target = Vec3::from(*target);
        let unit = frame.to_unit(target);
        let away = (unit.clamp(lo, hi) - unit).length();
        if !(unit.is_finite() && away <= MAX_PULL_REACH * size) {
            return Err(CliError::Usage(format!(
                "--pull {},{},{}: lies {:.3e} from the points' box, past the {MAX_PULL_REACH} \
                 box sizes ({:.3e}) a pull reaches",
                target.x,
                target.y,
                target.z,
                away * frame.scale,
                MAX_PULL_REACH * size * frame.scale
            )));
        }
    }
    for target in &args.pull {
        pull(&mut set, &frame, Vec3::from(*target), args.steps)?;
    }
    if let Some(image) = &args.emboss {
        set = emboss_image(&set, &frame, image, args, &options)?;
    }
    if let (Some(path), Some(format)) = (&args.mesh, mesh_format) {
        let (lo, hi) = set.bounds();
        let cell = 0.75 * set.spacing_fu;
        let cells = ((hi - lo) / cell).ceil() + Vec3::splat(2.0);
        if cells.max_element() > MAX_MESH_CELLS as f32 {
            return Err(CliError::Usage(format!(
                "--mesh: the surface spans {} cells of {cell:.4} (at most {MAX_MESH_CELLS}); \
                 thin the cloud first",
                cells.max_element()
            )));
        }
        let grid = SampleGrid::new(
            lo - Vec3::splat(cell),
            cell,
            [cells.x as u32, cells.y as u32, cells.z as u32],
        )
        .map_err(|e| CliError::output("the point set's sampling grid", e))?;
        let mut mesh = BrickOctree::build(grid, &set).weld();
        for v in &mut mesh.positions {
            *v = frame.to_file(*v);
        }
        write_mesh(path, &mesh, format)
            .map_err(|e| CliError::output(path.display().to_string(), e))?;
        say!("{}: {} triangles", path.display(), mesh.triangle_count());
    }
    let points: Vec<Vec3> = set.points.iter().map(|&p| frame.to_file(p)).collect();
    write_point_ply(&args.out, &points, &set.normals, &set.colours)
        .map_err(|e| CliError::output(args.out.display().to_string(), e))?;
    say!("{}: {} points with normals", args.out.display(), set.len());
    Ok(PointsOutcome {
        read: cloud.points.len(),
        written: set.len(),
        spacing_file_units: set.spacing_fu * frame.scale,
        build_s,
    })
}

/// Embosses `image` onto `set` as `args` say (`--depth`, `--engrave`, `--projection`).
fn emboss_image(
    set: &PointSet,
    frame: &UnitFrame,
    image: &Path,
    args: &PointsArgs,
    options: &PointSetOptions,
) -> Result<PointSet, CliError> {
    let relief = crate::io::load_relief(image).map_err(|e| CliError::bad_input("--emboss", e))?;
    let (lo, hi) = set.points.iter().fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(lo, hi), &p| (lo.min(p), hi.max(p)),
    );
    let centre = 0.5 * (lo + hi);
    let projection = match args.projection {
        EmbossProjection::Spherical => Projection::Spherical {
            centre,
            up: Vec3::Y,
        },
        EmbossProjection::Cylindrical => Projection::Cylindrical {
            centre,
            axis: Vec3::Y,
            up: Vec3::Z,
            height_fu: (hi - lo).y.max(set.spacing_fu),
        },
        EmbossProjection::Planar => Projection::Planar {
            centre,
            axis: Vec3::Z,
            up: Vec3::Y,
            size_fu: (hi - lo).max_element().max(set.spacing_fu),
        },
    };
    let params = EmbossParams {
        projection,
        depth_fu: args.depth.map_or(2.0 * set.spacing_fu, |d| d / frame.scale),
        engrave: args.engrave,
    };
    let (embossed, report) = crate::pointset::emboss(set, &relief, &params, options)
        .map_err(|e| CliError::bad_input(format!("--emboss {}", image.display()), e))?;
    say!(
        "{} {}: {} points moved, by at most {:.4}",
        if args.engrave { "engraved" } else { "embossed" },
        image.display(),
        report.moved,
        report.largest * frame.scale
    );
    Ok(embossed)
}

/// Drags the surface point nearest to `target` there ([`crate::pointset::pull`]).
fn pull(set: &mut PointSet, frame: &UnitFrame, target: Vec3, steps: u32) -> Result<(), CliError> {
    let report = crate::pointset::pull(set, frame.to_unit(target), steps).map_err(|e| match e {
        crate::pointset::PointSetError::PullTooFar { .. } => CliError::Usage(format!(
            "--pull {},{},{}: {e}",
            target.x, target.y, target.z
        )),
        e => CliError::output("--pull", e),
    })?;
    say!(
        "pull to {target}: {} points in the region, {} points in all",
        report.in_region,
        report.points
    );
    Ok(())
}
