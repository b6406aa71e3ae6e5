//! One import for `dynaclay import` and the GUI's Load: a file is read by its extension (point
//! clouds `.ply`/`.xyz`/`.txt`/`.pts`, meshes `.obj`/`.stl`, volumes `.nrrd` and, with their
//! dimensions given, `.raw`), fitted hierarchically ([`fit_hierarchy`],
//! [`fit_volume_hierarchy`]) and made into a session whose clay is the fitted field.
//!
//! A mesh takes one of two paths ([`FitPath`]): a closed one (every edge shared by two
//! triangles, after welding, [`super::watertight`]) is fitted from its signed distance on a grid
//! ([`super::sdf`]) by the volume fit; an open one whose holes are capped
//! ([`super::holes`]: none wider than half its size) takes the same path, and any other is
//! sampled into a point cloud and fitted as a scan. The log names the path and, for an open
//! mesh, why it is open and what was capped.
//!
//! The caller watches the fit through two callbacks: `progress` sees each stage (and stops the
//! fit by answering `false`), `note` receives one line per report (what was read, the levels,
//! the error reached), so the CLI prints them and the GUI shows them in its log.

use std::path::Path;
use std::time::Instant;

use glam::Vec3;

use super::cloud::{
    CloudFitError, CloudFitOptions, DEFAULT_GAP_SPANS, GivenNormals, MARGIN_SPANS, MAX_GAP_SPANS,
    SignedBy,
};
use super::consensus::parallel_map;
use super::hierarchy::{
    DEFAULT_ERROR, DEFAULT_MAX_DEPTH, FitProgress, HierarchyOptions, LevelReport, MAX_DEPTH,
    fit_hierarchy,
};
use super::holes::cap_holes;
use super::mesh::{read_mesh, sample_triangles};
use super::paint::{NEIGHBOURS, paint_from_cloud};
use super::point_file::read_points_about_their_centre;
use super::points::{PointCloud, PointColours, PointsError};
use super::sdf::{MAX_SDF_VOXELS, SdfGrid, signed_distance};
use super::stage_times::{StageTime, StageTimes};
use super::thinning::{MAX_FITTED_POINTS, thin_for_span};
use super::volume::{
    Sample, Volume, VolumeError, fit_volume_hierarchy, fit_volume_hierarchy_within, read_nrrd,
    read_raw,
};
use super::watertight::{MeshCheck, check_closed};
use dynaclay_core::dynamics::Material;
use dynaclay_core::field::MultiPatchField;
use dynaclay_core::io::{MaterialFields, Session, SessionMeta};
use dynaclay_core::tools::{Clay, ColourField};

/// The extensions [`fit_file`] reads (lower case).
pub const IMPORT_EXTENSIONS: [&str; 8] = ["ply", "xyz", "txt", "pts", "obj", "stl", "nrrd", "raw"];

/// Knots per axis of the base lattice unless the points choose it
/// ([`ImportSettings::resolution_from_points`]).
pub const DEFAULT_RESOLUTION: usize = 32;
/// The point count at which a cloud's base lattice has [`RESOLUTION_AT_REFERENCE`] knots per
/// axis (see [`resolution_for_points`]).
pub const REFERENCE_POINTS: usize = 50_000;
/// Knots per axis of a cloud of [`REFERENCE_POINTS`] points: the finest lattice whose fit
/// stays within 1.2 KB per point (the fit and its mesh peaked at 0.9–1.0 KB per point on
/// 50 000-point scans at 40 knots, 1.16 KB at 44, 0.55–0.65 KB at 32; the whole
/// `dynaclay import`, writing its session and mesh, at 1.0–1.07 KB at 40 knots).
pub const RESOLUTION_AT_REFERENCE: f32 = 40.0;
/// Knots per axis of a cloud of [`REFERENCE_POINTS`] points at most, when its noise is low
/// enough to want them ([`most_resolution_for_points`]): the fit and its mesh took 1.0–1.1 KB
/// per point on the peers bench's 50 000-point clouds at 44 knots (the issue's bound 1.2 KB).
pub const MOST_RESOLUTION_AT_REFERENCE: f32 = 44.0;
/// The finest base lattice the point count alone chooses, knots per axis (finer is asked for
/// with `--resolution`): its fit takes about twice the time of the 40-knot one.
pub const MAX_POINTS_RESOLUTION: usize = 48;

/// Knots per axis of the base lattice for a cloud of `points` points:
/// [`RESOLUTION_AT_REFERENCE`] at [`REFERENCE_POINTS`], growing with the cube root of the
/// count so that the lattice's memory per point stays the same, never below
/// [`DEFAULT_RESOLUTION`] nor above [`MAX_POINTS_RESOLUTION`].
///
/// Why the count: a denser scan holds the surface at a finer scale, and the base lattice is
/// what rounds a small radius (a cubic B-spline cannot bend tighter than about a knot span);
/// on a 50 000-point scan of a mechanical part the 32-knot lattice left the surface about 2.2
/// times farther from the part (median) than screened Poisson, the 40-knot one about 1.1 times.
///
/// # Examples
/// ```
/// use dynaclay_import::fit::import::resolution_for_points;
/// assert_eq!(resolution_for_points(1_000), 32);
/// assert_eq!(resolution_for_points(50_000), 40);
/// assert_eq!(resolution_for_points(1_000_000), 48);
/// ```
#[must_use]
pub fn resolution_for_points(points: usize) -> usize {
    knots_for_count(points, RESOLUTION_AT_REFERENCE)
}

