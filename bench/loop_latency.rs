//! Loop-latency benchmark: runs the 1 kHz haptic loop for N seconds per scenario — with and
//! without a CPU hog on the other core, at SCHED_FIFO and at normal priority — and reports
//! period error p50 / p99 / p99.9 / max, compute p99 and ticks later than 1 ms and 2 ms.
//!
//! Usage: `cargo bench --bench loop_latency -- [--seconds N] [--out DIR] [--only WORKLOAD]
//! [--spin-us N]` (`--spin-us` overrides the runner's spin margin), or the
//! environment variables `DYNACLAY_BENCH_SECONDS` (default 30) and `DYNACLAY_BENCH_OUT`
//! (default `target/tmp/loop_latency`). Writes `loop_latency.json`, `loop_latency.md` and
//! `loop_latency.svg` there and prints the table.
//!
//! Workloads: each is a function that runs the haptic loop (configured by the harness: rate,
//! priority, core) for the given time and returns its report. "bare" is the haptic loop alone
//! with a representative small compute body on `dynaclay_loops`' runner; "std-sleep" is the
//! obvious alternative, the same body on a `std::thread::sleep` loop with the same deadlines. A
//! whole-engine workload plugs in as another entry of `workloads()`.
//!
//! Before the scenarios, a probe spins at SCHED_FIFO reading the clock and reports the time the
//! environment (hypervisor, interrupts, RT throttling) took from it: no loop can do better.
//!
//! Where it is optimistic: the bare body touches a small lattice that stays in cache; the hog
//! is one spinning thread, not memory traffic. Where it is pessimistic: every tick is measured,
//! including the first (page faults, cold caches), and the VM's other tenants are not stopped.

use std::hint::black_box;
use std::ops::ControlFlow;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use dynaclay::field::BSplineLattice;
use dynaclay_loops::{
    DEFAULT_RT_PRIORITY, LatencyRecorder, LoopConfig, LoopReport, LoopSummary, PinOutcome,
    RtOutcome, SnapshotReader, SnapshotWriter, StopFlag, StopReason, TickInfo, TickTiming,
    markdown_table, pin_current_thread, request_realtime, snapshot_channel, spawn_loop_with,
    summaries_to_json, write_latency_svg,
};
use glam::Vec3;
use serde::Serialize;

/// Runs the haptic loop under `config` for `duration` and returns its report.
type Workload = fn(&LoopConfig, Duration) -> Result<LoopReport, String>;

/// The workloads measured, by name.
fn workloads() -> Vec<(&'static str, Workload)> {
    vec![
        ("bare", bare_haptic_loop),
        ("std-sleep", std_sleep_loop),
        ("engine", full_engine),
    ]
}

// ---------------------------------------------------------------------------------------------
// The whole engine: haptic, simulation and graphics loops with the simulated arm pushing
// strokes into the default block for the whole run; the haptic loop's report is returned.

