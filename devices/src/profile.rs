//! Device profiles: the TOML file that says how to talk to an arm and what its geometry is.
//!
//! A profile names the protocol, the USB IDs, the force limit, the motors (encoder resolution,
//! gear ratios, torque constant, current limit) and the kinematics (link lengths, or "none" for
//! firmware that reports Cartesian positions itself). Profiles shipped with dynaclay live in
//! `devices/profiles/` and are compiled in, so `hid:woodenhaptics` works without any file; any
//! other name is read as a path. Loading validates every number and names the file and field
//! that is wrong.

use std::path::{Path, PathBuf};

use glam::Vec3;
use serde::Deserialize;

use crate::device::DeviceInfo;

/// Wire protocol of a force-feedback arm.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Protocol {
    /// WoodenHaptics / Polhem 14-byte HID reports (encoders in, motor currents out).
    Woodenhaptics,
    /// dynaclay Cartesian HID reports (µm in, mN out).
    CartesianHid,
    /// dynaclay Cartesian framed serial protocol.
    CartesianSerial,
    /// Novint Falcon frames over its FTDI serial link.
    Falcon,
}

/// Motors and encoders, one entry per driven joint.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Motors {
    /// Encoder counts per motor revolution (after quadrature decoding).
    pub counts_per_rev: [f64; 3],
    /// Motor turns per joint turn (capstan or pulley reduction).
    pub gear_ratio: [f64; 3],
    /// +1 or -1: direction of a joint angle relative to its encoder count.
    pub joint_sign: [f64; 3],
    /// Joint angle when the encoder reads 0, radians.
    pub joint_offset_rad: [f64; 3],
    /// Motor torque constant, N·m per ampere.
    pub torque_constant_nm_per_a: [f64; 3],
    /// Largest current sent to any motor, mA. Commands are scaled down together to respect it.
    pub max_current_ma: f64,
    /// Firmware command units per mA (1 for firmware that takes mA).
    #[serde(default = "one")]
    pub command_units_per_ma: f64,
    /// +1 or -1: direction of a motor command relative to a positive joint torque.
    #[serde(default = "ones")]
    pub command_sign: [f64; 3],
}

fn default_stiffness() -> f32 {
    1000.0
}

fn default_damping() -> f32 {
    5.0
}

fn one() -> f64 {
    1.0
}

fn ones() -> [f64; 3] {
    [1.0; 3]
}

/// Geometry of the arm.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum Geometry {
    /// Base yaw, upper arm, and a forearm held by a parallel linkage (WoodenHaptics, Polhem v1):
    /// `s = Lb sin θb + Lc sin θc`, `p = (s cos θa, s sin θa, Ln + Lb cos θb − Lc cos θc) − origin`.
    SerialArm {
        /// Height of the shoulder above the base, m (`Ln`).
        base_height_m: f64,
        /// Upper arm length, m (`Lb`).
        upper_arm_m: f64,
        /// Forearm length, m (`Lc`).
        forearm_m: f64,
        /// Workspace origin in base coordinates, m.
        workspace_origin_m: [f64; 3],
    },
    /// Three-legged delta (Novint Falcon): each motor turns an upper arm of length `a`; a
    /// parallelogram of length `b`, hinged with offsets `d` and `e`, joins it to the effector.
    Delta {
        /// Upper arm length, m.
        upper_arm_m: f64,
        /// Parallelogram length, m.
        parallel_m: f64,
        /// Offset of the upper arm's pivot along the leg's radial axis, m (`c`).
        pivot_offset_m: f64,
        /// Hinge offset at the elbow, m (`d`).
        elbow_offset_m: f64,
        /// Hinge offset at the effector, m (`e`).
        effector_offset_m: f64,
        /// Offset along the motor axis, m (`f`).
        axial_offset_m: f64,
        /// Radial distance of each leg's frame from the centre, m (`r`).
        leg_radius_m: f64,
        /// Sideways offset of each leg's frame, m (`s`).
        leg_side_m: f64,
        /// Azimuth of each leg, radians.
        leg_azimuth_rad: [f64; 3],
    },
    /// Firmware reports Cartesian positions itself; no kinematics on the host.
    Cartesian,
}

