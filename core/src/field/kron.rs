//! The sampling operator `A = Bx ⊗ By ⊗ Bz`, its transpose and the inverse of `AᵀA`, applied
//! axis by axis; `A` is never formed.
//!
//! Arrays are x fastest. Coefficients have shape `cols = [nx, ny, nz]`, samples (mass points)
//! shape `rows = [mx, my, mz]`. `AᵀA = BxᵀBx ⊗ ByᵀBy ⊗ BzᵀBz`, so `(AᵀA)⁻¹` is three banded
//! Cholesky solves, one per axis, and `(AᵀA)⁻¹Aᵀ` fuses into one pass per axis. Every pass
//! sweeps [`LANES`] lines together (see `sweep.rs`): columns of whole rows along y and z, lines
//! transposed into a block along the contiguous x axis, whose banded solve would otherwise be a
//! latency-bound scalar recurrence. Nothing allocates after construction except where a method
//! says so; scratch space is passed in. [`apply_axes`] keeps the plain row-by-row passes for
//! one-off operators built without Gram factors.

use super::axis::{AxisBasis, BandedCholesky, NotPositiveDefinite};
use super::band::{Band, SolvePlan, TriLu};
pub use super::sweep::LANES;
use super::sweep::{AxisOp, SharedOut, sweep_strided, sweep_x};

/// Why an operator could not be built.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("axis {axis}: {source}")]
pub struct KronError {
    /// Which axis (0 = x, 1 = y, 2 = z).
    pub axis: usize,
    /// The axis's Gram matrix has no Cholesky factor.
    pub source: NotPositiveDefinite,
}

/// `A = Bx ⊗ By ⊗ Bz` with the Cholesky factors of the three Gram matrices.
#[derive(Clone, Debug, PartialEq)]
pub struct KroneckerBasis {
    /// The per-axis factors.
    pub axes: [AxisBasis; 3],
    /// Cholesky factors of `BᵀB`, per axis.
    pub chol: [BandedCholesky; 3],
    /// `B` per axis in gather form.
    forward: [Band; 3],
    /// `Bᵀ` per axis in gather form.
    transposed: [Band; 3],
    /// The Cholesky factors laid out for the sweeps.
    solve: [SolvePlan; 3],
    /// `B⁻¹` per axis where `B` is square (then `(BᵀB)⁻¹Bᵀ = B⁻¹`).
    inverse: [Option<TriLu>; 3],
}

/// Scratch space for [`KroneckerBasis`] operations (two intermediate arrays).
#[derive(Clone, Debug, Default)]
pub struct KronScratch {
    a: Vec<f32>,
    b: Vec<f32>,
}

impl KronScratch {
    /// Length of each scratch array.
    #[must_use]
    pub fn len(&self) -> usize {
        self.a.len().min(self.b.len())
    }

    /// Whether the scratch is empty.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Both scratch arrays, for a caller's own passes between operations.
    pub(crate) fn arrays(&mut self) -> (&mut [f32], &mut [f32]) {
        (&mut self.a, &mut self.b)
    }

    /// Scratch large enough for every operation of `basis`.
    #[must_use]
    pub fn for_basis(basis: &KroneckerBasis) -> Self {
        let len = basis.scratch_len();
        Self {
            a: vec![0.0; len],
            b: vec![0.0; len],
        }
    }
}

impl KroneckerBasis {
    /// Build from three axis factors.
    ///
    /// # Errors
    /// When an axis Gram matrix is not positive definite.
    pub fn new(axes: [AxisBasis; 3]) -> Result<Self, KronError> {
        let mut chol = Vec::with_capacity(3);
        for (axis, b) in axes.iter().enumerate() {
            chol.push(
                b.gram_cholesky()
                    .map_err(|source| KronError { axis, source })?,
            );
        }
        let [cx, cy, cz]: [BandedCholesky; 3] = chol.try_into().expect("three axes");
        let chol = [cx, cy, cz];
        Ok(Self {
            forward: std::array::from_fn(|a| Band::forward(&axes[a])),
            transposed: std::array::from_fn(|a| Band::transposed(&axes[a])),
            solve: std::array::from_fn(|a| SolvePlan::new(&chol[a])),
            inverse: std::array::from_fn(|a| TriLu::new(&axes[a])),
            axes,
            chol,
        })
    }

