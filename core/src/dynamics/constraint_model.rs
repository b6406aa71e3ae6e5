//! Geometric constraints on the clay (Hua & Qin §7.3, eq. 9): what a user pins, and the linear
//! rows `c(p) = C p − e = 0` on the B-spline coefficients each pin stands for.
//!
//! The paper writes the constraints on the densities, `L d + b = 0`; since `d = A p` and the
//! field value and gradient at a point are linear in `p`, each constraint is written here
//! directly on the coefficients (`L A = C`), so the dynamics of eq. (7) keep their form and
//! only the coefficients around a pin take part. Three kinds:
//! - a **point** keeps `s(x) = c0` (the point stays on the surface);
//! - a **curve** is point constraints sampled along a polyline, [`CURVE_SAMPLES_PER_SPAN`]
//!   per knot span (a cubic B-spline cannot bend faster than that between two samples);
//! - a **normal** keeps the direction of `∇s(x)`: `t1·∇s(x) = 0` and `t2·∇s(x) = 0` for two
//!   tangents `t1, t2` orthogonal to the normal it had when pinned (two linear conditions; the
//!   gradient's length stays free). Pin a point at the same place to keep the surface there too.
//!
//! Every row is scaled to unit length, so rank and residual tolerances read the same for every
//! kind. Building rows allocates; it runs when constraints change or a region is made, never
//! in the haptic loop.

use glam::{Affine3A, Vec3};
use serde::{Deserialize, Serialize};

use crate::field::{BSplineLattice, MultiPatchField, OtherPatches, cubic_weights_and_derivatives};

/// Point samples per knot span along a curve constraint.
pub const CURVE_SAMPLES_PER_SPAN: f32 = 2.0;
/// Most point samples one curve may produce (bounds the rows before they are allocated).
pub const MAX_CURVE_SAMPLES: usize = 4096;
/// Most vertices a curve's polyline may have.
pub const MAX_CURVE_POINTS: usize = 4096;
/// Most constraints a clay may carry.
pub const MAX_CONSTRAINTS: usize = 4096;
/// Bisection steps when a point is projected onto the surface.
const PROJECT_STEPS: usize = 40;

/// One pin on the clay, in world coordinates.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Constraint {
    /// `s(at) = c0`: the point stays on the surface.
    Point {
        /// The pinned point (on the surface when pinned).
        at: Vec3,
    },
    /// The surface keeps passing through this polyline (sampled as points).
    Curve {
        /// Vertices of the polyline, in order.
        points: Vec<Vec3>,
    },
    /// The gradient at `at` keeps the direction `normal`.
    Normal {
        /// Where the normal is kept.
        at: Vec3,
        /// The unit normal (gradient direction) to keep.
        normal: Vec3,
    },
}

/// Why a constraint could not be made or turned into rows.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ConstraintError {
    /// A coordinate is NaN or infinite.
    #[error("{what} has a coordinate that is not a finite number")]
    NonFinite {
        /// Which input.
        what: &'static str,
    },
    /// The point lies outside the clay's lattice.
    #[error("{what} at {at} lies outside the clay's lattice")]
    OutsideLattice {
        /// Which input.
        what: &'static str,
        /// The point.
        at: Vec3,
    },
    /// No surface crossing was found near the point.
    #[error("no surface found within {searched} of {at}")]
    NoSurfaceNear {
        /// The point.
        at: Vec3,
        /// How far along the gradient the search went, world units.
        searched: f32,
    },
    /// The clay has no patch with this index.
    #[error("the clay has no patch {patch} (it has {patches})")]
    NoSuchPatch {
        /// The patch asked for.
        patch: usize,
        /// Patches on the clay.
        patches: usize,
    },
    /// The gradient vanishes at the point (no normal to keep).
    #[error("the field has no gradient at {at} (no normal to keep)")]
    FlatField {
        /// The point.
        at: Vec3,
    },
    /// A curve needs at least two vertices.
    #[error("a curve needs at least 2 points, got {got}")]
    TooFewPoints {
        /// Vertices given.
        got: usize,
    },
    /// A curve is too long or has too many vertices.
    #[error("a curve of {got} {what} exceeds the limit of {limit}")]
    TooLarge {
        /// What was counted.
        what: &'static str,
        /// How many.
        got: usize,
        /// The bound.
        limit: usize,
    },
}

