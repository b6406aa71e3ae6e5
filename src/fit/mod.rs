//! Bringing real objects in: point clouds ([`points`]) and volumes ([`volume`]) read from
//! files become a clay fitted by least squares ([`cloud`], [`volume::fit_volume`]).
//! `dynaclay import` is the command that uses them.

pub mod cloud;
pub mod points;
pub mod volume;

pub use cloud::{CloudFit, CloudFitError, CloudFitOptions, SignedBy, fit_point_cloud};
pub use points::{MAX_POINTS, PointCloud, PointsError, read_points};
pub use volume::{Sample, Volume, VolumeError, VolumeFit, fit_volume, read_nrrd, read_raw};