    /// Coefficient shape `[nx, ny, nz]`.
    #[must_use]
    pub fn cols(&self) -> [usize; 3] {
        [self.axes[0].cols, self.axes[1].cols, self.axes[2].cols]
    }

    /// Sample shape `[mx, my, mz]`.
    #[must_use]
    pub fn rows(&self) -> [usize; 3] {
        [self.axes[0].rows, self.axes[1].rows, self.axes[2].rows]
    }

    /// Number of coefficients.
    #[must_use]
    pub fn coeff_count(&self) -> usize {
        self.cols().iter().product()
    }

    /// Number of samples.
    #[must_use]
    pub fn sample_count(&self) -> usize {
        self.rows().iter().product()
    }

    fn scratch_len(&self) -> usize {
        let [nx, ny, nz] = self.cols();
        let [mx, my, mz] = self.rows();
        let (x, y) = (nx.max(mx), ny.max(my));
        x * y * nz.max(mz)
    }

    /// `d = A p`. Allocates nothing.
    ///
    /// # Panics
    /// When the slices do not match the operator's shapes or the scratch is too small.
    pub fn apply(&self, p: &[f32], d: &mut [f32], scratch: &mut KronScratch) {
        assert_eq!(p.len(), self.coeff_count(), "coefficient length");
        assert_eq!(d.len(), self.sample_count(), "sample length");
        self.chain(
            [self.op_apply(0), self.op_apply(1), self.op_apply(2)],
            p,
            d,
            scratch,
        );
    }

    /// `b = Aᵀ d`. Allocates nothing.
    ///
    /// # Panics
    /// When the slices do not match the operator's shapes or the scratch is too small.
    pub fn apply_transpose(&self, d: &[f32], b: &mut [f32], scratch: &mut KronScratch) {
        assert_eq!(d.len(), self.sample_count(), "sample length");
        assert_eq!(b.len(), self.coeff_count(), "coefficient length");
        self.chain(
            [
                self.op_apply_transpose(0),
                self.op_apply_transpose(1),
                self.op_apply_transpose(2),
            ],
            d,
            b,
            scratch,
        );
    }

    /// `p = scale · (AᵀA)⁻¹ Aᵀ d`: the least-squares coefficients of the samples `d`, with
    /// `Aᵀ` and the Gram solve fused per axis. Allocates nothing.
    ///
    /// # Panics
    /// When the slices do not match the operator's shapes or the scratch is too small.
    pub fn project(&self, d: &[f32], p: &mut [f32], scale: f32, scratch: &mut KronScratch) {
        assert_eq!(d.len(), self.sample_count(), "sample length");
        assert_eq!(p.len(), self.coeff_count(), "coefficient length");
        self.chain(
            [
                self.op_project(0, 1.0),
                self.op_project(1, 1.0),
                self.op_project(2, scale),
            ],
            d,
            p,
            scratch,
        );
    }

    /// `x ← (AᵀA)⁻¹ x`, in place, by three banded solves. Allocates a scratch copy; use
    /// [`KroneckerBasis::solve_gram_into`] on a real-time path.
    ///
    /// # Panics
    /// When `x` does not have one entry per coefficient.
    pub fn solve_gram(&self, x: &mut [f32]) {
        let src = x.to_vec();
        self.solve_gram_into(&src, x, &mut KronScratch::for_basis(self));
    }

    /// `x = (AᵀA)⁻¹ b`. Allocates nothing.
    ///
    /// # Panics
    /// When the slices do not have one entry per coefficient or the scratch is too small.
    pub fn solve_gram_into(&self, b: &[f32], x: &mut [f32], scratch: &mut KronScratch) {
        assert_eq!(b.len(), self.coeff_count(), "coefficient length");
        assert_eq!(x.len(), self.coeff_count(), "coefficient length");
        self.chain(
            [
                self.op_solve(0, 1.0),
                self.op_solve(1, 1.0),
                self.op_solve(2, 1.0),
            ],
            b,
            x,
            scratch,
        );
    }

    /// [`KroneckerBasis::solve_gram`] as a plain sweep, one line at a time along x and one
    /// row at a time along y and z: the alternative that `bench/core.rs` compares against.
    pub fn solve_gram_line_by_line(&self, x: &mut [f32]) {
        let [nx, ny, nz] = self.cols();
        assert_eq!(x.len(), self.coeff_count(), "coefficient length");
        for line in x.chunks_exact_mut(nx) {
            self.chol[0].solve_in_place(line);
        }
        solve_strided(&self.chol[1], x, nx, nz);
        solve_strided(&self.chol[2], x, nx * ny, 1);
    }