/// One linear condition `Σ w_i p_i = target` on the lattice's coefficients (unit-length `w`).
#[derive(Clone, Debug, PartialEq)]
pub struct ConstraintRow {
    /// Lattice coefficient indices and their weights.
    pub terms: Vec<(usize, f32)>,
    /// The value the weighted sum must keep.
    pub target: f32,
}

impl ConstraintRow {
    /// `Σ w_i p_i − target` on `lattice`'s coefficients.
    #[must_use]
    pub fn residual(&self, lattice: &BSplineLattice) -> f32 {
        let sum: f64 = self
            .terms
            .iter()
            .map(|&(i, w)| f64::from(w) * f64::from(lattice.coeffs[i]))
            .sum();
        (sum - f64::from(self.target)) as f32
    }

    /// Scales the row to unit length; a row with no weight keeps none (and is dropped by the
    /// caller).
    fn normalised(mut self) -> Option<Self> {
        let norm = self
            .terms
            .iter()
            .map(|&(_, w)| f64::from(w) * f64::from(w))
            .sum::<f64>()
            .sqrt();
        if norm.is_nan() || norm <= 1e-12 {
            return None;
        }
        let inv = (1.0 / norm) as f32;
        self.terms.iter_mut().for_each(|(_, w)| *w *= inv);
        self.target *= inv;
        Some(self)
    }
}

fn check_finite(what: &'static str, v: Vec3) -> Result<(), ConstraintError> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(ConstraintError::NonFinite { what })
    }
}

fn check_inside(
    lattice: &BSplineLattice,
    what: &'static str,
    at: Vec3,
) -> Result<(), ConstraintError> {
    check_finite(what, at)?;
    let (lo, hi) = lattice.support();
    if at.cmplt(lo).any() || at.cmpgt(hi).any() {
        return Err(ConstraintError::OutsideLattice { what, at });
    }
    Ok(())
}

/// The 64 coefficients around `x` with the value weights and the gradient weights (per world
/// unit) of each; coefficients outside the lattice are left out (they are zero).
fn stencil(lattice: &BSplineLattice, x: Vec3) -> Vec<(usize, f32, Vec3)> {
    let u = lattice.to_lattice(x);
    let base = u.floor();
    let t = u - base;
    let (wx, dx) = cubic_weights_and_derivatives(t.x);
    let (wy, dy) = cubic_weights_and_derivatives(t.y);
    let (wz, dz) = cubic_weights_and_derivatives(t.z);
    let inv_h = 1.0 / lattice.spacing;
    let index = |b: f32, o: usize, n: usize| {
        let i = b as i64 - 1 + o as i64;
        (0..n as i64).contains(&i).then_some(i as usize)
    };
    let mut out = Vec::with_capacity(64);
    for c in 0..4 {
        let Some(k) = index(base.z, c, lattice.dims[2]) else {
            continue;
        };
        for b in 0..4 {
            let Some(j) = index(base.y, b, lattice.dims[1]) else {
                continue;
            };
            for a in 0..4 {
                let Some(i) = index(base.x, a, lattice.dims[0]) else {
                    continue;
                };
                let value = wx[a] * wy[b] * wz[c];
                let grad = Vec3::new(
                    dx[a] * wy[b] * wz[c],
                    wx[a] * dy[b] * wz[c],
                    wx[a] * wy[b] * dz[c],
                ) * inv_h;
                out.push((lattice.index(i, j, k), value, grad));
            }
        }
    }
    out
}

/// The point nearest `at` along the gradient line of the clay `field` (the sum of its patches)
/// where `F = c₀`: a bracket is searched outward along `±∇F` up to `reach` world units, in
/// steps of a quarter of the finest knot span, then bisected.
///
/// # Errors
/// When `at` is not finite or outside the clay, or no crossing lies within `reach`.
pub fn project_onto_surface(
    field: &MultiPatchField,
    at: Vec3,
    reach: f32,
) -> Result<Vec3, ConstraintError> {
    check_inside_clay(field, "the point", at)?;
    let iso = field.iso();
    let f = |x: Vec3| field.value(x) - iso;
    let f0 = f(at);
    if f0 == 0.0 {
        return Ok(at);
    }
    let g = field.value_and_gradient(at).1;
    if !g.is_finite() || g.length_squared() <= 0.0 {
        return Err(ConstraintError::NoSurfaceNear {
            at,
            searched: reach,
        });
    }
    // Inside (f > 0) the surface lies down the gradient; outside, up it.
    let dir = g.normalize() * if f0 > 0.0 { -1.0 } else { 1.0 };
    let step = 0.25 * field.finest_spacing();
    let mut near = at;
    let mut travelled = 0.0;
    while travelled < reach {
        let next = near + dir * step;
        travelled += step;
        if f(next).signum() != f0.signum() || f(next) == 0.0 {
            let (mut a, mut b) = (near, next);
            for _ in 0..PROJECT_STEPS {
                let m = 0.5 * (a + b);
                if f(m).signum() == f0.signum() && f(m) != 0.0 {
                    a = m;
                } else {
                    b = m;
                }
            }
            // The end with the smaller |F − c0|.
            return Ok(if f(a).abs() < f(b).abs() { a } else { b });
        }
        near = next;
    }
    Err(ConstraintError::NoSurfaceNear {
        at,
        searched: reach,
    })
}

