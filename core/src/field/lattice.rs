//! A single B-spline patch: an `nx × ny × nz` lattice of control coefficients.

use glam::{Vec3, Vec4};

use super::basis::{cubic_weights, cubic_weights_and_derivatives};
use super::bricks::BrickedCoeffs;

/// Why a lattice could not be built.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum LatticeError {
    /// A dimension was below 4 (a cubic needs four coefficients per axis).
    #[error("lattice {dims:?} is too small: each axis needs at least 4 coefficients")]
    TooSmall { dims: [usize; 3] },
    /// The knot spacing was not a positive finite number.
    #[error("knot spacing {spacing} must be positive and finite")]
    BadSpacing { spacing: f32 },
    /// The coefficient vector's length does not match the dimensions.
    #[error("expected {expected} coefficients, got {got}")]
    WrongLength { expected: usize, got: usize },
}

/// A uniform cubic B-spline field `s(x) = Σ p_ijk B_i(x) B_j(y) B_k(z)`.
///
/// Coefficient `(i, j, k)` is centred on the lattice point `origin + spacing · (i, j, k)` and
/// addressed as `i + nx · (j + ny · k)` (x fastest), in 8×8×8 bricks of which only those
/// holding more than one value cost memory ([`BrickedCoeffs`]). Coefficients beyond the lattice count as
/// zero, so the field fades to zero (empty space) outside it. Where all four coefficients per
/// axis exist — lattice coordinates in `[1, n − 2]` — the basis is a partition of unity and
/// linear functions are reproduced exactly; that box is [`BSplineLattice::exact_domain`].
///
/// The solid is where the value is greater than the iso-level `iso` (the paper's `c0`).
#[derive(Clone, Debug, PartialEq)]
pub struct BSplineLattice {
    pub dims: [usize; 3],
    pub spacing: f32,
    pub origin: Vec3,
    pub iso: f32,
    pub coeffs: BrickedCoeffs,
}

impl BSplineLattice {
    /// Default iso-level: the field is a clamped density in `[0, 1]` with the surface at one half.
    pub const DEFAULT_ISO: f32 = 0.5;

    /// A lattice with every coefficient zero.
    ///
    /// # Errors
    /// When an axis has fewer than 4 coefficients or the spacing is not positive and finite.
    pub fn zeros(dims: [usize; 3], spacing: f32, origin: Vec3) -> Result<Self, LatticeError> {
        Self::check(dims, spacing)?;
        Ok(Self {
            dims,
            spacing,
            origin,
            iso: Self::DEFAULT_ISO,
            coeffs: BrickedCoeffs::zeros(dims),
        })
    }

    fn check(dims: [usize; 3], spacing: f32) -> Result<(), LatticeError> {
        if dims.iter().any(|&n| n < 4) {
            return Err(LatticeError::TooSmall { dims });
        }
        if !(spacing.is_finite() && spacing > 0.0) {
            return Err(LatticeError::BadSpacing { spacing });
        }
        if dims
            .iter()
            .try_fold(1_usize, |acc, &n| acc.checked_mul(n))
            .is_none()
        {
            return Err(LatticeError::WrongLength {
                expected: usize::MAX,
                got: 0,
            });
        }
        Ok(())
    }

    /// A lattice over the given coefficients (x fastest).
    ///
    /// # Errors
    /// As [`BSplineLattice::zeros`], and when `coeffs` has the wrong length.
    pub fn from_coeffs(
        dims: [usize; 3],
        spacing: f32,
        origin: Vec3,
        coeffs: Vec<f32>,
    ) -> Result<Self, LatticeError> {
        Self::check(dims, spacing)?;
        let expected = dims[0] * dims[1] * dims[2];
        if coeffs.len() != expected {
            return Err(LatticeError::WrongLength {
                expected,
                got: coeffs.len(),
            });
        }
        Ok(Self {
            dims,
            spacing,
            origin,
            iso: Self::DEFAULT_ISO,
            coeffs: BrickedCoeffs::from_slice(dims, &coeffs),
        })
    }

