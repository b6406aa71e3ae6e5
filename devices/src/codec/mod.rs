//! Protocol codecs: pure functions over byte slices, no I/O, no panics on input, and no
//! allocation, except [`haply_service`], whose JSON runs on its driver's I/O thread.

pub mod cartesian;
mod error;
pub mod falcon;
pub mod frame;
pub mod haply_board;
pub mod haply_service;
pub mod spacemouse;
pub mod woodenhaptics;

pub use error::CodecError;