/// The most knots per axis of the base lattice a cloud of `points` points affords, the
/// noise choosing fewer ([`super::cloud::knots_for_noise`], from [`resolution_for_points`]):
/// [`MOST_RESOLUTION_AT_REFERENCE`] at [`REFERENCE_POINTS`], growing with the cube root of the
/// count so that the lattice's memory per point stays the same, within the same bounds.
///
/// # Examples
/// ```
/// use dynaclay_import::fit::import::most_resolution_for_points;
/// assert_eq!(most_resolution_for_points(1_000), 32);
/// assert_eq!(most_resolution_for_points(50_000), 44);
/// assert_eq!(most_resolution_for_points(1_000_000), 48);
/// ```
#[must_use]
pub fn most_resolution_for_points(points: usize) -> usize {
    knots_for_count(points, MOST_RESOLUTION_AT_REFERENCE)
}

/// `at_reference` knots at [`REFERENCE_POINTS`], times the cube root of `points` over it,
/// from [`DEFAULT_RESOLUTION`] to [`MAX_POINTS_RESOLUTION`].
fn knots_for_count(points: usize, at_reference: f32) -> usize {
    let ratio = points as f64 / REFERENCE_POINTS as f64;
    let knots = (f64::from(at_reference) * ratio.cbrt()).round();
    // Clamped as a float first: the cube root of any count is far below usize's range.
    knots.clamp(DEFAULT_RESOLUTION as f64, MAX_POINTS_RESOLUTION as f64) as usize
}

/// How a file is fitted. [`ImportSettings::default`] is `dynaclay import`'s defaults.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImportSettings {
    /// Knots per axis of the base lattice (of a point-cloud file, only when
    /// [`ImportSettings::resolution_from_points`] is off).
    pub resolution: usize,
    /// A point-cloud file's base lattice has [`resolution_for_points`] knots per axis (from
    /// its point count) instead of [`ImportSettings::resolution`]. On by default; off when
    /// `dynaclay import` is given `--resolution`. Meshes and volumes always take
    /// [`ImportSettings::resolution`].
    pub resolution_from_points: bool,
    /// Gap bridged by the tagging of unoriented clouds, in knot spans.
    pub gap_spans: f32,
    /// Error bound of the hierarchy, percent of the object's size.
    pub error_percent: f32,
    /// Deepest octree level of detail patches.
    pub max_depth: u32,
    /// A point cloud's noise (standard deviation across the surface), percent of the
    /// object's size; estimated from the cloud when `None`.
    pub noise_percent: Option<f32>,
    /// A volume's surface intensity.
    pub iso: Option<f32>,
    /// Without [`ImportSettings::iso`]: fit a volume at the middle of its intensity range
    /// (the GUI) instead of refusing it (the CLI, which asks for `--iso`).
    pub midrange_iso: bool,
    /// A raw volume's voxels per axis and sample type (a raw file says neither).
    pub raw: Option<([usize; 3], Sample)>,
}

impl Default for ImportSettings {
    fn default() -> Self {
        Self {
            resolution: DEFAULT_RESOLUTION,
            resolution_from_points: true,
            gap_spans: DEFAULT_GAP_SPANS,
            error_percent: DEFAULT_ERROR * 100.0,
            max_depth: DEFAULT_MAX_DEPTH,
            noise_percent: None,
            iso: None,
            midrange_iso: false,
            raw: None,
        }
    }
}