    /// This lattice with `low[a]` zero coefficients added before and `high[a]` after it along
    /// each axis `a`, its origin moved so that every kept coefficient stays on its world node.
    /// The field is unchanged everywhere (coefficients beyond a lattice count as zero) up to
    /// the rounding of the moved origin; only its extent grows.
    ///
    /// # Errors
    /// [`LatticeError::WrongLength`] when the grown lattice's size overflows `usize`.
    pub fn padded(&self, low: [usize; 3], high: [usize; 3]) -> Result<Self, LatticeError> {
        let dims: [usize; 3] =
            std::array::from_fn(|a| self.dims[a].saturating_add(low[a]).saturating_add(high[a]));
        dims.iter()
            .try_fold(1_usize, |acc, &n| acc.checked_mul(n))
            .ok_or(LatticeError::WrongLength {
                expected: usize::MAX,
                got: self.coeffs.len(),
            })?;
        // Whole bricks of padding move the bricks as they are; the new room is uniform zero.
        let coeffs = self.coeffs.padded(low, high);
        let shift = Vec3::new(low[0] as f32, low[1] as f32, low[2] as f32);
        Ok(Self {
            dims,
            spacing: self.spacing,
            origin: self.origin - self.spacing * shift,
            iso: self.iso,
            coeffs,
        })
    }

    /// Linear index of coefficient `(i, j, k)`.
    #[inline]
    #[must_use]
    pub fn index(&self, i: usize, j: usize, k: usize) -> usize {
        i + self.dims[0] * (j + self.dims[1] * k)
    }

    /// World position of the lattice point on which coefficient `(i, j, k)` is centred.
    #[inline]
    #[must_use]
    pub fn node_position(&self, i: usize, j: usize, k: usize) -> Vec3 {
        self.origin + self.spacing * Vec3::new(i as f32, j as f32, k as f32)
    }

    /// Lattice coordinates (in knot spans) of a world point.
    #[inline]
    #[must_use]
    pub fn to_lattice(&self, x: Vec3) -> Vec3 {
        (x - self.origin) / self.spacing
    }

    /// The box (min, max corners) where linear functions are reproduced exactly.
    #[must_use]
    pub fn exact_domain(&self) -> (Vec3, Vec3) {
        let n = Vec3::new(
            self.dims[0] as f32,
            self.dims[1] as f32,
            self.dims[2] as f32,
        );
        (
            self.origin + Vec3::splat(self.spacing),
            self.origin + (n - 2.0) * self.spacing,
        )
    }

    /// The box (min, max corners) outside which the field is exactly zero.
    #[must_use]
    pub fn support(&self) -> (Vec3, Vec3) {
        let n = Vec3::new(
            self.dims[0] as f32,
            self.dims[1] as f32,
            self.dims[2] as f32,
        );
        (
            self.origin - Vec3::splat(2.0 * self.spacing),
            self.origin + (n + 1.0) * self.spacing,
        )
    }

    /// Value of the field at a world point.
    #[inline]
    #[allow(clippy::needless_range_loop)] // taps index three weight arrays and the stencil
    #[must_use]
    pub fn value(&self, x: Vec3) -> f32 {
        let Some(stencil) = self.stencil(x) else {
            return 0.0;
        };
        let wx = cubic_weights(stencil.t.x);
        let wy = cubic_weights(stencil.t.y);
        let wz = cubic_weights(stencil.t.z);
        if let Some(base) = self.interior_base(&stencil) {
            // Fast path: all 64 coefficients exist, no per-tap range checks. Rows along x are
            // summed as 4-wide vectors and dotted with the x weights once at the end.
            return self.row_sums(base, &wy, &wz).dot(Vec4::from_array(wx));
        }
        let mut sum = 0.0;
        for c in 0..4 {
            let Some(k) = stencil.axis(2, c, self.dims[2]) else {
                continue;
            };
            let mut plane = 0.0;
            for b in 0..4 {
                let Some(j) = stencil.axis(1, b, self.dims[1]) else {
                    continue;
                };
                let mut line = 0.0;
                for a in 0..4 {
                    if let Some(i) = stencil.axis(0, a, self.dims[0]) {
                        line += wx[a] * self.coeffs.get(i, j, k);
                    }
                }
                plane += wy[b] * line;
            }
            sum += wz[c] * plane;
        }
        sum
    }

