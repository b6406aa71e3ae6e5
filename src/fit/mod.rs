//! Bringing real objects in: point clouds ([`points`]), meshes sampled into clouds ([`mesh`])
//! and volumes ([`volume`]) read from
//! files become a clay fitted by least squares ([`cloud`], [`volume::fit_volume`]); a cloud's
//! fit is refined by an octree of detail patches where the error is above a bound
//! ([`hierarchy`], Hua & Qin §5).
//! `dynaclay import` is the command that uses them.

pub mod cloud;
pub mod hierarchy;
pub mod mesh;
pub mod points;
pub mod volume;

pub use cloud::{
    CloudFit, CloudFitError, CloudFitOptions, SignedBy, SignedCloud, fit_point_cloud, sign_cloud,
};
pub use hierarchy::{FitProgress, HierarchicalFit, HierarchyOptions, LevelReport, fit_hierarchy};
pub use points::{MAX_POINTS, PointCloud, PointsError, read_points};
pub use volume::{
    Sample, Volume, VolumeError, VolumeFit, VolumeHierarchy, fit_volume, fit_volume_hierarchy,
    read_nrrd, read_raw,
};
