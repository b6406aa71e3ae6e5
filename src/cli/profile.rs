//! `dynaclay profile`: runs the engine with the simulated arm between two runs of the platform
//! probe, prints the latency table, the haptic loop beside the probe and the readiness verdict
//! for 1 kHz and 4 kHz, and writes them on request; or compares two `latency.json` files.

use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use dynaclay_devices::{SimArmConfig, SimulatedArm};
use dynaclay_loops::{
    LatencyRecorder, ProfileDoc, compare_table, latency_png, latency_svg, profile_report,
};

use super::args::ProfileArgs;
use super::error::CliError;
use super::platform::PlatformWatch;
use crate::engine::{Engine, EngineConfig, HeadlessSink, ScriptPlan, build_clay};
use crate::io::bounded_read::read_regular_file;

/// The largest `latency.json` that `--compare` reads.
const MAX_PROFILE_JSON_BYTES: u64 = 16 * 1024 * 1024;

/// Runs the profile `args` asks for, or the comparison.
///
/// # Errors
/// When the engine cannot start or a loop fails, when an output cannot be written, or (for
/// `--compare`) when a file cannot be read or parsed.
pub fn profile(args: &ProfileArgs) -> Result<(), CliError> {
    if let Some(files) = &args.compare {
        let [a, b] = files.as_slice() else {
            return Err(CliError::Usage("--compare takes two files".into()));
        };
        print!("{}", compare_files(a, b)?);
        return Ok(());
    }
    run_profile(args)
}

fn read_doc(path: &Path) -> Result<ProfileDoc, CliError> {
    let bytes = read_regular_file(path, MAX_PROFILE_JSON_BYTES)
        .map_err(|e| CliError::bad_input(path.display().to_string(), e))?;
    let text = String::from_utf8(bytes)
        .map_err(|e| CliError::bad_input(format!("{}: not UTF-8", path.display()), e))?;
    ProfileDoc::from_json(&text).map_err(|e| CliError::bad_input(path.display().to_string(), e))
}

/// The per-figure ratio table of `b` to `a`, with a heading naming both files.
///
/// # Errors
/// [`CliError::Usage`] naming the file that cannot be read or parsed.
pub fn compare_files(a: &Path, b: &Path) -> Result<String, CliError> {
    let (doc_a, doc_b) = (read_doc(a)?, read_doc(b)?);
    Ok(format!(
        "A = {}\nB = {}\nB ÷ A below 1 means B is better.\n\n{}",
        a.display(),
        b.display(),
        compare_table(&doc_a, &doc_b)
    ))
}

/// CPU hog threads on every other core, stopped on drop.
struct Hogs {
    stop: Arc<AtomicBool>,
    threads: Vec<std::thread::JoinHandle<()>>,
}

impl Hogs {
    fn start(on: bool) -> Result<Self, CliError> {
        let mut hogs = Self {
            stop: Arc::new(AtomicBool::new(false)),
            threads: Vec::new(),
        };
        if !on {
            return Ok(hogs);
        }
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        for i in 0..cores.saturating_sub(1).max(1) {
            let stop = hogs.stop.clone();
            let thread = std::thread::Builder::new()
                .name(format!("cpu-hog-{i}"))
                .spawn(move || {
                    let mut x = 0u64;
                    // NOTE: Relaxed: the flag only ends the loop eventually.
                    while !stop.load(Ordering::Relaxed) {
                        x = std::hint::black_box(
                            x.wrapping_mul(6364136223846793005).wrapping_add(1),
                        );
                    }
                })
                .map_err(|e| CliError::output("cannot start a CPU hog", e))?;
            hogs.threads.push(thread);
        }
        Ok(hogs)
    }
}

impl Drop for Hogs {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        for h in self.threads.drain(..) {
            let _ = h.join();
        }
    }
}

