//! The device doctor: a short zero-force read loop on one device that reports the rate it
//! achieved and the jitter of its period (percentiles of the time between reads and between
//! fresh samples), with every read or force error it met.
//!
//! The loop ticks at the device's own sample rate (1 kHz when it reports none), as the haptic
//! loop does: each tick waits for its deadline, reads once and commands zero force once,
//! through the [`SafetyFilter`], so nothing but zero ever reaches the motors. Time comes from a
//! [`TickClock`]: [`WallClock`] for a real run; a test passes a clock of its own, so the loop
//! and the statistics are checked without depending on the machine's speed. The statistics are
//! pure ([`PeriodStats::from_timestamps_us`]). Allocates its timestamp buffers once, before
//! the loop. Not for the haptic path: it is the haptic path, run alone for a diagnosis.

use std::fmt;
use std::time::{Duration, Instant};

use glam::Vec3;

use crate::device::{DeviceError, HapticDevice};
use crate::safety::SafetyFilter;

/// The rate the loop ticks at when the device reports none, hertz.
pub const DEFAULT_RATE_HZ: f64 = 1000.0;
/// Most ticks one run records (a bound on its buffers: 60 s at 10 kHz).
pub const MAX_TICKS: usize = 600_000;

/// Where the doctor's loop gets its time.
pub trait TickClock {
    /// Microseconds since an arbitrary start; never decreases.
    fn now_us(&mut self) -> u64;
    /// Returns at `t_us` or later (at once when `t_us` has passed).
    fn wait_until_us(&mut self, t_us: u64);
}

/// The machine's monotonic clock: sleeps until shortly before a deadline, then spins, so
/// the tick starts within microseconds of it without burning a core between ticks.
#[derive(Debug)]
pub struct WallClock {
    start: Instant,
}

impl WallClock {
    /// A clock starting now.
    #[must_use]
    pub fn new() -> Self {
        Self {
            start: Instant::now(),
        }
    }
}

impl Default for WallClock {
    fn default() -> Self {
        Self::new()
    }
}

/// How long before a deadline [`WallClock`] stops sleeping and spins (a sleep overshoots by
/// tens of microseconds on a desktop kernel).
const SPIN_BEFORE_US: u64 = 200;

impl TickClock for WallClock {
    fn now_us(&mut self) -> u64 {
        self.start.elapsed().as_micros() as u64
    }

    fn wait_until_us(&mut self, t_us: u64) {
        let now = self.now_us();
        if t_us > now + SPIN_BEFORE_US {
            std::thread::sleep(Duration::from_micros(t_us - now - SPIN_BEFORE_US));
        }
        while self.now_us() < t_us {
            std::hint::spin_loop();
        }
    }
}

/// Statistics of the periods between successive timestamps.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PeriodStats {
    /// Timestamps the periods were taken from.
    pub samples: usize,
    /// From the first timestamp to the last, seconds.
    pub span_s: f64,
    /// Periods per second over the span, hertz.
    pub rate_hz: f64,
    /// Mean period, microseconds.
    pub mean_us: f64,
    /// Shortest period, microseconds.
    pub min_us: u64,
    /// Median period (nearest rank), microseconds.
    pub p50_us: u64,
    /// 90th percentile, microseconds.
    pub p90_us: u64,
    /// 99th percentile, microseconds.
    pub p99_us: u64,
    /// 99.9th percentile, microseconds.
    pub p999_us: u64,
    /// Longest period, microseconds.
    pub max_us: u64,
}

