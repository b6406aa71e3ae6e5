//! One point's local distance field (Guo & Qin §3, eqs. 2–4): a trivariate B-spline with
//! 3×3×3 scalar coefficients over an axis-aligned cube around the point.
//!
//! Choices where the paper is vague:
//! - **Basis.** With three coefficients per axis the B-spline is the quadratic one on a single
//!   span with clamped knots (the Bernstein basis `(1−u)², 2u(1−u), u²`). It reproduces every
//!   quadratic exactly, so a plane's signed distance is exact and a sphere's is close.
//! - **Domain.** A cube centred on the point whose half edge encloses its `k` nearest
//!   neighbours (the paper's "size chosen to enclose all the k-nearest neighbours").
//! - **Fit (eq. 2's weighted least squares).** Every neighbour `p_j` (the point itself
//!   included) gives three samples: `0` at `p_j`, `+ε` at `p_j − ε n_j` (inside) and `−ε` at
//!   `p_j + ε n_j` (outside), each weighted by `θ(‖p_j − p_i‖) = exp(−‖p_j − p_i‖²/h²)` with
//!   `h` the cloud's spacing (the paper's anticipated spacing). Three layers of samples on one
//!   sheet leave the tangential curvature of the field free where neighbours are few, so a
//!   small ridge term pulls each coefficient toward the point's tangent-plane distance (the
//!   coefficients of a linear function are its values at the Greville points `u ∈ {0, ½, 1}`).
//! - **Eq. (4).** The fixed local grid `G` is the 3×3×3 Greville grid, so `B ⊗ C ⊗ D` is
//!   square and `p = (B⁻¹ ⊗ B⁻¹ ⊗ B⁻¹) d`: three tiny axis passes, no least squares needed.
//!
//! Signs follow the paper and the mesher: positive inside, negative outside, zero on the
//! surface; the outward normal is `−∇s/‖∇s‖`.

// NOTE: index loops over the 3×3×3 stencil and parallel per-point arrays read clearer than
// zipped iterators here.
#![allow(clippy::needless_range_loop)]

use glam::Vec3;

/// Coefficients per axis of a local field.
pub const LOCAL_DIM: usize = 3;
/// Coefficients (and grid nodes) of a local field.
pub const LOCAL_COUNT: usize = LOCAL_DIM * LOCAL_DIM * LOCAL_DIM;

/// `B⁻¹` for the quadratic Bernstein basis sampled at `u = 0, ½, 1`: rows give a coefficient
/// from the three node values (`p0 = d0`, `p1 = 2 d½ − (d0 + d1)/2`, `p2 = d1`).
const B_INV: [[f32; 3]; 3] = [[1.0, 0.0, 0.0], [-0.5, 2.0, -0.5], [0.0, 0.0, 1.0]];

/// A local trivariate field over the cube `centre ± half_fu` (half edge `half_fu`, world units).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LocalField {
    /// Centre of the local domain.
    pub centre: Vec3,
    /// Half edge of the cube, world units.
    pub half_fu: f32,
    /// Coefficients, `i + 3 j + 9 k` (x fastest).
    pub coeffs: [f32; LOCAL_COUNT],
}

/// The three quadratic Bernstein weights at `u` and their derivatives in `u`.
#[inline]
fn weights(u: f32) -> ([f32; 3], [f32; 3]) {
    let v = 1.0 - u;
    (
        [v * v, 2.0 * u * v, u * u],
        [-2.0 * v, 2.0 - 4.0 * u, 2.0 * u],
    )
}

impl LocalField {
    /// A field whose coefficients are all zero.
    #[must_use]
    pub fn zero(centre: Vec3, half_fu: f32) -> Self {
        Self {
            centre,
            half_fu,
            coeffs: [0.0; LOCAL_COUNT],
        }
    }

    /// Parameter coordinates (`[0, 1]³` inside the domain) of a world point.
    #[inline]
    #[must_use]
    pub fn to_param(&self, x: Vec3) -> Vec3 {
        (x - self.centre) / (2.0 * self.half_fu) + Vec3::splat(0.5)
    }

    /// World position of grid node `(i, j, k)`, each in `0..3` (the Greville points).
    #[inline]
    #[must_use]
    pub fn node(&self, i: usize, j: usize, k: usize) -> Vec3 {
        let t = |n: usize| (n as f32 - 1.0) * self.half_fu;
        self.centre + Vec3::new(t(i), t(j), t(k))
    }