/// A whole device profile.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DeviceProfile {
    /// Human-readable name.
    pub name: String,
    /// Wire protocol.
    pub protocol: Protocol,
    /// USB vendor ID (HID devices; informational for serial ones).
    #[serde(default)]
    pub vendor_id: u16,
    /// USB product ID.
    #[serde(default)]
    pub product_id: u16,
    /// Largest force the arm may render, N.
    pub max_force_n: f32,
    /// Radius of the usable workspace around the origin, m.
    pub workspace_radius_m: f32,
    /// Largest virtual stiffness rendered stably, N/m.
    #[serde(default = "default_stiffness")]
    pub max_stiffness_n_per_m: f32,
    /// Largest virtual damping rendered stably, N·s/m.
    #[serde(default = "default_damping")]
    pub max_damping_n_s_per_m: f32,
    /// Motors; required unless the geometry is `cartesian`.
    pub motors: Option<Motors>,
    /// Geometry.
    pub geometry: Geometry,
    /// Firmware image uploaded at `open` when none answers (the Falcon protocol: the user's own
    /// copy of the Novint firmware). A relative path is taken from the profile file's folder.
    /// Never guessed: without it (or `--falcon-firmware FILE`) a Falcon without firmware is an
    /// error that says so.
    #[serde(default)]
    pub firmware: Option<PathBuf>,
}

/// The largest device profile file read, bytes.
pub const MAX_PROFILE_BYTES: u64 = 1 << 20;

/// Why a profile could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum ProfileError {
    /// The file could not be read.
    #[error("cannot read device profile {}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The TOML was malformed or had a missing, unknown or mistyped field.
    #[error(
        "device profile {}{}: {message}",
        path.display(),
        line.map(|l| format!(":{l}")).unwrap_or_default()
    )]
    Parse {
        /// The file, or `built-in:NAME`.
        path: PathBuf,
        /// Line (1-based) where the parser stopped, if known.
        line: Option<usize>,
        /// The parser's message (names the field).
        message: String,
    },
    /// A value was out of range.
    #[error("device profile {}: field `{field}` {reason}", path.display())]
    Invalid {
        /// The file, or `built-in:NAME`.
        path: PathBuf,
        /// Dotted field name.
        field: &'static str,
        /// What is wrong with it.
        reason: String,
    },
}

/// Names and texts of the profiles compiled into dynaclay.
pub const BUILT_IN: [(&str, &str); 5] = [
    (
        "woodenhaptics",
        include_str!("../profiles/woodenhaptics.toml"),
    ),
    ("polhem", include_str!("../profiles/polhem.toml")),
    (
        "cartesian-hid",
        include_str!("../profiles/cartesian-hid.toml"),
    ),
    (
        "cartesian-serial",
        include_str!("../profiles/cartesian-serial.toml"),
    ),
    ("falcon", include_str!("../profiles/falcon.toml")),
];

impl DeviceProfile {
    /// Parses and validates a profile from TOML text; `origin` names it in errors.
    ///
    /// # Errors
    /// [`ProfileError::Parse`] or [`ProfileError::Invalid`] naming `origin`, the line and field.
    pub fn from_toml(text: &str, origin: &Path) -> Result<Self, ProfileError> {
        let p: Self = toml::from_str(text).map_err(|e| ProfileError::Parse {
            path: origin.to_path_buf(),
            line: e
                .span()
                .map(|s| text[..s.start.min(text.len())].matches('\n').count() + 1),
            message: e.message().to_string(),
        })?;
        p.validate(origin)?;
        Ok(p)
    }

    /// A compiled-in profile by name (see [`BUILT_IN`]).
    #[must_use]
    pub fn built_in(name: &str) -> Option<Self> {
        BUILT_IN
            .iter()
            .find(|(n, _)| *n == name)
            .and_then(|(n, text)| Self::from_toml(text, Path::new(&format!("built-in:{n}"))).ok())
    }

