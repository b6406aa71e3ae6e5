//! The one device abstraction: every haptic or pose-input device is a [`HapticDevice`].
//!
//! Guarantee for implementors: after [`HapticDevice::open`] succeeds, [`HapticDevice::read`] and
//! [`HapticDevice::write_force`] are called from the 1 kHz haptic thread, so they must allocate
//! nothing, take no blocking lock and return within a bounded time (well under a millisecond).
//! A read that has nothing new returns the previous sample again (same `sequence`); a read that
//! cannot get an answer in time returns [`DeviceError::Timeout`] instead of waiting longer.
//!
//! Force never goes to a device directly from the engine: it goes through
//! [`crate::SafetyFilter::write_force`], which itself calls the wrapped device's `write_force`.
//! The simulated arm ([`crate::SimulatedArm`]) is the reference driver to copy when writing a
//! new one.

use std::fmt;
use std::io;

use glam::{Quat, Vec3};

/// Static description of a device, after the fields of CHAI3D's device info.
///
/// Forces, stiffnesses and the workspace are the limits the safety filter and the force
/// renderer must respect. The workspace is an axis-aligned box in the device frame (metres,
/// right-handed, +y up, +z toward the user) that the end effector can reach.
#[derive(Clone, Debug, PartialEq)]
pub struct DeviceInfo {
    /// Human-readable model name, e.g. `"Novint Falcon"` or `"simulated arm"`.
    pub name: String,
    /// Degrees of freedom sensed (3 for position only, 6 with orientation).
    pub dof: u8,
    /// Largest continuous force the device may be commanded to output, newtons.
    pub max_force_n: f32,
    /// Largest virtual stiffness the device renders stably, newtons per metre.
    pub max_stiffness_n_per_m: f32,
    /// Largest virtual damping the device renders stably, newton-seconds per metre.
    pub max_damping_n_s_per_m: f32,
    /// Lower corner of the reachable workspace, metres.
    pub workspace_min_m: Vec3,
    /// Upper corner of the reachable workspace, metres.
    pub workspace_max_m: Vec3,
    /// Whether [`DeviceState::orientation`] is ever `Some`.
    pub has_orientation: bool,
    /// Whether the device outputs force. A device without force accepts
    /// [`HapticDevice::write_force`] and discards the value.
    pub has_force: bool,
    /// Number of buttons reported in [`DeviceState::buttons`] (bit `i` is button `i`).
    pub button_count: u8,
    /// Rate at which the device produces fresh samples, hertz (0 if unknown).
    pub sample_rate_hz: f32,
}

impl DeviceInfo {
    /// Centre of the workspace box, metres.
    #[must_use]
    pub fn workspace_center_m(&self) -> Vec3 {
        (self.workspace_min_m + self.workspace_max_m) * 0.5
    }

    /// Edge lengths of the workspace box, metres.
    #[must_use]
    pub fn workspace_size_m(&self) -> Vec3 {
        self.workspace_max_m - self.workspace_min_m
    }
}

/// One sample read from a device: plain data, copied by value through the loops.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DeviceState {
    /// End-effector position in the device frame, metres.
    pub position_m: Vec3,
    /// End-effector orientation, if the device senses it.
    pub orientation: Option<Quat>,
    /// End-effector velocity, metres per second (measured or estimated by the driver).
    pub velocity_m_per_s: Vec3,
    /// Button bitmask: bit `i` set while button `i` is pressed.
    pub buttons: u32,
    /// Time the sample was taken, microseconds on the device's monotonic clock since `open`.
    pub timestamp_us: u64,
    /// Count of fresh samples the device has produced since `open`. A read that returns the
    /// same `sequence` as the previous one returned a repeated (stale) sample; a jump of more
    /// than one means samples were lost between device and host.
    pub sequence: u64,
}

impl DeviceState {
    /// A state at the origin, at rest, no buttons, time zero.
    pub const ZERO: Self = Self {
        position_m: Vec3::ZERO,
        orientation: None,
        velocity_m_per_s: Vec3::ZERO,
        buttons: 0,
        timestamp_us: 0,
        sequence: 0,
    };

    /// Whether button `index` is pressed (`false` for indices past 31).
    #[must_use]
    pub fn button(&self, index: u32) -> bool {
        index < 32 && self.buttons & (1 << index) != 0
    }
}

impl Default for DeviceState {
    fn default() -> Self {
        Self::ZERO
    }
}

