//! Liveness check for a loop: the loop beats a shared counter every tick; a watchdog on another
//! thread notices when the counter stops moving for longer than a limit.
//!
//! Guarantee: [`Heartbeat::beat`] is one relaxed atomic increment — wait-free, no allocation, safe
//! on the haptic path. [`Watchdog::check_at`] is wait-free too and keeps its own state, so any
//! number of watchdogs may watch one heartbeat. The shared counter is freed by whichever holder
//! of the heartbeat is dropped last.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

/// A tick counter shared between a loop (which beats it) and watchdogs (which read it).
#[derive(Clone, Debug, Default)]
pub struct Heartbeat {
    count: Arc<AtomicU64>,
}

impl Heartbeat {
    /// A heartbeat at count 0.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// Counts one tick. Wait-free.
    pub fn beat(&self) {
        // NOTE: Relaxed is enough: the counter guards no other data, it only has to move, and
        // atomicity alone guarantees a reader eventually sees every increment.
        self.count.fetch_add(1, Ordering::Relaxed);
    }

    /// Beats counted so far.
    #[must_use]
    pub fn count(&self) -> u64 {
        self.count.load(Ordering::Relaxed)
    }
}

/// What a watchdog concluded about the loop it watches.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Liveness {
    /// The loop beat since the last check (`beats` times).
    Alive {
        /// Beats since the previous check.
        beats: u64,
    },
    /// No beat since the last check, but for less than the limit yet.
    Quiet {
        /// Time since the last observed beat.
        silent_for: Duration,
    },
    /// No beat for at least the limit: the loop stopped ticking.
    Stalled {
        /// Time since the last observed beat.
        silent_for: Duration,
    },
}

impl Liveness {
    /// True unless the loop is stalled.
    #[must_use]
    pub fn is_alive(&self) -> bool {
        !matches!(self, Self::Stalled { .. })
    }
}

/// Checks a [`Heartbeat`] against a silence limit.
#[derive(Clone, Debug)]
pub struct Watchdog {
    heartbeat: Heartbeat,
    limit: Duration,
    last_count: u64,
    last_change: Instant,
}

impl Watchdog {
    /// A watchdog that declares a stall after `limit` without a beat, counting from now.
    #[must_use]
    pub fn new(heartbeat: Heartbeat, limit: Duration) -> Self {
        Self::new_at(heartbeat, limit, Instant::now())
    }

    /// As [`new`](Self::new), counting silence from `now`.
    #[must_use]
    pub fn new_at(heartbeat: Heartbeat, limit: Duration, now: Instant) -> Self {
        let last_count = heartbeat.count();
        Self {
            heartbeat,
            limit,
            last_count,
            last_change: now,
        }
    }

    /// Checks now (reads the clock).
    pub fn check(&mut self) -> Liveness {
        self.check_at(Instant::now())
    }

    /// Checks at time `now`. Wait-free.
    pub fn check_at(&mut self, now: Instant) -> Liveness {
        let count = self.heartbeat.count();
        if count != self.last_count {
            let beats = count.wrapping_sub(self.last_count);
            self.last_count = count;
            self.last_change = now;
            return Liveness::Alive { beats };
        }
        let silent_for = now.saturating_duration_since(self.last_change);
        if silent_for >= self.limit {
            Liveness::Stalled { silent_for }
        } else {
            Liveness::Quiet { silent_for }
        }
    }

    /// The silence limit.
    #[must_use]
    pub fn limit(&self) -> Duration {
        self.limit
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: Duration = Duration::from_millis(1);

    #[test]
    fn beating_loop_is_alive() {
        let hb = Heartbeat::new();
        let t0 = Instant::now();
        let mut dog = Watchdog::new_at(hb.clone(), MS * 10, t0);
        hb.beat();
        hb.beat();
        assert_eq!(dog.check_at(t0 + MS), Liveness::Alive { beats: 2 });
        assert_eq!(hb.count(), 2);
    }

    #[test]
    fn silence_turns_quiet_then_stalled_then_alive_again() {
        let hb = Heartbeat::new();
        let t0 = Instant::now();
        let mut dog = Watchdog::new_at(hb.clone(), MS * 10, t0);
        assert_eq!(
            dog.check_at(t0 + MS * 4),
            Liveness::Quiet { silent_for: MS * 4 }
        );
        let stalled = dog.check_at(t0 + MS * 10);
        assert_eq!(
            stalled,
            Liveness::Stalled {
                silent_for: MS * 10
            }
        );
        assert!(!stalled.is_alive());
        hb.beat();
        assert!(dog.check_at(t0 + MS * 11).is_alive());
        // Silence is counted from the last observed beat, not from construction.
        assert!(dog.check_at(t0 + MS * 20).is_alive());
        assert!(!dog.check_at(t0 + MS * 21).is_alive());
    }

    #[test]
    fn watchdog_sees_beats_from_another_thread() {
        let hb = Heartbeat::new();
        let mut dog = Watchdog::new(hb.clone(), Duration::from_secs(60));
        let beater = hb.clone();
        std::thread::spawn(move || {
            for _ in 0..1000 {
                beater.beat();
            }
        })
        .join()
        .expect("beater");
        assert_eq!(dog.check(), Liveness::Alive { beats: 1000 });
        assert_eq!(dog.limit(), Duration::from_secs(60));
    }
}
