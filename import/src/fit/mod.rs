//! Bringing real objects in: point clouds ([`points`]), meshes ([`mesh`]: closed ones
//! ([`watertight`], or with their holes capped, [`holes`]) by their signed distance ([`sdf`]),
//! other open ones sampled into clouds) and
//! volumes ([`volume`]) read from
//! files become a clay fitted by least squares ([`cloud`], [`volume::fit_volume`]); a cloud's
//! fit is refined by an octree of detail patches where the error is above a bound
//! ([`hierarchy`], Hua & Qin §5).
//! [`import`] is the one import that `dynaclay import` and the GUI's Load both call.

pub mod cloud;
pub mod consensus;
mod disjoint_sets;
pub mod handles;
pub mod hierarchy;
pub mod holes;
pub mod import;
mod lanes;
pub mod mesh;
pub mod paint;
pub mod point_file;
pub mod points;
mod quadric;
pub mod regularised;
pub mod sdf;
pub mod sharpness;
pub mod stage_times;
#[cfg(test)]
mod test_boxes;
pub mod thinning;
pub mod volume;
pub mod watertight;

pub use cloud::{
    CloudFit, CloudFitError, CloudFitOptions, SignedBy, SignedCloud, fit_point_cloud, sign_cloud,
};
pub use hierarchy::{FitProgress, HierarchicalFit, HierarchyOptions, LevelReport, fit_hierarchy};
pub use holes::{CappedMesh, MAX_CAPPED_HOLE, UncappedHoles, cap_holes};
pub use import::{
    DEFAULT_RESOLUTION, FileFrame, FitPath, IMPORT_EXTENSIONS, ImportError, ImportSettings,
    ImportedCloud, ImportedFit, TimedImport, closed_mesh_grid, fit_file, fit_import, import_cloud,
    import_session, import_session_timed, imported_session, is_importable, is_point_cloud,
    most_resolution_for_points, resolution_for_points,
};
pub use paint::{PaintError, paint_from_cloud};
pub use point_file::{
    FAR_FROM_ORIGIN_SIZES, read_points, read_points_about_their_centre, read_points_with_colours,
};
pub use points::{MAX_POINTS, PointCloud, PointColours, PointsError, parse_ply, parse_xyz};
pub use sdf::{MAX_SDF_VOXELS, SdfGrid, SdfGridError, SignedDistance, signed_distance};
pub use stage_times::{StageTime, StageTimes};
pub use volume::{
    Sample, Volume, VolumeError, VolumeFit, VolumeHierarchy, fit_volume, fit_volume_hierarchy,
    fit_volume_hierarchy_within, fit_volume_within, read_nrrd, read_raw,
};
pub use watertight::{MeshCheck, WeldedMesh, check_closed, weld};
