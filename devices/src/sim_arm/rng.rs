//! A tiny seeded random generator (PCG-XSH-RR 32) for the simulated arm's noise and drops.
//!
//! Deterministic across platforms for a given seed, allocation-free, and not cryptographic.

/// Permuted congruential generator with 64-bit state and 32-bit output (O'Neill's PCG32).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SimRng {
    state: u64,
    increment: u64,
}

impl SimRng {
    const MULTIPLIER: u64 = 6_364_136_223_846_793_005;
    /// Default stream selector (any odd increment works).
    const STREAM: u64 = 1_442_695_040_888_963_407;

    /// A generator seeded with `seed`; equal seeds give equal sequences.
    #[must_use]
    pub fn new(seed: u64) -> Self {
        let mut rng = Self {
            state: 0,
            increment: Self::STREAM | 1,
        };
        rng.next_u32();
        rng.state = rng.state.wrapping_add(seed);
        rng.next_u32();
        rng
    }

    /// The next 32 uniformly distributed bits.
    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old
            .wrapping_mul(Self::MULTIPLIER)
            .wrapping_add(self.increment);
        // Output permutation: xorshift the high bits, then a state-dependent rotation.
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        let rotation = (old >> 59) as u32;
        xorshifted.rotate_right(rotation)
    }

    /// A uniform sample in `[0, 1)`, with 24 bits of precision.
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 * (1.0 / 16_777_216.0)
    }

    /// A standard normal sample (Box–Muller; one of the pair is discarded to keep the
    /// generator stateless beyond its counter).
    pub fn next_normal(&mut self) -> f32 {
        // u1 in (0, 1] so the logarithm is finite.
        let u1 = 1.0 - self.next_f32();
        let u2 = self.next_f32();
        (-2.0 * u1.ln()).sqrt() * (std::f32::consts::TAU * u2).cos()
    }

    /// `true` with probability `p` (clamped to `[0, 1]`; NaN counts as 0).
    pub fn chance(&mut self, p: f32) -> bool {
        self.next_f32() < p
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_seed_same_sequence_different_seed_differs() {
        let mut a = SimRng::new(42);
        let mut b = SimRng::new(42);
        let mut c = SimRng::new(43);
        let sa: Vec<u32> = (0..64).map(|_| a.next_u32()).collect();
        let sb: Vec<u32> = (0..64).map(|_| b.next_u32()).collect();
        let sc: Vec<u32> = (0..64).map(|_| c.next_u32()).collect();
        assert_eq!(sa, sb);
        assert_ne!(sa, sc);
    }

    #[test]
    fn uniform_and_normal_moments() {
        let mut rng = SimRng::new(7);
        let n = 20_000;
        let u: Vec<f32> = (0..n).map(|_| rng.next_f32()).collect();
        assert!(u.iter().all(|&x| (0.0..1.0).contains(&x)));
        let mean = u.iter().sum::<f32>() / n as f32;
        assert!((mean - 0.5).abs() < 0.01, "{mean}");

        let g: Vec<f32> = (0..n).map(|_| rng.next_normal()).collect();
        let mean = g.iter().sum::<f32>() / n as f32;
        let var = g.iter().map(|x| (x - mean) * (x - mean)).sum::<f32>() / n as f32;
        assert!(mean.abs() < 0.03, "{mean}");
        assert!((var - 1.0).abs() < 0.05, "{var}");
        assert!(g.iter().all(|x| x.is_finite()));
    }

    #[test]
    fn chance_extremes() {
        let mut rng = SimRng::new(1);
        assert!((0..1000).all(|_| !rng.chance(0.0)));
        assert!((0..1000).all(|_| rng.chance(1.0)));
        assert!((0..1000).all(|_| !rng.chance(f32::NAN)));
    }
}
