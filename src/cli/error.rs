//! Why a command failed, and the exit code each kind of failure gives.

use std::path::{Path, PathBuf};

use crate::engine::EngineError;
use crate::io::{ScriptError, SessionError};
use crate::render::RenderError;

/// Why a command failed; each kind has its own exit code.
#[derive(Debug, thiserror::Error)]
pub enum CliError {
    /// A bad argument (exit 2).
    #[error("{0}")]
    Usage(String),
    /// A bad input file or argument (exit 2), with the error that said so.
    #[error("{context}: {source}")]
    BadInput {
        /// What was read (the file, the option).
        context: String,
        /// Why it was refused.
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// A bad script (exit 2).
    #[error("script error: {0}")]
    Script(ScriptError),
    /// The device could not be made or opened (exit 3), with the error that said so.
    #[error("device error: {context}: {source}")]
    DeviceFailed {
        /// What was being done (the device spec, the recording).
        context: String,
        /// Why it failed.
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// The engine failed (exit 1).
    #[error("engine error: {0}")]
    Engine(EngineError),
    /// An output could not be made, or the starting clay could not be built (exit 1), for a
    /// reason found here (no error underneath).
    #[error("output error: {0}")]
    Output(String),
    /// An output could not be written, or the starting clay could not be built (exit 1),
    /// with the error that said so.
    #[error("output error: {context}: {source}")]
    OutputFailed {
        /// What was being done (the file, the step).
        context: String,
        /// Why it failed.
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// A session file could not be read (exit 2).
    #[error("cannot read session: {0}")]
    Session(SessionError),
    /// The run ended and every output was written, but the device failed to close (exit 5;
    /// see [`CliError::DEVICE_FAULT_EXIT`]).
    #[error("device fault at the end of the run (every output was written): {0}")]
    DeviceFault(dynaclay_devices::DeviceError),
    /// Rendering the PNG at the path failed (exit 1), or found no GPU adapter (exit 4; see
    /// [`CliError::NO_ADAPTER_EXIT`]).
    #[error("{}", render_message(.0, .1))]
    Render(RenderError, PathBuf),
    /// A mesh or image would not fit the memory budget; refused before allocating (exit 2).
    #[error("{0}")]
    OverBudget(super::budget::OverBudget),
    /// `dynaclay rbf` failed (exit 2 for bad input, 1 otherwise).
    #[error("rbf: {0}")]
    Rbf(super::rbf::RbfCommandError),
    /// An output breaks the output rule (an input, the script, a file of another kind, a
    /// link, or outside the allowed folders); refused before any work (exit 2).
    #[error("{0}")]
    OutputRefused(crate::io::OutputRefused),
    /// Ctrl-C stopped the command before it wrote anything (exit 130, the shell's code for
    /// SIGINT; see [`CliError::INTERRUPTED_EXIT`]).
    #[error("interrupted: {0}")]
    Interrupted(String),
}

/// A render failure with its file; no adapter at all is said as a skip, not a failure.
fn render_message(e: &RenderError, path: &Path) -> String {
    if e.is_no_adapter() {
        format!("{e}; skipped rendering {}", path.display())
    } else {
        format!("rendering {}: {e}", path.display())
    }
}

impl CliError {
    /// [`CliError::OutputFailed`]: `context` (what was being done) failed with `source`.
    pub fn output(
        context: impl Into<String>,
        source: impl Into<Box<dyn std::error::Error + Send + Sync>>,
    ) -> Self {
        Self::OutputFailed {
            context: context.into(),
            source: source.into(),
        }
    }

    /// [`CliError::BadInput`]: `context` (the file or option) was refused with `source`.
    pub fn bad_input(
        context: impl Into<String>,
        source: impl Into<Box<dyn std::error::Error + Send + Sync>>,
    ) -> Self {
        Self::BadInput {
            context: context.into(),
            source: source.into(),
        }
    }

    /// [`CliError::DeviceFailed`]: `context` (the device or recording) failed with `source`.
    pub fn device(
        context: impl Into<String>,
        source: impl Into<Box<dyn std::error::Error + Send + Sync>>,
    ) -> Self {
        Self::DeviceFailed {
            context: context.into(),
            source: source.into(),
        }
    }
    /// Exit status of `dynaclay render` when the machine has no GPU adapter: distinct from a
    /// failure (1) and a bad argument (2), so scripts can tell "cannot render here" apart.
    pub const NO_ADAPTER_EXIT: i32 = 4;

    /// Exit status of `dynaclay run` when every output was written but the device failed at
    /// the end of the run (closing it): the sculpt is safe, the hardware needs a look.
    pub const DEVICE_FAULT_EXIT: i32 = 5;

    /// Exit status when Ctrl-C stopped a command (`dynaclay import` during a fit): 128 + 2,
    /// what a shell reports for a process ended by SIGINT.
    pub const INTERRUPTED_EXIT: i32 = 130;

    /// The process exit code for this error.
    #[must_use]
    pub fn exit_code(&self) -> i32 {
        match self {
            Self::Usage(_)
            | Self::BadInput { .. }
            | Self::Script(_)
            | Self::Session(_)
            | Self::OverBudget(_)
            | Self::OutputRefused(_) => 2,
            Self::DeviceFailed { .. } => 3,
            Self::DeviceFault(_) => Self::DEVICE_FAULT_EXIT,
            Self::Render(e, _) if e.is_no_adapter() => Self::NO_ADAPTER_EXIT,
            Self::Engine(_) | Self::Output(_) | Self::OutputFailed { .. } | Self::Render(..) => 1,
            Self::Rbf(e) => e.exit_code(),
            Self::Interrupted(_) => Self::INTERRUPTED_EXIT,
        }
    }
}
