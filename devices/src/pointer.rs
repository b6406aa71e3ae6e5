//! A mouse or pen as a pose-input device: the app turns the pointer into a 3-D tool tip and
//! hands it to the haptic thread through a [`PointerHandle`]; the [`PointerDevice`] reads it
//! there like any other [`HapticDevice`], so a pointer session goes through the same haptic
//! loop, safety filter, recorder and replay as an arm.
//!
//! Guarantee: the hand-over is a triple buffer (the `triple_buffer` crate): the app's
//! [`PointerHandle::set`] and the haptic thread's [`HapticDevice::read`] are each one atomic
//! swap, bounded wait-free, never block and allocate nothing after construction. The buffer
//! holds three copies of a [`PointerSample`] (a few dozen bytes). No force is output.

use std::time::Instant;

use glam::Vec3;
use triple_buffer::{Input, Output, TripleBuffer};

use crate::device::{DeviceError, DeviceInfo, DeviceState, HapticDevice};

/// Bit of [`DeviceState::buttons`] that is set while the pointer presses (a stroke).
pub const PRESS_BUTTON: u32 = 0;

/// What the app hands over each time the pointer moves.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointerSample {
    /// Tool tip, metres in the device frame (the app maps field coordinates there with the
    /// engine's workspace map).
    pub position_m: Vec3,
    /// Whether the pointer presses (left button held, or a pen touching).
    pub pressed: bool,
    /// Count of samples handed over; the device reports a fresh sample when it changes.
    pub serial: u64,
}

/// Settings of a pointer device.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointerConfig {
    /// Lower corner of the workspace the app maps the clay into, metres.
    pub workspace_min_m: Vec3,
    /// Upper corner of that workspace, metres.
    pub workspace_max_m: Vec3,
}

impl Default for PointerConfig {
    /// A 20 cm cube around the origin, like a desktop arm's.
    fn default() -> Self {
        Self {
            workspace_min_m: Vec3::splat(-0.1),
            workspace_max_m: Vec3::splat(0.1),
        }
    }
}

impl PointerConfig {
    /// The device description the engine maps its workspace from.
    #[must_use]
    pub fn info(&self) -> DeviceInfo {
        DeviceInfo {
            name: "pointer".into(),
            dof: 3,
            // Nothing is output: these bound the contact forces the engine computes for the
            // clay, at a desktop arm's figures, so a pointer stroke sculpts like an arm's.
            max_force_n: 8.0,
            max_stiffness_n_per_m: 3000.0,
            max_damping_n_s_per_m: 20.0,
            workspace_min_m: self.workspace_min_m,
            workspace_max_m: self.workspace_max_m,
            has_orientation: false,
            has_force: false,
            button_count: 1,
            sample_rate_hz: 0.0,
        }
    }
}

/// The app's end: hands the newest tool tip to the device.
pub struct PointerHandle {
    input: Input<PointerSample>,
    last: PointerSample,
    min_m: Vec3,
    max_m: Vec3,
}

impl PointerHandle {
    /// Publishes a new tip (clamped to the workspace; a non-finite position keeps the previous
    /// one) and whether the pointer presses. Wait-free.
    pub fn set(&mut self, position_m: Vec3, pressed: bool) {
        let position_m = if position_m.is_finite() {
            position_m.clamp(self.min_m, self.max_m)
        } else {
            self.last.position_m
        };
        self.last = PointerSample {
            position_m,
            pressed,
            serial: self.last.serial + 1,
        };
        *self.input.input_buffer_mut() = self.last;
        self.input.publish();
    }

    /// The last sample handed over.
    #[must_use]
    pub fn last(&self) -> PointerSample {
        self.last
    }
}

/// The haptic thread's end: a [`HapticDevice`] whose pose is the app's pointer.
pub struct PointerDevice {
    config: PointerConfig,
    output: Output<PointerSample>,
    opened_at: Option<Instant>,
    last_serial: u64,
    state: DeviceState,
}