    /// The 27 node positions, `i + 3 j + 9 k`.
    #[must_use]
    pub fn nodes(&self) -> [Vec3; LOCAL_COUNT] {
        let mut out = [Vec3::ZERO; LOCAL_COUNT];
        for (n, o) in out.iter_mut().enumerate() {
            *o = self.node(n % 3, (n / 3) % 3, n / 9);
        }
        out
    }

    /// Field value at a world point (polynomial extrapolation outside the cube).
    #[inline]
    #[must_use]
    pub fn value(&self, x: Vec3) -> f32 {
        let u = self.to_param(x);
        let (wx, _) = weights(u.x);
        let (wy, _) = weights(u.y);
        let (wz, _) = weights(u.z);
        let mut s = 0.0;
        for k in 0..3 {
            let mut sy = 0.0;
            for j in 0..3 {
                let row = &self.coeffs[3 * j + 9 * k..3 * j + 9 * k + 3];
                sy += wy[j] * (wx[0] * row[0] + wx[1] * row[1] + wx[2] * row[2]);
            }
            s += wz[k] * sy;
        }
        s
    }

    /// Value and world-space gradient at a world point.
    #[inline]
    #[must_use]
    pub fn value_and_gradient(&self, x: Vec3) -> (f32, Vec3) {
        let u = self.to_param(x);
        let (wx, dx) = weights(u.x);
        let (wy, dy) = weights(u.y);
        let (wz, dz) = weights(u.z);
        let (mut s, mut g) = (0.0, Vec3::ZERO);
        for k in 0..3 {
            for j in 0..3 {
                let row = &self.coeffs[3 * j + 9 * k..3 * j + 9 * k + 3];
                let a = wx[0] * row[0] + wx[1] * row[1] + wx[2] * row[2];
                let da = dx[0] * row[0] + dx[1] * row[1] + dx[2] * row[2];
                s += wz[k] * wy[j] * a;
                g.x += wz[k] * wy[j] * da;
                g.y += wz[k] * dy[j] * a;
                g.z += dz[k] * wy[j] * a;
            }
        }
        (s, g / (2.0 * self.half_fu))
    }

    /// Eq. (4) on the Greville grid: the coefficients whose field takes the values `d` at the
    /// 27 nodes (`i + 3 j + 9 k`). Exact, allocation-free: three axis passes of `B⁻¹`.
    #[must_use]
    pub fn coeffs_from_nodes(d: &[f32; LOCAL_COUNT]) -> [f32; LOCAL_COUNT] {
        let mut a = *d;
        let mut b = [0.0; LOCAL_COUNT];
        for (axis, stride) in [1usize, 3, 9].into_iter().enumerate() {
            let (src, dst) = if axis % 2 == 0 {
                (&a, &mut b)
            } else {
                (&b, &mut a)
            };
            for n in 0..LOCAL_COUNT {
                let pos = (n / stride) % 3;
                let base = n - pos * stride;
                let r = &B_INV[pos];
                dst[n] =
                    r[0] * src[base] + r[1] * src[base + stride] + r[2] * src[base + 2 * stride];
            }
        }
        // Three passes: a → b → a → b.
        b
    }

    /// The field's values at its own 27 nodes (the inverse of [`LocalField::coeffs_from_nodes`]).
    #[must_use]
    pub fn node_values(&self) -> [f32; LOCAL_COUNT] {
        let nodes = self.nodes();
        let mut out = [0.0; LOCAL_COUNT];
        for (o, x) in out.iter_mut().zip(nodes) {
            *o = self.value(x);
        }
        out
    }

    /// The same surface over a new domain: this field sampled at the new cube's nodes and
    /// refitted there (eq. 4). Exact, since the basis reproduces quadratics.
    #[must_use]
    pub fn recentred(&self, centre: Vec3, half_fu: f32) -> Self {
        let mut out = Self::zero(centre, half_fu);
        let nodes = out.nodes();
        let mut d = [0.0; LOCAL_COUNT];
        for (v, x) in d.iter_mut().zip(nodes) {
            *v = self.value(x);
        }
        out.coeffs = Self::coeffs_from_nodes(&d);
        out
    }
}

