//! `dynaclay run`: a headless session from a script, written to an output directory.

use std::fmt;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use dynaclay_devices::record::{RecordingDevice, ReplayDevice};
use dynaclay_devices::spec::DeviceSpec;
use dynaclay_devices::{HapticDevice, SimArmConfig, SimulatedArm};

use super::args::RunArgs;
use super::outputs::{ExtraOutputs, RunOutputs, write_outputs};
use crate::engine::{
    Engine, EngineConfig, EngineError, HeadlessSink, Lockstep, Script, ScriptError, build_clay,
};
use crate::field::BSplineLattice;
use crate::io::SessionError;
use crate::render::RenderError;

/// Why a command failed; each kind has its own exit code.
#[derive(Debug)]
pub enum CliError {
    /// A bad argument (exit 2).
    Usage(String),
    /// A bad script (exit 2).
    Script(ScriptError),
    /// The device could not be made or opened (exit 3).
    Device(String),
    /// The engine failed (exit 1).
    Engine(EngineError),
    /// An output could not be written, or the starting clay could not be built (exit 1).
    Output(String),
    /// A session file could not be read (exit 2).
    Session(SessionError),
    /// Rendering the PNG at the path failed (exit 1), or found no GPU adapter (exit 4; see
    /// [`CliError::NO_ADAPTER_EXIT`]).
    Render(RenderError, PathBuf),
}

impl CliError {
    /// Exit status of `dynaclay render` when the machine has no GPU adapter: distinct from a
    /// failure (1) and a bad argument (2), so scripts can tell "cannot render here" apart.
    pub const NO_ADAPTER_EXIT: i32 = 4;

    /// The process exit code for this error.
    #[must_use]
    pub fn exit_code(&self) -> i32 {
        match self {
            Self::Usage(_) | Self::Script(_) | Self::Session(_) => 2,
            Self::Device(_) => 3,
            Self::Render(e, _) if e.is_no_adapter() => Self::NO_ADAPTER_EXIT,
            Self::Engine(_) | Self::Output(_) | Self::Render(..) => 1,
        }
    }
}

impl fmt::Display for CliError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Usage(m) => write!(f, "{m}"),
            Self::Script(e) => write!(f, "script error: {e}"),
            Self::Device(m) => write!(f, "device error: {m}"),
            Self::Engine(e) => write!(f, "engine error: {e}"),
            Self::Output(m) => write!(f, "output error: {m}"),
            Self::Session(e) => write!(f, "cannot read session: {e}"),
            Self::Render(e, path) if e.is_no_adapter() => {
                write!(f, "{e}; skipped rendering {}", path.display())
            }
            Self::Render(e, path) => write!(f, "rendering {}: {e}", path.display()),
        }
    }
}

impl std::error::Error for CliError {}

/// Runs a headless session and writes its outputs.
///
/// # Errors
/// A [`CliError`] naming what failed (argument, script line or field, device, output path).
pub fn run(args: &RunArgs) -> Result<RunOutputs, CliError> {
    let script = match &args.script {
        Some(path) => Script::load(path).map_err(CliError::Script)?,
        None => Script::builtin(),
    };
    let spec: DeviceSpec = args
        .device
        .parse()
        .map_err(|e: dynaclay_devices::spec::SpecError| CliError::Usage(e.to_string()))?;
    let seconds = args.seconds.or(script.seconds).unwrap_or(3.0);
    let field = build_clay(&script.clay)
        .map_err(|e| CliError::Output(format!("starting clay: fit failed: {e}")))?;

    let (device, info): (Box<dyn HapticDevice>, _) = match &spec {
        DeviceSpec::Sim => {
            let arm_config = SimArmConfig::default();
            let info = arm_config.info.clone();
            let map = EngineConfig::for_field(&field, &info).map;
            let trajectory = script.trajectory(&map).map_err(CliError::Script)?;
            (Box::new(SimulatedArm::new(arm_config, trajectory)), info)
        }
        DeviceSpec::Replay { file } => {
            let replay = ReplayDevice::load(file).map_err(|e| CliError::Device(e.to_string()))?;
            return run_replay(args, &script, field, replay);
        }
        hw => {
            let d = dynaclay_devices::open::build_driver(
                hw,
                &dynaclay_devices::open::DriverOptions::from_env(),
            )
            .map_err(|e| CliError::Device(e.to_string()))?;
            let info = d.info();
            (d, info)
        }
    };
    let device: Box<dyn HapticDevice> = match &args.record {
        Some(path) => Box::new(
            RecordingDevice::create(device, path)
                .map_err(|e| CliError::Output(format!("{}: {e}", path.display())))?,
        ),
        None => device,
    };
    let mut config = EngineConfig::for_script(&field, &info, &script);
    if !args.rt {
        config.haptic_rt_priority = None;
    }
    std::fs::create_dir_all(&args.out)
        .map_err(|e| CliError::Output(format!("{}: cannot create: {e}", args.out.display())))?;

    let engine =
        Engine::start(&config, field, device, Box::new(HeadlessSink::default())).map_err(|e| {
            match e {
                EngineError::Device(d) => CliError::Device(format!("{} ({})", d, args.device)),
                other => CliError::Engine(other),
            }
        })?;
    let rt = engine.haptic_rt();
    println!(
        "dynaclay run: {seconds:.1} s, device {}, haptic priority: {rt}",
        args.device
    );
    let started = Instant::now();
    while started.elapsed() < Duration::from_secs_f64(seconds) && engine.is_alive() {
        std::thread::sleep(Duration::from_millis(20));
    }
    let report = engine.stop().map_err(CliError::Engine)?;
    let outputs = write_outputs(&args.out, &report, &config, &extras(args))?;
    print!("{}", outputs.describe());
    Ok(outputs)
}

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

/// Replays a recording through the deterministic lockstep engine: one recorded sample, one
/// simulation step, until the recording ends. The same recording always gives the same field.
fn run_replay(
    args: &RunArgs,
    script: &Script,
    field: BSplineLattice,
    replay: ReplayDevice,
) -> Result<RunOutputs, CliError> {
    let samples = replay.read_count();
    let info = replay.info();
    let config = EngineConfig::for_script(&field, &info, script);
    std::fs::create_dir_all(&args.out)
        .map_err(|e| CliError::Output(format!("{}: cannot create: {e}", args.out.display())))?;
    let mut lockstep = Lockstep::new(
        &config,
        field,
        Box::new(replay),
        Box::new(HeadlessSink::default()),
        16,
    )
    .map_err(CliError::Engine)?;
    println!("dynaclay run: replaying {samples} samples in lockstep");
    for _ in 0..samples {
        lockstep.step();
    }
    let report = lockstep.finish().map_err(CliError::Engine)?;
    let outputs =
        super::outputs::write_lockstep_outputs(&args.out, &report, &config, &extras(args))?;
    print!("{}", outputs.describe());
    Ok(outputs)
}
