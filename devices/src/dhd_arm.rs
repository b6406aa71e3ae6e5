//! Force Dimension arms (omega, delta, sigma, lambda) and the Novint Falcon through Force
//! Dimension's DHD API (`libdhd.so`), loaded at run time (see [`crate::vendor_lib`]).
//!
//! Who ticks: DHD has no scheduler of its own; each `dhdGetPosition` is a fresh exchange with
//! the arm and each `dhdSetForce` one force command. So dynaclay's haptic loop drives the
//! device: `read` calls `dhdGetPosition` (and the button mask and the device clock) once, and
//! `write_force` calls `dhdSetForce` once, so the force reaches the arm exactly once per loop
//! tick. These calls allocate nothing and take no lock of ours; their duration is the SDK's
//! USB round trip (under a millisecond in DHD's default synchronous mode), which the driver
//! cannot bound further.
//!
//! Frames: DHD's x points toward the user, y right, z up (metres, origin at the workspace
//! centre); the device frame dynaclay uses is x right, y up, z toward the user, so positions
//! map `(x, y, z)_dhd → (y, z, x)` and forces the inverse, a rotation (no mirror).
//!
//! Time is the SDK's clock (`dhdGetTime`), so the safety filter's slew limit runs on device
//! time and the velocity estimate on the SDK's sample times.
//!
//! Faults: a failed position read or force command returns [`DeviceError::Vendor`] with DHD's
//! error code; the safety filter then sends zero. `open` enables forces and commands zero
//! before the first read; `close` commands zero before `dhdClose`.

use std::ffi::{CStr, c_char, c_int, c_uchar, c_uint};

use glam::Vec3;

use crate::device::{DeviceError, DeviceInfo, DeviceState, HapticDevice};
use crate::velocity::VelocityEstimator;
use crate::vendor_lib::{self, LibraryMissing, LibrarySource, LoadedLibrary, VendorLibrary};

/// Name of the library in [`DeviceError::Vendor`].
const LIBRARY: &str = "Force Dimension DHD";
/// `DHD_ON`.
const DHD_ON: c_uchar = 1;
/// `DHD_ERROR` (the generic code), used when the SDK has no `dhdErrorGetLast`.
const DHD_ERROR: u32 = 1;

// System types of Force Dimension's public header dhdc.h.
const DHD_DEVICE_3DOF: c_int = 31;
const DHD_DEVICE_OMEGA: c_int = 32;
const DHD_DEVICE_OMEGA3: c_int = 33;
const DHD_DEVICE_OMEGA33: c_int = 34;
const DHD_DEVICE_OMEGA331: c_int = 35;
const DHD_DEVICE_OMEGA33_LEFT: c_int = 36;
const DHD_DEVICE_OMEGA331_LEFT: c_int = 37;
const DHD_DEVICE_FALCON: c_int = 60;
const DHD_DEVICE_6DOF: c_int = 61;
const DHD_DEVICE_6DOF_500: c_int = 62;
const DHD_DEVICE_DELTA3: c_int = 63;
const DHD_DEVICE_DELTA6: c_int = 64;
const DHD_DEVICE_SIGMA331: c_int = 104;
const DHD_DEVICE_SIGMA331_LEFT: c_int = 105;

/// The loaded library and the DHD functions the driver calls; the pointers are valid while
/// `library` lives, and never leave this struct.
struct DhdApi {
    get_device_count: unsafe extern "C" fn() -> c_int,
    open_id: unsafe extern "C" fn(c_char) -> c_int,
    close: unsafe extern "C" fn(c_char) -> c_int,
    get_system_type: unsafe extern "C" fn(c_char) -> c_int,
    get_system_name: Option<unsafe extern "C" fn(c_char) -> *const c_char>,
    enable_force: unsafe extern "C" fn(c_uchar, c_char) -> c_int,
    get_position: unsafe extern "C" fn(*mut f64, *mut f64, *mut f64, c_char) -> c_int,
    set_force: unsafe extern "C" fn(f64, f64, f64, c_char) -> c_int,
    get_button_mask: Option<unsafe extern "C" fn(c_char) -> c_uint>,
    get_time: unsafe extern "C" fn() -> f64,
    error_get_last: Option<unsafe extern "C" fn() -> c_int>,
    error_get_last_str: unsafe extern "C" fn() -> *const c_char,
    library: LoadedLibrary,
}

