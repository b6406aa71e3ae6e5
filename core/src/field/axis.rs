//! One axis of the sampling operator: the banded factor `B` of `A = Bx ⊗ By ⊗ Bz`, and the
//! banded Cholesky factor of its Gram matrix `BᵀB`.
//!
//! Row `j` of `B` holds the weights of the cubic B-splines at sample `j` (at most four non-zeros,
//! in a window of consecutive columns). `BᵀB` has half-bandwidth 3, so its Cholesky factor is
//! stored as a diagonal and three sub-diagonals. Nothing here allocates after construction.

/// Centred uniform cubic B-spline: the weight of a coefficient at signed distance `t` (in knot
/// spans) from its node. Zero for `|t| >= 2`.
#[inline]
#[must_use]
pub fn centred_cubic(t: f64) -> f64 {
    let a = t.abs();
    if a < 1.0 {
        2.0 / 3.0 - a * a + 0.5 * a * a * a
    } else if a < 2.0 {
        let s = 2.0 - a;
        s * s * s / 6.0
    } else {
        0.0
    }
}

/// The banded `m × n` factor `B` of one axis: `m` samples, `n` coefficients.
#[derive(Clone, Debug, PartialEq)]
pub struct AxisBasis {
    /// Number of samples (rows).
    pub rows: usize,
    /// Number of coefficients (columns).
    pub cols: usize,
    /// Width of every row's window: `min(4, cols)`.
    pub width: usize,
    /// First column of each row's window (`first[j] + width <= cols`).
    pub first: Vec<usize>,
    /// `width` weights per row (row-major, padded to 4), zero where a column has no support.
    pub weights: Vec<[f32; 4]>,
}

impl AxisBasis {
    /// Samples at lattice coordinates `u0 + j · du` (`j < rows`) against the coefficients
    /// centred on lattice coordinates `c0, c0 + 1, …, c0 + cols − 1`.
    ///
    /// # Panics
    /// When `cols` is zero.
    #[must_use]
    pub fn uniform(c0: f64, cols: usize, u0: f64, du: f64, rows: usize) -> Self {
        assert!(cols > 0, "an axis needs at least one coefficient");
        let width = cols.min(4);
        let mut first = Vec::with_capacity(rows);
        let mut weights = Vec::with_capacity(rows);
        for j in 0..rows {
            let u = u0 + j as f64 * du - c0;
            // Columns floor(u)-1 ..= floor(u)+2 may be non-zero; clamp the window into range.
            let lo = (u.floor() as i64 - 1).clamp(0, (cols - width) as i64) as usize;
            let mut w = [0.0_f32; 4];
            for (t, slot) in w.iter_mut().enumerate().take(width) {
                *slot = centred_cubic(u - (lo + t) as f64) as f32;
            }
            first.push(lo);
            weights.push(w);
        }
        Self {
            rows,
            cols,
            width,
            first,
            weights,
        }
    }

    /// Dense copy of the factor (for tests and small reference computations).
    #[must_use]
    pub fn to_dense(&self) -> Vec<f64> {
        let mut dense = vec![0.0; self.rows * self.cols];
        for j in 0..self.rows {
            for t in 0..self.width {
                dense[j * self.cols + self.first[j] + t] = f64::from(self.weights[j][t]);
            }
        }
        dense
    }

    /// Banded Cholesky factor of `BᵀB`.
    ///
    /// # Errors
    /// When `BᵀB` is not positive definite (fewer useful samples than coefficients).
    pub fn gram_cholesky(&self) -> Result<BandedCholesky, NotPositiveDefinite> {
        let n = self.cols;
        // gram[a][k] = G[a][a - k] for k in 0..4 (lower band, k = 0 the diagonal).
        let mut gram = vec![[0.0_f64; 4]; n];
        for j in 0..self.rows {
            for s in 0..self.width {
                for t in 0..=s {
                    let (a, b) = (self.first[j] + s, self.first[j] + t);
                    gram[a][a - b] += f64::from(self.weights[j][s]) * f64::from(self.weights[j][t]);
                }
            }
        }
        BandedCholesky::factor(&gram)
    }
}

/// A band matrix that has no Cholesky factor: the pivot of row `row` came out `pivot`, not
/// positive (a Gram matrix with fewer useful samples than coefficients, or a NaN in it).
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
#[error("Gram matrix is not positive definite at pivot {row} (value {pivot})")]
pub struct NotPositiveDefinite {
    /// The row whose pivot failed.
    pub row: usize,
    /// Its value (zero, negative or NaN).
    pub pivot: f64,
}

