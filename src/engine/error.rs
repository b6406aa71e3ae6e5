//! Why the engine could not start or finish.

use std::fmt;

use dynaclay_devices::DeviceError;
use dynaclay_loops::LoopError;

use crate::mesh::GridError;

/// An engine failure, naming the part that failed.
#[derive(Debug)]
pub enum EngineError {
    /// Opening or closing the device failed.
    Device(DeviceError),
    /// The meshing grid could not be made for the field.
    Mesh(GridError),
    /// A loop could not start, or panicked.
    Loop(LoopError),
    /// A loop thread ended without handing its state back (it panicked).
    Lost(&'static str),
    /// A device could not be switched while running.
    DeviceSwap(String),
}

impl fmt::Display for EngineError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Device(e) => write!(f, "device: {e}"),
            Self::Mesh(e) => write!(f, "mesh grid: {e}"),
            Self::Loop(e) => write!(f, "loop: {e}"),
            Self::Lost(what) => write!(f, "the {what} loop ended without handing back its state"),
            Self::DeviceSwap(why) => write!(f, "device switch: {why}"),
        }
    }
}

impl std::error::Error for EngineError {}

impl From<DeviceError> for EngineError {
    fn from(e: DeviceError) -> Self {
        Self::Device(e)
    }
}

impl From<GridError> for EngineError {
    fn from(e: GridError) -> Self {
        Self::Mesh(e)
    }
}

impl From<LoopError> for EngineError {
    fn from(e: LoopError) -> Self {
        Self::Loop(e)
    }
}
