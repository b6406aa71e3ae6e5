//! Force-feedback arm over USB HID (hidapi): the WoodenHaptics / Polhem firmware, or custom
//! firmware speaking the Cartesian HID reports.
//!
//! The profile picks the protocol and the kinematics. WoodenHaptics: encoders → joint angles →
//! position through [`ArmModel`], and force → `Jᵀ F` → clamped motor currents in mA. The
//! firmware cuts motor power 0.5 s after the last report, so `read` sends a keep-alive command
//! (the last one) whenever the engine has not written since the previous read. Cartesian: µm in,
//! mN out. `read` drains queued input reports without blocking (bounded count) and allocates
//! nothing; the newest report wins.
//!
//! Frames: WoodenHaptics reports x toward the user, y to the user's right, z up; the dynaclay
//! device frame is x right, y up, z toward the user, so `(X, Y, Z) = (y, z, x)`.

use std::time::{Duration, Instant};

use glam::{DVec3, Vec3};
use hidapi::{HidApi, HidDevice};

use crate::arm_link::{ArmSession, arm_model, cartesian_force_mn, close_result, limited_force_n};
use crate::codec::{cartesian, woodenhaptics as wh};
use crate::device::{DeviceError, DeviceInfo, DeviceState, HapticDevice};
pub use crate::hid_link::open_hid;
use crate::kinematics::ArmModel;
use crate::link_health::LinkHealth;
use crate::profile::{DeviceProfile, Protocol};

/// Largest number of queued reports one `read` drains.
const MAX_REPORTS_PER_READ: usize = 64;

/// WoodenHaptics base frame → dynaclay device frame.
#[must_use]
pub fn wh_to_device(p: DVec3) -> Vec3 {
    Vec3::new(p.y as f32, p.z as f32, p.x as f32)
}

/// dynaclay device frame → WoodenHaptics base frame.
#[must_use]
pub fn device_to_wh(v: Vec3) -> DVec3 {
    DVec3::new(f64::from(v.z), f64::from(v.x), f64::from(v.y))
}

/// A USB HID arm.
pub struct HidArm {
    profile: DeviceProfile,
    model: Option<ArmModel>,
    api: Option<HidApi>,
    dev: Option<HidDevice>,
    command: [u8; wh::OUTPUT_LEN],
    seq: u8,
    session: ArmSession,
    /// No input report for 100 ms makes `read` fail with a timeout (a failed HID read is a
    /// disconnect at once, so the link is never probed).
    health: LinkHealth,
}

impl HidArm {
    /// An arm described by `profile` (not opened yet).
    ///
    /// # Errors
    /// [`DeviceError::Config`] when the profile's protocol is not a HID one.
    pub fn new(profile: DeviceProfile) -> Result<Self, DeviceError> {
        let model = match profile.protocol {
            Protocol::Woodenhaptics => Some(arm_model(&profile)?),
            Protocol::CartesianHid => None,
            other => {
                return Err(DeviceError::Config {
                    origin: profile.name.clone(),
                    message: format!(
                        "protocol {other:?} is not a USB HID protocol; use serial: or falcon:"
                    ),
                });
            }
        };
        let now = Instant::now();
        Ok(Self {
            profile,
            model,
            api: None,
            dev: None,
            command: [0; wh::OUTPUT_LEN],
            seq: 0,
            session: ArmSession::new(now),
            health: LinkHealth::new(Duration::from_millis(100), now),
        })
    }

    /// The output report for a force (pure; exposed for tests and recording).
    #[must_use]
    pub fn command_for_force(&mut self, force_n: Vec3) -> [u8; wh::OUTPUT_LEN] {
        let max_force_n = self.profile.max_force_n;
        match &self.model {
            Some(m) => wh::encode_command(&wh::WhCommand::Drive {
                currents_ma: m
                    .commands_for_force(device_to_wh(limited_force_n(force_n, max_force_n))),
            }),
            None => {
                self.seq = self.seq.wrapping_add(1);
                cartesian::encode_command(&cartesian::CartesianCommand {
                    force_mn: cartesian_force_mn(force_n, max_force_n),
                    flags: cartesian::FLAG_ENABLE,
                    seq: self.seq,
                })
            }
        }
    }

