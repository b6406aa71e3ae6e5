//! Is this machine fit for 1 kHz (or 4 kHz) haptics? A verdict with reasons and fixes.
//!
//! [`verdict`] is a pure function of [`PlatformFacts`], so every reason is tested without the
//! machine. [`read_platform_facts`] gathers the facts from `/proc` and `/sys` with bounded reads
//! (each file at most [`FACT_FILE_CAP`] bytes); a missing or unreadable file leaves its fact
//! `None`, shown as "unknown". Not for the real-time path (reads files, allocates).
//!
//! The verdict judges what endangers a deadline at the asked rate: stalls and wake-ups as long
//! as a good part of the period, and how often they come, never the sum of short stalls. The
//! haptic loop's own record, when there is one, outweighs the probes: a loop that met every
//! deadline is never told its machine fails. Every threshold is a row of [`THRESHOLDS`], with
//! the recorded figures that set it.

use std::fmt;
use std::io::Read;
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::probe::StallStats;
use crate::recorder::LatencyStats;

/// The most bytes read from any one `/proc` or `/sys` file (they report size 0, so the cap is
/// applied while reading).
pub const FACT_FILE_CAP: u64 = 64 * 1024;

/// What one row of [`THRESHOLDS`] measures. Every measure but
/// [`Measure::LoopMetEveryDeadline`] raises a finding to the row's grade when its value is
/// above the row's `above`; values are in the unit each variant names.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Measure {
    /// 1 when the haptic thread was refused real-time priority, else 0.
    RtRefused,
    /// 1 when a CPU frequency governor other than `performance` is in use, else 0.
    GovernorNotPerformance,
    /// 1 when no core is isolated, else 0.
    NoIsolatedCore,
    /// The CPUs' busy fraction over the run when SMT is on; 0 when SMT is off.
    BusySmtSiblings,
    /// Host-stall gaps at least `gap_periods` loop periods long, per second of probing.
    StallGapsPerS {
        /// The gap length counted, in loop periods.
        gap_periods: f64,
    },
    /// The wake-up probe's p99.9 latency, in loop periods.
    WakeupP999Periods,
    /// The wake-up probe's largest latency, in loop periods.
    WakeupMaxPeriods,
    /// The haptic loop's own deadline misses as a share of its ticks (at the judged rate).
    LoopMissShare,
    /// Seconds the haptic loop ran at the judged rate with no deadline missed and no tick
    /// skipped. Not a raise but a ceiling: above `above` seconds, the verdict is at most the
    /// row's grade, whatever the probes say.
    LoopMetEveryDeadline,
}

/// A grade that needs fixing: the only grades a finding with a fix can have.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Problem {
    /// Works, with occasional force glitches likely.
    Marginal,
    /// Not fit: ticks will be missed.
    Fail,
}

impl From<Problem> for Grade {
    fn from(p: Problem) -> Self {
        match p {
            Problem::Marginal => Self::Marginal,
            Problem::Fail => Self::Fail,
        }
    }
}

/// One threshold of the verdict: at rates above `above_rate_hz`, a `measure` above `above`
/// grades its finding `grade` (or, for [`Measure::LoopMetEveryDeadline`], caps the verdict at
/// it).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Threshold {
    /// What is measured.
    pub measure: Measure,
    /// The row applies to loop rates above this, Hz (0: every rate).
    pub above_rate_hz: f64,
    /// The measure's value must be above this, in the measure's unit.
    pub above: f64,
    /// The grade it gives.
    pub grade: Problem,
    /// Why this threshold, with the recorded figures behind it.
    pub why: &'static str,
}

/// Every threshold the verdict uses, and why. The recorded figures are from a 2-vCPU VM while
/// other builds ran on it (load average 4 to 6), as root: `dynaclay profile --seconds 5` at
/// 1 kHz (three runs, and one with `--load`) and at 4 kHz, and `cyclictest -m -p 90 -i 1000
/// -l 5000` and `-i 250 -l 20000`; docs/src/profiling.md ("How the verdict judges") has the
/// table of them.
pub const THRESHOLDS: [Threshold; 15] = [
    Threshold {
        measure: Measure::RtRefused,
        above_rate_hz: 0.0,
        above: 0.0,
        grade: Problem::Marginal,
        why: "without SCHED_FIFO every other thread competes with the haptic one; at 1 kHz \
              the scheduler's slices (a few ms) already exceed the period now and then",
    },
    Threshold {
        measure: Measure::RtRefused,
        above_rate_hz: 2000.0,
        above: 0.0,
        grade: Problem::Fail,
        why: "at 4 kHz the 250 µs period is shorter than one ordinary scheduler slice",
    },
    Threshold {
        measure: Measure::GovernorNotPerformance,
        above_rate_hz: 0.0,
        above: 0.0,
        grade: Problem::Marginal,
        why: "a clock ramping up after each sleep adds tens of µs to every wake-up",
    },
    Threshold {
        measure: Measure::NoIsolatedCore,
        above_rate_hz: 2000.0,
        above: 0.0,
        grade: Problem::Marginal,
        why: "at 4 kHz a shared core's interrupts and kernel threads take a good share of \
              the 250 µs period; at 1 kHz the stall and wake-up figures tell whether they \
              matter, so it is no finding there",
    },
    Threshold {
        measure: Measure::BusySmtSiblings,
        above_rate_hz: 2000.0,
        above: 0.5,
        grade: Problem::Marginal,
        why: "a busy sibling slows the haptic core's compute by up to half; it matters when \
              the period is short",
    },
    Threshold {
        measure: Measure::StallGapsPerS { gap_periods: 1.0 },
        above_rate_hz: 0.0,
        above: 1.0,
        grade: Problem::Fail,
        why: "a gap of a whole period or more holds the loop past its next deadline wherever \
              it lands: more than one a second is more than one missed tick a second. \
              Recorded at 1 kHz: a run whose probes saw 2 and 3 gaps a second of 1 ms \
              or more (longest 10.3 ms) had its loop miss 11 deadlines in 5037 ticks, 2.2 a \
              second: the gap rate foretold the miss rate",
    },
    Threshold {
        measure: Measure::StallGapsPerS { gap_periods: 1.0 },
        above_rate_hz: 0.0,
        above: 0.0,
        grade: Problem::Marginal,
        why: "any gap of a whole period is a tick missed when it comes; rarer than once a \
              second it is an occasional force glitch. Recorded: one gap of 1 ms or more in two seconds of probing \
              (53 ms long) beside a loop that missed 2 deadlines in 5035 ticks",
    },
    Threshold {
        measure: Measure::StallGapsPerS { gap_periods: 0.5 },
        above_rate_hz: 0.0,
        above: 10.0,
        grade: Problem::Marginal,
        why: "a gap of half a period leaves the tick half its budget; ten a second make a \
              miss likely whenever the tick's own work is long. The sum of short gaps is \
              not judged: 12.6 ms/s in gaps of at most 134 µs cost a 1 kHz loop no deadline \
              (period error max 79 µs). Recorded at 4 kHz: 36 gaps a second of 125 µs or more beside a loop that \
              missed 63 deadlines in 20111 ticks; at 1 kHz, 24.3 ms/s stolen in gaps of at most \
              198 µs, none of half the period",
    },
    Threshold {
        measure: Measure::WakeupP999Periods,
        above_rate_hz: 0.0,
        above: 0.5,
        grade: Problem::Fail,
        why: "one wake-up in a thousand half a period late leaves too little of the period \
              for the tick's work. Recorded: probe p99.9 of 278 to 1348 µs on the loaded VM, and every \
              1 kHz loop there missed deadlines (2 to 11 in about 5000 ticks); cyclictest -i 1000 \
              p99.9 378 µs on its best run",
    },
    Threshold {
        measure: Measure::WakeupMaxPeriods,
        above_rate_hz: 0.0,
        above: 2.0,
        grade: Problem::Fail,
        why: "a wake-up two periods late misses a deadline whatever the tick does. \
              Recorded: cyclictest max 2.8 to 3.5 ms at -i 1000 and 10.2 ms at -i 250; \
              the 4 kHz loop beside such wake-ups missed 63 deadlines in 20111 ticks",
    },
    Threshold {
        measure: Measure::WakeupP999Periods,
        above_rate_hz: 0.0,
        above: 0.1,
        grade: Problem::Marginal,
        why: "a tenth of the period lost one wake-up in a thousand is the margin a tick's \
              work normally leaves",
    },
    Threshold {
        measure: Measure::WakeupMaxPeriods,
        above_rate_hz: 0.0,
        above: 1.0,
        grade: Problem::Marginal,
        why: "a wake-up a whole period late is a missed deadline when it comes",
    },
    Threshold {
        measure: Measure::LoopMissShare,
        above_rate_hz: 0.0,
        above: 1e-3,
        grade: Problem::Fail,
        why: "more than one tick in a thousand late is a force glitch every second at 1 kHz",
    },
    Threshold {
        measure: Measure::LoopMissShare,
        above_rate_hz: 0.0,
        above: 0.0,
        grade: Problem::Marginal,
        why: "the loop itself missed a deadline: whatever the probes say, it happens here",
    },
    Threshold {
        measure: Measure::LoopMetEveryDeadline,
        above_rate_hz: 0.0,
        above: 1.0,
        grade: Problem::Marginal,
        why: "the loop's own record outweighs the probes: a machine on which it met every \
              deadline for over a second (a thousand ticks at 1 kHz) is at worst marginal \
              for that rate. The probes still say how close it came",
    },
];

