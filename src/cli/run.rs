//! `dynaclay run`: a headless session from a script, written to an output directory.

use super::error::CliError;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use crossbeam::channel::RecvTimeoutError;

use dynaclay_devices::record::{RecordingDevice, ReplayDevice, ScheduleGap};
use dynaclay_devices::spec::DeviceSpec;
use dynaclay_devices::{HapticDevice, SimArmConfig, SimulatedArm};

use super::args::RunArgs;
use super::outputs::{ExtraOutputs, RunOutputs, write_outputs};
use super::platform::{PlatformWatch, RUN_PROBE_EACH};
use crate::engine::{
    Engine, EngineConfig, EngineError, HeadlessSink, IoReport, Lockstep, ScheduledReplay,
    ScriptDriver, ScriptPlan, StartOptions, build_clay, builtin_script,
};
use crate::io::{
    Autosave, MaterialFields, OutputKind, OutputRule, Script, ScriptError, Session, load_script,
    load_session, recovery_to_use,
};

/// The session file a run writes into its output directory (autosave keeps its recovery
/// file beside it).
pub const SESSION_FILE: &str = "session.dclay";

/// Runs a headless session and writes its outputs.
///
/// The script is laid out on the device clock (see [`ScriptPlan`]): its strokes drive the
/// simulated arm and its other steps are sent to the simulation when their time comes.
/// Autosave writes `DIR/session.dclay.recovery` during the run; a recovery file newer than
/// `DIR/session.dclay` left by a crashed run stops the next run unless `--recover` starts
/// from it.
///
/// # Errors
/// A [`CliError`] naming what failed (argument, script line or step, device, output path).
pub fn run(args: &RunArgs) -> Result<RunOutputs, CliError> {
    if args.png.is_some() {
        // Refused before the run, not after it: the image's size is known now.
        super::budget::MemoryBudget::from_flag(args.memory_budget_mib)
            .check_image(args.image.width, args.image.height)
            .map_err(CliError::OverBudget)?;
    }
    let (script, file, base_dir) = match &args.script {
        Some(path) => (
            load_script(path).map_err(CliError::Script)?,
            path.display().to_string(),
            path.parent().map_or_else(PathBuf::new, Path::to_path_buf),
        ),
        None => (
            builtin_script(),
            "<built-in>".to_owned(),
            PathBuf::from("."),
        ),
    };
    for note in &script.deprecated {
        eprintln!("warning: {note}");
    }
    let spec: DeviceSpec = args
        .device
        .parse()
        .map_err(|e: dynaclay_devices::spec::SpecError| CliError::bad_input("--device", e))?;
    let session_path = args.out.join(SESSION_FILE);
    let start = starting_session(args.recover, &script, &base_dir, &session_path)?;
    let plan = ScriptPlan::new(
        &script,
        &file,
        &base_dir,
        &start.tools,
        start.material.uniform,
    )
    .map_err(CliError::Script)?;
    check_run_outputs(args, &script, &plan, &base_dir, &spec)?;
    plan.check_budget(&start.clay).map_err(CliError::Script)?;
    let seconds = args.seconds.unwrap_or(plan.seconds);
    let field = start.clay.density.clone();
    // A replay is checked whole before anything is made: exact (as scheduled) unless lockstep
    // is asked for, and a schedule that cannot drive an exact replay refused unless lockstep
    // is asked for (`gap` says why it is not used).
    let mut replay = match &spec {
        DeviceSpec::Replay { file } => Some(checked_replay(file, args.lockstep)?),
        _ => None,
    };
    if args.out.exists() && !args.out.is_dir() {
        return Err(CliError::Usage(format!(
            "--out {}: exists and is not a directory; --out names the folder the run writes into",
            args.out.display()
        )));
    }
    std::fs::create_dir_all(&args.out)
        .map_err(|e| CliError::output(format!("{}: cannot create", args.out.display()), e))?;

    // Lockstep needs a device whose every read is one fresh tick of its own clock: the
    // simulated arm, a replay, the vendor-library arms (HD's servo runs one frame per read;
    // each DHD read is one exchange with the arm) and the serial arms that answer each command
    // with one reply, their samples stamped by reply count (the Falcon, the 2DIY).
    let ticks_per_read = matches!(
        spec,
        DeviceSpec::OpenHaptics { .. }
            | DeviceSpec::Dhd { .. }
            | DeviceSpec::Falcon { .. }
            | DeviceSpec::TwoDiy { .. }
    );
    if args.lockstep
        && !ticks_per_read
        && !matches!(spec, DeviceSpec::Sim | DeviceSpec::Replay { .. })
    {
        return Err(CliError::Usage(format!(
            "--lockstep runs the simulated arm, a replay, touch, phantom, dhd, falcon or 2diy \
             on the device's own clock; device {} runs in real time",
            args.device
        )));
    }
    let (device, info): (Box<dyn HapticDevice>, _) = match &spec {
        DeviceSpec::Sim if args.lockstep => {
            let arm_config = SimArmConfig::default();
            let map = EngineConfig::for_clay(&field, &arm_config.info).map;
            let trajectory = plan.trajectory(&map).map_err(CliError::Script)?;
            // One sample per step of the arm's clock for the whole session.
            let samples = (seconds * 1e6 / arm_config.step_us as f64).ceil() as usize;
            let arm = SimulatedArm::new(arm_config, trajectory);
            let device: Box<dyn HapticDevice> = match &args.record {
                Some(path) => Box::new(
                    RecordingDevice::create(arm, path)
                        .map_err(|e| CliError::output(path.display().to_string(), e))?,
                ),
                None => Box::new(arm),
            };
            return run_lockstep(args, &plan, &start, &session_path, device, samples);
        }
        DeviceSpec::Sim => {
            let arm_config = SimArmConfig::default();
            let info = arm_config.info.clone();
            let map = EngineConfig::for_clay(&field, &info).map;
            let trajectory = plan.trajectory(&map).map_err(CliError::Script)?;
            (Box::new(SimulatedArm::new(arm_config, trajectory)), info)
        }
        DeviceSpec::Replay { .. } => {
            let (device, how) = replay.take().expect("loaded above for a replay");
            let unused = match how {
                ReplayUse::Scheduled => {
                    return run_scheduled_replay(args, &plan, &start, &session_path, device);
                }
                ReplayUse::Lockstep { unused } => unused,
            };
            let samples = device.read_count();
            let outputs = run_lockstep(
                args,
                &plan,
                &start,
                &session_path,
                Box::new(device),
                samples,
            )?;
            match unused {
                None => {
                    say!("replayed in lockstep, as asked (the recording's schedule was not used)");
                }
                Some(gap) => say!("replayed in lockstep, as asked, not as scheduled: {gap}"),
            }
            return Ok(outputs);
        }
        hw if args.lockstep => {
            let mut options = dynaclay_devices::open::DriverOptions::from_env().for_lockstep();
            if let Some(file) = &args.falcon_firmware {
                options.falcon.firmware = Some(file.clone());
            }
            let device = dynaclay_devices::open::build_driver(hw, &options)
                .map_err(|e| CliError::device(args.device.clone(), e))?;
            // One sample per servo tick of the arm for the whole session (1 kHz where the arm
            // does not say its rate before it is open).
            let rate_hz = Some(f64::from(device.info().sample_rate_hz))
                .filter(|r| r.is_finite() && *r > 0.0)
                .unwrap_or(1000.0);
            let samples = (seconds * rate_hz).ceil() as usize;
            let device: Box<dyn HapticDevice> = match &args.record {
                Some(path) => Box::new(
                    RecordingDevice::create(device, path)
                        .map_err(|e| CliError::output(path.display().to_string(), e))?,
                ),
                None => device,
            };
            return run_lockstep(args, &plan, &start, &session_path, device, samples);
        }
        hw => {
            let mut options = dynaclay_devices::open::DriverOptions::from_env();
            if let Some(file) = &args.falcon_firmware {
                options.falcon.firmware = Some(file.clone());
            }
            let d = dynaclay_devices::open::build_driver(hw, &options)
                .map_err(|e| CliError::device(args.device.clone(), e))?;
            let info = d.info();
            (d, info)
        }
    };
    // A recording also notes the loops' schedule, so that its replay is exact.
    let (device, schedule): (Box<dyn HapticDevice>, _) = match &args.record {
        Some(path) => {
            let recorder = RecordingDevice::create(device, path)
                .map_err(|e| CliError::output(path.display().to_string(), e))?;
            let log = recorder.schedule_log();
            (Box::new(recorder), Some(log))
        }
        None => (device, None),
    };
    let mut config = EngineConfig::for_clay(&field, &info);
    config.sim.material = start.material.uniform;
    config.haptics.tool_contact = plan.tool_contact;
    if !args.rt {
        config.haptic_rt_priority = None;
    }
    let autosave = Autosave::new(
        &session_path,
        script.autosave.unwrap_or_default().into(),
        Instant::now(),
    );

    // The platform probe, short, before the loops and after them: the machine's side of the
    // latency report and the readiness verdict. A probe that cannot run costs the report its
    // probe, never the run.
    let mut watch = PlatformWatch::before(
        config.haptic_rate_hz,
        RUN_PROBE_EACH,
        config.haptic_rt_priority,
    )
    .map_err(|e| eprintln!("dynaclay: {e}; the latency report has no probe"))
    .ok();
    let engine = Engine::start_with(
        &config,
        field,
        device,
        Box::new(HeadlessSink::default()),
        StartOptions {
            autosave: Some(autosave),
            schedule,
        },
    )
    .map_err(|e| match e {
        EngineError::Device(d) => CliError::device(args.device.clone(), d),
        other => CliError::Engine(other),
    })?;
    let installed = install_session(&engine.commands(), &start, &session_path);
    dynaclay_loops::assert_not_in_tick("dynaclay run waiting for the session install");
    installed_or_stop(
        installed.recv_timeout(Duration::from_secs(10)),
        &session_path,
    )?;
    let rt = engine.haptic_rt();
    say!(
        "dynaclay run: {seconds:.1} s, script {file}, device {}, haptic priority: {rt}",
        args.device
    );
    note_short_run(seconds, &plan);
    let mut driver = ScriptDriver::new(&plan);
    let commands = engine.commands();
    let mut engine = engine;
    if let Some(w) = &mut watch {
        w.loops_running();
    }
    // No frames in a headless run: each new mesh stamp counts as drawn when its meshes were
    // ready, so the figures end at the meshes (mesh → frame is 0).
    let mut mesh_stamps = engine.take_mesh_stamps();
    let mut motion = crate::engine::MotionToPhoton::new();
    let started = Instant::now();
    while started.elapsed() < Duration::from_secs_f64(seconds) && engine.is_alive() {
        let sample = engine.latest_tool();
        driver.dispatch(&sample, &commands);
        if let Some(fresh) = mesh_stamps.as_mut().and_then(|s| s.try_fresh()) {
            let stamp = fresh.value;
            motion.frame(stamp.meshed_ns, &stamp);
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    let motion = motion.summary(HEADLESS_PRESENTER);
    drop(commands);
    let cpu_busy = watch.as_ref().and_then(PlatformWatch::loops_stopping);
    let report = engine
        .stop()
        .map_err(|e| keep_session_of_failed_run(e, &session_path))?;
    let summaries = report.loops.iter().map(|r| r.summary()).collect();
    let judged = watch.and_then(|w| {
        w.after(summaries, rt, cpu_busy)
            .map_err(|e| eprintln!("dynaclay: {e}; the latency report has no probe"))
            .ok()
    });
    if let Some(j) = &judged {
        say!("{}", j.headline());
    }
    let outputs = write_outputs(
        &args.out,
        &report,
        &config,
        &extras(args),
        judged.as_ref(),
        Some(&motion),
    )?;
    say_raw!("{}", outputs.describe());
    say!(
        "motion to photon ({} strokes, meshes only): hand → force p50 {:.0} ticks, first \
         visible change p50 {:.1} ms p95 {:.1} ms, settled shape p50 {:.1} ms p95 {:.1} ms",
        motion.strokes,
        motion.hand_to_force_ticks.p50,
        motion.first_visible_ms.p50,
        motion.first_visible_ms.p95,
        motion.settled_ms.p50,
        motion.settled_ms.p95
    );
    report_device_faults(&report.safety);
    report_budget_refusals(report.counters.budget_refusals, report.budget_refusal);
    finish_run(&session_path, &mut driver, &report.io)?;
    match report.device_close_error {
        Some(e) => Err(CliError::DeviceFault(e)),
        None => Ok(outputs),
    }
}

/// What draws the frames of a headless run's motion-to-photon figures.
const HEADLESS_PRESENTER: &str =
    "none (headless run: a change counts as shown when its meshes are ready)";

/// The optional outputs `args` ask for; `--png` with no file means `DIR/sculpt.png`.
fn extras(args: &RunArgs) -> ExtraOutputs {
    ExtraOutputs {
        ply: args.ply,
        stl: args.stl,
        png: args.png.as_ref().map(|file| {
            let path = file.clone().unwrap_or_else(|| args.out.join("sculpt.png"));
            (path, args.image.clone())
        }),
    }
}

/// The session a run starts from: the recovery file with `--recover`, else the script's clay
/// (the session its `[clay] session` names, relative to the script's folder `base_dir`, or a
/// fresh block or ball). A recovery file newer than the session (unsaved work of a crashed
/// run) stops a run without `--recover`, so it is never overwritten unseen.
fn starting_session(
    recover: bool,
    script: &crate::io::Script,
    base_dir: &Path,
    session_path: &Path,
) -> Result<Session, CliError> {
    let found =
        recovery_to_use(session_path, recover).map_err(|e| CliError::bad_input("--recover", e))?;
    match found {
        Some(r) => {
            let session = load_session(&r.path).map_err(|e| CliError::output("--recover", e))?;
            if session.clay.density.patches.is_empty() {
                return Err(CliError::Output(format!(
                    "--recover: {} holds no clay",
                    r.path.display()
                )));
            }
            say!(
                "dynaclay run: starting from recovery file {}",
                r.path.display()
            );
            Ok(session)
        }
        None => {
            let spec = script.clay.clone().unwrap_or_default();
            if let Some(file) = &spec.session {
                let path = base_dir.join(file);
                let session = load_session(&path).map_err(CliError::Session)?;
                if session.clay.density.patches.is_empty() {
                    return Err(CliError::Usage(format!(
                        "[clay] session = {}: the session holds no clay",
                        path.display()
                    )));
                }
                say!("dynaclay run: starting from {}", path.display());
                return Ok(session);
            }
            let clay =
                build_clay(&spec).map_err(|e| CliError::output("starting clay: fit failed", e))?;
            Ok(Session {
                clay: crate::tools::Clay::single(clay),
                material: MaterialFields::default(),
                ..Session::default()
            })
        }
    }
}

/// Checks every file the run writes against the output rule before anything runs: the
/// script's `save`, `particles`, `rbf` and `points` steps, `--record` and `--png`. None may be
/// the script, a file the script or the device reads, or a file of another kind; the steps'
/// real paths stay in the script's folder and the output directory unless `--allow-outside`.
fn check_run_outputs(
    args: &RunArgs,
    script: &Script,
    plan: &ScriptPlan,
    script_dir: &Path,
    spec: &DeviceSpec,
) -> Result<(), CliError> {
    let mut rule = OutputRule::new();
    if let Some(path) = &args.script {
        rule = rule.input("SCRIPT", path);
    }
    for (what, path) in script.input_files(script_dir) {
        rule = rule.input(what, &path);
    }
    if let DeviceSpec::Replay { file } = spec {
        rule = rule.input("--device replay", file);
    }
    if let Some(path) = &args.record {
        rule.check("--record", path, OutputKind::Recording)
            .map_err(CliError::OutputRefused)?;
        rule = rule.input("--record", path);
    }
    if let Some(Some(path)) = &args.png {
        rule.check("--png", path, OutputKind::Image)
            .map_err(CliError::OutputRefused)?;
    }
    let steps_rule = if args.allow_outside {
        rule
    } else {
        rule.within(script_dir).within(&args.out)
    };
    for event in &plan.events {
        if let Some((kind, path, output)) = event.action.output() {
            steps_rule.check(kind, path, output).map_err(|e| {
                CliError::Script(ScriptError {
                    file: plan.file.clone(),
                    line: plan.step_line(event.step),
                    column: None,
                    step: Some(event.step),
                    message: e.to_string(),
                })
            })?;
        }
    }
    Ok(())
}

/// Sends the whole starting session to the engine, so that every part of it (the paint, the
/// further patches, material grids, tool library and metadata) is in the session the run
/// hands back; the reply tells whether the engine took it.
fn install_session(
    commands: &crossbeam::channel::Sender<crate::engine::Command>,
    start: &Session,
    session_path: &Path,
) -> crossbeam::channel::Receiver<Result<String, crate::engine::CommandError>> {
    let (tx, rx) = crossbeam::channel::bounded(1);
    let mut session = start.clone();
    if session.meta.created_unix_s == 0 {
        session.meta.created_unix_s = crate::io::unix_now_s();
    }
    // A closed channel shows up as a missing reply below.
    let _ = commands.send(crate::engine::Command::Load {
        session: Box::new(session),
        source: session_path.to_path_buf(),
        keep_history: false,
        reply: Some(tx),
    });
    rx
}

/// Stops the run when the engine refused or never answered the starting session.
fn installed_or_stop(
    reply: Result<Result<String, crate::engine::CommandError>, RecvTimeoutError>,
    session_path: &Path,
) -> Result<(), CliError> {
    match reply {
        Ok(Ok(_)) => Ok(()),
        Ok(Err(e)) => Err(CliError::output("starting session", e)),
        Err(_) => Err(CliError::Output(format!(
            "starting session {}: the engine did not take it",
            session_path.display()
        ))),
    }
}

fn note_short_run(seconds: f64, plan: &ScriptPlan) {
    if seconds < plan.end_s {
        say!(
            "note: the run ends at {seconds:.1} s, before the script's last step ends at {:.1} s",
            plan.end_s
        );
    }
}

/// Tells stderr about device faults the run survived (force went to zero meanwhile), so
/// that they are not found only in `latency.md`.
fn report_device_faults(safety: &dynaclay_devices::SafetyCounters) {
    if safety.read_faults + safety.write_faults + safety.nonfinite > 0 {
        eprintln!(
            "dynaclay: the device faulted during the run and the engine carried on with zero \
             force: {} read fault(s), {} write fault(s), {} non-finite force(s) replaced by zero",
            safety.read_faults, safety.write_faults, safety.nonfinite
        );
    }
}

/// Tells stderr about edits the clay's budgets refused during the run (a stroke's region, a
/// tool's application, a growth: each left the clay as it was, or clipped to its box), with the
/// latest one's what and where; a headless run has no window to show them in.
fn report_budget_refusals(count: u64, latest: Option<crate::engine::BudgetRefusal>) {
    if let Some(latest) = latest.filter(|_| count > 0) {
        eprintln!(
            "dynaclay: warning: the clay's budgets refused or clipped an edit {count} time(s) \
             during the run (a held stroke is tried again at every step); the latest: {latest}"
        );
    }
}

/// After a finished run whose session was written: removes the recovery file, reports
/// failed autosaves and steps, and fails on a failed script step.
fn finish_run(
    session_path: &Path,
    driver: &mut ScriptDriver,
    io: &IoReport,
) -> Result<(), CliError> {
    // The session was saved normally: the recovery file holds nothing newer.
    let mut autosave = Autosave::new(session_path, Default::default(), Instant::now());
    autosave
        .discard(Instant::now())
        .map_err(|e| CliError::output("discarding the recovery file", e))?;
    for e in &io.errors {
        eprintln!("dynaclay: autosave or save failed: {e}");
    }
    driver.wait_for_exports();
    let unsent = driver.unsent_steps();
    if !unsent.is_empty() {
        say!("note: script steps {unsent:?} were not reached");
    }
    for w in driver.warnings() {
        eprintln!("dynaclay: warning: {w}");
    }
    for (step, note) in driver.notes() {
        say!("script step {step}: {note}");
    }
    let failures = driver.failures().to_vec();
    for e in failures.iter().skip(1) {
        eprintln!("dynaclay: script error: {e}");
    }
    match failures.into_iter().next() {
        Some(first) => Err(CliError::Script(first)),
        None => Ok(()),
    }
}

/// A run whose loops failed: the session the simulation handed back is written where
/// `--recover` finds it (the autosave's recovery file beside `session_path`), and the error
/// says so.
fn keep_session_of_failed_run(e: EngineError, session_path: &Path) -> CliError {
    let EngineError::LoopsFailed {
        session: Some(session),
        ..
    } = &e
    else {
        return CliError::Engine(e);
    };
    let recovery = crate::io::recovery_path_for(session_path);
    match crate::io::save_session(&recovery, session) {
        Ok(()) => CliError::output(
            format!(
                "the sculpt is kept in {} (run again with --recover to go on from it)",
                recovery.display()
            ),
            e,
        ),
        Err(save) => CliError::output(
            format!(
                "the engine failed ({e}), and the sculpt could not be kept in {}",
                recovery.display()
            ),
            save,
        ),
    }
}

/// How a recording is replayed.
enum ReplayUse {
    /// As its schedule says: exact.
    Scheduled,
    /// In lockstep, as asked; `unused` says why the schedule could not have been used, if it
    /// could not.
    Lockstep { unused: Option<ScheduleGap> },
}

/// Loads the recording at `file` and checks its schedule whole, before anything runs.
///
/// # Errors
/// [`CliError::DeviceFailed`] for a file that cannot be read; [`CliError::Usage`] (exit 2) for a
/// schedule that cannot drive an exact replay when lockstep was not asked for, naming the
/// file and the record.
fn checked_replay(file: &Path, lockstep: bool) -> Result<(ReplayDevice, ReplayUse), CliError> {
    let replay = ReplayDevice::load(file)
        .map_err(|e| CliError::device(format!("replaying {}", file.display()), e))?;
    let how = match (replay.schedule(), lockstep) {
        (Ok(_), false) => ReplayUse::Scheduled,
        (Ok(_), true) => ReplayUse::Lockstep { unused: None },
        (Err(gap), true) => ReplayUse::Lockstep { unused: Some(gap) },
        (Err(gap), false) => {
            return Err(CliError::Usage(format!(
                "--device replay:{}: {gap}; the replay could not be exact. Pass --lockstep to \
                 replay its samples in lockstep (exact for a recording of a --lockstep run; a \
                 threaded run's hand motion, not its field)",
                file.display()
            )));
        }
    };
    Ok((replay, how))
}

fn run_scheduled_replay(
    args: &RunArgs,
    plan: &ScriptPlan,
    start: &Session,
    session_path: &Path,
    replay: ReplayDevice,
) -> Result<RunOutputs, CliError> {
    let info = replay.info();
    let field = start.clay.density.clone();
    let config = single_thread_config(&field, &info, start, plan);
    let mut replay = ScheduledReplay::new(
        &config,
        field,
        replay,
        Box::new(HeadlessSink::default()),
        16,
    )
    .map_err(CliError::Engine)?;
    say!(
        "dynaclay run: {} ticks of {} as scheduled in the recorded run",
        replay.tick_count(),
        args.device
    );
    let mut driver = ScriptDriver::new(plan);
    let commands = replay.commands();
    // As in the recorded run, the starting session is the first command sent; the recorded
    // schedule says before which step it was applied.
    let installed = install_session(&commands, start, session_path);
    while replay.tick().map_err(CliError::Engine)?.is_some() {
        driver.dispatch(&replay.latest_tool(), &commands);
    }
    let report = replay.finish().map_err(CliError::Engine)?;
    installed_or_stop(
        installed
            .try_recv()
            .map_err(|_| RecvTimeoutError::Disconnected),
        session_path,
    )?;
    finish_single_thread_run(args, &config, &report, session_path, &mut driver)
}

/// The engine settings of a lockstep or replayed run starting from `start` on `field`.
fn single_thread_config(
    field: &crate::field::MultiPatchField,
    info: &dynaclay_devices::DeviceInfo,
    start: &Session,
    plan: &ScriptPlan,
) -> EngineConfig {
    let mut config = EngineConfig::for_clay(field, info);
    config.sim.material = start.material.uniform;
    config.haptics.tool_contact = plan.tool_contact;
    config
}

/// Writes a lockstep or replayed run's outputs, reports its device faults and script outcome,
/// and turns a device that failed to close into exit 5.
fn finish_single_thread_run(
    args: &RunArgs,
    config: &EngineConfig,
    report: &crate::engine::LockstepReport,
    session_path: &Path,
    driver: &mut ScriptDriver,
) -> Result<RunOutputs, CliError> {
    let outputs = super::outputs::write_lockstep_outputs(&args.out, report, config, &extras(args))?;
    say_raw!("{}", outputs.describe());
    report_device_faults(&report.safety);
    report_budget_refusals(report.counters.budget_refusals, report.budget_refusal);
    finish_run(session_path, driver, &report.io)?;
    match &report.device_close_error {
        Some(e) => Err(CliError::DeviceFault(e.clone())),
        None => Ok(outputs),
    }
}

/// Runs `samples` device samples through the deterministic lockstep engine: one sample, one
/// simulation step; the script's non-stroke steps are sent on the device's clock. A replay
/// gives the recorded session's samples, the simulated arm its scripted hand; either way the
/// same input always gives the same field.
fn run_lockstep(
    args: &RunArgs,
    plan: &ScriptPlan,
    start: &Session,
    session_path: &Path,
    device: Box<dyn HapticDevice>,
    samples: usize,
) -> Result<RunOutputs, CliError> {
    let info = device.info();
    let field = start.clay.density.clone();
    let config = single_thread_config(&field, &info, start, plan);
    let mut lockstep = Lockstep::new(
        &config,
        field,
        device,
        Box::new(HeadlessSink::default()),
        16,
    )
    .map_err(CliError::Engine)?;
    say!(
        "dynaclay run: {samples} samples of {} in lockstep",
        args.device
    );
    let mut driver = ScriptDriver::new(plan);
    let commands = lockstep.commands();
    // The whole starting session (paint, further patches, grids, tools, metadata) is
    // installed by the first step, before the first recorded sample acts on the clay.
    let installed = install_session(&commands, start, session_path);
    let mut pending_install = Some(installed);
    for _ in 0..samples {
        if let Some(rx) = pending_install.take() {
            lockstep.step();
            installed_or_stop(
                rx.try_recv().map_err(|_| RecvTimeoutError::Disconnected),
                session_path,
            )?;
        }
        let sample = lockstep.latest_tool();
        driver.dispatch(&sample, &commands);
        lockstep.step();
    }
    let report = lockstep.finish().map_err(CliError::Engine)?;
    finish_single_thread_run(args, &config, &report, session_path, &mut driver)
}
