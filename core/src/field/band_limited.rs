//! Solids the cubic B-spline holds without ringing: a block whose faces are flat and whose
//! edges and corners are rounded evenly, and a ball, both with a density that rises smoothly
//! from 0 outside to 1 inside and crosses one half on the solid's surface.
//!
//! A least-squares fit of a clamped step `clamp(0.5 − sd/width, 0, 1)` of a sharp solid (what
//! [`super::lattice_from_primitive`] does) rings: a cubic spline cannot follow the step's kinks
//! nor a box's sharp edges, so the fitted surface undulates across the faces, carries a ridge
//! along each edge and a knob at each corner. Here instead:
//!
//! - **The profile across a surface** is the spline whose coefficients are that clamped ramp
//!   sampled at the knots (Schoenberg's quasi-interpolant of the ramp, [`smooth_step`]). Its
//!   coefficients lie in `[0, 1]` and rise monotonically, so the spline does too — no overshoot,
//!   no ringing — and it is C². Where it crosses one half its slope is the ramp's, `1 / width`
//!   (for the default `width` of two knot spans, the old fit's slope at the surface, so tools
//!   and touch meet the same gradient there); it reaches 0 and 1 about `width` outside and
//!   inside, where the ramp reached them at `width / 2`.
//! - **A block** ([`smooth_block_lattice`]) is the product of three such profiles, one per
//!   axis, each shifted by a fraction of a span so that it crosses one half exactly on the
//!   faces. A product of one-dimensional splines is itself a spline on the lattice
//!   (coefficients `cx_i · cy_j · cz_k`), so it is stored exactly, without a fit. Where two of
//!   the profiles are 1 — two knot spans or so from every edge — the field is a function of the
//!   third coordinate alone: the face is flat to rounding. No profile exceeds 1, so nothing
//!   rises above a face's plane anywhere: no ridge, no knob. Where two profiles fall below 1
//!   the surface `px · py = 1/2` rounds the edge convexly; where three do, the corner, the same
//!   at all eight. For the default width the edges and corners sit where a box rounded with a
//!   radius of about 1.7 knot spans has them (`tests/starting_clay.rs` measures it).
//! - **Any other primitive** ([`band_limited_lattice`]) is the least-squares fit of the smooth
//!   profile of its signed distance: a C² target (a ball's is C² everywhere near its surface),
//!   which the fit follows to a small fraction of a span without ringing.

use glam::Vec3;

use super::axis::centred_cubic;
use super::lattice::BSplineLattice;
use super::mass_grid::CoeffBox;
use super::primitive::Primitive;
use super::refit::{FitError, fit_lattice};

/// Bisection steps that place a face's profile on it (far below f32 resolution).
const PLACEMENT_STEPS: usize = 60;

/// The clamped ramp `clamp(0.5 + depth / width, 0, 1)` (depth positive inside).
#[inline]
fn ramp(depth: f64, width: f64) -> f64 {
    (0.5 + depth / width).clamp(0.0, 1.0)
}

/// The smooth density profile at `depth` (field units, positive inside the solid) for a ramp
/// of `width` on knots `spacing` apart: `Σ_i clamp(0.5 + i·spacing / width, 0, 1) · B(depth /
/// spacing − i)` over the integers `i`, with `B` the centred cubic B-spline. It is one half at
/// depth 0 with slope `1 / width` there (for `width ≥ spacing`; `1 / (2 spacing)` below),
/// `p(−d) = 1 − p(d)`, monotone, C², and exactly 1 from `(⌈width / (2 spacing)⌉ + 1)` knot
/// spans inside on (0 as far outside): for `width = 2 spacing`, from two spans.
///
/// A non-positive or non-finite `width` or `spacing` gives the sharp step at depth 0.
#[must_use]
pub fn smooth_step(depth: f32, width: f32, spacing: f32) -> f32 {
    let (d, w, h) = (f64::from(depth), f64::from(width), f64::from(spacing));
    if !(w > 0.0 && h > 0.0 && w.is_finite() && h.is_finite()) {
        return if depth > 0.0 { 1.0 } else { 0.0 };
    }
    let u = d / h;
    let first = u.floor() as i64 - 1;
    (first..first + 4)
        .map(|i| ramp(i as f64 * h, w) * centred_cubic(u - i as f64))
        .sum::<f64>() as f32
}