/// The haptic loop's own record, from a run at one rate: the fact that outweighs the probes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct LoopRecord {
    /// The rate the loop ran at, Hz.
    pub rate_hz: f64,
    /// Ticks recorded.
    pub ticks: u64,
    /// Seconds between the first and the last tick.
    pub elapsed_s: f64,
    /// Ticks whose work ended after the next tick was due.
    pub deadline_misses: u64,
    /// Ticks dropped after an overrun.
    pub skipped_ticks: u64,
    /// Period error p99.9, µs.
    pub period_error_p999_us: f64,
    /// Largest period error, µs.
    pub period_error_max_us: f64,
    /// Latest wake-up, µs after its scheduled time.
    pub lateness_max_us: f64,
    /// Longest tick body, µs.
    pub compute_max_us: f64,
}

impl LoopRecord {
    /// The record of a loop with `stats`.
    #[must_use]
    pub fn from_stats(stats: &LatencyStats) -> Self {
        Self {
            rate_hz: stats.nominal_rate_hz,
            ticks: stats.ticks,
            elapsed_s: stats.elapsed_s,
            deadline_misses: stats.deadline_misses,
            skipped_ticks: stats.skipped_ticks,
            period_error_p999_us: stats.period_error.p999_us,
            period_error_max_us: stats.period_error.max_us,
            lateness_max_us: stats.lateness.max_us,
            compute_max_us: stats.compute.max_us,
        }
    }

    /// Whether the loop ran at `rate_hz` (to half a hertz).
    #[must_use]
    pub fn ran_at(&self, rate_hz: f64) -> bool {
        (self.rate_hz - rate_hz).abs() < 0.5
    }

    /// Whether it missed no deadline and skipped no tick.
    #[must_use]
    pub fn met_every_deadline(&self) -> bool {
        self.ticks > 0 && self.deadline_misses == 0 && self.skipped_ticks == 0
    }
}

/// What is known about the machine; `None` is "unknown". Fields added after the first
/// `latency.json` default to `None`, so older documents still load.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct PlatformFacts {
    /// Whether the haptic thread got real-time priority.
    pub rt_granted: Option<bool>,
    /// The distinct CPU frequency governors in use (`cpufreq/scaling_governor`).
    pub governors: Option<Vec<String>>,
    /// Whether any core is isolated (`/sys/devices/system/cpu/isolated` not empty, or
    /// `isolcpus=`/`nohz_full=` on the kernel command line).
    pub isolated_core: Option<bool>,
    /// `/proc/sys/kernel/sched_rt_runtime_us`: −1 means real-time threads are never throttled.
    pub rt_runtime_us: Option<i64>,
    /// `/proc/sys/kernel/sched_rt_period_us`.
    pub rt_period_us: Option<i64>,
    /// Whether SMT (hyper-threading) is on (`/sys/devices/system/cpu/smt/active`).
    pub smt_active: Option<bool>,
    /// Fraction of all CPU time that was busy during the run (from `/proc/stat`).
    pub cpu_busy_fraction: Option<f64>,
    /// Time taken away from the stall probe, ms per second (the worse probe run). Shown, not
    /// judged: many short gaps add up without endangering a deadline.
    pub stall_ms_per_s: Option<f64>,
    /// The wake-up probe's p99.9 latency, µs (the worse probe run).
    pub wakeup_p999_us: Option<f64>,
    /// The wake-up probe's largest latency, µs (the worse probe run).
    pub wakeup_max_us: Option<f64>,
    /// The stall probe's figures, every probe run taken as one: the longest gap and the gaps
    /// by length, which the verdict judges against the period.
    #[serde(default)]
    pub stalls: Option<StallStats>,
    /// The haptic loop's own record, when it ran.
    #[serde(default)]
    pub haptic_loop: Option<LoopRecord>,
}

