//! `dynaclay gui [SESSION] [--device SPEC] [--record FILE] [--recover]`: builds the starting clay (the built-in script's,
//! or the session's) and the device, starts the threaded engine behind a bridge, and runs the
//! window until it is closed.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use dynaclay_devices::pointer::{PointerConfig, pointer_device};
use dynaclay_devices::spec::DeviceSpec;
use dynaclay_devices::{HapticDevice, RecordingDevice};
use dynaclay_loops::{busy_fraction, cpu_jiffies, run_probes};

use super::bridge::{DeviceInUse, DeviceOpener, RestartSettings, start_bridge};
use super::device_maker::{MakeDeviceError, make_device};
use super::link::engine_link;
use super::pointer_tool::PointerTool;
use super::probe_panel::{ProbeOutcome, ProbeSettings};
use super::run::{GuiOptions, run_gui};
use super::state::DEFAULT_SESSION;
use crate::engine::{Engine, EngineConfig, ScriptPlan, StartOptions, build_clay};
use crate::field::MultiPatchField;
use crate::io::{Autosave, AutosavePolicy, load_session, recovery_to_use};

/// Why `dynaclay gui` stopped.
#[derive(Debug, thiserror::Error)]
pub enum LaunchError {
    /// A bad argument.
    #[error("gui: {0} (usage: dynaclay gui [SESSION] [--device SPEC] [--record FILE] [--recover])")]
    Usage(String),
    /// The device could not be made.
    #[error("gui: device: {0}")]
    Device(#[from] MakeDeviceError),
    /// The engine could not start on the device (it could not be opened, or a loop failed).
    #[error("gui: device: {source} ({spec})")]
    Start {
        /// The device asked for.
        spec: DeviceSpec,
        /// The engine's error.
        source: crate::engine::EngineError,
    },
    /// The engine or the window failed.
    #[error("gui: {0}")]
    Failed(String),
    /// The session named on the command line could not be read (exit 2, as for `render`).
    #[error("gui: cannot read session: {0}")]
    Session(crate::io::SessionError),
}

/// What `dynaclay gui` was asked for.
#[derive(Clone, Debug, PartialEq)]
pub struct GuiArgs {
    /// The device (`--device SPEC` or `--device=SPEC`; default `mouse`, the window's pointer).
    pub device: DeviceSpec,
    /// Record the device's samples to this file (`--record FILE`); the engine reads the
    /// recording like any device, so the session replays bit for bit through the lockstep engine.
    pub record: Option<PathBuf>,
    /// A session file to start from (a later Load of another lattice restarts the engine).
    pub session: Option<PathBuf>,
    /// Start from the recovery file autosave left for the session (`--recover`).
    pub recover: bool,
}

/// Parses `dynaclay gui`'s arguments: an optional session path, `--device` and `--recover`.
///
/// # Errors
/// An unknown option, a second session, a missing value or a spec the devices parser rejects.
pub fn parse_gui_args(args: &[String]) -> Result<GuiArgs, LaunchError> {
    let mut spec = "mouse".to_owned();
    let mut session = None;
    let mut recover = false;
    let mut record = None;
    let mut it = args.iter();
    while let Some(a) = it.next() {
        if a == "--recover" {
            recover = true;
        } else if a == "--record" {
            record =
                Some(PathBuf::from(it.next().ok_or_else(|| {
                    LaunchError::Usage("--record needs a file".into())
                })?));
        } else if let Some(v) = a.strip_prefix("--record=") {
            record = Some(PathBuf::from(v));
        } else if a == "--device" {
            spec = it
                .next()
                .ok_or_else(|| LaunchError::Usage("--device needs a value".into()))?
                .clone();
        } else if let Some(v) = a.strip_prefix("--device=") {
            spec = v.to_owned();
        } else if a.starts_with('-') || session.is_some() {
            return Err(LaunchError::Usage(format!("unexpected argument {a:?}")));
        } else {
            session = Some(PathBuf::from(a));
        }
    }
    let device = spec
        .parse()
        .map_err(|e: dynaclay_devices::spec::SpecError| LaunchError::Usage(e.to_string()))?;
    Ok(GuiArgs {
        device,
        record,
        session,
        recover,
    })
}

/// Runs `dynaclay gui` with the given arguments.
///
/// # Errors
/// See [`LaunchError`].
pub fn gui_main(args: &[String]) -> Result<(), LaunchError> {
    let GuiArgs {
        device: spec,
        record,
        session: named,
        recover,
    } = parse_gui_args(args)?;
    // Autosave writes next to the session the window saves to; unsaved work a crash left
    // there stops the start unless --recover opens it, so it is never overwritten unseen.
    let session_path = named
        .clone()
        .unwrap_or_else(|| PathBuf::from(DEFAULT_SESSION));
    let recovery =
        recovery_to_use(&session_path, recover).map_err(|e| LaunchError::Usage(e.to_string()))?;
    let session = recovery.map(|r| r.path).or(named);
    let script = ScriptPlan::builtin();
    let (field, material) = match &session {
        None => (
            MultiPatchField::new(
                build_clay(&script.clay)
                    .map_err(|e| LaunchError::Failed(format!("starting clay: {e}")))?,
            ),
            None,
        ),
        Some(path) => {
            let s = load_session(path).map_err(LaunchError::Session)?;
            if !s.clay.density.patches[0].is_identity() {
                return Err(LaunchError::Failed(format!(
                    "{}: the session's base patch is mapped; the engine sculpts a base patch in world coordinates",
                    path.display()
                )));
            }
            (s.clay.density, Some(s.material.uniform))
        }
    };
    // The window's own pointer is the default tool; its handle stays with the app.
    let mut pointer_handle = None;
    let (device, info) = if spec == DeviceSpec::Pointer {
        let pointer = PointerConfig::default();
        let (device, handle) = pointer_device(pointer);
        pointer_handle = Some(handle);
        (Box::new(device) as Box<dyn HapticDevice>, pointer.info())
    } else {
        make_device(&spec, &field, &script)?
    };
    let device: Box<dyn HapticDevice> = match &record {
        Some(path) => Box::new(
            RecordingDevice::create(device, path)
                .map_err(|e| LaunchError::Failed(format!("{}: {e}", path.display())))?,
        ),
        None => device,
    };
    let mut config = EngineConfig::for_clay(&field, &info);
    let pointer = pointer_handle.map(|h| PointerTool::new(h, config.map));
    if let Some(m) = material {
        config.sim.material = m;
    }
    // The window asks before any one step removes more than half the clay.
    config.sim.removal_guard = crate::engine::RemovalGuard::Ask;
    let (link, endpoint) = engine_link();
    // The device panel opens devices for the same clay while the engine runs.
    let opener_field = field.clone();
    let opener: DeviceOpener = Box::new(move |spec: &DeviceSpec| {
        make_device(spec, &opener_field, &script).map(|(d, _)| d)
    });
    let autosave = Autosave::new(&session_path, AutosavePolicy::default(), Instant::now());
    let probe_settings = ProbeSettings {
        rate_hz: config.haptic_rate_hz,
        rt_priority: config.haptic_rt_priority,
    };
    let probe_at_start = probe_before_engine(probe_settings);
    // A loaded clay of another layout restarts the engine with these settings; the replaced
    // clay is written next to the session first.
    let restart = RestartSettings {
        config,
        autosave: Some(session_path.clone()),
        keep_replaced_at: session_path.with_extension("replaced.dclay"),
    };
    let in_use = DeviceInUse {
        spec: spec.clone(),
        info: info.clone(),
    };
    let bridge = start_bridge(endpoint, in_use, opener, Some(restart), |sink| {
        Engine::start_with(
            &config,
            field,
            device,
            sink,
            StartOptions {
                autosave: Some(autosave),
                // The GUI's commands are not recorded, so its schedule could not drive an
                // exact replay: a GUI recording replays the hand's motion in lockstep.
                schedule: None,
            },
        )
    })
    .map_err(|source| LaunchError::Start { spec, source })?;
    if let Some(path) = session {
        // The engine started on the session's density; the load installs the rest of it (its
        // paint) the way the Load button does.
        link.send(super::command::EngineCommand::Load { path })
            .map_err(|e| LaunchError::Failed(e.to_string()))?;
    }
    let options = GuiOptions {
        session_path: session_path.display().to_string(),
        probe_settings,
        probe_at_start,
        ..GuiOptions::default()
    };
    let shown = run_gui(options, link, pointer);
    let stopped = bridge.stop();
    shown.map_err(|e| LaunchError::Failed(e.to_string()))?;
    stopped.map_err(|e| LaunchError::Failed(format!("engine: {e}")))?;
    Ok(())
}

/// How long each half of the probe at launch runs (wake-ups, then stalls).
const LAUNCH_PROBE_EACH: Duration = Duration::from_millis(300);

/// The whole platform probe, as `dynaclay run` runs it, before the engine starts: the panel's
/// first figures. A probe that cannot run is left out (the panel says it was not probed).
fn probe_before_engine(settings: ProbeSettings) -> Option<ProbeOutcome> {
    let jiffies = cpu_jiffies();
    let run = run_probes(settings.rate_hz, LAUNCH_PROBE_EACH, settings.rt_priority).ok()?;
    let busy = jiffies
        .zip(cpu_jiffies())
        .and_then(|(b, a)| busy_fraction(b, a));
    Some(ProbeOutcome::before_engine(&run.summary(), busy))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gui_arguments_parse_like_run_devices() {
        let s = |v: &[&str]| parse_gui_args(&v.iter().map(|x| x.to_string()).collect::<Vec<_>>());
        assert_eq!(s(&[]).unwrap().device, DeviceSpec::Pointer);
        assert_eq!(s(&[]).unwrap().session, None);
        assert_eq!(
            s(&["--device", "spacemouse"]).unwrap().device,
            DeviceSpec::SpaceMouse
        );
        assert_eq!(s(&["--device=sim"]).unwrap().device, DeviceSpec::Sim);
        let with_session = s(&["a.dclay", "--device=sim"]).unwrap();
        assert_eq!(with_session.session, Some(PathBuf::from("a.dclay")));
        assert!(s(&["a.dclay", "b.dclay"]).is_err(), "one session at most");
        assert!(
            s(&["--device"])
                .unwrap_err()
                .to_string()
                .contains("needs a value")
        );
        assert!(s(&["--bogus"]).is_err());
        assert!(s(&["--device", "falcon"]).is_err());
        assert!(!s(&[]).unwrap().recover);
        assert_eq!(s(&[]).unwrap().record, None);
        assert_eq!(
            s(&["--record", "m.rec"]).unwrap().record,
            Some(PathBuf::from("m.rec"))
        );
        assert_eq!(
            s(&["--record=m.rec"]).unwrap().record,
            Some(PathBuf::from("m.rec"))
        );
        assert!(s(&["--record"]).is_err());
        let recovering = s(&["--recover", "a.dclay"]).unwrap();
        assert!(recovering.recover);
        assert_eq!(recovering.session, Some(PathBuf::from("a.dclay")));
    }
}
