//! What the platform probe costs the haptic thread: the whole engine (haptic loop at 1 kHz at
//! its real-time priority, simulation, graphics, the simulated arm pushing strokes) runs in
//! alternating phases, with and without a probe running beside it, and the haptic loop's
//! compute time (the tick body, not the wake-up) is compared, pooled over the phases of each
//! kind; the period error is shown too. The probe runs back to back for the whole phase, so the
//! comparison is its worst case.
//!
//! `--probe gui` (the default) is what the GUI runs beside the engine: the sleeping wake-up
//! probe at the haptic rate, one priority step below the haptic thread. `wakeup` is the same at
//! the haptic priority, `stall` the spinning stall probe at the haptic priority, `both` the two
//! in turn as `run_probes` runs them before and after the loops, and `none` runs nothing in the
//! "with" phases (both halves alike: the size of the comparison's noise).
//!
//! Usage: `cargo bench --bench probe_cost -- [--phase-seconds N] [--rounds N] [--no-rt]
//! [--probe gui|wakeup|stall|both|none]` (defaults 5 s, 4 rounds, gui; a round is one phase of each
//! kind, the order alternating ABBA so a drift in the machine's load falls on both). Prints
//! each phase, a Markdown table and the load average before and after.
//!
//! Where it is optimistic: the simulated arm, not a device on a serial line. Where it is
//! pessimistic: every tick is counted, including each phase's first (cold caches), and the
//! probe runs without a pause, where the GUI runs it on request.

use std::hint::black_box;
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use dynaclay::dynamics::Material;
use dynaclay::engine::{Engine, EngineConfig, HeadlessSink, ScriptPlan, build_clay};
use dynaclay::io::parse_script;
use dynaclay_devices::{SimArmConfig, SimulatedArm};
use dynaclay_loops::{
    DEFAULT_GAP_THRESHOLD, DEFAULT_RT_PRIORITY, LatencyRecorder, RtOutcome, run_probes,
    run_stall_probe, run_wakeup_probe,
};
use hdrhistogram::Histogram;

/// Which part of the probe runs beside the engine.
#[derive(Clone, Copy, Debug, PartialEq)]
enum ProbeKind {
    /// What the GUI runs beside the engine: the wake-up probe one priority step below the
    /// haptic thread.
    Gui,
    /// `run_probes` at the haptic priority: wake-ups, then stalls (as before the loops).
    Both,
    /// Nothing: both halves of each round are alike, which shows the comparison's noise.
    Nothing,
    /// Only the sleeping wake-up probe.
    Wakeup,
    /// Only the spinning stall probe.
    Stall,
}

struct Args {
    phase_seconds: f64,
    rounds: usize,
    rt: bool,
    probe: ProbeKind,
}

fn parse_args() -> Result<Args, String> {
    let mut args = Args {
        phase_seconds: 5.0,
        rounds: 4,
        rt: true,
        probe: ProbeKind::Gui,
    };
    let mut it = std::env::args().skip(1);
    while let Some(a) = it.next() {
        match a.as_str() {
            "--phase-seconds" => {
                args.phase_seconds = it
                    .next()
                    .and_then(|v| v.parse().ok())
                    .filter(|v: &f64| v.is_finite() && *v > 0.5)
                    .ok_or("--phase-seconds takes a number of seconds above 0.5")?;
            }
            "--rounds" => {
                args.rounds = it
                    .next()
                    .and_then(|v| v.parse().ok())
                    .filter(|v| *v > 0)
                    .ok_or("--rounds takes a positive whole number")?;
            }
            "--no-rt" => args.rt = false,
            "--probe" => {
                args.probe = match it.next().as_deref() {
                    Some("gui") => ProbeKind::Gui,
                    Some("both") => ProbeKind::Both,
                    Some("none") => ProbeKind::Nothing,
                    Some("wakeup") => ProbeKind::Wakeup,
                    Some("stall") => ProbeKind::Stall,
                    _ => return Err("--probe takes gui, both, wakeup, stall or none".into()),
                };
            }
            // cargo bench passes --bench to every harness.
            "--bench" => {}
            other => return Err(format!("unknown argument {other}")),
        }
    }
    Ok(args)
}