/// How far a reason goes against a rate.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Grade {
    /// Fit.
    Pass,
    /// Works, with occasional force glitches likely.
    Marginal,
    /// Not fit: ticks will be missed.
    Fail,
}

impl fmt::Display for Grade {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::Pass => "pass",
            Self::Marginal => "marginal",
            Self::Fail => "fail",
        })
    }
}

/// One reason behind a verdict. Only a [`Problem`] carries a fix: a passing finding (an
/// advisory or an unknown fact) is built by [`Finding::advisory`], which takes none, and a
/// passing finding read from JSON drops any fix it had.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(from = "FindingRecord")]
pub struct Finding {
    grade: Grade,
    reason: String,
    fix: String,
}

/// A finding as JSON holds it (`fix` empty when there is none).
#[derive(Deserialize)]
struct FindingRecord {
    grade: Grade,
    reason: String,
    #[serde(default)]
    fix: String,
}

impl From<FindingRecord> for Finding {
    fn from(r: FindingRecord) -> Self {
        Self {
            grade: r.grade,
            fix: if r.grade == Grade::Pass {
                String::new()
            } else {
                r.fix
            },
            reason: r.reason,
        }
    }
}

impl Finding {
    /// A finding that needs fixing.
    #[must_use]
    pub fn problem(grade: Problem, reason: impl Into<String>, fix: impl Into<String>) -> Self {
        Self {
            grade: grade.into(),
            reason: reason.into(),
            fix: fix.into(),
        }
    }

    /// A passing finding: something worth knowing, or an unknown fact. It has no fix.
    #[must_use]
    pub fn advisory(reason: impl Into<String>) -> Self {
        Self {
            grade: Grade::Pass,
            reason: reason.into(),
            fix: String::new(),
        }
    }

    /// How far it goes against the rate.
    #[must_use]
    pub fn grade(&self) -> Grade {
        self.grade
    }

    /// What was found.
    #[must_use]
    pub fn reason(&self) -> &str {
        &self.reason
    }

    /// How to fix it: `None` for a passing finding, never an empty fix.
    #[must_use]
    pub fn fix(&self) -> Option<&str> {
        (self.grade != Grade::Pass && !self.fix.is_empty()).then_some(self.fix.as_str())
    }

    /// Caps a failing finding at marginal, saying why in its reason.
    fn cap_at_marginal(&mut self, because: &str) {
        if self.grade == Grade::Fail {
            self.grade = Grade::Marginal;
            self.reason = format!("{} ({because})", self.reason);
        }
    }
}

/// The verdict for one loop rate.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Verdict {
    /// The rate judged, Hz.
    pub rate_hz: f64,
    /// The worst grade among the findings.
    pub grade: Grade,
    /// Every finding, worst first.
    pub findings: Vec<Finding>,
}

fn unknown(what: &str) -> Finding {
    Finding::advisory(format!("{what}: unknown"))
}

/// The worst row of `measure`'s family that applies at `rate_hz` and that `value_of` puts
/// above its threshold, with the value. `value_of` gives `None` for rows of other measures
/// and for unknown values.
fn worst_row(
    rate_hz: f64,
    value_of: impl Fn(&Measure) -> Option<f64>,
) -> Option<(&'static Threshold, f64)> {
    THRESHOLDS
        .iter()
        .filter(|t| rate_hz > t.above_rate_hz)
        .filter_map(|t| value_of(&t.measure).map(|v| (t, v)))
        .filter(|(t, v)| *v > t.above)
        // NOTE: max_by_key keeps the last of equals; the table lists the worse rows first,
        // so rev() makes the first worst row win.
        .rev()
        .max_by_key(|(t, _)| t.grade)
}

fn flag(b: bool) -> f64 {
    if b { 1.0 } else { 0.0 }
}

/// Judges `facts` for a loop at `rate_hz`. Pure. Every threshold is a row of
/// [`THRESHOLDS`]; when the haptic loop's own record shows it met every deadline at this rate
/// for long enough, no finding fails (see [`Measure::LoopMetEveryDeadline`]).
#[must_use]
pub fn verdict(facts: &PlatformFacts, rate_hz: f64) -> Verdict {
    let period_us = 1e6 / rate_hz.max(1.0);
    let mut findings = Vec::new();

    match facts.rt_granted {
        Some(granted) => {
            if let Some((row, _)) = worst_row(rate_hz, |m| {
                (*m == Measure::RtRefused).then_some(flag(!granted))
            }) {
                findings.push(Finding::problem(
                    row.grade,
                    "real-time priority not granted: any other thread can delay the haptic loop",
                    "run as root, grant CAP_SYS_NICE (sudo setcap cap_sys_nice+ep $(which \
                     dynaclay)), or add `<user> - rtprio 99` to /etc/security/limits.conf and \
                     log in again",
                ));
            }
        }
        None => findings.push(unknown("real-time priority")),
    }

    match &facts.governors {
        Some(g) if g.is_empty() => findings.push(unknown("CPU frequency governor")),
        Some(g) => {
            let slow = g.iter().any(|g| g != "performance");
            if let Some((row, _)) = worst_row(rate_hz, |m| {
                (*m == Measure::GovernorNotPerformance).then_some(flag(slow))
            }) {
                findings.push(Finding::problem(
                    row.grade,
                    format!(
                        "CPU frequency governor is {} not performance: wake-ups pay for clock \
                         ramp-up",
                        g.join(", ")
                    ),
                    "sudo cpupower frequency-set -g performance (or write `performance` to \
                     /sys/devices/system/cpu/cpu*/cpufreq/scaling_governor)",
                ));
            }
        }
        None => findings.push(unknown("CPU frequency governor")),
    }

    match facts.isolated_core {
        Some(isolated) => {
            if let Some((row, _)) = worst_row(rate_hz, |m| {
                (*m == Measure::NoIsolatedCore).then_some(flag(!isolated))
            }) {
                findings.push(Finding::problem(
                    row.grade,
                    "no isolated core: the haptic thread shares its core with everything else",
                    "boot with isolcpus=N nohz_full=N (one spare core) and pin the haptic loop \
                     to it",
                ));
            }
        }
        None => findings.push(unknown("core isolation")),
    }

    stall_finding(facts, rate_hz, period_us, &mut findings);

    match (facts.wakeup_p999_us, facts.wakeup_max_us) {
        (Some(p999), Some(max)) => {
            if let Some((row, _)) = worst_row(rate_hz, |m| match m {
                Measure::WakeupP999Periods => Some(p999 / period_us),
                Measure::WakeupMaxPeriods => Some(max / period_us),
                _ => None,
            }) {
                findings.push(Finding::problem(
                    row.grade,
                    format!(
                        "wake-up latency p99.9 {p999:.0} µs, max {max:.0} µs against a \
                         {period_us:.0} µs period"
                    ),
                    "see the other reasons; a kernel with PREEMPT_RT shortens wake-ups",
                ));
            }
        }
        _ => findings.push(unknown("wake-up latency")),
    }

    match (facts.rt_runtime_us, facts.rt_period_us) {
        (Some(-1), _) => {}
        (Some(runtime), period) => findings.push(Finding::advisory(format!(
            "RT throttling on: real-time threads get at most {runtime} µs per {} µs; only a \
             busy-waiting loop reaches it (sudo sysctl kernel.sched_rt_runtime_us=-1 lifts it)",
            period.map_or_else(|| "unknown".to_string(), |p| p.to_string())
        ))),
        (None, _) => findings.push(unknown("RT throttling")),
    }

    match (facts.smt_active, facts.cpu_busy_fraction) {
        (Some(false), _) => {}
        (Some(true), Some(busy)) => {
            if let Some((row, _)) = worst_row(rate_hz, |m| {
                (*m == Measure::BusySmtSiblings).then_some(busy)
            }) {
                findings.push(Finding::problem(
                    row.grade,
                    format!(
                        "SMT siblings busy: SMT is on and the CPUs were {:.0}% busy, so the \
                         haptic core's sibling was likely busy",
                        busy * 100.0
                    ),
                    "turn SMT off (echo off | sudo tee /sys/devices/system/cpu/smt/control) or \
                     keep the haptic core's sibling idle",
                ));
            }
        }
        (None, _) | (Some(true), None) => findings.push(unknown("SMT siblings")),
    }

    if let Some(record) = facts.haptic_loop.filter(|r| r.ran_at(rate_hz)) {
        loop_findings(&record, rate_hz, period_us, &mut findings);
    }

    findings.sort_by_key(|f| std::cmp::Reverse(f.grade));
    Verdict {
        rate_hz,
        grade: findings.first().map_or(Grade::Pass, |f| f.grade),
        findings,
    }
}