    /// A built-in profile by name, or else the file at that path (a regular file of at most
    /// [`MAX_PROFILE_BYTES`]; a FIFO or `/dev/zero` is refused at once).
    ///
    /// # Errors
    /// [`ProfileError`] when the name is not built in and the file cannot be read or is invalid.
    pub fn load(name_or_path: &str) -> Result<Self, ProfileError> {
        if let Some(p) = Self::built_in(name_or_path) {
            return Ok(p);
        }
        let path = Path::new(name_or_path);
        let bytes = dynaclay_files::read_regular_file(path, MAX_PROFILE_BYTES).map_err(|e| {
            ProfileError::Io {
                path: path.to_path_buf(),
                source: e.into_io(),
            }
        })?;
        let text = String::from_utf8(bytes).map_err(|e| ProfileError::Io {
            path: path.to_path_buf(),
            source: std::io::Error::new(std::io::ErrorKind::InvalidData, e.utf8_error()),
        })?;
        let mut profile = Self::from_toml(&text, path)?;
        if let Some(fw) = profile.firmware.as_mut()
            && fw.is_relative()
        {
            *fw = path.parent().unwrap_or(Path::new("")).join(&*fw);
        }
        Ok(profile)
    }

    /// The [`DeviceInfo`] of an arm driven by this profile: 3 DoF, force output, the
    /// workspace a cube of side `2 × workspace_radius_m` around `center_m` (device frame).
    #[must_use]
    pub fn device_info(&self, center_m: Vec3, button_count: u8, sample_rate_hz: f32) -> DeviceInfo {
        let r = Vec3::splat(self.workspace_radius_m);
        DeviceInfo {
            name: self.name.clone(),
            dof: 3,
            max_force_n: self.max_force_n,
            max_stiffness_n_per_m: self.max_stiffness_n_per_m,
            max_damping_n_s_per_m: self.max_damping_n_s_per_m,
            workspace_min_m: center_m - r,
            workspace_max_m: center_m + r,
            has_orientation: false,
            has_force: true,
            button_count,
            sample_rate_hz,
        }
    }