/// Why a file was not imported.
#[derive(Debug, thiserror::Error)]
pub enum ImportError {
    /// The extension names no importable format.
    #[error(
        "{}: unknown format (import reads point clouds .ply .xyz, meshes .obj .stl, volumes .nrrd .raw)",
        file.display()
    )]
    UnknownFormat {
        /// The file.
        file: std::path::PathBuf,
    },
    /// A volume without a surface intensity.
    #[error("a volume needs --iso V: the intensity of its surface")]
    NeedsIso,
    /// A raw volume without its dimensions.
    #[error("a raw volume needs --dims X,Y,Z (voxels per axis)")]
    NeedsDims,
    /// A volume whose intensities are all equal has no surface.
    #[error("{}: every voxel has the same intensity: no surface to fit", file.display())]
    FlatVolume {
        /// The file.
        file: std::path::PathBuf,
    },
    /// The point, mesh or cloud file is bad (the error names the file and where).
    #[error(transparent)]
    Points(#[from] PointsError),
    /// The volume file is bad (the error names the file and where).
    #[error(transparent)]
    Volume(#[from] VolumeError),
    /// Settings out of range.
    #[error("{0}")]
    Options(String),
    /// A closed mesh's signed-distance grid could not be laid out.
    #[error("{0}")]
    SdfGrid(#[from] super::sdf::SdfGridError),
    /// The fit failed.
    #[error("{}: {source}", file.display())]
    Fit {
        /// The file.
        file: std::path::PathBuf,
        /// Why.
        source: CloudFitError,
    },
    /// `progress` asked the fit to stop.
    #[error("the fit was stopped; nothing was imported")]
    Interrupted,
}

/// Whether `path`'s extension is one [`fit_file`] reads.
#[must_use]
pub fn is_importable(path: &Path) -> bool {
    extension(path).is_some_and(|e| IMPORT_EXTENSIONS.contains(&e.as_str()))
}

fn extension(path: &Path) -> Option<String> {
    path.extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
}

/// Which way a file was fitted.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FitPath {
    /// A point cloud file, fitted as a scan.
    Cloud,
    /// An open mesh (see the check), sampled into a point cloud and fitted as a scan.
    OpenMesh(MeshCheck),
    /// A closed mesh, fitted from its signed distance on a grid.
    ClosedMesh(MeshCheck),
    /// An open mesh whose holes were capped ([`super::holes`]), then fitted as a closed one;
    /// the check is the mesh's as read.
    CappedMesh(MeshCheck),
    /// A volume, fitted at its iso-surface.
    Volume,
}

/// A fitted clay, the path that made it, and where the file went in the clay.
#[derive(Clone, Debug)]
pub struct ImportedFit {
    /// The base (patch 0) and the detail patches.
    pub field: MultiPatchField,
    /// How the file was fitted.
    pub path: FitPath,
    /// Field units per file unit (a volume's file unit is its voxel).
    pub scale: f32,
    /// Field position of the file's origin: `field = file · scale + offset`.
    pub offset: Vec3,
    /// The wall time of each stage of a point cloud's fit (empty for a mesh fitted by its
    /// signed distance, or a volume).
    pub times: StageTimes,
}

impl ImportedFit {
    /// A file-unit point in field units.
    #[must_use]
    pub fn to_field(&self, p: Vec3) -> Vec3 {
        p * self.scale + self.offset
    }

    /// Where the file lies in the clay, the file's points read about `origin` (see
    /// [`ImportedCloud::origin`]; zero for a mesh or a volume).
    #[must_use]
    pub fn frame(&self, origin: glam::DVec3) -> FileFrame {
        FileFrame {
            scale: self.scale,
            offset: self.offset,
            origin,
        }
    }
}

/// Where an imported file lies in the clay fitted to it: a point `x` of the file is at
/// `(x − origin) · scale + offset` in field units. `--mesh` writes the fitted surface back in
/// the file's coordinates through it, to lay over the input.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FileFrame {
    /// Field units per file unit (a volume's file unit is its voxel).
    pub scale: f32,
    /// Field position of the point the file's points were read about.
    pub offset: Vec3,
    /// The point the file's points were read about, in the file's coordinates.
    pub origin: glam::DVec3,
}

impl FileFrame {
    /// A field-unit point in the file's coordinates.
    #[must_use]
    pub fn to_file(&self, field: Vec3) -> glam::DVec3 {
        self.origin + ((field - self.offset) / self.scale).as_dvec3()
    }
}

/// Reads `path` and fits a multi-patch clay to it; `progress` sees each stage (answer `false`
/// to stop), `note` receives the report lines.
///
/// # Errors
/// See [`ImportError`]: an unknown extension, a bad file, missing volume settings, a failed
/// or stopped fit.
pub fn fit_file(
    path: &Path,
    settings: &ImportSettings,
    progress: &mut dyn FnMut(FitProgress) -> bool,
    note: &mut dyn FnMut(String),
) -> Result<MultiPatchField, ImportError> {
    fit_import(path, settings, progress, note).map(|fit| fit.field)
}

/// [`fit_file`], also telling which path the fit took and where the file lies in the clay.
///
/// # Errors
/// As [`fit_file`].
pub fn fit_import(
    path: &Path,
    settings: &ImportSettings,
    progress: &mut dyn FnMut(FitProgress) -> bool,
    note: &mut dyn FnMut(String),
) -> Result<ImportedFit, ImportError> {
    match extension(path).as_deref() {
        Some("nrrd") => fit_volume_file(path, settings, true, progress, note),
        Some("raw") => fit_volume_file(path, settings, false, progress, note),
        Some("obj" | "stl") => fit_mesh_file(path, settings, progress, note),
        Some("ply" | "xyz" | "txt" | "pts") => {
            import_cloud(path, settings, progress, note).map(|imported| imported.fit)
        }
        _ => Err(ImportError::UnknownFormat {
            file: path.to_path_buf(),
        }),
    }
}

/// A point-cloud file fitted by [`import_cloud`]: the fit and the cloud as read.
#[derive(Clone, Debug)]
pub struct ImportedCloud {
    /// The fitted clay and where the file lies in it.
    pub fit: ImportedFit,
    /// The points as read, in the file's units, less [`ImportedCloud::origin`].
    pub cloud: PointCloud,
    /// Where the points were read from, in the file's coordinates: zero, or the centre of
    /// the cloud's box where it lies far from the file's origin
    /// ([`super::point_file::read_points_about_their_centre`]).
    pub origin: glam::DVec3,
    /// The points' colours, when the file has them.
    pub colours: Option<PointColours>,
    /// The colours as the clay's paint ([`paint_from_cloud`]), when the file has colours and
    /// they could be fitted.
    pub paint: Option<ColourField>,
}

impl ImportedCloud {
    /// The cloud in field units (normals unchanged: the map is a uniform scale and a shift).
    #[must_use]
    pub fn cloud_in_field_units(&self) -> PointCloud {
        PointCloud {
            points: self
                .cloud
                .points
                .iter()
                .map(|&p| self.fit.to_field(p))
                .collect(),
            normals: self.cloud.normals.clone(),
        }
    }
}

