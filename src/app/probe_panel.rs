//! The machine's side of the latency panel: the platform probe, its last figures, and the
//! readiness verdict for 1 kHz and 4 kHz.
//!
//! At launch, before the engine starts, the whole probe runs as `dynaclay run` runs it (a
//! cyclictest-style sleeper at the haptic rate and priority, then a spinning stall counter).
//! Beside the running engine (**Probe again**) only the sleeper runs, one priority step below
//! the haptic thread, so it never delays a haptic tick; the stall counter is not run there: at
//! the haptic priority it held a core for its whole half second and starved the haptic loop
//! (ticks up to 950 ms late in `bench/probe_cost.rs`), and below it, it would count the engine's
//! own threads as host stalls. The verdict then keeps the stalls measured at launch.
//!
//! The frame never waits on a probe: a worker thread hands its result over a channel that the
//! frame polls.
//!
//! The panel shows one plain line by default ("this machine is fine for 1 kHz haptics", or the
//! first rate it is not fit for and why); the probe's figures, the verdicts' reasons and fixes
//! and the loops' plots are under **details**. The verdict is drawn each frame from the
//! probe's facts and the haptic loop's figures so far: a loop that has met every deadline is
//! never told its machine fails (see `dynaclay_loops::THRESHOLDS`).

use std::time::{Duration, Instant};

use crossbeam::channel::{Receiver, TryRecvError, bounded};
use dynaclay_loops::{
    Grade, LatencyStats, LoopRecord, PlatformFacts, ProbeSummary, RtOutcome, StallStats, Verdict,
    busy_fraction, cpu_jiffies, plain_summary, read_platform_facts, run_wakeup_probe, verdict,
};

/// The rates judged, Hz.
const JUDGED_RATES_HZ: [f64; 2] = [1000.0, 4000.0];

/// How long the wake-up probe runs beside the engine.
pub const PROBE_EACH: Duration = Duration::from_millis(500);

/// Host stalls as the stall counter measured them, and what its priority request got.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StallFigures {
    pub rt: RtOutcome,
    pub stats: StallStats,
}

/// One finished probe: its figures and the verdicts drawn from them.
#[derive(Clone, Debug, PartialEq)]
pub struct ProbeOutcome {
    /// What the wake-up probe's priority request got.
    pub wakeup_rt: RtOutcome,
    /// The wake-up probe's figures (`lateness` is the wake-up latency).
    pub wakeup: LatencyStats,
    /// Host stalls, from the last probe that counted them (the one at launch).
    pub stalls: Option<StallFigures>,
    /// Whether the wake-up probe ran beside the engine (else before it started).
    pub beside_engine: bool,
    /// What the verdicts were drawn from (without the haptic loop's record).
    pub facts: PlatformFacts,
    /// The verdicts from the probe alone, one per judged rate.
    pub verdicts: Vec<Verdict>,
}