/// Checks that `at` is finite and inside the clay's support (every patch's, in world
/// coordinates).
fn check_inside_clay(
    field: &MultiPatchField,
    what: &'static str,
    at: Vec3,
) -> Result<(), ConstraintError> {
    check_finite(what, at)?;
    let (lo, hi) = field.support();
    if at.cmplt(lo).any() || at.cmpgt(hi).any() {
        return Err(ConstraintError::OutsideLattice { what, at });
    }
    Ok(())
}

impl Constraint {
    /// A normal constraint at `at` keeping the direction the clay's gradient (of the sum of
    /// its patches) has there now.
    ///
    /// # Errors
    /// When `at` is outside the clay or the gradient vanishes there.
    pub fn normal_here(field: &MultiPatchField, at: Vec3) -> Result<Self, ConstraintError> {
        check_inside_clay(field, "the normal's point", at)?;
        let g = field.value_and_gradient(at).1;
        if !g.is_finite() || g.length() <= 1e-6 {
            return Err(ConstraintError::FlatField { at });
        }
        Ok(Self::Normal {
            at,
            normal: g.normalize(),
        })
    }

    /// Short name of the kind (`point`, `curve`, `normal`).
    #[must_use]
    pub fn kind_name(&self) -> &'static str {
        match self {
            Self::Point { .. } => "point",
            Self::Curve { .. } => "curve",
            Self::Normal { .. } => "normal",
        }
    }

    /// Checks coordinates and sizes (for constraints read from a file or a script).
    ///
    /// # Errors
    /// When a coordinate is not finite, a normal is not a direction, or a curve has too few
    /// or too many vertices.
    pub fn validate(&self) -> Result<(), ConstraintError> {
        match self {
            Self::Point { at } => check_finite("the point", *at),
            Self::Normal { at, normal } => {
                check_finite("the normal's point", *at)?;
                check_finite("the normal", *normal)?;
                if normal.length() <= 1e-6 {
                    return Err(ConstraintError::FlatField { at: *at });
                }
                Ok(())
            }
            Self::Curve { points } => {
                if points.len() < 2 {
                    return Err(ConstraintError::TooFewPoints { got: points.len() });
                }
                if points.len() > MAX_CURVE_POINTS {
                    return Err(ConstraintError::TooLarge {
                        what: "points",
                        got: points.len(),
                        limit: MAX_CURVE_POINTS,
                    });
                }
                points
                    .iter()
                    .try_for_each(|&p| check_finite("a curve point", p))
            }
        }
    }

    /// The points a curve is sampled at: both ends and [`CURVE_SAMPLES_PER_SPAN`] per knot
    /// span of `spacing` along each segment (for the other kinds, their single point).
    ///
    /// # Errors
    /// When the curve would need more than [`MAX_CURVE_SAMPLES`] samples.
    pub fn sample_points(&self, spacing: f32) -> Result<Vec<Vec3>, ConstraintError> {
        match self {
            Self::Point { at } | Self::Normal { at, .. } => Ok(vec![*at]),
            Self::Curve { points } => {
                let step = spacing / CURVE_SAMPLES_PER_SPAN;
                let mut count = 1_usize;
                for w in points.windows(2) {
                    let pieces = ((w[1] - w[0]).length() / step).ceil().max(1.0);
                    if !pieces.is_finite() || pieces >= MAX_CURVE_SAMPLES as f32 {
                        count = MAX_CURVE_SAMPLES + 1;
                        break;
                    }
                    count += pieces as usize;
                }
                if count > MAX_CURVE_SAMPLES {
                    return Err(ConstraintError::TooLarge {
                        what: "samples",
                        got: count,
                        limit: MAX_CURVE_SAMPLES,
                    });
                }
                let mut out = Vec::with_capacity(count);
                out.push(points[0]);
                for w in points.windows(2) {
                    let pieces = ((w[1] - w[0]).length() / step).ceil().max(1.0) as usize;
                    for s in 1..=pieces {
                        out.push(w[0].lerp(w[1], s as f32 / pieces as f32));
                    }
                }
                Ok(out)
            }
        }
    }

    /// The linear rows this constraint stands for on `lattice`'s coefficients (the clay is
    /// that one lattice).
    ///
    /// # Errors
    /// When the constraint is invalid or one of its points lies outside the lattice.
    pub fn rows(&self, lattice: &BSplineLattice) -> Result<Vec<ConstraintRow>, ConstraintError> {
        self.patch_rows(lattice, &PatchFrame::alone(lattice))
    }

    /// The rows this constraint stands for on the coefficients of patch `patch` of the clay
    /// `field`, whose surface is that of the sum `F(x) = Σ sᵢ(Tᵢ x) = c₀` (Hua & Qin
    /// eq. (3)). The other patches stay fixed while this one moves, so each row holds the
    /// sum: a point row keeps `s(T x) = c₀ − (the others at x)`, a normal row keeps the
    /// tangential part of `∇F` zero with `∇ s(T x) = Tᵀ ∇s`. Curves are sampled at the base
    /// patch's spacing on every patch. A point outside a detail patch's support gives no row
    /// (that patch cannot move the surface there); on the base patch it is an error.
    ///
    /// # Errors
    /// When the constraint is invalid, `patch` does not exist, or (base patch) a point lies
    /// outside the lattice.
    pub fn rows_on_patch(
        &self,
        field: &MultiPatchField,
        patch: usize,
    ) -> Result<Vec<ConstraintRow>, ConstraintError> {
        let Some(this) = field.patches.get(patch) else {
            return Err(ConstraintError::NoSuchPatch {
                patch,
                patches: field.patches.len(),
            });
        };
        let frame = PatchFrame {
            world_to_patch: this.world_to_patch,
            others: OtherPatches {
                before: &field.patches[..patch],
                after: &field.patches[patch + 1..],
            },
            iso: field.iso(),
            sample_spacing: field.base().spacing,
            outside_is_error: patch == 0,
        };
        self.patch_rows(&this.lattice, &frame)
    }

    /// The rows on `lattice`, placed in the clay by `frame`.
    fn patch_rows(
        &self,
        lattice: &BSplineLattice,
        frame: &PatchFrame<'_>,
    ) -> Result<Vec<ConstraintRow>, ConstraintError> {
        self.validate()?;
        let mut rows = Vec::new();
        // `None`: the point lies outside a detail patch (no row).
        let place = |what: &'static str, x: Vec3| -> Result<Option<Vec3>, ConstraintError> {
            let u = frame.world_to_patch.transform_point3(x);
            match check_inside(lattice, what, u) {
                Ok(()) => Ok(Some(u)),
                Err(_) if !frame.outside_is_error => Ok(None),
                Err(e) => Err(e),
            }
        };
        match self {
            Self::Point { .. } | Self::Curve { .. } => {
                for x in self.sample_points(frame.sample_spacing)? {
                    let Some(u) = place("a pinned point", x)? else {
                        continue;
                    };
                    let others = if frame.others.is_empty() {
                        0.0
                    } else {
                        frame.others.value(x)
                    };
                    let row = ConstraintRow {
                        terms: stencil(lattice, u)
                            .into_iter()
                            .map(|(i, w, _)| (i, w))
                            .collect(),
                        target: frame.iso - others,
                    };
                    rows.extend(row.normalised());
                }
            }
            Self::Normal { at, normal } => {
                let Some(u) = place("the normal's point", *at)? else {
                    return Ok(rows);
                };
                let n = normal.normalize();
                let t1 = n.any_orthonormal_vector();
                let t2 = n.cross(t1);
                let taps = stencil(lattice, u);
                let others_gradient = if frame.others.is_empty() {
                    Vec3::ZERO
                } else {
                    frame.others.value_and_gradient(*at).1
                };
                let jacobian = frame.world_to_patch.matrix3;
                for t in [t1, t2] {
                    // t · (Jᵀ g) = (J t) · g for each tap's patch gradient g.
                    let along = jacobian * t;
                    let row = ConstraintRow {
                        terms: taps.iter().map(|&(i, _, g)| (i, along.dot(g))).collect(),
                        target: -t.dot(others_gradient),
                    };
                    rows.extend(row.normalised());
                }
            }
        }
        Ok(rows)
    }
}