    fn validate(&self, origin: &Path) -> Result<(), ProfileError> {
        let bad = |field: &'static str, reason: String| ProfileError::Invalid {
            path: origin.to_path_buf(),
            field,
            reason,
        };
        let positive = |field: &'static str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(bad(field, format!("must be a positive number, got {v}")))
            }
        };
        positive("max_force_n", f64::from(self.max_force_n))?;
        positive("workspace_radius_m", f64::from(self.workspace_radius_m))?;
        positive(
            "max_stiffness_n_per_m",
            f64::from(self.max_stiffness_n_per_m),
        )?;
        if !(self.max_damping_n_s_per_m.is_finite() && self.max_damping_n_s_per_m >= 0.0) {
            return Err(bad(
                "max_damping_n_s_per_m",
                format!(
                    "must be zero or positive, got {}",
                    self.max_damping_n_s_per_m
                ),
            ));
        }
        let needs_motors = !matches!(self.geometry, Geometry::Cartesian);
        if needs_motors != self.motors.is_some() {
            return Err(bad(
                "motors",
                if needs_motors {
                    "is required by this geometry".into()
                } else {
                    "is not used by a cartesian geometry".into()
                },
            ));
        }
        let cartesian_protocol = matches!(
            self.protocol,
            Protocol::CartesianHid | Protocol::CartesianSerial
        );
        if cartesian_protocol == needs_motors {
            return Err(bad(
                "geometry.kind",
                "must be `cartesian` exactly when the protocol is a Cartesian one".into(),
            ));
        }
        if let Some(m) = &self.motors {
            for i in 0..3 {
                positive("motors.counts_per_rev", m.counts_per_rev[i])?;
                positive("motors.gear_ratio", m.gear_ratio[i])?;
                positive(
                    "motors.torque_constant_nm_per_a",
                    m.torque_constant_nm_per_a[i],
                )?;
                if m.joint_sign[i].abs() != 1.0 {
                    return Err(bad(
                        "motors.joint_sign",
                        format!("entries must be 1 or -1, got {}", m.joint_sign[i]),
                    ));
                }
                if m.command_sign[i].abs() != 1.0 {
                    return Err(bad(
                        "motors.command_sign",
                        format!("entries must be 1 or -1, got {}", m.command_sign[i]),
                    ));
                }
                if !m.joint_offset_rad[i].is_finite() {
                    return Err(bad("motors.joint_offset_rad", "must be finite".into()));
                }
            }
            positive("motors.max_current_ma", m.max_current_ma)?;
            positive("motors.command_units_per_ma", m.command_units_per_ma)?;
            if m.max_current_ma * m.command_units_per_ma > f64::from(i16::MAX) {
                return Err(bad(
                    "motors.max_current_ma",
                    "times command_units_per_ma exceeds the i16 command range".into(),
                ));
            }
        }
        match self.geometry {
            Geometry::SerialArm {
                base_height_m,
                upper_arm_m,
                forearm_m,
                workspace_origin_m,
            } => {
                positive("geometry.upper_arm_m", upper_arm_m)?;
                positive("geometry.forearm_m", forearm_m)?;
                if !base_height_m.is_finite() || workspace_origin_m.iter().any(|v| !v.is_finite()) {
                    return Err(bad("geometry.workspace_origin_m", "must be finite".into()));
                }
            }
            Geometry::Delta {
                upper_arm_m,
                parallel_m,
                leg_azimuth_rad,
                ..
            } => {
                positive("geometry.upper_arm_m", upper_arm_m)?;
                positive("geometry.parallel_m", parallel_m)?;
                if leg_azimuth_rad.iter().any(|v| !v.is_finite()) {
                    return Err(bad("geometry.leg_azimuth_rad", "must be finite".into()));
                }
            }
            Geometry::Cartesian => {}
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_profile_names_its_firmware_relative_to_its_own_folder_and_built_ins_name_none() {
        assert_eq!(DeviceProfile::built_in("falcon").unwrap().firmware, None);
        let dir = tempfile::tempdir().unwrap();
        // A top-level key goes before the profile's tables.
        let text = "firmware = \"fw/novint.bin\"\n".to_string()
            + BUILT_IN.iter().find(|(n, _)| *n == "falcon").unwrap().1;
        let file = dir.path().join("my-falcon.toml");
        std::fs::write(&file, text).unwrap();
        let p = DeviceProfile::load(file.to_str().unwrap()).unwrap();
        assert_eq!(p.firmware, Some(dir.path().join("fw/novint.bin")));
    }

    #[test]
    fn every_built_in_profile_loads() {
        for (name, _) in BUILT_IN {
            let p = DeviceProfile::built_in(name).unwrap_or_else(|| {
                let text = BUILT_IN.iter().find(|(n, _)| *n == name).unwrap().1;
                panic!(
                    "{name}: {}",
                    DeviceProfile::from_toml(text, Path::new(name)).unwrap_err()
                )
            });
            assert!(p.max_force_n > 0.0);
        }
        assert_eq!(
            DeviceProfile::built_in("woodenhaptics").unwrap().vendor_id,
            0x1234
        );
    }

    #[test]
    fn errors_name_the_file_line_and_field() {
        let text = "name = \"x\"\nprotocol = \"woodenhaptics\"\nmax_force_n = \"strong\"\n";
        let e = DeviceProfile::from_toml(text, Path::new("arm.toml"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("arm.toml:3"), "{e}");
        let mut text = BUILT_IN[0]
            .1
            .replace("max_force_n = 8.0", "max_force_n = -1.0");
        assert!(text.contains("max_force_n = -1.0"));
        let e = DeviceProfile::from_toml(&text, Path::new("w.toml"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("max_force_n") && e.contains("positive"), "{e}");
        text = BUILT_IN[0].1.replace("[motors]", "[motors]\nbogus = 1");
        let e = DeviceProfile::from_toml(&text, Path::new("w.toml"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("bogus"), "{e}");
        let e = DeviceProfile::load("/nonexistent/arm.toml")
            .unwrap_err()
            .to_string();
        assert!(e.contains("/nonexistent/arm.toml"), "{e}");
    }
}