fn run_profile(args: &ProfileArgs) -> Result<(), CliError> {
    let plan = ScriptPlan::builtin();
    let field = build_clay(&plan.clay).map_err(|e| CliError::output("clay fit failed", e))?;
    let arm_config = SimArmConfig::default();
    let mut config = EngineConfig::for_field(&field, &arm_config.info);
    config.haptic_rate_hz = args.rate_hz;
    config.haptics.tool_contact = plan.tool_contact;
    if !args.rt {
        config.haptic_rt_priority = None;
    }
    let trajectory = plan.trajectory(&config.map).map_err(CliError::Script)?;
    let device = Box::new(SimulatedArm::new(arm_config, trajectory));

    let hogs = Hogs::start(args.load)?;
    // Each probe (wake-up, then stalls) runs for a fifth of the engine's time, 0.2 to 2 s.
    let each = Duration::from_secs_f64((args.seconds * 0.2).clamp(0.2, 2.0));
    let mut watch = PlatformWatch::before(args.rate_hz, each, config.haptic_rt_priority)?;

    let engine = Engine::start(&config, field, device, Box::new(HeadlessSink::default()))
        .map_err(CliError::Engine)?;
    println!(
        "profiling {:.1} s at {:.0} Hz{}; haptic priority: {}",
        args.seconds,
        args.rate_hz,
        if args.load { " with CPU hogs" } else { "" },
        engine.haptic_rt()
    );
    let haptic_rt = engine.haptic_rt();
    watch.loops_running();
    let started = Instant::now();
    while started.elapsed() < Duration::from_secs_f64(args.seconds) && engine.is_alive() {
        std::thread::sleep(Duration::from_millis(50));
    }
    let cpu_busy = watch.loops_stopping();
    let report = engine.stop().map_err(CliError::Engine)?;
    let summaries = report.loops.iter().map(|r| r.summary()).collect();
    let judged = watch.after(summaries, haptic_rt, cpu_busy)?;
    drop(hogs);

    let text = profile_report(&judged.doc);
    print!("{text}");
    let c = report.counters;
    println!(
        "haptic ticks {}, simulation steps {}, graphics updates {}, stale ticks {}, device faults {}",
        c.haptic_ticks,
        c.sim_steps,
        c.graphics_updates,
        c.stale_ticks,
        c.device_read_faults + c.device_write_faults
    );
    if let Some(dir) = &args.out {
        let recorders: Vec<(&str, &LatencyRecorder)> = report
            .loops
            .iter()
            .map(|r| (r.config.name.as_str(), &r.recorder))
            .collect();
        // The probe run with the worse tail is drawn over the loops.
        for path in write_profile_files(dir, &judged.doc, &text, &recorders, judged.worse_probe())?
        {
            println!("wrote {}", path.display());
        }
    }
    Ok(())
}

/// Writes `latency.json`, `latency.md`, `latency.svg` and `latency.png` (the plots with `probe`
/// drawn over the loops) into `dir` (created if missing), each atomically.
fn write_profile_files(
    dir: &Path,
    doc: &ProfileDoc,
    text: &str,
    recorders: &[(&str, &LatencyRecorder)],
    probe: &LatencyRecorder,
) -> Result<Vec<std::path::PathBuf>, CliError> {
    let err = |p: &Path, e: &dyn std::fmt::Display| {
        CliError::output(p.display().to_string(), e.to_string())
    };
    std::fs::create_dir_all(dir).map_err(|e| err(dir, &e))?;
    let json_path = dir.join("latency.json");
    let json = doc.to_json().map_err(|e| err(&json_path, &e))?;
    crate::io::write_atomic(&json_path, json.as_bytes()).map_err(|e| err(&json_path, &e))?;
    let md_path = dir.join("latency.md");
    let md = format!("# dynaclay profile\n\n{text}");
    crate::io::write_atomic(&md_path, md.as_bytes()).map_err(|e| err(&md_path, &e))?;
    let svg_path = dir.join("latency.svg");
    let svg = latency_svg(recorders, Some(probe)).map_err(|e| err(&svg_path, &e))?;
    crate::io::write_atomic(&svg_path, svg.as_bytes()).map_err(|e| err(&svg_path, &e))?;
    let png_path = dir.join("latency.png");
    let png = latency_png(recorders, Some(probe)).map_err(|e| err(&png_path, &e))?;
    crate::io::write_atomic(&png_path, &png).map_err(|e| err(&png_path, &e))?;
    Ok(vec![json_path, md_path, svg_path, png_path])
}

#[cfg(test)]
mod tests {
    use dynaclay_loops::{LoopSummary, RtOutcome};

    use super::*;

    #[test]
    fn compare_reads_two_files_and_names_a_bad_one() {
        let dir = std::env::temp_dir().join(format!("dynaclay-compare-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("dir");
        let a = dir.join("a.json");
        let b = dir.join("b.json");
        let bad = dir.join("bad.json");
        let doc = |p99: f64| {
            let mut s = dynaclay_loops::LatencyStats {
                ticks: 100,
                ..Default::default()
            };
            s.period_error.p99_us = p99;
            ProfileDoc {
                loops: vec![LoopSummary {
                    name: "haptic".into(),
                    rt_priority: RtOutcome::NotRequested,
                    pinning: dynaclay_loops::PinOutcome::NotRequested,
                    stats: s,
                }],
                ..ProfileDoc::default()
            }
        };
        std::fs::write(&a, doc(4.0).to_json().expect("json")).expect("write a");
        std::fs::write(&b, doc(1.0).to_json().expect("json")).expect("write b");
        std::fs::write(&bad, "{\"loops\": 3}").expect("write bad");
        let table = compare_files(&a, &b).expect("compare");
        assert!(
            table.contains("| haptic | period error p99 µs | 4.00 | 1.00 | 0.25 |"),
            "{table}"
        );
        let e = compare_files(&a, &bad).expect_err("bad file").to_string();
        assert!(e.contains("bad.json"), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
