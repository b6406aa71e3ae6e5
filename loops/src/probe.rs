//! A platform probe: what this machine does to a real-time thread without the engine, so a
//! loop's latency can be blamed on the engine or on the machine.
//!
//! - The wake-up probe ([`run_wakeup_probe`]) is cyclictest-style: a thread at the haptic
//!   thread's priority sleeps to absolute deadlines (`clock_nanosleep` with `TIMER_ABSTIME` on
//!   Linux) and records how late it woke, in a [`LatencyRecorder`] like any loop.
//! - The stall probe ([`run_stall_probe`]) spins reading the clock; a gap between two readings
//!   longer than a threshold is time taken away from it by the host (a stolen vCPU), by
//!   interrupts or by a higher-priority thread. [`StallCounter`] does the counting and is
//!   pure, so it is tested on made-up readings. Besides the sum and the longest gap it keeps
//!   how many gaps reached each of the fixed lengths [`GAP_FLOORS_NS`] ([`GapCounts`], a fixed
//!   array: counting a gap allocates nothing), because what endangers a deadline is a gap as
//!   long as a good part of the period, not many short ones adding up.
//!
//! Not for the real-time path: each probe spawns a thread and runs for its whole duration.

use std::time::{Duration, Instant};

use serde::{Deserialize, Serialize};

use crate::priority::{RtOutcome, request_realtime};
use crate::recorder::{LatencyRecorder, LatencyStats, TickTiming};

/// A gap between two clock readings longer than this counts as a stall.
pub const DEFAULT_GAP_THRESHOLD: Duration = Duration::from_micros(20);

/// The lengths the stall probe sorts gaps by, ns: 31.25 µs × {1, 1.5} × 2^k, k = 0..=9
/// (31.25 µs to 24 ms). Every power-of-two fraction of the 1 kHz and 4 kHz periods from 1/8
/// to 16 periods is one of them (1000 µs = 31.25 µs × 2^5, 250 µs = 31.25 µs × 2^3), so the
/// verdict asks for those exactly; for another length it takes the floor just below, which
/// counts a few shorter gaps too (at most 1.5 times shorter) and so errs towards caution.
pub const GAP_FLOORS_NS: [u64; 20] = {
    let mut floors = [0u64; 20];
    let mut k = 0;
    while k < 10 {
        floors[2 * k] = 31_250 << k;
        floors[2 * k + 1] = 46_875 << k;
        k += 1;
    }
    floors
};

/// How many counted gaps fell between consecutive [`GAP_FLOORS_NS`]: `counts[i]` gaps were at
/// least `GAP_FLOORS_NS[i]` and shorter than the next floor (the last bin is open-ended).
/// Counted gaps shorter than the first floor are in none of them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct GapCounts {
    /// Gaps per bin.
    pub counts: [u64; GAP_FLOORS_NS.len()],
}

impl GapCounts {
    /// Counts one gap of `gap_ns`.
    pub fn add(&mut self, gap_ns: u64) {
        // NOTE: the floors are sorted, so the bin is the number of floors not above the gap.
        let bins_reached = GAP_FLOORS_NS.partition_point(|&floor| floor <= gap_ns);
        if let Some(bin) = bins_reached.checked_sub(1) {
            self.counts[bin] += 1;
        }
    }

    /// Gaps at least `floor_us` long, counted from the largest floor of [`GAP_FLOORS_NS`] not
    /// above `floor_us` (so possibly a few shorter ones too: cautious). Below the first floor
    /// it counts from the first floor.
    #[must_use]
    pub fn at_least(&self, floor_us: f64) -> u64 {
        let floor_ns = (floor_us.max(0.0) * 1e3).round() as u64;
        let first = GAP_FLOORS_NS
            .partition_point(|&floor| floor <= floor_ns)
            .saturating_sub(1);
        self.counts[first..].iter().sum()
    }