/// What went wrong talking to a device.
///
/// The variants a driver returns from `read`/`write_force` on the haptic path
/// (`NotOpen`, `Disconnected`, `Timeout`, `Protocol`, `Io`, `Vendor`, `EndOfRecording`) carry no heap
/// data, so producing them allocates nothing. Variants with strings come from `open` and
/// configuration only.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum DeviceError {
    /// `read` or `write_force` was called while the device is not open.
    #[error("device is not open")]
    NotOpen,
    /// The device went away (unplugged, port closed by the peer, powered off).
    #[error("device disconnected")]
    Disconnected,
    /// No answer arrived within the bounded wait.
    #[error("device did not answer within {waited_us} µs")]
    Timeout {
        /// How long the driver waited, microseconds.
        waited_us: u64,
    },
    /// The device sent bytes that do not follow its protocol.
    #[error("device protocol error at byte {offset}: {what}")]
    Protocol {
        /// What was wrong, e.g. `"bad frame terminator"`.
        what: &'static str,
        /// Byte offset of the fault within the report, frame or stream.
        offset: usize,
    },
    /// An operating-system I/O call failed.
    #[error("I/O error during {context}: {kind}{}", OsCode(*os_code))]
    Io {
        /// The kind of failure.
        kind: io::ErrorKind,
        /// The raw OS error code, if there was one.
        os_code: Option<i32>,
        /// Which operation failed, e.g. `"write HID report"`.
        context: &'static str,
    },
    /// The device node exists but this user may not open it (see the udev rules in the user guide, `docs/src/devices.md`).
    #[error(
        "permission denied opening {path} (install the udev rules: `dynaclay devices` prints the command, or add your user to the owning group)"
    )]
    PermissionDenied {
        /// Path of the device node, e.g. `/dev/hidraw3`.
        path: String,
    },
    /// No device matching the request was found.
    #[error("no device found: {what}")]
    NotFound {
        /// What was looked for, e.g. `"HID 0x1234:0x0001"`.
        what: String,
    },
    /// A device profile or setting is invalid.
    #[error("{origin}: {message}")]
    Config {
        /// Where the setting came from: a file path (with line when known) or an option name.
        origin: String,
        /// What is wrong with it.
        message: String,
    },
    /// The device does not support the requested operation.
    #[error("device does not support {what}")]
    Unsupported {
        /// The operation, e.g. `"orientation"`.
        what: &'static str,
    },
    /// A vendor library the driver loads at run time (OpenHaptics, Force Dimension) could not
    /// be loaded: which library, every place it was looked for, and how to install it.
    #[error(transparent)]
    LibraryMissing(Box<crate::vendor_lib::LibraryMissing>),
    /// A vendor library reported an error code on the haptic path (a device fault, a lost
    /// connection); no heap data, so returning it allocates nothing.
    #[error("{library} reported error {code:#06x} during {context}")]
    Vendor {
        /// Which library, e.g. `"OpenHaptics HD"`.
        library: &'static str,
        /// The library's error code (`HD_COMM_ERROR`, `DHD_ERROR_COM`, ...).
        code: u32,
        /// Which call or stage failed, e.g. `"servo frame"`.
        context: &'static str,
    },
    /// A replayed recording has no more samples.
    #[error("recording ended after {samples} samples")]
    EndOfRecording {
        /// How many samples the recording held.
        samples: u64,
    },
}

impl DeviceError {
    /// Converts an I/O error from `context` without allocating.
    #[must_use]
    pub fn io(err: &io::Error, context: &'static str) -> Self {
        Self::Io {
            kind: err.kind(),
            os_code: err.raw_os_error(),
            context,
        }
    }

    /// Whether retrying the same call may succeed without reopening the device
    /// (a timeout or a garbled report), as opposed to a lost or unusable device.
    #[must_use]
    pub fn is_transient(&self) -> bool {
        matches!(self, Self::Timeout { .. } | Self::Protocol { .. })
    }
}

/// ` (os error N)` after an I/O error's kind, when the OS gave a code (allocates nothing).
struct OsCode(Option<i32>);

impl fmt::Display for OsCode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.0 {
            Some(code) => write!(f, " (os error {code})"),
            None => Ok(()),
        }
    }
}

/// A haptic device or pose-input device, after CHAI3D's `cGenericHapticDevice`.
///
/// Object safe and `Send`, so the engine holds a `Box<dyn HapticDevice>` and moves it into the
/// haptic thread. The contract for implementors:
/// - `open` may block, allocate and do I/O (handshakes, firmware upload, homing). Opening an
///   open device is a no-op that returns `Ok`.
/// - `read` and `write_force` run at 1 kHz: no allocation, no blocking lock, bounded time.
///   Both return [`DeviceError::NotOpen`] before `open` or after `close`.
/// - `write_force` takes the force in newtons in the device frame. A device whose
///   [`DeviceInfo::has_force`] is `false` accepts and discards it. Drivers may clamp to their
///   hardware limits, but the engine never calls this directly: force goes out through
///   [`crate::SafetyFilter`].
/// - `close` commands zero force before releasing the hardware, and is idempotent.
pub trait HapticDevice: Send {
    /// Static description of the device. Drivers that learn limits during `open` (a device
    /// profile, a firmware query) return the updated values afterwards.
    fn info(&self) -> DeviceInfo;

