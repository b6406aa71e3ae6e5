//! The machine's side of the latency panel: the platform probe (a cyclictest-style sleeper at
//! the haptic rate and priority, then a spinning stall counter) run on a worker thread beside
//! the engine, its last figures, and the readiness verdict for 1 kHz and 4 kHz.
//!
//! The probe runs when the user asks and, in the app, once at start. The frame never waits on
//! it: the worker hands its result over a channel that the frame polls.

use std::time::{Duration, Instant};

use crossbeam::channel::{Receiver, TryRecvError, bounded};
use dynaclay_loops::{
    Grade, ProbeSummary, RtOutcome, Verdict, busy_fraction, cpu_jiffies, read_platform_facts,
    run_probes, verdict,
};

/// The rates judged, Hz.
const JUDGED_RATES_HZ: [f64; 2] = [1000.0, 4000.0];

/// How long each half of the probe runs.
pub const PROBE_EACH: Duration = Duration::from_millis(500);

/// One finished probe: its figures and the verdicts drawn from them.
#[derive(Clone, Debug, PartialEq)]
pub struct ProbeOutcome {
    pub summary: ProbeSummary,
    pub verdicts: Vec<Verdict>,
}

/// What the probe is asked to imitate: the haptic loop's rate and real-time priority.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProbeSettings {
    pub rate_hz: f64,
    pub rt_priority: Option<i32>,
}

impl Default for ProbeSettings {
    fn default() -> Self {
        Self {
            rate_hz: 1000.0,
            rt_priority: Some(dynaclay_loops::DEFAULT_RT_PRIORITY),
        }
    }
}

/// The probe's state in the app.
#[derive(Debug, Default)]
pub struct ProbePanel {
    pub settings: ProbeSettings,
    /// Start a probe on the next frame (set at launch for the probe at start).
    pub start_pending: bool,
    running: Option<(Instant, Receiver<Result<ProbeOutcome, String>>)>,
    /// The last finished probe and when it finished.
    pub last: Option<(Instant, ProbeOutcome)>,
    /// Why the last probe failed, if it did.
    pub error: Option<String>,
}

/// Runs the probe and judges the machine (the worker thread's body).
fn probe_and_judge(settings: ProbeSettings) -> Result<ProbeOutcome, String> {
    let jiffies_before = cpu_jiffies();
    let run = run_probes(settings.rate_hz, PROBE_EACH, settings.rt_priority)
        .map_err(|e| format!("cannot run the platform probe: {e}"))?;
    let summary = run.summary();
    Ok(judge(
        summary,
        jiffies_before
            .zip(cpu_jiffies())
            .and_then(|(b, a)| busy_fraction(b, a)),
    ))
}

/// The verdicts for one probe run, with the machine's facts read now. Whether real-time
/// priority is granted is taken from the probe's own request (made at the haptic priority).
#[must_use]
pub fn judge(summary: ProbeSummary, cpu_busy: Option<f64>) -> ProbeOutcome {
    let mut facts = read_platform_facts();
    facts.rt_granted = match summary.wakeup_rt {
        RtOutcome::Granted { .. } => Some(true),
        RtOutcome::NotRequested => None,
        _ => Some(false),
    };
    facts.cpu_busy_fraction = cpu_busy;
    facts.stall_ms_per_s = Some(summary.stalls.stolen_ms_per_s());
    facts.wakeup_p999_us = Some(summary.wakeup.lateness.p999_us);
    facts.wakeup_max_us = Some(summary.wakeup.lateness.max_us);
    ProbeOutcome {
        summary,
        verdicts: JUDGED_RATES_HZ
            .iter()
            .map(|&hz| verdict(&facts, hz))
            .collect(),
    }
}

fn grade_colour(grade: Grade) -> egui::Color32 {
    match grade {
        Grade::Pass => egui::Color32::from_rgb(90, 190, 110),
        Grade::Marginal => egui::Color32::from_rgb(230, 170, 50),
        Grade::Fail => egui::Color32::from_rgb(230, 80, 70),
    }
}

