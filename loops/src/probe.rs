//! A platform probe: what this machine does to a real-time thread without the engine, so a
//! loop's latency can be blamed on the engine or on the machine.
//!
//! - The wake-up probe ([`run_wakeup_probe`]) is cyclictest-style: a thread at the haptic
//!   thread's priority sleeps to absolute deadlines (`clock_nanosleep` with `TIMER_ABSTIME` on
//!   Linux) and records how late it woke, in a [`LatencyRecorder`] like any loop.
//! - The stall probe ([`run_stall_probe`]) spins reading the clock; a gap between two readings
//!   longer than a threshold is time taken away from it by the host (a stolen vCPU), by
//!   interrupts or by a higher-priority thread. [`StallCounter`] does the counting and is
//!   pure, so it is tested on made-up readings.
//!
//! Not for the real-time path: each probe spawns a thread and runs for its whole duration.

use std::time::{Duration, Instant};

use serde::{Deserialize, Serialize};

use crate::priority::{RtOutcome, request_realtime};
use crate::recorder::{LatencyRecorder, LatencyStats, TickTiming};

/// A gap between two clock readings longer than this counts as a stall.
pub const DEFAULT_GAP_THRESHOLD: Duration = Duration::from_micros(20);

/// What the stall probe saw: how often and for how long its CPU was taken away.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct StallStats {
    /// Seconds the probe spun.
    pub seconds: f64,
    /// Gaps at least this long were counted, µs.
    pub gap_threshold_us: f64,
    /// Gaps counted.
    pub gaps: u64,
    /// Sum of the counted gaps, ms.
    pub stolen_ms: f64,
    /// Longest gap, µs (0 when none was counted).
    pub max_gap_us: f64,
}

impl StallStats {
    /// Counted gaps per second of probing.
    #[must_use]
    pub fn gaps_per_s(&self) -> f64 {
        if self.seconds > 0.0 {
            self.gaps as f64 / self.seconds
        } else {
            0.0
        }
    }

    /// Milliseconds taken away per second of probing.
    #[must_use]
    pub fn stolen_ms_per_s(&self) -> f64 {
        if self.seconds > 0.0 {
            self.stolen_ms / self.seconds
        } else {
            0.0
        }
    }
}

/// Counts gaps in a sequence of clock readings (ns from any fixed origin).
#[derive(Clone, Copy, Debug)]
pub struct StallCounter {
    threshold_ns: u64,
    first_ns: Option<u64>,
    last_ns: Option<u64>,
    gaps: u64,
    stolen_ns: u64,
    max_gap_ns: u64,
}

impl StallCounter {
    /// A counter that counts gaps of at least `threshold`.
    #[must_use]
    pub fn new(threshold: Duration) -> Self {
        Self {
            threshold_ns: u64::try_from(threshold.as_nanos()).unwrap_or(u64::MAX),
            first_ns: None,
            last_ns: None,
            gaps: 0,
            stolen_ns: 0,
            max_gap_ns: 0,
        }
    }

    /// Takes one clock reading; readings must not go backwards (a backwards one counts as no gap).
    pub fn observe(&mut self, now_ns: u64) {
        if let Some(last) = self.last_ns {
            let gap = now_ns.saturating_sub(last);
            if gap >= self.threshold_ns {
                self.gaps += 1;
                self.stolen_ns += gap;
                self.max_gap_ns = self.max_gap_ns.max(gap);
            }
        } else {
            self.first_ns = Some(now_ns);
        }
        self.last_ns = Some(now_ns);
    }

    /// The figures so far.
    #[must_use]
    pub fn stats(&self) -> StallStats {
        let span_ns = match (self.first_ns, self.last_ns) {
            (Some(a), Some(b)) => b.saturating_sub(a),
            _ => 0,
        };
        StallStats {
            seconds: span_ns as f64 / 1e9,
            gap_threshold_us: self.threshold_ns as f64 / 1e3,
            gaps: self.gaps,
            stolen_ms: self.stolen_ns as f64 / 1e6,
            max_gap_us: self.max_gap_ns as f64 / 1e3,
        }
    }
}

/// One run of both probes.
#[derive(Clone, Debug)]
pub struct ProbeRun {
    /// What the OS granted the wake-up probe's real-time request.
    pub wakeup_rt: RtOutcome,
    /// The wake-up probe's ticks: its `lateness` is the wake-up latency.
    pub wakeup: LatencyRecorder,
    /// What the OS granted the stall probe's real-time request.
    pub stall_rt: RtOutcome,
    /// The stall probe's figures.
    pub stalls: StallStats,
}

