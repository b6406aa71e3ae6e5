//! A readable Markdown table of several loops' latency summaries.
//!
//! Not for the real-time path (builds a `String`).

use std::fmt::Write as _;

use crate::priority::RtOutcome;
use crate::probe::ProbeSummary;
use crate::recorder::LatencyStats;
use crate::summary::{LoopSummary, ProfileDoc};

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

/// `a ÷ b` as a cell; "—" when `b` is zero or either is not finite.
fn ratio_cell(a: f64, b: f64) -> String {
    if b > 0.0 && a.is_finite() && b.is_finite() {
        format!("{:.2}", a / b)
    } else {
        "—".into()
    }
}

fn opt_cell(v: Option<f64>) -> String {
    v.map_or_else(|| "—".into(), |v| format!("{v:.1}"))
}

/// The haptic loop side by side with the platform probe run before and after it. The ratio
/// column divides the loop's figure by the worse of the two probe runs: near 1 the machine
/// sets the latency, well above 1 the engine adds to it.
#[must_use]
pub fn probe_table(
    haptic: &LoopSummary,
    before: Option<&ProbeSummary>,
    after: Option<&ProbeSummary>,
) -> String {
    type Pick = fn(&LatencyStats) -> f64;
    let rows: [(&str, Pick); 6] = [
        ("wake-up latency p50 µs", |s| s.lateness.p50_us),
        ("wake-up latency p99 µs", |s| s.lateness.p99_us),
        ("wake-up latency p99.9 µs", |s| s.lateness.p999_us),
        ("wake-up latency max µs", |s| s.lateness.max_us),
        ("period error p99.9 µs", |s| s.period_error.p999_us),
        ("period error max µs", |s| s.period_error.max_us),
    ];
    let mut out = String::from(
        "| figure | haptic loop | probe before | probe after | haptic ÷ probe |\n\
         | --- | ---: | ---: | ---: | ---: |\n",
    );
    for (label, pick) in rows {
        let engine = pick(&haptic.stats);
        let b = before.map(|p| pick(&p.wakeup));
        let a = after.map(|p| pick(&p.wakeup));
        let worse = b.into_iter().chain(a).fold(0.0, f64::max);
        let _ = writeln!(
            out,
            "| {label} | {engine:.1} | {} | {} | {} |",
            opt_cell(b),
            opt_cell(a),
            ratio_cell(engine, worse)
        );
    }
    let stall = |p: Option<&ProbeSummary>| {
        p.map_or_else(
            || "—".to_string(),
            |p| {
                format!(
                    "{:.1} ms/s in {:.0} gaps/s (max {:.0} µs)",
                    p.stalls.stolen_ms_per_s(),
                    p.stalls.gaps_per_s(),
                    p.stalls.max_gap_us
                )
            },
        )
    };
    let _ = writeln!(
        out,
        "| host stalls (gaps ≥ {:.0} µs) | — | {} | {} | — |",
        before.or(after).map_or(
            crate::probe::DEFAULT_GAP_THRESHOLD.as_secs_f64() * 1e6,
            |p| { p.stalls.gap_threshold_us }
        ),
        stall(before),
        stall(after)
    );
    out
}

