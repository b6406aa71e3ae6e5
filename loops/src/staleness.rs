//! Maps the age of a snapshot to a fade factor in [0, 1], so a consumer (the haptic loop) can
//! fade its output smoothly to zero when its input stops arriving.
//!
//! Guarantee: pure arithmetic — no allocation, no blocking, no panics, O(1). The factor is 1 up
//! to `fresh`, 0 from `limit` on, and falls between them along a smoothstep (C¹: no jump in the
//! factor nor in its slope at either end, so a force scaled by it has no jerk).

use std::time::Duration;

/// Fade schedule for data of a given age.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Staleness {
    /// Data up to this age is fully trusted (factor 1).
    pub fresh: Duration,
    /// Data this old or older is not used at all (factor 0).
    pub limit: Duration,
}

impl Staleness {
    /// A schedule that starts fading at `fresh` and reaches zero at `limit`. If `limit` is not
    /// after `fresh`, the factor steps from 1 to 0 at `limit`.
    #[must_use]
    pub const fn new(fresh: Duration, limit: Duration) -> Self {
        Self { fresh, limit }
    }

    /// A schedule that is fully fresh for the first half of `limit`, then fades to 0 at `limit`.
    #[must_use]
    pub const fn with_limit(limit: Duration) -> Self {
        Self {
            fresh: Duration::from_nanos(limit.as_nanos() as u64 / 2),
            limit,
        }
    }

    /// Fade factor for data of age `age`: 1 when fresh, 0 past the limit, smooth in between.
    #[must_use]
    pub fn factor(&self, age: Duration) -> f64 {
        if age >= self.limit {
            return 0.0;
        }
        if age <= self.fresh {
            return 1.0;
        }
        // Here fresh < age < limit, so the span is positive.
        let span = (self.limit - self.fresh).as_secs_f64();
        let t = ((age - self.fresh).as_secs_f64() / span).clamp(0.0, 1.0);
        1.0 - t * t * (3.0 - 2.0 * t)
    }

    /// True once data of age `age` is no longer used (factor 0).
    #[must_use]
    pub fn is_stale(&self, age: Duration) -> bool {
        age >= self.limit
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: Duration = Duration::from_millis(1);

    #[test]
    fn ends_and_midpoint() {
        let s = Staleness::new(MS * 10, MS * 30);
        assert_eq!(s.factor(Duration::ZERO), 1.0);
        assert_eq!(s.factor(MS * 10), 1.0);
        assert!((s.factor(MS * 20) - 0.5).abs() < 1e-12);
        assert_eq!(s.factor(MS * 30), 0.0);
        assert_eq!(s.factor(Duration::from_secs(1000)), 0.0);
        assert!(s.is_stale(MS * 30));
        assert!(!s.is_stale(MS * 29));
    }

    #[test]
    fn monotone_and_in_unit_interval() {
        let s = Staleness::with_limit(MS * 8);
        assert_eq!(s.fresh, MS * 4);
        let mut prev = 1.0;
        for us in 0..10_000u64 {
            let f = s.factor(Duration::from_micros(us));
            assert!((0.0..=1.0).contains(&f));
            assert!(f <= prev, "not monotone at {us} µs");
            prev = f;
        }
    }

    #[test]
    fn smooth_at_both_ends() {
        // Slope near the ends tends to zero (smoothstep), so small steps change little.
        let s = Staleness::new(MS * 10, MS * 20);
        let eps = Duration::from_micros(10);
        assert!(1.0 - s.factor(MS * 10 + eps) < 1e-5);
        assert!(s.factor(MS * 20 - eps) < 1e-5);
    }

    #[test]
    fn degenerate_schedule_is_a_step() {
        let s = Staleness::new(MS * 5, MS * 5);
        assert_eq!(s.factor(MS * 4), 1.0);
        assert_eq!(s.factor(MS * 5), 0.0);
        let inverted = Staleness::new(MS * 9, MS * 3);
        assert_eq!(inverted.factor(MS * 2), 1.0);
        assert_eq!(inverted.factor(MS * 3), 0.0);
    }
}