    /// Connects to the device and makes it ready for `read` and `write_force`.
    ///
    /// # Errors
    /// [`DeviceError::NotFound`], [`DeviceError::PermissionDenied`], [`DeviceError::Io`],
    /// [`DeviceError::Config`] or a protocol/timeout error from the handshake.
    fn open(&mut self) -> Result<(), DeviceError>;

    /// Commands zero force and releases the device. Closing a closed device returns `Ok`.
    ///
    /// # Errors
    /// An I/O error while sending the final zero-force command (the device is released anyway).
    fn close(&mut self) -> Result<(), DeviceError>;

    /// Whether the device is open (it may still fail on the next call if it was unplugged).
    fn is_open(&self) -> bool;

    /// Returns the latest sample, within bounded time.
    ///
    /// # Errors
    /// [`DeviceError::NotOpen`], [`DeviceError::Disconnected`], [`DeviceError::Timeout`],
    /// [`DeviceError::Protocol`], [`DeviceError::Io`], or [`DeviceError::EndOfRecording`]
    /// from a replay.
    fn read(&mut self) -> Result<DeviceState, DeviceError>;

    /// Sends a force command, newtons, within bounded time.
    ///
    /// # Errors
    /// [`DeviceError::NotOpen`], [`DeviceError::Disconnected`], [`DeviceError::Timeout`] or
    /// [`DeviceError::Io`].
    fn write_force(&mut self, force_n: Vec3) -> Result<(), DeviceError>;
}

impl<D: HapticDevice + ?Sized> HapticDevice for Box<D> {
    fn info(&self) -> DeviceInfo {
        (**self).info()
    }
    fn open(&mut self) -> Result<(), DeviceError> {
        (**self).open()
    }
    fn close(&mut self) -> Result<(), DeviceError> {
        (**self).close()
    }
    fn is_open(&self) -> bool {
        (**self).is_open()
    }
    fn read(&mut self) -> Result<DeviceState, DeviceError> {
        (**self).read()
    }
    fn write_force(&mut self, force_n: Vec3) -> Result<(), DeviceError> {
        (**self).write_force(force_n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trait_is_object_safe_and_send() {
        fn assert_send<T: Send + ?Sized>() {}
        assert_send::<dyn HapticDevice>();
        assert_send::<Box<dyn HapticDevice>>();
    }

    #[test]
    fn button_bits() {
        let s = DeviceState {
            buttons: 0b101,
            ..DeviceState::ZERO
        };
        assert!(s.button(0));
        assert!(!s.button(1));
        assert!(s.button(2));
        assert!(!s.button(40));
    }

    #[test]
    fn error_messages_name_what_and_where() {
        let e = DeviceError::Protocol {
            what: "bad frame terminator",
            offset: 15,
        };
        assert_eq!(
            e.to_string(),
            "device protocol error at byte 15: bad frame terminator"
        );
        let e = DeviceError::io(&io::Error::from_raw_os_error(5), "write HID report");
        assert!(e.to_string().contains("write HID report"), "{e}");
        assert!(e.to_string().contains("os error 5"), "{e}");
        assert!(DeviceError::Timeout { waited_us: 900 }.is_transient());
        assert!(!DeviceError::Disconnected.is_transient());
    }

    #[test]
    fn workspace_helpers() {
        let info = DeviceInfo {
            name: "x".into(),
            dof: 3,
            max_force_n: 1.0,
            max_stiffness_n_per_m: 1.0,
            max_damping_n_s_per_m: 0.0,
            workspace_min_m: Vec3::splat(-0.1),
            workspace_max_m: Vec3::new(0.1, 0.3, 0.1),
            has_orientation: false,
            has_force: true,
            button_count: 1,
            sample_rate_hz: 1000.0,
        };
        assert!(
            info.workspace_center_m()
                .abs_diff_eq(Vec3::new(0.0, 0.1, 0.0), 1e-6)
        );
        assert!(
            info.workspace_size_m()
                .abs_diff_eq(Vec3::new(0.2, 0.4, 0.2), 1e-6)
        );
    }
}
