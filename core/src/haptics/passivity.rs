//! Passivity: an energy observer on the device port and a variable damper that spends any
//! energy the rendering generated (after Hannaford & Ryu's passivity observer/controller).
//!
//! Guarantee: constant work, no allocation, no lock; device time and device positions only,
//! so a replay computes the same forces bit for bit.
//!
//! The observer sums the energy the hand has put into the device since the contact began,
//! `E = −Σ F_k · (x_{k+1} − x_k)`, with `F_k` the force actually sent over the interval (after
//! the safety filter). A device that reports its position late (a USB frame, a filter) makes
//! the reported motion lag the force that caused it, and an observer pairing them tick by tick
//! then misses the energy the delay generates. So the observer pairs each reported
//! displacement with the force sent [`MAX_SENSOR_DELAY_TICKS`] ticks before the interval: a
//! force older than the one that really acted makes a pressed spring look weaker going in and
//! stronger coming out, so the account errs on the safe side for any delay up to that bound.
//! It also never pairs a displacement with the force computed from the same noisy sample,
//! which would bias the account by `k σ²` per tick of sensor noise `σ`. A passive rendering keeps `E ≥ 0`: the clay stores (springs) or spends
//! (sculpting, damping, friction) what the hand gives it, and never returns more: `E` never
//! falls below the energy the rendering stores and will give back (`S`, a pressed spring's
//! `|F|²/2k`). Whenever `E < S`, the controller adds a damping force `−α v` with
//! `α = (S − E) / (v² Δt)`, capped at the device's stable damping, which spends the deficit
//! over the next interval. `E` is capped at
//! `reservoir_j`, so credit earned pushing into the clay cannot license a long buzz later.
//! Between contacts (no force rendered, so no damper either: free space stays free) the credit
//! is dropped but a deficit is kept and spent in the next contact, so a bouncing contact
//! cannot generate energy one bounce at a time.

use glam::Vec3;

/// The longest position-report delay the observer accounts for, ticks.
pub const MAX_SENSOR_DELAY_TICKS: usize = 1;
/// Forces remembered: the last interval's and the ones before it, up to the delay bound.
const ACCOUNTS: usize = MAX_SENSOR_DELAY_TICKS + 1;
/// Time constant of the low-pass on the damper's velocity, seconds.
const VELOCITY_FILTER_S: f32 = 0.002;

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
    /// Speeds below this are taken as sensor noise and not damped, metres per second.
    pub velocity_deadband_m_per_s: f32,
}

impl Default for PassivityConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            max_damping_n_s_per_m: 20.0,
            // Above what a press to the simulated arm's 8 N stores, in touch (8²/(2·3000) J)
            // or against the calibrated sculpting force (about 0.03 J).
            reservoir_j: 0.05,
            // A few encoder counts per millisecond of noise, filtered.
            velocity_deadband_m_per_s: 0.003,
        }
    }
}

