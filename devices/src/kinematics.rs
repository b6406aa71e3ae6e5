//! Arm kinematics: encoder counts → joint angles → tool position, and tool force → joint torques
//! (Jacobian transpose) → clamped motor commands.
//!
//! Driven entirely by a [`DeviceProfile`]: [`JointMap`] holds the motor side (encoder
//! resolution, gear ratios, torque constants, current limit), [`SerialArm`] and
//! [`crate::delta::Delta`] the geometry. All maths is `f64`, fixed-size and allocation-free, so
//! an [`ArmModel`] can run on the haptic thread; the delta's forward solve is a bounded Newton
//! iteration warm-started from the previous position.

use glam::{DMat3, DVec3};

use crate::delta::Delta;
pub use crate::kinematics_error::KinematicsError;
use crate::profile::{DeviceProfile, Geometry, Motors};

/// Motor side of an arm: counts ↔ joint angles, joint torques → firmware commands.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointMap {
    /// The profile's motor table.
    pub motors: Motors,
}

impl JointMap {
    /// Joint angles in radians for (unwrapped) encoder counts.
    #[must_use]
    pub fn joint_angles(&self, counts: [i64; 3]) -> DVec3 {
        let m = &self.motors;
        DVec3::from_array(std::array::from_fn(|i| {
            m.joint_offset_rad[i]
                + m.joint_sign[i] * counts[i] as f64 * std::f64::consts::TAU
                    / (m.counts_per_rev[i] * m.gear_ratio[i])
        }))
    }

    /// Encoder counts (not rounded) that give these joint angles; the inverse of
    /// [`JointMap::joint_angles`], used by simulated firmware.
    #[must_use]
    pub fn counts(&self, angles_rad: DVec3) -> [f64; 3] {
        let m = &self.motors;
        let a = angles_rad.to_array();
        std::array::from_fn(|i| {
            (a[i] - m.joint_offset_rad[i]) * m.joint_sign[i] * m.counts_per_rev[i] * m.gear_ratio[i]
                / std::f64::consts::TAU
        })
    }

    /// Motor currents in mA for joint torques in N·m, before any clamping.
    #[must_use]
    pub fn currents_ma(&self, joint_torque_nm: DVec3) -> DVec3 {
        let m = &self.motors;
        let t = joint_torque_nm.to_array();
        // Joint angle = motor angle / ratio, so motor torque = joint torque / ratio.
        DVec3::from_array(std::array::from_fn(|i| {
            m.joint_sign[i] * t[i] / m.gear_ratio[i] / m.torque_constant_nm_per_a[i] * 1000.0
        }))
    }

    /// Firmware commands for joint torques: currents scaled down *together* when any exceeds
    /// `max_current_ma` (so the force keeps its direction), then converted to command units.
    /// Non-finite torques give zero commands.
    #[must_use]
    pub fn commands(&self, joint_torque_nm: DVec3) -> [i16; 3] {
        let m = &self.motors;
        let mut ma = self.currents_ma(joint_torque_nm);
        if !ma.is_finite() {
            return [0; 3];
        }
        let peak = ma.abs().max_element();
        if peak > m.max_current_ma {
            ma *= m.max_current_ma / peak;
        }
        let ma = ma.to_array();
        let limit = m.max_current_ma * m.command_units_per_ma;
        std::array::from_fn(|i| {
            (m.command_sign[i] * ma[i] * m.command_units_per_ma)
                .round()
                .clamp(-limit, limit) as i16
        })
    }

    /// Joint torques in N·m that firmware commands produce (the inverse of
    /// [`JointMap::commands`] below the limit); used by simulated firmware and tests.
    #[must_use]
    pub fn torques_from_commands(&self, cmd: [i16; 3]) -> DVec3 {
        let m = &self.motors;
        DVec3::from_array(std::array::from_fn(|i| {
            let ma = f64::from(cmd[i]) * m.command_sign[i] / m.command_units_per_ma;
            m.joint_sign[i] * ma / 1000.0 * m.torque_constant_nm_per_a[i] * m.gear_ratio[i]
        }))
    }
}

/// Extends 16-bit encoder counts that wrap around into 64-bit totals.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct EncoderUnwrap {
    last: [i16; 3],
    total: [i64; 3],
    primed: bool,
}

impl EncoderUnwrap {
    /// Feeds the latest raw counts; returns the unwrapped totals. Assumes fewer than 32768 counts
    /// of motion between two reads (at 1 kHz that is over 100 motor turns a second).
    pub fn update(&mut self, raw: [i16; 3]) -> [i64; 3] {
        if !self.primed {
            self.total = raw.map(i64::from);
            self.primed = true;
        } else {
            for ((total, now), before) in self.total.iter_mut().zip(raw).zip(self.last) {
                *total += i64::from(now.wrapping_sub(before));
            }
        }
        self.last = raw;
        self.total
    }

