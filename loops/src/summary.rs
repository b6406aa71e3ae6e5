//! The serialisable per-loop summary and its JSON form.
//!
//! Not for the real-time path: building a summary clones the loop's name and JSON allocates.
//! Read the loop's [`LatencyStats`] through its monitor (wait-free) and build summaries on the
//! reporting thread.

use serde::{Deserialize, Serialize};

use crate::priority::{PinOutcome, RtOutcome};
use crate::recorder::LatencyStats;

/// One loop's figures with how it was scheduled.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LoopSummary {
    /// The loop's name.
    pub name: String,
    /// What the OS granted for the real-time request.
    pub rt_priority: RtOutcome,
    /// What happened to the pinning request.
    pub pinning: PinOutcome,
    /// Counts and percentiles.
    pub stats: LatencyStats,
}

/// Pretty JSON for a set of loop summaries: `{"loops": [...]}`.
///
/// # Errors
/// Only if serde_json fails to write, which does not happen for these types; kept as a value
/// rather than a panic.
pub fn summaries_to_json(summaries: &[LoopSummary]) -> Result<String, serde_json::Error> {
    #[derive(Serialize)]
    struct Doc<'a> {
        loops: &'a [LoopSummary],
    }
    serde_json::to_string_pretty(&Doc { loops: summaries })
}

/// Parses what [`summaries_to_json`] wrote.
///
/// # Errors
/// The serde_json error, with line and column, if `json` is not such a document.
pub fn summaries_from_json(json: &str) -> Result<Vec<LoopSummary>, serde_json::Error> {
    #[derive(Deserialize)]
    struct Doc {
        loops: Vec<LoopSummary>,
    }
    serde_json::from_str::<Doc>(json).map(|d| d.loops)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::recorder::Percentiles;

    fn sample() -> LoopSummary {
        LoopSummary {
            name: "haptic".into(),
            rt_priority: RtOutcome::Granted { priority: 80 },
            pinning: PinOutcome::Pinned { core: 1 },
            stats: LatencyStats {
                ticks: 5000,
                nominal_rate_hz: 1000.0,
                achieved_rate_hz: 999.9,
                period_error: Percentiles {
                    p50_us: 0.4,
                    p99_us: 3.0,
                    p999_us: 30.0,
                    max_us: 120.0,
                    mean_us: 0.6,
                },
                ..LatencyStats::default()
            },
        }
    }

    #[test]
    fn json_round_trip() {
        let json = summaries_to_json(&[sample()]).expect("json");
        assert!(json.contains("\"p999_us\": 30.0"), "{json}");
        assert!(json.contains("\"status\": \"granted\""), "{json}");
        assert_eq!(summaries_from_json(&json).expect("parse"), vec![sample()]);
    }

    #[test]
    fn bad_json_reports_position() {
        let err = summaries_from_json("{\"loops\": [ {\"name\": 3} ]}").expect_err("bad");
        assert!(err.line() == 1 && err.column() > 0);
    }
}
