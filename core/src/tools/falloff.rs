//! Falloff curves: the profile of a round brush from its centre to its edge, as sculpting
//! apps offer them (Blender's brush falloff presets: smooth, sphere, root, sharp, linear,
//! constant, and a user curve).
//!
//! A curve maps the distance from the brush's axis, as a fraction `u` of its radius
//! (`0` at the centre, `1` at the edge), to the brush's depth there as a fraction of its
//! radius. A round brush of radius `R` with curve `c` is the solid of revolution
//! `|z| ≤ R·c(ρ/R)`, `ρ ≤ R` about its local z axis ([`crate::tools::ToolShape::Profiled`]),
//! so a stroke carves (or deposits) a cross-section that follows the curve. The sphere
//! curve `√(1 − u²)` is the sphere itself: the default brush is the sphere tool unchanged.
//!
//! The preset formulas are Blender's (with `p = 1 − u`): smooth `3p² − 2p³`, sphere
//! `√(2p − p²)`, root `√p`, sharp `p²`, linear `p`, constant `1`. A custom curve is the
//! piecewise-linear line through a few control points.
//!
//! Evaluation is pure and allocates nothing.

use glam::{Quat, Vec3};
use serde::{Deserialize, Serialize};

use super::force::{PRESS_REACH_SPANS, anchor_normal};
use crate::field::MultiPatchField;

/// Most control points of a custom curve (enough for any profile a user draws by hand, few
/// enough that the brush's distance stays cheap).
pub const MAX_FALLOFF_POINTS: usize = 8;

/// Nodes of the polyline that stands for a preset curve in the brush's distance (the chord
/// error of the sphere curve between nodes is under half a percent of the radius).
pub const PRESET_NODES: usize = 48;

/// A brush's falloff curve: its depth (fraction of its radius) against the distance from its
/// axis (fraction of its radius).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FalloffCurve {
    /// `3p² − 2p³`: a bell, flat at the centre and at the edge.
    Smooth,
    /// `√(1 − u²)`: the round brush is a sphere (the default, the brush as it always was).
    #[default]
    Sphere,
    /// `√p`: full almost to the edge, then a steep wall.
    Root,
    /// `p²`: a narrow tip.
    Sharp,
    /// `p`: a cone.
    Linear,
    /// `1`: a flat-ended cylinder, a flat-bottomed groove with vertical walls.
    Constant,
    /// The piecewise-linear line through `[u, depth]` control points: `u` rising strictly
    /// from 0 to 1, depths within `[0, 1]`, at most [`MAX_FALLOFF_POINTS`] points.
    Custom(Vec<[f32; 2]>),
}

/// Why a falloff curve cannot be used.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum CurveError {
    /// Too few or too many control points.
    #[error("a custom falloff curve needs 2 to {max} control points, got {count}", max = MAX_FALLOFF_POINTS)]
    PointCount { count: usize },
    /// A control point is not finite or out of range.
    #[error("custom falloff curve point {index} = {point:?}: u and depth must lie within [0, 1]")]
    OutOfRange { index: usize, point: [f32; 2] },
    /// The control points do not run from the centre to the edge in order.
    #[error(
        "custom falloff curve point {index}: u must rise strictly from 0 (first point) to 1 (last point)"
    )]
    NotAscending { index: usize },
}

impl FalloffCurve {
    /// The presets, in menu order.
    pub const PRESETS: [FalloffCurve; 6] = [
        Self::Smooth,
        Self::Sphere,
        Self::Root,
        Self::Sharp,
        Self::Linear,
        Self::Constant,
    ];

    /// A custom curve to start editing from: the linear ramp with two inner points.
    #[must_use]
    pub fn default_custom() -> Self {
        Self::Custom(vec![
            [0.0, 1.0],
            [1.0 / 3.0, 2.0 / 3.0],
            [2.0 / 3.0, 1.0 / 3.0],
            [1.0, 0.0],
        ])
    }

