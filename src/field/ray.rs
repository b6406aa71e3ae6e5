//! Where a ray meets the clay: march the field along the ray, then bisect the crossing.
//!
//! Guarantee: [`pick_surface`] does bounded work — at most [`MAX_PICK_STEPS`] marching
//! evaluations and [`PICK_BISECT_STEPS`] bisection steps, plus one gradient — and allocates
//! nothing, so the window can call it every frame for the pointer.

use glam::Vec3;

use super::lattice::BSplineLattice;

/// Most marching steps along one ray (the step grows past half a knot span when the ray's
/// path through the lattice is longer than this many half spans).
pub const MAX_PICK_STEPS: usize = 512;
/// Bisection steps once the crossing is bracketed (a 2⁻¹⁶ fraction of a step).
pub const PICK_BISECT_STEPS: usize = 16;

/// A ray's first meeting with the clay's surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayHit {
    /// The surface point, world units.
    pub point: Vec3,
    /// Outward unit normal there (the density falls outward); zero where the field is flat.
    pub normal: Vec3,
    /// Distance from the ray's origin, world units.
    pub distance: f32,
}

/// The first point where the ray from `origin` along `direction` enters the clay (`s`
/// crosses the iso-level upward), or `None` when it misses the clay within the lattice's
/// support. A ray that starts inside the clay reports where it leaves it instead, so a camera
/// inside the clay still picks the surface it looks at.
#[must_use]
pub fn pick_surface(lattice: &BSplineLattice, origin: Vec3, direction: Vec3) -> Option<RayHit> {
    let dir = direction.try_normalize()?;
    if !origin.is_finite() {
        return None;
    }
    let (lo, hi) = lattice.support();
    let (t0, t1) = clip_to_box(origin, dir, lo, hi)?;
    let length = t1 - t0;
    let step = (0.5 * lattice.spacing).max(length / MAX_PICK_STEPS as f32);
    let inside = |t: f32| lattice.value(origin + dir * t) > lattice.iso;
    let start_inside = inside(t0);
    let mut near = t0;
    let mut t = t0;
    while t < t1 {
        let next = (t + step).min(t1);
        if inside(next) != start_inside {
            let mut far = next;
            for _ in 0..PICK_BISECT_STEPS {
                let mid = 0.5 * (near + far);
                if inside(mid) == start_inside {
                    near = mid;
                } else {
                    far = mid;
                }
            }
            let distance = 0.5 * (near + far);
            let point = origin + dir * distance;
            return Some(RayHit {
                point,
                normal: (-lattice.gradient(point)).normalize_or_zero(),
                distance,
            });
        }
        near = next;
        t = next;
    }
    None
}

/// The parameter range `[t0, t1]` (with `t0 ≥ 0`) where the ray is inside the box.
fn clip_to_box(origin: Vec3, dir: Vec3, lo: Vec3, hi: Vec3) -> Option<(f32, f32)> {
    let inv = dir.recip();
    let a = (lo - origin) * inv;
    let b = (hi - origin) * inv;
    let t0 = a.min(b).max_element().max(0.0);
    let t1 = a.max(b).min_element();
    (t0.is_finite() && t1.is_finite() && t1 > t0).then_some((t0, t1))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::{Primitive, lattice_from_primitive};

    const CENTRE: Vec3 = Vec3::new(1.2, 1.2, 1.2);
    const RADIUS: f32 = 0.6;

    fn ball() -> BSplineLattice {
        let s = Primitive::Sphere {
            centre: CENTRE,
            radius: RADIUS,
        };
        lattice_from_primitive([25; 3], 0.1, Vec3::ZERO, &s, 0.2, 2).unwrap()
    }

    /// Where the fitted field's own surface lies along `dir` from the centre (bisection).
    fn fitted_radius(l: &BSplineLattice, dir: Vec3) -> f32 {
        let (mut a, mut b) = (0.0f32, 1.2f32);
        for _ in 0..40 {
            let m = 0.5 * (a + b);
            if l.value(CENTRE + dir * m) > l.iso {
                a = m;
            } else {
                b = m;
            }
        }
        0.5 * (a + b)
    }

    #[test]
    fn a_ray_meets_a_fitted_sphere_where_its_surface_is() {
        let l = ball();
        for dir in [
            Vec3::X,
            Vec3::new(1.0, 1.0, 0.0).normalize(),
            Vec3::new(-0.3, 0.5, 0.8).normalize(),
        ] {
            let origin = CENTRE + dir * 3.0;
            let hit = pick_surface(&l, origin, -dir).expect("hits");
            // The analytic sphere, within the fit's own error.
            assert!(
                (hit.point.distance(CENTRE) - RADIUS).abs() < 0.02,
                "{}",
                hit.point
            );
            // The fitted field's surface along the ray, within 1e-3 knot spans.
            let r = fitted_radius(&l, dir);
            assert!(
                (hit.point - (CENTRE + dir * r)).length() < 1e-3 * l.spacing,
                "{} vs {}",
                hit.point,
                CENTRE + dir * r
            );
            assert!(hit.normal.dot(dir) > 0.99, "outward normal {}", hit.normal);
            assert!((hit.distance - (3.0 - r)).abs() < 1e-3 * l.spacing);
        }
    }

    #[test]
    fn a_ray_that_misses_returns_none() {
        let l = ball();
        // Passes beside the sphere.
        assert!(pick_surface(&l, CENTRE + Vec3::new(0.9, 0.0, 3.0), -Vec3::Z).is_none());
        // Points away from it.
        assert!(pick_surface(&l, CENTRE + Vec3::Z * 3.0, Vec3::Z).is_none());
        // Misses the lattice altogether, or has no direction.
        assert!(pick_surface(&l, Vec3::splat(50.0), Vec3::X).is_none());
        assert!(pick_surface(&l, CENTRE + Vec3::Z * 3.0, Vec3::ZERO).is_none());
    }

    #[test]
    fn a_camera_inside_the_clay_picks_where_it_leaves() {
        let l = ball();
        let hit = pick_surface(&l, CENTRE, Vec3::Y).expect("leaves the ball");
        assert!((hit.point.distance(CENTRE) - RADIUS).abs() < 0.02);
    }
}
