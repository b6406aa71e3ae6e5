//! Per-loop latency recorder: HDR histograms of period, period error, wake-up lateness and
//! compute time, deadline-miss and late-tick counters, and a [`Timeline`] of the run.
//!
//! Guarantee: after [`LatencyRecorder::new`] (which allocates every histogram at its full size),
//! [`record_tick`](LatencyRecorder::record_tick), [`stats`](LatencyRecorder::stats) and
//! [`reset`](LatencyRecorder::reset) never allocate and never block: auto-resize is off and values
//! beyond [`MAX_RECORDABLE`] saturate at it (the exact maximum is still kept). `record_tick` is
//! O(1); `stats` scans each histogram once (a few tens of thousands of counters, bounded, tens of
//! microseconds), so a loop should call it every N ticks, not every tick. Single-threaded: the loop
//! thread owns the recorder; other threads see it through published [`LatencyStats`] or after
//! the loop returns it.

use std::time::{Duration, Instant};

use hdrhistogram::Histogram;
use serde::{Deserialize, Serialize};

use crate::live::LogBins;
use crate::timeline::Timeline;

/// Largest value a histogram holds before saturating (10 s, in ns).
pub const MAX_RECORDABLE: Duration = Duration::from_secs(10);

/// Significant decimal digits kept by every histogram (0.1 % relative resolution).
const SIGFIG: u8 = 3;

/// A tick whose start was later than this after its scheduled time counts in `late_over_1ms`.
pub const LATE_1MS: Duration = Duration::from_millis(1);
/// A tick whose start was later than this after its scheduled time counts in `late_over_2ms`.
pub const LATE_2MS: Duration = Duration::from_millis(2);

/// Timing of one tick, as measured by the loop runner.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TickTiming {
    /// When the tick was due.
    pub scheduled: Instant,
    /// When the loop thread actually started the tick.
    pub woke: Instant,
    /// Time spent in the tick body.
    pub compute: Duration,
    /// Ticks dropped (by the skip overrun policy) just before this one.
    pub skipped_before: u64,
}

/// Distribution summary of one measured quantity, in microseconds.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Percentiles {
    /// Median.
    pub p50_us: f64,
    /// 99th percentile.
    pub p99_us: f64,
    /// 99.9th percentile.
    pub p999_us: f64,
    /// Largest value seen (exact, even beyond the histogram's range).
    pub max_us: f64,
    /// Arithmetic mean.
    pub mean_us: f64,
}

/// A snapshot of a recorder's figures: plain `Copy` data, cheap to publish through a triple
/// buffer and serialisable.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct LatencyStats {
    /// Ticks recorded.
    pub ticks: u64,
    /// Ticks whose work ended after the next tick was due (lateness + compute > period).
    pub deadline_misses: u64,
    /// Ticks dropped by the skip overrun policy.
    pub skipped_ticks: u64,
    /// Ticks that started more than 1 ms after their scheduled time.
    pub late_over_1ms: u64,
    /// Ticks that started more than 2 ms after their scheduled time.
    pub late_over_2ms: u64,
    /// The rate the loop was asked to run at.
    pub nominal_rate_hz: f64,
    /// Ticks per second actually achieved between the first and the last recorded tick.
    pub achieved_rate_hz: f64,
    /// Seconds between the first and the last recorded tick.
    pub elapsed_s: f64,
    /// Time between consecutive tick starts.
    pub period: Percentiles,
    /// |actual period − nominal period|.
    pub period_error: Percentiles,
    /// Tick start − scheduled time (how late the thread woke).
    pub lateness: Percentiles,
    /// Time spent in the tick body.
    pub compute: Percentiles,
    /// Period error in coarse bins, for live displays. Not in the JSON: reports draw the
    /// recorder's exact histograms.
    #[serde(skip)]
    pub period_error_bins: LogBins,
    /// Compute time in coarse bins, for live displays. Not in the JSON.
    #[serde(skip)]
    pub compute_bins: LogBins,
}

