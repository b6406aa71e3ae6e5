//! Wake-ups for a periodic loop: another thread rings a [`WakeBell`] when it has published
//! something the loop should act on, and the loop, sleeping towards its next deadline, starts a
//! tick at once instead of at the deadline — but never sooner after its previous tick than its
//! rate cap allows, so a bell rung at a thousand hertz cannot drive the loop at that rate.
//!
//! Guarantee: [`WakeBell::ring`] is lock-free, never allocates and never waits: a relaxed
//! `fetch_min`, a release store and an unpark of the loop thread (an atomic swap, plus one
//! futex wake system call when the loop is asleep). The loop side ([`spawn_woken_loop`]
//! (crate::spawn_woken_loop)) sleeps with `std::thread::park_timeout`; it takes no lock and
//! allocates nothing after set-up. The decision of when to tick is the pure
//! [`WakeSchedule::decide`], tested on injected instants.
//!
//! A woken loop does not keep the absolute deadline grid of a plain loop: its next periodic
//! tick is due one period after the start of the previous tick, whether that tick was periodic
//! or woken. Its ticks' `scheduled` time is the deadline for a periodic tick, and for a woken
//! tick the moment the bell was first rung since the previous tick (or the earliest moment the
//! rate cap allowed, if later), so the recorded lateness is the wake-up's own delay.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, OnceLock};
use std::thread::Thread;
use std::time::{Duration, Instant};

/// The highest rate cap a bell takes: the highest rate a loop may run at (the runner's
/// `MAX_RATE_HZ`; this module does not import the runner, which imports it).
pub const MAX_WAKE_RATE_HZ: f64 = 100_000.0;

/// A `rung_at_ns` that means "not rung since the last tick".
const NOT_RUNG: u64 = u64::MAX;

/// Errors from making a wake bell.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum WakeError {
    /// The rate cap is not a finite rate in (0, [`MAX_WAKE_RATE_HZ`]].
    #[error(
        "wake bell: `max_rate_hz` must be finite and in (0, {MAX_WAKE_RATE_HZ}], got {max_rate_hz}"
    )]
    InvalidMaxRate {
        /// The rate asked for.
        max_rate_hz: f64,
    },
}

/// What the bell and its loop share.
#[derive(Debug)]
struct Shared {
    /// Rung since the loop's last tick.
    rung: AtomicBool,
    /// When it was first rung since the loop's last tick, nanoseconds after `epoch`
    /// ([`NOT_RUNG`] when not).
    rung_at_ns: AtomicU64,
    /// The instant `rung_at_ns` counts from.
    epoch: Instant,
    /// The loop thread, once it has started.
    thread: OnceLock<Thread>,
}

/// The ringing end: clone it to every thread that publishes work for the loop.
#[derive(Clone, Debug)]
pub struct WakeBell {
    shared: Arc<Shared>,
}

/// The loop's end: handed to [`spawn_woken_loop`](crate::spawn_woken_loop) with the rate cap.
#[derive(Debug)]
pub struct WakeWaiter {
    shared: Arc<Shared>,
    min_interval: Duration,
}

/// Makes a connected bell and waiter; a woken loop ticks at most `max_rate_hz` times a second
/// however often the bell rings. Allocates (call at set-up).
///
/// # Errors
/// [`WakeError::InvalidMaxRate`] when `max_rate_hz` is not finite or outside
/// (0, [`MAX_WAKE_RATE_HZ`]].
pub fn wake_bell(max_rate_hz: f64) -> Result<(WakeBell, WakeWaiter), WakeError> {
    if !(max_rate_hz.is_finite() && max_rate_hz > 0.0 && max_rate_hz <= MAX_WAKE_RATE_HZ) {
        return Err(WakeError::InvalidMaxRate { max_rate_hz });
    }
    let shared = Arc::new(Shared {
        rung: AtomicBool::new(false),
        rung_at_ns: AtomicU64::new(NOT_RUNG),
        epoch: Instant::now(),
        thread: OnceLock::new(),
    });
    Ok((
        WakeBell {
            shared: Arc::clone(&shared),
        },
        WakeWaiter {
            shared,
            min_interval: Duration::from_secs_f64(1.0 / max_rate_hz),
        },
    ))
}

