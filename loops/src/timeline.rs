//! A loop's run over time, in a fixed number of windows: per window the largest period error,
//! the largest compute time and the deadline misses. When the run outgrows the windows, pairs
//! of neighbours merge and the window doubles, so any run length fits in the same memory.
//!
//! Guarantee: [`Timeline::new`] allocates every window; [`record`](Timeline::record) never
//! allocates and does bounded work (at most one merge pass over [`TIMELINE_WINDOWS`] windows per
//! doubling, so a handful of passes over a whole run).

use std::time::Duration;

/// How many windows a timeline holds.
pub const TIMELINE_WINDOWS: usize = 1024;
/// The window length a timeline starts with.
pub const FIRST_WINDOW: Duration = Duration::from_millis(10);

/// The figures of one window.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TimelineWindow {
    /// Ticks recorded in the window.
    pub ticks: u32,
    /// Largest |period − nominal| in the window, ns.
    pub max_period_error_ns: u64,
    /// Largest compute time in the window, ns.
    pub max_compute_ns: u64,
    /// Deadline misses in the window.
    pub deadline_misses: u32,
}

impl TimelineWindow {
    fn merge(self, other: Self) -> Self {
        Self {
            ticks: self.ticks.saturating_add(other.ticks),
            max_period_error_ns: self.max_period_error_ns.max(other.max_period_error_ns),
            max_compute_ns: self.max_compute_ns.max(other.max_compute_ns),
            deadline_misses: self.deadline_misses.saturating_add(other.deadline_misses),
        }
    }
}

/// See the module docs.
#[derive(Clone, Debug)]
pub struct Timeline {
    window_ns: u64,
    windows: Vec<TimelineWindow>,
}

impl Default for Timeline {
    fn default() -> Self {
        Self::new()
    }
}

impl Timeline {
    /// An empty timeline; allocates its windows now.
    #[must_use]
    pub fn new() -> Self {
        Self {
            window_ns: nanos(FIRST_WINDOW),
            windows: Vec::with_capacity(TIMELINE_WINDOWS),
        }
    }

    /// Records one tick `since_start` after the run's first tick. No allocation.
    pub fn record(
        &mut self,
        since_start: Duration,
        period_error: Duration,
        compute: Duration,
        missed: bool,
    ) {
        let at_ns = nanos(since_start);
        while at_ns / self.window_ns >= TIMELINE_WINDOWS as u64 {
            self.fold();
        }
        // In range by the loop above: below TIMELINE_WINDOWS.
        let index = (at_ns / self.window_ns) as usize;
        while self.windows.len() <= index {
            // NOTE: within the capacity reserved in `new`: never reallocates.
            self.windows.push(TimelineWindow::default());
        }
        let w = &mut self.windows[index];
        w.ticks = w.ticks.saturating_add(1);
        w.max_period_error_ns = w.max_period_error_ns.max(nanos(period_error));
        w.max_compute_ns = w.max_compute_ns.max(nanos(compute));
        w.deadline_misses = w.deadline_misses.saturating_add(u32::from(missed));
    }

    /// Merges neighbouring windows pairwise and doubles the window length.
    fn fold(&mut self) {
        let n = self.windows.len();
        for i in 0..n.div_ceil(2) {
            let a = self.windows[2 * i];
            let b = self.windows.get(2 * i + 1).copied().unwrap_or_default();
            self.windows[i] = a.merge(b);
        }
        self.windows.truncate(n.div_ceil(2));
        self.window_ns = self.window_ns.saturating_mul(2);
    }

    /// Forgets everything; the window returns to [`FIRST_WINDOW`]. No allocation.
    pub fn reset(&mut self) {
        self.windows.clear();
        self.window_ns = nanos(FIRST_WINDOW);
    }

    /// The current window length.
    #[must_use]
    pub fn window(&self) -> Duration {
        Duration::from_nanos(self.window_ns)
    }

    /// The windows from the run's start, one per [`window`](Self::window).
    #[must_use]
    pub fn windows(&self) -> &[TimelineWindow] {
        &self.windows
    }
}

fn nanos(d: Duration) -> u64 {
    u64::try_from(d.as_nanos()).unwrap_or(u64::MAX)
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: Duration = Duration::from_millis(1);

    #[test]
    fn ticks_land_in_their_window() {
        let mut t = Timeline::new();
        t.record(MS * 3, MS, MS * 2, false);
        t.record(MS * 25, MS * 4, MS, true);
        let w = t.windows();
        assert_eq!(w.len(), 3);
        assert_eq!(w[0].max_period_error_ns, 1_000_000);
        assert_eq!(w[1], TimelineWindow::default());
        assert_eq!(w[2].deadline_misses, 1);
        assert_eq!(w[2].max_period_error_ns, 4_000_000);
    }

    #[test]
    fn a_long_run_folds_and_keeps_every_tick_and_miss() {
        let mut t = Timeline::new();
        let capacity = t.windows.capacity();
        // 60 s at 1 kHz, a miss every 1000 ticks, one 7 ms spike.
        for i in 0..60_000u32 {
            let err = if i == 31_234 { MS * 7 } else { Duration::ZERO };
            t.record(MS * i, err, Duration::from_micros(5), i % 1000 == 0);
        }
        assert!(t.windows().len() <= TIMELINE_WINDOWS);
        assert_eq!(t.windows.capacity(), capacity, "reallocated");
        assert_eq!(t.window(), FIRST_WINDOW * 8);
        let w = t.windows();
        assert_eq!(w.iter().map(|w| u64::from(w.ticks)).sum::<u64>(), 60_000);
        assert_eq!(w.iter().map(|w| w.deadline_misses).sum::<u32>(), 60);
        let spike = w
            .iter()
            .position(|w| w.max_period_error_ns > 0)
            .expect("spike");
        assert_eq!(spike as u64, 31_234 / 80);
    }

    #[test]
    fn reset_starts_over() {
        let mut t = Timeline::new();
        t.record(Duration::from_secs(100), MS, MS, true);
        t.reset();
        assert!(t.windows().is_empty());
        assert_eq!(t.window(), FIRST_WINDOW);
    }
}