    /// Value and analytic gradient (per world unit) at a world point.
    #[inline]
    #[must_use]
    pub fn value_and_gradient(&self, x: Vec3) -> (f32, Vec3) {
        let Some(stencil) = self.stencil(x) else {
            return (0.0, Vec3::ZERO);
        };
        let (wx, dx) = cubic_weights_and_derivatives(stencil.t.x);
        let (wy, dy) = cubic_weights_and_derivatives(stencil.t.y);
        let (wz, dz) = cubic_weights_and_derivatives(stencil.t.z);
        if let Some(base) = self.interior_base(&stencil) {
            // Fast path: all 64 coefficients exist, no per-tap range checks. Rows along x are
            // summed as 4-wide vectors with the y/z weights (three sums share the rows) and
            // dotted with the x weights or their derivatives once at the end.
            let rows = self.coeffs.stencil_rows(base);
            let (mut s, mut sdy, mut sdz) = (Vec4::ZERO, Vec4::ZERO, Vec4::ZERO);
            for c in 0..4 {
                let (mut plane, mut plane_dy) = (Vec4::ZERO, Vec4::ZERO);
                for b in 0..4 {
                    let row = rows[b + 4 * c];
                    plane += wy[b] * row;
                    plane_dy += dy[b] * row;
                }
                s += wz[c] * plane;
                sdy += wz[c] * plane_dy;
                sdz += dz[c] * plane;
            }
            let (wx, dx) = (Vec4::from_array(wx), Vec4::from_array(dx));
            let g = Vec3::new(s.dot(dx), sdy.dot(wx), sdz.dot(wx));
            return (s.dot(wx), g / self.spacing);
        }
        let (mut v, mut gx, mut gy, mut gz) = (0.0, 0.0, 0.0, 0.0);
        for c in 0..4 {
            let Some(k) = stencil.axis(2, c, self.dims[2]) else {
                continue;
            };
            let (mut pv, mut pgx, mut pgy) = (0.0, 0.0, 0.0);
            for b in 0..4 {
                let Some(j) = stencil.axis(1, b, self.dims[1]) else {
                    continue;
                };
                let (mut lv, mut lg) = (0.0, 0.0);
                for a in 0..4 {
                    if let Some(i) = stencil.axis(0, a, self.dims[0]) {
                        let p = self.coeffs.get(i, j, k);
                        lv += wx[a] * p;
                        lg += dx[a] * p;
                    }
                }
                pv += wy[b] * lv;
                pgx += wy[b] * lg;
                pgy += dy[b] * lv;
            }
            v += wz[c] * pv;
            gx += wz[c] * pgx;
            gy += wz[c] * pgy;
            gz += dz[c] * pv;
        }
        (v, Vec3::new(gx, gy, gz) / self.spacing)
    }

    /// Analytic gradient (per world unit) at a world point.
    #[inline]
    #[must_use]
    pub fn gradient(&self, x: Vec3) -> Vec3 {
        self.value_and_gradient(x).1
    }

    /// Values at many points, written into `out` (which must be as long as `points`).
    ///
    /// # Panics
    /// When `out.len() != points.len()`.
    pub fn values_into(&self, points: &[Vec3], out: &mut [f32]) {
        assert_eq!(points.len(), out.len(), "one output per point");
        for (x, o) in points.iter().zip(out.iter_mut()) {
            *o = self.value(*x);
        }
    }

