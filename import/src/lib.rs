//! dynaclay's import and the other surface models: fitting a clay to point clouds, meshes and
//! volumes (`fit`), Guo & Qin's point-set surfaces (`pointset`), Zhang et al.'s constrained
//! particles (`particles`) and the compact RBF of the sculpt (`rbf`).
//!
//! Built on `dynaclay-core` (the clay, its tools and sessions); nothing here knows the loops.

#![deny(unsafe_op_in_unsafe_fn)]

pub mod fit;
pub mod particles;
pub mod pointset;
pub mod rbf;