/// Where a patch sits in the clay, for its constraint rows.
struct PatchFrame<'a> {
    /// World coordinates to the patch's lattice coordinates.
    world_to_patch: Affine3A,
    /// The clay's other patches (fixed while this one moves).
    others: OtherPatches<'a>,
    /// The clay's iso-value.
    iso: f32,
    /// Spacing at which curves are sampled, world units.
    sample_spacing: f32,
    /// Whether a point outside the lattice is an error (else it gives no row).
    outside_is_error: bool,
}

impl PatchFrame<'_> {
    /// A clay that is `lattice` alone.
    fn alone(lattice: &BSplineLattice) -> Self {
        PatchFrame {
            world_to_patch: Affine3A::IDENTITY,
            others: OtherPatches {
                before: &[],
                after: &[],
            },
            iso: lattice.iso,
            sample_spacing: lattice.spacing,
            outside_is_error: true,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::{Primitive, lattice_from_primitive};

    const CENTRE: Vec3 = Vec3::new(0.95, 0.95, 0.95);

    fn sphere() -> BSplineLattice {
        let s = Primitive::Sphere {
            centre: CENTRE,
            radius: 0.4,
        };
        lattice_from_primitive([20, 20, 20], 0.1, Vec3::ZERO, &s, 0.2, 2).unwrap()
    }

    /// The sphere plus a detail patch with a bump in it, under a rotated, scaled map that
    /// puts `x` at the middle of the patch.
    fn sphere_with_detail(x: Vec3) -> MultiPatchField {
        let mut field = MultiPatchField::new(sphere());
        let mut detail = BSplineLattice::zeros([14; 3], 0.05, Vec3::ZERO).unwrap();
        detail.coeffs.update_each(|i, c| {
            let (x, y, z) = (i % 14, (i / 14) % 14, i / 196);
            *c = 0.3 * ((x as f32 * 0.7).sin() * (y as f32 * 0.4).cos() + 0.1 * z as f32);
        });
        let turn = glam::Quat::from_rotation_y(0.4);
        let map = Affine3A::from_scale_rotation_translation(
            Vec3::splat(0.9),
            turn,
            Vec3::splat(0.33) - turn * (0.9 * x),
        );
        field.push(detail, map);
        field
    }

    #[test]
    fn rows_on_a_patch_hold_the_sum_of_the_patches() {
        let x = CENTRE + Vec3::new(0.37, 0.05, -0.1);
        let field = sphere_with_detail(x);
        let inside = field.patches[1].world_to_patch.transform_point3(x);
        assert!(inside.cmpgt(Vec3::splat(0.2)).all() && inside.cmplt(Vec3::splat(0.5)).all());
        for patch in [0, 1] {
            let own = &field.patches[patch].lattice;
            let rows = Constraint::Point { at: x }
                .rows_on_patch(&field, patch)
                .unwrap();
            assert_eq!(rows.len(), 1);
            // residual · |w| = F(x) − c₀ with the others fixed, on either patch (w: the
            // stencil's weights before the row was made unit length).
            let u = field.patches[patch].world_to_patch.transform_point3(x);
            let weights: f32 = stencil(own, u).iter().map(|t| t.1 * t.1).sum();
            let r = rows[0].residual(own);
            assert!(
                ((field.value(x) - field.iso()) - r * weights.sqrt()).abs() < 1e-4,
                "patch {patch}: {r}"
            );
            let unit: f32 = rows[0].terms.iter().map(|t| t.1 * t.1).sum();
            assert!((unit - 1.0).abs() < 1e-5);

            // A normal row is met by the sum's own normal and is violated by a turned one.
            let here = Constraint::normal_here(&field, x).unwrap();
            for row in here.rows_on_patch(&field, patch).unwrap() {
                assert!(
                    row.residual(own).abs() < 1e-4,
                    "patch {patch}: {}",
                    row.residual(own)
                );
            }
            let g = field.value_and_gradient(x).1;
            let tilted = Constraint::Normal {
                at: x,
                normal: g.normalize().any_orthonormal_vector(),
            };
            let worst = tilted
                .rows_on_patch(&field, patch)
                .unwrap()
                .iter()
                .map(|r| r.residual(own).abs())
                .fold(0.0, f32::max);
            assert!(
                worst > 0.1 * g.length() / 1.0f32.max(g.length()),
                "patch {patch}: {worst}"
            );
        }
        // The one-patch clay gives exactly the lattice's rows.
        let alone = MultiPatchField::new(sphere());
        assert_eq!(
            Constraint::Point { at: x }
                .rows_on_patch(&alone, 0)
                .unwrap(),
            Constraint::Point { at: x }.rows(&sphere()).unwrap()
        );
        // Off the detail patch: no row there, an error on the base.
        let far = Vec3::new(0.2, 1.7, 1.8);
        assert!(
            field.patches[1]
                .world_to_patch
                .transform_point3(far)
                .cmplt(Vec3::ZERO)
                .any()
                || field.patches[1]
                    .world_to_patch
                    .transform_point3(far)
                    .cmpgt(Vec3::splat(0.65))
                    .any()
        );
        assert!(
            Constraint::Point { at: far }
                .rows_on_patch(&field, 1)
                .unwrap()
                .is_empty()
        );
        assert!(
            Constraint::Point {
                at: Vec3::splat(50.0)
            }
            .rows_on_patch(&field, 0)
            .is_err()
        );
        assert!(matches!(
            Constraint::Point { at: x }.rows_on_patch(&field, 2),
            Err(ConstraintError::NoSuchPatch {
                patch: 2,
                patches: 2
            })
        ));
    }

    #[test]
    fn a_point_row_evaluates_the_field_and_a_normal_row_the_tangential_gradient() {
        let lattice = sphere();
        let x = CENTRE + Vec3::new(0.37, 0.05, -0.1);
        let rows = Constraint::Point { at: x }.rows(&lattice).unwrap();
        assert_eq!(rows.len(), 1);
        assert_eq!(rows[0].terms.len(), 64);
        // residual · norm = s(x) − c0, so the signs agree and the row is unit length.
        let r = rows[0].residual(&lattice);
        assert_eq!(r.signum(), (lattice.value(x) - lattice.iso).signum());
        let n: f32 = rows[0].terms.iter().map(|t| t.1 * t.1).sum();
        assert!((n - 1.0).abs() < 1e-5);
        let normal = Constraint::normal_here(&MultiPatchField::new(lattice.clone()), x).unwrap();
        let rows = normal.rows(&lattice).unwrap();
        assert_eq!(rows.len(), 2);
        for row in &rows {
            assert!(
                row.residual(&lattice).abs() < 1e-5,
                "{}",
                row.residual(&lattice)
            );
        }
        // A different normal is violated.
        let tilted = Constraint::Normal {
            at: x,
            normal: Vec3::Y,
        };
        let worst = tilted
            .rows(&lattice)
            .unwrap()
            .iter()
            .map(|r| r.residual(&lattice).abs())
            .fold(0.0, f32::max);
        assert!(worst > 0.1, "{worst}");
    }

    #[test]
    fn projection_lands_on_the_surface_from_inside_and_outside() {
        let lattice = sphere();
        let clay = MultiPatchField::new(lattice.clone());
        for r in [0.3, 0.5] {
            let p = project_onto_surface(&clay, CENTRE + Vec3::new(r, 0.0, 0.0), 0.5).unwrap();
            assert!((lattice.value(p) - lattice.iso).abs() < 1e-5);
            assert!((p.y - CENTRE.y).abs() < 0.02, "moved along the normal: {p}");
        }
        assert!(matches!(
            project_onto_surface(&clay, Vec3::splat(f32::NAN), 0.5),
            Err(ConstraintError::NonFinite { .. })
        ));
        assert!(matches!(
            project_onto_surface(&clay, Vec3::splat(50.0), 0.5),
            Err(ConstraintError::OutsideLattice { .. })
        ));
    }

    #[test]
    fn a_curve_is_sampled_twice_per_knot_span_and_bounded() {
        let lattice = sphere();
        let c = Constraint::Curve {
            points: vec![Vec3::ZERO, Vec3::new(1.0, 0.0, 0.0)],
        };
        // 1.0 long at spacing 0.1: 20 pieces, 21 samples.
        assert_eq!(c.sample_points(lattice.spacing).unwrap().len(), 21);
        let long = Constraint::Curve {
            points: vec![Vec3::ZERO, Vec3::new(1.0e4, 0.0, 0.0)],
        };
        assert!(matches!(
            long.sample_points(0.1),
            Err(ConstraintError::TooLarge { .. })
        ));
        assert!(matches!(
            Constraint::Curve {
                points: vec![Vec3::ZERO]
            }
            .validate(),
            Err(ConstraintError::TooFewPoints { got: 1 })
        ));
    }
}
