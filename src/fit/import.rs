//! One import for `dynaclay import` and the GUI's Load: a file is read by its extension (point
//! clouds `.ply`/`.xyz`/`.txt`/`.pts`, meshes `.obj`/`.stl`, volumes `.nrrd` and, with their
//! dimensions given, `.raw`), fitted hierarchically ([`fit_hierarchy`],
//! [`fit_volume_hierarchy`]) and made into a session whose clay is the fitted field.
//!
//! The caller watches the fit through two callbacks: `progress` sees each stage (and stops the
//! fit by answering `false`), `note` receives one line per report (what was read, the levels,
//! the error reached), so the CLI prints them and the GUI shows them in its log.

use std::path::Path;

use glam::Vec3;

use super::cloud::{CloudFitError, CloudFitOptions, DEFAULT_GAP_SPANS, SignedBy};
use super::hierarchy::{
    DEFAULT_ERROR, DEFAULT_MAX_DEPTH, FitProgress, HierarchyOptions, fit_hierarchy,
};
use super::points::{PointCloud, PointsError, read_points_with_colours};
use super::volume::{Sample, Volume, VolumeError, fit_volume_hierarchy, read_nrrd, read_raw};
use crate::dynamics::Material;
use crate::field::MultiPatchField;
use crate::io::{MaterialFields, Session, SessionMeta};
use crate::tools::Clay;

/// The extensions [`fit_file`] reads (lower case).
pub const IMPORT_EXTENSIONS: [&str; 8] = ["ply", "xyz", "txt", "pts", "obj", "stl", "nrrd", "raw"];

/// How a file is fitted. [`ImportSettings::default`] is `dynaclay import`'s defaults.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImportSettings {
    /// Knots per axis of the base lattice.
    pub resolution: usize,
    /// Gap bridged by the tagging of unoriented clouds, in knot spans.
    pub gap_spans: f32,
    /// Error bound of the hierarchy, percent of the object's size.
    pub error_percent: f32,
    /// Deepest octree level of detail patches.
    pub max_depth: u32,
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
            resolution: 32,
            gap_spans: DEFAULT_GAP_SPANS,
            error_percent: DEFAULT_ERROR * 100.0,
            max_depth: DEFAULT_MAX_DEPTH,
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
    match extension(path).as_deref() {
        Some("nrrd") => fit_volume_file(path, settings, true, progress, note),
        Some("raw") => fit_volume_file(path, settings, false, progress, note),
        Some("ply" | "xyz" | "txt" | "pts" | "obj" | "stl") => {
            fit_cloud_file(path, settings, progress, note).map(|c| c.field)
        }
        _ => Err(ImportError::UnknownFormat {
            file: path.to_path_buf(),
        }),
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

/// A point cloud fitted by [`import_cloud`]: the field, the cloud as read, and the map from
/// the file's units to the field's.
#[derive(Clone, Debug)]
pub struct ImportedCloud {
    /// The fitted clay.
    pub field: MultiPatchField,
    /// The points as read, in the file's units.
    pub cloud: PointCloud,
    /// The points' colours, when the file has them.
    pub colours: Option<Vec<[u8; 3]>>,
    /// Field units per file unit.
    pub scale: f32,
    /// Field position of the file's origin: `field = file · scale + offset`.
    pub offset: Vec3,
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
                .map(|&p| p * self.scale + self.offset)
                .collect(),
            normals: self.cloud.normals.clone(),
        }
    }
}

/// Fits a point-cloud file (`.ply`, `.xyz`, `.txt`, `.pts`, or a mesh's vertices) as
/// [`fit_file`] does, keeping the cloud and the map into field units.
///
/// # Errors
/// As [`fit_file`].
pub fn import_cloud(
    path: &Path,
    settings: &ImportSettings,
    progress: &mut dyn FnMut(FitProgress) -> bool,
    note: &mut dyn FnMut(String),
) -> Result<ImportedCloud, ImportError> {
    fit_cloud_file(path, settings, progress, note)
}

/// Whether `path` names a point-cloud file by its extension (`.ply`, `.xyz`, `.txt`, `.pts`).
#[must_use]
pub fn is_point_cloud(path: &Path) -> bool {
    matches!(
        extension(path).as_deref(),
        Some("ply" | "xyz" | "txt" | "pts")
    )
}

fn fit_cloud_file(
    path: &Path,
    settings: &ImportSettings,
    progress: &mut dyn FnMut(FitProgress) -> bool,
    note: &mut dyn FnMut(String),
) -> Result<ImportedCloud, ImportError> {
    let (cloud, colours) = read_points_with_colours(path)?;
    let options = HierarchyOptions {
        base: CloudFitOptions {
            resolution: settings.resolution,
            gap_spans: settings.gap_spans,
            ..CloudFitOptions::default()
        },
        error: settings.error_percent / 100.0,
        max_depth: settings.max_depth,
    };
    note(format!(
        "{} points{} from {}, fitting a {}³ clay with detail patches down to depth {} where \
         the error is above {}% of its size",
        cloud.points.len(),
        if cloud.normals.is_some() {
            " with normals"
        } else {
            ""
        },
        path.display(),
        options.base.resolution,
        options.max_depth,
        settings.error_percent
    ));
    let fit = fit_hierarchy(&cloud, &options, progress).map_err(|e| fit_error(path, e))?;
    for level in &fit.levels {
        note(format!(
            "depth {}: {} of {} octree nodes refined",
            level.depth, level.refined, level.nodes
        ));
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
    note(format!(
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
    ));
    Ok(ImportedCloud {
        field: fit.field,
        cloud,
        colours,
        scale: fit.scale,
        offset: fit.offset,
    })
}

fn fit_volume_file(
    path: &Path,
    settings: &ImportSettings,
    nrrd: bool,
    progress: &mut dyn FnMut(FitProgress) -> bool,
    note: &mut dyn FnMut(String),
) -> Result<MultiPatchField, ImportError> {
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
        crate::engine::CLAY_SPACING,
        &options,
        progress,
    )
    .map_err(|e| fit_error(path, e))?;
    for level in &fit.levels {
        note(format!(
            "depth {}: {} of {} octree nodes refined",
            level.depth, level.refined, level.nodes
        ));
    }
    note(format!(
        "{} patches; RMS error near the surface {:.3}% of the volume's size ({:.3}% with the \
         base alone)",
        fit.field.patches.len(),
        100.0 * fit.rms,
        100.0 * fit.rms_base
    ));
    Ok(fit.field)
}

/// The session of a fitted clay imported from `path`: the field as its density (no paint, no
/// pins), plastic, named after the file.
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

/// [`fit_file`] and [`imported_session`] in one: the session `dynaclay import` would write.
///
/// # Errors
/// As [`fit_file`].
pub fn import_session(
    path: &Path,
    settings: &ImportSettings,
    progress: &mut dyn FnMut(FitProgress) -> bool,
    note: &mut dyn FnMut(String),
) -> Result<Session, ImportError> {
    let field = fit_file(path, settings, progress, note)?;
    let now = std::time::SystemTime::now()
        .duration_since(std::time::SystemTime::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    Ok(imported_session(field, path, now))
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
