//! GPU faults as values: wgpu's error scopes around allocations, and a log behind the device's
//! uncaptured-error and device-lost callbacks.
//!
//! Without a handler, wgpu panics on an error raised outside any error scope (a validation
//! error, an out-of-memory error) and only logs a lost device. [`GpuFaultLog::install`] replaces
//! that: errors are counted (and, for the GUI, said on stderr), the first one of each kind is
//! kept, and the caller decides what to show. [`guarded_on`] runs allocations inside
//! out-of-memory and validation scopes so a refused allocation is a [`RenderError`] naming what
//! was being made.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, OnceLock};

use super::error::RenderError;

/// How many uncaptured errors are written to stderr before the rest are only counted.
pub const PRINTED_ERRORS: u64 = 8;

/// What wgpu reported through a device's callbacks: counts, and the first message of each kind.
#[derive(Debug, Default)]
pub struct GpuFaultLog {
    /// Write each fault to stderr (the first [`PRINTED_ERRORS`] errors, and a lost device).
    to_stderr: bool,
    errors: AtomicU64,
    out_of_memory: AtomicU64,
    /// The first uncaptured error: (out of memory?, message).
    first_error: OnceLock<(bool, String)>,
    lost: OnceLock<String>,
}

impl GpuFaultLog {
    /// Installs the uncaptured-error handler and the device-lost callback on `device`
    /// (replacing wgpu's panicking default) and returns the log they fill. With `to_stderr`,
    /// faults are also written to stderr as they happen.
    pub fn install(device: &wgpu::Device, to_stderr: bool) -> Arc<Self> {
        let log = Arc::new(Self {
            to_stderr,
            ..Self::default()
        });
        let on_error = Arc::clone(&log);
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| on_error.record_error(&e)));
        let on_lost = Arc::clone(&log);
        device.set_device_lost_callback(move |reason, message| {
            on_lost.record_lost(&format!("{reason:?}: {message}"));
        });
        log
    }

    fn record_error(&self, e: &wgpu::Error) {
        let oom = matches!(e, wgpu::Error::OutOfMemory { .. });
        let n = self.errors.fetch_add(1, Ordering::Relaxed) + 1;
        if oom {
            self.out_of_memory.fetch_add(1, Ordering::Relaxed);
        }
        let _ = self.first_error.set((oom, e.to_string()));
        if self.to_stderr && n <= PRINTED_ERRORS {
            let kind = if oom { "out of memory" } else { "error" };
            eprintln!("dynaclay: GPU {kind} (#{n}), the window carries on: {e}");
            if n == PRINTED_ERRORS {
                eprintln!("dynaclay: further GPU errors are counted, not printed");
            }
        }
    }

    fn record_lost(&self, message: &str) {
        let _ = self.lost.set(message.to_owned());
        if self.to_stderr {
            eprintln!(
                "dynaclay: the GPU device was lost ({message}); the sculpt is kept and \
                 autosaved: save it and restart the window"
            );
        }
    }

    /// Errors raised outside any error scope so far (out-of-memory ones included).
    #[must_use]
    pub fn error_count(&self) -> u64 {
        self.errors.load(Ordering::Relaxed)
    }

    /// Out-of-memory errors among [`Self::error_count`].
    #[must_use]
    pub fn out_of_memory_count(&self) -> u64 {
        self.out_of_memory.load(Ordering::Relaxed)
    }

    /// The first uncaptured error, as (out of memory?, message).
    #[must_use]
    pub fn first_error(&self) -> Option<&(bool, String)> {
        self.first_error.get()
    }

    /// Why the device was lost, if it was.
    #[must_use]
    pub fn lost(&self) -> Option<&str> {
        self.lost.get().map(String::as_str)
    }

    /// The first fault as an error: a lost device first, then the first uncaptured error.
    ///
    /// # Errors
    /// [`RenderError::DeviceLost`], [`RenderError::OutOfMemory`] or [`RenderError::Gpu`]
    /// (naming `what`).
    pub fn check(&self, what: &'static str) -> Result<(), RenderError> {
        if let Some(message) = self.lost() {
            return Err(RenderError::DeviceLost {
                message: message.to_owned(),
            });
        }
        match self.first_error() {
            Some((true, message)) => Err(RenderError::OutOfMemory {
                what,
                message: message.clone(),
            }),
            Some((false, message)) => Err(RenderError::Gpu {
                what,
                message: message.clone(),
            }),
            None => Ok(()),
        }
    }
}

/// Runs `f` with `device`'s out-of-memory and validation errors caught in error scopes (on this
/// thread), so an allocation the GPU cannot hold or refuses is an error value, never a panic.
///
/// # Errors
/// [`RenderError::OutOfMemory`] or [`RenderError::Gpu`] naming `what`. The value `f` made is
/// dropped then: a resource whose creation failed is invalid and must not be used.
pub fn guarded_on<T>(
    device: &wgpu::Device,
    what: &'static str,
    f: impl FnOnce() -> T,
) -> Result<T, RenderError> {
    let oom = device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
    let validation = device.push_error_scope(wgpu::ErrorFilter::Validation);
    let value = f();
    // Scopes pop in reverse order of their pushes. On native wgpu the futures are ready at
    // once: the errors were raised synchronously by the calls in `f`.
    let invalid = pollster::block_on(validation.pop());
    let out_of_memory = pollster::block_on(oom.pop());
    if let Some(e) = out_of_memory {
        return Err(RenderError::OutOfMemory {
            what,
            message: e.to_string(),
        });
    }
    if let Some(e) = invalid {
        return Err(RenderError::Gpu {
            what,
            message: e.to_string(),
        });
    }
    Ok(value)
}
