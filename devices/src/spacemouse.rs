//! 3Dconnexion SpaceMouse driver: a 6-DoF tool-pose input without force.
//!
//! Implements [`HapticDevice`] with `has_force = false` (forces are accepted and discarded) and
//! `has_orientation = true`, so the engine drives a tool with it exactly as with an arm. The
//! SpaceMouse is a rate controller: reports (decoded by [`crate::codec::spacemouse`]) set the
//! deflection, and each `read` integrates the pose over the time since the previous read
//! ([`PoseIntegrator`]). `read` drains queued reports without blocking and allocates nothing.

use std::time::Instant;

use glam::Vec3;
use hidapi::{HidApi, HidDevice};

use crate::codec::CodecError;
use crate::codec::spacemouse::{SpaceMouseReport, decode_report};
use crate::device::{DeviceError, DeviceInfo, DeviceState, HapticDevice};
use crate::hid_link::open_hid;
use crate::pose_input::{PoseInputConfig, PoseIntegrator};

/// USB IDs handled as SpaceMice (kept in the one table of supported USB devices).
pub use crate::usb_ids::SPACEMOUSE_IDS;

/// Largest number of queued reports one `read` drains.
const MAX_REPORTS_PER_READ: usize = 64;

/// A SpaceMouse as a pose input.
pub struct SpaceMouse {
    config: PoseInputConfig,
    pose: PoseIntegrator,
    api: Option<HidApi>,
    dev: Option<HidDevice>,
    buttons: u64,
    t0: Instant,
    last_read: Instant,
    sequence: u64,
    /// Reports with an ID this driver does not use (battery, LED state), skipped.
    pub ignored_reports: u64,
}

impl SpaceMouse {
    /// A SpaceMouse (not opened yet) with these pose settings.
    #[must_use]
    pub fn new(config: PoseInputConfig) -> Self {
        let now = Instant::now();
        Self {
            config,
            pose: PoseIntegrator::new(config),
            api: None,
            dev: None,
            buttons: 0,
            t0: now,
            last_read: now,
            sequence: 0,
            ignored_reports: 0,
        }
    }

    /// Applies one decoded report to the pose input (public so recorded reports can be
    /// replayed through the same path).
    pub fn apply(&mut self, report: SpaceMouseReport) {
        match report {
            SpaceMouseReport::Translation(t) => self.pose.set_translation(t),
            SpaceMouseReport::Rotation(r) => self.pose.set_rotation(r),
            SpaceMouseReport::Combined {
                translation,
                rotation,
            } => {
                self.pose.set_translation(translation);
                self.pose.set_rotation(rotation);
            }
            SpaceMouseReport::Buttons(b) => self.buttons = b,
        }
    }

    /// The integrated pose.
    #[must_use]
    pub fn pose(&self) -> &PoseIntegrator {
        &self.pose
    }
}

impl HapticDevice for SpaceMouse {
    fn info(&self) -> DeviceInfo {
        DeviceInfo {
            name: "3Dconnexion SpaceMouse".into(),
            dof: 6,
            max_force_n: 0.0,
            max_stiffness_n_per_m: 0.0,
            max_damping_n_s_per_m: 0.0,
            workspace_min_m: self.config.workspace_min_m,
            workspace_max_m: self.config.workspace_max_m,
            has_orientation: true,
            has_force: false,
            button_count: 32,
            sample_rate_hz: 0.0,
        }
    }

    fn open(&mut self) -> Result<(), DeviceError> {
        if self.dev.is_some() {
            return Ok(());
        }
        let (api, dev, _path) = open_hid(&SPACEMOUSE_IDS, "SpaceMouse (3Dconnexion 046d/256f)")?;
        self.api = Some(api);
        self.dev = Some(dev);
        self.pose = PoseIntegrator::new(self.config);
        self.buttons = 0;
        self.t0 = Instant::now();
        self.last_read = self.t0;
        self.sequence = 0;
        Ok(())
    }

    fn close(&mut self) -> Result<(), DeviceError> {
        self.dev = None;
        self.api = None;
        Ok(())
    }

    fn is_open(&self) -> bool {
        self.dev.is_some()
    }

    fn read(&mut self) -> Result<DeviceState, DeviceError> {
        let mut buf = [0u8; 64];
        let mut fault = None;
        for _ in 0..MAX_REPORTS_PER_READ {
            let dev = self.dev.as_ref().ok_or(DeviceError::NotOpen)?;
            let n = dev.read(&mut buf).map_err(|_| DeviceError::Disconnected)?;
            if n == 0 {
                break;
            }
            match decode_report(&buf[..n]) {
                Ok(r) => self.apply(r),
                // Reports with other IDs (battery level, LED) are not pose data.
                Err(CodecError::BadByte { offset: 0, .. }) => self.ignored_reports += 1,
                Err(_) => {
                    fault.get_or_insert(DeviceError::Protocol {
                        what: "SpaceMouse report of the wrong length",
                        offset: 0,
                    });
                }
            }
        }
        let now = Instant::now();
        self.pose
            .step(now.duration_since(self.last_read).as_secs_f32());
        self.last_read = now;
        if let Some(f) = fault {
            return Err(f);
        }
        self.sequence += 1;
        Ok(DeviceState {
            position_m: self.pose.position_m,
            orientation: Some(self.pose.orientation),
            velocity_m_per_s: self.pose.velocity_m_per_s,
            buttons: self.buttons as u32,
            timestamp_us: now.duration_since(self.t0).as_micros() as u64,
            sequence: self.sequence,
        })
    }

    fn write_force(&mut self, _force_n: Vec3) -> Result<(), DeviceError> {
        if self.dev.is_none() {
            return Err(DeviceError::NotOpen);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::codec::spacemouse::encode_report;

    #[test]
    fn reports_drive_the_pose_and_buttons() {
        let mut m = SpaceMouse::new(PoseInputConfig::default());
        for r in [
            SpaceMouseReport::Translation([350, 0, 0]),
            SpaceMouseReport::Rotation([0, 0, 0]),
            SpaceMouseReport::Buttons(0b10),
        ] {
            let (b, n) = encode_report(&r);
            m.apply(decode_report(&b[..n]).unwrap());
        }
        m.pose.step(0.1);
        assert!(m.pose().position_m.x > 0.01);
        assert_eq!(m.buttons, 2);
        let info = m.info();
        assert!(!info.has_force && info.has_orientation && info.dof == 6);
        assert_eq!(m.write_force(Vec3::X), Err(DeviceError::NotOpen));
        assert_eq!(m.read(), Err(DeviceError::NotOpen));
    }
}