/// Fits a point-cloud file (`.ply`, `.xyz`, `.txt`, `.pts`) as [`fit_file`] does, keeping the
/// cloud, its colours and the map into field units.
///
/// # Errors
/// As [`fit_file`].
pub fn import_cloud(
    path: &Path,
    settings: &ImportSettings,
    progress: &mut dyn FnMut(FitProgress) -> bool,
    note: &mut dyn FnMut(String),
) -> Result<ImportedCloud, ImportError> {
    let started = Instant::now();
    let (cloud, colours, origin) = read_points_about_their_centre(path)?;
    let read = started.elapsed();
    let mut fit = fit_cloud(path, &cloud, FitPath::Cloud, settings, progress, note)?;
    if origin != glam::DVec3::ZERO {
        note(format!(
            "the points lie far from the file's origin: read in double precision relative to \
             ({}, {}, {})",
            origin.x, origin.y, origin.z
        ));
    }
    fit.times.stages.insert(
        0,
        StageTime {
            name: "reading",
            depth: 0,
            wall: read,
        },
    );
    let mut imported = ImportedCloud {
        fit,
        cloud,
        origin,
        colours,
        paint: None,
    };
    if let Some(colours) = &imported.colours {
        let started = Instant::now();
        let painted = paint_from_cloud(
            imported.fit.field.base(),
            &imported.cloud_in_field_units().points,
            colours,
        );
        imported.fit.times.record("paint", started);
        match painted {
            Ok(paint) => {
                note(format!(
                    "painted from the points' colours (each node from its {NEIGHBOURS} nearest \
                     points)"
                ));
                imported.paint = Some(paint);
            }
            Err(e) => note(format!(
                "warning: the points' colours were not made into paint ({e}); the clay is \
                 unpainted"
            )),
        }
    }
    Ok(imported)
}

impl ImportedCloud {
    /// The session of this import ([`imported_session`]), painted with [`ImportedCloud::paint`].
    #[must_use]
    pub fn into_session(self, path: &Path, created_unix_s: u64) -> Session {
        let mut session = imported_session(self.fit.field, path, created_unix_s);
        session.clay.colour = self.paint;
        session
    }
}

/// Whether `path` names a point-cloud file by its extension (`.ply`, `.xyz`, `.txt`, `.pts`).
#[must_use]
pub fn is_point_cloud(path: &Path) -> bool {
    matches!(
        extension(path).as_deref(),
        Some("ply" | "xyz" | "txt" | "pts")
    )
}

/// One report line per octree depth: how many nodes were refined; and one more when the
/// clay's budget stopped the refinement.
fn note_levels(levels: &[LevelReport], over_budget: bool, note: &mut dyn FnMut(String)) {
    for level in levels {
        let refused = if level.refused > 0 {
            format!(
                "; {} patches refused: they changed the clay's topology where the points do not",
                level.refused
            )
        } else {
            String::new()
        };
        note(format!(
            "depth {}: {} of {} octree nodes refined{refused}",
            level.depth, level.refined, level.nodes
        ));
    }
    if over_budget {
        note(format!(
            "warning: the clay's budget ({} patches, {} coefficients) stopped the detail with \
             nodes still over the error bound (the worst were refined first); raise --error or \
             lower --max-depth",
            dynaclay_core::field::MAX_PATCHES,
            dynaclay_core::field::MAX_CLAY_COEFFS
        ));
    }
}

fn fit_error(path: &Path, e: CloudFitError) -> ImportError {
    match e {
        CloudFitError::Options(m) => ImportError::Options(m),
        CloudFitError::Interrupted => ImportError::Interrupted,
        source => ImportError::Fit {
            file: path.to_path_buf(),
            source,
        },
    }
}