/// The host-stall finding: gaps as long as a good part of the period, per second.
fn stall_finding(facts: &PlatformFacts, rate_hz: f64, period_us: f64, out: &mut Vec<Finding>) {
    let Some(stalls) = facts.stalls else {
        out.push(match facts.stall_ms_per_s {
            Some(ms) => Finding::advisory(format!(
                "host stalls: {ms:.1} ms per second, gap lengths not recorded (an older record)"
            )),
            None => unknown("host stalls"),
        });
        return;
    };
    let per_s_at_least = |gap_us: f64| {
        stalls.gaps_at_least_per_s(gap_us).or(
            // An older record without the gaps by length: none reached a length longer than
            // its longest gap; otherwise unknown.
            (stalls.max_gap_us < gap_us).then_some(0.0),
        )
    };
    let worst = worst_row(rate_hz, |m| match m {
        Measure::StallGapsPerS { gap_periods } => per_s_at_least(gap_periods * period_us),
        _ => None,
    });
    if let Some((row, per_s)) = worst {
        let Measure::StallGapsPerS { gap_periods } = row.measure else {
            return;
        };
        out.push(Finding::problem(
            row.grade,
            format!(
                "host stalls up to {:.0} µs: {per_s:.1} a second of {:.0} µs or more ({} of \
                 the {period_us:.0} µs period)",
                stalls.max_gap_us,
                gap_periods * period_us,
                period_fraction(gap_periods),
            ),
            stall_fix(),
        ));
    } else if stalls.gap_counts.is_none() && stalls.max_gap_us >= period_us * 0.5 {
        out.push(Finding::advisory(format!(
            "host stalls up to {:.0} µs, how often unknown (an older record)",
            stalls.max_gap_us
        )));
    }
}

fn period_fraction(periods: f64) -> String {
    if (periods - 1.0).abs() < 1e-9 {
        "all".into()
    } else if (periods - 0.5).abs() < 1e-9 {
        "half".into()
    } else {
        format!("{periods:.2}×")
    }
}

/// The haptic loop's own record at this rate: its misses, or that it met every deadline.
fn loop_findings(record: &LoopRecord, rate_hz: f64, period_us: f64, out: &mut Vec<Finding>) {
    let miss_share = if record.ticks > 0 {
        record.deadline_misses as f64 / record.ticks as f64
    } else {
        0.0
    };
    if let Some((row, _)) = worst_row(rate_hz, |m| {
        (*m == Measure::LoopMissShare).then_some(miss_share)
    }) {
        out.push(Finding::problem(
            row.grade,
            format!(
                "the haptic loop missed {} deadline{} in {} ticks at {rate_hz:.0} Hz",
                record.deadline_misses,
                if record.deadline_misses == 1 { "" } else { "s" },
                record.ticks
            ),
            "find the cause among the other reasons; if none shows, the tick's work is too \
             long for the period (see compute in the loop table)",
        ));
        return;
    }
    let clean_s = if record.met_every_deadline() {
        record.elapsed_s
    } else {
        0.0
    };
    let worst_wake_and_work_us = record.lateness_max_us + record.compute_max_us;
    let margin = if worst_wake_and_work_us < period_us {
        format!(
            "margin at least {:.0} µs of the {period_us:.0} µs period (latest wake-up {:.0} µs, \
             longest tick {:.0} µs)",
            period_us - worst_wake_and_work_us,
            record.lateness_max_us,
            record.compute_max_us
        )
    } else {
        format!(
            "latest wake-up {:.0} µs and longest tick {:.0} µs, never in the same tick, \
             against the {period_us:.0} µs period",
            record.lateness_max_us, record.compute_max_us
        )
    };
    let summary = format!(
        "the haptic loop met every deadline: {} ticks over {:.1} s, period error p99.9 {:.0} \
         µs, max {:.0} µs; {margin}",
        record.ticks, record.elapsed_s, record.period_error_p999_us, record.period_error_max_us
    );
    match worst_row(rate_hz, |m| {
        (*m == Measure::LoopMetEveryDeadline).then_some(clean_s)
    }) {
        Some((row, _)) if row.grade == Problem::Marginal => {
            let capped = out.iter().any(|f| f.grade == Grade::Fail);
            for f in out.iter_mut() {
                f.cap_at_marginal("yet the haptic loop met every deadline");
            }
            out.push(if capped {
                Finding::problem(
                    Problem::Marginal,
                    format!("{summary}, though the probes found the machine unfit"),
                    "the other reasons' fixes widen the margin",
                )
            } else {
                Finding::advisory(summary)
            });
        }
        _ if record.met_every_deadline() => out.push(Finding::advisory(format!(
            "{summary} (too short a run to outweigh the probes)"
        ))),
        _ => {}
    }
}