    /// Applies one input report (pure except for the model's state); returns whether it held a
    /// valid sample.
    ///
    /// # Errors
    /// [`DeviceError::Protocol`] for a report of the wrong size or an unsolvable pose.
    pub fn apply_report(&mut self, report: &[u8], t_us: u64) -> Result<(), DeviceError> {
        let (p, buttons) = match &mut self.model {
            Some(m) => {
                let s = wh::decode_status(report).map_err(|_| DeviceError::Protocol {
                    what: "WoodenHaptics report of the wrong length",
                    offset: 0,
                })?;
                let p = m
                    .update([s.encoders[0], s.encoders[1], s.encoders[2]])
                    .map_err(|_| DeviceError::Protocol {
                        what: "encoder counts outside the arm's reach",
                        offset: 0,
                    })?;
                (wh_to_device(p), 0)
            }
            None => {
                let s = cartesian::decode_state(report).map_err(|_| DeviceError::Protocol {
                    what: "Cartesian report of the wrong length",
                    offset: 0,
                })?;
                (
                    Vec3::new(
                        s.position_um[0] as f32,
                        s.position_um[1] as f32,
                        s.position_um[2] as f32,
                    ) * 1e-6,
                    u32::from(s.buttons),
                )
            }
        };
        self.session.sample(p, buttons, t_us);
        Ok(())
    }

    fn send(&mut self) -> Result<(), DeviceError> {
        let dev = self.dev.as_ref().ok_or(DeviceError::NotOpen)?;
        dev.write(&self.command)
            .map(|_| ())
            .map_err(|_| DeviceError::Disconnected)
    }
}

impl HapticDevice for HidArm {
    fn info(&self) -> DeviceInfo {
        self.profile.device_info(
            Vec3::ZERO,
            if self.model.is_some() { 0 } else { 16 },
            1000.0,
        )
    }

    fn open(&mut self) -> Result<(), DeviceError> {
        if self.dev.is_some() {
            return Ok(());
        }
        let ids = [(self.profile.vendor_id, self.profile.product_id)];
        let what = format!(
            "{} (HID {:04x}:{:04x})",
            self.profile.name, ids[0].0, ids[0].1
        );
        let (api, dev, _path) = open_hid(&ids, &what)?;
        self.api = Some(api);
        self.dev = Some(dev);
        if let Some(m) = self.model.as_mut() {
            m.reset();
        }
        let now = Instant::now();
        self.session.start(now);
        self.health.restart(now);
        self.command = self.command_for_force(Vec3::ZERO);
        self.send()
    }

    fn close(&mut self) -> Result<(), DeviceError> {
        let r = if self.dev.is_some() {
            self.command = self.command_for_force(Vec3::ZERO);
            self.send()
        } else {
            Ok(())
        };
        self.dev = None;
        self.api = None;
        close_result(r)
    }

    fn is_open(&self) -> bool {
        self.dev.is_some()
    }

    fn read(&mut self) -> Result<DeviceState, DeviceError> {
        if self.dev.is_none() {
            return Err(DeviceError::NotOpen);
        }
        if self.session.keep_alive_due() {
            // Feed the firmware's 0.5 s watchdog even when the engine only reads.
            self.send()?;
        }
        let mut buf = [0u8; 64];
        let mut newest = [0u8; 64];
        let mut newest_len = None;
        for _ in 0..MAX_REPORTS_PER_READ {
            let dev = self.dev.as_ref().ok_or(DeviceError::NotOpen)?;
            let n = dev.read(&mut buf).map_err(|_| DeviceError::Disconnected)?;
            if n == 0 {
                break;
            }
            newest[..n].copy_from_slice(&buf[..n]);
            newest_len = Some(n);
        }
        let now = Instant::now();
        if let Some(n) = newest_len {
            self.apply_report(&newest[..n], self.session.elapsed_us(now))?;
            self.health.frame(now);
        } else {
            self.health.check(now, || false)?;
        }
        Ok(self.session.state())
    }

