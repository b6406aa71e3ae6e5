//! A readable Markdown table of several loops' latency summaries.
//!
//! Not for the real-time path (builds a `String`).

use std::fmt::Write as _;

use crate::priority::RtOutcome;
use crate::summary::LoopSummary;

/// One row per loop: rate, scheduling, period error and compute percentiles (µs), late ticks,
/// deadline misses and skipped ticks.
#[must_use]
pub fn markdown_table(summaries: &[LoopSummary]) -> String {
    let mut out = String::new();
    out.push_str(
        "| loop | rate Hz (nominal / achieved) | priority | ticks \
         | period err p50 / p99 / p99.9 / max µs | compute p50 / p99 / max µs \
         | late >1 ms | late >2 ms | deadline misses | skipped |\n",
    );
    out.push_str("| --- | --- | --- | ---: | --- | --- | ---: | ---: | ---: | ---: |\n");
    for s in summaries {
        let st = &s.stats;
        let pe = &st.period_error;
        let c = &st.compute;
        // Writing to a String cannot fail.
        let _ = writeln!(
            out,
            "| {} | {:.0} / {:.1} | {} | {} | {:.1} / {:.1} / {:.1} / {:.1} | {:.1} / {:.1} / {:.1} \
             | {} | {} | {} | {} |",
            s.name.replace('|', "\\|"),
            st.nominal_rate_hz,
            st.achieved_rate_hz,
            priority_cell(&s.rt_priority),
            st.ticks,
            pe.p50_us,
            pe.p99_us,
            pe.p999_us,
            pe.max_us,
            c.p50_us,
            c.p99_us,
            c.max_us,
            st.late_over_1ms,
            st.late_over_2ms,
            st.deadline_misses,
            st.skipped_ticks,
        );
    }
    out
}

fn priority_cell(rt: &RtOutcome) -> String {
    match *rt {
        RtOutcome::NotRequested => "normal".into(),
        RtOutcome::Granted { priority } => format!("FIFO {priority}"),
        RtOutcome::Denied { priority, os_error } => {
            format!("normal (FIFO {priority} denied, os error {os_error})")
        }
        RtOutcome::InvalidPriority { priority, .. } => format!("normal (FIFO {priority} invalid)"),
        RtOutcome::Unsupported => "normal (no FIFO)".into(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::priority::PinOutcome;
    use crate::recorder::{LatencyStats, Percentiles};

    #[test]
    fn one_row_per_loop_with_figures() {
        let mk = |name: &str, rt| LoopSummary {
            name: name.into(),
            rt_priority: rt,
            pinning: PinOutcome::NotRequested,
            stats: LatencyStats {
                ticks: 1234,
                late_over_1ms: 2,
                nominal_rate_hz: 1000.0,
                achieved_rate_hz: 998.25,
                period_error: Percentiles {
                    p99_us: 7.25,
                    ..Percentiles::default()
                },
                ..LatencyStats::default()
            },
        };
        let table = markdown_table(&[
            mk("haptic", RtOutcome::Granted { priority: 80 }),
            mk(
                "sim|x",
                RtOutcome::Denied {
                    priority: 80,
                    os_error: 1,
                },
            ),
        ]);
        let lines: Vec<&str> = table.lines().collect();
        assert_eq!(lines.len(), 4);
        assert!(
            lines[2].starts_with("| haptic | 1000 / 998.2 | FIFO 80 | 1234 | 0.0 / 7.2"),
            "{}",
            lines[2]
        );
        assert!(lines[3].contains("sim\\|x") && lines[3].contains("denied, os error 1"));
        // Every row has as many cells as the header.
        let cells = |l: &str| l.matches(" | ").count();
        assert!(lines.iter().all(|l| cells(l) == cells(lines[0])), "{table}");
    }
}