    /// Both runs' gaps together.
    #[must_use]
    pub fn merged(&self, other: &Self) -> Self {
        let mut counts = self.counts;
        for (c, o) in counts.iter_mut().zip(other.counts) {
            *c += o;
        }
        Self { counts }
    }
}

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
    /// The counted gaps by length; `None` in records made before the probe sorted them.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gap_counts: Option<GapCounts>,
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

    /// Gaps at least `floor_us` long per second of probing (see [`GapCounts::at_least`]);
    /// `None` when the record has no [`GapCounts`] or no probing time.
    #[must_use]
    pub fn gaps_at_least_per_s(&self, floor_us: f64) -> Option<f64> {
        let counts = self.gap_counts?;
        (self.seconds > 0.0).then(|| counts.at_least(floor_us) as f64 / self.seconds)
    }

    /// Two probe runs taken as one: times, counts and bins added, the longer longest gap.
    /// The gap threshold is the larger of the two (the runs normally share it).
    #[must_use]
    pub fn merged(&self, other: &Self) -> Self {
        Self {
            seconds: self.seconds + other.seconds,
            gap_threshold_us: self.gap_threshold_us.max(other.gap_threshold_us),
            gaps: self.gaps + other.gaps,
            stolen_ms: self.stolen_ms + other.stolen_ms,
            max_gap_us: self.max_gap_us.max(other.max_gap_us),
            gap_counts: match (self.gap_counts, other.gap_counts) {
                (Some(a), Some(b)) => Some(a.merged(&b)),
                // One run without bins: the bins would undercount the runs' time.
                _ => None,
            },
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
    by_length: GapCounts,
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
            by_length: GapCounts::default(),
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
                self.by_length.add(gap);
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
            gap_counts: Some(self.by_length),
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
    fn gaps_are_sorted_by_length_at_the_floors() {
        let mut c = StallCounter::new(Duration::from_micros(20));
        let mut t = 0u64;
        c.observe(t);
        // 25 µs (counted, below the first floor), 31.25 µs (first floor exactly), 134 µs,
        // 250 µs, 999 µs, 1000 µs, 2 ms and 30 ms (past the last floor).
        for gap in [
            25_000, 31_250, 134_000, 250_000, 999_000, 1_000_000, 2_000_000, 30_000_000,
        ] {
            t += gap;
            c.observe(t);
        }
        let s = c.stats();
        assert_eq!(s.gaps, 8);
        let counts = s.gap_counts.expect("bins");
        assert_eq!(counts.counts.iter().sum::<u64>(), 7, "{counts:?}");
        assert_eq!(counts.at_least(0.0), 7);
        assert_eq!(counts.at_least(125.0), 6);
        assert_eq!(counts.at_least(250.0), 5);
        assert_eq!(counts.at_least(500.0), 4);
        assert_eq!(counts.at_least(1000.0), 3);
        assert_eq!(counts.at_least(2000.0), 2);
        assert_eq!(counts.at_least(24_000.0), 1);
        // 1.2 ms is no floor: counted from 1 ms, so the 1000 µs gap counts too (cautious).
        assert_eq!(counts.at_least(1200.0), 3);
        let per_s = s.gaps_at_least_per_s(1000.0).expect("rate");
        assert!((per_s - 3.0 / s.seconds).abs() < 1e-9);
    }

    #[test]
    fn the_floors_hold_the_fractions_of_1_and_4_khz_periods() {
        for period_us in [1000u64, 250] {
            for (num, den) in [(1, 8), (1, 4), (1, 2), (1, 1), (2, 1), (4, 1), (8, 1)] {
                let ns = period_us * 1000 * num / den;
                if ns >= GAP_FLOORS_NS[0] {
                    assert!(GAP_FLOORS_NS.contains(&ns), "{ns} ns");
                }
            }
        }
        assert!(GAP_FLOORS_NS.windows(2).all(|w| w[0] < w[1]));
    }

    #[test]
    fn merged_runs_add_up() {
        let mut a = StallCounter::new(Duration::from_micros(20));
        let mut b = a;
        for (c, gap) in [(&mut a, 40_000u64), (&mut b, 600_000)] {
            c.observe(0);
            c.observe(gap);
            c.observe(gap + 10_000);
        }
        let m = a.stats().merged(&b.stats());
        assert_eq!(m.gaps, 2);
        assert!((m.max_gap_us - 600.0).abs() < 1e-9);
        assert!((m.seconds - (a.stats().seconds + b.stats().seconds)).abs() < 1e-12);
        assert_eq!(m.gap_counts.expect("bins").at_least(500.0), 1);
        let old = StallStats {
            gap_counts: None,
            ..b.stats()
        };
        assert_eq!(a.stats().merged(&old).gap_counts, None);
    }

    #[test]
    fn stall_figures_without_bins_still_load() {
        let old =
            r#"{"seconds":0.2,"gap_threshold_us":20.0,"gaps":3,"stolen_ms":0.1,"max_gap_us":50.0}"#;
        let s: StallStats = serde_json::from_str(old).expect("parse");
        assert_eq!(s.gap_counts, None);
        assert_eq!(s.gaps_at_least_per_s(100.0), None);
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
                gap_counts: Some(GapCounts::default()),
            },
        };
        let json = serde_json::to_string(&run.summary()).expect("json");
        let back: ProbeSummary = serde_json::from_str(&json).expect("parse");
        assert_eq!(back, run.summary());
    }
}
