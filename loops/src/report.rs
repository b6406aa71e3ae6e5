//! The profile report as text: loop table, the haptic loop beside the platform probe, and the
//! readiness verdicts. What `dynaclay profile` prints and `latency.md` holds.
//!
//! Not for the real-time path (builds a `String`).

use std::fmt::Write as _;

use crate::readiness::verdict_text;
use crate::summary::ProfileDoc;
use crate::table::{markdown_table, probe_table};

/// The name of the loop compared with the probe.
pub const HAPTIC_LOOP: &str = "haptic";

/// Markdown text of a profile: the loops, the probe comparison (when the document has a probe
/// and a haptic loop) and the verdicts (when it has any).
#[must_use]
pub fn profile_report(doc: &ProfileDoc) -> String {
    let mut out = String::from("## Loops\n\n");
    out.push_str(&markdown_table(&doc.loops));
    let haptic = doc.loops.iter().find(|l| l.name == HAPTIC_LOOP);
    if let Some(haptic) = haptic
        && (doc.probe_before.is_some() || doc.probe_after.is_some())
    {
        out.push_str("\n## Haptic loop beside the platform probe\n\n");
        out.push_str(&probe_table(
            haptic,
            doc.probe_before.as_ref(),
            doc.probe_after.as_ref(),
        ));
    }
    if let Some(m) = &doc.motion_to_photon {
        out.push_str("\n## Motion to photon\n\n");
        out.push_str(&crate::motion::motion_table(m));
    }
    if !doc.readiness.is_empty() {
        out.push_str("\n## Readiness\n\n```text\n");
        out.push_str(&verdict_text(&doc.readiness));
        out.push_str("```\n");
    }
    if let Some(f) = &doc.facts {
        let _ = writeln!(
            out,
            "\nFacts: governors {}, isolated core {}, sched_rt_runtime_us {}, SMT {}, \
             CPUs busy {}.",
            f.governors
                .as_ref()
                .map_or_else(|| "unknown".into(), |g| g.join(", ")),
            known(
                f.isolated_core
                    .map(|b| if b { "yes" } else { "no" }.to_string())
            ),
            known(f.rt_runtime_us.map(|v| v.to_string())),
            known(
                f.smt_active
                    .map(|b| if b { "on" } else { "off" }.to_string())
            ),
            known(f.cpu_busy_fraction.map(|v| format!("{:.0}%", v * 100.0))),
        );
    }
    out
}

fn known(v: Option<String>) -> String {
    v.unwrap_or_else(|| "unknown".into())
}

#[cfg(test)]
mod tests {
    use std::time::{Duration, Instant};

    use super::*;
    use crate::priority::{PinOutcome, RtOutcome};
    use crate::probe::{GapCounts, ProbeRun, StallStats};
    use crate::readiness::{LoopRecord, PlatformFacts, verdict};
    use crate::recorder::{LatencyRecorder, TickTiming};
    use crate::summary::LoopSummary;

    /// 1000 ticks at 1 kHz: lateness `i % 10` µs, one tick 900 µs late, compute 5 µs.
    fn synthetic_recorder(scale: u64) -> LatencyRecorder {
        let period = Duration::from_millis(1);
        let mut rec = LatencyRecorder::new(period);
        let t0 = Instant::now();
        for i in 0..1000u32 {
            let late_us = if i == 500 { 900 } else { u64::from(i % 10) } * scale;
            rec.record_tick(&TickTiming {
                scheduled: t0 + period * i,
                woke: t0 + period * i + Duration::from_micros(late_us),
                compute: Duration::from_micros(5),
                skipped_before: 0,
            });
        }
        rec
    }