impl DhdApi {
    fn load(source: &LibrarySource) -> Result<Self, LibraryMissing> {
        let library = vendor_lib::load(
            VendorLibrary::ForceDimensionDhd,
            source,
            "dhdGetDeviceCount",
        )?;
        let missing = |tried| LibraryMissing {
            library: VendorLibrary::ForceDimensionDhd,
            tried: vec![tried],
        };
        // SAFETY: each type below is the C declaration of the named function in dhdc.h
        // (`char ID` is c_char, `uchar` c_uchar, `uint` c_uint; __SDK is the C convention on
        // Linux), and the pointers live in this struct beside `library`, which outlives them.
        unsafe {
            Ok(Self {
                get_device_count: vendor_lib::function(&library, "dhdGetDeviceCount")
                    .map_err(missing)?,
                open_id: vendor_lib::function(&library, "dhdOpenID").map_err(missing)?,
                close: vendor_lib::function(&library, "dhdClose").map_err(missing)?,
                get_system_type: vendor_lib::function(&library, "dhdGetSystemType")
                    .map_err(missing)?,
                get_system_name: vendor_lib::optional_function(&library, "dhdGetSystemName"),
                enable_force: vendor_lib::function(&library, "dhdEnableForce").map_err(missing)?,
                get_position: vendor_lib::function(&library, "dhdGetPosition").map_err(missing)?,
                set_force: vendor_lib::function(&library, "dhdSetForce").map_err(missing)?,
                get_button_mask: vendor_lib::optional_function(&library, "dhdGetButtonMask"),
                get_time: vendor_lib::function(&library, "dhdGetTime").map_err(missing)?,
                error_get_last: vendor_lib::optional_function(&library, "dhdErrorGetLast"),
                error_get_last_str: vendor_lib::function(&library, "dhdErrorGetLastStr")
                    .map_err(missing)?,
                library,
            })
        }
    }

    /// DHD's last error code (allocation-free).
    fn last_error(&self) -> u32 {
        match self.error_get_last {
            // SAFETY: dhdErrorGetLast takes no arguments and returns the thread's last error.
            Some(f) => u32::try_from(unsafe { f() }).unwrap_or(DHD_ERROR),
            None => DHD_ERROR,
        }
    }

    /// DHD's text for the last error (allocates: `open` only).
    fn last_error_text(&self) -> String {
        // SAFETY: dhdErrorGetLastStr returns a static NUL-terminated string or null.
        let p = unsafe { (self.error_get_last_str)() };
        if p.is_null() {
            return "the library gives no text for its last error".into();
        }
        // SAFETY: non-null and NUL-terminated, static in the library.
        unsafe { CStr::from_ptr(p) }.to_string_lossy().into_owned()
    }

    fn system_name(&self, id: c_char) -> Option<String> {
        // SAFETY: dhdGetSystemName takes an open device ID and returns a static string or null.
        let p = unsafe { (self.get_system_name?)(id) };
        // SAFETY: non-null and NUL-terminated, static in the library.
        (!p.is_null()).then(|| unsafe { CStr::from_ptr(p) }.to_string_lossy().into_owned())
    }
}

