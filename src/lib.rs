//! dynaclay: a haptic volumetric sculpting engine.
//!
//! The clay is the level set `s(x) = c0` of a trivariate cubic B-spline (`field`), whose
//! coefficients move under density-spring dynamics (`dynamics`) driven by forces that a
//! force-feedback arm applies. Three fixed-rate loops (`engine`) — haptic, simulation and
//! graphics — share state only through lock-free triple buffers from `dynaclay-loops`.
//! Folders follow the data flow: field → dynamics → tools → haptics → mesh → io → engine → render
//! → app.

#![deny(unsafe_op_in_unsafe_fn)]
#![warn(clippy::undocumented_unsafe_blocks)]

pub mod app;
pub mod cli;
pub mod dynamics;
pub mod engine;
pub mod field;
pub mod fit;
pub mod haptics;
pub mod io;
pub mod mesh;
pub mod particles;
pub mod pointset;
pub mod rbf;
pub mod render;
pub mod tools;