/// Cholesky factor `L` (lower, half-bandwidth 3) of a symmetric positive definite band matrix.
#[derive(Clone, Debug, PartialEq)]
pub struct BandedCholesky {
    /// `1 / L[i][i]`.
    pub inv_diag: Vec<f32>,
    /// `sub[i][k - 1] = L[i][i - k]` for `k = 1..=3` (zero where `i < k`).
    pub sub: Vec<[f32; 3]>,
}

impl BandedCholesky {
    /// Factor a band matrix given as `band[a][k] = G[a][a - k]`.
    ///
    /// # Errors
    /// When a pivot is not positive (the matrix is not positive definite).
    pub fn factor(band: &[[f64; 4]]) -> Result<Self, NotPositiveDefinite> {
        let n = band.len();
        let mut l = vec![[0.0_f64; 4]; n]; // l[i][k] = L[i][i-k]
        for i in 0..n {
            for k in (1..4).rev() {
                if i < k {
                    continue;
                }
                let jcol = i - k;
                // L[i][j] = (G[i][j] - Σ_{q<j} L[i][q] L[j][q]) / L[j][j]
                let mut s = band[i][k];
                for q in 1..4 {
                    // q indexes columns j - q (must be within band of both rows).
                    if jcol < q || k + q > 3 {
                        continue;
                    }
                    s -= l[i][k + q] * l[jcol][q];
                }
                l[i][k] = s / l[jcol][0];
            }
            let d = band[i][0] - l[i][1..].iter().map(|v| v * v).sum::<f64>();
            // Also rejects NaN.
            if d.is_nan() || d <= 0.0 {
                return Err(NotPositiveDefinite { row: i, pivot: d });
            }
            l[i][0] = d.sqrt();
        }
        Ok(Self {
            inv_diag: l.iter().map(|r| (1.0 / r[0]) as f32).collect(),
            sub: l
                .iter()
                .map(|r| [r[1] as f32, r[2] as f32, r[3] as f32])
                .collect(),
        })
    }

    /// Number of unknowns.
    #[must_use]
    pub fn len(&self) -> usize {
        self.inv_diag.len()
    }

    /// Whether the factor is empty.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.inv_diag.is_empty()
    }

    /// Solve `L Lᵀ x = b` in place for one contiguous vector.
    pub fn solve_in_place(&self, x: &mut [f32]) {
        let n = self.len();
        for i in 0..n {
            let mut s = x[i];
            for k in 1..=3.min(i) {
                s -= self.sub[i][k - 1] * x[i - k];
            }
            x[i] = s * self.inv_diag[i];
        }
        for i in (0..n).rev() {
            let mut s = x[i];
            for k in 1..=3 {
                if i + k < n {
                    s -= self.sub[i + k][k - 1] * x[i + k];
                }
            }
            x[i] = s * self.inv_diag[i];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_are_a_partition_of_unity_inside() {
        let b = AxisBasis::uniform(0.0, 8, 1.0, 0.25, 21);
        for j in 0..b.rows {
            let s: f32 = b.weights[j].iter().sum();
            assert!((s - 1.0).abs() < 1e-6, "row {j}: {s}");
        }
    }

    #[test]
    fn cholesky_solves_the_gram_system() {
        for (n, m, du) in [(5, 5, 1.0), (7, 13, 0.5), (4, 10, 1.0 / 3.0), (2, 3, 0.5)] {
            let b = AxisBasis::uniform(0.0, n, 0.0, du, m);
            let chol = b.gram_cholesky().unwrap();
            let dense = b.to_dense();
            let mut g = vec![0.0; n * n];
            for j in 0..m {
                for a in 0..n {
                    for c in 0..n {
                        g[a * n + c] += dense[j * n + a] * dense[j * n + c];
                    }
                }
            }
            let x_true: Vec<f32> = (0..n).map(|i| (i as f32 * 0.7).sin() + 0.3).collect();
            let mut rhs: Vec<f32> = (0..n)
                .map(|a| {
                    (0..n)
                        .map(|c| g[a * n + c] * f64::from(x_true[c]))
                        .sum::<f64>() as f32
                })
                .collect();
            chol.solve_in_place(&mut rhs);
            for (x, t) in rhs.iter().zip(&x_true) {
                assert!((x - t).abs() < 1e-4, "n={n} m={m}: {x} vs {t}");
            }
        }
    }
}