    /// Short name for menus and scripts.
    #[must_use]
    pub fn name(&self) -> &'static str {
        match self {
            Self::Smooth => "smooth",
            Self::Sphere => "sphere",
            Self::Root => "root",
            Self::Sharp => "sharp",
            Self::Linear => "linear",
            Self::Constant => "constant",
            Self::Custom(_) => "custom",
        }
    }

    /// Whether this is the sphere curve (the default, which leaves a sphere a sphere).
    #[must_use]
    pub fn is_sphere(&self) -> bool {
        matches!(self, Self::Sphere)
    }

    /// Checks a custom curve's control points (presets are always valid).
    ///
    /// # Errors
    /// The count, or the first point out of range or out of order.
    pub fn validate(&self) -> Result<(), CurveError> {
        let Self::Custom(points) = self else {
            return Ok(());
        };
        if !(2..=MAX_FALLOFF_POINTS).contains(&points.len()) {
            return Err(CurveError::PointCount {
                count: points.len(),
            });
        }
        for (index, &point) in points.iter().enumerate() {
            if !point.iter().all(|v| (0.0..=1.0).contains(v)) {
                return Err(CurveError::OutOfRange { index, point });
            }
        }
        let last = points.len() - 1;
        if points[0][0] != 0.0 {
            return Err(CurveError::NotAscending { index: 0 });
        }
        if points[last][0] != 1.0 {
            return Err(CurveError::NotAscending { index: last });
        }
        if let Some(index) = (1..points.len()).find(|&i| points[i][0] <= points[i - 1][0]) {
            return Err(CurveError::NotAscending { index });
        }
        Ok(())
    }

    /// The depth, a fraction of the radius, at `u` (distance from the axis over the radius,
    /// clamped to `[0, 1]`).
    #[inline]
    #[must_use]
    pub fn value(&self, u: f32) -> f32 {
        let u = u.clamp(0.0, 1.0);
        let p = 1.0 - u;
        match self {
            Self::Smooth => p * p * (3.0 - 2.0 * p),
            Self::Sphere => (2.0 * p - p * p).max(0.0).sqrt(),
            Self::Root => p.sqrt(),
            Self::Sharp => p * p,
            Self::Linear => p,
            Self::Constant => 1.0,
            Self::Custom(points) => custom_value(points, u),
        }
    }

    /// How many polyline nodes stand for the curve in [`Self::node`].
    #[inline]
    #[must_use]
    pub fn node_count(&self) -> usize {
        match self {
            Self::Custom(points) => points.len(),
            Self::Linear | Self::Constant => 2,
            _ => PRESET_NODES + 1,
        }
    }

    /// Node `i` (`[u, depth]`) of the polyline standing for the curve: a custom curve's own
    /// points, a preset sampled evenly in `u` (exact for the linear and constant curves).
    #[inline]
    #[must_use]
    pub fn node(&self, i: usize) -> [f32; 2] {
        match self {
            Self::Custom(points) => points[i.min(points.len() - 1)],
            _ => {
                let u = i as f32 / (self.node_count() - 1) as f32;
                [u, self.value(u)]
            }
        }
    }

    /// The greatest depth, a fraction of the radius.
    #[must_use]
    pub fn max_depth(&self) -> f32 {
        (0..self.node_count())
            .map(|i| self.node(i)[1])
            .fold(0.0, f32::max)
    }

    /// The farthest point of the profile from the brush's centre, a fraction of the radius.
    #[must_use]
    pub fn max_reach(&self) -> f32 {
        (0..self.node_count())
            .map(|i| {
                let [u, v] = self.node(i);
                u.hypot(v)
            })
            .fold(0.0, f32::max)
    }

    /// `∫₀¹ u·c(u) du` over the polyline: the brush's volume is `4π·R³` times this.
    #[must_use]
    pub fn first_moment(&self) -> f32 {
        (1..self.node_count())
            .map(|i| {
                let [u0, c0] = self.node(i - 1);
                let [u1, c1] = self.node(i);
                (u1 - u0) / 6.0 * (2.0 * u0 * c0 + u0 * c1 + u1 * c0 + 2.0 * u1 * c1)
            })
            .sum()
    }

    /// Signed distance (negative inside) from a point at distance `rho` from the axis and
    /// height `z` above the brush's middle plane to the surface of the brush of radius
    /// `radius` with this curve: exact for the polyline of [`Self::node`], so within its
    /// chord error of the curve. Allocates nothing.
    #[must_use]
    pub fn signed_distance(&self, rho: f32, z: f32, radius: f32) -> f32 {
        let q = [rho / radius, z.abs() / radius];
        // The boundary in the meridian half-plane: the profile's polyline and the wall
        // from its last node down to the middle plane (the axis and the middle plane are
        // symmetry lines inside the solid, not boundary).
        let mut nearest_sq = f32::INFINITY;
        let mut previous = self.node(0);
        for i in 1..self.node_count() {
            let node = self.node(i);
            nearest_sq = nearest_sq.min(segment_distance_sq(q, previous, node));
            previous = node;
        }
        nearest_sq = nearest_sq.min(segment_distance_sq(q, previous, [previous[0], 0.0]));
        let inside = q[0] <= 1.0 && q[1] <= self.polyline_value(q[0]);
        let distance = nearest_sq.sqrt() * radius;
        if inside { -distance } else { distance }
    }

    /// The polyline of [`Self::node`] at `u` in `[0, 1]`.
    fn polyline_value(&self, u: f32) -> f32 {
        match self {
            Self::Custom(points) => custom_value(points, u),
            Self::Linear | Self::Constant => self.value(u),
            _ => {
                let x = u.clamp(0.0, 1.0) * PRESET_NODES as f32;
                let i = (x.floor() as usize).min(PRESET_NODES - 1);
                let [u0, c0] = self.node(i);
                let [_, c1] = self.node(i + 1);
                let t = (u - u0) * PRESET_NODES as f32;
                c0 + (c1 - c0) * t.clamp(0.0, 1.0)
            }
        }
    }
}