/// The serialisable figures of one [`ProbeRun`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ProbeSummary {
    /// What the OS granted the wake-up probe's real-time request.
    pub wakeup_rt: RtOutcome,
    /// The wake-up probe's figures; `lateness` is the wake-up latency.
    pub wakeup: LatencyStats,
    /// What the OS granted the stall probe's real-time request.
    pub stall_rt: RtOutcome,
    /// The stall probe's figures.
    pub stalls: StallStats,
}

impl ProbeRun {
    /// The serialisable figures.
    #[must_use]
    pub fn summary(&self) -> ProbeSummary {
        ProbeSummary {
            wakeup_rt: self.wakeup_rt,
            wakeup: self.wakeup.stats(),
            stall_rt: self.stall_rt,
            stalls: self.stalls,
        }
    }
}

/// Runs the wake-up probe then the stall probe, each for `each`, both at `rt_priority`
/// (`None`: normal priority). The wake-up probe wakes at `rate_hz`.
///
/// # Errors
/// The OS error when a probe thread cannot be spawned.
pub fn run_probes(
    rate_hz: f64,
    each: Duration,
    rt_priority: Option<i32>,
) -> std::io::Result<ProbeRun> {
    let period = Duration::from_secs_f64(1.0 / rate_hz.max(1.0));
    let (wakeup_rt, wakeup) = std::thread::Builder::new()
        .name("probe-wakeup".into())
        .spawn(move || run_wakeup_probe(period, each, rt_priority))?
        .join()
        .map_err(|_| std::io::Error::other("the wake-up probe thread panicked"))?;
    let (stall_rt, stalls) = std::thread::Builder::new()
        .name("probe-stall".into())
        .spawn(move || run_stall_probe(each, DEFAULT_GAP_THRESHOLD, rt_priority))?
        .join()
        .map_err(|_| std::io::Error::other("the stall probe thread panicked"))?;
    Ok(ProbeRun {
        wakeup_rt,
        wakeup,
        stall_rt,
        stalls,
    })
}

fn raise(rt_priority: Option<i32>) -> RtOutcome {
    rt_priority.map_or(RtOutcome::NotRequested, request_realtime)
}

/// On the calling thread: asks for `rt_priority`, then sleeps to absolute deadlines `period`
/// apart for `duration`, recording each wake-up. Changes the calling thread's priority: run it
/// on a thread of its own.
#[must_use]
pub fn run_wakeup_probe(
    period: Duration,
    duration: Duration,
    rt_priority: Option<i32>,
) -> (RtOutcome, LatencyRecorder) {
    let rt = raise(rt_priority);
    let mut recorder = LatencyRecorder::new(period);
    let clock = AbsoluteClock::now();
    let ticks = (duration.as_secs_f64() / period.as_secs_f64()).ceil() as u64;
    for i in 1..=ticks {
        let due = period.saturating_mul(u32::try_from(i).unwrap_or(u32::MAX));
        let woke = clock.sleep_until(due);
        recorder.record_tick(&TickTiming {
            scheduled: clock.origin + due,
            woke: clock.origin + woke,
            compute: Duration::ZERO,
            skipped_before: 0,
        });
    }
    (rt, recorder)
}

/// On the calling thread: asks for `rt_priority`, then spins reading the clock for `duration`,
/// counting gaps of at least `threshold`. Changes the calling thread's priority: run it on a
/// thread of its own.
#[must_use]
pub fn run_stall_probe(
    duration: Duration,
    threshold: Duration,
    rt_priority: Option<i32>,
) -> (RtOutcome, StallStats) {
    let rt = raise(rt_priority);
    let mut counter = StallCounter::new(threshold);
    let start = Instant::now();
    loop {
        let elapsed = start.elapsed();
        counter.observe(u64::try_from(elapsed.as_nanos()).unwrap_or(u64::MAX));
        if elapsed >= duration {
            break;
        }
    }
    (rt, counter.stats())
}

/// Sleeps to deadlines given as offsets from one origin, on the monotonic clock.
struct AbsoluteClock {
    origin: Instant,
    #[cfg(target_os = "linux")]
    origin_ns: u64,
}

#[cfg(target_os = "linux")]
fn monotonic_ns() -> u64 {
    // SAFETY: all-zero is a valid `timespec` (plain integers).
    let mut ts: libc::timespec = unsafe { std::mem::zeroed() };
    // SAFETY: `ts` is a valid, exclusively borrowed out-pointer for the call;
    // CLOCK_MONOTONIC always exists on Linux.
    unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts) };
    u64::try_from(ts.tv_sec).unwrap_or(0) * 1_000_000_000 + u64::try_from(ts.tv_nsec).unwrap_or(0)
}

