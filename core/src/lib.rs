//! dynaclay's core: the clay and everything that acts on it, with no loop, device driver or
//! window in sight.
//!
//! The clay is the level set `s(x) = c0` of trivariate cubic B-splines (`field`, Hua & Qin
//! eq. (3)), whose coefficients move under density-spring dynamics (`dynamics`, §4–§7) driven
//! by the sculpting tools (`tools`, with Ferley's tools and undo) and felt through the haptic
//! renderer (`haptics`); `mesh` extracts its surface with local marching cubes on an octree,
//! and `io` reads and writes sessions and scripts.
//!
//! Modules follow the data flow: field → dynamics → tools → haptics → mesh → io. The crates
//! above (`dynaclay-import`, `dynaclay-engine`, `dynaclay`) build on this one; Cargo keeps
//! every arrow pointing down.

#![deny(unsafe_op_in_unsafe_fn)]

pub mod dynamics;
pub mod field;
pub mod haptics;
pub mod io;
pub mod mesh;
pub mod tools;