    /// The x, y, z passes of `ops` one after the other, single-threaded.
    fn chain(&self, ops: [AxisOp<'_>; 3], src: &[f32], dst: &mut [f32], scratch: &mut KronScratch) {
        let [sx, sy, sz] = self.pass_shapes(&ops);
        let t1 = &mut scratch.a[..sx.out_len];
        // SAFETY: one thread, and the output is an exclusively borrowed buffer (a fresh
        // `SharedOut` over `&mut`) that the source does not overlap; the same for the two
        // passes below.
        unsafe { sweep_x(&ops[0], src, 0..sx.lines, &SharedOut::new(t1)) };
        let t1 = &scratch.a[..sx.out_len];
        let t2 = &mut scratch.b[..sy.out_len];
        // SAFETY: as above.
        unsafe {
            sweep_strided(
                &ops[1],
                t1,
                sy.inner,
                0..sy.outer,
                0..sy.inner,
                &SharedOut::new(t2),
            );
        }
        let t2 = &scratch.b[..sy.out_len];
        // SAFETY: as above.
        unsafe {
            sweep_strided(
                &ops[2],
                t2,
                sz.inner,
                0..1,
                0..sz.inner,
                &SharedOut::new(dst),
            );
        }
    }

    /// Shapes of the three passes of `ops` (x, then y, then z).
    pub(crate) fn pass_shapes(&self, ops: &[AxisOp<'_>; 3]) -> [PassShape; 3] {
        let [iy, iz] = [ops[1].rows_in(), ops[2].rows_in()];
        let [ox, oy, oz] = [ops[0].rows_out(), ops[1].rows_out(), ops[2].rows_out()];
        [
            PassShape {
                lines: iy * iz,
                inner: 1,
                outer: iy * iz,
                out_len: ox * iy * iz,
            },
            PassShape {
                lines: ox * iz,
                inner: ox,
                outer: iz,
                out_len: ox * oy * iz,
            },
            PassShape {
                lines: ox * oy,
                inner: ox * oy,
                outer: 1,
                out_len: ox * oy * oz,
            },
        ]
    }

    /// `B` along `axis`.
    pub(crate) fn op_apply(&self, axis: usize) -> AxisOp<'_> {
        AxisOp::Apply(&self.forward[axis])
    }

    /// `Bᵀ` along `axis`.
    pub(crate) fn op_apply_transpose(&self, axis: usize) -> AxisOp<'_> {
        AxisOp::Apply(&self.transposed[axis])
    }

    /// `scale · (BᵀB)⁻¹ Bᵀ` along `axis` (`scale · B⁻¹` when `B` is square).
    pub(crate) fn op_project(&self, axis: usize, scale: f32) -> AxisOp<'_> {
        if let Some(lu) = &self.inverse[axis] {
            return AxisOp::Inverse { lu, scale };
        }
        AxisOp::Project {
            band: &self.transposed[axis],
            solve: &self.solve[axis],
            scale,
        }
    }

    /// `scale · (BᵀB)⁻¹` along `axis`.
    pub(crate) fn op_solve(&self, axis: usize, scale: f32) -> AxisOp<'_> {
        AxisOp::Solve {
            solve: &self.solve[axis],
            scale,
        }
    }
}

/// The shape of one pass of a chain: along x, `lines` lines; along y, `outer` planes of rows
/// `inner` long; along z, one block of rows `inner` long. `out_len` values come out.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct PassShape {
    pub lines: usize,
    pub inner: usize,
    pub outer: usize,
    pub out_len: usize,
}

/// `d = (Bx ⊗ By ⊗ Bz) p` for any three factors (no Gram factor needed). The scratch slices
/// must each hold at least `mx · max(ny, my) · max(nz, mz)` values.
///
/// # Panics
/// When a slice is shorter than the shapes need.
pub fn apply_axes(
    axes: &[AxisBasis; 3],
    p: &[f32],
    d: &mut [f32],
    scratch_a: &mut [f32],
    scratch_b: &mut [f32],
) {
    let [nx, ny, nz] = [axes[0].cols, axes[1].cols, axes[2].cols];
    let [mx, my, mz] = [axes[0].rows, axes[1].rows, axes[2].rows];
    assert_eq!(p.len(), nx * ny * nz, "coefficient length");
    assert_eq!(d.len(), mx * my * mz, "sample length");
    let t1 = &mut scratch_a[..mx * ny * nz];
    pass_x(&axes[0], p, t1);
    let t2 = &mut scratch_b[..mx * my * nz];
    pass_strided(&axes[1], t1, mx, nz, t2);
    pass_strided(&axes[2], t2, mx * my, 1, d);
}