impl WakeBell {
    /// Asks the loop for a tick as soon as its rate cap allows. Lock-free, never allocates,
    /// never waits; a ring before the loop has started is kept for its first sleep.
    pub fn ring(&self) {
        let now_ns = u64::try_from(self.shared.epoch.elapsed().as_nanos()).unwrap_or(NOT_RUNG - 1);
        // NOTE: Relaxed: the time is a statistic (the woken tick's `scheduled`); a ring that
        // lands between the loop's taking of the flag and of the time counts towards the next
        // tick's lateness, never towards whether the loop wakes.
        self.shared.rung_at_ns.fetch_min(now_ns, Ordering::Relaxed);
        // NOTE: Release pairs with the loop's Acquire swap: whatever this thread wrote before
        // ringing is visible to the tick the ring starts.
        self.shared.rung.store(true, Ordering::Release);
        if let Some(thread) = self.shared.thread.get() {
            thread.unpark();
        }
    }
}

impl WakeWaiter {
    /// The shortest time between two tick starts (one over the rate cap).
    #[must_use]
    pub fn min_interval(&self) -> Duration {
        self.min_interval
    }

    /// Whether the bell was rung since the loop's last tick (for observers and tests; the
    /// loop itself decides with [`WakeSchedule::decide`]).
    #[must_use]
    pub fn is_rung(&self) -> bool {
        self.rung_at().is_some()
    }

    /// A bell that rings this waiter.
    #[must_use]
    pub fn bell(&self) -> WakeBell {
        WakeBell {
            shared: Arc::clone(&self.shared),
        }
    }

    /// Registers the calling thread as the one [`WakeBell::ring`] unparks (the loop thread,
    /// at set-up; a second call keeps the first thread).
    pub(crate) fn register_current_thread(&self) {
        let _ = self.shared.thread.set(std::thread::current());
    }

    /// When the bell was first rung since the last tick, if it was.
    fn rung_at(&self) -> Option<Instant> {
        // NOTE: Acquire pairs with the bell's Release store (see `ring`).
        if !self.shared.rung.load(Ordering::Acquire) {
            return None;
        }
        let ns = self.shared.rung_at_ns.load(Ordering::Relaxed);
        // A ring whose time was taken by the previous tick (see `ring`): it counts as now.
        Some(if ns == NOT_RUNG {
            Instant::now()
        } else {
            self.shared.epoch + Duration::from_nanos(ns)
        })
    }

    /// Forgets the rings so far: the tick about to start serves them.
    fn take(&self) {
        // NOTE: Acquire pairs with the bell's Release store (see `ring`).
        self.shared.rung.swap(false, Ordering::Acquire);
        self.shared.rung_at_ns.store(NOT_RUNG, Ordering::Relaxed);
    }

    /// Sleeps until the next tick is due by `schedule` (its deadline, or a ring the rate cap
    /// allows) and returns when it was due; `None` once `stopped` says so (whoever stops the
    /// loop rings the bell). Parks the thread; takes no lock, never allocates.
    pub(crate) fn wait_for_tick(
        &self,
        schedule: &WakeSchedule,
        stopped: impl Fn() -> bool,
    ) -> Option<Instant> {
        loop {
            if stopped() {
                return None;
            }
            let now = Instant::now();
            match schedule.decide(now, self.rung_at()) {
                WakeDecision::TickNow { scheduled } => {
                    self.take();
                    return Some(scheduled);
                }
                // A spurious unpark or an early ring only loops back here.
                WakeDecision::SleepUntil(at) => std::thread::park_timeout(at - now),
            }
        }
    }
}

/// When a woken loop's next tick is due.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct WakeSchedule {
    /// The loop's period: a tick is due this long after the previous one even without a ring.
    pub period: Duration,
    /// The rate cap's interval: no tick starts sooner than this after the previous one.
    pub min_interval: Duration,
    /// When the previous tick started (`None` before the first, which is due at once).
    pub last_tick: Option<Instant>,
}

/// What a woken loop does next ([`WakeSchedule::decide`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WakeDecision {
    /// Start a tick now; it was due at `scheduled`.
    TickNow {
        /// When the tick was due: the periodic deadline, or the ring (no sooner than the cap
        /// allowed).
        scheduled: Instant,
    },
    /// Sleep until this instant (or a ring) and decide again.
    SleepUntil(Instant),
}

impl WakeSchedule {
    /// A schedule before the first tick.
    #[must_use]
    pub fn new(period: Duration, min_interval: Duration) -> Self {
        Self {
            period,
            min_interval,
            last_tick: None,
        }
    }