/// Published figures of a DHD system type: (model, max force N, stiffness N/m, damping N·s/m,
/// workspace radius m, buttons). The figures are the ones CHAI3D's Force Dimension driver
/// (CDeltaDevices) gives each model; `None` for a type not in that table.
#[must_use]
pub fn published_figures(system_type: c_int) -> Option<(&'static str, f32, f32, f32, f32, u8)> {
    Some(match system_type {
        DHD_DEVICE_OMEGA | DHD_DEVICE_OMEGA3 => ("omega.3", 12.0, 5000.0, 30.0, 0.075, 1),
        DHD_DEVICE_OMEGA33 | DHD_DEVICE_OMEGA33_LEFT => ("omega.6", 12.0, 5000.0, 30.0, 0.075, 1),
        DHD_DEVICE_OMEGA331 | DHD_DEVICE_OMEGA331_LEFT => ("omega.7", 12.0, 5000.0, 30.0, 0.075, 1),
        DHD_DEVICE_3DOF | DHD_DEVICE_DELTA3 => ("delta.3", 20.0, 5000.0, 30.0, 0.15, 1),
        DHD_DEVICE_6DOF | DHD_DEVICE_6DOF_500 | DHD_DEVICE_DELTA6 => {
            ("delta.6", 20.0, 5000.0, 30.0, 0.15, 1)
        }
        DHD_DEVICE_FALCON => ("Novint Falcon", 8.0, 3000.0, 20.0, 0.04, 4),
        DHD_DEVICE_SIGMA331 | DHD_DEVICE_SIGMA331_LEFT => ("sigma.7", 12.0, 4000.0, 30.0, 0.09, 1),
        _ => return None,
    })
}

/// The [`DeviceInfo`] for a DHD system type. A type without published figures (a lambda, a
/// newer model) gets the most conservative of the table, the Falcon's limits, under the name
/// the SDK reports. The workspace is the cube circumscribing CHAI3D's workspace sphere, about
/// DHD's origin (the workspace centre). Orientation and gripper are not read: 3 degrees of
/// freedom.
#[must_use]
pub fn info_for_system_type(system_type: c_int, sdk_name: Option<&str>) -> DeviceInfo {
    let (model, force, stiffness, damping, radius, buttons) = published_figures(system_type)
        .unwrap_or(("Force Dimension arm", 8.0, 3000.0, 20.0, 0.04, 1));
    let name = match (published_figures(system_type), sdk_name) {
        (None, Some(n)) if !n.is_empty() => format!("{n} (Force Dimension DHD)"),
        (None, _) => format!("Force Dimension arm, system type {system_type} (DHD)"),
        (Some(_), _) => format!("{model} (Force Dimension DHD)"),
    };
    DeviceInfo {
        name,
        dof: 3,
        max_force_n: force,
        max_stiffness_n_per_m: stiffness,
        max_damping_n_s_per_m: damping,
        workspace_min_m: Vec3::splat(-radius),
        workspace_max_m: Vec3::splat(radius),
        has_orientation: false,
        has_force: true,
        button_count: buttons,
        sample_rate_hz: 0.0,
    }
}

/// DHD's frame (x toward the user, y right, z up) to the device frame (x right, y up, z
/// toward the user).
#[must_use]
pub fn dhd_to_device(v: [f64; 3]) -> Vec3 {
    Vec3::new(v[1] as f32, v[2] as f32, v[0] as f32)
}

/// The device frame to DHD's.
#[must_use]
pub fn device_to_dhd(v: Vec3) -> [f64; 3] {
    [f64::from(v.z), f64::from(v.x), f64::from(v.y)]
}

/// Settings of a [`DhdArm`].
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct DhdConfig {
    /// Where `libdhd.so` comes from.
    pub library: LibrarySource,
    /// Which connected device, counting from 0 (`--device dhd:N`).
    pub index: u8,
}

struct DhdSession {
    api: DhdApi,
    id: c_char,
    t0_s: f64,
    last_timestamp_us: u64,
    sequence: u64,
    velocity: VelocityEstimator,
}

impl DhdSession {
    /// Zero force, then release the device. Errors are reported but the device is released.
    fn close(&mut self) -> Result<(), DeviceError> {
        // SAFETY: `id` is the ID dhdOpenID returned; zero force then close, as DHD documents.
        let (zero, closed) = unsafe {
            (
                (self.api.set_force)(0.0, 0.0, 0.0, self.id),
                (self.api.close)(self.id),
            )
        };
        if zero < 0 || closed < 0 {
            return Err(DeviceError::Vendor {
                library: LIBRARY,
                code: self.api.last_error(),
                context: "closing the device",
            });
        }
        Ok(())
    }
}

