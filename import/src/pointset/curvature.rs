//! How the clay's unit normal turns around a point of its surface: the normal's gradient
//! `W = dn/dx` (the shape operator, extended to 3D), taken from the clay's own gradient so it
//! is as fresh as the point's normal.
//!
//! A splat drawn with one normal is lit flat, and the splats of a curved surface (a groove's
//! wall) show as facets. With `W`, a renderer lights each pixel of a splat with
//! `n + W·(x − p)`, the surface's normal at that offset to first order, so neighbouring
//! splats agree where they overlap and the surface shades smoothly (Phong splatting). The
//! largest eigenvalue of `W` is the largest principal curvature, which bounds how large a
//! flat disc may be before it leaves the surface.
//!
//! `W` comes from central differences of the normal `−∇F/‖∇F‖` along the three axes, a step
//! of a fraction of the point spacing apart: six evaluations of the clay's gradient. The
//! clay's field is a cubic B-spline, twice continuously differentiable, so the differences
//! converge with the square of the step. The result is projected onto the tangent plane on
//! both sides and symmetrised, as the shape operator is.

use glam::{Mat3, Vec3};

use dynaclay_core::field::MultiPatchField;

/// The gradient of the unit normal at a surface point, a symmetric 3×3 matrix acting on
/// tangent offsets, stored as its diagonal and the three entries above it; units: per the
/// clay's unit (a change of normal per unit of length). Zero on a plane.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct NormalGradient {
    /// `(Wxx, Wyy, Wzz)`, per clay unit.
    pub diagonal_per_fu: Vec3,
    /// `(Wxy, Wxz, Wyz)`, per clay unit.
    pub off_diagonal_per_fu: Vec3,
}

impl NormalGradient {
    /// A plane's: no turning.
    pub const FLAT: Self = Self {
        diagonal_per_fu: Vec3::ZERO,
        off_diagonal_per_fu: Vec3::ZERO,
    };

    /// The full matrix.
    #[must_use]
    pub fn matrix(&self) -> Mat3 {
        let (d, o) = (self.diagonal_per_fu, self.off_diagonal_per_fu);
        Mat3::from_cols(
            Vec3::new(d.x, o.x, o.y),
            Vec3::new(o.x, d.y, o.z),
            Vec3::new(o.y, o.z, d.z),
        )
    }

    /// The symmetric part of `m`.
    #[must_use]
    pub fn from_matrix(m: Mat3) -> Self {
        let s = |a: f32, b: f32| 0.5 * (a + b);
        Self {
            diagonal_per_fu: Vec3::new(m.x_axis.x, m.y_axis.y, m.z_axis.z),
            off_diagonal_per_fu: Vec3::new(
                s(m.y_axis.x, m.x_axis.y),
                s(m.z_axis.x, m.x_axis.z),
                s(m.z_axis.y, m.y_axis.z),
            ),
        }
    }

    /// The normal `offset` away from the point along its tangent plane, to first order:
    /// `normalize(n + W·offset)` (`n` itself where that degenerates).
    #[must_use]
    pub fn normal_at(&self, normal: Vec3, offset: Vec3) -> Vec3 {
        (normal + self.matrix() * offset)
            .try_normalize()
            .unwrap_or(normal)
    }

    /// The largest principal curvature in magnitude, per clay unit: the largest `|W·t|` over
    /// unit tangents `t`, bounded above by the matrix's Frobenius norm (used as is: the
    /// bound errs toward smaller discs).
    #[must_use]
    pub fn max_curvature_per_fu(&self) -> f32 {
        let (d, o) = (self.diagonal_per_fu, self.off_diagonal_per_fu);
        (d.length_squared() + 2.0 * o.length_squared()).sqrt()
    }

    /// Whether every entry is finite.
    #[must_use]
    pub fn is_finite(&self) -> bool {
        self.diagonal_per_fu.is_finite() && self.off_diagonal_per_fu.is_finite()
    }
}

/// The unit outward normal `−∇F/‖∇F‖` of `field` at `x`, or `None` where the gradient
/// vanishes or is not finite.
fn unit_normal(field: &MultiPatchField, x: Vec3) -> Option<Vec3> {
    let (_, g) = field.value_and_gradient(x);
    let len = g.length();
    (len > 1e-10 && len.is_finite()).then(|| -g / len)
}