/// Along x (contiguous): `dst[line][r] = Σ_t w[r][t] src[line][first[r] + t]`.
pub(crate) fn pass_x(basis: &AxisBasis, src: &[f32], dst: &mut [f32]) {
    let (n, m) = (basis.cols, basis.rows);
    for (line, out) in src.chunks_exact(n).zip(dst.chunks_exact_mut(m)) {
        if basis.width == 4 {
            for ((o, &f), w) in out.iter_mut().zip(&basis.first).zip(&basis.weights) {
                let s = &line[f..f + 4];
                *o = w[0] * s[0] + w[1] * s[1] + w[2] * s[2] + w[3] * s[3];
            }
        } else {
            for ((o, &f), w) in out.iter_mut().zip(&basis.first).zip(&basis.weights) {
                *o = (0..basis.width).map(|t| w[t] * line[f + t]).sum();
            }
        }
    }
}

/// Along a strided axis: `src` has shape `[inner, n, outer]`, `dst` shape `[inner, m, outer]`.
pub(crate) fn pass_strided(
    basis: &AxisBasis,
    src: &[f32],
    inner: usize,
    outer: usize,
    dst: &mut [f32],
) {
    let (n, m) = (basis.cols, basis.rows);
    for o in 0..outer {
        let src_block = &src[o * n * inner..(o + 1) * n * inner];
        let dst_block = &mut dst[o * m * inner..(o + 1) * m * inner];
        for (r, out) in dst_block.chunks_exact_mut(inner).enumerate() {
            let f = basis.first[r];
            let w = basis.weights[r];
            if basis.width == 4 {
                let s0 = &src_block[f * inner..(f + 1) * inner];
                let s1 = &src_block[(f + 1) * inner..(f + 2) * inner];
                let s2 = &src_block[(f + 2) * inner..(f + 3) * inner];
                let s3 = &src_block[(f + 3) * inner..(f + 4) * inner];
                for ((((o, &a), &b), &c), &d) in out.iter_mut().zip(s0).zip(s1).zip(s2).zip(s3) {
                    *o = w[0] * a + w[1] * b + w[2] * c + w[3] * d;
                }
            } else {
                out.fill(0.0);
                for t in 0..basis.width {
                    let s = &src_block[(f + t) * inner..(f + t + 1) * inner];
                    for (o, &v) in out.iter_mut().zip(s) {
                        *o += w[t] * v;
                    }
                }
            }
        }
    }
}

