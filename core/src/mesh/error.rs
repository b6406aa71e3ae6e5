//! Why a sampling grid could not be set up.

use glam::Vec3;

/// A sampling grid's parameters were unusable.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum GridError {
    /// The cell size was not a positive finite number.
    #[error("grid cell size {cell_size} must be positive and finite")]
    BadCellSize { cell_size: f32 },
    /// The origin had a NaN or infinite coordinate.
    #[error("grid origin {origin} is not finite")]
    BadOrigin { origin: Vec3 },
    /// An axis had zero cells or more than [`super::SampleGrid::MAX_CELLS`].
    #[error("grid of {cells:?} cells: each axis needs 1 to {max} cells", max = super::SampleGrid::MAX_CELLS)]
    BadCellCount { cells: [u32; 3] },
    /// The box to cover was empty, inverted or not finite.
    #[error("box from {min} to {max} is empty or not finite")]
    BadBox { min: Vec3, max: Vec3 },
}