/// A script of back-and-forth pushes along the block's top, one every 2.5 s, filling `seconds`.
fn engine_script(seconds: f64) -> String {
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

/// Runs the whole engine under the harness's haptic settings (rate, priority; the engine does
/// not pin its threads, so the core setting is not applied).
fn full_engine(config: &LoopConfig, duration: Duration) -> Result<LoopReport, String> {
    use dynaclay::dynamics::Material;
    use dynaclay::engine::{Engine, EngineConfig, HeadlessSink, ScriptPlan, build_clay};
    use dynaclay::io::parse_script;
    use dynaclay_devices::{SimArmConfig, SimulatedArm};

    let script = parse_script(&engine_script(duration.as_secs_f64()), "<bench>")
        .map_err(|e| e.to_string())?;
    let plan = ScriptPlan::new(
        &script,
        "<bench>",
        std::path::Path::new("."),
        &[],
        Material::PLASTIC,
    )
    .map_err(|e| e.to_string())?;
    let field = build_clay(&plan.clay).map_err(|e| e.to_string())?;
    let arm_config = SimArmConfig::default();
    let mut engine_config = EngineConfig::for_field(&field, &arm_config.info);
    engine_config.haptics.tool_contact = plan.tool_contact;
    engine_config.haptic_rate_hz = config.rate_hz;
    engine_config.haptic_rt_priority = config.rt_priority;
    let trajectory = plan
        .trajectory(&engine_config.map)
        .map_err(|e| e.to_string())?;
    let device = Box::new(SimulatedArm::new(arm_config, trajectory));
    let engine = Engine::start(
        &engine_config,
        field,
        device,
        Box::new(HeadlessSink::default()),
    )
    .map_err(|e| e.to_string())?;
    std::thread::sleep(duration);
    let mut report = engine.stop().map_err(|e| e.to_string())?;
    let mut haptic = report.loops.remove(0);
    haptic.config.name = config.name.clone();
    Ok(haptic)
}

// ---------------------------------------------------------------------------------------------
// The bare haptic loop: read a field snapshot, integrate contact forces, filter, publish.

/// 4-point Gauss–Legendre nodes (±0.3399810436, ±0.8611363116) and weights (0.6521451549,
/// 0.3478548451) on [−1, 1], mapped to [0, 1].
const GL_NODES: [f32; 4] = [
    (1.0 - 0.861_136_3) * 0.5,
    (1.0 - 0.339_981) * 0.5,
    (1.0 + 0.339_981) * 0.5,
    (1.0 + 0.861_136_3) * 0.5,
];
const GL_WEIGHTS: [f32; 4] = [
    0.347_854_8 * 0.5,
    0.652_145_2 * 0.5,
    0.652_145_2 * 0.5,
    0.347_854_8 * 0.5,
];

/// A 24³ lattice holding a ball of clay, built once before the loop starts.
fn ball_lattice() -> BSplineLattice {
    let n = 24usize;
    let spacing = 1.0 / (n as f32 - 3.0);
    let origin = Vec3::splat(-spacing);
    let mut coeffs = vec![0.0f32; n * n * n];
    let centre = Vec3::splat(0.5);
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let p = origin + spacing * Vec3::new(i as f32, j as f32, k as f32);
                let d = (p - centre).length();
                coeffs[i + n * (j + n * k)] = (0.5 + (0.3 - d) * 4.0).clamp(0.0, 1.0);
            }
        }
    }
    BSplineLattice::from_coeffs([n, n, n], spacing, origin, coeffs)
        .unwrap_or_else(|e| unreachable!("constant lattice is valid: {e}"))
}

/// Tool sample the haptic loop publishes each tick (position, force, tick index).
#[derive(Clone, Copy, Debug, Default)]
struct ToolSample {
    position: Vec3,
    force_n: Vec3,
    tick: u64,
}

/// Contact force on a spherical tool at `tip`: for each of 14 directions, the field integrated
/// along the tool radius with 4-point Gauss–Legendre (Hua & Qin eq. 6), pushing the tool out.
fn contact_force(field: &BSplineLattice, tip: Vec3, radius: f32, dirs: &[Vec3; 14]) -> Vec3 {
    let mut force = Vec3::ZERO;
    for &d in dirs {
        let mut integral = 0.0f32;
        for (t, w) in GL_NODES.iter().zip(GL_WEIGHTS) {
            let v = field.value(tip + d * (radius * t));
            integral += w * (v - field.iso).max(0.0);
        }
        force -= d * (integral * radius * 40.0);
    }
    let (_, grad) = field.value_and_gradient(tip);
    force + grad * 1e-3
}

const MAX_FORCE_N: f32 = 3.0;

