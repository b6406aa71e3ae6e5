//! Scheduled faults for the simulated arm: what goes wrong, and when (simulated time).

use serde::{Deserialize, Serialize};

/// The kind of fault injected while a [`Fault`] is active.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "kind")]
pub enum FaultKind {
    /// The link is gone: `read` and `write_force` return `Disconnected`, and the arm's
    /// firmware drops the motor command to zero. The link comes back when the fault ends.
    Disconnect,
    /// The device stops answering: `read` and `write_force` return `Timeout`, and the
    /// firmware watchdog drops the motor command to zero.
    Stall,
    /// Samples keep arriving (fresh sequence and timestamp) but report the position the
    /// effector had when the fault began, with zero velocity: a jammed encoder or stuck buffer.
    Freeze,
    /// Gaussian noise of standard deviation `std_m` on each axis of the reported position
    /// (the physical effector is unaffected).
    Noise {
        /// Standard deviation per axis, metres.
        std_m: f32,
    },
    /// Each read misses the fresh sample with this probability and returns the previous one
    /// again (same `sequence` and timestamp); the next fresh sample shows the gap.
    Drop {
        /// Probability per read, in `[0, 1]`.
        probability: f32,
    },
}

/// A fault active during `[start_s, start_s + duration_s)` of the arm's simulated time.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Fault {
    /// Start, seconds of simulated time since `open`.
    pub start_s: f64,
    /// Length, seconds (`f64::INFINITY` for the rest of the run).
    pub duration_s: f64,
    /// What goes wrong.
    #[serde(flatten)]
    pub kind: FaultKind,
}

impl Fault {
    /// A fault of `kind` from `start_s` for `duration_s`.
    #[must_use]
    pub fn new(start_s: f64, duration_s: f64, kind: FaultKind) -> Self {
        Self {
            start_s,
            duration_s,
            kind,
        }
    }

    /// Whether the fault is active at `time_s`.
    #[must_use]
    pub fn active_at(&self, time_s: f64) -> bool {
        time_s >= self.start_s && time_s - self.start_s < self.duration_s
    }

    /// Whether the fault is active at `time_us`, with the bounds rounded to whole
    /// microseconds so that a fault from 0.1 s starts exactly at tick 100 000 µs.
    #[must_use]
    pub fn active_at_us(&self, time_us: u64) -> bool {
        let t = time_us as f64;
        let start = (self.start_s * 1e6).round();
        let duration = (self.duration_s * 1e6).round();
        t >= start && t - start < duration
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn active_interval_is_half_open() {
        let f = Fault::new(1.0, 0.5, FaultKind::Stall);
        assert!(!f.active_at(0.999));
        assert!(f.active_at(1.0));
        assert!(f.active_at(1.499));
        assert!(!f.active_at(1.5));
        let forever = Fault::new(2.0, f64::INFINITY, FaultKind::Disconnect);
        assert!(forever.active_at(1e9));
        let f = Fault::new(0.1, 0.05, FaultKind::Stall);
        assert!(!f.active_at_us(99_999));
        assert!(f.active_at_us(100_000));
        assert!(f.active_at_us(149_999));
        assert!(!f.active_at_us(150_000));
        assert!(forever.active_at_us(u64::MAX));
    }

    #[test]
    fn faults_deserialize_from_toml() {
        #[derive(Deserialize)]
        struct S {
            fault: Vec<Fault>,
        }
        let s: S = toml::from_str(
            "[[fault]]\nstart_s = 1.0\nduration_s = 0.2\nkind = \"disconnect\"\n\
             [[fault]]\nstart_s = 0.0\nduration_s = 5.0\nkind = \"noise\"\nstd_m = 0.0001\n",
        )
        .unwrap();
        assert_eq!(s.fault[0].kind, FaultKind::Disconnect);
        assert_eq!(s.fault[1].kind, FaultKind::Noise { std_m: 0.0001 });
    }
}