/// Histograms and counters of one loop. See the module docs for the allocation guarantee.
#[derive(Clone, Debug)]
pub struct LatencyRecorder {
    nominal_period: Duration,
    period: Tracked,
    period_error: Tracked,
    lateness: Tracked,
    compute: Tracked,
    ticks: u64,
    deadline_misses: u64,
    skipped_ticks: u64,
    late_over_1ms: u64,
    late_over_2ms: u64,
    first_woke: Option<Instant>,
    last_woke: Option<Instant>,
    timeline: Timeline,
    period_error_bins: LogBins,
    compute_bins: LogBins,
}

/// A histogram plus the exact maximum (the histogram saturates, the maximum does not).
#[derive(Clone, Debug)]
struct Tracked {
    hist: Histogram<u64>,
    max_ns: u64,
}

impl Tracked {
    fn new() -> Self {
        // NOTE: `new_with_bounds` leaves auto-resize off, so recording never reallocates.
        let hist = Histogram::new_with_bounds(1, nanos(MAX_RECORDABLE), SIGFIG)
            .unwrap_or_else(|e| unreachable!("constant histogram bounds are valid: {e}"));
        Self { hist, max_ns: 0 }
    }

    fn record(&mut self, ns: u64) {
        self.hist.saturating_record(ns);
        self.max_ns = self.max_ns.max(ns);
    }

    fn reset(&mut self) {
        self.hist.reset();
        self.max_ns = 0;
    }

    fn percentiles(&self) -> Percentiles {
        if self.hist.is_empty() {
            return Percentiles::default();
        }
        let mut q = [0u64; 3];
        for (slot, v) in q
            .iter_mut()
            .zip(self.hist.value_at_quantiles([0.5, 0.99, 0.999]))
        {
            *slot = v;
        }
        Percentiles {
            p50_us: us(q[0]),
            p99_us: us(q[1]),
            p999_us: us(q[2]),
            max_us: us(self.max_ns),
            mean_us: self.hist.mean() / 1e3,
        }
    }
}

fn nanos(d: Duration) -> u64 {
    u64::try_from(d.as_nanos()).unwrap_or(u64::MAX)
}

fn us(ns: u64) -> f64 {
    ns as f64 / 1e3
}

impl LatencyRecorder {
    /// A recorder for a loop of nominal period `nominal_period`; allocates all histograms now
    /// (about 200 KiB each, four of them) and the timeline (32 KiB).
    #[must_use]
    pub fn new(nominal_period: Duration) -> Self {
        Self {
            nominal_period,
            period: Tracked::new(),
            period_error: Tracked::new(),
            lateness: Tracked::new(),
            compute: Tracked::new(),
            ticks: 0,
            deadline_misses: 0,
            skipped_ticks: 0,
            late_over_1ms: 0,
            late_over_2ms: 0,
            first_woke: None,
            last_woke: None,
            timeline: Timeline::new(),
            period_error_bins: LogBins::default(),
            compute_bins: LogBins::default(),
        }
    }

    /// Records one tick. O(1), no allocation. The first tick has no period, so the period
    /// histograms start at the second.
    pub fn record_tick(&mut self, t: &TickTiming) {
        let lateness = t.woke.saturating_duration_since(t.scheduled);
        let mut period_error = Duration::ZERO;
        if let Some(prev) = self.last_woke {
            let period = t.woke.saturating_duration_since(prev);
            period_error = period.abs_diff(self.nominal_period);
            self.period.record(nanos(period));
            self.period_error.record(nanos(period_error));
            self.period_error_bins.record(nanos(period_error));
        } else {
            self.first_woke = Some(t.woke);
        }
        self.last_woke = Some(t.woke);
        self.lateness.record(nanos(lateness));
        self.compute.record(nanos(t.compute));
        self.compute_bins.record(nanos(t.compute));
        self.ticks += 1;
        self.skipped_ticks += t.skipped_before;
        let missed = lateness + t.compute > self.nominal_period;
        if missed {
            self.deadline_misses += 1;
        }
        if lateness > LATE_1MS {
            self.late_over_1ms += 1;
        }
        if lateness > LATE_2MS {
            self.late_over_2ms += 1;
        }
        let since_start = self.first_woke.map_or(Duration::ZERO, |first| {
            t.woke.saturating_duration_since(first)
        });
        self.timeline
            .record(since_start, period_error, t.compute, missed);
    }