/// A Force Dimension (or Falcon) arm through DHD; see the module docs for who ticks.
pub struct DhdArm {
    config: DhdConfig,
    info: DeviceInfo,
    session: Option<DhdSession>,
    loaded_from: Option<String>,
}

impl DhdArm {
    /// An arm (not opened yet); nothing is loaded until `open`. Until then its info holds the
    /// most conservative published limits (the model is known only once open).
    #[must_use]
    pub fn new(config: DhdConfig) -> Self {
        let mut info = info_for_system_type(-1, None);
        info.name = "Force Dimension arm (DHD)".into();
        Self {
            config,
            info,
            session: None,
            loaded_from: None,
        }
    }

    /// Where `libdhd.so` was loaded from by the last `open` (a path or a loader name).
    #[must_use]
    pub fn loaded_from(&self) -> Option<&str> {
        self.loaded_from.as_deref()
    }
}

impl HapticDevice for DhdArm {
    fn info(&self) -> DeviceInfo {
        self.info.clone()
    }

    fn open(&mut self) -> Result<(), DeviceError> {
        if self.session.is_some() {
            return Ok(());
        }
        let api = DhdApi::load(&self.config.library)
            .map_err(|e| DeviceError::LibraryMissing(Box::new(e)))?;
        // SAFETY: dhdGetDeviceCount takes no arguments.
        let count = unsafe { (api.get_device_count)() };
        if count < 0 {
            return Err(DeviceError::NotFound {
                what: format!(
                    "Force Dimension devices: dhdGetDeviceCount failed ({})",
                    api.last_error_text()
                ),
            });
        }
        let index = self.config.index;
        if c_int::from(index) >= count {
            return Err(DeviceError::NotFound {
                what: format!(
                    "Force Dimension device {index} (dhd:{index}): the SDK sees {count} \
                     device(s); is the arm powered, plugged in and allowed by its udev rule?"
                ),
            });
        }
        let wanted = c_char::try_from(index).map_err(|_| DeviceError::Config {
            origin: format!("--device dhd:{index}"),
            message: "device index out of DHD's range".into(),
        })?;
        // SAFETY: dhdOpenID takes a device index in 0..count.
        let id = unsafe { (api.open_id)(wanted) };
        let id = c_char::try_from(id)
            .ok()
            .filter(|id| *id >= 0)
            .ok_or_else(|| DeviceError::NotFound {
                what: format!(
                    "Force Dimension device {index}: dhdOpenID failed ({})",
                    api.last_error_text()
                ),
            })?;
        // SAFETY: `id` is an open device's ID.
        let system_type = unsafe { (api.get_system_type)(id) };
        let info = info_for_system_type(system_type, api.system_name(id).as_deref());
        // SAFETY: `id` is an open device's ID; forces on, then an explicit zero so the arm's
        // first force is zero, then the clock's origin.
        let (enabled, zeroed, t0_s) = unsafe {
            (
                (api.enable_force)(DHD_ON, id),
                (api.set_force)(0.0, 0.0, 0.0, id),
                (api.get_time)(),
            )
        };
        let loaded_from = api.library.from.clone();
        let mut session = DhdSession {
            api,
            id,
            t0_s,
            last_timestamp_us: 0,
            sequence: 0,
            velocity: VelocityEstimator::default(),
        };
        if enabled < 0 || zeroed < 0 {
            let code = session.api.last_error();
            let _ = session.close();
            return Err(DeviceError::Vendor {
                library: LIBRARY,
                code,
                context: "enabling forces",
            });
        }
        self.info = info;
        self.loaded_from = Some(loaded_from);
        self.session = Some(session);
        Ok(())
    }

    fn close(&mut self) -> Result<(), DeviceError> {
        match self.session.take() {
            Some(mut session) => session.close(),
            None => Ok(()),
        }
    }

    fn is_open(&self) -> bool {
        self.session.is_some()
    }

