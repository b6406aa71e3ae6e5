//! Implicit primitives (sphere, box, torus, cylinder) and the construction of a field from
//! them by fitting a clamped density profile.
//!
//! The profile is `clamp(0.5 − signed_distance / width, 0, 1)`: one half on the surface (the
//! default iso-level), rising to one `width / 2` inside and falling to zero — empty space —
//! `width / 2` outside, which agrees with coefficients beyond the lattice counting as zero.

use glam::Vec3;

use super::lattice::BSplineLattice;
use super::refit::{FitError, coeff_box_around, refit_box};

/// An implicit primitive with an exact (or, for the box, exact) signed distance; negative
/// inside. Torus and cylinder are around the z axis through `centre`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Primitive {
    /// A ball.
    Sphere { centre: Vec3, radius: f32 },
    /// An axis-aligned box.
    Box { centre: Vec3, half_extents: Vec3 },
    /// A torus in the plane `z = centre.z`.
    Torus {
        centre: Vec3,
        major_radius: f32,
        minor_radius: f32,
    },
    /// A capped cylinder along z.
    Cylinder {
        centre: Vec3,
        radius: f32,
        half_height: f32,
    },
}

impl Primitive {
    /// Signed distance from `x` to the surface, negative inside.
    #[must_use]
    pub fn signed_distance(&self, x: Vec3) -> f32 {
        match *self {
            Self::Sphere { centre, radius } => (x - centre).length() - radius,
            Self::Box {
                centre,
                half_extents,
            } => {
                let q = (x - centre).abs() - half_extents;
                q.max(Vec3::ZERO).length() + q.max_element().min(0.0)
            }
            Self::Torus {
                centre,
                major_radius,
                minor_radius,
            } => {
                let d = x - centre;
                let ring = d.truncate().length() - major_radius;
                (ring * ring + d.z * d.z).sqrt() - minor_radius
            }
            Self::Cylinder {
                centre,
                radius,
                half_height,
            } => {
                let d = x - centre;
                let q = glam::Vec2::new(d.truncate().length() - radius, d.z.abs() - half_height);
                q.max(glam::Vec2::ZERO).length() + q.max_element().min(0.0)
            }
        }
    }

    /// World bounding box `(min, max)` of the solid.
    #[must_use]
    pub fn bounds(&self) -> (Vec3, Vec3) {
        let (c, h) = match *self {
            Self::Sphere { centre, radius } => (centre, Vec3::splat(radius)),
            Self::Box {
                centre,
                half_extents,
            } => (centre, half_extents),
            Self::Torus {
                centre,
                major_radius,
                minor_radius,
            } => (
                centre,
                Vec3::new(
                    major_radius + minor_radius,
                    major_radius + minor_radius,
                    minor_radius,
                ),
            ),
            Self::Cylinder {
                centre,
                radius,
                half_height,
            } => (centre, Vec3::new(radius, radius, half_height)),
        };
        (c - h, c + h)
    }

    /// The clamped density profile at `x` for a transition of `width` world units.
    #[must_use]
    pub fn density(&self, x: Vec3, width: f32) -> f32 {
        density_profile(self.signed_distance(x), width)
    }
}

/// `clamp(0.5 − signed_distance / width, 0, 1)`.
#[inline]
#[must_use]
pub fn density_profile(signed_distance: f32, width: f32) -> f32 {
    (0.5 - signed_distance / width).clamp(0.0, 1.0)
}

/// Replace the field near `primitive` by a least-squares fit of its density profile, over the
/// coefficients that influence the primitive's bounds grown by the profile's half width;
/// coefficients elsewhere are untouched.
///
/// `width` is the profile's transition width in world units (about two knot spans keeps the
/// fitted iso-surface within a few hundredths of a span of the true one).
///
/// # Errors
/// As [`refit_box`]; a primitive that misses the lattice changes nothing and is not an error.
pub fn fit_primitive(
    lattice: &mut BSplineLattice,
    primitive: &Primitive,
    width: f32,
    samples_per_span: usize,
) -> Result<(), FitError> {
    let (lo, hi) = primitive.bounds();
    let pad = Vec3::splat(0.5 * width.abs());
    let Some(b) = coeff_box_around(lattice, lo - pad, hi + pad, 0) else {
        return Ok(());
    };
    refit_box(lattice, b.min, b.max, samples_per_span, |x| {
        primitive.density(x, width)
    })
}