/// Pushes along the block's top, one every 2.5 s, filling `seconds`.
fn script(seconds: f64) -> String {
    let mut text = String::from("version = 1\n[clay]\nshape = \"block\"\nresolution = 24\n");
    let mut t = 0.2;
    let mut k = 0usize;
    while t + 2.2 < seconds {
        let z = 0.95 + 0.1 * (k % 4) as f64;
        text.push_str(&format!(
            "[[step]]\ndo = \"stroke\"\nstart_s = {t}\n\
             path = [[0.85, 1.55, {z}], [1.45, 1.55, {z}]]\nduration_s = 1.5\n"
        ));
        t += 2.5;
        k += 1;
    }
    text
}

/// The probe, run back to back until `stop` is set.
struct ProbeLoad {
    stop: Arc<AtomicBool>,
    thread: std::thread::JoinHandle<Result<u32, String>>,
}

impl ProbeLoad {
    fn start(kind: ProbeKind, rt_priority: Option<i32>) -> Self {
        let stop = Arc::new(AtomicBool::new(false));
        let flag = stop.clone();
        let each = Duration::from_millis(500);
        let thread = std::thread::spawn(move || {
            let mut runs = 0u32;
            // NOTE: Relaxed: the flag only ends the loop eventually.
            while !flag.load(Ordering::Relaxed) {
                match kind {
                    ProbeKind::Gui => {
                        black_box(run_wakeup_probe(
                            Duration::from_millis(1),
                            each,
                            rt_priority.map(|p| (p - 1).max(1)),
                        ));
                    }
                    ProbeKind::Both => {
                        run_probes(1000.0, each, rt_priority).map_err(|e| e.to_string())?;
                    }
                    ProbeKind::Wakeup => {
                        black_box(run_wakeup_probe(
                            Duration::from_millis(1),
                            each,
                            rt_priority,
                        ));
                    }
                    ProbeKind::Nothing => std::thread::sleep(each),
                    ProbeKind::Stall => {
                        black_box(run_stall_probe(each, DEFAULT_GAP_THRESHOLD, rt_priority));
                    }
                }
                runs += 1;
            }
            Ok(runs)
        });
        Self { stop, thread }
    }

    fn stop(self) -> Result<u32, String> {
        self.stop.store(true, Ordering::Relaxed);
        self.thread
            .join()
            .map_err(|_| "the probe thread panicked".to_string())?
    }
}

/// Runs the engine for `seconds` (with the probe beside it when `probe`); returns the haptic
/// loop's recorder, what its priority request got and how many probe runs completed.
fn phase(
    seconds: f64,
    rt_priority: Option<i32>,
    probe: Option<ProbeKind>,
) -> Result<(LatencyRecorder, RtOutcome, u32), String> {
    let script = parse_script(&script(seconds), "<bench>").map_err(|e| e.to_string())?;
    let plan = ScriptPlan::new(&script, "<bench>", Path::new("."), &[], Material::PLASTIC)
        .map_err(|e| e.to_string())?;
    let field = build_clay(&plan.clay).map_err(|e| e.to_string())?;
    let arm_config = SimArmConfig::default();
    let mut config = EngineConfig::for_field(&field, &arm_config.info);
    config.haptics.tool_contact = plan.tool_contact;
    config.haptic_rate_hz = 1000.0;
    config.haptic_rt_priority = rt_priority;
    let trajectory = plan.trajectory(&config.map).map_err(|e| e.to_string())?;
    let device = Box::new(SimulatedArm::new(arm_config, trajectory));
    let engine = Engine::start(&config, field, device, Box::new(HeadlessSink::default()))
        .map_err(|e| e.to_string())?;
    let rt = engine.haptic_rt();
    let load = probe.map(|kind| ProbeLoad::start(kind, rt_priority));
    std::thread::sleep(Duration::from_secs_f64(seconds));
    // The engine stops first, so every tick it recorded had the probe beside it.
    let mut report = engine.stop().map_err(|e| e.to_string())?;
    let runs = match load {
        Some(l) => l.stop()?,
        None => 0,
    };
    Ok((report.loops.remove(0).recorder, rt, runs))
}

