//! Errors of the render module, as values with messages that name what failed and where.

use std::path::PathBuf;

use super::chunk::ChunkError;

/// Why a render could not be produced.
#[derive(Debug)]
pub enum RenderError {
    /// No usable GPU adapter (hardware or software) on this machine. Callers that can do
    /// without a picture should print this and carry on; see [`RenderError::is_no_adapter`].
    NoAdapter {
        /// One entry per backend tried, with the reason it gave.
        tried: Vec<String>,
    },
    /// The adapter refused to create a device.
    Device { adapter: String, message: String },
    /// A mesh chunk was malformed.
    Chunk(ChunkError),
    /// Copying the frame back from the GPU failed.
    Readback { message: String },
    /// Writing the PNG failed.
    Png { path: PathBuf, message: String },
    /// The GPU (or the software rasterizer's memory) could not hold `what`: caught from
    /// wgpu's out-of-memory error scope instead of a panic.
    OutOfMemory { what: &'static str, message: String },
    /// The GPU refused an operation on `what` (a validation or internal error, caught from an
    /// error scope instead of a panic).
    Gpu { what: &'static str, message: String },
    /// The GPU device was lost (driver reset, device removed).
    DeviceLost { message: String },
}

impl RenderError {
    /// True when the machine simply has no GPU adapter, as opposed to a real failure.
    #[must_use]
    pub fn is_no_adapter(&self) -> bool {
        matches!(self, Self::NoAdapter { .. })
    }
}

impl std::fmt::Display for RenderError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::NoAdapter { tried } => {
                write!(f, "no GPU adapter: tried {}", tried.join("; "))
            }
            Self::Device { adapter, message } => {
                write!(f, "GPU adapter {adapter:?} refused a device: {message}")
            }
            Self::Chunk(e) => write!(f, "cannot render: {e}"),
            Self::Readback { message } => {
                write!(f, "reading the frame back from the GPU failed: {message}")
            }
            Self::Png { path, message } => {
                write!(f, "writing PNG {}: {message}", path.display())
            }
            Self::OutOfMemory { what, message } => write!(
                f,
                "the GPU ran out of memory for {what} ({message}); a smaller image or window \
                 needs less"
            ),
            Self::Gpu { what, message } => write!(f, "the GPU refused {what}: {message}"),
            Self::DeviceLost { message } => write!(f, "the GPU device was lost: {message}"),
        }
    }
}

impl std::error::Error for RenderError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Self::Chunk(e) => Some(e),
            _ => None,
        }
    }
}

impl From<ChunkError> for RenderError {
    fn from(e: ChunkError) -> Self {
        Self::Chunk(e)
    }
}