/// Builds the haptic tick body (on the loop thread): latest field snapshot → contact force →
/// safety filter → publish the tool sample.
fn haptic_body(
    mut tool_tx: SnapshotWriter<ToolSample>,
) -> impl FnMut(&TickInfo) -> ControlFlow<()> {
    let field = ball_lattice();
    // No simulation runs here: the field snapshot stays at its first version.
    let (_field_tx, mut field_rx) = snapshot_channel(&field);
    let mut dirs = [Vec3::ZERO; 14];
    for (i, a) in [Vec3::X, Vec3::Y, Vec3::Z].iter().enumerate() {
        dirs[2 * i] = *a;
        dirs[2 * i + 1] = -*a;
    }
    let mut n = 6;
    for sx in [-1.0f32, 1.0] {
        for sy in [-1.0f32, 1.0] {
            for sz in [-1.0f32, 1.0] {
                dirs[n] = Vec3::new(sx, sy, sz).normalize();
                n += 1;
            }
        }
    }
    let mut last_force = Vec3::ZERO;
    move |t: &TickInfo| {
        let snap = field_rx.latest();
        // The tip circles the ball just inside its surface (radius 0.3 about the centre).
        let phase = t.index as f32 * 2e-3;
        let tip = Vec3::new(0.5 + 0.28 * phase.cos(), 0.5 + 0.28 * phase.sin(), 0.5);
        let raw = contact_force(&snap.value, tip, 0.05, &dirs);
        // Safety filter: NaN → 0, clamp magnitude, slew limit of 0.05 N per tick.
        let raw = if raw.is_finite() { raw } else { Vec3::ZERO };
        let clamped = raw.clamp_length_max(MAX_FORCE_N);
        let force = last_force + (clamped - last_force).clamp_length_max(0.05);
        last_force = force;
        tool_tx.write_with(|s| {
            *s = ToolSample {
                position: tip,
                force_n: force,
                tick: t.index,
            }
        });
        black_box(force);
        ControlFlow::Continue(())
    }
}

/// Checks that the last published tool sample is the last tick's, with a bounded force.
fn check_last_sample(
    tool_rx: &mut SnapshotReader<ToolSample>,
    report: &LoopReport,
) -> Result<(), String> {
    let last = tool_rx.latest();
    let ticks = report.recorder.ticks();
    if last.value.tick + 1 != ticks || last.version != ticks {
        return Err(format!(
            "last tool sample is tick {} (version {}), loop ran {ticks} ticks",
            last.value.tick, last.version
        ));
    }
    if !last.value.force_n.is_finite()
        || last.value.force_n.length() > MAX_FORCE_N * 1.001
        || !last.value.position.is_finite()
    {
        return Err(format!("bad tool sample {:?}", last.value));
    }
    Ok(())
}

/// The haptic body on the crate's runner (spin_sleep, absolute deadlines).
fn bare_haptic_loop(config: &LoopConfig, duration: Duration) -> Result<LoopReport, String> {
    let (tool_tx, mut tool_rx) = snapshot_channel(&ToolSample::default());
    let handle =
        spawn_loop_with(config.clone(), move || haptic_body(tool_tx)).map_err(|e| e.to_string())?;
    std::thread::sleep(duration);
    let report = handle.stop_and_join().map_err(|e| e.to_string())?;
    check_last_sample(&mut tool_rx, &report)?;
    Ok(report)
}

/// Baseline: the same body on a plain `std::thread::sleep` loop with the same absolute
/// deadlines and skip policy (no spin), measured with the same recorder.
fn std_sleep_loop(config: &LoopConfig, duration: Duration) -> Result<LoopReport, String> {
    let (tool_tx, mut tool_rx) = snapshot_channel(&ToolSample::default());
    let stop = StopFlag::new();
    let stop_loop = stop.clone();
    let config_loop = config.clone();
    let period = config.try_period().map_err(|e| e.to_string())?;
    let thread = std::thread::Builder::new()
        .name(config.name.clone())
        .spawn(move || {
            let pin = config_loop
                .core
                .map_or(PinOutcome::NotRequested, pin_current_thread);
            let rt = config_loop
                .rt_priority
                .map_or(RtOutcome::NotRequested, request_realtime);
            let mut body = haptic_body(tool_tx);
            let mut recorder = LatencyRecorder::new(period);
            let start = Instant::now();
            let period_ns = u64::try_from(period.as_nanos()).unwrap_or(u64::MAX).max(1);
            let (mut k, mut index, mut skipped_next) = (0u64, 0u64, 0u64);
            let mut prev_woke = start;
            while !stop_loop.is_stopped() {
                let scheduled = start + Duration::from_nanos(period_ns.saturating_mul(k));
                if let Some(wait) = scheduled.checked_duration_since(Instant::now()) {
                    std::thread::sleep(wait);
                }
                let woke = Instant::now();
                let skipped_before = skipped_next;
                let info = TickInfo {
                    index,
                    scheduled,
                    woke,
                    dt: if index == 0 { period } else { woke - prev_woke },
                    skipped_before,
                    nominal_period: period,
                };
                let _ = body(&info);
                recorder.record_tick(&TickTiming {
                    scheduled,
                    woke,
                    compute: woke.elapsed(),
                    skipped_before,
                });
                prev_woke = woke;
                index += 1;
                // Skip policy: the next deadline is the first one still ahead of now.
                let behind = u64::try_from(
                    Instant::now()
                        .saturating_duration_since(scheduled)
                        .as_nanos()
                        / u128::from(period_ns),
                )
                .unwrap_or(0);
                skipped_next = behind;
                k += 1 + behind;
            }
            LoopReport {
                config: config_loop,
                rt,
                pin,
                stop_reason: StopReason::StopRequested,
                recorder,
            }
        })
        .map_err(|e| e.to_string())?;
    std::thread::sleep(duration);
    stop.stop();
    let report = thread
        .join()
        .map_err(|_| "std-sleep loop panicked".to_owned())?;
    check_last_sample(&mut tool_rx, &report)?;
    Ok(report)
}

