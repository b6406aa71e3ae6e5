//! A coarse, fixed-size histogram for live displays: [`LogBins`] counts durations in half-octave
//! bins (edges 2ⁿ and 1.5·2ⁿ ns) from 128 ns to about 270 ms. It travels inside the published
//! [`LatencyStats`](crate::LatencyStats) so a GUI can draw each loop's distribution while the
//! loop runs; the exact histograms stay in the recorder.
//!
//! Recording is O(1) (a leading-zero count), never allocates and never blocks; the whole
//! histogram is a `Copy` array of [`LOG_BINS`] counters.

/// Number of bins: bin 0 holds everything under 128 ns, the last everything from its lower
/// edge up.
pub const LOG_BINS: usize = 44;

/// The smallest bin edge above zero: 2⁷ ns.
const FIRST_EDGE_LOG2: u32 = 7;

/// Counts per half-octave bin of a duration in ns (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LogBins {
    counts: [u64; LOG_BINS],
}

impl Default for LogBins {
    fn default() -> Self {
        Self {
            counts: [0; LOG_BINS],
        }
    }
}

impl LogBins {
    /// The bin holding `ns`.
    #[must_use]
    pub fn bin_of(ns: u64) -> usize {
        if ns < 1 << FIRST_EDGE_LOG2 {
            return 0;
        }
        let log2 = 63 - ns.leading_zeros();
        // The bit below the leading one: set from 1.5·2ⁿ up.
        let upper_half = (ns >> (log2 - 1)) & 1;
        let index = 1 + 2 * (log2 - FIRST_EDGE_LOG2) as usize + upper_half as usize;
        index.min(LOG_BINS - 1)
    }

    /// The lower edge of bin `index`, ns (0 for the first bin).
    #[must_use]
    pub fn lower_edge_ns(index: usize) -> f64 {
        if index == 0 {
            return 0.0;
        }
        let k = index - 1;
        let base = 2f64.powi(i32::try_from(k / 2).unwrap_or(i32::MAX) + FIRST_EDGE_LOG2 as i32);
        if k % 2 == 1 { base * 1.5 } else { base }
    }

    /// The upper edge of bin `index`, ns (the last bin is given the width of the one before).
    #[must_use]
    pub fn upper_edge_ns(index: usize) -> f64 {
        if index + 1 < LOG_BINS {
            Self::lower_edge_ns(index + 1)
        } else {
            Self::lower_edge_ns(index) * 4.0 / 3.0
        }
    }

    /// Counts `ns`. O(1), no allocation.
    pub fn record(&mut self, ns: u64) {
        let slot = &mut self.counts[Self::bin_of(ns)];
        *slot = slot.saturating_add(1);
    }

    /// Forgets every count.
    pub fn reset(&mut self) {
        self.counts = [0; LOG_BINS];
    }

    /// The counts, bin by bin.
    #[must_use]
    pub fn counts(&self) -> &[u64; LOG_BINS] {
        &self.counts
    }

    /// All counts.
    #[must_use]
    pub fn total(&self) -> u64 {
        self.counts.iter().sum()
    }

    /// The counts added since `earlier` (a previous copy of the same histogram): what was
    /// recorded in between. A bin that went down (the recorder was reset) counts from zero.
    #[must_use]
    pub fn since(&self, earlier: &Self) -> Self {
        let mut out = Self::default();
        for ((o, now), then) in out.counts.iter_mut().zip(&self.counts).zip(&earlier.counts) {
            *o = if now >= then { now - then } else { *now };
        }
        out
    }

    /// Adds `other`'s counts to these.
    pub fn add(&mut self, other: &Self) {
        for (a, b) in self.counts.iter_mut().zip(&other.counts) {
            *a = a.saturating_add(*b);
        }
    }

    /// The upper edge (ns) of the highest non-empty bin: the worst value recorded, to within a
    /// half octave. `None` when empty.
    #[must_use]
    pub fn worst_ns(&self) -> Option<f64> {
        self.counts
            .iter()
            .rposition(|&c| c > 0)
            .map(Self::upper_edge_ns)
    }

    /// The upper edge (ns) of the bin where the cumulative share reaches `q` (0..=1). `None`
    /// when empty.
    #[must_use]
    pub fn quantile_ns(&self, q: f64) -> Option<f64> {
        let total = self.total();
        if total == 0 {
            return None;
        }
        let want = (q.clamp(0.0, 1.0) * total as f64).ceil().max(1.0) as u64;
        let mut seen = 0u64;
        for (i, &c) in self.counts.iter().enumerate() {
            seen += c;
            if seen >= want {
                return Some(Self::upper_edge_ns(i));
            }
        }
        self.worst_ns()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bins_follow_half_octave_edges() {
        assert_eq!(LogBins::bin_of(0), 0);
        assert_eq!(LogBins::bin_of(127), 0);
        assert_eq!(LogBins::bin_of(128), 1);
        assert_eq!(LogBins::bin_of(191), 1);
        assert_eq!(LogBins::bin_of(192), 2);
        assert_eq!(LogBins::bin_of(256), 3);
        assert_eq!(LogBins::bin_of(u64::MAX), LOG_BINS - 1);
        // Every value falls inside its bin's edges.
        for ns in [128u64, 150, 200, 1_000, 1_500, 20_000, 999_999, 50_000_000] {
            let b = LogBins::bin_of(ns);
            let (lo, hi) = (LogBins::lower_edge_ns(b), LogBins::upper_edge_ns(b));
            assert!(
                lo <= ns as f64 && (ns as f64) < hi,
                "{ns} in bin {b}: {lo}..{hi}"
            );
        }
        // The top regular bin reaches past 100 ms.
        assert!(LogBins::lower_edge_ns(LOG_BINS - 1) > 1e8);
    }

    #[test]
    fn counts_differences_and_quantiles() {
        let mut a = LogBins::default();
        for _ in 0..99 {
            a.record(1_000);
        }
        let earlier = a;
        a.record(500_000);
        assert_eq!(a.total(), 100);
        let delta = a.since(&earlier);
        assert_eq!(delta.total(), 1);
        assert_eq!(
            delta.worst_ns(),
            Some(LogBins::upper_edge_ns(LogBins::bin_of(500_000)))
        );
        assert_eq!(
            a.quantile_ns(0.5),
            Some(LogBins::upper_edge_ns(LogBins::bin_of(1_000)))
        );
        assert_eq!(a.quantile_ns(1.0), a.worst_ns());
        // After a reset the newer copy is smaller: it counts from zero.
        let mut b = LogBins::default();
        b.record(1_000);
        assert_eq!(b.since(&a).total(), 1);
        let mut sum = LogBins::default();
        sum.add(&a);
        sum.add(&b);
        assert_eq!(sum.total(), 101);
        assert_eq!(LogBins::default().worst_ns(), None);
        assert_eq!(LogBins::default().quantile_ns(0.5), None);
    }
}