/// The normal's gradient at the surface point `p` (unit outward normal `normal`), from
/// central differences `step_fu` apart; `None` where the clay's gradient vanishes at a
/// sample or `step_fu` is not positive.
#[must_use]
pub fn normal_gradient(
    field: &MultiPatchField,
    p: Vec3,
    normal: Vec3,
    step_fu: f32,
) -> Option<NormalGradient> {
    if !(step_fu.is_finite() && step_fu > 0.0) {
        return None;
    }
    let mut columns = [Vec3::ZERO; 3];
    for (axis, column) in columns.iter_mut().enumerate() {
        let e = Vec3::AXES[axis] * step_fu;
        let ahead = unit_normal(field, p + e)?;
        let behind = unit_normal(field, p - e)?;
        *column = (ahead - behind) / (2.0 * step_fu);
    }
    let jacobian = Mat3::from_cols(columns[0], columns[1], columns[2]);
    // Onto the tangent plane on both sides: the normal turns within it, along it.
    let tangent =
        Mat3::IDENTITY - Mat3::from_cols(normal * normal.x, normal * normal.y, normal * normal.z);
    let w = NormalGradient::from_matrix(tangent * jacobian * tangent);
    w.is_finite().then_some(w)
}

#[cfg(test)]
mod tests {
    use super::*;
    use dynaclay_core::field::{BSplineLattice, fit_lattice};

    /// A ball of radius `r` around the origin: density `0.5 − (|x|² − r²) / (1.6 r)`,
    /// iso-level 0.5, fitted on a lattice over `± 2` with knots 0.125 apart. A quadratic is
    /// in the cubic B-splines' space, so the fit is exact and its level sets are spheres (a
    /// clamped profile's kinks, smoothed by the fit, bend the normals near them).
    fn ball(radius: f32) -> MultiPatchField {
        let spacing = 0.125;
        let mut lattice =
            BSplineLattice::zeros([35; 3], spacing, Vec3::splat(-2.0 - spacing)).unwrap();
        fit_lattice(&mut lattice, 2, |x| {
            0.5 - (x.length_squared() - radius * radius) / (1.6 * radius)
        })
        .unwrap();
        lattice.iso = 0.5;
        MultiPatchField::from(lattice)
    }

    /// On a sphere of radius r the normal's gradient is `(I − nnᵀ)/r`: both principal
    /// curvatures 1/r, nothing along the normal; and the normal it predicts a small step
    /// along the surface is the sphere's normal there.
    #[test]
    fn a_sphere_turns_its_normal_by_one_over_its_radius() {
        let r = 1.0;
        let field = ball(r);
        for dir in [
            Vec3::X,
            Vec3::new(0.3, -0.8, 0.52).normalize(),
            Vec3::new(-0.6, 0.6, 0.53).normalize(),
        ] {
            let p = dir * r;
            let w = normal_gradient(&field, p, dir, 0.02).unwrap();
            let m = w.matrix();
            let expected = (Mat3::IDENTITY
                - Mat3::from_cols(dir * dir.x, dir * dir.y, dir * dir.z))
                * (1.0 / r);
            for c in 0..3 {
                let d = (m.col(c) - expected.col(c)).length();
                assert!(
                    d < 0.08,
                    "at {p}: column {c} {} vs {}",
                    m.col(c),
                    expected.col(c)
                );
            }
            assert!(
                (m * dir).length() < 1e-3,
                "no turning along the normal at {p}"
            );
            let k = w.max_curvature_per_fu();
            assert!((1.0..1.6).contains(&k), "curvature bound {k} at {p}");
            let t = dir.any_orthonormal_vector() * 0.1;
            let predicted = w.normal_at(dir, t);
            let truth = (p + t).normalize();
            assert!(
                predicted.angle_between(truth) < 0.01,
                "{predicted} vs {truth} at {p}"
            );
        }
    }

    #[test]
    fn a_bad_step_or_an_empty_clay_gives_none() {
        let field = ball(1.0);
        assert!(normal_gradient(&field, Vec3::X, Vec3::X, 0.0).is_none());
        assert!(normal_gradient(&field, Vec3::X, Vec3::X, f32::NAN).is_none());
        let empty =
            MultiPatchField::from(BSplineLattice::zeros([8; 3], 1.0, Vec3::splat(-4.0)).unwrap());
        assert!(normal_gradient(&empty, Vec3::ZERO, Vec3::X, 0.1).is_none());
    }
}
