//! From a [`DeviceSpec`] to a hardware driver, ready for `open`.
//!
//! [`build_driver`] resolves the profile (built-in name or TOML file) and constructs the driver;
//! it does no I/O, so errors here are configuration errors. The engine then wraps the result in
//! the [`crate::SafetyFilter`] and calls `open`. `sim` and `replay:FILE` are not hardware: the
//! engine builds them from [`crate::SimulatedArm`] and [`crate::ReplayDevice`] directly.

use std::path::PathBuf;
use std::time::Duration;

use crate::arm_link::SampleClock;
use crate::device::{DeviceError, HapticDevice};
use crate::dhd_arm::{DhdArm, DhdConfig};
use crate::falcon::{Falcon, FalconOptions};
use crate::hid_arm::HidArm;
use crate::inverse3::{Inverse3, Inverse3Config};
use crate::openhaptics_arm::{HdServo, OpenHapticsArm, OpenHapticsConfig};
use crate::pose_input::PoseInputConfig;
use crate::profile::{DeviceProfile, Protocol};
use crate::serial_arm::{SerialArm, SerialArmOptions};
use crate::spacemouse::SpaceMouse;
use crate::spec::DeviceSpec;
use crate::two_diy::{TwoDiy, TwoDiyOptions};
use crate::vendor_lib::{LibrarySource, VendorLibrary};

/// Environment variable naming the Falcon firmware file.
pub const FALCON_FIRMWARE_ENV: &str = "DYNACLAY_FALCON_FIRMWARE";

/// Per-driver settings.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DriverOptions {
    /// Falcon settings (firmware file, homing, timeouts).
    pub falcon: FalconOptions,
    /// Cartesian serial settings.
    pub serial: SerialArmOptions,
    /// Haply 2DIY settings (the generation comes from the spec).
    pub two_diy: TwoDiyOptions,
    /// SpaceMouse pose settings.
    pub spacemouse: PoseInputConfig,
    /// Where OpenHaptics' `libHD.so` comes from (`touch`, `phantom`).
    pub hd_library: LibrarySource,
    /// Where Force Dimension's `libdhd.so` comes from (`dhd`).
    pub dhd_library: LibrarySource,
    /// Who runs HD's servo frames (`touch`, `phantom`): its scheduler, or the engine's
    /// lockstep ticks (`dynaclay run --lockstep`).
    pub hd_servo: HdServo,
}

impl DriverOptions {
    /// Defaults, with the Falcon firmware file taken from `DYNACLAY_FALCON_FIRMWARE` if set,
    /// and the vendor libraries from `DYNACLAY_HD_LIB` and `DYNACLAY_DHD_LIB` if set (else
    /// searched for where the vendors install them).
    #[must_use]
    pub fn from_env() -> Self {
        let mut o = Self::default();
        o.falcon.firmware = std::env::var_os(FALCON_FIRMWARE_ENV).map(PathBuf::from);
        let explicit = |lib: VendorLibrary| match std::env::var_os(lib.env_var()) {
            Some(p) if !p.is_empty() => LibrarySource::Path(PathBuf::from(p)),
            _ => LibrarySource::Search,
        };
        o.hd_library = explicit(VendorLibrary::OpenHapticsHd);
        o.dhd_library = explicit(VendorLibrary::ForceDimensionDhd);
        o
    }

    /// These settings for a lockstep run (`dynaclay run --lockstep`: one engine tick per
    /// device sample, on the device's clock): HD's servo frames are run by the engine's
    /// ticks, and the arms whose frames carry no clock (the Falcon, the 2DIY) stamp their
    /// samples by reply count ([`SampleClock::LOCKSTEP_1KHZ`]: each answers one command with
    /// one reply, one command per tick) and wait up to [`LOCKSTEP_REPLY_WAIT`] for the reply
    /// to the previous tick's command, so every tick reads that reply whatever the machine's
    /// load. On the host's clock the soft start, the velocities and so every force would
    /// follow how fast this machine ran the ticks; stamped by reply count, a run depends on
    /// the exchanges alone.
    #[must_use]
    pub fn for_lockstep(mut self) -> Self {
        self.hd_servo = HdServo::Lockstep;
        self.falcon.sample_clock = SampleClock::LOCKSTEP_1KHZ;
        self.falcon.reply_wait = LOCKSTEP_REPLY_WAIT;
        self.falcon.stale_after = self.falcon.stale_after.max(LOCKSTEP_REPLY_WAIT);
        self.two_diy.sample_clock = SampleClock::LOCKSTEP_1KHZ;
        self.two_diy.reply_wait = LOCKSTEP_REPLY_WAIT;
        self.two_diy.stale_after = self.two_diy.stale_after.max(LOCKSTEP_REPLY_WAIT);
        self
    }
}

