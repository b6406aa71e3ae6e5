//! Is this machine fit for 1 kHz (or 4 kHz) haptics? A verdict with reasons and fixes.
//!
//! [`verdict`] is a pure function of [`PlatformFacts`], so every reason is tested without the
//! machine. [`read_platform_facts`] gathers the facts from `/proc` and `/sys` with bounded reads
//! (each file at most [`FACT_FILE_CAP`] bytes); a missing or unreadable file leaves its fact
//! `None`, shown as "unknown". Not for the real-time path (reads files, allocates).

use std::fmt;
use std::io::Read;
use std::path::Path;

use serde::{Deserialize, Serialize};

/// The most bytes read from any one `/proc` or `/sys` file (they report size 0, so the cap is
/// applied while reading).
pub const FACT_FILE_CAP: u64 = 64 * 1024;

/// Stolen time at or above this, ms per second, downgrades a verdict to marginal.
const STALL_MARGINAL_MS_PER_S: f64 = 1.0;
/// Stolen time at or above this, ms per second, fails a verdict.
const STALL_FAIL_MS_PER_S: f64 = 10.0;
/// CPUs busier than this, on average over the run, count as busy SMT siblings.
const BUSY_FRACTION: f64 = 0.5;

/// What is known about the machine; `None` is "unknown".
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
    /// Time taken away from the stall probe, ms per second (the worse probe run).
    pub stall_ms_per_s: Option<f64>,
    /// The wake-up probe's p99.9 latency, µs (the worse probe run).
    pub wakeup_p999_us: Option<f64>,
    /// The wake-up probe's largest latency, µs (the worse probe run).
    pub wakeup_max_us: Option<f64>,
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

/// One reason behind a verdict.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Finding {
    /// How far it goes against the rate (`pass` for an advisory or unknown fact).
    pub grade: Grade,
    /// What was found.
    pub reason: String,
    /// How to fix it (empty when nothing needs fixing).
    pub fix: String,
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

fn finding(grade: Grade, reason: impl Into<String>, fix: impl Into<String>) -> Finding {
    Finding {
        grade,
        reason: reason.into(),
        fix: fix.into(),
    }
}

fn unknown(what: &str) -> Finding {
    finding(Grade::Pass, format!("{what}: unknown"), "")
}

