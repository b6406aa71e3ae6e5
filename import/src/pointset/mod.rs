//! Point-set surfaces with local B-spline fields (Guo & Qin 2003): each point sample carries a
//! small trivariate B-spline distance field (§3), the fields blend into one global field
//! (eq. 5), the global field gets the density-spring dynamics of Hua & Qin on a mass-spring
//! grid (§4), points are inserted and removed as the surface stretches (§4.3), and booleans
//! keep their intersection curve sharp by keeping two patches (§5.1, Table 1), and images are
//! embossed or engraved onto the points (§5.1).
//!
//! [`PointSetFollower`] keeps a point set on the live engine's clay: on the graphics loop, the
//! points follow each new copy of the clay by eq. (9) with bounded dynamic sampling, and a
//! viewer draws them as splats.
//!
//! Units: every length here (spacings, half-widths, bands, reaches) is in the point set's
//! own coordinates and carries `_fu`: field units when the set lies on the clay, and the
//! cloud's unit frame ([`UnitFrame`]) while a file's cloud is built; `_m` is kept for the
//! device's metres.
//!
//! Nothing here runs on the haptic thread: construction, sampling and booleans allocate; the
//! per-step update of [`PointSetSculpt`] allocates nothing after its set-up.

mod boolean;
mod curvature;
mod emboss;
mod error;
mod follow;
mod frame;
mod local;
mod normals;
mod ply;
mod pull;
mod sampling;
mod sculpt;
mod surface;

pub use boolean::{BooleanOp, SharpBoolean};
pub use curvature::{NormalGradient, normal_gradient};
pub use emboss::{EmbossReport, emboss};
pub use error::PointSetError;
pub use follow::{
    CURVATURE_STEP_SPANS, DISC_CURVATURE_RADII, FollowOptions, FollowReport, FollowedPoints,
    LOST_SPANS, MAX_STEP_SPANS, PointFollower, PointSetFollower, PointSetView, SETTLED_MOVE_SPANS,
};
pub use frame::UnitFrame;
pub use local::{FitSample, FitScratch, LOCAL_COUNT, LOCAL_DIM, LocalField, fit_local};
pub use normals::{orient_over_mst, plane_normal};
pub use ply::{encode_point_ply, write_point_ply};
pub use pull::{PULL_GAIN, PullReport, RESAMPLE_EVERY, pull};
pub use sampling::{
    INSERT_CLEARANCE, SAME_SHEET_COSINE, SamplingOptions, SamplingReport, farthest_voronoi_vertex,
    nearest_spacings, resample, same_sheet,
};
pub use sculpt::{CornerBlend, PointSetSculpt, SculptOptions, UpdateTimes};
pub use surface::{
    BuildTimes, DEFAULT_COLOUR, FALLBACK_WEIGHT, PointSet, PointSetOptions, nearest_neighbours,
};
