//! A 6-DoF tool pose driven by a rate controller (a SpaceMouse): raw axes → dead zone →
//! sensitivity → velocity → integrated position and orientation, clamped to a workspace.
//!
//! Pure and allocation-free; the SpaceMouse driver feeds it raw reports and the time between
//! reads. Axis conventions are data ([`AxisMap`]), so a left-handed user or a mouse lying on its
//! side is a setting, not code.

use glam::{Quat, Vec3};

/// Maps device axes to the dynaclay device frame (+x right, +y up, +z toward the user).
/// Entry `i` says which raw axis (0..3) feeds output axis `i`, and its sign.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AxisMap {
    /// Translation: (raw index, sign) per output axis.
    pub translation: [(usize, f32); 3],
    /// Rotation: (raw index, sign) per output axis.
    pub rotation: [(usize, f32); 3],
}

impl AxisMap {
    /// 3Dconnexion's raw axes (x right, y toward the user, z down) to the device frame:
    /// `(x, −z, y)` for both translation and rotation.
    pub const SPACEMOUSE: Self = Self {
        translation: [(0, 1.0), (2, -1.0), (1, 1.0)],
        rotation: [(0, 1.0), (2, -1.0), (1, 1.0)],
    };

    fn apply(map: [(usize, f32); 3], raw: [f32; 3]) -> Vec3 {
        Vec3::new(
            map[0].1 * raw[map[0].0 % 3],
            map[1].1 * raw[map[1].0 % 3],
            map[2].1 * raw[map[2].0 % 3],
        )
    }
}

/// Settings of the pose integrator.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoseInputConfig {
    /// Raw value at full deflection (about 350 on 3Dconnexion devices).
    pub full_scale: f32,
    /// Fraction of full scale ignored around rest, 0..1.
    pub dead_zone: f32,
    /// Tool speed at full deflection, m/s.
    pub max_speed_m_per_s: f32,
    /// Tool turn rate at full deflection, rad/s.
    pub max_turn_rad_per_s: f32,
    /// Axis conventions.
    pub axes: AxisMap,
    /// Workspace box the position is clamped to, m.
    pub workspace_min_m: Vec3,
    /// Workspace box the position is clamped to, m.
    pub workspace_max_m: Vec3,
}

impl Default for PoseInputConfig {
    fn default() -> Self {
        Self {
            full_scale: 350.0,
            dead_zone: 0.05,
            max_speed_m_per_s: 0.15,
            max_turn_rad_per_s: 1.5,
            axes: AxisMap::SPACEMOUSE,
            workspace_min_m: Vec3::splat(-0.1),
            workspace_max_m: Vec3::splat(0.1),
        }
    }
}

/// Integrated tool pose.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoseIntegrator {
    /// Settings.
    pub config: PoseInputConfig,
    translation_raw: [f32; 3],
    rotation_raw: [f32; 3],
    /// Current position, m.
    pub position_m: Vec3,
    /// Current orientation.
    pub orientation: Quat,
    /// Current linear velocity, m/s.
    pub velocity_m_per_s: Vec3,
}

/// One axis after dead zone and scaling, in −1..=1; continuous at the dead-zone edge.
#[must_use]
pub fn shape_axis(raw: f32, full_scale: f32, dead_zone: f32) -> f32 {
    if !raw.is_finite() || full_scale <= 0.0 {
        return 0.0;
    }
    let x = (raw / full_scale).clamp(-1.0, 1.0);
    let dz = dead_zone.clamp(0.0, 0.99);
    if x.abs() <= dz {
        0.0
    } else {
        x.signum() * (x.abs() - dz) / (1.0 - dz)
    }
}

impl PoseIntegrator {
    /// At the workspace centre, identity orientation, at rest.
    #[must_use]
    pub fn new(config: PoseInputConfig) -> Self {
        Self {
            config,
            translation_raw: [0.0; 3],
            rotation_raw: [0.0; 3],
            position_m: (config.workspace_min_m + config.workspace_max_m) * 0.5,
            orientation: Quat::IDENTITY,
            velocity_m_per_s: Vec3::ZERO,
        }
    }

    /// Latest raw translation axes (device order).
    pub fn set_translation(&mut self, raw: [i16; 3]) {
        self.translation_raw = raw.map(f32::from);
    }

    /// Latest raw rotation axes (device order).
    pub fn set_rotation(&mut self, raw: [i16; 3]) {
        self.rotation_raw = raw.map(f32::from);
    }

    /// Advances the pose by `dt_s` seconds at the current deflection.
    pub fn step(&mut self, dt_s: f32) {
        let c = &self.config;
        let dt = if dt_s.is_finite() {
            dt_s.clamp(0.0, 0.1)
        } else {
            0.0
        };
        let shape = |v: [f32; 3]| v.map(|x| shape_axis(x, c.full_scale, c.dead_zone));
        let v =
            AxisMap::apply(c.axes.translation, shape(self.translation_raw)) * c.max_speed_m_per_s;
        let w = AxisMap::apply(c.axes.rotation, shape(self.rotation_raw)) * c.max_turn_rad_per_s;
        let before = self.position_m;
        self.position_m = (self.position_m + v * dt).clamp(c.workspace_min_m, c.workspace_max_m);
        self.velocity_m_per_s = if dt > 0.0 {
            (self.position_m - before) / dt
        } else {
            Vec3::ZERO
        };
        let angle = w.length() * dt;
        if angle > 0.0 {
            // Body-fixed rates: the turn is applied in the tool's own frame.
            self.orientation =
                (self.orientation * Quat::from_axis_angle(w.normalize(), angle)).normalize();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dead_zone_and_scaling() {
        assert_eq!(shape_axis(10.0, 350.0, 0.05), 0.0, "inside the dead zone");
        assert!((shape_axis(350.0, 350.0, 0.05) - 1.0).abs() < 1e-6);
        assert!(
            (shape_axis(-700.0, 350.0, 0.05) + 1.0).abs() < 1e-6,
            "clamped"
        );
        let edge = 0.05 * 350.0;
        assert!(
            shape_axis(edge + 0.01, 350.0, 0.05).abs() < 1e-3,
            "continuous at the edge"
        );
        assert_eq!(shape_axis(f32::NAN, 350.0, 0.05), 0.0);
    }

    #[test]
    fn pushing_right_moves_right_and_pushing_down_moves_down() {
        let mut p = PoseIntegrator::new(PoseInputConfig::default());
        p.set_translation([350, 0, 0]);
        p.step(0.1);
        assert!((p.position_m.x - 0.015).abs() < 1e-6, "{}", p.position_m);
        p.set_translation([0, 0, 350]); // raw +z is down
        p.step(0.1);
        assert!(p.position_m.y < -0.01, "{}", p.position_m);
        p.set_translation([0, 350, 0]); // raw +y is toward the user
        p.step(0.1);
        assert!(p.position_m.z > 0.01);
    }

    #[test]
    fn position_is_clamped_and_rotation_integrates() {
        let mut p = PoseIntegrator::new(PoseInputConfig::default());
        p.set_translation([350, 350, 350]);
        for _ in 0..100 {
            p.step(0.1);
        }
        assert_eq!(p.position_m, Vec3::new(0.1, -0.1, 0.1));
        p.set_translation([0; 3]);
        p.set_rotation([0, 0, -350]); // raw −z twist: about +y (up)
        for _ in 0..10 {
            p.step(0.1);
        }
        let (axis, angle) = p.orientation.to_axis_angle();
        assert!(
            (angle - 1.5).abs() < 1e-4 && axis.abs_diff_eq(Vec3::Y, 1e-4),
            "{axis} {angle}"
        );
    }
}
