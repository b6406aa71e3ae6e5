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
}

/// `B⁻¹` of a square tridiagonal factor (one mass point per coefficient), as `B = L U` with
/// `L` unit lower and `U` upper bidiagonal. Then `(BᵀB)⁻¹Bᵀ = B⁻¹`, and one tridiagonal solve
/// replaces `Bᵀ` followed by the Gram solve (about a quarter of the arithmetic).
#[derive(Clone, Debug, PartialEq)]
pub struct TriLu {
    /// `lower[i] = L[i][i − 1]` (zero for `i = 0`).
    pub lower: Vec<f32>,
    /// `upper[i] = B[i][i + 1]` (zero for the last row).
    pub upper: Vec<f32>,
    /// `1 / U[i][i]`.
    pub inv_diag: Vec<f32>,
}

impl TriLu {
    /// The factorisation, when `axis` is square, tridiagonal and strictly diagonally dominant
    /// (so elimination without pivoting is stable); `None` otherwise.
    #[must_use]
    pub fn new(axis: &AxisBasis) -> Option<Self> {
        let n = axis.cols;
        if axis.rows != n {
            return None;
        }
        let dense = dense_f32(axis);
        let at = |r: usize, c: usize| f64::from(dense[r * n + c]);
        for r in 0..n {
            let off: f64 = (0..n)
                .filter(|&c| c != r)
                .map(|c| {
                    let v = at(r, c);
                    if r.abs_diff(c) > 1 && v != 0.0 {
                        f64::INFINITY
                    } else {
                        v.abs()
                    }
                })
                .sum();
            if at(r, r).abs() <= off {
                return None;
            }
        }
        let (mut lower, mut upper, mut inv_diag) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        let mut pivot = at(0, 0);
        inv_diag[0] = (1.0 / pivot) as f32;
        for i in 1..n {
            let l = at(i, i - 1) / pivot;
            pivot = at(i, i) - l * at(i - 1, i);
            lower[i] = l as f32;
            upper[i - 1] = at(i - 1, i) as f32;
            inv_diag[i] = (1.0 / pivot) as f32;
        }
        Some(Self {
            lower,
            upper,
            inv_diag,
        })
    }

    /// Number of unknowns.
    #[must_use]
    pub fn len(&self) -> usize {
        self.inv_diag.len()
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
            // B⁻¹ exists exactly when the factor is square.
            let lu = TriLu::new(&axis);
            assert_eq!(lu.is_some(), m == n, "n={n} m={m}");
            if let Some(lu) = lu {
                // Solve B x = B v for a known v.
                let v: Vec<f64> = (0..n).map(|i| (i as f64 * 0.9).cos()).collect();
                let b: Vec<f64> = (0..n)
                    .map(|r| (0..n).map(|c| f64::from(dense[r * n + c]) * v[c]).sum())
                    .collect();
                let mut y = vec![0.0; n];
                for i in 0..n {
                    let prev = if i > 0 { y[i - 1] } else { 0.0 };
                    y[i] = b[i] - f64::from(lu.lower[i]) * prev;
                }
                for i in (0..n).rev() {
                    let next = if i + 1 < n { y[i + 1] } else { 0.0 };
                    y[i] = (y[i] - f64::from(lu.upper[i]) * next) * f64::from(lu.inv_diag[i]);
                }
                for (a, b) in y.iter().zip(&v) {
                    assert!((a - b).abs() < 1e-5, "{a} vs {b}");
                }
            }
        }
    }
}