    /// Values at every point of the grid `xs × ys × zs` (world coordinates along each axis),
    /// written into `out` with x fastest: `out[i + xs.len() * (j + ys.len() * k)]` is, bit for
    /// bit, [`BSplineLattice::value`] at `(xs[i], ys[j], zs[k])`.
    ///
    /// Separable: the weights are computed once per coordinate of each axis; for each y
    /// coordinate and run of x coordinates in one knot span, the four rows of each z-plane of
    /// a stencil are summed with the y weights once per run of z coordinates in one knot span,
    /// and those planes with the z weights once per z coordinate (then each point is one 4-wide
    /// dot product), where [`BSplineLattice::value`] does the whole sum per point. The sums
    /// are the ones `value` makes, in its order, so the bits are the same. Points whose
    /// stencil reaches past the lattice's border are evaluated one by one.
    ///
    /// # Panics
    /// When `out.len() != xs.len() * ys.len() * zs.len()`.
    // NOTE: the planes were summed again for every z coordinate (per point row) before; at the
    // window's 4 cells per knot span a plane serves four z coordinates of the finest patch and
    // up to 32 of the base's (`bench/profile_adaptive.rs` `3000 local 4 cut`, the region's
    // block).
    pub fn values_on_grid(&self, xs: &[f32], ys: &[f32], zs: &[f32], out: &mut [f32]) {
        assert_eq!(
            out.len(),
            xs.len() * ys.len() * zs.len(),
            "one output per grid point"
        );
        // Per coordinate: the first coefficient of its stencil where all four lie inside the
        // lattice (as `stencil` and `interior_base` find it), and its weights.
        let taps = |coords: &[f32], axis: usize| -> Vec<(Option<usize>, [f32; 4])> {
            coords
                .iter()
                .map(|&x| {
                    let u = (x - self.origin[axis]) / self.spacing;
                    let base = u.floor();
                    let first = base as i64 - 1;
                    let inside = u.is_finite() && first >= 0 && first + 3 < self.dims[axis] as i64;
                    (inside.then_some(first as usize), cubic_weights(u - base))
                })
                .collect()
        };
        let (tx, ty, tz) = (taps(xs, 0), taps(ys, 1), taps(zs, 2));
        let (nx, ny) = (xs.len(), ys.len());
        let one_by_one = |out: &mut [f32], i: usize, j: usize, k: usize| {
            out[i + nx * (j + ny * k)] = self.value(Vec3::new(xs[i], ys[j], zs[k]));
        };
        for (j, &(fy, wy)) in ty.iter().enumerate() {
            let mut i = 0;
            while i < nx {
                // The run of x coordinates from `i` that share one stencil along x.
                let fx = tx[i].0;
                let end = i + tx[i..].iter().take_while(|t| t.0 == fx).count();
                let (Some(fx), Some(fy)) = (fx, fy) else {
                    for k in 0..zs.len() {
                        (i..end).for_each(|i| one_by_one(out, i, j, k));
                    }
                    i = end;
                    continue;
                };
                // The four planes of the last z stencil, each its rows summed with `wy`.
                let mut last: Option<(usize, [Vec4; 4])> = None;
                for (k, &(fz, wz)) in tz.iter().enumerate() {
                    let Some(fz) = fz else {
                        (i..end).for_each(|i| one_by_one(out, i, j, k));
                        continue;
                    };
                    let planes = match last {
                        Some((first, planes)) if first == fz => planes,
                        _ => {
                            let planes = self.plane_sums([fx, fy, fz], &wy);
                            last = Some((fz, planes));
                            planes
                        }
                    };
                    let sum = Self::planes_sum(&planes, &wz);
                    let row = nx * (j + ny * k);
                    for (o, (_, wx)) in out[row + i..row + end].iter_mut().zip(&tx[i..end]) {
                        *o = sum.dot(Vec4::from_array(*wx));
                    }
                }
                i = end;
            }
        }
    }

    /// The 4×4×4 coefficients from coefficient `first`, each of their four z-planes summed
    /// along y with the weights `wy`: per plane four sums along x, one per x tap (the first
    /// half of [`BSplineLattice::row_sums`], in its order).
    #[inline]
    fn plane_sums(&self, first: [usize; 3], wy: &[f32; 4]) -> [Vec4; 4] {
        let rows = self.coeffs.stencil_rows(first);
        std::array::from_fn(|c| {
            let mut plane = Vec4::ZERO;
            for (b, &wyb) in wy.iter().enumerate() {
                plane += wyb * rows[b + 4 * c];
            }
            plane
        })
    }

    /// The planes of [`BSplineLattice::plane_sums`] summed along z with the weights `wz` (the
    /// second half of [`BSplineLattice::row_sums`], in its order).
    #[inline]
    fn planes_sum(planes: &[Vec4; 4], wz: &[f32; 4]) -> Vec4 {
        let mut sum = Vec4::ZERO;
        for (plane, &wzc) in planes.iter().zip(wz) {
            sum += wzc * *plane;
        }
        sum
    }

    /// The 4×4×4 coefficients from coefficient `first` summed along z and y with the weights
    /// `wz` and `wy`: four sums along x, one per x tap (the fast path of
    /// [`BSplineLattice::value`], made of the halves [`BSplineLattice::values_on_grid`] uses
    /// so that both give the same bits).
    #[inline]
    fn row_sums(&self, first: [usize; 3], wy: &[f32; 4], wz: &[f32; 4]) -> Vec4 {
        Self::planes_sum(&self.plane_sums(first, wy), wz)
    }

    /// Values and gradients at many points, written into `values` and `gradients`.
    ///
    /// # Panics
    /// When the three slices differ in length.
    pub fn values_and_gradients_into(
        &self,
        points: &[Vec3],
        values: &mut [f32],
        gradients: &mut [Vec3],
    ) {
        assert_eq!(points.len(), values.len(), "one value per point");
        assert_eq!(points.len(), gradients.len(), "one gradient per point");
        for ((x, v), g) in points
            .iter()
            .zip(values.iter_mut())
            .zip(gradients.iter_mut())
        {
            (*v, *g) = self.value_and_gradient(*x);
        }
    }

