//! A solid as a clay of its own: the operand of a CSG with a sphere, box or cylinder (Guo &
//! Qin Table 1), so union, difference and intersection with a solid take the same path as CSG
//! with another session's clay. Intersection is not a brush (see
//! [`super::INTERSECTION_IS_CSG`]); with a solid it is this.

use glam::Vec3;

use super::apply::GeometricTool;
use super::clay::Clay;
use super::shape::ToolPose;
use crate::field::{BSplineLattice, CLAY_SPACING, FitError, fit_lattice};

/// Most knots along each side of a solid's lattice.
pub const MAX_SOLID_KNOTS: usize = 96;

/// Knot spans of empty lattice around the solid's reach, so its potential falls to zero inside
/// the lattice.
const PAD_SPANS: f32 = 3.0;

/// Why a solid could not be made into a clay (nothing was allocated for the lattice).
#[derive(Debug, thiserror::Error)]
pub enum SolidClayError {
    /// The solid's reach needs more knots than [`MAX_SOLID_KNOTS`] on some side.
    #[error(
        "the solid needs {knots:?} knots at spacing {spacing_fu} (at most {MAX_SOLID_KNOTS} a \
         side): make it smaller or its edge band wider"
    )]
    TooLarge {
        /// Knots per axis it would need.
        knots: [usize; 3],
        /// The knot spacing, field units.
        spacing_fu: f32,
    },
    /// The solid's size or pose is not finite, or its edge band not positive.
    #[error("the solid's size, pose or edge band is not usable")]
    Degenerate,
    /// The least-squares fit failed.
    #[error("fit: {0}")]
    Fit(#[from] FitError),
}

/// The knot spacing for a solid whose potential falls over `falloff_fu` on each side of its
/// surface: half the band (so the fall spans four knots), no coarser than the default clay's
/// and no finer than a quarter of it.
#[must_use]
pub fn solid_spacing_fu(falloff_fu: f32) -> f32 {
    (0.5 * falloff_fu).clamp(0.25 * CLAY_SPACING, CLAY_SPACING)
}

/// The solid `tool.shape` at `pose` as a clay: a lattice over its reach (the shape grown by
/// its falloff band, and [`PAD_SPANS`] more) at [`solid_spacing_fu`], fitted to the tool's
/// potential. Its density is the tool's: one half on the solid's surface, 1 inside, 0 outside
/// the band.
///
/// # Errors
/// [`SolidClayError`] when the lattice would exceed [`MAX_SOLID_KNOTS`] a side (checked
/// before anything is allocated), the solid is degenerate, or the fit fails.
pub fn solid_clay(tool: &GeometricTool, pose: &ToolPose) -> Result<Clay, SolidClayError> {
    let falloff = tool.falloff_fu;
    if !(falloff.is_finite() && falloff > 0.0) {
        return Err(SolidClayError::Degenerate);
    }
    let spacing = solid_spacing_fu(falloff);
    let (lo, hi) = pose.world_bounds(tool.shape.influence_half_extents(falloff));
    if !(lo.is_finite() && hi.is_finite()) {
        return Err(SolidClayError::Degenerate);
    }
    let pad = Vec3::splat(PAD_SPANS * spacing);
    let (lo, hi) = (lo - pad, hi + pad);
    let span = (hi - lo) / spacing;
    let knots = [span.x, span.y, span.z].map(|s| s.ceil() as usize + 1);
    if knots.iter().any(|&k| k > MAX_SOLID_KNOTS) {
        return Err(SolidClayError::TooLarge {
            knots,
            spacing_fu: spacing,
        });
    }
    let mut lattice =
        BSplineLattice::zeros(knots, spacing, lo).map_err(|_| SolidClayError::Degenerate)?;
    fit_lattice(&mut lattice, 2, |x| {
        tool.shape.density(pose.to_local(x), falloff)
    })?;
    Ok(Clay::single(lattice))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tools::{ToolAction, ToolShape};

    #[test]
    fn a_ball_becomes_a_clay_whose_surface_is_the_ball() {
        let tool = GeometricTool {
            shape: ToolShape::Sphere { radius_fu: 0.3 },
            action: ToolAction::Difference,
            falloff_fu: 0.1,
        };
        let centre = Vec3::new(1.0, 2.0, 0.5);
        let clay = solid_clay(&tool, &ToolPose::at(centre)).unwrap();
        let field = clay.base();
        assert_eq!(field.spacing, 0.05);
        for dir in [Vec3::X, Vec3::NEG_Y, Vec3::new(1.0, 1.0, 1.0).normalize()] {
            let on = field.value(centre + dir * 0.3);
            assert!((on - 0.5).abs() < 0.02, "{on} on the surface along {dir}");
            assert!(field.value(centre + dir * 0.1) > 0.95);
            assert!(field.value(centre + dir * 0.45) < 0.02);
        }
    }

    #[test]
    fn a_solid_too_large_for_its_band_is_refused_before_allocating() {
        let tool = GeometricTool {
            shape: ToolShape::Sphere { radius_fu: 50.0 },
            action: ToolAction::Union,
            falloff_fu: 0.1,
        };
        let e = solid_clay(&tool, &ToolPose::at(Vec3::ZERO)).unwrap_err();
        assert!(matches!(e, SolidClayError::TooLarge { .. }), "{e}");
        assert!(e.to_string().contains("at most 96"), "{e}");
        let flat = GeometricTool {
            falloff_fu: 0.0,
            ..tool
        };
        assert!(matches!(
            solid_clay(&flat, &ToolPose::at(Vec3::ZERO)),
            Err(SolidClayError::Degenerate)
        ));
    }
}