/// How much time the environment takes from a thread that never sleeps: spins at SCHED_FIFO on
/// `core` for `duration` reading the clock, and sums the gaps between reads longer than 20 µs
/// (hypervisor preemption, interrupts, higher-priority kernel work). Sets the floor no loop can
/// beat.
#[derive(Debug, Serialize)]
struct ClockGaps {
    rt: RtOutcome,
    seconds: f64,
    gaps_over_20us: u64,
    gaps_over_1ms: u64,
    lost_ms: f64,
    largest_gap_us: f64,
}

fn probe_clock_gaps(core: Option<usize>, duration: Duration) -> Option<ClockGaps> {
    std::thread::spawn(move || {
        if let Some(c) = core {
            let _ = pin_current_thread(c);
        }
        let rt = request_realtime(DEFAULT_RT_PRIORITY);
        let (mut n20, mut n1ms, mut lost, mut largest) =
            (0u64, 0u64, Duration::ZERO, Duration::ZERO);
        let mut spun = Duration::ZERO;
        // Spin in 400 ms bursts with 200 ms rests, so the kernel's real-time throttling (by
        // default 950 ms of every 1 s for SCHED_FIFO) never kicks in and only foreign gaps count.
        while spun < duration {
            let burst = (duration - spun).min(Duration::from_millis(400));
            let start = Instant::now();
            let mut last = start;
            while last - start < burst {
                let now = Instant::now();
                let gap = now - last;
                if gap > Duration::from_micros(20) {
                    n20 += 1;
                    lost += gap;
                    largest = largest.max(gap);
                    if gap > Duration::from_millis(1) {
                        n1ms += 1;
                    }
                }
                last = now;
            }
            spun += last - start;
            std::thread::sleep(Duration::from_millis(200));
        }
        ClockGaps {
            rt,
            seconds: duration.as_secs_f64(),
            gaps_over_20us: n20,
            gaps_over_1ms: n1ms,
            lost_ms: lost.as_secs_f64() * 1e3,
            largest_gap_us: largest.as_secs_f64() * 1e6,
        }
    })
    .join()
    .ok()
}

// ---------------------------------------------------------------------------------------------
// Harness.

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
enum Load {
    Idle,
    BusyOtherCore,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
enum Priority {
    Fifo,
    Normal,
}

/// A CPU hog spinning on core `core` until dropped.
struct Hog {
    stop: Arc<AtomicBool>,
    thread: Option<std::thread::JoinHandle<PinOutcome>>,
}

impl Hog {
    fn start(core: usize) -> Self {
        let stop = Arc::new(AtomicBool::new(false));
        let flag = Arc::clone(&stop);
        let thread = std::thread::Builder::new()
            .name("cpu-hog".into())
            .spawn(move || {
                let pin = pin_current_thread(core);
                let mut x = 1u64;
                while !flag.load(Ordering::Relaxed) {
                    for _ in 0..10_000 {
                        x = black_box(x.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1));
                    }
                }
                pin
            })
            .ok();
        Self { stop, thread }
    }