/// The turn that makes a profiled brush face the clay at `at` (its local z along the clay's
/// outward normal there, [`anchor_normal`]), so that its profile is carved into the surface
/// whichever face the stroke is on; no turn where no normal is found. A stroke takes it at
/// each point where the brush acts, on the clay as it was when the stroke began: the brush
/// follows the surface (a stroke begun over an edge still carves its profile into the face it
/// runs along), and the groove it carves never turns it. Bounded work (see [`anchor_normal`]).
#[must_use]
pub fn facing_surface(field: &MultiPatchField, at: Vec3) -> Quat {
    let normal = if field.is_inside(at) {
        anchor_normal(field, at)
    } else {
        outside_normal(field, at)
    };
    if normal == Vec3::ZERO {
        Quat::IDENTITY
    } else {
        Quat::from_rotation_arc(Vec3::Z, normal)
    }
}

/// The clay's outward normal seen from `at` outside it: the density's rising direction where
/// its gradient is worth trusting (within the clay's ramp), else the axis direction along
/// which the clay is met soonest (within [`PRESS_REACH_SPANS`] knot spans), reversed; zero
/// when neither is found. Bounded: at most `1 + 6 · 12` field evaluations.
fn outside_normal(field: &MultiPatchField, at: Vec3) -> Vec3 {
    let (_, gradient) = field.value_and_gradient(at);
    let spacing = field.finest_spacing();
    if gradient.is_finite() && gradient.length() * spacing > 0.1 * field.iso() {
        return (-gradient).normalize_or_zero();
    }
    const STEPS: u32 = 12;
    let reach = PRESS_REACH_SPANS * spacing;
    [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z]
        .into_iter()
        .filter_map(|dir| {
            (1..=STEPS)
                .find(|&i| field.is_inside(at + dir * (reach * i as f32 / STEPS as f32)))
                .map(|i| (i, dir))
        })
        .min_by_key(|&(i, _)| i)
        .map_or(Vec3::ZERO, |(_, dir)| -dir)
}

/// The piecewise-linear line through `points` at `u` (held flat beyond the ends).
fn custom_value(points: &[[f32; 2]], u: f32) -> f32 {
    let Some(first) = points.first() else {
        return 0.0;
    };
    if u <= first[0] {
        return first[1];
    }
    for pair in points.windows(2) {
        let ([u0, c0], [u1, c1]) = (pair[0], pair[1]);
        if u <= u1 {
            let t = if u1 > u0 { (u - u0) / (u1 - u0) } else { 1.0 };
            return c0 + (c1 - c0) * t;
        }
    }
    points[points.len() - 1][1]
}