/// A new lattice holding the fitted density profile of `primitive`.
///
/// # Errors
/// As [`refit_box`].
pub fn lattice_from_primitive(
    dims: [usize; 3],
    spacing: f32,
    origin: Vec3,
    primitive: &Primitive,
    width: f32,
    samples_per_span: usize,
) -> Result<BSplineLattice, FitError> {
    let mut lattice =
        BSplineLattice::zeros(dims, spacing, origin).map_err(|_| FitError::BadBox {
            coeffs: super::mass_grid::CoeffBox {
                min: [0; 3],
                max: dims,
            },
            dims,
        })?;
    super::refit::fit_lattice(&mut lattice, samples_per_span, |x| {
        primitive.density(x, width)
    })?;
    Ok(lattice)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn find_surface(lattice: &BSplineLattice, from: Vec3, dir: Vec3, len: f32) -> f32 {
        // Bisection along a ray from inside to outside.
        let (mut a, mut b) = (0.0, len);
        for _ in 0..40 {
            let m = 0.5 * (a + b);
            if lattice.value(from + dir * m) > lattice.iso {
                a = m;
            } else {
                b = m;
            }
        }
        0.5 * (a + b)
    }

    #[test]
    fn fitted_sphere_surface_is_close_to_the_true_one() {
        let sphere = Primitive::Sphere {
            centre: Vec3::splat(1.6),
            radius: 1.0,
        };
        let lattice =
            lattice_from_primitive([17, 17, 17], 0.2, Vec3::ZERO, &sphere, 0.4, 2).unwrap();
        for dir in [
            Vec3::X,
            Vec3::NEG_Y,
            Vec3::new(1.0, 1.0, 1.0).normalize(),
            Vec3::new(-0.3, 0.5, -0.8).normalize(),
        ] {
            let r = find_surface(&lattice, Vec3::splat(1.6), dir, 1.5);
            assert!((r - 1.0).abs() < 0.02, "radius {r} along {dir}");
        }
        assert!(lattice.value(Vec3::splat(1.6)) > 0.9);
        assert!(lattice.value(Vec3::new(0.05, 0.05, 0.05)).abs() < 0.02);
    }

    #[test]
    fn signed_distances_are_right_on_known_points() {
        let b = Primitive::Box {
            centre: Vec3::ZERO,
            half_extents: Vec3::new(1.0, 2.0, 3.0),
        };
        assert!((b.signed_distance(Vec3::new(2.0, 0.0, 0.0)) - 1.0).abs() < 1e-6);
        assert!((b.signed_distance(Vec3::ZERO) + 1.0).abs() < 1e-6);
        let t = Primitive::Torus {
            centre: Vec3::ZERO,
            major_radius: 2.0,
            minor_radius: 0.5,
        };
        assert!(t.signed_distance(Vec3::new(2.0, 0.0, 0.0)) + 0.5 < 1e-6);
        assert!((t.signed_distance(Vec3::ZERO) - 1.5).abs() < 1e-6);
        let c = Primitive::Cylinder {
            centre: Vec3::ZERO,
            radius: 1.0,
            half_height: 2.0,
        };
        assert!((c.signed_distance(Vec3::new(0.0, 0.0, 3.0)) - 1.0).abs() < 1e-6);
        assert!((c.signed_distance(Vec3::new(3.0, 0.0, 0.0)) - 2.0).abs() < 1e-6);
    }

    #[test]
    fn fit_primitive_only_touches_coefficients_near_it() {
        let mut lattice = BSplineLattice::zeros([20, 20, 20], 0.1, Vec3::ZERO).unwrap();
        let cyl = Primitive::Cylinder {
            centre: Vec3::splat(0.5),
            radius: 0.2,
            half_height: 0.2,
        };
        fit_primitive(&mut lattice, &cyl, 0.2, 2).unwrap();
        assert!(lattice.is_inside(Vec3::splat(0.5)));
        assert!(!lattice.is_inside(Vec3::new(0.5, 0.5, 0.75)));
        // Coefficient 15 is centred at 1.5 > 0.5 + 0.2 + 0.1 + 0.2: untouched.
        assert_eq!(lattice.coeffs[lattice.index(15, 15, 15)], 0.0);
    }
}