fn stall_fix() -> &'static str {
    "on a VM, give it dedicated vCPUs (CPU pinning on the host, no overcommit); on bare metal, \
     look for SMIs or interrupt storms (irqbalance, BIOS power settings)"
}

/// The verdicts as text, one block per rate. Only a finding that needs fixing has a fix line.
#[must_use]
pub fn verdict_text(verdicts: &[Verdict]) -> String {
    use fmt::Write as _;
    let mut out = String::new();
    for v in verdicts {
        let _ = writeln!(out, "{:.0} Hz: {}", v.rate_hz, v.grade);
        for f in &v.findings {
            let _ = writeln!(out, "  [{}] {}", f.grade, f.reason);
            if let Some(fix) = f.fix() {
                let _ = writeln!(out, "      fix: {fix}");
            }
        }
    }
    out
}

/// The verdicts in one plain line: "this machine is fine for 1 kHz haptics", or the first
/// rate it is not fit for and its worst reason ("not suited for 4 kHz: host stalls up to …").
#[must_use]
pub fn plain_summary(verdicts: &[Verdict]) -> String {
    let khz = |v: &Verdict| {
        let k = v.rate_hz / 1000.0;
        if (k - k.round()).abs() < 1e-9 {
            format!("{k:.0} kHz")
        } else {
            format!("{:.0} Hz", v.rate_hz)
        }
    };
    let mut by_rate: Vec<&Verdict> = verdicts.iter().collect();
    by_rate.sort_by(|a, b| a.rate_hz.total_cmp(&b.rate_hz));
    let fine = by_rate
        .iter()
        .rev()
        .find(|v| v.grade == Grade::Pass)
        .map(|v| format!("this machine is fine for {} haptics", khz(v)));
    let not_fine = by_rate.iter().find(|v| v.grade != Grade::Pass).map(|v| {
        let what = if v.grade == Grade::Fail {
            "not suited for"
        } else {
            "marginal for"
        };
        let why = v.findings.first().map_or("", |f| f.reason.as_str());
        format!("{what} {}: {why}", khz(v))
    });
    match (fine, not_fine) {
        (Some(a), Some(b)) => format!("{a}; {b}"),
        (Some(a), None) => a,
        (None, Some(b)) => b,
        (None, None) => "not judged yet".into(),
    }
}

/// Reads at most [`FACT_FILE_CAP`] bytes of a text file; `None` if it is missing or unreadable.
#[must_use]
pub fn read_fact_file(path: &Path) -> Option<String> {
    let file = std::fs::File::open(path).ok()?;
    let mut text = String::new();
    file.take(FACT_FILE_CAP).read_to_string(&mut text).ok()?;
    Some(text)
}

/// Busy and total jiffies of all CPUs, from `/proc/stat`'s first line.
#[must_use]
pub fn cpu_jiffies() -> Option<(u64, u64)> {
    parse_cpu_jiffies(&read_fact_file(Path::new("/proc/stat"))?)
}

fn parse_cpu_jiffies(stat: &str) -> Option<(u64, u64)> {
    let line = stat.lines().find(|l| l.starts_with("cpu "))?;
    let fields: Vec<u64> = line
        .split_whitespace()
        .skip(1)
        .map(|f| f.parse().ok())
        .collect::<Option<_>>()?;
    let total: u64 = fields.iter().sum();
    // idle and iowait are the 4th and 5th fields.
    let idle = fields.get(3).copied().unwrap_or(0) + fields.get(4).copied().unwrap_or(0);
    Some((total.saturating_sub(idle), total))
}

/// Busy fraction between two [`cpu_jiffies`] samples.
#[must_use]
pub fn busy_fraction(before: (u64, u64), after: (u64, u64)) -> Option<f64> {
    let busy = after.0.checked_sub(before.0)?;
    let total = after.1.checked_sub(before.1)?;
    (total > 0).then(|| busy as f64 / total as f64)
}

fn isolation_from(isolated: Option<&str>, cmdline: Option<&str>) -> Option<bool> {
    let by_sys = isolated.map(|s| !s.trim().is_empty());
    let by_cmdline = cmdline.map(|c| {
        c.split_whitespace()
            .any(|a| a.starts_with("isolcpus=") || a.starts_with("nohz_full="))
    });
    match (by_sys, by_cmdline) {
        (Some(a), Some(b)) => Some(a || b),
        (a, b) => a.or(b),
    }
}

fn read_i64(path: &str) -> Option<i64> {
    read_fact_file(Path::new(path))?.trim().parse().ok()
}

fn read_governors() -> Option<Vec<String>> {
    let dir = std::fs::read_dir("/sys/devices/system/cpu").ok()?;
    let mut governors: Vec<String> = Vec::new();
    // NOTE: the directory lists one entry per CPU plus a few others; bounded by the CPU count.
    for entry in dir.flatten().take(4096) {
        let name = entry.file_name();
        let is_cpu = name
            .to_str()
            .and_then(|n| n.strip_prefix("cpu"))
            .is_some_and(|n| !n.is_empty() && n.bytes().all(|b| b.is_ascii_digit()));
        if !is_cpu {
            continue;
        }
        if let Some(g) = read_fact_file(&entry.path().join("cpufreq/scaling_governor")) {
            let g = g.trim().to_string();
            if !governors.contains(&g) {
                governors.push(g);
            }
        }
    }
    // No cpufreq at all (common on VMs): unknown rather than "no governor".
    (!governors.is_empty()).then_some(governors)
}