/// One axis of a slab `[lo, hi]` on `n` knots at `origin + i · spacing`: the ramp coefficients
/// `min(ramp(x_i − lo'), ramp(hi' − x_i))`, with `lo'` and `hi'` placed (by bisection) so that
/// the spline crosses one half at `lo` and at `hi`.
fn slab_coefficients(
    n: usize,
    origin: f64,
    spacing: f64,
    lo: f64,
    hi: f64,
    width: f64,
) -> Vec<f64> {
    let node = |i: usize| origin + i as f64 * spacing;
    let coefficients = |lo_s: f64, hi_s: f64| -> Vec<f64> {
        (0..n)
            .map(|i| ramp(node(i) - lo_s, width).min(ramp(hi_s - node(i), width)))
            .collect()
    };
    // The spline of `c` at `x` (coefficients beyond the lattice count as zero).
    let value = |c: &[f64], x: f64| -> f64 {
        let u = (x - origin) / spacing;
        let first = (u.floor() as i64 - 1).max(0);
        let last = (u.floor() as i64 + 2).min(n as i64 - 1);
        (first..=last)
            .map(|i| c[i as usize] * centred_cubic(u - i as f64))
            .sum()
    };
    // Shifting a ramp inward lowers the spline at its face: bisect on the shift within one
    // ramp width of the face (a slab too thin to reach one half ends at the bracket's end).
    let place = |face: f64, other: f64, is_lo: bool| -> f64 {
        let (mut a, mut b) = (face - width, face + width);
        for _ in 0..PLACEMENT_STEPS {
            let m = 0.5 * (a + b);
            let c = if is_lo {
                coefficients(m, other)
            } else {
                coefficients(other, m)
            };
            // `lo'` moves inward as it grows, `hi'` as it shrinks.
            let too_high = value(&c, face) > 0.5;
            if too_high == is_lo {
                a = m;
            } else {
                b = m;
            }
        }
        0.5 * (a + b)
    };
    let (mut lo_s, mut hi_s) = (lo, hi);
    // The two faces see each other only in slabs a few spans thin; three rounds settle them.
    for _ in 0..3 {
        lo_s = place(lo, hi_s, true);
        hi_s = place(hi, lo_s, false);
    }
    coefficients(lo_s, hi_s)
}

/// A lattice holding the smooth block `[min, max]`: the product of three one-dimensional
/// smooth profiles (see the module docs), exact, without a fit. `width` is the profile's ramp
/// width in world units (two knot spans gives the slope of [`super::density_profile`] at the
/// surface).
///
/// # Errors
/// [`FitError::BadBox`] when `dims` or `spacing` cannot make a lattice.
pub fn smooth_block_lattice(
    dims: [usize; 3],
    spacing: f32,
    origin: Vec3,
    min: Vec3,
    max: Vec3,
    width: f32,
) -> Result<BSplineLattice, FitError> {
    let mut lattice = zeros(dims, spacing, origin)?;
    let axes: [Vec<f64>; 3] = std::array::from_fn(|a| {
        slab_coefficients(
            dims[a],
            f64::from(origin[a]),
            f64::from(spacing),
            f64::from(min[a]),
            f64::from(max[a]),
            f64::from(width),
        )
    });
    let mut row = Vec::with_capacity(dims[0]);
    for (k, &cz) in axes[2].iter().enumerate() {
        for (j, &cy) in axes[1].iter().enumerate() {
            row.clear();
            row.extend(axes[0].iter().map(|&cx| (cx * cy * cz) as f32));
            lattice.coeffs.write_row_at([0, j, k], &row);
        }
    }
    Ok(lattice)
}

/// A new lattice holding `primitive` with the smooth density profile [`smooth_step`] of
/// ramp `width` (world units): a box exactly by [`smooth_block_lattice`], anything else by a
/// least-squares fit of `smooth_step(−signed_distance)` sampled at `samples_per_span` points
/// per knot span.
///
/// # Errors
/// As [`fit_lattice`]; [`FitError::BadBox`] when `dims` or `spacing` cannot make a lattice.
pub fn band_limited_lattice(
    dims: [usize; 3],
    spacing: f32,
    origin: Vec3,
    primitive: &Primitive,
    width: f32,
    samples_per_span: usize,
) -> Result<BSplineLattice, FitError> {
    if let Primitive::Box {
        centre,
        half_extents,
    } = *primitive
    {
        return smooth_block_lattice(
            dims,
            spacing,
            origin,
            centre - half_extents,
            centre + half_extents,
            width,
        );
    }
    let mut lattice = zeros(dims, spacing, origin)?;
    fit_lattice(&mut lattice, samples_per_span, |x| {
        smooth_step(-primitive.signed_distance(x), width, spacing)
    })?;
    Ok(lattice)
}

