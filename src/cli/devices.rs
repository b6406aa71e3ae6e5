//! `dynaclay devices`: what is connected and why each supported device cannot be opened,
//! which vendor haptic libraries load, the udev rules (`--udev-rules`), and the device doctor
//! (`--doctor SPEC`): a zero-force read loop that reports the rate achieved and its jitter.

use std::path::Path;

use dynaclay_devices::doctor::{self, DoctorConfig, DoctorReport, WallClock};
use dynaclay_devices::enumerate::{self, UDEV_INSTALL_COMMAND};
use dynaclay_devices::falcon::Falcon;
use dynaclay_devices::node_holders::holders_of;
use dynaclay_devices::open::{DriverOptions, build_driver};
use dynaclay_devices::spec::DeviceSpec;
use dynaclay_devices::{DeviceError, HapticDevice, SimArmConfig, SimulatedArm, Trajectory};

use super::args::DevicesArgs;
use super::error::CliError;

/// Runs `dynaclay devices` as `args` ask.
///
/// # Errors
/// A usage error for a bad `--doctor` spec; a device error when the doctor cannot open the
/// device. Listing never fails: enumeration problems are printed as notes.
pub fn devices(args: &DevicesArgs) -> Result<(), CliError> {
    if args.udev_rules {
        say_raw!("{}", enumerate::UDEV_RULES);
        return Ok(());
    }
    match &args.doctor {
        None => {
            list();
            Ok(())
        }
        Some(spec) => run_doctor(spec, args),
    }
}

/// Prints the connected devices, what stops each supported one opening, and the vendor
/// libraries.
fn list() {
    let (mut devices, notes) = enumerate::list_all();
    let libraries = enumerate::vendor_libraries();
    enumerate::diagnose_libraries(&mut devices, &libraries);
    say_raw!("{}", enumerate::report(&devices, &notes));
    say_raw!("{}", enumerate::vendor_report(&libraries));
    say!("(the simulated arm is always available as --device sim)");
    say!("(`dynaclay devices --doctor SPEC` opens one and measures its rate)");
}

/// The node a spec names, for the spec kinds that name one.
fn node_of(spec: &DeviceSpec) -> Option<&Path> {
    match spec {
        DeviceSpec::Falcon { path } | DeviceSpec::Serial { path, .. } => Some(path),
        _ => None,
    }
}

/// Opens the device `spec_text` names, runs the zero-force loop and prints the report.
fn run_doctor(spec_text: &str, args: &DevicesArgs) -> Result<(), CliError> {
    let spec: DeviceSpec = spec_text
        .parse()
        .map_err(|e| CliError::bad_input("--doctor", e))?;
    let config = DoctorConfig {
        duration_us: (args.seconds * 1e6).round() as u64,
        rate_hz: None,
    };
    let mut options = DriverOptions::from_env();
    if let Some(file) = &args.falcon_firmware {
        options.falcon.firmware = Some(file.clone());
    }
    let mut clock = WallClock::new();
    say!(
        "doctor: {spec} for {:.2} s, zero force; it reads as the haptic loop does",
        args.seconds
    );
    let outcome = match &spec {
        DeviceSpec::Sim => {
            let arm = SimArmConfig::default();
            let center = arm.info.workspace_center_m();
            doctor::run(
                SimulatedArm::new(arm, Trajectory::hold(center)),
                config,
                &mut clock,
            )
            .0
        }
        DeviceSpec::Replay { .. } | DeviceSpec::Pointer => {
            return Err(CliError::Usage(format!(
                "--doctor {spec_text}: the doctor reads a device; a recording or the window's mouse is not one"
            )));
        }
        DeviceSpec::Falcon { path } => {
            // Built here rather than boxed, so its latency timer and link counters can be told.
            let falcon = Falcon::new(&path.to_string_lossy(), options.falcon.clone());
            let (outcome, falcon) = doctor::run(falcon, config, &mut clock);
            say!("{}", falcon.latency_timer());
            let stats = falcon.link_stats();
            say!(
                "Falcon link: {} frames sent, {} received, {} malformed, {} stray bytes, firmware uploads {}",
                stats.sent,
                stats.received,
                stats.bad_frames,
                stats.skipped_bytes,
                stats.firmware_attempts
            );
            outcome
        }
        hw => {
            let driver = build_driver(hw, &options)
                .map_err(|e| CliError::device(spec_text.to_string(), e))?;
            doctor::run::<Box<dyn HapticDevice>>(driver, config, &mut clock).0
        }
    };
    match outcome {
        Ok(report) => {
            say_raw!("{report}");
            say!("{}", verdict(&report));
            Ok(())
        }
        Err(e) => {
            say!("cannot open {spec_text}: {e}");
            for hint in open_hints(&e, node_of(&spec)) {
                say!("  {hint}");
            }
            Err(CliError::device(spec_text.to_string(), e))
        }
    }
}

/// What an open failure suggests doing, with the programs holding the node when it is busy.
fn open_hints(e: &DeviceError, node: Option<&Path>) -> Vec<String> {
    let mut hints = Vec::new();
    if matches!(e, DeviceError::PermissionDenied { .. }) {
        hints.push(format!("install the udev rules: {UDEV_INSTALL_COMMAND}"));
    }
    let busy = matches!(
        e,
        DeviceError::Io {
            kind: std::io::ErrorKind::ResourceBusy,
            ..
        }
    );
    if let Some(scan) = node.and_then(holders_of) {
        if !scan.holders.is_empty() {
            let who: Vec<String> = scan
                .holders
                .iter()
                .map(|h| format!("pid {} ({})", h.pid, h.command))
                .collect();
            hints.push(format!(
                "held open by another program (found in /proc/*/fd): {}",
                who.join(", ")
            ));
        } else if busy {
            hints.push(format!(
                "the port is busy (EBUSY: another program opened it exclusively); none of this user's processes holds it, so look at other users' ({} processes could not be read)",
                scan.unreadable_processes
            ));
        }
    }
    hints
}

/// One line saying whether the device kept up with the rate the loop asked for.
fn verdict(report: &DoctorReport) -> String {
    let Some(fresh) = report.fresh_periods else {
        return "verdict: no fresh samples; the device did not stream".into();
    };
    let share = fresh.rate_hz / report.target_rate_hz;
    if report.read_errors == 0 && share >= 0.95 {
        format!(
            "verdict: fresh samples at {:.0}% of {:.0} Hz",
            share * 100.0,
            report.target_rate_hz
        )
    } else {
        format!(
            "verdict: fresh samples at {:.0}% of {:.0} Hz with {} failed reads; the device, its link or this machine's scheduling falls short (`--doctor sim` answers at once, so its figures are the machine's alone)",
            share * 100.0,
            report.target_rate_hz,
            report.read_errors
        )
    }
}
