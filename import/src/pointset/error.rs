//! Why a point-set operation was refused.

/// Errors of the point-set surface.
#[derive(Debug, thiserror::Error)]
pub enum PointSetError {
    /// The cloud has fewer points than one neighbourhood needs.
    #[error("{got} points: a point-set surface needs at least {need}")]
    TooFewPoints {
        /// Points given.
        got: usize,
        /// Points needed (`k + 1`).
        need: usize,
    },
    /// A coordinate is NaN or infinite.
    #[error("point {index} is not finite")]
    NotFinite {
        /// Index of the first bad point.
        index: usize,
    },
    /// Every point sits at the same place.
    #[error("the points have no spread (all neighbours coincide)")]
    Degenerate,
    /// A local least-squares fit had no solution.
    #[error("the local field of point {index} could not be fitted")]
    FitFailed {
        /// Index of the first point whose fit failed.
        index: usize,
    },
    /// The k-d tree could not be built.
    #[error("k-d tree: {0}")]
    Index(String),
    /// Parts of different lengths.
    #[error("points, normals, colours and fields differ in length")]
    LengthMismatch,
    /// The sculpting region could not be set up.
    #[error("sculpting region: {0}")]
    Region(String),
    /// A pull's target lies so far from the surface that its sculpting region would hold
    /// more than [`MAX_PULL_REGION_NODES`](super::pull::MAX_PULL_REGION_NODES) lattice nodes;
    /// refused before anything is allocated.
    #[error(
        "the pull reaches {reach:.3e} from the surface: its sculpting region would hold {nodes:.3e} lattice nodes of spacing {spacing:.3e}, past the {max} a pull may use; pull nearer the surface"
    )]
    PullTooFar {
        /// Distance from the nearest surface point to the target.
        reach: f32,
        /// Lattice nodes the region would hold.
        nodes: f64,
        /// The lattice spacing (the point spacing).
        spacing: f32,
        /// The most allowed.
        max: usize,
    },
    /// An emboss's parameters are invalid (the error names the parameter).
    #[error("emboss: {0}")]
    Emboss(#[from] dynaclay_core::tools::EmbossParamsError),
    /// A simulation step was refused.
    #[error("simulation step: {0}")]
    Step(#[from] dynaclay_core::dynamics::StepError),
}
