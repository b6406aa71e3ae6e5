//! Bringing real objects in: point clouds read from files ([`points`]) become a clay fitted
//! by least squares ([`cloud`]). `dynaclay import` is the command that uses them.

pub mod cloud;
pub mod points;

pub use cloud::{CloudFit, CloudFitError, CloudFitOptions, SignedBy, fit_point_cloud};
pub use points::{MAX_POINTS, PointCloud, PointsError, read_points};
