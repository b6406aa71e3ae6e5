//! Errors of the render module, as values with messages that name what failed and where.

use std::path::PathBuf;

use super::chunk::ChunkError;

/// Why a render could not be produced.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// No usable GPU adapter (hardware or software) on this machine. Callers that can do
    /// without a picture should print this and carry on; see [`RenderError::is_no_adapter`].
    #[error("no GPU adapter: tried {}", tried.join("; "))]
    NoAdapter {
        /// One entry per backend tried, with the reason it gave.
        tried: Vec<String>,
    },
    /// The adapter refused to create a device.
    #[error("GPU adapter {adapter:?} refused a device: {message}")]
    Device { adapter: String, message: String },
    /// A mesh chunk was malformed.
    #[error("cannot render: {0}")]
    Chunk(#[from] ChunkError),
    /// Copying the frame back from the GPU failed.
    #[error("reading the frame back from the GPU failed: {message}")]
    Readback { message: String },
    /// Writing the PNG failed.
    #[error("writing PNG {}: {message}", path.display())]
    Png { path: PathBuf, message: String },
    /// The GPU (or the software rasterizer's memory) could not hold `what`: caught from
    /// wgpu's out-of-memory error scope instead of a panic.
    #[error(
        "the GPU ran out of memory for {what} ({message}); a smaller image or window needs less"
    )]
    OutOfMemory { what: &'static str, message: String },
    /// The GPU refused an operation on `what` (a validation or internal error, caught from an
    /// error scope instead of a panic).
    #[error("the GPU refused {what}: {message}")]
    Gpu { what: &'static str, message: String },
    /// The GPU device was lost (driver reset, device removed).
    #[error("the GPU device was lost: {message}")]
    DeviceLost { message: String },
}

impl RenderError {
    /// True when the machine simply has no GPU adapter, as opposed to a real failure.
    #[must_use]
    pub fn is_no_adapter(&self) -> bool {
        matches!(self, Self::NoAdapter { .. })
    }
}
