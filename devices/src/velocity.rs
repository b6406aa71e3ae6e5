//! Velocity from successive positions: a finite difference through a first-order low-pass.
//!
//! Encoders give position only; the force renderer wants velocity for damping. The filter's
//! cut-off trades noise against lag; 50 Hz (the default) is the usual choice for 1 kHz arms.
//! Plain data, no allocation.

use glam::Vec3;

/// Low-passed finite-difference velocity estimator.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VelocityEstimator {
    /// Cut-off frequency of the low-pass, hertz.
    pub cutoff_hz: f32,
    last: Option<(Vec3, u64)>,
    velocity_m_per_s: Vec3,
}

impl Default for VelocityEstimator {
    fn default() -> Self {
        Self::new(50.0)
    }
}

impl VelocityEstimator {
    /// An estimator with the given cut-off.
    #[must_use]
    pub fn new(cutoff_hz: f32) -> Self {
        Self {
            cutoff_hz,
            last: None,
            velocity_m_per_s: Vec3::ZERO,
        }
    }

    /// Forgets history.
    pub fn reset(&mut self) {
        self.last = None;
        self.velocity_m_per_s = Vec3::ZERO;
    }

    /// Feeds a position at `t_us`; returns the filtered velocity. Samples at the same or an
    /// earlier time leave the estimate unchanged.
    pub fn update(&mut self, position_m: Vec3, t_us: u64) -> Vec3 {
        if let Some((p0, t0)) = self.last {
            if t_us > t0 {
                let dt = (t_us - t0) as f32 * 1e-6;
                let raw = (position_m - p0) / dt;
                let rc = 1.0 / (std::f32::consts::TAU * self.cutoff_hz);
                let alpha = dt / (rc + dt);
                self.velocity_m_per_s += (raw - self.velocity_m_per_s) * alpha;
                if !self.velocity_m_per_s.is_finite() {
                    self.velocity_m_per_s = Vec3::ZERO;
                }
            }
        }
        if self.last.is_none_or(|(_, t0)| t_us > t0) {
            self.last = Some((position_m, t_us));
        }
        self.velocity_m_per_s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn converges_to_a_constant_velocity() {
        let mut v = VelocityEstimator::default();
        let mut out = Vec3::ZERO;
        for k in 0..500u64 {
            out = v.update(Vec3::new(0.1 * k as f32 * 1e-3, 0.0, 0.0), k * 1000);
        }
        assert!((out.x - 0.1).abs() < 1e-3, "{out}");
        assert_eq!(
            v.update(Vec3::ONE, 0),
            out,
            "a sample from the past is ignored"
        );
    }
}