    #[test]
    fn report_text_snapshot() {
        let haptic = LoopSummary {
            name: HAPTIC_LOOP.into(),
            rt_priority: RtOutcome::Granted { priority: 80 },
            pinning: PinOutcome::NotRequested,
            stats: synthetic_recorder(2).stats(),
        };
        // Eleven gaps of 50 µs and one of 800 µs.
        let mut gap_counts = GapCounts::default();
        for gap_ns in [50_000; 11].into_iter().chain([800_000]) {
            gap_counts.add(gap_ns);
        }
        let probe = ProbeRun {
            wakeup_rt: RtOutcome::Granted { priority: 80 },
            wakeup: synthetic_recorder(1),
            stall_rt: RtOutcome::Granted { priority: 80 },
            stalls: StallStats {
                seconds: 1.0,
                gap_threshold_us: 20.0,
                gaps: 12,
                stolen_ms: 3.5,
                max_gap_us: 800.0,
                gap_counts: Some(gap_counts),
            },
        }
        .summary();
        let facts = PlatformFacts {
            rt_granted: Some(true),
            governors: Some(vec!["performance".into()]),
            isolated_core: Some(false),
            rt_runtime_us: Some(950_000),
            rt_period_us: Some(1_000_000),
            smt_active: Some(false),
            cpu_busy_fraction: Some(0.25),
            stall_ms_per_s: Some(probe.stalls.stolen_ms_per_s()),
            wakeup_p999_us: Some(probe.wakeup.lateness.p999_us),
            wakeup_max_us: Some(probe.wakeup.lateness.max_us),
            stalls: Some(probe.stalls),
            haptic_loop: Some(LoopRecord::from_stats(&haptic.stats)),
        };
        let doc = ProfileDoc {
            loops: vec![haptic],
            probe_before: Some(probe),
            probe_after: None,
            readiness: vec![verdict(&facts, 1000.0), verdict(&facts, 4000.0)],
            facts: Some(facts),
            motion_to_photon: None,
        };
        let text = profile_report(&doc);
        let expected = "\
## Loops

| loop | rate Hz (nominal / achieved) | priority | ticks | period err p50 / p99 / p99.9 / max µs | compute p50 / p99 / max µs | late >1 ms | late >2 ms | deadline misses | skipped |
| --- | --- | --- | ---: | --- | --- | ---: | ---: | ---: | ---: |
| haptic | 1000 / 1000.0 | FIFO 80 | 1000 | 2.0 / 18.0 / 1782.8 / 1782.0 | 5.0 / 5.0 / 5.0 | 1 | 0 | 1 | 0 |

## Haptic loop beside the platform probe

| figure | haptic loop | probe before | probe after | haptic ÷ probe |
| --- | ---: | ---: | ---: | ---: |
| wake-up latency p50 µs | 10.0 | 5.0 | — | 2.00 |
| wake-up latency p99 µs | 18.0 | 9.0 | — | 2.00 |
| wake-up latency p99.9 µs | 18.0 | 9.0 | — | 2.00 |
| wake-up latency max µs | 1800.0 | 900.0 | — | 2.00 |
| period error p99.9 µs | 1782.8 | 899.1 | — | 1.98 |
| period error max µs | 1782.0 | 899.0 | — | 1.98 |
| host stalls (gaps ≥ 20 µs) | — | 3.5 ms/s in 12 gaps/s (max 800 µs) | — | — |

## Readiness

```text
1000 Hz: marginal
  [marginal] the haptic loop missed 1 deadline in 1000 ticks at 1000 Hz
      fix: find the cause among the other reasons; if none shows, the tick's work is too long for the period (see compute in the loop table)
  [pass] RT throttling on: real-time threads get at most 950000 µs per 1000000 µs; only a busy-waiting loop reaches it (sudo sysctl kernel.sched_rt_runtime_us=-1 lifts it)
4000 Hz: fail
  [fail] wake-up latency p99.9 9 µs, max 900 µs against a 250 µs period
      fix: see the other reasons; a kernel with PREEMPT_RT shortens wake-ups
  [marginal] no isolated core: the haptic thread shares its core with everything else
      fix: boot with isolcpus=N nohz_full=N (one spare core) and pin the haptic loop to it
  [marginal] host stalls up to 800 µs: 1.0 a second of 250 µs or more (all of the 250 µs period)
      fix: on a VM, give it dedicated vCPUs (CPU pinning on the host, no overcommit); on bare metal, look for SMIs or interrupt storms (irqbalance, BIOS power settings)
  [pass] RT throttling on: real-time threads get at most 950000 µs per 1000000 µs; only a busy-waiting loop reaches it (sudo sysctl kernel.sched_rt_runtime_us=-1 lifts it)
```

Facts: governors performance, isolated core no, sched_rt_runtime_us 950000, SMT off, CPUs busy 25%.
";
        assert_eq!(text, expected, "\n{text}");
    }

    #[test]
    fn a_loops_only_document_reports_only_the_loops() {
        let doc = ProfileDoc::from_json(r#"{"loops": []}"#).expect("parse");
        let text = profile_report(&doc);
        assert!(
            !text.contains("probe") && !text.contains("Readiness"),
            "{text}"
        );
    }
}
