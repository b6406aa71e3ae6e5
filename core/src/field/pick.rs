//! Picking: where a view ray first meets the clay's iso-surface.
//!
//! Guarantee: bounded work, no allocation. The ray is clipped to the lattice's support box
//! (outside it the field is exactly zero, so there is nothing to find), marched in steps of
//! [`MARCH_STEP_SPANS`] knot spans, and the first step that crosses from outside to inside is
//! bisected [`BISECTION_STEPS`] times. On a 96³ lattice that is at most about 340 field
//! evaluations plus the bisection, cheap enough for the GUI thread every frame
//! (`cargo bench --bench pointer` measures it).
//!
//! A feature thinner than one march step along the ray can be stepped over; half a knot span
//! is finer than anything the cubic field can hold, so in practice the first crossing is found.

use glam::Vec3;

use super::multipatch::MultiPatchField;

/// March step along the ray, knot spans.
pub const MARCH_STEP_SPANS: f32 = 0.5;
/// Bisection steps after the march: the bracket shrinks to `0.5 / 2^24` spans.
pub const BISECTION_STEPS: u32 = 24;

/// A ray in field coordinates; `direction` need not be normalised (it is normalised here).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Start of the ray.
    pub origin: Vec3,
    /// Direction of travel.
    pub direction: Vec3,
}

/// Where a ray meets the surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceHit {
    /// The surface point, field coordinates.
    pub point: Vec3,
    /// Outward unit normal at `point` (against the field's gradient).
    pub normal: Vec3,
    /// Distance from the ray's origin to `point`, field units.
    pub distance: f32,
}

/// The entry and exit distances of a ray (unit `dir`) through the box `lo..hi`, if it meets it
/// ahead of its origin.
fn clip_to_box(origin: Vec3, dir: Vec3, lo: Vec3, hi: Vec3) -> Option<(f32, f32)> {
    let inv = dir.recip();
    let t0 = (lo - origin) * inv;
    let t1 = (hi - origin) * inv;
    // NaN from 0 · ∞ (a ray in a face's plane) is dropped by min/max toward the other operand.
    let near = t0.min(t1).max_element().max(0.0);
    let far = t0.max(t1).min_element();
    (near <= far && far.is_finite()).then_some((near, far))
}