/// Banded solve along a strided axis of `x` with shape `[inner, n, outer]`.
pub(crate) fn solve_strided(chol: &BandedCholesky, x: &mut [f32], inner: usize, outer: usize) {
    let n = chol.len();
    for o in 0..outer {
        let block = &mut x[o * n * inner..(o + 1) * n * inner];
        for i in 0..n {
            let (prev, cur) = block.split_at_mut(i * inner);
            let cur = &mut cur[..inner];
            let l = chol.sub[i];
            let inv = chol.inv_diag[i];
            match i {
                0 => cur.iter_mut().for_each(|v| *v *= inv),
                1 => {
                    for (c, &a) in cur.iter_mut().zip(&prev[..inner]) {
                        *c = (*c - l[0] * a) * inv;
                    }
                }
                2 => {
                    let (p2, p1) = prev.split_at(inner);
                    for ((c, &a), &b) in cur.iter_mut().zip(p1).zip(p2) {
                        *c = (*c - l[0] * a - l[1] * b) * inv;
                    }
                }
                _ => {
                    let base = (i - 3) * inner;
                    let p3 = &prev[base..base + inner];
                    let p2 = &prev[base + inner..base + 2 * inner];
                    let p1 = &prev[base + 2 * inner..base + 3 * inner];
                    for (((c, &a), &b), &d) in cur.iter_mut().zip(p1).zip(p2).zip(p3) {
                        *c = (*c - l[0] * a - l[1] * b - l[2] * d) * inv;
                    }
                }
            }
        }
        for i in (0..n).rev() {
            let (head, tail) = block.split_at_mut((i + 1) * inner);
            let cur = &mut head[i * inner..];
            let inv = chol.inv_diag[i];
            let c1 = if i + 1 < n { chol.sub[i + 1][0] } else { 0.0 };
            let c2 = if i + 2 < n { chol.sub[i + 2][1] } else { 0.0 };
            let c3 = if i + 3 < n { chol.sub[i + 3][2] } else { 0.0 };
            let avail = n - i - 1;
            match avail {
                0 => cur.iter_mut().for_each(|v| *v *= inv),
                1 => {
                    for (c, &a) in cur.iter_mut().zip(&tail[..inner]) {
                        *c = (*c - c1 * a) * inv;
                    }
                }
                2 => {
                    let (n1, n2) = (&tail[..inner], &tail[inner..2 * inner]);
                    for ((c, &a), &b) in cur.iter_mut().zip(n1).zip(n2) {
                        *c = (*c - c1 * a - c2 * b) * inv;
                    }
                }
                _ => {
                    let (n1, n2, n3) = (
                        &tail[..inner],
                        &tail[inner..2 * inner],
                        &tail[2 * inner..3 * inner],
                    );
                    for (((c, &a), &b), &d) in cur.iter_mut().zip(n1).zip(n2).zip(n3) {
                        *c = (*c - c1 * a - c2 * b - c3 * d) * inv;
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn basis(n: [usize; 3], m: [usize; 3]) -> KroneckerBasis {
        let axis = |a: usize| {
            let du = (n[a] - 1) as f64 / (m[a] - 1) as f64;
            AxisBasis::uniform(0.0, n[a], 0.0, du, m[a])
        };
        KroneckerBasis::new([axis(0), axis(1), axis(2)]).unwrap()
    }

    /// Dense `A` (rows = samples, cols = coefficients), both x fastest.
    fn dense(k: &KroneckerBasis) -> (Vec<f64>, usize, usize) {
        let [nx, ny, nz] = k.cols();
        let [mx, my, mz] = k.rows();
        let (bx, by, bz) = (
            k.axes[0].to_dense(),
            k.axes[1].to_dense(),
            k.axes[2].to_dense(),
        );
        let (rows, cols) = (mx * my * mz, nx * ny * nz);
        let mut a = vec![0.0; rows * cols];
        for r in 0..rows {
            let (rx, ry, rz) = (r % mx, (r / mx) % my, r / (mx * my));
            for c in 0..cols {
                let (cx, cy, cz) = (c % nx, (c / nx) % ny, c / (nx * ny));
                a[r * cols + c] = bx[rx * nx + cx] * by[ry * ny + cy] * bz[rz * nz + cz];
            }
        }
        (a, rows, cols)
    }

    fn pseudo(len: usize, seed: u32) -> Vec<f32> {
        (0..len)
            .map(|i| (((i as u32).wrapping_mul(2654435761) ^ seed) % 1000) as f32 / 500.0 - 1.0)
            .collect()
    }

    #[test]
    fn apply_and_transpose_match_dense_reference() {
        for (n, m) in [
            ([4, 5, 6], [4, 5, 6]),
            ([5, 4, 5], [9, 7, 13]),
            ([6, 5, 4], [11, 9, 7]),
        ] {
            let k = basis(n, m);
            let (a, rows, cols) = dense(&k);
            let mut scratch = KronScratch::for_basis(&k);
            let p = pseudo(cols, 7);
            let mut d = vec![0.0; rows];
            k.apply(&p, &mut d, &mut scratch);
            for r in 0..rows {
                let want: f64 = (0..cols).map(|c| a[r * cols + c] * f64::from(p[c])).sum();
                assert!((f64::from(d[r]) - want).abs() < 1e-5, "A p row {r}");
            }
            let dv = pseudo(rows, 11);
            let mut b = vec![0.0; cols];
            k.apply_transpose(&dv, &mut b, &mut scratch);
            for c in 0..cols {
                let want: f64 = (0..rows).map(|r| a[r * cols + c] * f64::from(dv[r])).sum();
                assert!((f64::from(b[c]) - want).abs() < 1e-4, "Aᵀ d col {c}");
            }
        }
    }

    /// Dense Gaussian elimination with partial pivoting, f64.
    fn dense_solve(mut g: Vec<f64>, mut rhs: Vec<f64>, n: usize) -> Vec<f64> {
        for c in 0..n {
            let piv = (c..n)
                .max_by(|&a, &b| g[a * n + c].abs().total_cmp(&g[b * n + c].abs()))
                .unwrap();
            for j in 0..n {
                g.swap(c * n + j, piv * n + j);
            }
            rhs.swap(c, piv);
            for r in c + 1..n {
                let f = g[r * n + c] / g[c * n + c];
                for j in c..n {
                    g[r * n + j] -= f * g[c * n + j];
                }
                rhs[r] -= f * rhs[c];
            }
        }
        let mut x = vec![0.0; n];
        for r in (0..n).rev() {
            let s: f64 = (r + 1..n).map(|j| g[r * n + j] * x[j]).sum();
            x[r] = (rhs[r] - s) / g[r * n + r];
        }
        x
    }

    #[test]
    fn kronecker_inverse_equals_dense_inverse() {
        for (n, m) in [([4, 5, 4], [4, 5, 4]), ([5, 4, 6], [9, 10, 6])] {
            let k = basis(n, m);
            let (a, rows, cols) = dense(&k);
            let mut g = vec![0.0; cols * cols];
            for r in 0..rows {
                for i in 0..cols {
                    let ai = a[r * cols + i];
                    if ai == 0.0 {
                        continue;
                    }
                    for j in 0..cols {
                        g[i * cols + j] += ai * a[r * cols + j];
                    }
                }
            }
            let b = pseudo(cols, 3);
            let want = dense_solve(g, b.iter().map(|&v| f64::from(v)).collect(), cols);
            let mut x = b.clone();
            k.solve_gram(&mut x);
            let scale = want.iter().fold(0.0_f64, |s, v| s.max(v.abs()));
            for (got, w) in x.iter().zip(&want) {
                assert!(
                    (f64::from(*got) - w).abs() < 1e-4 * scale.max(1.0),
                    "{got} vs {w}"
                );
            }
        }
    }

    #[test]
    fn round_trip_is_well_conditioned_when_samples_equal_coefficients() {
        // Design trap 1: the grid covers every coefficient's node, so BᵀB stays well
        // conditioned even at m = n.
        let k = basis([32, 32, 32], [32, 32, 32]);
        let mut scratch = KronScratch::for_basis(&k);
        let p = pseudo(k.coeff_count(), 5);
        let mut d = vec![0.0; k.sample_count()];
        k.apply(&p, &mut d, &mut scratch);
        let mut back = vec![0.0; k.coeff_count()];
        k.apply_transpose(&d, &mut back, &mut scratch);
        k.solve_gram(&mut back);
        let err = back
            .iter()
            .zip(&p)
            .fold(0.0_f32, |e, (a, b)| e.max((a - b).abs()));
        assert!(err < 1e-4, "round trip error {err}");
    }

    #[test]
    fn fused_projection_and_solve_match_the_line_by_line_reference() {
        for (n, m) in [
            ([4, 5, 6], [4, 5, 6]),
            ([9, 12, 5], [17, 12, 9]),
            ([15, 15, 15], [15, 15, 15]),
        ] {
            let k = basis(n, m);
            let mut scratch = KronScratch::for_basis(&k);
            let d = pseudo(k.sample_count(), 13);
            let mut reference = vec![0.0; k.coeff_count()];
            k.apply_transpose(&d, &mut reference, &mut scratch);
            let rhs = reference.clone();
            k.solve_gram_line_by_line(&mut reference);
            let scale = reference.iter().fold(0.0_f32, |s, v| s.max(v.abs()));
            let mut fused = vec![0.0; k.coeff_count()];
            k.project(&d, &mut fused, 0.5, &mut scratch);
            let mut solved = vec![0.0; k.coeff_count()];
            k.solve_gram_into(&rhs, &mut solved, &mut scratch);
            for ((f, s), r) in fused.iter().zip(&solved).zip(&reference) {
                assert!((f - 0.5 * r).abs() <= 1e-5 * scale, "{f} vs {}", 0.5 * r);
                assert!((s - r).abs() <= 1e-5 * scale, "{s} vs {r}");
            }
        }
    }
}
