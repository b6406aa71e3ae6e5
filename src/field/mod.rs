//! The implicit solid: a uniform cubic B-spline field and the operators on it.

mod basis;
mod lattice;

pub use basis::{cubic_weights, cubic_weights_and_derivatives};
pub use lattice::{BSplineLattice, LatticeError};