    fn stop(mut self) -> Option<PinOutcome> {
        self.stop.store(true, Ordering::Relaxed);
        self.thread.take().and_then(|t| t.join().ok())
    }
}

impl Drop for Hog {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
    }
}

#[derive(Serialize)]
struct ScenarioResult {
    workload: String,
    load: Load,
    priority: Priority,
    hog_pinning: Option<PinOutcome>,
    seconds: f64,
    summary: LoopSummary,
}

struct Args {
    seconds: f64,
    spin_us: Option<u32>,
    out: PathBuf,
    only: Option<String>,
}

fn parse_args() -> Result<Args, String> {
    let mut seconds = match std::env::var("DYNACLAY_BENCH_SECONDS") {
        Ok(v) => v
            .parse::<f64>()
            .map_err(|e| format!("DYNACLAY_BENCH_SECONDS={v:?}: {e}"))?,
        Err(_) => 30.0,
    };
    let mut out = std::env::var_os("DYNACLAY_BENCH_OUT")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("loop_latency"));
    let mut only = None;
    let mut spin_us = None;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--seconds" => {
                let v = args.next().ok_or("--seconds needs a value")?;
                seconds = v.parse().map_err(|e| format!("--seconds {v:?}: {e}"))?;
            }
            "--out" => out = PathBuf::from(args.next().ok_or("--out needs a directory")?),
            "--spin-us" => {
                let v = args.next().ok_or("--spin-us needs a value")?;
                spin_us = Some(v.parse().map_err(|e| format!("--spin-us {v:?}: {e}"))?);
            }
            "--only" => only = Some(args.next().ok_or("--only needs a workload name")?),
            // cargo bench passes --bench to harness = false targets.
            "--bench" => {}
            other => {
                return Err(format!(
                    "unknown argument {other:?} (expected --seconds, --out, --only, --spin-us)"
                ));
            }
        }
    }
    if !(seconds.is_finite() && seconds > 0.0) {
        return Err(format!("seconds must be positive, got {seconds}"));
    }
    Ok(Args {
        seconds,
        spin_us,
        out,
        only,
    })
}

fn main() {
    if let Err(e) = run() {
        eprintln!("loop_latency: {e}");
        std::process::exit(1);
    }
}

