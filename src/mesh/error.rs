//! Why a sampling grid could not be set up.

use glam::Vec3;

/// A sampling grid's parameters were unusable.
#[derive(Clone, Debug, PartialEq)]
pub enum GridError {
    /// The cell size was not a positive finite number.
    BadCellSize { cell_size: f32 },
    /// The origin had a NaN or infinite coordinate.
    BadOrigin { origin: Vec3 },
    /// An axis had zero cells or more than [`super::SampleGrid::MAX_CELLS`].
    BadCellCount { cells: [u32; 3] },
    /// The box to cover was empty, inverted or not finite.
    BadBox { min: Vec3, max: Vec3 },
}

impl std::fmt::Display for GridError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::BadCellSize { cell_size } => {
                write!(f, "grid cell size {cell_size} must be positive and finite")
            }
            Self::BadOrigin { origin } => write!(f, "grid origin {origin} is not finite"),
            Self::BadCellCount { cells } => write!(
                f,
                "grid of {cells:?} cells: each axis needs 1 to {} cells",
                super::SampleGrid::MAX_CELLS
            ),
            Self::BadBox { min, max } => {
                write!(f, "box from {min} to {max} is empty or not finite")
            }
        }
    }
}

impl std::error::Error for GridError {}