/// A connected device and handle; the device rests at the workspace centre until the first
/// [`PointerHandle::set`].
#[must_use]
pub fn pointer_device(config: PointerConfig) -> (PointerDevice, PointerHandle) {
    let centre = (config.workspace_min_m + config.workspace_max_m) * 0.5;
    let first = PointerSample {
        position_m: centre,
        pressed: false,
        serial: 0,
    };
    let (input, output) = TripleBuffer::new(&first).split();
    let handle = PointerHandle {
        input,
        last: first,
        min_m: config.workspace_min_m.min(config.workspace_max_m),
        max_m: config.workspace_min_m.max(config.workspace_max_m),
    };
    let device = PointerDevice {
        config,
        output,
        opened_at: None,
        last_serial: 0,
        state: DeviceState {
            position_m: centre,
            ..DeviceState::ZERO
        },
    };
    (device, handle)
}

impl HapticDevice for PointerDevice {
    fn info(&self) -> DeviceInfo {
        self.config.info()
    }

    fn open(&mut self) -> Result<(), DeviceError> {
        if self.opened_at.is_none() {
            self.opened_at = Some(Instant::now());
        }
        Ok(())
    }

    fn close(&mut self) -> Result<(), DeviceError> {
        self.opened_at = None;
        Ok(())
    }

    fn is_open(&self) -> bool {
        self.opened_at.is_some()
    }

    fn read(&mut self) -> Result<DeviceState, DeviceError> {
        let Some(opened_at) = self.opened_at else {
            return Err(DeviceError::NotOpen);
        };
        let sample = *self.output.read();
        if sample.serial == self.last_serial {
            return Ok(self.state);
        }
        self.last_serial = sample.serial;
        let now_us = opened_at.elapsed().as_micros() as u64;
        let dt_s = now_us.saturating_sub(self.state.timestamp_us) as f32 * 1e-6;
        let velocity_m_per_s = if self.state.sequence > 0 && dt_s > 0.0 {
            (sample.position_m - self.state.position_m) / dt_s
        } else {
            Vec3::ZERO
        };
        self.state = DeviceState {
            position_m: sample.position_m,
            orientation: None,
            velocity_m_per_s,
            buttons: u32::from(sample.pressed) << PRESS_BUTTON,
            timestamp_us: now_us,
            sequence: self.state.sequence + 1,
        };
        Ok(self.state)
    }

    fn write_force(&mut self, _force_n: Vec3) -> Result<(), DeviceError> {
        if self.opened_at.is_none() {
            return Err(DeviceError::NotOpen);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_device_reads_what_the_handle_set_and_repeats_it_until_the_next() {
        let (mut dev, mut handle) = pointer_device(PointerConfig::default());
        assert_eq!(dev.read(), Err(DeviceError::NotOpen));
        dev.open().unwrap();
        let rest = dev.read().unwrap();
        assert_eq!(rest.position_m, Vec3::ZERO);
        assert_eq!(rest.sequence, 0);
        handle.set(Vec3::new(0.01, 0.02, 0.03), true);
        let s = dev.read().unwrap();
        assert_eq!(s.position_m, Vec3::new(0.01, 0.02, 0.03));
        assert!(s.button(PRESS_BUTTON));
        assert_eq!(s.sequence, 1);
        let again = dev.read().unwrap();
        assert_eq!(again, s, "no new sample: the same state, same sequence");
        handle.set(Vec3::new(5.0, 0.0, f32::NAN), false);
        let s = dev.read().unwrap();
        assert_eq!(
            s.position_m,
            Vec3::new(0.01, 0.02, 0.03),
            "NaN keeps the tip"
        );
        handle.set(Vec3::new(5.0, 0.0, 0.0), false);
        let s = dev.read().unwrap();
        assert_eq!(
            s.position_m,
            Vec3::new(0.1, 0.0, 0.0),
            "clamped to the workspace"
        );
        assert!(!s.button(PRESS_BUTTON));
        assert_eq!(s.sequence, 3);
        assert!(dev.write_force(Vec3::X).is_ok());
        assert!(!dev.info().has_force);
        dev.close().unwrap();
        assert_eq!(dev.write_force(Vec3::X), Err(DeviceError::NotOpen));
    }
}