/// Reads the machine's facts from `/proc` and `/sys`. The run-time facts (real-time priority
/// granted, busy fraction, probe figures) are left `None` for the caller to fill in.
#[must_use]
pub fn read_platform_facts() -> PlatformFacts {
    let isolated = read_fact_file(Path::new("/sys/devices/system/cpu/isolated"));
    let cmdline = read_fact_file(Path::new("/proc/cmdline"));
    PlatformFacts {
        governors: read_governors(),
        isolated_core: isolation_from(isolated.as_deref(), cmdline.as_deref()),
        rt_runtime_us: read_i64("/proc/sys/kernel/sched_rt_runtime_us"),
        rt_period_us: read_i64("/proc/sys/kernel/sched_rt_period_us"),
        smt_active: read_i64("/sys/devices/system/cpu/smt/active").map(|v| v != 0),
        ..PlatformFacts::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::probe::GapCounts;

    /// The stall probe's figures for `seconds` of spinning with `gaps_us` (each at least the
    /// 20 µs threshold) taken away.
    fn stalls(seconds: f64, gaps_us: &[u64]) -> StallStats {
        let mut counts = GapCounts::default();
        for &gap in gaps_us {
            counts.add(gap * 1000);
        }
        StallStats {
            seconds,
            gap_threshold_us: 20.0,
            gaps: gaps_us.len() as u64,
            stolen_ms: gaps_us.iter().sum::<u64>() as f64 / 1e3,
            max_gap_us: gaps_us.iter().copied().max().unwrap_or(0) as f64,
            gap_counts: Some(counts),
        }
    }

    fn fit() -> PlatformFacts {
        PlatformFacts {
            rt_granted: Some(true),
            governors: Some(vec!["performance".into()]),
            isolated_core: Some(true),
            rt_runtime_us: Some(-1),
            rt_period_us: Some(1_000_000),
            smt_active: Some(false),
            cpu_busy_fraction: Some(0.9),
            stall_ms_per_s: Some(0.1),
            wakeup_p999_us: Some(20.0),
            wakeup_max_us: Some(60.0),
            stalls: Some(stalls(1.0, &[25, 40])),
            haptic_loop: None,
        }
    }

    /// A haptic loop at `rate_hz` for `seconds` with `misses` deadline misses.
    fn haptic(rate_hz: f64, seconds: f64, misses: u64) -> LoopRecord {
        LoopRecord {
            rate_hz,
            ticks: (rate_hz * seconds) as u64,
            elapsed_s: seconds,
            deadline_misses: misses,
            skipped_ticks: 0,
            period_error_p999_us: 35.0,
            period_error_max_us: 79.0,
            lateness_max_us: 70.0,
            compute_max_us: 40.0,
        }
    }

    fn grades(f: &PlatformFacts) -> (Grade, Grade) {
        (verdict(f, 1000.0).grade, verdict(f, 4000.0).grade)
    }

    fn reasons(f: &PlatformFacts, rate: f64) -> String {
        verdict(f, rate)
            .findings
            .iter()
            .map(|f| format!("{}|{}\n", f.reason(), f.fix().unwrap_or("")))
            .collect()
    }

    #[test]
    fn a_fit_machine_passes_both_rates_with_no_findings() {
        assert_eq!(grades(&fit()), (Grade::Pass, Grade::Pass));
        assert!(verdict(&fit(), 1000.0).findings.is_empty());
        assert!(verdict(&fit(), 4000.0).findings.is_empty());
    }

    #[test]
    fn rt_not_granted_is_marginal_at_1k_and_fails_at_4k() {
        let f = PlatformFacts {
            rt_granted: Some(false),
            ..fit()
        };
        assert_eq!(grades(&f), (Grade::Marginal, Grade::Fail));
        let r = reasons(&f, 1000.0);
        assert!(r.contains("CAP_SYS_NICE") && r.contains("rtprio"), "{r}");
    }

    #[test]
    fn governor_not_performance_is_marginal() {
        let f = PlatformFacts {
            governors: Some(vec!["powersave".into(), "performance".into()]),
            ..fit()
        };
        assert_eq!(grades(&f), (Grade::Marginal, Grade::Marginal));
        assert!(reasons(&f, 1000.0).contains("powersave"));
    }

    #[test]
    fn no_isolated_core_matters_at_4k_only() {
        let f = PlatformFacts {
            isolated_core: Some(false),
            ..fit()
        };
        assert_eq!(grades(&f), (Grade::Pass, Grade::Marginal));
        // At 1 kHz it is no finding at all: no "[pass] … fix: isolcpus".
        assert!(!reasons(&f, 1000.0).contains("isolcpus"));
        assert!(reasons(&f, 4000.0).contains("isolcpus"));
    }

    /// The reported run: 12.6 ms/s stolen in gaps of at most 134 µs, while the haptic loop
    /// met every deadline (period error p99.9 35 µs, max 79 µs).
    fn reported_case() -> PlatformFacts {
        // 100 gaps of 126 µs (one of them 134 µs, one 118 µs): 12.6 ms in one second.
        let mut gaps = vec![126u64; 98];
        gaps.extend([134, 118]);
        let stalls = stalls(1.0, &gaps);
        PlatformFacts {
            stall_ms_per_s: Some(stalls.stolen_ms_per_s()),
            stalls: Some(stalls),
            isolated_core: Some(false),
            haptic_loop: Some(haptic(1000.0, 10.0, 0)),
            ..fit()
        }
    }

    #[test]
    fn many_short_stalls_do_not_fail_a_loop_that_met_every_deadline() {
        let f = reported_case();
        let stolen = f.stall_ms_per_s.expect("stolen");
        assert!((stolen - 12.6).abs() < 0.05, "{stolen}");
        let v = verdict(&f, 1000.0);
        assert_eq!(
            v.grade,
            Grade::Pass,
            "{}",
            verdict_text(std::slice::from_ref(&v))
        );
        let text = verdict_text(&[v]);
        assert!(text.contains("met every deadline"), "{text}");
        assert!(!text.contains("fix:"), "{text}");
        // The short stalls alone, without the loop's record, pass 1 kHz too.
        let probes_only = PlatformFacts {
            haptic_loop: None,
            ..f.clone()
        };
        assert_eq!(verdict(&probes_only, 1000.0).grade, Grade::Pass);
        // At 4 kHz, 134 µs is more than half the 250 µs period, a hundred times a second.
        let v4 = verdict(&probes_only, 4000.0);
        assert_eq!(v4.grade, Grade::Marginal);
        assert!(
            v4.findings.iter().any(|f| f
                .reason()
                .contains("host stalls up to 134 µs: 99.0 a second")),
            "{:?}",
            v4.findings
        );
    }

    #[test]
    fn a_loop_that_met_every_deadline_caps_failing_probes_at_marginal() {
        // The probes alone fail 1 kHz (wake-ups 2.5 ms late, gaps of 2 ms).
        let bad = PlatformFacts {
            wakeup_p999_us: Some(581.0),
            wakeup_max_us: Some(2500.0),
            stalls: Some(stalls(1.0, &[2000, 2000, 2000, 2000, 2000])),
            ..fit()
        };
        assert_eq!(verdict(&bad, 1000.0).grade, Grade::Fail);
        let clean = PlatformFacts {
            haptic_loop: Some(haptic(1000.0, 10.0, 0)),
            ..bad.clone()
        };
        let v = verdict(&clean, 1000.0);
        assert_eq!(v.grade, Grade::Marginal);
        assert!(v.findings.iter().all(|f| f.grade() < Grade::Fail));
        let text = verdict_text(&[v]);
        assert!(
            text.contains("met every deadline: 10000 ticks over 10.0 s")
                && text.contains("margin at least 890 µs of the 1000 µs period"),
            "{text}"
        );
        assert!(
            text.contains("yet the haptic loop met every deadline"),
            "{text}"
        );
        // The record is of a 1 kHz run: it says nothing of 4 kHz.
        assert_eq!(verdict(&clean, 4000.0).grade, Grade::Fail);
        // A run too short to outweigh the probes does not cap them.
        let short = PlatformFacts {
            haptic_loop: Some(haptic(1000.0, 0.5, 0)),
            ..bad
        };
        assert_eq!(verdict(&short, 1000.0).grade, Grade::Fail);
        assert!(reasons(&short, 1000.0).contains("too short a run"));
    }

    #[test]
    fn a_loop_that_missed_deadlines_is_judged_by_how_many() {
        let few = PlatformFacts {
            haptic_loop: Some(haptic(1000.0, 10.0, 3)),
            ..fit()
        };
        assert_eq!(verdict(&few, 1000.0).grade, Grade::Marginal);
        assert!(reasons(&few, 1000.0).contains("missed 3 deadlines in 10000 ticks"));
        let many = PlatformFacts {
            haptic_loop: Some(haptic(1000.0, 10.0, 11)),
            ..fit()
        };
        assert_eq!(verdict(&many, 1000.0).grade, Grade::Fail);
    }

    #[test]
    fn long_gaps_several_times_a_second_fail_1k() {
        let f = PlatformFacts {
            stalls: Some(stalls(1.0, &[2000, 2100, 1900, 2000, 2000])),
            ..fit()
        };
        assert_eq!(grades(&f), (Grade::Fail, Grade::Fail));
        let r = reasons(&f, 1000.0);
        assert!(
            r.contains("host stalls up to 2100 µs: 5.0 a second of 1000 µs or more"),
            "{r}"
        );
        assert!(r.contains("dedicated vCPUs"), "{r}");
        // One such gap in the run is an occasional glitch, not a failure.
        let once = PlatformFacts {
            stalls: Some(stalls(2.0, &[2000])),
            ..fit()
        };
        assert_eq!(grades(&once), (Grade::Marginal, Grade::Marginal));
    }

    #[test]
    fn gaps_are_judged_against_the_shorter_4k_period() {
        // 300 µs gaps three times a second: under half the 1 kHz period, more than the whole
        // 4 kHz period.
        let f = PlatformFacts {
            stalls: Some(stalls(1.0, &[300, 300, 300])),
            ..fit()
        };
        assert_eq!(grades(&f), (Grade::Pass, Grade::Fail));
        assert!(reasons(&f, 4000.0).contains("of 250 µs or more (all of the 250 µs period)"));
        // 150 µs gaps twenty times a second: half the 4 kHz period, often.
        let g = PlatformFacts {
            stalls: Some(stalls(1.0, &[150; 20])),
            ..fit()
        };
        assert_eq!(grades(&g), (Grade::Pass, Grade::Marginal));
        // Five of them a second are fine at both rates.
        let h = PlatformFacts {
            stalls: Some(stalls(1.0, &[150; 5])),
            ..fit()
        };
        assert_eq!(grades(&h), (Grade::Pass, Grade::Pass));
    }

    #[test]
    fn wakeup_latency_is_judged_against_the_period() {
        // The VM figures: p99.9 581 µs, max 2.5 ms.
        let f = PlatformFacts {
            wakeup_p999_us: Some(581.0),
            wakeup_max_us: Some(2500.0),
            ..fit()
        };
        assert_eq!(grades(&f), (Grade::Fail, Grade::Fail));
        let g = PlatformFacts {
            wakeup_p999_us: Some(40.0),
            wakeup_max_us: Some(400.0),
            ..fit()
        };
        assert_eq!(grades(&g), (Grade::Pass, Grade::Marginal));
    }

    #[test]
    fn old_facts_without_the_new_fields_still_load_and_judge() {
        let old = r#"{
            "rt_granted": true, "governors": ["performance"], "isolated_core": false,
            "rt_runtime_us": -1, "rt_period_us": 1000000, "smt_active": false,
            "cpu_busy_fraction": 0.2, "stall_ms_per_s": 12.6,
            "wakeup_p999_us": 30.0, "wakeup_max_us": 120.0
        }"#;
        let f: PlatformFacts = serde_json::from_str(old).expect("old facts load");
        assert_eq!((f.stalls, f.haptic_loop), (None, None));
        let v = verdict(&f, 1000.0);
        // The stolen time alone is no reason to fail: it is reported, not judged.
        assert_eq!(v.grade, Grade::Pass);
        let text = verdict_text(&[v]);
        assert!(
            text.contains("host stalls: 12.6 ms per second, gap lengths not recorded"),
            "{text}"
        );
        // An older verdict with a "[pass] … fix:" finding loads without the fix.
        let finding: Finding = serde_json::from_str(
            r#"{"grade": "pass", "reason": "no isolated core", "fix": "boot with isolcpus"}"#,
        )
        .expect("finding");
        assert_eq!(finding.fix(), None);
        let problem: Finding = serde_json::from_str(
            r#"{"grade": "fail", "reason": "host stalls", "fix": "pin vCPUs"}"#,
        )
        .expect("finding");
        assert_eq!(problem.fix(), Some("pin vCPUs"));
    }

    #[test]
    fn old_stall_figures_without_bins_judge_by_the_longest_gap() {
        let short = StallStats {
            gap_counts: None,
            ..stalls(1.0, &[134; 100])
        };
        let f = PlatformFacts {
            stalls: Some(short),
            ..fit()
        };
        // No gap reached half of 1 ms: nothing to say at 1 kHz.
        assert_eq!(verdict(&f, 1000.0).grade, Grade::Pass);
        assert!(verdict(&f, 1000.0).findings.is_empty());
        // At 4 kHz how often is unknown: said, not graded.
        let v4 = verdict(&f, 4000.0);
        assert_eq!(v4.grade, Grade::Pass);
        assert!(reasons(&f, 4000.0).contains("how often unknown"));
    }

    /// Every combination of the facts' states, at both rates: no passing finding has a fix,
    /// and the text prints no fix under a pass.
    #[test]
    fn no_passing_finding_ever_carries_a_fix() {
        let bools = [None, Some(false), Some(true)];
        let stall_cases = [
            None,
            Some(stalls(1.0, &[25])),
            Some(stalls(1.0, &[150; 20])),
            Some(stalls(1.0, &[2000; 5])),
            Some(StallStats {
                gap_counts: None,
                ..stalls(1.0, &[300])
            }),
        ];
        let loops = [
            None,
            Some(haptic(1000.0, 10.0, 0)),
            Some(haptic(1000.0, 0.5, 0)),
            Some(haptic(4000.0, 10.0, 2)),
        ];
        let mut seen = [0usize; 3];
        for rt in bools {
            for isolated in bools {
                for smt in bools {
                    for stalls in &stall_cases {
                        for haptic_loop in loops {
                            for (governor, runtime, wake) in [
                                (None, None, None),
                                (Some("powersave"), Some(950_000), Some((581.0, 2500.0))),
                                (Some("performance"), Some(-1), Some((20.0, 60.0))),
                            ] {
                                let f = PlatformFacts {
                                    rt_granted: rt,
                                    governors: governor.map(|g| vec![g.to_string()]),
                                    isolated_core: isolated,
                                    rt_runtime_us: runtime,
                                    rt_period_us: Some(1_000_000),
                                    smt_active: smt,
                                    cpu_busy_fraction: Some(0.9),
                                    stall_ms_per_s: Some(12.6),
                                    wakeup_p999_us: wake.map(|w| w.0),
                                    wakeup_max_us: wake.map(|w| w.1),
                                    stalls: *stalls,
                                    haptic_loop,
                                };
                                for rate in [1000.0, 4000.0] {
                                    let v = verdict(&f, rate);
                                    for finding in &v.findings {
                                        seen[finding.grade() as usize] += 1;
                                        if finding.grade() == Grade::Pass {
                                            assert_eq!(finding.fix(), None, "{finding:?}");
                                        } else {
                                            assert!(finding.fix().is_some(), "{finding:?}");
                                        }
                                    }
                                    let text = verdict_text(&[v]);
                                    let lines: Vec<&str> = text.lines().collect();
                                    for w in lines.windows(2) {
                                        assert!(
                                            !(w[0].contains("[pass]") && w[1].contains("fix:")),
                                            "{text}"
                                        );
                                    }
                                }
                            }
                        }
                    }
                }
            }
        }
        // Every grade came up, so the rule was tried on each.
        assert!(seen.iter().all(|&n| n > 0), "{seen:?}");
    }

    #[test]
    fn every_threshold_says_why_with_its_figures() {
        for t in &THRESHOLDS {
            assert!(t.why.len() > 40, "{t:?}");
            assert!(!t.why.contains("CALIBRATION"), "{t:?}");
            assert!(t.above >= 0.0 && t.above_rate_hz >= 0.0, "{t:?}");
        }
        // The worse row of a family comes first, so it wins ties.
        for (i, a) in THRESHOLDS.iter().enumerate() {
            for b in &THRESHOLDS[i + 1..] {
                if a.measure == b.measure && a.above_rate_hz == b.above_rate_hz {
                    assert!(a.above >= b.above, "{a:?} before {b:?}");
                }
            }
        }
    }

    #[test]
    fn the_plain_summary_names_the_first_rate_not_fit_and_why() {
        let f = PlatformFacts {
            stalls: Some(stalls(1.0, &[[200; 19].as_slice(), &[210]].concat())),
            ..fit()
        };
        let line = plain_summary(&[verdict(&f, 1000.0), verdict(&f, 4000.0)]);
        assert_eq!(
            line,
            "this machine is fine for 1 kHz haptics; marginal for 4 kHz: host stalls up to \
             210 µs: 20.0 a second of 125 µs or more (half of the 250 µs period)"
        );
        let both = plain_summary(&[verdict(&fit(), 1000.0), verdict(&fit(), 4000.0)]);
        assert_eq!(both, "this machine is fine for 4 kHz haptics");
        let long = PlatformFacts {
            stalls: Some(stalls(1.0, &[2000; 5])),
            ..fit()
        };
        assert!(
            plain_summary(&[verdict(&long, 4000.0), verdict(&long, 1000.0)])
                .starts_with("not suited for 1 kHz: host stalls up to 2000 µs")
        );
        assert_eq!(plain_summary(&[]), "not judged yet");
    }

    #[test]
    fn rt_throttling_is_reported_without_a_fix() {
        let f = PlatformFacts {
            rt_runtime_us: Some(950_000),
            ..fit()
        };
        let r = reasons(&f, 1000.0);
        assert!(
            r.contains("950000 µs per 1000000 µs") && r.contains("sched_rt_runtime_us=-1"),
            "{r}"
        );
        assert_eq!(grades(&f), (Grade::Pass, Grade::Pass));
        assert!(
            verdict(&f, 1000.0)
                .findings
                .iter()
                .all(|f| f.fix().is_none())
        );
    }

    #[test]
    fn busy_smt_siblings_matter_at_4k() {
        let f = PlatformFacts {
            smt_active: Some(true),
            ..fit()
        };
        assert_eq!(grades(&f), (Grade::Pass, Grade::Marginal));
        let idle = PlatformFacts {
            cpu_busy_fraction: Some(0.1),
            ..f
        };
        assert_eq!(grades(&idle), (Grade::Pass, Grade::Pass));
    }

    #[test]
    fn missing_facts_are_unknown_not_failures() {
        let v = verdict(&PlatformFacts::default(), 1000.0);
        assert_eq!(v.grade, Grade::Pass);
        let text = verdict_text(&[v]);
        for what in [
            "real-time priority: unknown",
            "CPU frequency governor: unknown",
            "core isolation: unknown",
            "host stalls: unknown",
            "RT throttling: unknown",
            "SMT siblings: unknown",
            "wake-up latency: unknown",
        ] {
            assert!(text.contains(what), "{what} missing from\n{text}");
        }
    }

    #[test]
    fn findings_are_worst_first() {
        let f = PlatformFacts {
            rt_granted: Some(false),
            stalls: Some(stalls(1.0, &[3000; 4])),
            rt_runtime_us: Some(950_000),
            ..fit()
        };
        let v = verdict(&f, 1000.0);
        assert!(v.findings.windows(2).all(|w| w[0].grade() >= w[1].grade()));
        assert_eq!(v.findings[0].grade(), Grade::Fail);
    }

    #[test]
    fn isolation_comes_from_sys_or_cmdline() {
        assert_eq!(isolation_from(Some("\n"), Some("ro quiet")), Some(false));
        assert_eq!(isolation_from(Some("2-3\n"), None), Some(true));
        assert_eq!(isolation_from(None, Some("ro nohz_full=3")), Some(true));
        assert_eq!(isolation_from(None, None), None);
    }

    #[test]
    fn proc_stat_busy_fraction() {
        let a = parse_cpu_jiffies("cpu  100 0 100 700 100 0 0 0 0 0\ncpu0 1 2 3\n").expect("a");
        let b = parse_cpu_jiffies("cpu  200 0 200 800 100 0 0 0 0 0\n").expect("b");
        assert_eq!(a, (200, 1000));
        assert!((busy_fraction(a, b).expect("fraction") - 200.0 / 300.0).abs() < 1e-12);
        assert_eq!(parse_cpu_jiffies("intr 5\n"), None);
    }

    #[test]
    fn missing_fact_file_is_none() {
        assert_eq!(
            read_fact_file(Path::new("/nonexistent/dynaclay/fact")),
            None
        );
    }
}