/// One sample of the weighted least-squares fit: a position, its target distance and weight.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FitSample {
    pub position: Vec3,
    pub distance: f32,
    pub weight: f32,
}

/// Working memory of [`fit_local`], kept by the caller so repeated fits allocate nothing.
///
/// The fit never forms a 27-wide rank-one update per sample. With the quadratic Bernstein
/// basis, a product of two basis functions on one axis is a scaled quartic monomial,
/// `b_i(u) b_i'(u) = c_i c_i' u^(i+i') (1−u)^(4−i−i')` with `c = (1, 2, 1)`, so every entry of
/// the 27×27 normal matrix is `c_n c_n' M[i+i', j+j', k+k']` where `M` holds the 5×5×5
/// weighted moments `Σ w x^a y^b z^c` (in those monomials) of the samples: 125 products per
/// sample instead of 729, and the matrix is assembled once per point.
#[derive(Clone, Debug)]
pub struct FitScratch {
    /// The weighted moments, `a + 5 b + 25 c`.
    moments: [f32; 125],
    /// The normal matrix (lower triangle used), row-major, overwritten by its Cholesky factor.
    solve: [f64; LOCAL_COUNT * LOCAL_COUNT],
}

impl Default for FitScratch {
    fn default() -> Self {
        Self {
            moments: [0.0; 125],
            solve: [0.0; LOCAL_COUNT * LOCAL_COUNT],
        }
    }
}

/// The quartic monomials `u^a (1−u)^(4−a)`, `a = 0..5`, and the quadratic ones
/// `u^i (1−u)^(2−i)`, `i = 0..3` (the Bernstein weights without their binomials).
#[inline]
fn monomials(u: f32) -> ([f32; 5], [f32; 3]) {
    let v = 1.0 - u;
    let (u2, v2, uv) = (u * u, v * v, u * v);
    ([v2 * v2, uv * v2, uv * uv, uv * u2, u2 * u2], [v2, uv, u2])
}

/// Binomials of the quadratic Bernstein basis.
const BINOMIAL2: [f32; 3] = [1.0, 2.0, 1.0];

/// Eq. (2)'s weighted least squares: the coefficients over `centre ± half_fu` minimising
/// `Σ w (s(x) − d)²  +  ridge · Σ_c (p_c − plane(g_c))²`, where `plane(x) = −n·(x − point)` is
/// the tangent-plane distance (positive inside) and `g_c` the Greville node of coefficient
/// `c`. `ridge` is relative to the total sample weight. Returns `None` when the system is not
/// positive definite (no samples and no ridge) or a value is not finite. Allocates nothing.
#[must_use]
pub fn fit_local(
    centre: Vec3,
    half_fu: f32,
    point: Vec3,
    normal: Vec3,
    samples: &[FitSample],
    ridge: f32,
    scratch: &mut FitScratch,
) -> Option<LocalField> {
    let mut field = LocalField::zero(centre, half_fu);
    let m = &mut scratch.moments;
    *m = [0.0; 125];
    // Right-hand side without the binomials (`Σ w d u^i.. v^j.. w^k..`), `i + 3 j + 9 k`.
    let mut rhs = [0.0f32; LOCAL_COUNT];
    let mut total = 0.0_f32;
    for s in samples {
        let u = field.to_param(s.position);
        let (mx, qx) = monomials(u.x);
        let (my, qy) = monomials(u.y);
        let (mz, qz) = monomials(u.z);
        let w = s.weight;
        total += w;
        for c in 0..5 {
            let wz = w * mz[c];
            for b in 0..5 {
                let t = wz * my[b];
                let line = &mut m[5 * b + 25 * c..5 * b + 25 * c + 5];
                for a in 0..5 {
                    line[a] += t * mx[a];
                }
            }
        }
        if s.distance != 0.0 {
            let wd = w * s.distance;
            for k in 0..3 {
                let tz = wd * qz[k];
                for j in 0..3 {
                    let t = tz * qy[j];
                    for i in 0..3 {
                        rhs[i + 3 * j + 9 * k] += t * qx[i];
                    }
                }
            }
        }
    }
    let lambda = f64::from(ridge) * f64::from(total).max(1e-12);
    // Binomial scale of each coefficient, and its stencil position.
    let mut scale = [0.0f32; LOCAL_COUNT];
    let mut at = [[0usize; 3]; LOCAL_COUNT];
    for n in 0..LOCAL_COUNT {
        let (i, j, k) = (n % 3, (n / 3) % 3, n / 9);
        scale[n] = BINOMIAL2[i] * BINOMIAL2[j] * BINOMIAL2[k];
        at[n] = [i, j, k];
    }
    let a = &mut scratch.solve;
    let mut b = [0.0f64; LOCAL_COUNT];
    for r in 0..LOCAL_COUNT {
        let [ri, rj, rk] = at[r];
        for c in 0..=r {
            let [ci, cj, ck] = at[c];
            let moment = m[(ri + ci) + 5 * (rj + cj) + 25 * (rk + ck)];
            a[r * LOCAL_COUNT + c] = f64::from(scale[r] * scale[c] * moment);
        }
        b[r] = f64::from(scale[r] * rhs[r]);
    }
    for (c, g) in field.nodes().iter().enumerate() {
        let plane = -normal.dot(*g - point);
        a[c * LOCAL_COUNT + c] += lambda;
        b[c] += lambda * f64::from(plane);
    }
    let x = cholesky_solve(a, &b)?;
    for (p, v) in field.coeffs.iter_mut().zip(x) {
        *p = v as f32;
    }
    field.coeffs.iter().all(|v| v.is_finite()).then_some(field)
}