fn fit_cloud(
    path: &Path,
    cloud: &PointCloud,
    kind: FitPath,
    settings: &ImportSettings,
    progress: &mut dyn FnMut(FitProgress) -> bool,
    note: &mut dyn FnMut(String),
) -> Result<ImportedFit, ImportError> {
    // Only a cloud file's own points choose the lattice: an open mesh sampled into a cloud
    // has as many points as the sampling made, not as the scan held.
    // The count sets the most knots; the noise, once the screening knows it, the knots.
    let knots_from_noise = matches!(kind, FitPath::Cloud) && settings.resolution_from_points;
    let resolution = if knots_from_noise {
        most_resolution_for_points(cloud.points.len())
    } else {
        settings.resolution
    };
    let options = HierarchyOptions {
        base: CloudFitOptions {
            resolution,
            gap_spans: settings.gap_spans,
            noise: settings.noise_percent.map(|p| p / 100.0),
            fewest_knots_by_noise: knots_from_noise
                .then(|| resolution_for_points(cloud.points.len())),
            ..CloudFitOptions::default()
        },
        error: settings.error_percent / 100.0,
        max_depth: settings.max_depth,
    };
    note(format!(
        "{} points{} from {}, fitting a {}{}³ clay{} with detail patches down to depth {} \
         where the error is above {}% of its size",
        cloud.points.len(),
        if cloud.normals.is_some() {
            " with normals"
        } else {
            ""
        },
        path.display(),
        if knots_from_noise { "at most " } else { "" },
        options.base.resolution,
        if knots_from_noise {
            " (its knots set by the noise, at most as many as the point count affords; \
             --resolution sets them)"
        } else {
            ""
        },
        options.max_depth,
        settings.error_percent
    ));
    // A scan denser than the finest knot span can use is thinned first (see `thinning`).
    let mut times = StageTimes::default();
    let started = Instant::now();
    let size = cloud_size(&cloud.points);
    // The base's spans cover the object less its margin (see `cloud::place`).
    let base_spans = ((options.base.resolution.max(2) - 1) as f32 - 2.0 * MARGIN_SPANS).max(1.0);
    let finest_span = size / base_spans / (1_u32 << options.max_depth.min(16)) as f32;
    let thinned = match kind {
        FitPath::Cloud => thin_for_span(cloud, finest_span),
        _ => None,
    };
    let cloud = match &thinned {
        Some((thin, done)) => {
            note(if done.limited_by_count {
                format!(
                    "thinned to {} points (one in {}): a fit keeps at most {} points (the \
                     points lie {:.3}% of the size apart; the finest knot span could use \
                     {:.3}%)",
                    thin.points.len(),
                    done.stride,
                    MAX_FITTED_POINTS,
                    100.0 * done.spacing_before / size,
                    100.0 * done.spacing_wanted / size
                )
            } else {
                format!(
                    "thinned to {} points (one in {}): the points lie {:.3}% of the size apart, \
                     closer than the finest knot span can use ({:.3}% wanted)",
                    thin.points.len(),
                    done.stride,
                    100.0 * done.spacing_before / size,
                    100.0 * done.spacing_wanted / size
                )
            });
            thin
        }
        None => cloud,
    };
    times.record("thinning", started);
    let started = Instant::now();
    let mut fit = fit_hierarchy(cloud, &options, progress).map_err(|e| fit_error(path, e))?;
    times.record_with("fit", started, std::mem::take(&mut fit.times));
    let s = fit.screening;
    let noise = match (s.noise_given, s.noise_off_quadrics) {
        (true, _) => format!("noise {:.3}% of the size (given)", 100.0 * s.noise),
        (false, None) => format!("noise {:.3}% of the size (estimated)", 100.0 * s.noise),
        (false, Some(q)) => format!(
            "noise {:.3}% of the size (estimated off quadrics; the lattice and the smoothing \
             follow the neighbours' planes' scatter, {:.3}%, the curvature over the sparse \
             cloud's wide neighbourhoods included)",
            100.0 * q,
            100.0 * s.noise
        ),
    };
    note(format!(
        "dropped {} isolated points and {} off the surface their neighbours agree on; turned \
         {} normals to agree with their neighbours'; {noise}, points {:.3}% apart; base \
         lattice {}³; smoothed over {:.3}%; error bound {:.3}%; removed {} small pieces, \
         filled {} small cavities",
        s.isolated,
        s.far,
        s.overruled_normals,
        100.0 * s.point_spacing,
        s.resolution,
        100.0 * s.bandwidth,
        100.0 * fit.bound,
        s.removed_pieces,
        s.filled_cavities
    ));
    if let Some(g) = s.gap_widened {
        note(format!(
            "the outside got in between the points (it lay on both sides of {} of them, \
             through gaps wider than {DEFAULT_GAP_SPANS} knot spans): closed gaps up to \
             {MAX_GAP_SPANS} spans instead ({} then)",
            g.open_before, g.open_after
        ));
    }
    if s.sparse > 0 {
        note(format!(
            "kept {} points of sparsely sampled areas (too few neighbours within the \
             screening's radius), judged by the plane of their nearest neighbours",
            s.sparse
        ));
    }
    let sides = s.normal_sides;
    match sides.verdict() {
        GivenNormals::Kept => {}
        GivenNormals::Turned => note(format!(
            "the file's normals point inward ({} of the {} points that show a side): turned \
             them all outward",
            sides.inward,
            sides.inward + sides.outward
        )),
        GivenNormals::Unoriented => note(format!(
            "the file's normals disagree on which side is out ({:.0}% of {} pairs of \
             neighbouring points point opposite ways): signed by flood tagging instead",
            100.0 * sides.opposed_share(),
            sides.neighbour_pairs
        )),
    }
    if let Some(o) = s.open_sheets {
        note(format!(
            "{} points lie on open sheets (the outside on both sides, as over a partial \
             scan): their normals were oriented by their neighbours' in {} pieces ({} \
             turned whole to the side their points show)",
            o.open_sheet_points, o.pieces, o.turned
        ));
    }
    note_levels(&fit.levels, fit.over_budget, note);
    let kept: Vec<Vec3> = cloud
        .points
        .iter()
        .zip(&fit.kept)
        .filter_map(|(&p, &kept)| kept.then_some(p))
        .collect();
    let (mean, worst) = times.time("kept points' distances", || {
        distance_to_surface(&fit.field, &kept, |p| fit.to_field(p))
    });
    let percent = |d: f32| 100.0 * d / fit.size;
    if fit.loose_pieces > 0 {
        note(format!(
            "took out {} loose pieces of the fit (pinched off from the surface, too small and \
             held by too few points to be data)",
            fit.loose_pieces
        ));
    }
    if fit.fit_cavities > 0 {
        note(format!(
            "filled {} small cavities of the fit (closed off inside the clay, too small to be \
             data)",
            fit.fit_cavities
        ));
    }
    if fit.fit_holes > 0 {
        note(format!(
            "closed {} small holes of the fit (tunnels through thin walls, under about two and a \
             half knot spans across, that no point holds open)",
            fit.fit_holes
        ));
    }
    note(format!(
        "signed by {}; {} patches; RMS error {:.3}% of the size ({:.3}% with the base alone); \
         the {} points kept lie {:.3}% of the size from the surface on average, {:.3}% at most",
        match fit.signed_by {
            SignedBy::Normals => "the normals",
            SignedBy::Tagging => "flood tagging",
        },
        fit.field.patches.len(),
        100.0 * fit.rms,
        100.0 * fit.rms_base,
        kept.len(),
        percent(mean),
        percent(worst)
    ));
    Ok(ImportedFit {
        field: fit.field,
        path: kind,
        scale: fit.scale,
        offset: fit.offset,
        times,
    })
}