/// Percentiles of a pooled histogram, µs: p50, p99, p99.9, max.
fn figures(h: &Histogram<u64>) -> [f64; 4] {
    let us = |ns: u64| ns as f64 / 1e3;
    [
        us(h.value_at_quantile(0.5)),
        us(h.value_at_quantile(0.99)),
        us(h.value_at_quantile(0.999)),
        us(h.max()),
    ]
}

fn pool(into: &mut Option<Histogram<u64>>, h: &Histogram<u64>) -> Result<(), String> {
    match into {
        Some(p) => p.add(h).map_err(|e| e.to_string()),
        None => {
            *into = Some(h.clone());
            Ok(())
        }
    }
}

fn load_average() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .unwrap_or_default()
        .trim()
        .to_string()
}

fn main() {
    if let Err(e) = run() {
        eprintln!("probe_cost: {e}");
        std::process::exit(1);
    }
}

fn run() -> Result<(), String> {
    let args = parse_args()?;
    let rt_priority = args.rt.then_some(DEFAULT_RT_PRIORITY);
    println!(
        "probe_cost: {} rounds of {} s with and {} s without the probe ({:?}); load average \
         before: {}",
        args.rounds,
        args.phase_seconds,
        args.phase_seconds,
        args.probe,
        load_average()
    );
    // [without, with]: pooled compute and period error, ticks, probe runs.
    let mut compute: [Option<Histogram<u64>>; 2] = [None, None];
    let mut period_error: [Option<Histogram<u64>>; 2] = [None, None];
    let mut probe_runs = 0u32;
    let mut haptic_rt = RtOutcome::NotRequested;
    for round in 0..args.rounds {
        // ABBA: the order alternates every round.
        let order = if round % 2 == 0 {
            [false, true]
        } else {
            [true, false]
        };
        for with_probe in order {
            let probe = with_probe.then_some(args.probe);
            let (rec, rt, runs) = phase(args.phase_seconds, rt_priority, probe)?;
            let k = usize::from(with_probe);
            pool(&mut compute[k], rec.compute_histogram())?;
            pool(&mut period_error[k], rec.period_error_histogram())?;
            probe_runs += runs;
            haptic_rt = rt;
            let c = figures(rec.compute_histogram());
            println!(
                "round {round} {}: {} ticks, compute p50 {:.1} / p99 {:.1} µs",
                if with_probe {
                    "with probe   "
                } else {
                    "without probe"
                },
                rec.ticks(),
                c[0],
                c[1]
            );
        }
    }
    let [Some(c0), Some(c1)] = &compute else {
        return Err("no phase ran".into());
    };
    let [Some(e0), Some(e1)] = &period_error else {
        return Err("no phase ran".into());
    };
    let (fc0, fc1, fe0, fe1) = (figures(c0), figures(c1), figures(e0), figures(e1));
    println!("\nhaptic priority: {haptic_rt}; probe runs completed: {probe_runs}\n");
    println!(
        "| haptic loop | ticks | compute p50 / p99 / p99.9 / max µs | period error p50 / p99 / p99.9 / max µs |"
    );
    println!("| --- | ---: | --- | --- |");
    for (name, h, c, e) in [
        ("without the probe", c0, fc0, fe0),
        ("with the probe", c1, fc1, fe1),
    ] {
        println!(
            "| {name} | {} | {:.1} / {:.1} / {:.1} / {:.1} | {:.1} / {:.1} / {:.1} / {:.1} |",
            h.len(),
            c[0],
            c[1],
            c[2],
            c[3],
            e[0],
            e[1],
            e[2],
            e[3]
        );
    }
    let ratio = fc1[1] / fc0[1];
    println!(
        "\ncompute p99 with ÷ without: {ratio:.3} ({:+.1}%; the bar is within 5%)",
        (ratio - 1.0) * 100.0
    );
    println!("load average after: {}", load_average());
    Ok(())
}
