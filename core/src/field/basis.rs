//! Uniform cubic B-spline basis weights.
//!
//! A coefficient with index `a` is centred on lattice point `a`; at a point whose lattice
//! coordinate is `u = i + t` (`i = floor(u)`, `t` in `[0, 1)`) the four coefficients
//! `i-1 ..= i+2` contribute, with the weights returned here in that order.

/// The four uniform cubic B-spline weights at fractional position `t` in `[0, 1)`.
///
/// They are non-negative and sum to one (partition of unity).
#[inline]
#[must_use]
pub fn cubic_weights(t: f32) -> [f32; 4] {
    let t2 = t * t;
    let t3 = t2 * t;
    let s = 1.0 - t;
    const SIXTH: f32 = 1.0 / 6.0;
    [
        s * s * s * SIXTH,
        (3.0 * t3 - 6.0 * t2 + 4.0) * SIXTH,
        (-3.0 * t3 + 3.0 * t2 + 3.0 * t + 1.0) * SIXTH,
        t3 * SIXTH,
    ]
}

/// The four weights and their derivatives with respect to `t`.
#[inline]
#[must_use]
pub fn cubic_weights_and_derivatives(t: f32) -> ([f32; 4], [f32; 4]) {
    let t2 = t * t;
    let s = 1.0 - t;
    let derivatives = [
        -0.5 * s * s,
        1.5 * t2 - 2.0 * t,
        -1.5 * t2 + t + 0.5,
        0.5 * t2,
    ];
    (cubic_weights(t), derivatives)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weights_are_a_partition_of_unity() {
        for step in 0..=100 {
            let t = step as f32 / 100.0 * 0.9999;
            let (w, dw) = cubic_weights_and_derivatives(t);
            assert!((w.iter().sum::<f32>() - 1.0).abs() < 1e-6);
            assert!(dw.iter().sum::<f32>().abs() < 1e-6);
            assert!(w.iter().all(|&x| x >= 0.0));
        }
    }

    #[test]
    fn derivatives_match_finite_differences() {
        let h = 1e-3_f32;
        for step in 1..10 {
            let t = step as f32 / 10.0;
            let (_, dw) = cubic_weights_and_derivatives(t);
            let (plus, minus) = (cubic_weights(t + h), cubic_weights(t - h));
            for a in 0..4 {
                let fd = (plus[a] - minus[a]) / (2.0 * h);
                assert!(
                    (fd - dw[a]).abs() < 1e-3,
                    "weight {a} at t={t}: {fd} vs {}",
                    dw[a]
                );
            }
        }
    }
}
