//! The force limit the user may change while the engine runs: a requested value written by
//! any thread and picked up by the haptic tick, and the bound the safety filter then applies,
//! reported back.
//!
//! Guarantee: wait-free and allocation-free on both sides — each value is one `f32` held as
//! bits in an `AtomicU32`. The haptic tick does one relaxed load per tick and, only when the
//! request changed, one constant-time filter update and one relaxed store. Relaxed suffices:
//! each value is the whole message and no other memory depends on it.

use std::sync::Arc;
use std::sync::atomic::{AtomicU32, Ordering};

/// A shared handle on the force limit (cheap to clone: an `Arc`).
#[derive(Clone, Debug)]
pub struct ForceLimit {
    inner: Arc<Cells>,
}

#[derive(Debug)]
struct Cells {
    /// What was asked for, newtons (as `f32` bits).
    requested: AtomicU32,
    /// What the safety filter applies, newtons (as `f32` bits).
    applied: AtomicU32,
}

/// A force limit that is not a number of newtons, zero or more.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[error("max force {requested_n} N: must be a number of newtons, zero or more")]
pub struct InvalidForceLimit {
    /// The value asked for.
    pub requested_n: f32,
}

impl ForceLimit {
    /// A limit whose request and applied bound start at `requested_n` and `applied_n`.
    #[must_use]
    pub fn new(requested_n: f32, applied_n: f32) -> Self {
        Self {
            inner: Arc::new(Cells {
                requested: AtomicU32::new(requested_n.to_bits()),
                applied: AtomicU32::new(applied_n.to_bits()),
            }),
        }
    }

    /// Asks the haptic loop to limit force to `max_force_n` newtons from its next tick on
    /// (the device's own maximum still caps it; `f32::INFINITY` means the device's maximum).
    ///
    /// # Errors
    /// A NaN or negative value; nothing changes then.
    pub fn request(&self, max_force_n: f32) -> Result<(), InvalidForceLimit> {
        if max_force_n.is_nan() || max_force_n < 0.0 {
            return Err(InvalidForceLimit {
                requested_n: max_force_n,
            });
        }
        self.inner
            .requested
            .store(max_force_n.to_bits(), Ordering::Relaxed);
        Ok(())
    }

    /// The latest requested limit, newtons.
    #[must_use]
    pub fn requested_n(&self) -> f32 {
        f32::from_bits(self.inner.requested.load(Ordering::Relaxed))
    }

    /// The bound the safety filter applied at the haptic loop's latest change, newtons.
    #[must_use]
    pub fn applied_n(&self) -> f32 {
        f32::from_bits(self.inner.applied.load(Ordering::Relaxed))
    }

    /// The request as raw bits (the haptic tick compares bits to notice a change).
    #[must_use]
    pub(crate) fn requested_bits(&self) -> u32 {
        self.inner.requested.load(Ordering::Relaxed)
    }

    /// Records the bound the filter now applies.
    pub(crate) fn set_applied(&self, applied_n: f32) {
        self.inner
            .applied
            .store(applied_n.to_bits(), Ordering::Relaxed);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn requests_are_shared_and_bad_values_refused() {
        let limit = ForceLimit::new(f32::INFINITY, 8.0);
        let other = limit.clone();
        assert_eq!(other.requested_n(), f32::INFINITY);
        limit.request(2.5).unwrap();
        assert_eq!(other.requested_n(), 2.5);
        assert_eq!(other.requested_bits(), 2.5f32.to_bits());
        let err = limit.request(-1.0).unwrap_err();
        assert_eq!(err.requested_n, -1.0);
        assert!(err.to_string().contains("-1 N"), "{err}");
        assert!(limit.request(f32::NAN).is_err());
        assert_eq!(other.requested_n(), 2.5, "refused values change nothing");
        other.set_applied(2.5);
        assert_eq!(limit.applied_n(), 2.5);
    }
}