/// Solves `A x = b` for a symmetric positive definite 27×27 `A` (row-major, lower triangle
/// read, overwritten by its Cholesky factor). `None` when `A` is not positive definite.
fn cholesky_solve(
    a: &mut [f64; LOCAL_COUNT * LOCAL_COUNT],
    b: &[f64; LOCAL_COUNT],
) -> Option<[f64; LOCAL_COUNT]> {
    const N: usize = LOCAL_COUNT;
    let mut inv_diag = [0.0f64; N];
    for j in 0..N {
        let (head, tail) = a.split_at_mut(j * N + N);
        let row_j = &mut head[j * N..j * N + N];
        let d = row_j[j] - row_j[..j].iter().map(|v| v * v).sum::<f64>();
        if !(d > 0.0 && d.is_finite()) {
            return None;
        }
        let d = d.sqrt();
        row_j[j] = d;
        let inv = 1.0 / d;
        inv_diag[j] = inv;
        let row_j = &head[j * N..j * N + j];
        for row_i in tail.chunks_exact_mut(N) {
            let s: f64 = row_i[..j].iter().zip(row_j).map(|(x, y)| x * y).sum();
            row_i[j] = (row_i[j] - s) * inv;
        }
    }
    let mut y = *b;
    for i in 0..N {
        let row = &a[i * N..i * N + i];
        let s: f64 = row.iter().zip(&y[..i]).map(|(x, v)| x * v).sum();
        y[i] = (y[i] - s) * inv_diag[i];
    }
    for i in (0..N).rev() {
        let mut s = y[i];
        for k in i + 1..N {
            s -= a[k * N + i] * y[k];
        }
        y[i] = s * inv_diag[i];
    }
    Some(y)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plane_samples(n: Vec3, p0: Vec3, spread: f32, eps: f32) -> Vec<FitSample> {
        let t = n.any_orthonormal_vector();
        let b = n.cross(t);
        let mut out = Vec::new();
        for a in -2..=2 {
            for c in -2..=2 {
                let p = p0 + spread * (a as f32 * t + c as f32 * b);
                for (off, d) in [(0.0, 0.0), (eps, -eps), (-eps, eps)] {
                    out.push(FitSample {
                        position: p + off * n,
                        distance: d,
                        weight: 1.0,
                    });
                }
            }
        }
        out
    }

    #[test]
    fn node_values_round_trip_through_eq4() {
        let mut f = LocalField::zero(Vec3::new(0.3, -0.2, 1.0), 0.25);
        for (n, c) in f.coeffs.iter_mut().enumerate() {
            *c = ((n * 7) % 11) as f32 * 0.1 - 0.5;
        }
        let back = LocalField::coeffs_from_nodes(&f.node_values());
        for (a, b) in back.iter().zip(f.coeffs) {
            assert!((a - b).abs() < 1e-5, "{a} vs {b}");
        }
    }

    #[test]
    fn a_plane_is_fitted_exactly_and_its_gradient_is_the_inward_normal() {
        let n = Vec3::new(1.0, 2.0, -0.5).normalize();
        let p0 = Vec3::new(0.1, 0.2, 0.3);
        let samples = plane_samples(n, p0, 0.05, 0.05);
        let f = fit_local(p0, 0.15, p0, n, &samples, 1e-3, &mut FitScratch::default()).unwrap();
        for x in [p0, p0 + 0.1 * n, p0 - 0.07 * n.any_orthonormal_vector()] {
            let (s, g) = f.value_and_gradient(x);
            assert!((s - (-n.dot(x - p0))).abs() < 1e-4, "value {s}");
            assert!((g + n).length() < 1e-3, "gradient {g}");
        }
    }

    /// The moment-assembled fit against the direct one: the 27×27 normal equations built from
    /// rank-one updates of the basis row and solved by Gaussian elimination in `f64`.
    #[test]
    fn moment_assembly_matches_the_direct_normal_equations() {
        let n = Vec3::new(0.3, -0.4, 0.8).normalize();
        let p0 = Vec3::new(0.02, -0.01, 0.03);
        let mut samples = plane_samples(n, p0, 0.04, 0.03);
        for (m, s) in samples.iter_mut().enumerate() {
            // A curved target and uneven weights, so every moment matters.
            s.distance += 0.3 * (s.position - p0).length_squared();
            s.weight = 0.2 + (m % 7) as f32 * 0.13;
        }
        let (centre, half, ridge) = (p0 + Vec3::new(0.01, 0.0, -0.02), 0.12, 1e-3);
        let got = fit_local(
            centre,
            half,
            p0,
            n,
            &samples,
            ridge,
            &mut FitScratch::default(),
        )
        .unwrap();
        let field = LocalField::zero(centre, half);
        let mut a = vec![vec![0.0f64; LOCAL_COUNT + 1]; LOCAL_COUNT];
        let mut total = 0.0;
        for s in &samples {
            let u = field.to_param(s.position);
            let (wx, wy, wz) = (weights(u.x).0, weights(u.y).0, weights(u.z).0);
            let row: Vec<f64> = (0..LOCAL_COUNT)
                .map(|c| f64::from(wx[c % 3] * wy[(c / 3) % 3] * wz[c / 9]))
                .collect();
            let w = f64::from(s.weight);
            total += w;
            for r in 0..LOCAL_COUNT {
                for c in 0..LOCAL_COUNT {
                    a[r][c] += w * row[r] * row[c];
                }
                a[r][LOCAL_COUNT] += w * f64::from(s.distance) * row[r];
            }
        }
        let lambda = f64::from(ridge) * total;
        for (c, g) in field.nodes().iter().enumerate() {
            a[c][c] += lambda;
            a[c][LOCAL_COUNT] += lambda * f64::from(-n.dot(*g - p0));
        }
        for col in 0..LOCAL_COUNT {
            let piv = (col..LOCAL_COUNT)
                .max_by(|&x, &y| a[x][col].abs().total_cmp(&a[y][col].abs()))
                .unwrap();
            a.swap(col, piv);
            for r in 0..LOCAL_COUNT {
                if r != col {
                    let f = a[r][col] / a[col][col];
                    for c in col..=LOCAL_COUNT {
                        a[r][c] -= f * a[col][c];
                    }
                }
            }
        }
        for (c, v) in got.coeffs.iter().enumerate() {
            let want = a[c][LOCAL_COUNT] / a[c][c];
            assert!(
                (f64::from(*v) - want).abs() < 1e-3,
                "coefficient {c}: {v} vs {want}"
            );
        }
    }

    #[test]
    fn recentring_keeps_a_quadratic_field() {
        let mut f = LocalField::zero(Vec3::ZERO, 0.2);
        let nodes = f.nodes();
        let mut d = [0.0; LOCAL_COUNT];
        for (v, x) in d.iter_mut().zip(nodes) {
            *v = 0.3 - x.length_squared();
        }
        f.coeffs = LocalField::coeffs_from_nodes(&d);
        let g = f.recentred(Vec3::new(0.05, 0.02, -0.03), 0.25);
        for x in [Vec3::ZERO, Vec3::new(0.1, -0.1, 0.05)] {
            assert!((g.value(x) - (0.3 - x.length_squared())).abs() < 1e-5);
        }
    }
}
