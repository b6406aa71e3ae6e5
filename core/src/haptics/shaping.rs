//! Force shaping: the one stage every force change passes before the safety filter.
//!
//! Guarantee: constant work, no allocation, no lock. Runs on device time, so a replay shapes
//! bit for bit.
//!
//! Two things happen here:
//! - **Blending.** Each source of force (touch, sculpting) has a weight that moves toward 1
//!   while the source is active and toward 0 while it is not, at `1 / blend_s` per second. A
//!   stroke that starts or ends, a tool switch, or a tip entering a stroke already inside the
//!   clay cross-fade over `blend_s` instead of switching in one tick.
//! - **Fading out.** A source that stops (a stroke released, a tool switched) keeps the force
//!   it last gave and lets it go through [`FadeOut`]: each millisecond the force shrinks by
//!   [`FadeOut::RELATIVE_PER_MS`] of itself plus [`FadeOut::ABSOLUTE_N_PER_MS`], so no tick's
//!   step exceeds 7% of the force plus 0.02 N (about the just-noticeable difference of force)
//!   and any force up to 10 N is gone within [`FadeOut::LONGEST_S`]. A linear cross-fade of
//!   `blend_s` would step by `F / (blend_s · rate)` each tick: 0.1 N at 2 N, felt as a drop.
//! - **Rate limit.** The output moves toward the blended target by at most
//!   `max_rate_n_per_s · dt` per tick (a vector step), with `dt` the device time since the
//!   last tick, capped at `max_step_s` so a pause never credits a jump.

use glam::Vec3;

/// Settings of the shaping stage.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ShapingConfig {
    /// Largest change of the shaped force, newtons per second.
    pub max_rate_n_per_s: f32,
    /// Cross-fade time of a source switching on or off, seconds.
    pub blend_s: f32,
    /// Longest device-time step credited to the rate limit and the blend, seconds.
    pub max_step_s: f32,
}

impl ShapingConfig {
    /// Default rate limit: 0.5 N per millisecond — above what a stiff touch needs at hand
    /// speeds (3 kN/m at 0.1 m/s is 0.3 N/ms), well below the safety filter's 1 N/ms.
    pub const DEFAULT_MAX_RATE_N_PER_S: f32 = 500.0;
    /// Default cross-fade: 20 ms.
    pub const DEFAULT_BLEND_S: f32 = 0.02;
}

impl Default for ShapingConfig {
    fn default() -> Self {
        Self {
            max_rate_n_per_s: Self::DEFAULT_MAX_RATE_N_PER_S,
            blend_s: Self::DEFAULT_BLEND_S,
            max_step_s: 0.01,
        }
    }
}

/// A source's blend weight, moving linearly toward its target.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Blend {
    weight: f32,
}

impl Blend {
    /// Moves the weight toward 1 (`on`) or 0 over `blend_s`, by `dt_s`, and returns it.
    pub fn advance(&mut self, on: bool, dt_s: f32, blend_s: f32) -> f32 {
        let step = if blend_s > 0.0 { dt_s / blend_s } else { 1.0 };
        let target = if on { 1.0 } else { 0.0 };
        self.weight = if self.weight < target {
            (self.weight + step).min(target)
        } else {
            (self.weight - step).max(target)
        };
        self.weight
    }

    /// The weight now.
    #[must_use]
    pub fn weight(&self) -> f32 {
        self.weight
    }

    /// Drops to zero at once (only where the output is also zeroed: a fault).
    pub fn reset(&mut self) {
        self.weight = 0.0;
    }
}

/// A stopped source's force, let go no faster than the hand can tell (module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FadeOut {
    held_n: Vec3,
}

impl FadeOut {
    /// Share of the held force let go per millisecond.
    pub const RELATIVE_PER_MS: f32 = 0.06;
    /// Force let go per millisecond besides, newtons: the tail ends instead of decaying forever.
    pub const ABSOLUTE_N_PER_MS: f32 = 0.015;
    /// The longest fade, from 10 N: `ln(1 + 0.06 · 10 / 0.015) / 0.06` ms, about 62 ms.
    pub const LONGEST_S: f32 = 0.062;

    /// Holds `force_n` (non-finite counts as zero) to be faded from now on.
    pub fn hold(&mut self, force_n: Vec3) {
        self.held_n = if force_n.is_finite() {
            force_n
        } else {
            Vec3::ZERO
        };
    }

    /// Lets the held force go for `dt_s` seconds and returns what remains.
    pub fn advance(&mut self, dt_s: f32) -> Vec3 {
        let held = self.held_n.length();
        if held <= 0.0 {
            return Vec3::ZERO;
        }
        let ms = (dt_s * 1e3).max(0.0);
        let left = (held - (Self::RELATIVE_PER_MS * held + Self::ABSOLUTE_N_PER_MS) * ms).max(0.0);
        self.held_n *= left / held;
        self.held_n
    }