impl PeriodStats {
    /// The statistics of the periods between `timestamps_us` (non-decreasing), or `None` with
    /// fewer than two timestamps. Percentiles are nearest-rank: the smallest period at or
    /// below which that share of the periods lie.
    #[must_use]
    pub fn from_timestamps_us(timestamps_us: &[u64]) -> Option<Self> {
        let (&first, &last) = (timestamps_us.first()?, timestamps_us.last()?);
        if timestamps_us.len() < 2 {
            return None;
        }
        let mut periods: Vec<u64> = timestamps_us
            .windows(2)
            .map(|w| w[1].saturating_sub(w[0]))
            .collect();
        periods.sort_unstable();
        let n = periods.len();
        let rank = |p: f64| periods[((p * n as f64).ceil() as usize).clamp(1, n) - 1];
        let span_us = last.saturating_sub(first);
        Some(Self {
            samples: timestamps_us.len(),
            span_s: span_us as f64 / 1e6,
            rate_hz: if span_us == 0 {
                f64::INFINITY
            } else {
                n as f64 * 1e6 / span_us as f64
            },
            mean_us: span_us as f64 / n as f64,
            min_us: periods[0],
            p50_us: rank(0.50),
            p90_us: rank(0.90),
            p99_us: rank(0.99),
            p999_us: rank(0.999),
            max_us: periods[n - 1],
        })
    }
}

impl fmt::Display for PeriodStats {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{:.1} Hz over {:.3} s ({} samples); period µs: min {} p50 {} p90 {} p99 {} p99.9 {} max {} (mean {:.1}); jitter p99−p50 {} µs",
            self.rate_hz,
            self.span_s,
            self.samples,
            self.min_us,
            self.p50_us,
            self.p90_us,
            self.p99_us,
            self.p999_us,
            self.max_us,
            self.mean_us,
            self.p99_us.saturating_sub(self.p50_us)
        )
    }
}

/// What the doctor runs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DoctorConfig {
    /// How long the loop runs, microseconds.
    pub duration_us: u64,
    /// Tick rate, hertz; `None`: the device's sample rate, or [`DEFAULT_RATE_HZ`].
    pub rate_hz: Option<f64>,
}

impl Default for DoctorConfig {
    /// Two seconds at the device's rate.
    fn default() -> Self {
        Self {
            duration_us: 2_000_000,
            rate_hz: None,
        }
    }
}

/// The doctor's findings.
#[derive(Clone, Debug, PartialEq)]
pub struct DoctorReport {
    /// The device's name.
    pub device: String,
    /// The rate the loop aimed at, hertz.
    pub target_rate_hz: f64,
    /// Ticks run (one read and one zero-force command each).
    pub ticks: usize,
    /// Tick slots skipped because the tick before ran past them.
    pub missed_slots: usize,
    /// Reads that returned a state.
    pub reads_ok: usize,
    /// Reads whose sample was new (its sequence number moved on).
    pub fresh_samples: usize,
    /// Reads that failed.
    pub read_errors: usize,
    /// The first read error.
    pub first_read_error: Option<DeviceError>,
    /// Zero-force commands that failed.
    pub force_errors: usize,
    /// The first force error.
    pub first_force_error: Option<DeviceError>,
    /// Periods between successful reads (the loop's achieved rate).
    pub read_periods: Option<PeriodStats>,
    /// Periods between fresh samples (the device's achieved rate).
    pub fresh_periods: Option<PeriodStats>,
}

impl fmt::Display for DoctorReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "{}: {} ticks aiming at {:.0} Hz ({} slots missed), zero force every tick",
            self.device, self.ticks, self.target_rate_hz, self.missed_slots
        )?;
        writeln!(
            f,
            "  reads: {} ok ({} fresh samples), {} failed",
            self.reads_ok, self.fresh_samples, self.read_errors
        )?;
        match &self.read_periods {
            Some(s) => writeln!(f, "  read rate: {s}")?,
            None => writeln!(f, "  read rate: fewer than two successful reads")?,
        }
        match &self.fresh_periods {
            Some(s) => writeln!(f, "  fresh-sample rate: {s}")?,
            None => writeln!(f, "  fresh-sample rate: fewer than two fresh samples")?,
        }
        if let Some(e) = &self.first_read_error {
            writeln!(f, "  first read error: {e}")?;
        }
        if self.force_errors > 0 {
            writeln!(f, "  zero-force commands failed: {}", self.force_errors)?;
        }
        if let Some(e) = &self.first_force_error {
            writeln!(f, "  first force error: {e}")?;
        }
        Ok(())
    }
}

