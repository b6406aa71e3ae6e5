//! Passivity: an energy observer on the device port and a variable damper that spends any
//! energy the rendering generated (after Hannaford & Ryu's passivity observer/controller).
//!
//! Guarantee: constant work, no allocation, no lock; device time and device positions only,
//! so a replay computes the same forces bit for bit.
//!
//! The observer sums the energy the hand has put into the device since the contact began,
//! `E = −Σ F_k · (x_{k+1} − x_k)`, with `F_k` the force actually sent over the interval (after
//! the safety filter). A passive rendering keeps `E ≥ 0`: the clay stores (springs) or spends
//! (sculpting, damping, friction) what the hand gives it, and never returns more. Whenever
//! `E < 0`, the controller adds a damping force `−α v` with `α = −E / (v² Δt)`, capped at the
//! device's stable damping, which spends the deficit over the next interval. `E` is capped at
//! `reservoir_j`, so credit earned pushing into the clay cannot license a long buzz later,
//! and it restarts at zero whenever no force is rendered (between contacts).

use glam::Vec3;

/// Settings of the passivity controller.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PassivityConfig {
    /// Whether the controller acts (the observer always runs).
    pub enabled: bool,
    /// Largest damping the controller adds, newton-seconds per metre (the device's stable
    /// damping).
    pub max_damping_n_s_per_m: f32,
    /// Most energy credit kept, joules.
    pub reservoir_j: f32,
}

impl Default for PassivityConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            max_damping_n_s_per_m: 20.0,
            // Above what a press to the simulated arm's 8 N stores, in touch (8²/(2·3000) J)
            // or against the calibrated sculpting force (about 0.03 J).
            reservoir_j: 0.05,
        }
    }
}

/// The observer's state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PassivityController {
    config: PassivityConfig,
    energy_j: f32,
    last_position_m: Option<Vec3>,
    velocity_m_per_s: Vec3,
}

impl PassivityController {
    /// A controller with no energy observed.
    #[must_use]
    pub fn new(config: PassivityConfig) -> Self {
        Self {
            config,
            energy_j: 0.0,
            last_position_m: None,
            velocity_m_per_s: Vec3::ZERO,
        }
    }

    /// Energy the hand has put in since the contact began, joules (negative: the rendering
    /// generated energy that the damper has not spent yet).
    #[must_use]
    pub fn energy_j(&self) -> f32 {
        self.energy_j
    }

    /// Notes the device at `position_m`, `dt_s` after the previous tick, while `sent_n` was
    /// the force sent over that interval.
    pub fn observe(&mut self, position_m: Vec3, sent_n: Vec3, dt_s: f32) {
        if let Some(last) = self.last_position_m {
            let moved = position_m - last;
            if moved.is_finite() && sent_n.is_finite() {
                self.energy_j = (self.energy_j - sent_n.dot(moved)).min(self.config.reservoir_j);
                if dt_s > 0.0 {
                    self.velocity_m_per_s = moved / dt_s;
                }
            }
        }
        self.last_position_m = position_m.is_finite().then_some(position_m);
    }

    /// The damping force that spends the current deficit over an interval of `dt_s`, newtons
    /// (zero while the observed energy is not negative).
    #[must_use]
    pub fn damping_n(&self, dt_s: f32) -> Vec3 {
        let v = self.velocity_m_per_s;
        let v2 = v.length_squared();
        if !self.config.enabled || self.energy_j >= 0.0 || dt_s <= 0.0 || v2 < 1e-10 {
            return Vec3::ZERO;
        }
        let alpha = (-self.energy_j / (v2 * dt_s)).min(self.config.max_damping_n_s_per_m);
        -v * alpha
    }

    /// Starts a new account (no force is rendered: between contacts).
    pub fn restart(&mut self) {
        self.energy_j = 0.0;
    }

    /// Forgets the device position too (a new device, or a fault).
    pub fn reset(&mut self) {
        self.energy_j = 0.0;
        self.last_position_m = None;
        self.velocity_m_per_s = Vec3::ZERO;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_spring_pressed_and_released_balances_and_a_generating_one_is_damped() {
        // Press 10 mm into a 400 N/m spring at 0.1 m/s and come back out (20 mJ stored).
        let mut pc = PassivityController::new(PassivityConfig::default());
        let k = 400.0;
        let dt = 1e-3;
        let mut x = 0.0_f32;
        let mut sent = Vec3::ZERO;
        for i in 0..=200 {
            x = if i < 100 {
                -1e-4 * i as f32
            } else {
                -1e-4 * (200 - i) as f32
            };
            pc.observe(Vec3::new(0.0, x, 0.0), sent, dt);
            sent = Vec3::new(0.0, -k * x, 0.0);
        }
        assert!(x.abs() < 1e-9);
        // Held over each interval, a sampled spring is slightly active (Colgate): the force
        // on the way out is the one of the step before, deeper. The observer sees the small
        // deficit and the damper opposes the motion (upward here).
        let stored = 0.5 * k * 0.01 * 0.01;
        assert!(
            pc.energy_j() < 0.0 && pc.energy_j() > -0.05 * stored,
            "{}",
            pc.energy_j()
        );
        assert!(pc.damping_n(dt).y < 0.0);

        // A force that pushes along the motion generates energy: the damper opposes it.
        pc.restart();
        pc.observe(Vec3::new(0.0, 0.0, 0.0), Vec3::ZERO, dt);
        pc.observe(Vec3::new(0.0, 1e-4, 0.0), Vec3::new(0.0, 1.0, 0.0), dt);
        assert!(pc.energy_j() < 0.0);
        let d = pc.damping_n(dt);
        assert!(d.y < 0.0, "opposes the motion: {d}");
        // Spending exactly the deficit over the next interval at the same speed.
        let spent = -d.dot(Vec3::new(0.0, 1e-4, 0.0));
        assert!((spent + pc.energy_j()).abs() < 1e-9, "{spent}");
    }
}
