//! dynaclay: a haptic volumetric sculpting engine.
//!
//! The workspace is layered, and Cargo enforces it (a crate can only use the ones below it):
//!
//! | crate | what it holds |
//! | --- | --- |
//! | `dynaclay-files` | the bounded reader and the one atomic writer |
//! | `dynaclay-loops` | fixed-rate loops, triple buffers, latency recording |
//! | `dynaclay-devices` | arms over HID and serial, the simulated arm, the safety filter, recordings |
//! | `dynaclay-core` | the clay: field, dynamics, tools, haptic rendering, meshing, sessions and scripts |
//! | `dynaclay-import` | fitting clouds and meshes, point-set surfaces, particles, the compact RBF |
//! | `dynaclay-engine` | the three loops wired, commands, the lockstep engine, replay |
//! | `dynaclay` (this crate) | the command line, the renderer and the window |
//!
//! The lower crates' modules are re-exported here under their old names
//! (`dynaclay::field`, `dynaclay::engine`, …), so that a user of the library needs one
//! dependency.

#![deny(unsafe_op_in_unsafe_fn)]

pub use dynaclay_core::{dynamics, field, haptics, io, mesh, tools};
pub use dynaclay_engine as engine;
pub use dynaclay_import::{fit, particles, pointset, rbf};

pub mod app;
pub mod cli;
pub mod render;
