//! The platform probe around a real-time run, shared by `dynaclay profile` and `dynaclay run`:
//! the probe before the engine's loops and after them, the machine's facts, and the readiness
//! verdict for 1 kHz and 4 kHz, gathered into the `latency.json` document.

use std::time::Duration;

use dynaclay_loops::{
    HAPTIC_LOOP, LatencyRecorder, LoopRecord, LoopSummary, ProbeRun, ProfileDoc, RtOutcome,
    busy_fraction, cpu_jiffies, plain_summary, read_platform_facts, run_probes, verdict,
};

use super::error::CliError;

/// The rates the readiness verdict judges, Hz.
pub const JUDGED_RATES_HZ: [f64; 2] = [1000.0, 4000.0];

/// How long each half of the probe (wake-ups, then stalls) runs around a `dynaclay run`: short,
/// so a run takes under a second longer.
pub const RUN_PROBE_EACH: Duration = Duration::from_millis(200);

/// The probe run before the loops, waiting for the loops to run and the probe after them.
pub struct PlatformWatch {
    rate_hz: f64,
    each: Duration,
    rt_priority: Option<i32>,
    before: ProbeRun,
    jiffies_at_start: Option<(u64, u64)>,
}

/// Both probe runs and the document judging the machine by them.
pub struct PlatformJudged {
    /// Loops, probes, facts and verdicts: the `latency.json` document.
    pub doc: ProfileDoc,
    before: ProbeRun,
    after: ProbeRun,
}

fn probe(rate_hz: f64, each: Duration, rt: Option<i32>) -> Result<ProbeRun, CliError> {
    run_probes(rate_hz, each, rt).map_err(|e| CliError::output("cannot run the platform probe", e))
}

impl PlatformWatch {
    /// Runs the probe (wake-ups at `rate_hz` at priority `rt_priority`, then stalls, `each`
    /// long apiece) before the loops start.
    ///
    /// # Errors
    /// [`CliError::Output`] when a probe thread cannot be started or panics.
    pub fn before(
        rate_hz: f64,
        each: Duration,
        rt_priority: Option<i32>,
    ) -> Result<Self, CliError> {
        Ok(Self {
            rate_hz,
            each,
            rt_priority,
            before: probe(rate_hz, each, rt_priority)?,
            jiffies_at_start: None,
        })
    }

    /// Marks the loops as running: the CPUs' busy share is measured from here to
    /// [`PlatformWatch::loops_stopping`].
    pub fn loops_running(&mut self) {
        self.jiffies_at_start = cpu_jiffies();
    }

    /// The CPUs' busy share since [`PlatformWatch::loops_running`]; call just before the loops
    /// stop.
    #[must_use]
    pub fn loops_stopping(&self) -> Option<f64> {
        self.jiffies_at_start
            .zip(cpu_jiffies())
            .and_then(|(b, a)| busy_fraction(b, a))
    }

    /// Runs the probe again after the loops stopped and judges the machine from both runs,
    /// whether the haptic loop got its real-time priority (`haptic_rt`), how busy the CPUs
    /// were (`cpu_busy`) and the haptic loop's own record in `loops` (a loop that met every
    /// deadline is never judged to fail at its rate).
    ///
    /// # Errors
    /// [`CliError::Output`] when a probe thread cannot be started or panics.
    pub fn after(
        self,
        loops: Vec<LoopSummary>,
        haptic_rt: RtOutcome,
        cpu_busy: Option<f64>,
    ) -> Result<PlatformJudged, CliError> {
        let after = probe(self.rate_hz, self.each, self.rt_priority)?;
        let mut facts = read_platform_facts();
        facts.rt_granted = Some(matches!(haptic_rt, RtOutcome::Granted { .. }));
        facts.cpu_busy_fraction = cpu_busy;
        let probes = [self.before.summary(), after.summary()];
        let worst = |f: fn(&dynaclay_loops::ProbeSummary) -> f64| {
            Some(probes.iter().map(f).fold(0.0, f64::max))
        };
        facts.stall_ms_per_s = worst(|p| p.stalls.stolen_ms_per_s());
        facts.wakeup_p999_us = worst(|p| p.wakeup.lateness.p999_us);
        facts.wakeup_max_us = worst(|p| p.wakeup.lateness.max_us);
        facts.stalls = Some(probes[0].stalls.merged(&probes[1].stalls));
        // The loop's own record outweighs the probes in the verdict.
        facts.haptic_loop = loops
            .iter()
            .find(|l| l.name == HAPTIC_LOOP && l.stats.ticks > 0)
            .map(|l| LoopRecord::from_stats(&l.stats));
        let doc = ProfileDoc {
            loops,
            probe_before: Some(probes[0]),
            probe_after: Some(probes[1]),
            readiness: JUDGED_RATES_HZ
                .iter()
                .map(|&hz| verdict(&facts, hz))
                .collect(),
            facts: Some(facts),
            motion_to_photon: None,
        };
        Ok(PlatformJudged {
            doc,
            before: self.before,
            after,
        })
    }
}

impl PlatformJudged {
    /// The probe run with the worse wake-up tail, the one drawn over the loops in the plots.
    #[must_use]
    pub fn worse_probe(&self) -> &LatencyRecorder {
        let tail = |p: &ProbeRun| p.wakeup.stats().period_error.p999_us;
        if tail(&self.after) > tail(&self.before) {
            &self.after.wakeup
        } else {
            &self.before.wakeup
        }
    }

    /// One line: the grade per judged rate, then the verdict in plain words ("readiness:
    /// 1000 Hz pass, 4000 Hz marginal: this machine is fine for 1 kHz haptics; marginal for
    /// 4 kHz: host stalls up to …").
    #[must_use]
    pub fn headline(&self) -> String {
        let grades: Vec<String> = self
            .doc
            .readiness
            .iter()
            .map(|v| format!("{:.0} Hz {}", v.rate_hz, v.grade))
            .collect();
        format!(
            "readiness: {}: {}",
            grades.join(", "),
            plain_summary(&self.doc.readiness)
        )
    }
}