    /// Whether a world point is inside the solid (value above the iso-level).
    #[inline]
    #[must_use]
    pub fn is_inside(&self, x: Vec3) -> bool {
        self.value(x) > self.iso
    }

    /// The stencil's first coefficient when all 4×4×4 lie inside the lattice.
    #[inline]
    fn interior_base(&self, stencil: &Stencil) -> Option<[usize; 3]> {
        let f = stencil.first;
        let inside = (0..3).all(|a| f[a] >= 0 && (f[a] + 3) < self.dims[a] as i64);
        inside.then(|| f.map(|x| x as usize))
    }

    fn stencil(&self, x: Vec3) -> Option<Stencil> {
        let u = self.to_lattice(x);
        // Beyond two spans outside the lattice every basis function is zero: no stencil where
        // `floor(u) < -3` or `floor(u) > n + 1`, that is where `u < -3` or `u ≥ n + 2` (n a whole
        // number), checked on `u` itself so that a point away from this lattice (most points
        // for most patches of a clay) costs no floor. A NaN or infinite `u` fails it too.
        let n = Vec3::new(
            self.dims[0] as f32,
            self.dims[1] as f32,
            self.dims[2] as f32,
        );
        if !(u.cmpge(Vec3::splat(-3.0)).all() && u.cmplt(n + 2.0).all()) {
            return None;
        }
        let base = Vec3::new(
            floor_near_lattice(u.x),
            floor_near_lattice(u.y),
            floor_near_lattice(u.z),
        );
        Some(Stencil {
            first: [base.x as i64 - 1, base.y as i64 - 1, base.z as i64 - 1],
            t: u - base,
        })
    }
}

/// `u.floor()`, bit for bit, for `u` in `-3 .. 2^24` (a point within reach of a lattice, in
/// its knot spans), without a call to `floorf` (x86-64's baseline has no rounding
/// instruction): truncate, step down where that rounded a negative value up, and keep the
/// sign of a zero.
#[inline]
fn floor_near_lattice(u: f32) -> f32 {
    let t = u as i32 as f32;
    if t > u { t - 1.0 } else { t.copysign(u) }
}

/// The 4×4×4 block of coefficients that influences one point.
struct Stencil {
    /// Index of the first contributing coefficient per axis (may be outside the lattice).
    first: [i64; 3],
    /// Fractional position within the knot span per axis.
    t: Vec3,
}