    /// Forgets history (after a reconnect the firmware may have restarted its counters).
    pub fn reset(&mut self) {
        *self = Self::default();
    }
}

/// WoodenHaptics-style arm: base yaw `θa`, upper arm `θb` from vertical, forearm `θc` held by a
/// parallel linkage. `s = Lb sin θb + Lc sin θc`;
/// `p = (s cos θa, s sin θa, Ln + Lb cos θb − Lc cos θc) − origin`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SerialArm {
    /// Shoulder height `Ln`, m.
    pub base_height_m: f64,
    /// Upper arm `Lb`, m.
    pub upper_arm_m: f64,
    /// Forearm `Lc`, m.
    pub forearm_m: f64,
    /// Workspace origin in base coordinates, m.
    pub origin_m: DVec3,
}

impl SerialArm {
    /// Tool position for joint angles.
    #[must_use]
    pub fn forward(&self, q: DVec3) -> DVec3 {
        let (lb, lc) = (self.upper_arm_m, self.forearm_m);
        let s = lb * q.y.sin() + lc * q.z.sin();
        DVec3::new(
            s * q.x.cos(),
            s * q.x.sin(),
            self.base_height_m + lb * q.y.cos() - lc * q.z.cos(),
        ) - self.origin_m
    }

    /// Joint angles for a tool position, elbow above the shoulder–tool line.
    ///
    /// # Errors
    /// [`KinematicsError::Unreachable`] outside the annulus the two links can reach, or on the
    /// base axis where the yaw is undefined.
    pub fn inverse(&self, p: DVec3) -> Result<DVec3, KinematicsError> {
        let unreachable = KinematicsError::Unreachable {
            position_m: p.to_array(),
        };
        let q = p + self.origin_m;
        let s = q.x.hypot(q.y);
        if !q.is_finite() || s < 1e-9 {
            return Err(unreachable);
        }
        let yaw = q.y.atan2(q.x);
        let h = q.z - self.base_height_m;
        let (lb, lc) = (self.upper_arm_m, self.forearm_m);
        let d = s.hypot(h);
        let cos_beta = (lb * lb + d * d - lc * lc) / (2.0 * lb * d);
        if !(-1.0..=1.0).contains(&cos_beta) {
            return Err(unreachable);
        }
        // Planar two-link problem: upper arm direction α_A = π/2 − θb, forearm α_C = θc − π/2.
        let alpha_a = h.atan2(s) + cos_beta.acos();
        let elbow = DVec3::new(lb * alpha_a.cos(), lb * alpha_a.sin(), 0.0);
        let alpha_c = (h - elbow.y).atan2(s - elbow.x);
        Ok(DVec3::new(
            yaw,
            std::f64::consts::FRAC_PI_2 - alpha_a,
            alpha_c + std::f64::consts::FRAC_PI_2,
        ))
    }

    /// `∂p/∂θ` at joint angles `q` (columns are the joints).
    #[must_use]
    pub fn jacobian(&self, q: DVec3) -> DMat3 {
        let (lb, lc) = (self.upper_arm_m, self.forearm_m);
        let s = lb * q.y.sin() + lc * q.z.sin();
        let (sa, ca) = q.x.sin_cos();
        DMat3::from_cols(
            DVec3::new(-sa * s, ca * s, 0.0),
            DVec3::new(ca * lb * q.y.cos(), sa * lb * q.y.cos(), -lb * q.y.sin()),
            DVec3::new(ca * lc * q.z.cos(), sa * lc * q.z.cos(), lc * q.z.sin()),
        )
    }
}

/// The geometry part of an arm.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Linkage {
    /// Serial arm with a parallel-linkage forearm.
    Serial(SerialArm),
    /// Three-legged delta.
    Delta(Delta),
}

impl Linkage {
    /// Tool position for joint angles; `guess` warm-starts iterative solves.
    ///
    /// # Errors
    /// [`KinematicsError`] when the delta's solve does not converge.
    pub fn forward(&self, q: DVec3, guess: DVec3) -> Result<DVec3, KinematicsError> {
        match self {
            Self::Serial(a) => Ok(a.forward(q)),
            Self::Delta(d) => d.forward(q, guess),
        }
    }

    /// Joint angles for a tool position.
    ///
    /// # Errors
    /// [`KinematicsError::Unreachable`] outside the workspace.
    pub fn inverse(&self, p: DVec3) -> Result<DVec3, KinematicsError> {
        match self {
            Self::Serial(a) => a.inverse(p),
            Self::Delta(d) => d.inverse(p),
        }
    }