/// Per-figure ratios of profile `b` to profile `a` (below 1: `b` is better), for every loop
/// the two share and for the platform probe.
#[must_use]
pub fn compare_table(a: &ProfileDoc, b: &ProfileDoc) -> String {
    type Pick = fn(&LatencyStats) -> f64;
    let figures: [(&str, Pick); 11] = [
        ("period error p50 µs", |s| s.period_error.p50_us),
        ("period error p99 µs", |s| s.period_error.p99_us),
        ("period error p99.9 µs", |s| s.period_error.p999_us),
        ("period error max µs", |s| s.period_error.max_us),
        ("wake-up latency p99 µs", |s| s.lateness.p99_us),
        ("wake-up latency p99.9 µs", |s| s.lateness.p999_us),
        ("wake-up latency max µs", |s| s.lateness.max_us),
        ("compute p50 µs", |s| s.compute.p50_us),
        ("compute p99 µs", |s| s.compute.p99_us),
        ("compute max µs", |s| s.compute.max_us),
        ("deadline misses per 1000 ticks", |s| {
            if s.ticks > 0 {
                s.deadline_misses as f64 * 1000.0 / s.ticks as f64
            } else {
                0.0
            }
        }),
    ];
    let mut out =
        String::from("| loop | figure | A | B | B ÷ A |\n| --- | --- | ---: | ---: | ---: |\n");
    let mut row = |name: &str, label: &str, x: f64, y: f64| {
        let _ = writeln!(
            out,
            "| {} | {label} | {x:.2} | {y:.2} | {} |",
            name.replace('|', "\\|"),
            ratio_cell(y, x)
        );
    };
    for lb in &b.loops {
        let Some(la) = a.loops.iter().find(|l| l.name == lb.name) else {
            continue;
        };
        for (label, pick) in figures {
            row(&lb.name, label, pick(&la.stats), pick(&lb.stats));
        }
    }
    let worse_probe = |d: &ProfileDoc| -> Option<(LatencyStats, f64)> {
        let runs: Vec<&ProbeSummary> = d.probe_before.iter().chain(&d.probe_after).collect();
        let worst = runs.iter().max_by(|x, y| {
            x.wakeup
                .lateness
                .p999_us
                .total_cmp(&y.wakeup.lateness.p999_us)
        })?;
        let stall = runs
            .iter()
            .map(|p| p.stalls.stolen_ms_per_s())
            .fold(0.0, f64::max);
        Some((worst.wakeup, stall))
    };
    if let (Some((pa, sa)), Some((pb, sb))) = (worse_probe(a), worse_probe(b)) {
        for (label, pick) in &figures[4..7] {
            row("probe", label, pick(&pa), pick(&pb));
        }
        row("probe", "host stalls ms/s", sa, sb);
    }
    out
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

    fn synthetic(name: &str, scale: f64) -> LoopSummary {
        let p = |base: f64| Percentiles {
            p50_us: base * scale,
            p99_us: base * 10.0 * scale,
            p999_us: base * 100.0 * scale,
            max_us: base * 400.0 * scale,
            mean_us: base * scale,
        };
        LoopSummary {
            name: name.into(),
            rt_priority: RtOutcome::Granted { priority: 80 },
            pinning: PinOutcome::NotRequested,
            stats: LatencyStats {
                ticks: 5000,
                deadline_misses: (10.0 * scale) as u64,
                nominal_rate_hz: 1000.0,
                achieved_rate_hz: 999.5,
                elapsed_s: 5.0,
                period: p(1000.0),
                period_error: p(0.5),
                lateness: p(0.8),
                compute: p(2.0),
                ..LatencyStats::default()
            },
        }
    }

    fn probe(scale: f64) -> ProbeSummary {
        ProbeSummary {
            wakeup_rt: RtOutcome::Granted { priority: 80 },
            wakeup: synthetic("probe", scale).stats,
            stall_rt: RtOutcome::Granted { priority: 80 },
            stalls: crate::probe::StallStats {
                seconds: 0.5,
                gap_threshold_us: 20.0,
                gaps: 40,
                stolen_ms: 2.0 * scale,
                max_gap_us: 300.0,
                gap_counts: None,
            },
        }
    }

    #[test]
    fn probe_table_snapshot() {
        let table = probe_table(
            &synthetic("haptic", 1.0),
            Some(&probe(0.5)),
            Some(&probe(0.25)),
        );
        let expected = "\
| figure | haptic loop | probe before | probe after | haptic ÷ probe |
| --- | ---: | ---: | ---: | ---: |
| wake-up latency p50 µs | 0.8 | 0.4 | 0.2 | 2.00 |
| wake-up latency p99 µs | 8.0 | 4.0 | 2.0 | 2.00 |
| wake-up latency p99.9 µs | 80.0 | 40.0 | 20.0 | 2.00 |
| wake-up latency max µs | 320.0 | 160.0 | 80.0 | 2.00 |
| period error p99.9 µs | 50.0 | 25.0 | 12.5 | 2.00 |
| period error max µs | 200.0 | 100.0 | 50.0 | 2.00 |
| host stalls (gaps ≥ 20 µs) | — | 2.0 ms/s in 80 gaps/s (max 300 µs) | 1.0 ms/s in 80 gaps/s (max 300 µs) | — |
";
        assert_eq!(table, expected);
        // Without a probe the ratios are left blank rather than dividing by zero.
        let bare = probe_table(&synthetic("haptic", 1.0), None, None);
        assert!(
            bare.lines()
                .nth(2)
                .is_some_and(|l| l.ends_with("| — | — | — |")),
            "{bare}"
        );
    }

    #[test]
    fn compare_gives_b_over_a_per_figure() {
        let a = ProfileDoc {
            loops: vec![synthetic("haptic", 1.0), synthetic("sim", 1.0)],
            probe_before: Some(probe(1.0)),
            probe_after: Some(probe(2.0)),
            ..ProfileDoc::default()
        };
        let b = ProfileDoc {
            loops: vec![synthetic("haptic", 0.5), synthetic("graphics", 1.0)],
            probe_before: Some(probe(4.0)),
            ..ProfileDoc::default()
        };
        let table = compare_table(&a, &b);
        assert!(
            table.contains("| haptic | period error p99.9 µs | 50.00 | 25.00 | 0.50 |"),
            "{table}"
        );
        assert!(
            table.contains("| haptic | deadline misses per 1000 ticks | 2.00 | 1.00 | 0.50 |"),
            "{table}"
        );
        // Loops only one side has are left out; the probe compares its worse run.
        assert!(!table.contains("| sim |") && !table.contains("| graphics |"));
        assert!(
            table.contains("| probe | wake-up latency max µs | 640.00 | 1280.00 | 2.00 |"),
            "{table}"
        );
        assert!(
            table.contains("| probe | host stalls ms/s | 8.00 | 16.00 | 2.00 |"),
            "{table}"
        );
    }
}