/// Judges `facts` for a loop at `rate_hz`. Pure.
#[must_use]
pub fn verdict(facts: &PlatformFacts, rate_hz: f64) -> Verdict {
    let period_us = 1e6 / rate_hz.max(1.0);
    let fast = rate_hz > 2000.0;
    let mut findings = Vec::new();

    match facts.rt_granted {
        Some(true) => {}
        Some(false) => findings.push(finding(
            if fast { Grade::Fail } else { Grade::Marginal },
            "real-time priority not granted: any other thread can delay the haptic loop",
            "run as root, grant CAP_SYS_NICE (sudo setcap cap_sys_nice+ep $(which dynaclay)), \
             or add `<user> - rtprio 99` to /etc/security/limits.conf and log in again",
        )),
        None => findings.push(unknown("real-time priority")),
    }

    match &facts.governors {
        Some(g) if g.iter().all(|g| g == "performance") => {}
        Some(g) if g.is_empty() => findings.push(unknown("CPU frequency governor")),
        Some(g) => findings.push(finding(
            Grade::Marginal,
            format!(
                "CPU frequency governor is {} not performance: wake-ups pay for clock ramp-up",
                g.join(", ")
            ),
            "sudo cpupower frequency-set -g performance (or write `performance` to \
             /sys/devices/system/cpu/cpu*/cpufreq/scaling_governor)",
        )),
        None => findings.push(unknown("CPU frequency governor")),
    }

    match facts.isolated_core {
        Some(true) => {}
        Some(false) => findings.push(finding(
            if fast { Grade::Marginal } else { Grade::Pass },
            "no isolated core: the haptic thread shares its core with everything else",
            "boot with isolcpus=N nohz_full=N (one spare core) and pin the haptic loop to it",
        )),
        None => findings.push(unknown("core isolation")),
    }

    match facts.stall_ms_per_s {
        Some(ms) if ms >= STALL_FAIL_MS_PER_S => findings.push(finding(
            Grade::Fail,
            format!("host stalls: {ms:.1} ms per second taken from a spinning thread"),
            stall_fix(),
        )),
        Some(ms) if ms >= STALL_MARGINAL_MS_PER_S => findings.push(finding(
            Grade::Marginal,
            format!("host stalls: {ms:.1} ms per second taken from a spinning thread"),
            stall_fix(),
        )),
        Some(_) => {}
        None => findings.push(unknown("host stalls")),
    }

    match (facts.wakeup_p999_us, facts.wakeup_max_us) {
        (Some(p999), Some(max)) => {
            let grade = if p999 > period_us / 2.0 || max > 2.0 * period_us {
                Grade::Fail
            } else if p999 > period_us / 10.0 || max > period_us {
                Grade::Marginal
            } else {
                Grade::Pass
            };
            if grade > Grade::Pass {
                findings.push(finding(
                    grade,
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
        (Some(runtime), period) => findings.push(finding(
            Grade::Pass,
            format!(
                "RT throttling on: real-time threads get at most {runtime} µs per {} µs",
                period.map_or_else(|| "unknown".to_string(), |p| p.to_string())
            ),
            "only a busy-waiting loop reaches it; to lift it: \
             sudo sysctl kernel.sched_rt_runtime_us=-1",
        )),
        (None, _) => findings.push(unknown("RT throttling")),
    }

    match (facts.smt_active, facts.cpu_busy_fraction) {
        (Some(true), Some(busy)) if busy > BUSY_FRACTION => findings.push(finding(
            if fast { Grade::Marginal } else { Grade::Pass },
            format!(
                "SMT siblings busy: SMT is on and the CPUs were {:.0}% busy, so the haptic \
                 core's sibling was likely busy",
                busy * 100.0
            ),
            "turn SMT off (echo off | sudo tee /sys/devices/system/cpu/smt/control) or keep \
             the haptic core's sibling idle",
        )),
        (Some(false), _) | (Some(true), Some(_)) => {}
        (None, _) | (Some(true), None) => findings.push(unknown("SMT siblings")),
    }

    findings.sort_by_key(|f| std::cmp::Reverse(f.grade));
    Verdict {
        rate_hz,
        grade: findings.first().map_or(Grade::Pass, |f| f.grade),
        findings,
    }
}

fn stall_fix() -> &'static str {
    "on a VM, give it dedicated vCPUs (CPU pinning on the host, no overcommit); on bare metal, \
     look for SMIs or interrupt storms (irqbalance, BIOS power settings)"
}

/// The verdicts as text, one block per rate.
#[must_use]
pub fn verdict_text(verdicts: &[Verdict]) -> String {
    use fmt::Write as _;
    let mut out = String::new();
    for v in verdicts {
        let _ = writeln!(out, "{:.0} Hz: {}", v.rate_hz, v.grade);
        for f in &v.findings {
            let _ = writeln!(out, "  [{}] {}", f.grade, f.reason);
            if !f.fix.is_empty() {
                let _ = writeln!(out, "      fix: {}", f.fix);
            }
        }
    }
    out
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
        }
    }

    fn grades(f: &PlatformFacts) -> (Grade, Grade) {
        (verdict(f, 1000.0).grade, verdict(f, 4000.0).grade)
    }

    fn reasons(f: &PlatformFacts, rate: f64) -> String {
        verdict(f, rate)
            .findings
            .iter()
            .map(|f| format!("{}|{}\n", f.reason, f.fix))
            .collect()
    }

    #[test]
    fn a_fit_machine_passes_both_rates_with_no_findings() {
        assert_eq!(grades(&fit()), (Grade::Pass, Grade::Pass));
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
        assert!(reasons(&f, 1000.0).contains("isolcpus"));
    }

    #[test]
    fn host_stalls_grade_by_ms_per_second() {
        let at = |ms| PlatformFacts {
            stall_ms_per_s: Some(ms),
            ..fit()
        };
        assert_eq!(grades(&at(0.5)), (Grade::Pass, Grade::Pass));
        assert_eq!(grades(&at(3.0)), (Grade::Marginal, Grade::Marginal));
        assert_eq!(grades(&at(25.0)), (Grade::Fail, Grade::Fail));
        assert!(reasons(&at(25.0), 1000.0).contains("25.0 ms per second"));
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
    fn rt_throttling_is_reported_with_its_fix() {
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
            stall_ms_per_s: Some(50.0),
            rt_runtime_us: Some(950_000),
            ..fit()
        };
        let v = verdict(&f, 1000.0);
        assert!(v.findings.windows(2).all(|w| w[0].grade >= w[1].grade));
        assert_eq!(v.findings[0].grade, Grade::Fail);
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