/// The first point where `ray` enters the solid (`value > iso`), or `None` when the ray misses
/// the clay, starts inside it, or is not finite.
#[must_use]
pub fn pick_surface(field: &MultiPatchField, ray: Ray) -> Option<SurfaceHit> {
    let dir = ray.direction.try_normalize()?;
    if !ray.origin.is_finite() {
        return None;
    }
    let (lo, hi) = field.support();
    let (near, far) = clip_to_box(ray.origin, dir, lo, hi)?;
    let step = MARCH_STEP_SPANS * field.finest_spacing();
    let inside = |t: f32| field.value(ray.origin + dir * t) > field.iso();
    if inside(near) {
        return None;
    }
    // Bounded: the support box's diagonal over the step.
    let steps = ((far - near) / step).ceil() as usize;
    let mut outside_t = near;
    for n in 1..=steps {
        let t = (near + n as f32 * step).min(far);
        if inside(t) {
            let (mut a, mut b) = (outside_t, t);
            for _ in 0..BISECTION_STEPS {
                let m = 0.5 * (a + b);
                if inside(m) {
                    b = m;
                } else {
                    a = m;
                }
            }
            let t_hit = 0.5 * (a + b);
            let point = ray.origin + dir * t_hit;
            let normal = (-field.value_and_gradient(point).1)
                .try_normalize()
                .unwrap_or(-dir);
            return Some(SurfaceHit {
                point,
                normal,
                distance: t_hit,
            });
        }
        outside_t = t;
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::{BSplineLattice, MultiPatchField};
    use crate::field::{Primitive, lattice_from_primitive};

    /// A ball of radius `r` around `c` held exactly by the cubic lattice: the field
    /// `1 − |x − c|² / (2r²)` is a quadratic, which uniform cubic B-splines reproduce exactly
    /// with coefficients `f(node) + h² / (2r²) · 3 · (1/3)` (each axis' x² picks up h²/3).
    fn exact_ball(c: Vec3, r: f32) -> BSplineLattice {
        let dims = [16, 16, 16];
        let h = 0.25;
        let mut l = BSplineLattice::zeros(dims, h, Vec3::ZERO).unwrap();
        for k in 0..dims[2] {
            for j in 0..dims[1] {
                for i in 0..dims[0] {
                    let n = l.node_position(i, j, k);
                    let idx = l.index(i, j, k);
                    l.coeffs.set_flat(
                        idx,
                        1.0 - ((n - c).length_squared() - h * h) / (2.0 * r * r),
                    );
                }
            }
        }
        l
    }

    #[test]
    fn a_ray_meets_an_exact_ball_at_the_analytic_point() {
        let c = Vec3::splat(1.9);
        let r = 0.8;
        let field = MultiPatchField::new(exact_ball(c, r));
        let span = field.finest_spacing();
        for (origin, dir) in [
            (Vec3::new(1.9, 1.9, -1.0), Vec3::Z),
            (Vec3::new(1.6, 2.1, 4.5), Vec3::NEG_Z),
            (Vec3::new(-0.5, 1.5, 1.7), Vec3::new(1.0, 0.1, 0.05)),
        ] {
            let hit = pick_surface(
                &field,
                Ray {
                    origin,
                    direction: dir,
                },
            )
            .expect("ray hits");
            // Analytic first intersection of the ray with the ball.
            let d = dir.normalize();
            let oc = origin - c;
            let b = oc.dot(d);
            let t = -b - (b * b - (oc.length_squared() - r * r)).sqrt();
            let expected = origin + d * t;
            let err_spans = (hit.point - expected).length() / span;
            assert!(
                err_spans < 1e-3,
                "{origin} → {dir}: off by {err_spans} spans"
            );
            let n = (expected - c).normalize();
            assert!(hit.normal.dot(n) > 0.999, "normal {} vs {n}", hit.normal);
            assert!((hit.distance - t).abs() / span < 1e-3);
        }
    }

    #[test]
    fn a_ray_meets_a_fitted_sphere_at_its_iso_surface_and_near_the_true_one() {
        let sphere = Primitive::Sphere {
            centre: Vec3::splat(1.6),
            radius: 1.0,
        };
        let field = MultiPatchField::new(
            lattice_from_primitive([17, 17, 17], 0.2, Vec3::ZERO, &sphere, 0.4, 2).unwrap(),
        );
        let origin = Vec3::new(1.6, 1.6, -0.5);
        let hit = pick_surface(
            &field,
            Ray {
                origin,
                direction: Vec3::Z,
            },
        )
        .unwrap();
        // On the fitted field's own iso-surface to a thousandth of a span …
        let g = field.value_and_gradient(hit.point).1.length();
        let off_spans = (field.value(hit.point) - field.iso()).abs() / g / field.finest_spacing();
        assert!(off_spans < 1e-3, "{off_spans} spans off the iso-surface");
        // … which lies within the fit's tolerance of the true sphere (z = 0.6).
        assert!((hit.point.z - 0.6).abs() < 0.02, "{}", hit.point);
    }

    #[test]
    fn rays_that_miss_return_none() {
        let field = MultiPatchField::new(exact_ball(Vec3::splat(1.9), 0.8));
        let miss = |origin, direction| pick_surface(&field, Ray { origin, direction });
        // Passes beside the ball.
        assert_eq!(miss(Vec3::new(0.3, 0.3, -1.0), Vec3::Z), None);
        // Points away from it.
        assert_eq!(miss(Vec3::new(1.9, 1.9, -1.0), Vec3::NEG_Z), None);
        // Never reaches the lattice.
        assert_eq!(miss(Vec3::new(-5.0, 1.9, 1.9), Vec3::Y), None);
        // Degenerate input.
        assert_eq!(miss(Vec3::new(1.9, 1.9, -1.0), Vec3::ZERO), None);
        assert_eq!(miss(Vec3::NAN, Vec3::Z), None);
        // Starts inside the clay.
        assert_eq!(miss(Vec3::splat(1.9), Vec3::Z), None);
    }
}
