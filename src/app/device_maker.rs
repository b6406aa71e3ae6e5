//! Making the device a `--device` spec names, for the window: the simulated arm follows the
//! script's strokes on the clay; a hardware spec gets its driver; the mouse and replays are
//! refused with what to do instead.

use std::path::PathBuf;

use dynaclay_devices::spec::DeviceSpec;
use dynaclay_devices::{DeviceInfo, HapticDevice, SimArmConfig, SimulatedArm};

use crate::engine::{EngineConfig, ScriptPlan};
use crate::field::MultiPatchField;

/// Why [`make_device`] made no device.
#[derive(Debug, thiserror::Error)]
pub enum MakeDeviceError {
    /// The mouse is the window's own device, made with the window.
    #[error(
        "the mouse is the window's own device: start with `dynaclay gui` (or `--device mouse`) to sculpt with it"
    )]
    PointerIsTheWindow,
    /// Recordings are replayed by `dynaclay run`.
    #[error("{}: use `dynaclay run --device replay:FILE` to replay recordings", file.display())]
    Replay {
        /// The recording named.
        file: PathBuf,
    },
    /// The simulated arm's script does not map onto the clay.
    #[error(transparent)]
    Script(#[from] crate::io::ScriptError),
    /// The driver could not be made.
    #[error(transparent)]
    Device(#[from] dynaclay_devices::DeviceError),
}

/// Makes the device `spec` names, for the clay `field`: the simulated arm follows `script`'s
/// strokes mapped onto that clay (so the view moves); a hardware spec gets its driver. A
/// replay is refused here: recordings are replayed by `dynaclay run`.
///
/// # Errors
/// The driver's or the script's error, or the refusal of the mouse or a replay.
pub fn make_device(
    spec: &DeviceSpec,
    field: &MultiPatchField,
    script: &ScriptPlan,
) -> Result<(Box<dyn HapticDevice>, DeviceInfo), MakeDeviceError> {
    match spec {
        DeviceSpec::Sim => {
            let arm = SimArmConfig::default();
            let info = arm.info.clone();
            let map = EngineConfig::for_clay(field, &info).map;
            let trajectory = script.trajectory(&map)?;
            Ok((Box::new(SimulatedArm::new(arm, trajectory)), info))
        }
        DeviceSpec::Pointer => Err(MakeDeviceError::PointerIsTheWindow),
        DeviceSpec::Replay { file } => Err(MakeDeviceError::Replay { file: file.clone() }),
        hw => {
            let d = dynaclay_devices::open::build_driver(
                hw,
                &dynaclay_devices::open::DriverOptions::from_env(),
            )?;
            let info = d.info();
            Ok((d, info))
        }
    }
}