    /// Drops the held force at once (only where the output is also zeroed: a fault).
    pub fn reset(&mut self) {
        self.held_n = Vec3::ZERO;
    }
}

/// The rate limiter.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ForceShaper {
    config: ShapingConfig,
    output_n: Vec3,
    last_time_us: Option<u64>,
}

impl ForceShaper {
    /// A shaper at zero force.
    #[must_use]
    pub fn new(config: ShapingConfig) -> Self {
        Self {
            config,
            output_n: Vec3::ZERO,
            last_time_us: None,
        }
    }

    /// The settings.
    #[must_use]
    pub fn config(&self) -> &ShapingConfig {
        &self.config
    }

    /// Device time since the previous call, seconds, capped at `max_step_s` (zero for the
    /// first call, a repeated sample, or a clock that went back), and notes `time_us`.
    pub fn elapsed_s(&mut self, time_us: u64) -> f32 {
        let dt = match self.last_time_us {
            Some(t) if time_us > t => ((time_us - t) as f32 * 1e-6).min(self.config.max_step_s),
            _ => 0.0,
        };
        self.last_time_us = Some(time_us);
        dt
    }

    /// Moves the output toward `target_n` by at most `max_rate · dt_s` and returns it. A
    /// non-finite target counts as zero.
    pub fn shape(&mut self, target_n: Vec3, dt_s: f32) -> Vec3 {
        let target = if target_n.is_finite() {
            target_n
        } else {
            Vec3::ZERO
        };
        let step = target - self.output_n;
        let max = self.config.max_rate_n_per_s * dt_s;
        let len = step.length();
        self.output_n = if len <= max {
            target
        } else {
            self.output_n + step * (max / len)
        };
        self.output_n
    }

    /// The shaped force last returned, newtons.
    #[must_use]
    pub fn output_n(&self) -> Vec3 {
        self.output_n
    }

    /// Zero output at once (the safety filter already sent zero: a device fault or switch).
    pub fn reset(&mut self) {
        self.output_n = Vec3::ZERO;
        self.last_time_us = None;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_step_is_spread_at_the_stated_rate() {
        let mut s = ForceShaper::new(ShapingConfig::default());
        assert_eq!(s.elapsed_s(0), 0.0);
        let dt = s.elapsed_s(1000);
        assert!((dt - 1e-3).abs() < 1e-9);
        let target = Vec3::new(0.0, 2.0, 0.0);
        let mut ticks = 0;
        let mut last = Vec3::ZERO;
        while s.output_n() != target {
            let out = s.shape(target, dt);
            assert!(
                (out - last).length() <= 0.5 + 1e-6,
                "step {}",
                (out - last).length()
            );
            last = out;
            ticks += 1;
        }
        assert_eq!(ticks, 4, "2 N at 0.5 N/ms");
        assert_eq!(s.shape(Vec3::NAN, dt), Vec3::new(0.0, 1.5, 0.0));
    }

    #[test]
    fn a_pause_credits_at_most_the_longest_step() {
        let mut s = ForceShaper::new(ShapingConfig::default());
        s.elapsed_s(0);
        assert_eq!(s.elapsed_s(5_000_000), 0.01);
        assert_eq!(
            s.elapsed_s(5_000_000),
            0.0,
            "a repeated sample credits nothing"
        );
    }

    #[test]
    fn a_fade_out_never_steps_past_the_force_jnd_and_ends_in_time() {
        for from in [0.39f32, 2.0, 10.0] {
            for dt in [0.001f32, 0.00025] {
                let mut f = FadeOut::default();
                f.hold(Vec3::new(0.0, from, 0.0));
                let mut last = from;
                let mut t = 0.0;
                while last > 0.0 {
                    let now = f.advance(dt).y;
                    assert!(
                        last - now <= 0.07 * last + 0.02,
                        "{from} N at {dt} s: {last} → {now}"
                    );
                    assert!(now <= last && now >= 0.0);
                    last = now;
                    t += dt;
                }
                assert!(t <= FadeOut::LONGEST_S + dt, "{from} N took {t} s");
            }
        }
        let mut f = FadeOut::default();
        f.hold(Vec3::NAN);
        assert_eq!(f.advance(0.001), Vec3::ZERO);
    }

    #[test]
    fn blends_cross_fade_linearly() {
        let mut b = Blend::default();
        let w: Vec<f32> = (0..5).map(|_| b.advance(true, 0.005, 0.02)).collect();
        assert_eq!(w, [0.25, 0.5, 0.75, 1.0, 1.0]);
        assert_eq!(b.advance(false, 0.005, 0.02), 0.75);
    }
}