    fn write_force(&mut self, force_n: Vec3) -> Result<(), DeviceError> {
        if self.dev.is_none() {
            return Err(DeviceError::NotOpen);
        }
        self.command = self.command_for_force(force_n);
        self.session.force_written();
        self.send()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kinematics::Linkage;

    #[test]
    fn frames_are_a_proper_rotation() {
        let v = Vec3::new(1.0, 2.0, 3.0);
        assert_eq!(wh_to_device(device_to_wh(v)), v);
        // Right-handed: x_wh × y_wh = z_wh maps to Z × X = Y.
        assert_eq!(Vec3::Z.cross(Vec3::X), Vec3::Y);
    }

    #[test]
    fn woodenhaptics_reports_give_positions_and_forces_give_currents() {
        let profile = DeviceProfile::built_in("woodenhaptics").unwrap();
        let mut arm = HidArm::new(profile).unwrap();
        let model = arm.model.unwrap();
        let Linkage::Serial(geo) = model.linkage else {
            unreachable!()
        };
        let target = DVec3::new(0.02, -0.01, 0.03);
        let q = geo.inverse(target).unwrap();
        let counts = model.joints.counts(q).map(|c| c.round() as i16);
        let report = wh::encode_status(&wh::WhStatus {
            encoders: [counts[0], counts[1], counts[2], 0, 0, 0],
            info: 0,
        });
        arm.apply_report(&report, 1000).unwrap();
        assert!(
            (arm.session.state().position_m - wh_to_device(target)).length() < 1e-3,
            "{}",
            arm.session.state().position_m
        );
        assert_eq!(arm.session.state().sequence, 1);
        // A force along the device's +z pushes the tool toward the user (WoodenHaptics +x).
        let cmd = arm.command_for_force(Vec3::new(0.0, 0.0, 2.0));
        let wh::WhCommand::Drive { currents_ma } = wh::decode_command(&cmd).unwrap() else {
            panic!()
        };
        let m = arm.model.unwrap();
        let back = m.joints.torques_from_commands(currents_ma);
        let expect = m.joint_torques(DVec3::new(2.0, 0.0, 0.0)).unwrap();
        assert!(
            (back - expect).abs().max_element() < 2e-3,
            "{back} vs {expect}"
        );
        // Malformed report.
        assert!(matches!(
            arm.apply_report(&report[..10], 2000),
            Err(DeviceError::Protocol { .. })
        ));
        // Non-finite force: zero currents.
        let cmd = arm.command_for_force(Vec3::NAN);
        assert_eq!(
            wh::decode_command(&cmd).unwrap(),
            wh::WhCommand::Drive {
                currents_ma: [0; 3]
            }
        );
    }

    #[test]
    fn cartesian_hid_reports_round_trip_through_the_driver() {
        let mut arm = HidArm::new(DeviceProfile::built_in("cartesian-hid").unwrap()).unwrap();
        let r = cartesian::encode_state(&cartesian::CartesianState {
            position_um: [1000, 2000, -3000],
            buttons: 5,
            status: 1,
            seq: 0,
        });
        arm.apply_report(&r, 10).unwrap();
        assert!((arm.session.state().position_m - Vec3::new(0.001, 0.002, -0.003)).length() < 1e-9);
        assert_eq!(arm.session.state().buttons, 5);
        let c =
            cartesian::decode_command(&arm.command_for_force(Vec3::new(100.0, 0.0, 0.0))).unwrap();
        assert_eq!(c.force_mn, [5000, 0, 0], "clamped to the profile's 5 N");
        assert!(HidArm::new(DeviceProfile::built_in("falcon").unwrap()).is_err());
    }

    #[test]
    fn no_device_here_means_a_clear_not_found() {
        let mut arm = HidArm::new(DeviceProfile::built_in("woodenhaptics").unwrap()).unwrap();
        match arm.open() {
            Err(DeviceError::NotFound { what }) => assert!(what.contains("1234:0006"), "{what}"),
            Err(DeviceError::Io { .. } | DeviceError::PermissionDenied { .. }) => {}
            other => panic!("unexpected {other:?}"),
        }
        assert_eq!(arm.read(), Err(DeviceError::NotOpen));
    }
}