    /// `∂p/∂θ` at joint angles `q` and matching position `p`.
    ///
    /// # Errors
    /// [`KinematicsError::Unreachable`] when the delta's leg Jacobian is singular there.
    pub fn jacobian(&self, q: DVec3, p: DVec3) -> Result<DMat3, KinematicsError> {
        match self {
            Self::Serial(a) => Ok(a.jacobian(q)),
            Self::Delta(d) => d.jacobian(q, p),
        }
    }
}

/// An arm described by a profile, with the state the haptic loop needs: unwrapped encoders and
/// the last position (warm start, and the pose at which forces are mapped to torques).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ArmModel {
    /// Motor side.
    pub joints: JointMap,
    /// Geometry.
    pub linkage: Linkage,
    unwrap: EncoderUnwrap,
    angles_rad: DVec3,
    position_m: DVec3,
}

impl ArmModel {
    /// Builds the model for a profile.
    ///
    /// # Errors
    /// [`KinematicsError::NotAnArm`] for Cartesian profiles.
    pub fn from_profile(p: &DeviceProfile) -> Result<Self, KinematicsError> {
        let motors = p.motors.ok_or(KinematicsError::NotAnArm)?;
        let linkage = match p.geometry {
            Geometry::SerialArm {
                base_height_m,
                upper_arm_m,
                forearm_m,
                workspace_origin_m,
            } => Linkage::Serial(SerialArm {
                base_height_m,
                upper_arm_m,
                forearm_m,
                origin_m: DVec3::from_array(workspace_origin_m),
            }),
            Geometry::Delta { .. } => {
                Linkage::Delta(Delta::from_geometry(&p.geometry).ok_or(KinematicsError::NotAnArm)?)
            }
            Geometry::Cartesian => return Err(KinematicsError::NotAnArm),
        };
        let position_m = match linkage {
            Linkage::Serial(_) => DVec3::ZERO,
            Linkage::Delta(d) => d.home_guess_m,
        };
        Ok(Self {
            joints: JointMap { motors },
            linkage,
            unwrap: EncoderUnwrap::default(),
            angles_rad: DVec3::ZERO,
            position_m,
        })
    }

    /// Forgets encoder history (after a reconnect).
    pub fn reset(&mut self) {
        self.unwrap.reset();
    }

    /// Feeds raw encoder counts; returns the tool position in metres. On a failed solve the
    /// previous position is kept and the error returned.
    ///
    /// # Errors
    /// [`KinematicsError`] from the forward solve.
    pub fn update(&mut self, raw_counts: [i16; 3]) -> Result<DVec3, KinematicsError> {
        let counts = self.unwrap.update(raw_counts);
        let q = self.joints.joint_angles(counts);
        let p = self.linkage.forward(q, self.position_m)?;
        self.angles_rad = q;
        self.position_m = p;
        Ok(p)
    }

    /// Last joint angles, rad.
    #[must_use]
    pub fn angles_rad(&self) -> DVec3 {
        self.angles_rad
    }

    /// Last tool position, m.
    #[must_use]
    pub fn position_m(&self) -> DVec3 {
        self.position_m
    }

    /// Joint torques for a tool force at the current pose: `τ = Jᵀ F`.
    ///
    /// # Errors
    /// [`KinematicsError`] when the Jacobian is unavailable at this pose.
    pub fn joint_torques(&self, force_n: DVec3) -> Result<DVec3, KinematicsError> {
        let j = self.linkage.jacobian(self.angles_rad, self.position_m)?;
        Ok(j.transpose() * force_n)
    }