/// Opens `device` behind the safety filter, runs the zero-force loop for
/// `config.duration_us` on `clock`, closes it and reports; the device comes back either way,
/// so its driver's own findings (a link's counters, the FTDI latency timer) can be read.
///
/// # Errors
/// The device's error when it cannot be opened (the loop does not run).
pub fn run<D: HapticDevice>(
    device: D,
    config: DoctorConfig,
    clock: &mut dyn TickClock,
) -> (Result<DoctorReport, DeviceError>, D) {
    let info = device.info();
    let target_rate_hz = config
        .rate_hz
        .filter(|r| r.is_finite() && *r > 0.0)
        .or_else(|| (info.sample_rate_hz > 0.0).then_some(f64::from(info.sample_rate_hz)))
        .unwrap_or(DEFAULT_RATE_HZ);
    let period_us = (1e6 / target_rate_hz).max(1.0);
    let expected = (config.duration_us as f64 / period_us).ceil() as usize;
    let capacity = expected.min(MAX_TICKS);

    let mut filter = SafetyFilter::new(device);
    if let Err(e) = filter.open() {
        return (Err(e), filter.into_inner());
    }
    let mut read_times = Vec::with_capacity(capacity);
    let mut fresh_times = Vec::with_capacity(capacity);
    let mut report = DoctorReport {
        device: info.name,
        target_rate_hz,
        ticks: 0,
        missed_slots: 0,
        reads_ok: 0,
        fresh_samples: 0,
        read_errors: 0,
        first_read_error: None,
        force_errors: 0,
        first_force_error: None,
        read_periods: None,
        fresh_periods: None,
    };
    let mut last_sequence = None;
    let start_us = clock.now_us();
    let end_us = start_us + config.duration_us;
    let deadline_of = |slot: u64| start_us + (slot as f64 * period_us).round() as u64;
    let mut slot = 0u64;
    while report.ticks < capacity && deadline_of(slot) < end_us {
        clock.wait_until_us(deadline_of(slot));
        let t_us = clock.now_us();
        match filter.read() {
            Ok(state) => {
                report.reads_ok += 1;
                read_times.push(t_us);
                if last_sequence != Some(state.sequence) {
                    last_sequence = Some(state.sequence);
                    report.fresh_samples += 1;
                    fresh_times.push(t_us);
                }
            }
            Err(e) => {
                report.read_errors += 1;
                report.first_read_error.get_or_insert(e);
            }
        }
        if let Err(e) = filter.write_force(Vec3::ZERO) {
            report.force_errors += 1;
            report.first_force_error.get_or_insert(e);
        }
        report.ticks += 1;
        // A tick that overran its slot skips the slots it missed rather than bursting to
        // catch up, as a fixed-rate loop does, so a slow device shows as a lower rate.
        slot += 1;
        let now_us = clock.now_us();
        if now_us > deadline_of(slot) {
            let behind = ((now_us - start_us) as f64 / period_us).ceil() as u64;
            report.missed_slots += behind.saturating_sub(slot) as usize;
            slot = slot.max(behind);
        }
    }
    let _ = filter.close();
    report.read_periods = PeriodStats::from_timestamps_us(&read_times);
    report.fresh_periods = PeriodStats::from_timestamps_us(&fresh_times);
    (Ok(report), filter.into_inner())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_steady_period_has_equal_percentiles_and_the_rate_it_implies() {
        let ts: Vec<u64> = (0..=1000).map(|k| 5 + k * 1000).collect();
        let s = PeriodStats::from_timestamps_us(&ts).unwrap();
        assert_eq!(s.samples, 1001);
        assert!((s.rate_hz - 1000.0).abs() < 1e-9, "{s}");
        assert!((s.span_s - 1.0).abs() < 1e-12);
        assert_eq!(
            (s.min_us, s.p50_us, s.p90_us, s.p99_us, s.p999_us, s.max_us),
            (1000, 1000, 1000, 1000, 1000, 1000)
        );
    }

    #[test]
    fn percentiles_are_nearest_rank_over_the_periods() {
        // 1000 periods: 1..=1000 µs in a scrambled order.
        let mut periods: Vec<u64> = (1..=1000).collect();
        periods.reverse();
        periods.swap(3, 700);
        let mut ts = vec![0u64];
        for p in &periods {
            ts.push(ts.last().unwrap() + p);
        }
        let s = PeriodStats::from_timestamps_us(&ts).unwrap();
        assert_eq!(s.min_us, 1);
        assert_eq!(s.p50_us, 500);
        assert_eq!(s.p90_us, 900);
        assert_eq!(s.p99_us, 990);
        assert_eq!(s.p999_us, 999);
        assert_eq!(s.max_us, 1000);
        assert!((s.mean_us - 500.5).abs() < 1e-9);
        assert!((s.rate_hz - 1000.0 / (500_500.0 / 1e6)).abs() < 1e-6);
    }

    #[test]
    fn one_late_tick_shows_in_the_tail_not_the_median() {
        let mut ts: Vec<u64> = (0..=200).map(|k| k * 1000).collect();
        for t in ts.iter_mut().skip(100) {
            *t += 4000; // the 100th period took 5 ms
        }
        let s = PeriodStats::from_timestamps_us(&ts).unwrap();
        assert_eq!(s.p50_us, 1000);
        assert_eq!(
            s.p99_us, 1000,
            "1 in 200 periods is beyond the 99th percentile"
        );
        assert_eq!(s.p999_us, 5000);
        assert_eq!(s.max_us, 5000);
        assert!(s.to_string().contains("max 5000"), "{s}");
    }

    /// A clock that moves only when waited on, plus `cost_us` per reading, so a tick can be
    /// made to overrun its slot without depending on this machine's speed.
    struct CostlyClock {
        now_us: u64,
        cost_us: u64,
    }

    impl TickClock for CostlyClock {
        fn now_us(&mut self) -> u64 {
            self.now_us += self.cost_us;
            self.now_us
        }

        fn wait_until_us(&mut self, t_us: u64) {
            self.now_us = self.now_us.max(t_us);
        }
    }

    fn held_arm() -> crate::SimulatedArm {
        crate::SimulatedArm::with_trajectory(crate::Trajectory::hold(Vec3::ZERO))
    }

    #[test]
    fn a_loop_on_time_runs_one_tick_per_slot_at_the_asked_rate() {
        let config = DoctorConfig {
            duration_us: 100_000,
            rate_hz: Some(1000.0),
        };
        let mut clock = CostlyClock {
            now_us: 0,
            cost_us: 0,
        };
        let (report, arm) = run(held_arm(), config, &mut clock);
        let report = report.unwrap();
        assert_eq!((report.ticks, report.missed_slots), (100, 0));
        assert_eq!(report.reads_ok, 100);
        assert_eq!(report.read_periods.unwrap().p99_us, 1000);
        assert!(!arm.is_open(), "the doctor closes the device");
    }

    #[test]
    fn ticks_that_overrun_skip_their_missed_slots_and_show_a_lower_rate() {
        // Each clock reading costs 700 µs and a tick reads the clock twice: every tick overruns
        // its 1 ms slot and the next one starts at the following slot boundary, 2 ms later.
        let config = DoctorConfig {
            duration_us: 100_000,
            rate_hz: Some(1000.0),
        };
        let mut clock = CostlyClock {
            now_us: 0,
            cost_us: 700,
        };
        let (report, _) = run(held_arm(), config, &mut clock);
        let report = report.unwrap();
        assert_eq!(report.ticks + report.missed_slots, 100, "{report}");
        assert!(report.missed_slots >= 45, "{report}");
        let periods = report.read_periods.unwrap();
        assert_eq!(
            periods.min_us, 2000,
            "no burst of catch-up ticks: {periods}"
        );
        assert!(periods.rate_hz < 600.0, "{periods}");
    }

    #[test]
    fn fewer_than_two_timestamps_have_no_period() {
        assert_eq!(PeriodStats::from_timestamps_us(&[]), None);
        assert_eq!(PeriodStats::from_timestamps_us(&[7]), None);
        let s = PeriodStats::from_timestamps_us(&[7, 7]).unwrap();
        assert_eq!(s.max_us, 0);
        assert!(s.rate_hz.is_infinite());
    }
}