fn run() -> Result<(), String> {
    let args = parse_args()?;
    let cores = core_affinity_count();
    // The loop takes the last core, the hog the first: "the other core" on a 2-core machine.
    let loop_core = cores.saturating_sub(1);
    let hog_core = 0;
    let duration = Duration::from_secs_f64(args.seconds);
    let load_avg = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    println!(
        "loop_latency: {} s per scenario, {cores} cores, loop on core {loop_core}, hog on core \
         {hog_core}; load average before: {}",
        args.seconds,
        load_avg.trim()
    );

    let loop_pin = (cores > 1).then_some(loop_core);
    let gaps = probe_clock_gaps(loop_pin, duration.min(Duration::from_secs(3)));
    if let Some(g) = &gaps {
        println!(
            "environment: a thread spinning at {} lost {:.1} ms of {:.0} s to {} gaps > 20 µs \
             ({} > 1 ms, largest {:.0} µs)",
            g.rt, g.lost_ms, g.seconds, g.gaps_over_20us, g.gaps_over_1ms, g.largest_gap_us
        );
    }

    let mut results = Vec::new();
    let mut recorders = Vec::new();
    for (workload, run_workload) in workloads() {
        if args.only.as_deref().is_some_and(|o| o != workload) {
            continue;
        }
        for load in [Load::Idle, Load::BusyOtherCore] {
            for priority in [Priority::Fifo, Priority::Normal] {
                let name = format!(
                    "{workload} / {} / {}",
                    match load {
                        Load::Idle => "idle",
                        Load::BusyOtherCore => "other core busy",
                    },
                    match priority {
                        Priority::Fifo => "FIFO",
                        Priority::Normal => "normal",
                    }
                );
                let mut config = LoopConfig::new("haptic").with_rate_hz(1000.0);
                if let Some(spin_us) = args.spin_us {
                    config.spin_margin_us = spin_us;
                }
                if let Some(core) = loop_pin {
                    config = config.with_core(core);
                }
                if priority == Priority::Fifo {
                    config = config.with_rt_priority(DEFAULT_RT_PRIORITY);
                }
                let hog = (load == Load::BusyOtherCore).then(|| Hog::start(hog_core));
                let started = Instant::now();
                let report = run_workload(&config, duration).map_err(|e| format!("{name}: {e}"))?;
                let seconds = started.elapsed().as_secs_f64();
                let hog_pinning = hog.and_then(Hog::stop);
                let mut summary = report.summary();
                summary.name = name.clone();
                eprintln!("  {name}: {} ({})", summary.rt_priority, summary.pinning);
                results.push(ScenarioResult {
                    workload: workload.to_owned(),
                    load,
                    priority,
                    hog_pinning,
                    seconds,
                    summary,
                });
                recorders.push((name, report.recorder));
            }
        }
    }

    let summaries: Vec<LoopSummary> = results.iter().map(|r| r.summary.clone()).collect();
    let table = markdown_table(&summaries);
    println!("\n{table}");
    print_floors(&results);

    std::fs::create_dir_all(&args.out)
        .map_err(|e| format!("creating {}: {e}", args.out.display()))?;
    let json_path = args.out.join("loop_latency.json");
    #[derive(Serialize)]
    struct Doc<'a> {
        command_seconds: f64,
        load_average_before: &'a str,
        clock_gaps: Option<&'a ClockGaps>,
        scenarios: &'a [ScenarioResult],
    }
    let doc = Doc {
        command_seconds: args.seconds,
        load_average_before: load_avg.trim(),
        clock_gaps: gaps.as_ref(),
        scenarios: &results,
    };
    let json = serde_json::to_string_pretty(&doc).map_err(|e| e.to_string())?;
    dynaclay_files::write_atomic(&json_path, json.as_bytes()).map_err(|e| e.to_string())?;
    let md_path = args.out.join("loop_latency.md");
    dynaclay_files::write_atomic(&md_path, table.as_bytes()).map_err(|e| e.to_string())?;
    let svg_path = args.out.join("loop_latency.svg");
    let refs: Vec<(&str, &LatencyRecorder)> =
        recorders.iter().map(|(n, r)| (n.as_str(), r)).collect();
    write_latency_svg(&svg_path, &refs, None).map_err(|e| e.to_string())?;
    // Also the plain summaries, in the format the engine's `latency.json` uses.
    let plain = summaries_to_json(&summaries).map_err(|e| e.to_string())?;
    let plain_path = args.out.join("loop_latency_summaries.json");
    dynaclay_files::write_atomic(&plain_path, plain.as_bytes()).map_err(|e| e.to_string())?;
    println!(
        "wrote {}, {}, {}, {}",
        json_path.display(),
        md_path.display(),
        svg_path.display(),
        plain_path.display()
    );
    Ok(())
}

/// Checks the floors for the SCHED_FIFO, other-core-busy scenarios.
fn print_floors(results: &[ScenarioResult]) {
    for r in results
        .iter()
        .filter(|r| r.load == Load::BusyOtherCore && r.priority == Priority::Fifo)
    {
        let s = &r.summary.stats;
        let checks = [
            ("period error p99 <= 10 us", s.period_error.p99_us <= 10.0),
            (
                "period error p99.9 <= 100 us",
                s.period_error.p999_us <= 100.0,
            ),
            ("period error max <= 500 us", s.period_error.max_us <= 500.0),
            ("compute p99 <= 20 us", s.compute.p99_us <= 20.0),
            ("no tick later than 1 ms", s.late_over_1ms == 0),
        ];
        for (what, ok) in checks {
            println!(
                "floor [{}] {what}: {}",
                r.summary.name,
                if ok { "met" } else { "MISSED" }
            );
        }
        if !r.summary.rt_priority.is_granted() {
            println!("note: {}", r.summary.rt_priority);
        }
    }
}

fn core_affinity_count() -> usize {
    std::thread::available_parallelism().map_or(1, usize::from)
}
