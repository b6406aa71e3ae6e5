//! Fixed-width gather forms of the per-axis operators, built once per basis so that the
//! sweeps in [`super::sweep`] run branch-free: `B` and `Bᵀ` as "output `o` is a weighted sum of
//! `taps` consecutive inputs starting at `start[o]`", and the banded Cholesky factor of `BᵀB`
//! with its lower and upper coefficients laid out per row (zero beyond the ends).
//!
//! Zero weights are trimmed from both ends of every window, so with one mass point per
//! coefficient (`m = n`) `B` and `Bᵀ` have three taps, not four. Nothing here allocates after
//! construction.

use super::axis::{AxisBasis, BandedCholesky};

/// A banded operator as a gather: `out[o] = Σ_t weights[o · taps + t] · in[start[o] + t]`.
#[derive(Clone, Debug, PartialEq)]
pub struct Band {
    /// Number of outputs.
    pub outputs: usize,
    /// Number of inputs.
    pub inputs: usize,
    /// Window width shared by every output (at least 1).
    pub taps: usize,
    /// First input of each output's window (`start[o] + taps <= inputs`).
    pub start: Vec<usize>,
    /// `taps` weights per output, zero where the window is wider than the support.
    pub weights: Vec<f32>,
}

impl Band {
    /// The gather form of a dense `outputs × inputs` matrix (row-major) with contiguous
    /// non-zeros per row.
    #[must_use]
    pub fn from_dense(dense: &[f32], outputs: usize, inputs: usize) -> Self {
        let range = |o: usize| {
            let row = &dense[o * inputs..(o + 1) * inputs];
            let lo = row.iter().position(|&w| w != 0.0).unwrap_or(0);
            let hi = row
                .iter()
                .rposition(|&w| w != 0.0)
                .map_or(lo + 1, |h| h + 1);
            (lo, hi)
        };
        let taps = (0..outputs)
            .map(|o| {
                let (lo, hi) = range(o);
                hi - lo
            })
            .max()
            .unwrap_or(1)
            .clamp(1, inputs.max(1));
        let mut start = Vec::with_capacity(outputs);
        let mut weights = Vec::with_capacity(outputs * taps);
        for o in 0..outputs {
            let (lo, _) = range(o);
            let s = lo.min(inputs.saturating_sub(taps));
            start.push(s);
            weights
                .extend((0..taps).map(|t| dense.get(o * inputs + s + t).copied().unwrap_or(0.0)));
        }
        Self {
            outputs,
            inputs,
            taps,
            start,
            weights,
        }
    }

    /// `B` of one axis (outputs = samples, inputs = coefficients).
    #[must_use]
    pub fn forward(axis: &AxisBasis) -> Self {
        Self::from_dense(&dense_f32(axis), axis.rows, axis.cols)
    }

    /// `Bᵀ` of one axis (outputs = coefficients, inputs = samples).
    #[must_use]
    pub fn transposed(axis: &AxisBasis) -> Self {
        let dense = dense_f32(axis);
        let (m, n) = (axis.rows, axis.cols);
        let mut t = vec![0.0; m * n];
        for r in 0..m {
            for c in 0..n {
                t[c * m + r] = dense[r * n + c];
            }
        }
        Self::from_dense(&t, n, m)
    }
}

fn dense_f32(axis: &AxisBasis) -> Vec<f32> {
    let mut dense = vec![0.0; axis.rows * axis.cols];
    for j in 0..axis.rows {
        for t in 0..axis.width {
            dense[j * axis.cols + axis.first[j] + t] = axis.weights[j][t];
        }
    }
    dense
}

/// The banded Cholesky solve `L Lᵀ x = b` laid out for branch-free sweeps.
#[derive(Clone, Debug, PartialEq)]
pub struct SolvePlan {
    /// `1 / L[i][i]`.
    pub inv_diag: Vec<f32>,
    /// `lower[i][k - 1] = L[i][i - k]` (zero where `i < k`): the forward sweep.
    pub lower: Vec<[f32; 3]>,
    /// `upper[i][k - 1] = L[i + k][i]` (zero where `i + k >= n`): the backward sweep.
    pub upper: Vec<[f32; 3]>,
}

impl SolvePlan {
    /// Lay out a banded Cholesky factor.
    #[must_use]
    pub fn new(chol: &BandedCholesky) -> Self {
        let n = chol.len();
        let upper = (0..n)
            .map(|i| {
                let mut u = [0.0; 3];
                for (k, slot) in u.iter_mut().enumerate() {
                    if i + k + 1 < n {
                        *slot = chol.sub[i + k + 1][k];
                    }
                }
                u
            })
            .collect();
        Self {
            inv_diag: chol.inv_diag.clone(),
            lower: chol.sub.clone(),
            upper,
        }
    }

    /// Number of unknowns.
    #[must_use]
    pub fn len(&self) -> usize {
        self.inv_diag.len()
    }

    /// Whether there are no unknowns.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.inv_diag.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bands_reproduce_the_dense_factor_and_trim_zero_taps() {
        for (n, m) in [(5, 5), (7, 13), (4, 10), (2, 3), (32, 32)] {
            let du = (n - 1) as f64 / (m - 1) as f64;
            let axis = AxisBasis::uniform(0.0, n, 0.0, du, m);
            let dense = dense_f32(&axis);
            let f = Band::forward(&axis);
            let t = Band::transposed(&axis);
            for r in 0..m {
                for c in 0..n {
                    let get = |b: &Band, o: usize, i: usize| {
                        let s = b.start[o];
                        if (s..s + b.taps).contains(&i) {
                            b.weights[o * b.taps + i - s]
                        } else {
                            0.0
                        }
                    };
                    assert_eq!(get(&f, r, c), dense[r * n + c], "B[{r}][{c}]");
                    assert_eq!(get(&t, c, r), dense[r * n + c], "Bᵀ[{c}][{r}]");
                }
            }
            if m == n && n >= 4 {
                assert_eq!((f.taps, t.taps), (3, 3), "m = n needs three taps");
            }
        }
    }
}