impl ProbePanel {
    /// A panel that probes with `settings` on the first frame.
    #[must_use]
    pub fn probing_at_start(settings: ProbeSettings) -> Self {
        Self {
            settings,
            start_pending: true,
            ..Self::default()
        }
    }

    /// Whether a probe is running.
    #[must_use]
    pub fn is_running(&self) -> bool {
        self.running.is_some()
    }

    /// Starts a probe on a worker thread unless one is running.
    pub fn start(&mut self) {
        if self.running.is_some() {
            return;
        }
        let (tx, rx) = bounded(1);
        let settings = self.settings;
        let spawned = std::thread::Builder::new()
            .name("probe-panel".into())
            .spawn(move || {
                // The frame may have gone (app closed): nothing to tell then.
                let _ = tx.send(probe_and_judge(settings));
            });
        match spawned {
            Ok(_) => {
                self.running = Some((Instant::now(), rx));
                self.error = None;
            }
            Err(e) => self.error = Some(format!("cannot start the probe: {e}")),
        }
    }

    /// Takes the finished probe's result, if any. Never waits.
    pub fn poll(&mut self) {
        if std::mem::take(&mut self.start_pending) {
            self.start();
        }
        let Some((_, rx)) = &self.running else {
            return;
        };
        match rx.try_recv() {
            Ok(result) => {
                self.running = None;
                self.finish(result);
            }
            Err(TryRecvError::Empty) => {}
            Err(TryRecvError::Disconnected) => {
                self.running = None;
                self.error = Some("the probe thread ended without a result".into());
            }
        }
    }

    /// Records a probe's result as if a worker had just handed it over.
    pub fn finish(&mut self, result: Result<ProbeOutcome, String>) {
        match result {
            Ok(outcome) => {
                self.last = Some((Instant::now(), outcome));
                self.error = None;
            }
            Err(e) => self.error = Some(e),
        }
    }

    /// The probe's figures, the verdicts with their reasons and fixes, and the button.
    pub fn ui(&mut self, ui: &mut egui::Ui) {
        ui.horizontal(|ui| {
            if let Some((since, _)) = &self.running {
                ui.spinner();
                ui.label(format!("probing… {:.1} s", since.elapsed().as_secs_f64()));
            } else if ui
                .button("Probe the machine")
                .on_hover_text(
                    "A sleeping thread at the haptic rate and priority, then a spinning stall \
                     counter, half a second each, beside the running engine.",
                )
                .clicked()
            {
                self.start();
            }
        });
        if let Some(e) = &self.error {
            ui.colored_label(ui.visuals().error_fg_color, e);
        }
        let Some((at, outcome)) = &self.last else {
            ui.weak("not probed yet");
            return;
        };
        let w = &outcome.summary.wakeup;
        let s = &outcome.summary.stalls;
        ui.label(format!(
            "probe {:.0} s ago at {:.0} Hz ({})",
            at.elapsed().as_secs_f64(),
            w.nominal_rate_hz,
            outcome.summary.wakeup_rt
        ));
        ui.label(format!(
            "wake-up p99 {:.1} µs, p99.9 {:.1} µs, max {:.1} µs",
            w.lateness.p99_us, w.lateness.p999_us, w.lateness.max_us
        ));
        ui.label(format!(
            "host stalls: {} gaps, {:.2} ms/s, worst {:.0} µs",
            s.gaps,
            s.stolen_ms_per_s(),
            s.max_gap_us
        ));
        for v in &outcome.verdicts {
            let head = format!("{:.0} Hz: {}", v.rate_hz, v.grade);
            egui::CollapsingHeader::new(egui::RichText::new(head).color(grade_colour(v.grade)))
                .id_salt(("readiness", v.rate_hz.to_bits()))
                .default_open(v.grade != Grade::Pass)
                .show(ui, |ui| {
                    for f in &v.findings {
                        ui.colored_label(grade_colour(f.grade), format!("[{}]", f.grade));
                        ui.label(&f.reason);
                        if !f.fix.is_empty() {
                            ui.weak(format!("fix: {}", f.fix));
                        }
                    }
                });
        }
    }
}
