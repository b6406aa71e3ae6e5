//! The serialisable per-loop summary and its JSON form.
//!
//! Not for the real-time path: building a summary clones the loop's name and JSON allocates.
//! Read the loop's [`LatencyStats`] through its monitor (wait-free) and build summaries on the
//! reporting thread.

use serde::{Deserialize, Serialize};

use crate::motion::MotionToPhotonSummary;
use crate::priority::{PinOutcome, RtOutcome};
use crate::probe::ProbeSummary;
use crate::readiness::{PlatformFacts, Verdict};
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

/// Everything a profile run reports: the loops, the platform probe before and after them, the
/// machine's facts and the readiness verdicts. The JSON form of `latency.json`; a document
/// holding only `loops` (as `dynaclay run` writes) is valid too.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ProfileDoc {
    /// One summary per loop.
    pub loops: Vec<LoopSummary>,
    /// The platform probe run before the loops started.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub probe_before: Option<ProbeSummary>,
    /// The platform probe run after the loops stopped.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub probe_after: Option<ProbeSummary>,
    /// What was known about the machine.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub facts: Option<PlatformFacts>,
    /// The readiness verdicts, one per rate judged.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub readiness: Vec<Verdict>,
    /// Motion to photon: hand → force, hand → first visible change and hand → settled shape
    /// per stroke (runs that drove the engine).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub motion_to_photon: Option<MotionToPhotonSummary>,
}

impl ProfileDoc {
    /// Pretty JSON.
    ///
    /// # Errors
    /// Only if serde_json fails to write, which does not happen for these types; kept as a
    /// value rather than a panic.
    pub fn to_json(&self) -> Result<String, serde_json::Error> {
        serde_json::to_string_pretty(self)
    }

    /// Parses what [`ProfileDoc::to_json`] (or [`summaries_to_json`]) wrote.
    ///
    /// # Errors
    /// The serde_json error, with line and column, if `json` is not such a document.
    pub fn from_json(json: &str) -> Result<Self, serde_json::Error> {
        serde_json::from_str(json)
    }
}

/// Pretty JSON for a set of loop summaries: `{"loops": [...]}`.
///
/// # Errors
/// Only if serde_json fails to write, which does not happen for these types; kept as a value
/// rather than a panic.
pub fn summaries_to_json(summaries: &[LoopSummary]) -> Result<String, serde_json::Error> {
    ProfileDoc {
        loops: summaries.to_vec(),
        ..ProfileDoc::default()
    }
    .to_json()
}

/// Parses what [`summaries_to_json`] wrote.
///
/// # Errors
/// The serde_json error, with line and column, if `json` is not such a document.
pub fn summaries_from_json(json: &str) -> Result<Vec<LoopSummary>, serde_json::Error> {
    ProfileDoc::from_json(json).map(|d| d.loops)
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
    fn full_profile_doc_round_trips() {
        let probe = ProbeSummary {
            wakeup_rt: RtOutcome::Granted { priority: 80 },
            wakeup: sample().stats,
            stall_rt: RtOutcome::NotRequested,
            stalls: crate::probe::StallStats {
                seconds: 0.5,
                gap_threshold_us: 20.0,
                gaps: 7,
                stolen_ms: 1.25,
                max_gap_us: 400.0,
                gap_counts: None,
            },
        };
        let facts = PlatformFacts {
            rt_granted: Some(true),
            governors: Some(vec!["schedutil".into()]),
            stall_ms_per_s: Some(2.5),
            ..PlatformFacts::default()
        };
        let doc = ProfileDoc {
            loops: vec![sample()],
            probe_before: Some(probe),
            probe_after: Some(probe),
            readiness: vec![crate::readiness::verdict(&facts, 1000.0)],
            facts: Some(facts),
            motion_to_photon: Some(crate::motion::MotionToPhotonSummary {
                presenter: "test frames".into(),
                strokes: 2,
                first_visible_ms: crate::motion::Spread::of(&[12.5, 30.0]),
                ..crate::motion::MotionToPhotonSummary::default()
            }),
        };
        let json = doc.to_json().expect("json");
        assert!(json.contains("\"stolen_ms\": 1.25"), "{json}");
        assert!(json.contains("\"first_visible_ms\""), "{json}");
        assert_eq!(ProfileDoc::from_json(&json).expect("parse"), doc);
        // A run's loops-only document is a valid profile document.
        let loops_only = summaries_to_json(&[sample()]).expect("json");
        assert!(!loops_only.contains("probe_before"));
        assert_eq!(
            ProfileDoc::from_json(&loops_only).expect("parse").loops,
            vec![sample()]
        );
    }

    #[test]
    fn bad_json_reports_position() {
        let err = summaries_from_json("{\"loops\": [ {\"name\": 3} ]}").expect_err("bad");
        assert!(err.line() == 1 && err.column() > 0);
    }
}