    /// Forgets everything recorded (for example after a warm-up). No allocation.
    pub fn reset(&mut self) {
        for t in [
            &mut self.period,
            &mut self.period_error,
            &mut self.lateness,
            &mut self.compute,
        ] {
            t.reset();
        }
        self.ticks = 0;
        self.deadline_misses = 0;
        self.skipped_ticks = 0;
        self.late_over_1ms = 0;
        self.late_over_2ms = 0;
        self.first_woke = None;
        self.last_woke = None;
        self.timeline.reset();
        self.period_error_bins.reset();
        self.compute_bins.reset();
    }

    /// Current figures. No allocation; scans each histogram once (call it every N ticks).
    #[must_use]
    pub fn stats(&self) -> LatencyStats {
        let elapsed_s = match (self.first_woke, self.last_woke) {
            (Some(a), Some(b)) => b.saturating_duration_since(a).as_secs_f64(),
            _ => 0.0,
        };
        let achieved_rate_hz = if elapsed_s > 0.0 {
            (self.ticks.saturating_sub(1)) as f64 / elapsed_s
        } else {
            0.0
        };
        LatencyStats {
            ticks: self.ticks,
            deadline_misses: self.deadline_misses,
            skipped_ticks: self.skipped_ticks,
            late_over_1ms: self.late_over_1ms,
            late_over_2ms: self.late_over_2ms,
            nominal_rate_hz: 1.0 / self.nominal_period.as_secs_f64(),
            achieved_rate_hz,
            elapsed_s,
            period: self.period.percentiles(),
            period_error: self.period_error.percentiles(),
            lateness: self.lateness.percentiles(),
            compute: self.compute.percentiles(),
            period_error_bins: self.period_error_bins,
            compute_bins: self.compute_bins,
        }
    }

    /// Ticks recorded so far.
    #[must_use]
    pub fn ticks(&self) -> u64 {
        self.ticks
    }

    /// The nominal period this recorder measures against.
    #[must_use]
    pub fn nominal_period(&self) -> Duration {
        self.nominal_period
    }

    /// Histogram of |actual − nominal period|, in ns.
    #[must_use]
    pub fn period_error_histogram(&self) -> &Histogram<u64> {
        &self.period_error.hist
    }

    /// Histogram of the tick body's compute time, in ns.
    #[must_use]
    pub fn compute_histogram(&self) -> &Histogram<u64> {
        &self.compute.hist
    }

    /// Histogram of the time between consecutive tick starts, in ns.
    #[must_use]
    pub fn period_histogram(&self) -> &Histogram<u64> {
        &self.period.hist
    }

    /// The run over time: per window the worst period error and compute time, and the misses.
    #[must_use]
    pub fn timeline(&self) -> &Timeline {
        &self.timeline
    }