/// Longest a lockstep run's read waits for the reply to the previous tick's command: a
/// lockstep tick is not held to real time, so a reply that is late on a loaded machine is
/// waited for instead of skipped (which would make the run depend on the machine's speed).
/// An arm answers in about a millisecond, but on a loaded machine a pseudo-terminal's reply
/// was seen to take up to 2.9 s (2 cores, load 14: the Falcon stand-in's replies, whose
/// exchanges the stand-in answered at once); the wait is asleep in the kernel
/// ([`crate::serial_link::SPIN_WAIT_LIMIT`]) and a hang-up ends it at once, so only an arm
/// that is connected and silent this long pays for it, reported as a timeout as in real time.
pub const LOCKSTEP_REPLY_WAIT: Duration = Duration::from_secs(10);

fn load_profile(name: &str) -> Result<DeviceProfile, DeviceError> {
    DeviceProfile::load(name).map_err(|e| DeviceError::Config {
        origin: name.to_string(),
        message: e.to_string(),
    })
}

/// Builds the (unopened) driver for a hardware spec.
///
/// # Errors
/// [`DeviceError::Config`] for a bad or mismatched profile; [`DeviceError::Unsupported`] for
/// `sim` and `replay`, which the engine builds itself.
pub fn build_driver(
    spec: &DeviceSpec,
    opts: &DriverOptions,
) -> Result<Box<dyn HapticDevice>, DeviceError> {
    match spec {
        DeviceSpec::Sim => Err(DeviceError::Unsupported {
            what: "`sim` as hardware: build crate::sim_arm::SimulatedArm",
        }),
        DeviceSpec::Replay { .. } => Err(DeviceError::Unsupported {
            what: "`replay` as hardware: build crate::record::ReplayDevice",
        }),
        DeviceSpec::Pointer => Err(DeviceError::Unsupported {
            what: "`mouse` as hardware: the window builds crate::pointer::PointerDevice",
        }),
        DeviceSpec::SpaceMouse => Ok(Box::new(SpaceMouse::new(opts.spacemouse))),
        DeviceSpec::OpenHaptics { device } => {
            Ok(Box::new(OpenHapticsArm::new(OpenHapticsConfig {
                library: opts.hd_library.clone(),
                device_name: device.clone(),
                servo: opts.hd_servo,
            })))
        }
        DeviceSpec::Dhd { index } => Ok(Box::new(DhdArm::new(DhdConfig {
            library: opts.dhd_library.clone(),
            index: *index,
        }))),
        DeviceSpec::Inverse3 { url } => Ok(Box::new(Inverse3::new(Inverse3Config {
            url: url
                .clone()
                .unwrap_or_else(|| crate::codec::haply_service::DEFAULT_SERVICE_URL.into()),
            ..Inverse3Config::default()
        }))),
        DeviceSpec::TwoDiy { path, version } => Ok(Box::new(TwoDiy::new(
            &path.to_string_lossy(),
            TwoDiyOptions {
                version: *version,
                ..opts.two_diy.clone()
            },
        ))),
        DeviceSpec::Hid { profile } => {
            let p = load_profile(profile.as_deref().unwrap_or("woodenhaptics"))?;
            Ok(Box::new(HidArm::new(p)?))
        }
        DeviceSpec::Falcon { path } => Ok(Box::new(Falcon::new(
            &path.to_string_lossy(),
            opts.falcon.clone(),
        ))),
        DeviceSpec::Serial { path, profile } => {
            let name = profile.as_deref().unwrap_or("cartesian-serial");
            let p = load_profile(name)?;
            let path = path.to_string_lossy();
            match p.protocol {
                Protocol::CartesianSerial => {
                    Ok(Box::new(SerialArm::new(&path, p, opts.serial.clone())))
                }
                Protocol::Falcon => {
                    // The command line's firmware file wins over the profile's.
                    let mut falcon = opts.falcon.clone();
                    falcon.firmware = falcon.firmware.or_else(|| p.firmware.clone());
                    Ok(Box::new(Falcon::with_profile(&path, p, falcon)?))
                }
                other => Err(DeviceError::Config {
                    origin: name.to_string(),
                    message: format!(
                        "profile protocol {other:?} is not a serial protocol; use hid:{name}"
                    ),
                }),
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_hardware_spec_builds_a_driver_without_io() {
        let o = DriverOptions::default();
        for s in [
            "hid",
            "hid:polhem",
            "hid:cartesian-hid",
            "serial:/dev/null",
            "serial:/dev/null:falcon",
            "falcon:/dev/null",
            "spacemouse",
            "touch",
            "phantom:PHANToM 1",
            "dhd:1",
            "inverse3",
            "inverse3:ws://127.0.0.1:1",
            "2diy:/dev/null",
            "2diy:/dev/null:v2",
        ] {
            let spec: DeviceSpec = s.parse().unwrap();
            let d = build_driver(&spec, &o).unwrap_or_else(|e| panic!("{s}: {e}"));
            assert!(!d.is_open(), "{s}");
        }
    }

    #[test]
    fn lockstep_stamps_the_clockless_arms_by_reply_at_their_stated_rate() {
        let o = DriverOptions::default().for_lockstep();
        assert_eq!(o.hd_servo, HdServo::Lockstep);
        for (name, clock, wait, stale) in [
            (
                "falcon",
                o.falcon.sample_clock,
                o.falcon.reply_wait,
                o.falcon.stale_after,
            ),
            (
                "2diy",
                o.two_diy.sample_clock,
                o.two_diy.reply_wait,
                o.two_diy.stale_after,
            ),
        ] {
            assert_eq!(clock, SampleClock::LOCKSTEP_1KHZ, "{name}");
            assert_eq!(wait, LOCKSTEP_REPLY_WAIT, "{name}");
            assert!(
                stale >= wait,
                "{name}: silent {stale:?} < the wait {wait:?}"
            );
        }
        // The command line counts a lockstep run's samples at the arm's stated rate: the
        // reply clock must tick at that rate.
        let SampleClock::PerReply { period_us } = SampleClock::LOCKSTEP_1KHZ else {
            panic!("a reply clock")
        };
        for spec in ["falcon:/dev/null", "2diy:/dev/null", "2diy:/dev/null:v2"] {
            let d = build_driver(&spec.parse().unwrap(), &o).unwrap();
            let rate_hz = d.info().sample_rate_hz;
            assert_eq!(rate_hz, 1e6 / period_us.get() as f32, "{spec}");
        }
        // Real time is untouched.
        let real = DriverOptions::default();
        assert_eq!(real.falcon.sample_clock, SampleClock::Host);
        assert_eq!(real.two_diy.sample_clock, SampleClock::Host);
    }

    #[test]
    fn mismatches_and_missing_profiles_are_config_errors() {
        let o = DriverOptions::default();
        let e = build_driver(&"hid:falcon".parse().unwrap(), &o)
            .err()
            .unwrap();
        assert!(matches!(e, DeviceError::Config { .. }), "{e}");
        let e = build_driver(&"serial:/dev/null:woodenhaptics".parse().unwrap(), &o)
            .err()
            .unwrap();
        assert!(e.to_string().contains("not a serial protocol"), "{e}");
        let e = build_driver(&"hid:/nonexistent/arm.toml".parse().unwrap(), &o)
            .err()
            .unwrap();
        assert!(e.to_string().contains("/nonexistent/arm.toml"), "{e}");
        assert!(matches!(
            build_driver(&DeviceSpec::Sim, &o).err().unwrap(),
            DeviceError::Unsupported { .. }
        ));
    }
}