/// The longest side of the box around `points` (0 for none).
fn cloud_size(points: &[Vec3]) -> f32 {
    let (lo, hi) = points
        .iter()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(a, b), &p| {
            (a.min(p), b.max(p))
        });
    if lo.x.is_finite() {
        (hi - lo).max_element()
    } else {
        0.0
    }
}

/// How far `points` (mapped to field units by `to_field`) lie from the fitted surface, to
/// first order (`|F − iso| / |∇F|`), field units: mean and worst.
///
/// The distances are found on every core and summed in the points' order.
fn distance_to_surface(
    field: &MultiPatchField,
    points: &[Vec3],
    to_field: impl Fn(Vec3) -> Vec3 + Sync,
) -> (f32, f32) {
    let distances = parallel_map(points.len(), |i| {
        let (v, g) = field.value_and_gradient(to_field(points[i]));
        (v - field.iso()).abs() / g.length().max(1e-6)
    });
    let (mut sum, mut worst) = (0.0f64, 0.0f32);
    for d in distances {
        sum += f64::from(d);
        worst = worst.max(d);
    }
    ((sum / points.len().max(1) as f64) as f32, worst)
}

/// The signed-distance grid [`fit_import`] uses for a closed mesh whose box is `lo..hi`, and
/// whether [`MAX_SDF_VOXELS`] made it coarser than asked. The mesh is placed as a cloud is
/// (its longest side spans the base lattice less its margin); the voxel is half the finest
/// detail patch's spacing (`base spacing / 2^max_depth`), and the band one base knot span
/// (the density ramp's half width) plus two voxels.
///
/// # Errors
/// [`ImportError::Options`] for a resolution out of 12..=256, or a box too thin or empty for
/// a grid.
pub fn closed_mesh_grid(
    settings: &ImportSettings,
    lo: Vec3,
    hi: Vec3,
) -> Result<(SdfGrid, bool), ImportError> {
    let resolution = settings.resolution;
    if !(12..=256).contains(&resolution) {
        return Err(ImportError::Options(format!(
            "resolution {resolution}: must be 12 to 256 coefficients"
        )));
    }
    let span_total = (resolution - 1) as f32 - 2.0 * MARGIN_SPANS;
    let depth = settings.max_depth.min(MAX_DEPTH);
    let mut across = (2.0 * span_total * (1u32 << depth) as f32).ceil() as usize;
    let extent = hi - lo;
    let size = extent.max_element().max(f32::MIN_POSITIVE);
    let mut capped = false;
    loop {
        let band = across as f32 / span_total + 2.0;
        let margin = 2.0 * (band.ceil() + 2.0) + 1.0;
        let voxels: f64 = (0..3)
            .map(|a| f64::from((extent[a] / size * across as f32).ceil() + margin))
            .product();
        if voxels <= MAX_SDF_VOXELS as f64 {
            let grid = SdfGrid::around(lo, hi, across, band)?;
            return Ok((grid, capped));
        }
        capped = true;
        across = across * 9 / 10;
    }
}