    /// At `now`, with the bell first rung at `rung_at` since the last tick (`None`: not rung):
    /// tick when the period has run out, or when rung and the rate cap's interval has passed;
    /// otherwise sleep until whichever of those comes first.
    #[must_use]
    pub fn decide(&self, now: Instant, rung_at: Option<Instant>) -> WakeDecision {
        let Some(last) = self.last_tick else {
            return WakeDecision::TickNow { scheduled: now };
        };
        let deadline = last + self.period;
        if now >= deadline {
            return WakeDecision::TickNow {
                scheduled: deadline,
            };
        }
        let Some(rung) = rung_at else {
            return WakeDecision::SleepUntil(deadline);
        };
        let earliest = last + self.min_interval;
        if now >= earliest {
            WakeDecision::TickNow {
                scheduled: rung.max(earliest),
            }
        } else {
            WakeDecision::SleepUntil(earliest.min(deadline))
        }
    }

    /// Notes that a tick started at `woke`.
    pub fn ticked(&mut self, woke: Instant) {
        self.last_tick = Some(woke);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const PERIOD: Duration = Duration::from_micros(16_667);
    const CAP: Duration = Duration::from_micros(8_333);

    fn after_a_tick(at: Instant) -> WakeSchedule {
        let mut s = WakeSchedule::new(PERIOD, CAP);
        s.ticked(at);
        s
    }

    #[test]
    fn the_first_tick_is_due_at_once() {
        let now = Instant::now();
        let s = WakeSchedule::new(PERIOD, CAP);
        assert_eq!(
            s.decide(now, None),
            WakeDecision::TickNow { scheduled: now }
        );
    }

    #[test]
    fn without_a_ring_the_loop_sleeps_to_its_period() {
        let t0 = Instant::now();
        let s = after_a_tick(t0);
        let now = t0 + Duration::from_millis(3);
        assert_eq!(s.decide(now, None), WakeDecision::SleepUntil(t0 + PERIOD));
        assert_eq!(
            s.decide(t0 + PERIOD, None),
            WakeDecision::TickNow {
                scheduled: t0 + PERIOD
            }
        );
    }

    #[test]
    fn a_ring_after_the_cap_ticks_at_once_well_before_the_period() {
        let t0 = Instant::now();
        let s = after_a_tick(t0);
        let rung = t0 + Duration::from_millis(10);
        assert_eq!(
            s.decide(rung, Some(rung)),
            WakeDecision::TickNow { scheduled: rung }
        );
    }

    #[test]
    fn a_ring_inside_the_cap_waits_for_the_cap_not_the_period() {
        let t0 = Instant::now();
        let s = after_a_tick(t0);
        let rung = t0 + Duration::from_millis(1);
        assert_eq!(
            s.decide(rung, Some(rung)),
            WakeDecision::SleepUntil(t0 + CAP)
        );
        // Woken at the cap: the tick was due then, not at the ring (the cap held it back).
        assert_eq!(
            s.decide(t0 + CAP, Some(rung)),
            WakeDecision::TickNow {
                scheduled: t0 + CAP
            }
        );
    }

    #[test]
    fn a_cap_slower_than_the_period_never_delays_the_periodic_tick() {
        let t0 = Instant::now();
        let mut s = after_a_tick(t0);
        s.min_interval = PERIOD * 3;
        let rung = t0 + Duration::from_millis(1);
        assert_eq!(
            s.decide(rung, Some(rung)),
            WakeDecision::SleepUntil(t0 + PERIOD)
        );
    }

    #[test]
    fn bad_rate_caps_are_refused_with_the_rate() {
        assert_eq!(MAX_WAKE_RATE_HZ, crate::MAX_RATE_HZ);
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY, MAX_WAKE_RATE_HZ * 2.0] {
            match wake_bell(bad) {
                Err(WakeError::InvalidMaxRate { max_rate_hz }) => {
                    assert!(max_rate_hz.to_bits() == bad.to_bits());
                }
                Ok(_) => panic!("accepted a cap of {bad} Hz"),
            }
        }
        let text = WakeError::InvalidMaxRate { max_rate_hz: -3.0 }.to_string();
        assert!(
            text.contains("max_rate_hz") && text.contains("-3"),
            "{text}"
        );
    }

    #[test]
    fn a_ring_is_seen_once_and_taken_by_the_tick() {
        let (bell, waiter) = wake_bell(120.0).expect("valid cap");
        assert_eq!(waiter.min_interval(), Duration::from_secs_f64(1.0 / 120.0));
        assert!(waiter.rung_at().is_none());
        let before = Instant::now();
        bell.ring();
        bell.clone().ring();
        let rung = waiter.rung_at().expect("rung");
        assert!(rung >= before, "the first ring's time");
        waiter.take();
        assert!(waiter.rung_at().is_none(), "the tick served both rings");
    }
}