/// Squared distance from `q` to the segment `a`–`b` in the plane.
#[inline]
fn segment_distance_sq(q: [f32; 2], a: [f32; 2], b: [f32; 2]) -> f32 {
    let ab = [b[0] - a[0], b[1] - a[1]];
    let aq = [q[0] - a[0], q[1] - a[1]];
    let len_sq = ab[0] * ab[0] + ab[1] * ab[1];
    let t = if len_sq > 0.0 {
        ((aq[0] * ab[0] + aq[1] * ab[1]) / len_sq).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let d = [aq[0] - t * ab[0], aq[1] - t * ab[1]];
    d[0] * d[0] + d[1] * d[1]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_follow_blenders_formulas_at_centre_middle_and_edge() {
        let cases = [
            (FalloffCurve::Smooth, 0.5),
            (FalloffCurve::Sphere, 0.75_f32.sqrt()),
            (FalloffCurve::Root, 0.5_f32.sqrt()),
            (FalloffCurve::Sharp, 0.25),
            (FalloffCurve::Linear, 0.5),
            (FalloffCurve::Constant, 1.0),
        ];
        for (curve, middle) in cases {
            assert_eq!(curve.value(0.0), 1.0, "{curve:?}");
            assert!((curve.value(0.5) - middle).abs() < 1e-6, "{curve:?}");
            let edge = if curve == FalloffCurve::Constant {
                1.0
            } else {
                0.0
            };
            assert!((curve.value(1.0) - edge).abs() < 1e-6, "{curve:?}");
        }
    }

    #[test]
    fn the_sphere_curves_distance_is_the_spheres_within_its_chord_error() {
        let r = 0.3;
        for (rho, z) in [(0.0, 0.1), (0.2, 0.1), (0.29, 0.0), (0.1, 0.5), (0.6, 0.2)] {
            let exact: f32 = f32::hypot(rho, z) - r;
            let d = FalloffCurve::Sphere.signed_distance(rho, z, r);
            assert!(
                (d - exact).abs() < 0.005 * r,
                "({rho}, {z}): {d} vs {exact}"
            );
        }
    }

    #[test]
    fn the_constant_curve_is_a_cylinder_as_tall_as_it_is_wide() {
        let c = FalloffCurve::Constant;
        let r = 0.2;
        assert!((c.signed_distance(0.0, 0.3, r) - 0.1).abs() < 1e-6);
        assert!((c.signed_distance(0.3, 0.0, r) - 0.1).abs() < 1e-6);
        assert!((c.signed_distance(0.15, 0.1, r) + 0.05).abs() < 1e-6);
        assert!((c.max_reach() - 2.0_f32.sqrt()).abs() < 1e-6);
        // Volume of the cylinder: π R² · 2R = 4π R³ · ½.
        assert!((c.first_moment() - 0.5).abs() < 1e-6);
    }

    #[test]
    fn custom_curves_are_checked_and_read_as_their_polyline() {
        let c = FalloffCurve::Custom(vec![[0.0, 1.0], [0.5, 1.0], [1.0, 0.0]]);
        c.validate().unwrap();
        assert_eq!(c.value(0.25), 1.0);
        assert!((c.value(0.75) - 0.5).abs() < 1e-6);
        assert!(c.signed_distance(0.1, 0.19, 0.2) < 0.0);
        assert!(c.signed_distance(0.1, 0.21, 0.2) > 0.0);
        let bad = [
            (vec![[0.0, 1.0]], CurveError::PointCount { count: 1 }),
            (
                vec![[0.0, 1.0], [0.5, 1.5], [1.0, 0.0]],
                CurveError::OutOfRange {
                    index: 1,
                    point: [0.5, 1.5],
                },
            ),
            (
                vec![[0.0, 1.0], [0.6, 0.5], [0.6, 0.4], [1.0, 0.0]],
                CurveError::NotAscending { index: 2 },
            ),
            (
                vec![[0.1, 1.0], [1.0, 0.0]],
                CurveError::NotAscending { index: 0 },
            ),
        ];
        for (points, error) in bad {
            assert_eq!(FalloffCurve::Custom(points).validate(), Err(error));
        }
        assert!(
            FalloffCurve::Custom(vec![[0.0, f32::NAN], [1.0, 0.0]])
                .validate()
                .is_err()
        );
    }

    #[test]
    fn scripts_name_presets_by_word_and_custom_curves_by_their_points() {
        #[derive(Deserialize)]
        struct Brush {
            curve: FalloffCurve,
        }
        let b: Brush = toml::from_str("curve = \"sharp\"").unwrap();
        assert_eq!(b.curve, FalloffCurve::Sharp);
        let b: Brush = toml::from_str("curve = { custom = [[0, 1], [1, 0]] }").unwrap();
        assert_eq!(b.curve, FalloffCurve::Custom(vec![[0.0, 1.0], [1.0, 0.0]]));
        assert!(toml::from_str::<Brush>("curve = \"wobbly\"").is_err());
    }
}