fn fit_mesh_file(
    path: &Path,
    settings: &ImportSettings,
    progress: &mut dyn FnMut(FitProgress) -> bool,
    note: &mut dyn FnMut(String),
) -> Result<ImportedFit, ImportError> {
    let (vertices, triangles) = read_mesh(path)?;
    if triangles.is_empty() {
        return Err(PointsError::Empty {
            file: path.to_path_buf(),
        }
        .into());
    }
    // Before the weld, which measures the mesh's diagonal: past the fit's sizes it overflows
    // (every vertex then welds to one) or the squared distances of the signing vanish.
    super::cloud::check_extent("mesh", cloud_size(&vertices)).map_err(|e| fit_error(path, e))?;
    let (mesh, check) = check_closed(&vertices, &triangles);
    note(format!(
        "{} triangles from {}: {}",
        triangles.len(),
        path.display(),
        check.describe()
    ));
    let as_cloud = |why: &str,
                    progress: &mut dyn FnMut(FitProgress) -> bool,
                    note: &mut dyn FnMut(String)|
     -> Result<ImportedFit, ImportError> {
        note(format!(
            "{why}: fitting it as a point cloud sampled from its triangles"
        ));
        let cloud = sample_triangles(&vertices, &triangles, path)?;
        fit_cloud(
            path,
            &cloud,
            FitPath::OpenMesh(check),
            settings,
            progress,
            note,
        )
    };
    let (mesh, path_taken) = if check.is_closed() {
        (mesh, FitPath::ClosedMesh(check))
    } else {
        match cap_holes(&mesh) {
            Ok(capped) => {
                let (closed, recheck) =
                    check_closed(&capped.mesh.positions, &capped.mesh.triangles);
                if !recheck.is_closed() {
                    return as_cloud(
                        "open, and capping its holes did not close it",
                        progress,
                        note,
                    );
                }
                note(format!(
                    "capped {} hole{} (the widest {:.1}% of its size) to fit it as a closed mesh",
                    capped.holes,
                    if capped.holes == 1 { "" } else { "s" },
                    100.0 * capped.widest
                ));
                (closed, FitPath::CappedMesh(check))
            }
            Err(why) => return as_cloud(&format!("open ({why})"), progress, note),
        }
    };
    let (lo, hi) = mesh
        .positions
        .iter()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(a, b), &p| {
            (a.min(p), b.max(p))
        });
    let (grid, capped) = closed_mesh_grid(settings, lo, hi)?;
    let across = ((hi - lo).max_element() / grid.voxel).round();
    note(format!(
        "closed: fitting its signed distance on a {}×{}×{} grid ({} voxels across, exact within \
         {:.1} voxels of the surface, signed by the winding number along three axes){}",
        grid.dims[0],
        grid.dims[1],
        grid.dims[2],
        across,
        grid.band_voxels,
        if capped {
            format!(
                "; the grid is limited to {MAX_SDF_VOXELS} voxels, so detail below {:.3}% of \
                 the size is not resolved",
                100.0 / across
            )
        } else {
            String::new()
        }
    ));
    if !progress(FitProgress::Signing) {
        return Err(ImportError::Interrupted);
    }
    let sdf = signed_distance(&mesh, &grid, &mut || !progress(FitProgress::Signing))
        .ok_or(ImportError::Interrupted)?;
    if sdf.flipped {
        note("its faces wind inward (negative enclosed volume): the sign is flipped".into());
    }
    if sdf.inside == 0 {
        return as_cloud(
            "no voxel lies inside the mesh (thinner than a voxel)",
            progress,
            note,
        );
    }
    let options = HierarchyOptions {
        error: settings.error_percent / 100.0,
        max_depth: settings.max_depth,
        ..HierarchyOptions::default()
    };
    let fit = fit_volume_hierarchy_within(
        &sdf.volume,
        0.0,
        [grid.to_voxel(lo), grid.to_voxel(hi)],
        settings.resolution,
        dynaclay_core::field::CLAY_SPACING,
        &options,
        progress,
    )
    .map_err(|e| fit_error(path, e))?;
    note_levels(&fit.levels, fit.over_budget, note);
    // file → voxel → field.
    let scale = fit.scale / grid.voxel;
    let offset = fit.offset - grid.origin * scale;
    // The vertices as read: a cap's centre is no part of the mesh.
    let (mean, worst) = distance_to_surface(&fit.field, &vertices, |p| p * scale + offset);
    let size = (hi - lo).max_element() * scale;
    note(format!(
        "{} patches; RMS error near the surface {:.3}% of the size ({:.3}% with the base \
         alone); the mesh's vertices lie {:.3}% of the size from the surface on average, \
         {:.3}% at most",
        fit.field.patches.len(),
        100.0 * fit.rms,
        100.0 * fit.rms_base,
        100.0 * mean / size,
        100.0 * worst / size
    ));
    Ok(ImportedFit {
        field: fit.field,
        path: path_taken,
        scale,
        offset,
        times: StageTimes::default(),
    })
}

fn fit_volume_file(
    path: &Path,
    settings: &ImportSettings,
    nrrd: bool,
    progress: &mut dyn FnMut(FitProgress) -> bool,
    note: &mut dyn FnMut(String),
) -> Result<ImportedFit, ImportError> {
    if settings.iso.is_none() && !settings.midrange_iso {
        return Err(ImportError::NeedsIso);
    }
    let volume: Volume = if nrrd {
        read_nrrd(path)?
    } else {
        let (dims, sample) = settings.raw.ok_or(ImportError::NeedsDims)?;
        read_raw(path, dims, sample)?
    };
    let iso = match settings.iso {
        Some(iso) => iso,
        None => {
            let (lo, hi) = volume
                .values
                .iter()
                .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &v| {
                    (lo.min(v), hi.max(v))
                });
            if hi.partial_cmp(&lo) != Some(std::cmp::Ordering::Greater) {
                return Err(ImportError::FlatVolume {
                    file: path.to_path_buf(),
                });
            }
            let iso = 0.5 * (lo + hi);
            note(format!(
                "surface at the middle of the intensities {lo}..{hi}: {iso} (`dynaclay import \
                 --iso V` chooses another)"
            ));
            iso
        }
    };
    note(format!(
        "a {}×{}×{} volume from {}, surface at {iso}, fitting a {}³ clay",
        volume.dims[0],
        volume.dims[1],
        volume.dims[2],
        path.display(),
        settings.resolution
    ));
    let options = HierarchyOptions {
        error: settings.error_percent / 100.0,
        max_depth: settings.max_depth,
        ..HierarchyOptions::default()
    };
    let fit = fit_volume_hierarchy(
        &volume,
        iso,
        settings.resolution,
        dynaclay_core::field::CLAY_SPACING,
        &options,
        progress,
    )
    .map_err(|e| fit_error(path, e))?;
    note_levels(&fit.levels, fit.over_budget, note);
    note(format!(
        "{} patches; RMS error near the surface {:.3}% of the volume's size ({:.3}% with the \
         base alone)",
        fit.field.patches.len(),
        100.0 * fit.rms,
        100.0 * fit.rms_base
    ));
    Ok(ImportedFit {
        field: fit.field,
        path: FitPath::Volume,
        scale: fit.scale,
        offset: fit.offset,
        times: StageTimes::default(),
    })
}

/// The session of a fitted clay imported from `path`: the field as its density (no paint, no
/// pins; [`ImportedCloud::into_session`] adds a cloud's paint), plastic, named after the file.
#[must_use]
pub fn imported_session(field: MultiPatchField, path: &Path, created_unix_s: u64) -> Session {
    let name = path
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or("import")
        .to_owned();
    Session {
        clay: Clay {
            density: field,
            colour: None,
            constraints: Vec::new(),
            mask: None,
        },
        material: MaterialFields {
            uniform: Material::PLASTIC,
            grids: Vec::new(),
        },
        tools: Vec::new(),
        meta: SessionMeta {
            name,
            created_unix_s,
            ..SessionMeta::default()
        },
    }
}