impl AbsoluteClock {
    fn now() -> Self {
        Self {
            origin: Instant::now(),
            #[cfg(target_os = "linux")]
            origin_ns: monotonic_ns(),
        }
    }

    /// Sleeps until `origin + due`; returns when it woke, as an offset from the origin.
    #[cfg(target_os = "linux")]
    fn sleep_until(&self, due: Duration) -> Duration {
        let due_ns = self.origin_ns + u64::try_from(due.as_nanos()).unwrap_or(u64::MAX / 2);
        // SAFETY: all-zero is a valid `timespec` (plain integers).
        let mut ts: libc::timespec = unsafe { std::mem::zeroed() };
        ts.tv_sec = libc::time_t::try_from(due_ns / 1_000_000_000).unwrap_or(libc::time_t::MAX);
        ts.tv_nsec = libc::c_long::try_from(due_ns % 1_000_000_000).unwrap_or(0);
        loop {
            // SAFETY: `ts` is a valid `timespec` that outlives the call; the remaining-time
            // pointer may be null with TIMER_ABSTIME.
            let rc = unsafe {
                libc::clock_nanosleep(
                    libc::CLOCK_MONOTONIC,
                    libc::TIMER_ABSTIME,
                    &ts,
                    std::ptr::null_mut(),
                )
            };
            // NOTE: only EINTR (a signal) wakes it early; sleep again to the same deadline.
            if rc != libc::EINTR {
                break;
            }
        }
        Duration::from_nanos(monotonic_ns().saturating_sub(self.origin_ns))
    }

    /// Sleeps until `origin + due`; returns when it woke, as an offset from the origin.
    #[cfg(not(target_os = "linux"))]
    fn sleep_until(&self, due: Duration) -> Duration {
        let deadline = self.origin + due;
        let now = Instant::now();
        if deadline > now {
            std::thread::sleep(deadline - now);
        }
        self.origin.elapsed()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gaps_at_or_over_the_threshold_count() {
        let mut c = StallCounter::new(Duration::from_micros(20));
        // Readings 1 µs apart, then a 19 µs step (no gap), a 20 µs gap and a 500 µs gap.
        let mut t = 0u64;
        for step in [1_000, 1_000, 19_000, 20_000, 1_000, 500_000, 1_000] {
            c.observe(t);
            t += step;
        }
        c.observe(t);
        let s = c.stats();
        assert_eq!(s.gaps, 2);
        assert!((s.stolen_ms - 0.52).abs() < 1e-12, "{s:?}");
        assert!((s.max_gap_us - 500.0).abs() < 1e-9);
        assert!((s.seconds - 543e-6).abs() < 1e-15);
        assert!((s.stolen_ms_per_s() - 0.52 / 543e-6).abs() < 1e-6);
        assert!((s.gaps_per_s() - 2.0 / 543e-6).abs() < 1e-6);
    }

    #[test]
    fn no_readings_give_zero_rates() {
        let s = StallCounter::new(DEFAULT_GAP_THRESHOLD).stats();
        assert_eq!(s.gaps, 0);
        assert_eq!(s.stolen_ms_per_s(), 0.0);
        assert_eq!(s.gaps_per_s(), 0.0);
        assert!((s.gap_threshold_us - 20.0).abs() < 1e-12);
    }

    #[test]
    fn backwards_readings_are_no_gap() {
        let mut c = StallCounter::new(Duration::from_micros(20));
        c.observe(1_000_000);
        c.observe(10);
        assert_eq!(c.stats().gaps, 0);
    }

    #[test]
    fn wakeup_probe_records_one_tick_per_period() {
        // Counts only: the latency itself depends on the machine and is not asserted.
        let (rt, rec) = run_wakeup_probe(Duration::from_millis(1), Duration::from_millis(20), None);
        assert_eq!(rt, RtOutcome::NotRequested);
        assert_eq!(rec.ticks(), 20);
        assert_eq!(rec.stats().skipped_ticks, 0);
    }

    #[test]
    fn summary_round_trips_through_json() {
        let run = ProbeRun {
            wakeup_rt: RtOutcome::Granted { priority: 80 },
            wakeup: LatencyRecorder::new(Duration::from_millis(1)),
            stall_rt: RtOutcome::NotRequested,
            stalls: StallStats {
                seconds: 1.0,
                gap_threshold_us: 20.0,
                gaps: 3,
                stolen_ms: 0.25,
                max_gap_us: 120.0,
            },
        };
        let json = serde_json::to_string(&run.summary()).expect("json");
        let back: ProbeSummary = serde_json::from_str(&json).expect("parse");
        assert_eq!(back, run.summary());
    }
}