impl Stencil {
    /// Coefficient index along `axis` of tap `tap` (0..4), or `None` if outside the lattice.
    #[inline]
    fn axis(&self, axis: usize, tap: usize, n: usize) -> Option<usize> {
        let i = self.first[axis] + tap as i64;
        (i >= 0 && (i as usize) < n).then_some(i as usize)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_floor_near_a_lattice_is_the_floor_bit_for_bit() {
        let mut us = vec![-0.0, 0.0, -3.0, 16_777_215.0, 8_388_607.5, 8_388_608.0];
        for n in -3_i32..300 {
            let whole = n as f32;
            us.extend([whole, whole + 0.5, whole + 0.25, whole - 0.75]);
            // The floats next to each whole number, either side.
            us.push(f32::from_bits(whole.to_bits() + 1));
            if n != 0 {
                us.push(f32::from_bits(whole.to_bits() - 1));
            }
        }
        us.extend((1..1000).map(|n| n as f32 * 1234.567));
        for u in us.into_iter().filter(|&u| u >= -3.0) {
            assert_eq!(
                floor_near_lattice(u).to_bits(),
                u.floor().to_bits(),
                "floor of {u}"
            );
        }
    }

    #[test]
    fn a_point_two_spans_past_the_lattice_is_zero_and_one_just_inside_is_not() {
        let lattice =
            BSplineLattice::from_coeffs([5, 6, 7], 0.5, Vec3::new(1.0, -2.0, 0.25), vec![1.0; 210])
                .unwrap();
        let (lo, hi) = lattice.support();
        let middle = 0.5 * (lo + hi);
        for axis in 0..3 {
            let mut e = Vec3::ZERO;
            e[axis] = 1e-3;
            for (edge, out) in [(lo, -e), (hi, e)] {
                let mut at = middle;
                at[axis] = edge[axis];
                assert_eq!(lattice.value(at + out), 0.0, "past {at} along {axis}");
                assert_eq!(lattice.value_and_gradient(at + out), (0.0, Vec3::ZERO));
                assert!(lattice.value(at - out) > 0.0, "inside {at} along {axis}");
            }
        }
        let spans_out = |spans: f32| hi + Vec3::splat(spans * lattice.spacing);
        for far in [
            spans_out(0.7),
            spans_out(1.2),
            lo - Vec3::splat(0.7 * lattice.spacing),
            Vec3::splat(1e30),
            Vec3::splat(-1e30),
            Vec3::NAN,
            Vec3::INFINITY,
        ] {
            assert_eq!(lattice.value(far), 0.0, "at {far}");
        }
    }

    /// Asserts that [`BSplineLattice::values_on_grid`] over `xs × ys × zs` gives
    /// [`BSplineLattice::value`] at every point, bit for bit; returns how many of the values
    /// are not zero and how many are.
    fn assert_grid_is_values(
        lattice: &BSplineLattice,
        xs: &[f32],
        ys: &[f32],
        zs: &[f32],
    ) -> (usize, usize) {
        let mut out = vec![f32::NAN; xs.len() * ys.len() * zs.len()];
        lattice.values_on_grid(xs, ys, zs, &mut out);
        let mut at = 0;
        let (mut inner, mut zero) = (0, 0);
        for &z in zs {
            for &y in ys {
                for &x in xs {
                    let one = lattice.value(Vec3::new(x, y, z));
                    assert_eq!(out[at].to_bits(), one.to_bits(), "at ({x}, {y}, {z})");
                    inner += usize::from(one != 0.0);
                    zero += usize::from(one == 0.0);
                    at += 1;
                }
            }
        }
        (inner, zero)
    }

    #[test]
    fn values_on_a_grid_are_the_values_point_by_point_bit_for_bit() {
        let mut lattice =
            BSplineLattice::zeros([9, 7, 8], 0.3, Vec3::new(0.1, -0.2, 0.05)).expect("lattice");
        lattice
            .coeffs
            .update_each(|n, c| *c = ((n * 7919) % 61) as f32 / 61.0 - 0.3);
        // From beyond the support on the low side, across the borders, to beyond the high
        // side; x steps of a fifth of a span so several points share a span.
        let axis = |start: f32, step: f32, n: usize| -> Vec<f32> {
            (0..n).map(|i| start + step * i as f32).collect()
        };
        let (xs, ys, zs) = (
            axis(-1.0, 0.06, 66),
            axis(-1.1, 0.13, 25),
            axis(-0.9, 0.17, 22),
        );
        let (inner, zero) = assert_grid_is_values(&lattice, &xs, &ys, &zs);
        assert!(inner > 0 && zero > 0, "{inner} inside, {zero} outside");
        // Without points the call writes nothing.
        lattice.values_on_grid(&[], &ys, &zs, &mut []);
    }

    #[test]
    fn values_on_a_grid_dense_along_z_or_descending_are_the_values_point_by_point_bit_for_bit() {
        // Several z coordinates per knot span share a stencil's planes along z; coordinates
        // that go down, or jump back into a span left before, must not reuse another's.
        let mut lattice =
            BSplineLattice::zeros([10, 9, 11], 0.25, Vec3::new(-0.3, 0.2, -0.1)).expect("lattice");
        lattice
            .coeffs
            .update_each(|n, c| *c = ((n * 104_729) % 97) as f32 / 97.0 - 0.45);
        let axis = |start: f32, step: f32, n: usize| -> Vec<f32> {
            (0..n).map(|i| start + step * i as f32).collect()
        };
        let mut zs = axis(-0.9, 0.04, 80);
        zs.extend(axis(2.2, -0.37, 9));
        zs.extend([0.5, 0.51, 0.5, 1.7, 0.52]);
        let grids = [
            (axis(-0.8, 0.03, 40), axis(0.1, 0.05, 30), zs.clone()),
            (axis(2.5, -0.11, 30), axis(2.3, -0.09, 31), zs),
        ];
        let mut inner = 0;
        for (xs, ys, zs) in grids {
            inner += assert_grid_is_values(&lattice, &xs, &ys, &zs).0;
        }
        assert!(inner > 10_000, "{inner} values inside the support");
    }

    fn linear_lattice(
        dims: [usize; 3],
        spacing: f32,
        origin: Vec3,
        a: Vec3,
        b: f32,
    ) -> BSplineLattice {
        // A cubic B-spline reproduces a linear function when each coefficient takes the
        // function's value at the node it is centred on.
        let mut lattice = BSplineLattice::zeros(dims, spacing, origin).unwrap();
        for k in 0..dims[2] {
            for j in 0..dims[1] {
                for i in 0..dims[0] {
                    let idx = lattice.index(i, j, k);
                    lattice
                        .coeffs
                        .set_flat(idx, a.dot(lattice.node_position(i, j, k)) + b);
                }
            }
        }
        lattice
    }

    #[test]
    fn reproduces_linear_functions_exactly_in_the_exact_domain() {
        let (a, b) = (Vec3::new(0.3, -1.2, 0.7), 0.25);
        let lattice = linear_lattice([7, 8, 9], 0.5, Vec3::new(-1.0, 0.5, 2.0), a, b);
        let (lo, hi) = lattice.exact_domain();
        for s in 0..200 {
            let f = Vec3::new(
                (s * 37 % 101) as f32,
                (s * 53 % 103) as f32,
                (s * 71 % 107) as f32,
            ) / Vec3::new(101.0, 103.0, 107.0);
            let x = lo + (hi - lo) * f;
            let (v, g) = lattice.value_and_gradient(x);
            let expected = a.dot(x) + b;
            assert!(
                (v - expected).abs() < 1e-5 * (1.0 + expected.abs()),
                "{v} vs {expected} at {x}"
            );
            assert!((g - a).length() < 1e-4, "gradient {g} vs {a}");
        }
    }

    #[test]
    fn partition_of_unity_inside_and_zero_far_outside() {
        let lattice =
            BSplineLattice::from_coeffs([5, 5, 5], 1.0, Vec3::ZERO, vec![1.0; 125]).unwrap();
        for x in [
            Vec3::splat(1.0),
            Vec3::new(1.3, 2.7, 2.99),
            Vec3::new(2.5, 1.01, 1.5),
        ] {
            assert!((lattice.value(x) - 1.0).abs() < 1e-6);
        }
        assert_eq!(lattice.value(Vec3::new(-2.5, 1.0, 1.0)), 0.0);
        assert_eq!(lattice.value(Vec3::new(6.5, 1.0, 1.0)), 0.0);
        assert_eq!(lattice.value(Vec3::NAN), 0.0);
    }

    /// f64 reference: the field summed over every coefficient with the centred cubic.
    fn reference_value(lattice: &BSplineLattice, x: [f64; 3]) -> f64 {
        let s = f64::from(lattice.spacing);
        let o = lattice.origin.as_dvec3();
        let u = [(x[0] - o.x) / s, (x[1] - o.y) / s, (x[2] - o.z) / s];
        let mut sum = 0.0;
        for k in 0..lattice.dims[2] {
            let wz = crate::field::centred_cubic(u[2] - k as f64);
            if wz == 0.0 {
                continue;
            }
            for j in 0..lattice.dims[1] {
                let wy = crate::field::centred_cubic(u[1] - j as f64);
                if wy == 0.0 {
                    continue;
                }
                for i in 0..lattice.dims[0] {
                    let w = wz * wy * crate::field::centred_cubic(u[0] - i as f64);
                    sum += w * f64::from(lattice.coeffs[lattice.index(i, j, k)]);
                }
            }
        }
        sum
    }

    #[test]
    fn analytic_gradient_matches_central_differences() {
        let mut lattice = BSplineLattice::zeros([6, 7, 8], 0.4, Vec3::new(0.1, -0.2, 0.3)).unwrap();
        lattice
            .coeffs
            .update_each(|n, c| *c = ((n * 7919) % 97) as f32 / 97.0);
        // Central differences of an f64 evaluation: truncation ~h², rounding ~1e-16/h, both
        // far below the f32 analytic gradient's own rounding.
        let h = 1e-4_f64;
        for s in 0..200 {
            let x = Vec3::new(
                -0.5 + 0.0131 * s as f32,
                -0.6 + 0.0143 * s as f32,
                -0.4 + 0.0157 * s as f32,
            );
            let (v, g) = lattice.value_and_gradient(x);
            let xd = [f64::from(x.x), f64::from(x.y), f64::from(x.z)];
            let mut fd = [0.0; 3];
            for a in 0..3 {
                let (mut p, mut m) = (xd, xd);
                p[a] += h;
                m[a] -= h;
                fd[a] = (reference_value(&lattice, p) - reference_value(&lattice, m)) / (2.0 * h);
            }
            let err = ((f64::from(g.x) - fd[0]).powi(2)
                + (f64::from(g.y) - fd[1]).powi(2)
                + (f64::from(g.z) - fd[2]).powi(2))
            .sqrt();
            let norm = (fd[0] * fd[0] + fd[1] * fd[1] + fd[2] * fd[2]).sqrt();
            assert!(
                err / norm.max(1e-3) < 1e-4,
                "rel {} at {x}: {g} vs {fd:?}",
                err / norm
            );
            let vref = reference_value(&lattice, xd);
            assert!((f64::from(v) - vref).abs() < 1e-5, "value {v} vs {vref}");
        }
    }

    /// A ball of radius `0.35 n` knot spans in an `n³` lattice, its density ramp two spans
    /// wide as the starting clays have it, and the heap bytes of its coefficients.
    fn ball_heap_bytes(n: usize) -> usize {
        let mut lattice = BSplineLattice::zeros([n; 3], 1.0, Vec3::ZERO).unwrap();
        let centre = Vec3::splat((n - 1) as f32 / 2.0);
        let radius = 0.35 * n as f32;
        let dims = lattice.dims;
        lattice.coeffs.update_each(|m, c| {
            let (i, j, k) = (
                m % dims[0],
                (m / dims[0]) % dims[1],
                m / (dims[0] * dims[1]),
            );
            let d = (Vec3::new(i as f32, j as f32, k as f32) - centre).length();
            *c = (0.5 + (radius - d) / 2.0).clamp(0.0, 1.0);
        });
        lattice.coeffs.compact();
        assert!((lattice.value(centre) - 1.0).abs() < 1e-6);
        assert_eq!(lattice.value(Vec3::splat(1.0)), 0.0);
        lattice.coeffs.heap_bytes()
    }

    #[test]
    fn a_balls_coefficients_take_memory_by_its_area_not_its_volume() {
        let heaps: Vec<usize> = [64, 128, 256].into_iter().map(ball_heap_bytes).collect();
        println!("heap bytes at 64³, 128³, 256³: {heaps:?}");
        let dense = |n: usize| n * n * n * size_of::<f32>();
        // Doubling the size quadruples the area (×8 the volume): allow a little over ×4 for
        // the bricks a coarser surface crosses.
        for pair in heaps.windows(2) {
            let growth = pair[1] as f64 / pair[0] as f64;
            assert!(growth < 5.0, "heap grew ×{growth} from {heaps:?}");
        }
        // A dense brick holds its 8³ values and an apron, 11³ in all (2.6 times the values it
        // owns), so the bricked ball beats the dense box by less at this size: about 1/3.6 at
        // 256³ and 1/7 at 512³ (bench/RESULTS.md).
        assert!(
            heaps[2] * 3 < dense(256),
            "256³ ball: {} bytes bricked, {} dense",
            heaps[2],
            dense(256)
        );
    }

    /// The figure in bench/RESULTS.md: `cargo test --release -p dynaclay-core --lib
    /// ball_at_512 -- --ignored --nocapture`.
    #[test]
    #[ignore = "a figure for bench/RESULTS.md (a 512³ lattice, about a second)"]
    fn ball_at_512_heap_bytes_bricked_and_dense() {
        let bricked = ball_heap_bytes(512);
        let dense = 512_usize.pow(3) * size_of::<f32>();
        println!(
            "512³ ball: {bricked} bytes bricked ({:.1} MiB), {dense} bytes dense ({:.1} MiB), 1/{:.1}",
            bricked as f64 / f64::from(1 << 20),
            dense as f64 / f64::from(1 << 20),
            dense as f64 / bricked as f64
        );
        assert!(bricked * 6 < dense);
    }

    #[test]
    fn rejects_bad_construction() {
        assert!(matches!(
            BSplineLattice::zeros([3, 5, 5], 1.0, Vec3::ZERO),
            Err(LatticeError::TooSmall { .. })
        ));
        assert!(matches!(
            BSplineLattice::zeros([5, 5, 5], 0.0, Vec3::ZERO),
            Err(LatticeError::BadSpacing { .. })
        ));
        assert!(matches!(
            BSplineLattice::from_coeffs([4, 4, 4], 1.0, Vec3::ZERO, vec![0.0; 10]),
            Err(LatticeError::WrongLength {
                expected: 64,
                got: 10
            })
        ));
    }
}