/// [`fit_file`] and [`imported_session`] in one: the session `dynaclay import` writes; a
/// point cloud with colours comes painted ([`ImportedCloud::into_session`]).
///
/// # Errors
/// As [`fit_file`].
pub fn import_session(
    path: &Path,
    settings: &ImportSettings,
    progress: &mut dyn FnMut(FitProgress) -> bool,
    note: &mut dyn FnMut(String),
) -> Result<Session, ImportError> {
    import_session_timed(path, settings, progress, note).map(|imported| imported.session)
}

/// [`import_session`], also giving the wall time of each stage (`dynaclay import --timings`):
/// a point cloud's stages one by one ([`ImportedFit::times`]), a mesh's or a volume's fit as
/// one stage.
///
/// # Errors
/// As [`fit_file`].
pub fn import_session_timed(
    path: &Path,
    settings: &ImportSettings,
    progress: &mut dyn FnMut(FitProgress) -> bool,
    note: &mut dyn FnMut(String),
) -> Result<TimedImport, ImportError> {
    if is_point_cloud(path) {
        let mut imported = import_cloud(path, settings, progress, note)?;
        let times = std::mem::take(&mut imported.fit.times);
        let frame = imported.fit.frame(imported.origin);
        return Ok(TimedImport {
            session: imported.into_session(path, dynaclay_core::io::unix_now_s()),
            times,
            frame,
        });
    }
    let mut times = StageTimes::default();
    let fit = times.time("reading and fit", || {
        fit_import(path, settings, progress, note)
    })?;
    let frame = fit.frame(glam::DVec3::ZERO);
    Ok(TimedImport {
        session: imported_session(fit.field, path, dynaclay_core::io::unix_now_s()),
        times,
        frame,
    })
}

/// What [`import_session_timed`] gives: the session, each stage's wall time, and where the
/// file lies in the clay.
#[derive(Clone, Debug)]
pub struct TimedImport {
    /// The session `dynaclay import` writes.
    pub session: Session,
    /// The wall time of each stage.
    pub times: StageTimes,
    /// Where the file lies in the session's clay.
    pub frame: FileFrame,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A sphere of radius 1 sampled as an XYZ cloud with outward normals.
    fn sphere_xyz(n: usize) -> String {
        let mut text = String::new();
        let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
        for i in 0..n {
            let y = 1.0 - 2.0 * (i as f32 + 0.5) / n as f32;
            let r = (1.0 - y * y).sqrt();
            let t = golden * i as f32;
            let (x, z) = (r * t.cos(), r * t.sin());
            text.push_str(&format!("{x} {y} {z} {x} {y} {z}\n"));
        }
        text
    }

    #[test]
    fn a_small_cloud_becomes_a_session_whose_clay_holds_its_surface() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("ball.xyz");
        std::fs::write(&path, sphere_xyz(600)).unwrap();
        assert!(is_importable(&path));
        let settings = ImportSettings {
            resolution: 12,
            resolution_from_points: false,
            max_depth: 0,
            ..ImportSettings::default()
        };
        let (mut stages, mut notes) = (0, Vec::new());
        let session = import_session(
            &path,
            &settings,
            &mut |_| {
                stages += 1;
                true
            },
            &mut |line| notes.push(line),
        )
        .unwrap();
        assert!(stages > 0, "progress is reported");
        assert!(notes[0].contains("600 points with normals"), "{notes:?}");
        assert_eq!(session.meta.name, "ball");
        let base = session.clay.density.base();
        assert_eq!(base.dims, [12, 12, 12]);
        assert!(session.clay.density.patches[0].is_identity());
        assert!(
            session.clay.density.patches.iter().all(|p| p
                .lattice
                .coeffs
                .iter()
                .all(|c| c.is_finite()))
        );
    }

    #[test]
    fn bad_files_and_missing_settings_are_named() {
        let dir = tempfile::tempdir().unwrap();
        let none = |_| true;
        let mut quiet = |_| {};
        let odd = dir.path().join("scan.abc");
        std::fs::write(&odd, "1 2 3\n").unwrap();
        let e = fit_file(&odd, &ImportSettings::default(), &mut { none }, &mut quiet).unwrap_err();
        assert!(matches!(e, ImportError::UnknownFormat { .. }), "{e}");
        assert!(e.to_string().contains("scan.abc"), "{e}");
        let empty = dir.path().join("empty.ply");
        std::fs::write(&empty, "not a ply\n").unwrap();
        let e = fit_file(
            &empty,
            &ImportSettings::default(),
            &mut { none },
            &mut quiet,
        )
        .unwrap_err();
        assert!(e.to_string().contains("empty.ply"), "{e}");
        let raw = dir.path().join("ct.raw");
        std::fs::write(&raw, [0u8; 8]).unwrap();
        let gui = ImportSettings {
            midrange_iso: true,
            ..ImportSettings::default()
        };
        let e = fit_file(&raw, &gui, &mut { none }, &mut quiet).unwrap_err();
        assert!(matches!(e, ImportError::NeedsDims), "{e}");
        let e = fit_file(&raw, &ImportSettings::default(), &mut { none }, &mut quiet).unwrap_err();
        assert!(matches!(e, ImportError::NeedsIso), "{e}");
    }
}