    /// One `dhdGetPosition` (plus the button mask and the SDK clock): one fresh sample.
    fn read(&mut self) -> Result<DeviceState, DeviceError> {
        let s = self.session.as_mut().ok_or(DeviceError::NotOpen)?;
        let mut p = [0.0f64; 3];
        let [px, py, pz] = p.each_mut().map(std::ptr::from_mut);
        // SAFETY: three writable doubles and an open device's ID.
        let rc = unsafe { (s.api.get_position)(px, py, pz, s.id) };
        if rc < 0 {
            return Err(DeviceError::Vendor {
                library: LIBRARY,
                code: s.api.last_error(),
                context: "dhdGetPosition",
            });
        }
        // SAFETY: an open device's ID; dhdGetTime takes no arguments.
        let (buttons, now_s) = unsafe {
            (
                s.api.get_button_mask.map_or(0, |f| f(s.id)),
                (s.api.get_time)(),
            )
        };
        let elapsed_us = ((now_s - s.t0_s).max(0.0) * 1e6) as u64;
        s.last_timestamp_us = s.last_timestamp_us.max(elapsed_us);
        s.sequence += 1;
        let position_m = dhd_to_device(p);
        let velocity_m_per_s = s.velocity.update(position_m, s.last_timestamp_us);
        Ok(DeviceState {
            position_m,
            orientation: None,
            velocity_m_per_s,
            buttons,
            timestamp_us: s.last_timestamp_us,
            sequence: s.sequence,
        })
    }

    /// One `dhdSetForce`.
    fn write_force(&mut self, force_n: Vec3) -> Result<(), DeviceError> {
        let s = self.session.as_mut().ok_or(DeviceError::NotOpen)?;
        let [fx, fy, fz] = device_to_dhd(if force_n.is_finite() {
            force_n
        } else {
            Vec3::ZERO
        });
        // SAFETY: an open device's ID.
        let rc = unsafe { (s.api.set_force)(fx, fy, fz, s.id) };
        if rc < 0 {
            return Err(DeviceError::Vendor {
                library: LIBRARY,
                code: s.api.last_error(),
                context: "dhdSetForce",
            });
        }
        Ok(())
    }
}

impl Drop for DhdArm {
    fn drop(&mut self) {
        let _ = self.close();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_frame_change_is_a_rotation_and_round_trips() {
        // DHD x toward the user is device +z, y right is +x, z up is +y.
        assert_eq!(dhd_to_device([1.0, 0.0, 0.0]), Vec3::Z);
        assert_eq!(dhd_to_device([0.0, 1.0, 0.0]), Vec3::X);
        assert_eq!(dhd_to_device([0.0, 0.0, 1.0]), Vec3::Y);
        let f = Vec3::new(0.5, -1.5, 2.0);
        assert_eq!(dhd_to_device(device_to_dhd(f)), f);
        // Right-handed in both: x × y = z maps to the image of z.
        let (x, y, z) = (
            dhd_to_device([1.0, 0.0, 0.0]),
            dhd_to_device([0.0, 1.0, 0.0]),
            dhd_to_device([0.0, 0.0, 1.0]),
        );
        assert_eq!(x.cross(y), z);
    }

    #[test]
    fn unknown_systems_get_the_most_conservative_published_limits() {
        let unknown = info_for_system_type(108, Some("lambda.7"));
        assert!(unknown.name.contains("lambda.7"), "{}", unknown.name);
        for t in [
            DHD_DEVICE_OMEGA3,
            DHD_DEVICE_OMEGA331,
            DHD_DEVICE_DELTA3,
            DHD_DEVICE_FALCON,
            DHD_DEVICE_SIGMA331,
        ] {
            let known = info_for_system_type(t, None);
            assert!(unknown.max_force_n <= known.max_force_n, "{}", known.name);
            assert!(
                unknown.max_stiffness_n_per_m <= known.max_stiffness_n_per_m,
                "{}",
                known.name
            );
            assert!(
                unknown.workspace_size_m().x <= known.workspace_size_m().x,
                "{}",
                known.name
            );
        }
        let omega = info_for_system_type(DHD_DEVICE_OMEGA3, Some("omega.3"));
        assert_eq!(omega.max_force_n, 12.0);
        assert!(omega.name.starts_with("omega.3"), "{}", omega.name);
    }
}
