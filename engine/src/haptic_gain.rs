//! The haptic gain the user may change while the engine runs: how strongly the sculpting
//! reaction is felt, as a factor on the calibrated scale (1: a 5 mm press into the fresh clay
//! feels 2 N).
//!
//! Guarantee: wait-free and allocation-free — one `f32` held as bits in an `AtomicU32`; the
//! haptic tick does one relaxed load per tick. Relaxed suffices: the value is the whole
//! message and no other memory depends on it.

use std::sync::Arc;
use std::sync::atomic::{AtomicU32, Ordering};

/// Largest haptic gain accepted.
pub const MAX_HAPTIC_GAIN: f32 = 10.0;

/// A gain outside `0..=MAX_HAPTIC_GAIN`, or not a number.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
#[error("haptic gain {0}: must be a number from 0 to {MAX_HAPTIC_GAIN}", MAX_HAPTIC_GAIN = MAX_HAPTIC_GAIN)]
pub struct InvalidHapticGain(pub f32);

/// A shared handle on the haptic gain (cheap to clone: an `Arc`).
#[derive(Clone, Debug)]
pub struct HapticGain {
    bits: Arc<AtomicU32>,
}

impl HapticGain {
    /// A gain starting at `gain` (clamped into the accepted range; NaN gives 1).
    #[must_use]
    pub fn new(gain: f32) -> Self {
        let gain = if gain.is_nan() {
            1.0
        } else {
            gain.clamp(0.0, MAX_HAPTIC_GAIN)
        };
        Self {
            bits: Arc::new(AtomicU32::new(gain.to_bits())),
        }
    }

    /// Sets the gain from the next haptic tick on.
    ///
    /// # Errors
    /// [`InvalidHapticGain`] for a NaN, a negative value or one above [`MAX_HAPTIC_GAIN`];
    /// nothing changes then.
    pub fn set(&self, gain: f32) -> Result<(), InvalidHapticGain> {
        if !(0.0..=MAX_HAPTIC_GAIN).contains(&gain) {
            return Err(InvalidHapticGain(gain));
        }
        self.bits.store(gain.to_bits(), Ordering::Relaxed);
        Ok(())
    }

    /// The gain now.
    #[must_use]
    pub fn get(&self) -> f32 {
        f32::from_bits(self.bits.load(Ordering::Relaxed))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn accepts_the_range_and_refuses_the_rest() {
        let g = HapticGain::new(1.0);
        let other = g.clone();
        other.set(2.5).unwrap();
        assert_eq!(g.get(), 2.5);
        for bad in [f32::NAN, -0.1, 10.5] {
            assert!(g.set(bad).is_err());
        }
        assert_eq!(g.get(), 2.5);
        assert_eq!(HapticGain::new(f32::NAN).get(), 1.0);
    }
}