    /// Histogram of wake-up lateness (tick start − scheduled time), in ns.
    #[must_use]
    pub fn lateness_histogram(&self) -> &Histogram<u64> {
        &self.lateness.hist
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: Duration = Duration::from_millis(1);

    fn tick(scheduled: Instant, late_us: u64, compute_us: u64) -> TickTiming {
        TickTiming {
            scheduled,
            woke: scheduled + Duration::from_micros(late_us),
            compute: Duration::from_micros(compute_us),
            skipped_before: 0,
        }
    }

    #[test]
    fn perfect_ticks_have_zero_error() {
        let t0 = Instant::now();
        let mut rec = LatencyRecorder::new(MS);
        for i in 0..1000u32 {
            rec.record_tick(&tick(t0 + MS * i, 0, 5));
        }
        let s = rec.stats();
        assert_eq!(s.ticks, 1000);
        assert_eq!(s.period_error.max_us, 0.0);
        // Percentiles report the top of their bucket: within the 0.1 % resolution, never below.
        assert!(
            s.period.p50_us >= 1000.0 && s.period.p50_us <= 1001.0,
            "{}",
            s.period.p50_us
        );
        assert!((s.compute.p99_us - 5.0).abs() < 0.01);
        assert_eq!(s.deadline_misses, 0);
        assert!((s.achieved_rate_hz - 1000.0).abs() < 1e-6);
        assert!((s.elapsed_s - 0.999).abs() < 1e-9);
        assert!((s.nominal_rate_hz - 1000.0).abs() < 1e-9);
    }

    #[test]
    fn one_late_tick_shows_in_tail_and_counters() {
        let t0 = Instant::now();
        let mut rec = LatencyRecorder::new(MS);
        for i in 0..2000u32 {
            match i {
                1000 => rec.record_tick(&tick(t0 + MS * i, 1500, 10)),
                // Tick 1001 was due while 1000 was still late: the skip policy dropped it.
                1001 => {}
                1002 => rec.record_tick(&TickTiming {
                    skipped_before: 1,
                    ..tick(t0 + MS * i, 0, 10)
                }),
                _ => rec.record_tick(&tick(t0 + MS * i, 0, 10)),
            }
        }
        let s = rec.stats();
        assert_eq!(s.ticks, 1999);
        assert_eq!(s.skipped_ticks, 1);
        // Periods around the late tick: 2.5 ms (error 1.5 ms) then 0.5 ms (error 0.5 ms).
        assert!((s.period_error.max_us - 1500.0).abs() < 1e-9);
        assert_eq!(s.period_error.p99_us, 0.0);
        assert_eq!(s.late_over_1ms, 1);
        assert_eq!(s.late_over_2ms, 0);
        assert_eq!(s.deadline_misses, 1);
        assert!((s.lateness.max_us - 1500.0).abs() < 1e-9);
    }

    #[test]
    fn compute_over_the_period_is_a_deadline_miss() {
        let t0 = Instant::now();
        let mut rec = LatencyRecorder::new(MS);
        rec.record_tick(&tick(t0, 0, 999));
        rec.record_tick(&tick(t0 + MS, 0, 1001));
        rec.record_tick(&tick(t0 + MS * 2, 2, 999));
        assert_eq!(rec.stats().deadline_misses, 2);
    }

    #[test]
    fn skipped_ticks_accumulate() {
        let t0 = Instant::now();
        let mut rec = LatencyRecorder::new(MS);
        rec.record_tick(&tick(t0, 0, 1));
        rec.record_tick(&TickTiming {
            skipped_before: 3,
            ..tick(t0 + MS * 4, 0, 1)
        });
        assert_eq!(rec.stats().skipped_ticks, 3);
    }

    #[test]
    fn huge_values_saturate_but_max_is_exact() {
        let t0 = Instant::now();
        let mut rec = LatencyRecorder::new(MS);
        rec.record_tick(&tick(t0, 0, 1));
        rec.record_tick(&tick(t0 + Duration::from_secs(30), 0, 1));
        let s = rec.stats();
        assert!((s.period.max_us - 30e6).abs() < 1.0);
        // The histogram itself holds at most MAX_RECORDABLE (within its resolution).
        let held = rec.period_histogram().max() as f64;
        assert!(held <= nanos(MAX_RECORDABLE) as f64 * 1.001);
    }

    #[test]
    fn reset_clears_everything() {
        let t0 = Instant::now();
        let mut rec = LatencyRecorder::new(MS);
        rec.record_tick(&tick(t0, 3000, 1));
        rec.reset();
        assert_eq!(
            rec.stats(),
            LatencyStats {
                nominal_rate_hz: 1000.0,
                ..LatencyStats::default()
            }
        );
    }

    #[test]
    fn empty_recorder_reports_zeros() {
        let s = LatencyRecorder::new(MS).stats();
        assert_eq!(s.ticks, 0);
        assert_eq!(s.period_error, Percentiles::default());
    }
}