/// The observer's state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PassivityController {
    config: PassivityConfig,
    /// The energy account, joules.
    energy_j: f32,
    /// The forces sent over the last intervals, newest first.
    sent_n: [Vec3; ACCOUNTS],
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
            sent_n: [Vec3::ZERO; ACCOUNTS],
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
        self.sent_n.rotate_right(1);
        self.sent_n[0] = if sent_n.is_finite() {
            sent_n
        } else {
            Vec3::ZERO
        };
        if let Some(last) = self.last_position_m {
            let moved = position_m - last;
            if moved.is_finite() {
                let force = self.sent_n[MAX_SENSOR_DELAY_TICKS];
                self.energy_j = (self.energy_j - force.dot(moved)).min(self.config.reservoir_j);
                if dt_s > 0.0 {
                    // A first-order low-pass on the measured velocity: a damper driven by
                    // position noise would itself put energy into the hand.
                    let blend = dt_s / (VELOCITY_FILTER_S + dt_s);
                    self.velocity_m_per_s += (moved / dt_s - self.velocity_m_per_s) * blend;
                }
            }
        }
        self.last_position_m = position_m.is_finite().then_some(position_m);
    }

    /// The damping force that spends the current deficit over an interval of `dt_s`, newtons.
    /// `stored_j` is the energy the rendering holds now and will give back (a pressed touch
    /// spring's `|F|²/2k`): the hand must have put in at least that much, so the deficit is
    /// `stored_j − E`, and a contact that leaks its credit while held (a small limit cycle) is
    /// damped before the release hands the stored energy back. Zero while there is no deficit.
    #[must_use]
    pub fn damping_n(&self, dt_s: f32, stored_j: f32) -> Vec3 {
        -self.damped_velocity_m_per_s() * self.damping_n_s_per_m(dt_s, stored_j)
    }

    /// The damping coefficient that spends the current deficit over `dt_s` at the port's
    /// velocity (see [`Self::damping_n`]), newton-seconds per metre, at most the configured
    /// bound; zero while there is no deficit or the port is still.
    #[must_use]
    pub fn damping_n_s_per_m(&self, dt_s: f32, stored_j: f32) -> f32 {
        let v2 = self.damped_velocity_m_per_s().length_squared();
        let deficit = stored_j.max(0.0) - self.energy_j();
        if !self.config.enabled || deficit.is_nan() || deficit <= 0.0 || dt_s <= 0.0 || v2 < 1e-10 {
            return 0.0;
        }
        (deficit / (v2 * dt_s)).min(self.config.max_damping_n_s_per_m)
    }

    /// The velocity a damper acts on: the observer's, less its noise floor (speed within the
    /// sensor's noise is not damped: a damper driven by noise would itself put energy into
    /// the hand), metres per second.
    #[must_use]
    pub fn damped_velocity_m_per_s(&self) -> Vec3 {
        let speed = self.velocity_m_per_s.length();
        let above = speed - self.config.velocity_deadband_m_per_s;
        if above.is_nan() || above <= 0.0 {
            return Vec3::ZERO;
        }
        self.velocity_m_per_s * (above / speed)
    }

    /// Between contacts (no force is rendered): drops any credit, so energy the hand put into
    /// one contact never licenses energy out in the next, but keeps a deficit, so energy a
    /// contact generated (a bounce that left the surface) is spent by the damper in the next
    /// contact instead of being forgiven.
    pub fn between_contacts(&mut self) {
        self.energy_j = self.energy_j.min(0.0);
    }

    /// A device fault in the middle of a contact (a failed read or write; the safety filter
    /// sent zero): forgets the position, the velocity and the forces sent, so the next sample
    /// starts a new track, but keeps the energy account, credit and deficit alike.
    ///
    /// The account is what the hand has put into this contact, and a fault does not change
    /// it: the zero force the fault sent does no work, and the intervals around the lost
    /// sample go unobserved (a reset loses them too). Emptying the account instead would hand
    /// the rest of the contact a zero balance that the sampling's own small losses and gains
    /// (a force held over each interval, position counts that step back and forth) tip below
    /// zero, and the damper would then act where the same contact without the fault felt
    /// none; it would also forgive a deficit, which a fault must never do. Whether the fault
    /// ended the contact is the caller's to say: it then calls [`Self::between_contacts`].
    pub fn lose_track(&mut self) {
        self.sent_n = [Vec3::ZERO; ACCOUNTS];
        self.last_position_m = None;
        self.velocity_m_per_s = Vec3::ZERO;
    }

    /// Forgets everything, the account included (a new device: another hand, another port).
    pub fn reset(&mut self) {
        self.energy_j = 0.0;
        self.sent_n = [Vec3::ZERO; ACCOUNTS];
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
        // on the way out is the one of the step before, deeper. The observer, which pairs each
        // move with the force of the tick before that (a one-tick sensor delay is covered),
        // sees a small deficit and the damper opposes the motion (upward here).
        let stored = 0.5 * k * 0.01 * 0.01;
        assert!(
            pc.energy_j() < 0.0 && pc.energy_j() > -0.1 * stored,
            "{}",
            pc.energy_j()
        );
        assert!(pc.damping_n(dt, 0.0).y < 0.0);

        // A force that pushes along the motion generates energy: the damper opposes it.
        pc.reset();
        let up = Vec3::new(0.0, 1.0, 0.0);
        for i in 0..20 {
            pc.observe(up * (0.01 * i as f32), up, dt);
        }
        assert!(pc.energy_j() < 0.0);
        let d = pc.damping_n(dt, 0.0);
        assert!(d.y < 0.0, "opposes the motion: {d}");
        // Slow motion within the sensor's noise floor is not damped at all.
        pc.reset();
        for i in 0..20 {
            pc.observe(up * (1e-6 * i as f32), up, dt);
        }
        assert!(pc.energy_j() < 0.0);
        assert_eq!(pc.damping_n(dt, 0.0), Vec3::ZERO);
        // A stored spring that the account does not cover is a deficit too.
        pc.reset();
        for i in 0..20 {
            pc.observe(up * (0.01 * i as f32), Vec3::ZERO, dt);
        }
        assert_eq!(pc.damping_n(dt, 0.0), Vec3::ZERO);
        assert!(pc.damping_n(dt, 1e-3).y < 0.0);
    }

    #[test]
    fn a_lost_track_keeps_the_account_and_pairs_no_move_across_the_gap() {
        let dt = 1e-3;
        let down = Vec3::new(0.0, -1e-4, 0.0);
        let up_n = Vec3::new(0.0, 2.0, 0.0);
        // The hand presses down against 2 N for 20 samples: 19 moves of 0.1 mm, each paired
        // with the 2 N sent before it.
        let mut pc = PassivityController::new(PassivityConfig::default());
        for i in 0..20 {
            pc.observe(down * i as f32, up_n, dt);
        }
        let credit = pc.energy_j();
        assert!((credit - 2.0 * 19.0 * 1e-4).abs() < 1e-6, "{credit}");
        pc.lose_track();
        assert_eq!(pc.energy_j(), credit);
        assert_eq!(pc.damped_velocity_m_per_s(), Vec3::ZERO);
        // The first sample after the gap is 5 mm away: not paired with any force.
        pc.observe(down * 70.0, Vec3::ZERO, dt);
        assert_eq!(pc.energy_j(), credit);
        // The next moves pair with the forces sent since the gap only (zero, then 2 N).
        pc.observe(down * 71.0, up_n, dt);
        assert_eq!(pc.energy_j(), credit);
        pc.observe(down * 72.0, up_n, dt);
        assert!((pc.energy_j() - credit - 2.0 * 1e-4).abs() < 1e-7);

        // A deficit is kept too: a fault forgives nothing.
        let up = Vec3::new(0.0, 0.01, 0.0);
        let mut pc = PassivityController::new(PassivityConfig::default());
        for i in 0..20 {
            pc.observe(up * i as f32, up_n, dt);
        }
        let deficit = pc.energy_j();
        assert!(deficit < 0.0);
        pc.lose_track();
        assert_eq!(pc.energy_j(), deficit);
    }
}
