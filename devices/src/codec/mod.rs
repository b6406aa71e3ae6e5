//! Protocol codecs: pure functions over byte slices, no I/O, no allocation, no panics on input.

pub mod cartesian;
mod error;
pub mod falcon;
pub mod frame;
pub mod spacemouse;
pub mod woodenhaptics;

pub use error::CodecError;