/// An all-zero lattice, its construction error reported as a fit error.
fn zeros(dims: [usize; 3], spacing: f32, origin: Vec3) -> Result<BSplineLattice, FitError> {
    BSplineLattice::zeros(dims, spacing, origin).map_err(|_| FitError::BadBox {
        coeffs: CoeffBox {
            min: [0; 3],
            max: dims,
        },
        dims,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn smooth_step_is_a_symmetric_monotone_step_with_the_ramps_slope() {
        let (w, h) = (0.2_f32, 0.1_f32);
        assert!((smooth_step(0.0, w, h) - 0.5).abs() < 1e-7);
        let e = 1e-3;
        let slope = (smooth_step(e, w, h) - smooth_step(-e, w, h)) / (2.0 * e);
        assert!((slope - 1.0 / w).abs() < 1e-2 / w, "slope {slope}");
        let mut last = 0.0;
        for s in -300..=300 {
            let d = s as f32 * 1e-3;
            let p = smooth_step(d, w, h);
            assert!(p >= last - 1e-7, "not monotone at {d}");
            assert!(
                (p + smooth_step(-d, w, h) - 1.0).abs() < 1e-6,
                "not symmetric at {d}"
            );
            last = p;
        }
        assert_eq!(smooth_step(0.2, w, h), 1.0);
        assert_eq!(smooth_step(-0.2, w, h), 0.0);
    }

    /// The surface crossing along x of the line `(·, y, z)`, bisected between `a` (inside)
    /// and `b` (outside).
    fn crossing(l: &BSplineLattice, y: f32, z: f32, mut a: f32, mut b: f32) -> f32 {
        for _ in 0..40 {
            let m = 0.5 * (a + b);
            if l.value(Vec3::new(m, y, z)) > 0.5 {
                a = m;
            } else {
                b = m;
            }
        }
        0.5 * (a + b)
    }

    #[test]
    fn block_faces_lie_on_the_box_at_every_alignment_and_are_flat() {
        // Faces a quarter, a half and three quarters of a span off the knots, and on them.
        for off in [0.0_f32, 0.25, 0.5, 0.75, 0.13] {
            let lo = Vec3::new(0.5 + off * 0.1, 0.4, 0.4);
            let hi = Vec3::new(1.3 + off * 0.1, 1.5, 1.5);
            let l = smooth_block_lattice([20; 3], 0.1, Vec3::ZERO, lo, hi, 0.2).unwrap();
            for (y, z) in [(0.95, 0.95), (0.7, 1.2), (1.1, 0.66)] {
                let x0 = crossing(&l, y, z, 0.9, 0.2);
                let x1 = crossing(&l, y, z, 0.9, 1.8);
                assert!(
                    (x0 - lo.x).abs() < 1e-5,
                    "offset {off}: low face at {x0}, not {}",
                    lo.x
                );
                assert!(
                    (x1 - hi.x).abs() < 1e-5,
                    "offset {off}: high face at {x1}, not {}",
                    hi.x
                );
            }
            // The slope across the face stays near the ramp's.
            let e = 1e-3;
            let at = |x: f32| l.value(Vec3::new(x, 0.95, 0.95));
            let slope = (at(lo.x + e) - at(lo.x - e)) / (2.0 * e);
            assert!((4.0..=5.0).contains(&slope), "offset {off}: slope {slope}");
            // Inside and away from the faces the density is 1, outside 0, never beyond.
            assert!((at(0.9) - 1.0).abs() < 1e-6);
            assert_eq!(l.value(Vec3::new(0.9, 0.0, 0.0)), 0.0);
            assert!(l.coeffs.iter().all(|&c| (0.0..=1.0).contains(&c)));
        }
    }

    #[test]
    fn block_edges_round_inward_and_never_rise_above_a_face() {
        let lo = Vec3::splat(0.575);
        let hi = Vec3::splat(1.725);
        let l = smooth_block_lattice([24; 3], 0.1, Vec3::ZERO, lo, hi, 0.2).unwrap();
        // Across the top face's edge at x = hi.x: the top stays at or below hi.y, falling off
        // monotonically as the edge nears.
        let mut last = f32::INFINITY;
        for s in 0..=40 {
            let x = 1.3 + s as f32 * 0.01;
            let mut a = 1.0;
            let mut b = 1.9;
            for _ in 0..40 {
                let m = 0.5 * (a + b);
                if l.value(Vec3::new(x, m, 1.15)) > 0.5 {
                    a = m;
                } else {
                    b = m;
                }
            }
            let top = 0.5 * (a + b);
            assert!(top <= hi.y + 1e-5, "top {top} above the face at x = {x}");
            assert!(top <= last + 1e-6, "top rises toward the edge at x = {x}");
            last = top;
        }
    }

    #[test]
    fn a_ball_fits_its_radius() {
        let ball = Primitive::Sphere {
            centre: Vec3::splat(1.15),
            radius: 0.575,
        };
        let l = band_limited_lattice([24; 3], 0.1, Vec3::ZERO, &ball, 0.2, 2).unwrap();
        for dir in [
            Vec3::X,
            Vec3::NEG_Y,
            Vec3::new(1.0, 1.0, 1.0).normalize(),
            Vec3::new(-0.3, 0.5, -0.8).normalize(),
        ] {
            let (mut a, mut b) = (0.0, 1.0);
            for _ in 0..40 {
                let m = 0.5 * (a + b);
                if l.value(Vec3::splat(1.15) + dir * m) > 0.5 {
                    a = m;
                } else {
                    b = m;
                }
            }
            let r = 0.5 * (a + b);
            assert!((r - 0.575).abs() < 1e-3, "radius {r} along {dir}");
        }
        // The fit of a C² profile ripples a little inside (1.0018 here), where the fit of the
        // clamped step rang by several percent.
        let inside = l.value(Vec3::splat(1.15));
        assert!((inside - 1.0).abs() < 0.01, "{inside} at the centre");
        assert!(l.value(Vec3::splat(0.05)).abs() < 1e-3);
    }
}
