//! The engine's clock: nanoseconds since the engine started, read by every loop to stamp the
//! path from the hand to the screen (see [`super::motion_to_photon`]).
//!
//! Guarantee: [`EngineClock::now_ns`] never allocates, never blocks and never fails: a wall
//! clock reads the monotonic clock once; a stepped clock does one relaxed atomic load. Clones
//! share one clock, so the haptic, simulation and graphics loops and whoever draws the frames
//! stamp on one time line.
//!
//! A threaded engine runs on the wall clock. A lockstep run (and any test) runs on a stepped
//! clock that only its owner advances, so stamps depend on the schedule alone, never on how
//! fast the machine is.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

/// One time line for every loop of an engine, in nanoseconds since its start.
#[derive(Clone, Debug)]
pub enum EngineClock {
    /// The monotonic wall clock, counted from `origin`.
    Wall {
        /// The instant that reads as 0 ns.
        origin: Instant,
    },
    /// A clock that stands still until [`EngineClock::set_ns`] or [`EngineClock::advance_ns`]
    /// moves it (lockstep runs, tests).
    Stepped(Arc<AtomicU64>),
}

impl EngineClock {
    /// The wall clock, reading 0 now.
    #[must_use]
    pub fn wall() -> Self {
        Self::Wall {
            origin: Instant::now(),
        }
    }

    /// A stepped clock reading 0 until it is moved.
    #[must_use]
    pub fn stepped() -> Self {
        Self::Stepped(Arc::new(AtomicU64::new(0)))
    }

    /// The time now, nanoseconds since the clock's start.
    #[must_use]
    pub fn now_ns(&self) -> u64 {
        match self {
            Self::Wall { origin } => u64::try_from(origin.elapsed().as_nanos()).unwrap_or(u64::MAX),
            // NOTE: Relaxed: the time carries no other data; each loop publishes its stamps
            // through the triple buffers, which order them.
            Self::Stepped(ns) => ns.load(Ordering::Relaxed),
        }
    }

    /// `at` on this clock (wall clocks; a stepped clock ignores `at` and reads its own time).
    #[must_use]
    pub fn ns_at(&self, at: Instant) -> u64 {
        match self {
            Self::Wall { origin } => {
                u64::try_from(at.saturating_duration_since(*origin).as_nanos()).unwrap_or(u64::MAX)
            }
            Self::Stepped(ns) => ns.load(Ordering::Relaxed),
        }
    }

    /// Sets a stepped clock to `ns` (never backwards: an earlier time is ignored); a wall
    /// clock cannot be set and ignores it. Returns the time the clock reads afterwards.
    pub fn set_ns(&self, ns: u64) -> u64 {
        match self {
            Self::Wall { .. } => self.now_ns(),
            Self::Stepped(now) => now.fetch_max(ns, Ordering::Relaxed).max(ns),
        }
    }

    /// Moves a stepped clock on by `ns`; a wall clock ignores it. Returns the time the clock
    /// reads afterwards.
    pub fn advance_ns(&self, ns: u64) -> u64 {
        match self {
            Self::Wall { .. } => self.now_ns(),
            Self::Stepped(now) => now.fetch_add(ns, Ordering::Relaxed).saturating_add(ns),
        }
    }

    /// Whether this clock moves only when told to.
    #[must_use]
    pub fn is_stepped(&self) -> bool {
        matches!(self, Self::Stepped(_))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stepped_clock_moves_only_forward_and_only_when_told() {
        let clock = EngineClock::stepped();
        let shared = clock.clone();
        assert_eq!(clock.now_ns(), 0);
        assert_eq!(clock.advance_ns(1_000), 1_000);
        assert_eq!(shared.now_ns(), 1_000, "clones share one time line");
        assert_eq!(clock.set_ns(500), 1_000, "never backwards");
        assert_eq!(clock.set_ns(4_000), 4_000);
        assert_eq!(shared.ns_at(Instant::now()), 4_000);
        assert!(clock.is_stepped());
    }

    #[test]
    fn a_wall_clock_counts_from_its_origin() {
        let origin = Instant::now();
        let clock = EngineClock::Wall { origin };
        assert_eq!(clock.ns_at(origin), 0);
        assert_eq!(
            clock.ns_at(origin + std::time::Duration::from_millis(3)),
            3_000_000
        );
        // Before the origin reads as 0, not a wrapped time.
        assert_eq!(
            EngineClock::Wall {
                origin: origin + std::time::Duration::from_secs(1)
            }
            .ns_at(origin),
            0
        );
        assert!(!clock.is_stepped());
    }
}