impl ProbeOutcome {
    /// The outcome of a whole probe run before the engine started (as `dynaclay run` makes).
    #[must_use]
    pub fn before_engine(summary: &ProbeSummary, cpu_busy: Option<f64>) -> Self {
        judge(
            summary.wakeup_rt,
            summary.wakeup,
            Some(StallFigures {
                rt: summary.stall_rt,
                stats: summary.stalls,
            }),
            false,
            cpu_busy,
        )
    }
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

impl ProbeSettings {
    /// The wake-up probe's priority beside the engine: one step below the haptic thread's.
    #[must_use]
    pub fn beside_engine_priority(&self) -> Option<i32> {
        self.rt_priority.map(|p| (p - 1).max(1))
    }
}

/// The probe's state in the app.
#[derive(Debug, Default)]
pub struct ProbePanel {
    pub settings: ProbeSettings,
    running: Option<(Instant, Receiver<ProbeOutcome>)>,
    /// The last finished probe and when it finished.
    pub last: Option<(Instant, ProbeOutcome)>,
    /// Why the last probe failed, if it did.
    pub error: Option<String>,
}

/// Runs the wake-up probe beside the engine and judges the machine with `stalls` (the worker
/// thread's body; it changes the thread's priority).
fn probe_beside_engine(settings: ProbeSettings, stalls: Option<StallFigures>) -> ProbeOutcome {
    let jiffies_before = cpu_jiffies();
    let period = Duration::from_secs_f64(1.0 / settings.rate_hz.max(1.0));
    let (rt, recorder) = run_wakeup_probe(period, PROBE_EACH, settings.beside_engine_priority());
    let busy = jiffies_before
        .zip(cpu_jiffies())
        .and_then(|(b, a)| busy_fraction(b, a));
    judge(rt, recorder.stats(), stalls, true, busy)
}

/// The verdicts for a probe's figures, with the machine's facts read now. Whether real-time
/// priority is granted is taken from the wake-up probe's own request.
#[must_use]
pub fn judge(
    wakeup_rt: RtOutcome,
    wakeup: LatencyStats,
    stalls: Option<StallFigures>,
    beside_engine: bool,
    cpu_busy: Option<f64>,
) -> ProbeOutcome {
    let mut facts = read_platform_facts();
    facts.rt_granted = match wakeup_rt {
        RtOutcome::Granted { .. } => Some(true),
        RtOutcome::NotRequested => None,
        _ => Some(false),
    };
    facts.cpu_busy_fraction = cpu_busy;
    facts.stall_ms_per_s = stalls.map(|s| s.stats.stolen_ms_per_s());
    facts.stalls = stalls.map(|s| s.stats);
    facts.wakeup_p999_us = Some(wakeup.lateness.p999_us);
    facts.wakeup_max_us = Some(wakeup.lateness.max_us);
    ProbeOutcome {
        wakeup_rt,
        wakeup,
        stalls,
        beside_engine,
        verdicts: verdicts_for(&facts),
        facts,
    }
}

fn verdicts_for(facts: &PlatformFacts) -> Vec<Verdict> {
    JUDGED_RATES_HZ
        .iter()
        .map(|&hz| verdict(facts, hz))
        .collect()
}

impl ProbeOutcome {
    /// The verdicts with the haptic loop's figures so far (`haptic`, no ticks: not running)
    /// taken as the loop's own record.
    #[must_use]
    pub fn verdicts_with(&self, haptic: &LatencyStats) -> Vec<Verdict> {
        if haptic.ticks == 0 {
            return self.verdicts.clone();
        }
        let facts = PlatformFacts {
            haptic_loop: Some(LoopRecord::from_stats(haptic)),
            ..self.facts.clone()
        };
        verdicts_for(&facts)
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
    /// A panel for a haptic loop with `settings`, showing `at_start` (the probe run at launch,
    /// before the engine) when there is one.
    #[must_use]
    pub fn new(settings: ProbeSettings, at_start: Option<ProbeOutcome>) -> Self {
        Self {
            settings,
            last: at_start.map(|o| (Instant::now(), o)),
            ..Self::default()
        }
    }

    /// Whether a probe is running.
    #[must_use]
    pub fn is_running(&self) -> bool {
        self.running.is_some()
    }

    /// Starts the wake-up probe beside the engine on a worker thread, unless one is running.
    pub fn start(&mut self) {
        if self.running.is_some() {
            return;
        }
        let (tx, rx) = bounded(1);
        let settings = self.settings;
        let stalls = self.last.as_ref().and_then(|(_, o)| o.stalls);
        let spawned = std::thread::Builder::new()
            .name("probe-panel".into())
            .spawn(move || {
                // The frame may have gone (app closed): nothing to tell then.
                let _ = tx.send(probe_beside_engine(settings, stalls));
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
        let Some((_, rx)) = &self.running else {
            return;
        };
        match rx.try_recv() {
            Ok(outcome) => {
                self.running = None;
                self.finish(Ok(outcome));
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

    /// One plain line with the verdict, and under **details** (closed at first) the probe's
    /// figures, the verdicts with their reasons and fixes, the button, then `details_below`
    /// (the loops' figures and plots). `haptic` is the haptic loop's figures so far.
    pub fn ui(
        &mut self,
        ui: &mut egui::Ui,
        haptic: &LatencyStats,
        details_below: impl FnOnce(&mut egui::Ui),
    ) {
        let verdicts = self
            .last
            .as_ref()
            .map(|(_, o)| o.verdicts_with(haptic))
            .unwrap_or_default();
        self.summary_line(ui, &verdicts);
        egui::CollapsingHeader::new("details")
            .id_salt("latency details")
            .default_open(false)
            .show(ui, |ui| {
                ui.heading("Machine");
                self.details_ui(ui, &verdicts);
                ui.separator();
                ui.heading("Loops");
                details_below(ui);
            });
    }

    /// The verdict in one plain line, coloured by the worst grade it names.
    fn summary_line(&self, ui: &mut egui::Ui, verdicts: &[Verdict]) {
        ui.horizontal_wrapped(|ui| {
            if let Some((since, _)) = &self.running {
                ui.spinner();
                ui.label(format!("probing… {:.1} s", since.elapsed().as_secs_f64()));
            } else if verdicts.is_empty() {
                ui.weak("not probed yet");
            } else {
                let grade = verdicts
                    .iter()
                    .map(|v| v.grade)
                    .find(|&g| g != Grade::Pass)
                    .unwrap_or(Grade::Pass);
                ui.colored_label(grade_colour(grade), plain_summary(verdicts));
            }
        });
        if let Some(e) = &self.error {
            ui.colored_label(ui.visuals().error_fg_color, e);
        }
    }

    /// The button, the probe's figures and the verdicts with their reasons and fixes.
    fn details_ui(&mut self, ui: &mut egui::Ui, verdicts: &[Verdict]) {
        if self.running.is_none()
            && ui
                .button("Probe again")
                .on_hover_text(
                    "Half a second of a thread sleeping to deadlines at the haptic rate, one \
                     priority step below the haptic thread, beside the running engine.",
                )
                .clicked()
        {
            self.start();
        }
        let Some((at, outcome)) = &self.last else {
            ui.weak("no probe figures yet");
            return;
        };
        let w = &outcome.wakeup;
        ui.label(format!(
            "wake-up probe {:.0} s ago, {}, at {:.0} Hz ({})",
            at.elapsed().as_secs_f64(),
            if outcome.beside_engine {
                "beside the engine"
            } else {
                "before the engine started"
            },
            w.nominal_rate_hz,
            outcome.wakeup_rt
        ));
        ui.label(format!(
            "wake-up p99 {:.1} µs, p99.9 {:.1} µs, max {:.1} µs",
            w.lateness.p99_us, w.lateness.p999_us, w.lateness.max_us
        ));
        match &outcome.stalls {
            Some(s) => {
                ui.label(format!(
                    "host stalls: {} gaps, {:.2} ms/s, worst {:.0} µs",
                    s.stats.gaps,
                    s.stats.stolen_ms_per_s(),
                    s.stats.max_gap_us
                ));
                if outcome.beside_engine {
                    ui.weak("(stalls counted at launch, before the engine started)");
                }
            }
            None => {
                ui.weak("host stalls: not counted (counted only before the engine starts)");
            }
        }
        for v in verdicts {
            let head = format!("{:.0} Hz: {}", v.rate_hz, v.grade);
            egui::CollapsingHeader::new(egui::RichText::new(head).color(grade_colour(v.grade)))
                .id_salt(("readiness", v.rate_hz.to_bits()))
                .default_open(false)
                .show(ui, |ui| {
                    for f in &v.findings {
                        ui.horizontal_wrapped(|ui| {
                            ui.colored_label(grade_colour(f.grade()), format!("[{}]", f.grade()));
                            ui.label(f.reason());
                        });
                        if let Some(fix) = f.fix() {
                            ui.weak(format!("fix: {fix}"));
                        }
                    }
                });
        }
    }
}