    /// Clamped motor commands for a tool force at the current pose; zero when the pose has no
    /// usable Jacobian or the force is not finite.
    #[must_use]
    pub fn commands_for_force(&self, force_n: DVec3) -> [i16; 3] {
        match self.joint_torques(force_n) {
            Ok(t) => self.joints.commands(t),
            Err(_) => [0; 3],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn woody() -> DeviceProfile {
        DeviceProfile::built_in("woodenhaptics").unwrap()
    }

    fn serial_arm(p: &DeviceProfile) -> SerialArm {
        match ArmModel::from_profile(p).unwrap().linkage {
            Linkage::Serial(a) => a,
            Linkage::Delta(_) => unreachable!(),
        }
    }

    #[test]
    fn serial_arm_forward_then_inverse_recovers_angles() {
        for name in ["woodenhaptics", "polhem"] {
            let arm = serial_arm(&DeviceProfile::built_in(name).unwrap());
            for &q in &[
                DVec3::new(0.0, 0.3, 0.9),
                DVec3::new(-0.5, 0.1, 1.2),
                DVec3::new(0.7, 0.45, 0.6),
            ] {
                let p = arm.forward(q);
                let back = arm.inverse(p).unwrap();
                assert!(
                    (back - q).abs().max_element() < 1e-9,
                    "{name}: {q} -> {p} -> {back}"
                );
            }
        }
    }

    #[test]
    fn serial_arm_inverse_then_forward_recovers_positions() {
        let arm = serial_arm(&woody());
        for &p in &[
            DVec3::ZERO,
            DVec3::new(0.05, -0.04, 0.03),
            DVec3::new(-0.06, 0.05, -0.05),
        ] {
            let q = arm.inverse(p).unwrap();
            assert!((arm.forward(q) - p).length() < 1e-12, "{p}");
        }
        assert!(matches!(
            arm.inverse(DVec3::new(2.0, 0.0, 0.0)),
            Err(KinematicsError::Unreachable { .. })
        ));
        assert!(arm.inverse(DVec3::NAN).is_err());
    }

    #[test]
    fn serial_arm_jacobian_matches_finite_differences() {
        let arm = serial_arm(&woody());
        let q = DVec3::new(0.2, 0.35, 0.8);
        let j = arm.jacobian(q);
        let h = 1e-6;
        for k in 0..3 {
            let mut dq = DVec3::ZERO;
            dq[k] = h;
            let fd = (arm.forward(q + dq) - arm.forward(q - dq)) / (2.0 * h);
            assert!(
                (fd - j.col(k)).abs().max_element() < 1e-8,
                "column {k}: {fd} vs {}",
                j.col(k)
            );
        }
    }

    #[test]
    fn counts_map_to_angles_and_back() {
        let jm = JointMap {
            motors: woody().motors.unwrap(),
        };
        let counts = [1234, -5678, 32000];
        let q = jm.joint_angles(counts);
        let back = jm.counts(q);
        for i in 0..3 {
            assert!((back[i] - counts[i] as f64).abs() < 1e-6);
        }
        // One joint turn is counts_per_rev * gear_ratio counts.
        let turn = jm.joint_angles([32000, 0, 0]).x - jm.joint_angles([0, 0, 0]).x;
        assert!((turn - std::f64::consts::TAU).abs() < 1e-12);
    }

    #[test]
    fn commands_clamp_together_and_keep_direction() {
        let jm = JointMap {
            motors: woody().motors.unwrap(),
        };
        let small = jm.commands(DVec3::new(0.1, -0.05, 0.0));
        let back = jm.torques_from_commands(small);
        assert!((back - DVec3::new(0.1, -0.05, 0.0)).abs().max_element() < 2e-3);
        let big = jm.commands(DVec3::new(100.0, -50.0, 0.0));
        assert_eq!(
            big[0].unsigned_abs(),
            2500,
            "peak clamped to max_current_ma"
        );
        let ma = jm.currents_ma(DVec3::new(100.0, -50.0, 0.0));
        let ratio = f64::from(big[0]) / f64::from(big[1]);
        assert!(
            (ratio - ma.x / ma.y).abs() < 1e-2,
            "direction kept: {ratio} vs {}",
            ma.x / ma.y
        );
        assert_eq!(jm.commands(DVec3::new(f64::NAN, 0.0, 0.0)), [0; 3]);
    }

    #[test]
    fn encoder_unwrap_crosses_the_i16_boundary() {
        let mut u = EncoderUnwrap::default();
        assert_eq!(u.update([32760, -32760, 0]), [32760, -32760, 0]);
        assert_eq!(u.update([-32760, 32760, 5]), [32776, -32776, 5]);
    }

    #[test]
    fn model_maps_force_through_jacobian_transpose() {
        let p = woody();
        let mut m = ArmModel::from_profile(&p).unwrap();
        let arm = serial_arm(&p);
        let q = arm.inverse(DVec3::new(0.01, 0.02, -0.01)).unwrap();
        let counts = m.joints.counts(q).map(|c| c.round() as i16);
        let pos = m.update(counts).unwrap();
        assert!((pos - DVec3::new(0.01, 0.02, -0.01)).length() < 1e-3);
        // Virtual work: τ·dq = F·dp for a small joint motion.
        let f = DVec3::new(1.0, -2.0, 0.5);
        let tau = m.joint_torques(f).unwrap();
        let dq = DVec3::new(1e-6, -2e-6, 3e-6);
        let dp = arm.forward(m.angles_rad() + dq) - arm.forward(m.angles_rad());
        assert!((tau.dot(dq) - f.dot(dp)).abs() < 1e-10);
    }
}
