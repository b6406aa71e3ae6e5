//! Room wherever the clay goes: before an edit reaches past the base patch, the base grows by
//! whole bricks of zero coefficients (empty space), so a pull or an added lump extends the clay
//! beyond the box it started in instead of being clipped flat against it.
//!
//! Growth is symmetric per axis (the same number of coefficients before and after), so the
//! lattice's centre — the mirror plane of symmetric sculpting — stays where it was, and it adds
//! a multiple of [`BRICK`] coefficients per side, so the undo history's brick deltas keep their
//! brick alignment when they are moved onto the grown lattice ([`super::History::regrid`]).
//! The colour field grows with the base; material grids are carried over by their owner
//! ([`crate::dynamics::MaterialGrid::grown`]).
//!
//! Budget: the grown clay's box is checked against [`MAX_CLAY_BOX_COEFFS`] before anything is
//! allocated (what its brick directories cost), and its dense bricks against
//! [`crate::field::MAX_DENSE_BRICKS`] before it replaces the clay. Growth moves bricks as they
//! are: the new coefficients are uniform empty space, so memory grows with the surface the
//! clay has, not the box it spans.

use glam::Vec3;

use super::clay::{BRICK, Clay};
use crate::field::{
    BSplineLattice, DenseBudgetError, LatticeError, MAX_CLAY_BOX_COEFFS, check_dense_room,
};

/// How many knot spans an edit's box must stay inside the base patch's first and last
/// nodes: a point's cubic stencil reaches one node below and two above it, so a box kept 1.5
/// spans inside is written wholly by the lattice's own coefficients (none beyond it, which
/// count as zero and would clip the edit flat).
pub const GROWTH_MARGIN_SPANS: f32 = 1.5;

/// Why the clay could not grow to take an edit.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum GrowthError {
    /// The edit's box is not finite.
    #[error("the box {lo:?}..{hi:?} to grow the clay to is not finite")]
    NotFinite {
        /// The box's low corner.
        lo: [f32; 3],
        /// The box's high corner.
        hi: [f32; 3],
    },
    /// The grown clay would span more than [`MAX_CLAY_BOX_COEFFS`] coefficients of box.
    #[error(
        "growing the clay to {dims:?} base coefficients would make {total} coefficients of box in all, more than {MAX_CLAY_BOX_COEFFS}; the edit stays clipped to the clay's box"
    )]
    ClayTooLarge {
        /// The grown base's dimensions (saturated when they overflow).
        dims: [usize; 3],
        /// Coefficients of the grown clay, every patch and the colour field.
        total: usize,
    },
    /// The grown lattice could not be made.
    #[error("the grown base lattice: {0}")]
    Lattice(#[from] LatticeError),
    /// The grown clay would hold more dense bricks than its budget (bricks at the old border
    /// whose aprons now reach different values).
    #[error("growing the clay: {0}")]
    DenseBudget(#[from] DenseBudgetError),
}

/// How the base patch grew: `pad[a]` coefficients were added before and after it along axis
/// `a`. Everything that indexes the base's (and the colour field's) coefficients moves by
/// `pad`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Growth {
    /// Coefficients added on each side, per axis (a multiple of [`BRICK`]).
    pub pad: [usize; 3],
    /// The base's dimensions before.
    pub old_dims: [usize; 3],
    /// The base's dimensions after.
    pub new_dims: [usize; 3],
}

/// The padding per side the base `lattice` needs so that the world box `lo..=hi` lies
/// [`GROWTH_MARGIN_SPANS`] inside its nodes, rounded up to whole bricks (`None` when it
/// already does).
///
/// # Errors
/// [`GrowthError::NotFinite`] for a box that is not finite.
pub fn padding_to_cover(
    lattice: &BSplineLattice,
    lo: Vec3,
    hi: Vec3,
) -> Result<Option<[usize; 3]>, GrowthError> {
    if !(lo.is_finite() && hi.is_finite()) {
        return Err(GrowthError::NotFinite {
            lo: lo.to_array(),
            hi: hi.to_array(),
        });
    }
    let (ulo, uhi) = (lattice.to_lattice(lo), lattice.to_lattice(hi));
    let mut pad = [0_usize; 3];
    for a in 0..3 {
        let last = (lattice.dims[a] - 1) as f32;
        let short = (GROWTH_MARGIN_SPANS - ulo[a].min(uhi[a]))
            .max(ulo[a].max(uhi[a]) - (last - GROWTH_MARGIN_SPANS))
            .max(0.0);
        if short > 0.0 {
            // Saturating: an absurd box asks for more than any budget and is refused there.
            let spans = short.ceil().min(1e9) as usize;
            pad[a] = spans.div_ceil(BRICK) * BRICK;
        }
    }
    Ok((pad != [0; 3]).then_some(pad))
}

impl Clay {
    /// Grows the base patch (and the colour field) so that the world box `lo..=hi` lies well
    /// inside it (see [`padding_to_cover`]); returns how it grew, or `None` when it already
    /// did. The density is unchanged (new coefficients are empty space).
    ///
    /// # Errors
    /// [`GrowthError`] when the box is not finite or the grown clay would exceed
    /// [`MAX_CLAY_BOX_COEFFS`] or the dense-brick budget; the clay is unchanged then.
    pub fn grow_to_cover(&mut self, lo: Vec3, hi: Vec3) -> Result<Option<Growth>, GrowthError> {
        match padding_to_cover(self.base(), lo, hi)? {
            Some(pad) => self.grow(pad).map(Some),
            None => Ok(None),
        }
    }

    /// Whether growing by `pad` ([`Clay::grow`]) keeps the clay within
    /// [`MAX_CLAY_BOX_COEFFS`] coefficients of box, every lattice together. Reads only.
    ///
    /// # Errors
    /// [`GrowthError::ClayTooLarge`] when it would not.
    pub fn check_growth_box(&self, pad: [usize; 3]) -> Result<(), GrowthError> {
        let old_dims = self.base().dims;
        let new_dims: [usize; 3] =
            std::array::from_fn(|a| old_dims[a].saturating_add(pad[a].saturating_mul(2)));
        // Every lattice counts, as a refine and a session load count them: the base, the
        // colour channels and the base's mask grow; the rest stays.
        let grown_count = |dims: [usize; 3]| {
            (0..3).fold(1_usize, |acc, a| {
                acc.saturating_mul(dims[a].saturating_add(pad[a].saturating_mul(2)))
            })
        };
        let base_mask = self
            .mask
            .as_ref()
            .and_then(|m| m.patches.first())
            .filter(|m| m.dims == old_dims);
        let colour = self.colour.iter().flat_map(|c| c.channels.iter());
        let growing: Vec<&BSplineLattice> = std::iter::once(self.base())
            .chain(colour)
            .chain(base_mask)
            .collect();
        let staying =
            self.box_coefficient_count() - growing.iter().map(|l| l.coeffs.len()).sum::<usize>();
        let total = growing
            .iter()
            .fold(staying, |acc, l| acc.saturating_add(grown_count(l.dims)));
        if total > MAX_CLAY_BOX_COEFFS {
            return Err(GrowthError::ClayTooLarge {
                dims: new_dims,
                total,
            });
        }
        Ok(())
    }

    /// Adds `pad[a]` zero coefficients on both sides of axis `a` to the base patch, the
    /// colour field and the base's mask.
    ///
    /// # Errors
    /// As [`Clay::grow_to_cover`].
    pub fn grow(&mut self, pad: [usize; 3]) -> Result<Growth, GrowthError> {
        let old_dims = self.base().dims;
        let new_dims: [usize; 3] =
            std::array::from_fn(|a| old_dims[a].saturating_add(pad[a].saturating_mul(2)));
        self.check_growth_box(pad)?;
        let base = self.base().padded(pad, pad)?;
        let colour = match &self.colour {
            Some(c) => {
                let mut channels = c.channels.clone();
                for channel in &mut channels {
                    *channel = channel.padded(pad, pad)?;
                }
                Some(channels)
            }
            None => None,
        };
        // The base's mask grows with it (the new coefficients are free); a mask that no
        // longer fits the base is left for `ensure_mask` to remake.
        let base_mask = match self.mask.as_ref().and_then(|m| m.patches.first()) {
            Some(m) if m.dims == old_dims => Some(m.padded(pad, pad)?),
            _ => None,
        };
        // The grown lattices replace the old ones only if the clay then fits its budget.
        let dense_of = |l: &BSplineLattice| l.coeffs.dense_brick_count();
        let mut grown_dense = self.dense_brick_count() - dense_of(self.base()) + dense_of(&base);
        if let (Some(old), Some(new)) = (&self.colour, &colour) {
            grown_dense -= old.channels.iter().map(dense_of).sum::<usize>();
            grown_dense += new.iter().map(dense_of).sum::<usize>();
        }
        if let (Some(old), Some(new)) = (
            self.mask.as_ref().and_then(|m| m.patches.first()),
            &base_mask,
        ) {
            grown_dense = grown_dense - dense_of(old) + dense_of(new);
        }
        check_dense_room(grown_dense, 0, None)?;
        *self.base_mut() = base;
        if let (Some(field), Some(channels)) = (self.colour.as_mut(), colour) {
            field.channels = channels;
        }
        if let (Some(mask), Some(grown)) = (self.mask.as_mut(), base_mask) {
            mask.patches[0] = grown;
        }
        Ok(Growth {
            pad,
            old_dims,
            new_dims,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tools::{ColourField, apply_tool};

    fn ball(n: usize) -> BSplineLattice {
        let spacing = 1.0 / (n - 3) as f32;
        let mut l = BSplineLattice::zeros([n; 3], spacing, Vec3::splat(-spacing)).unwrap();
        let centre = Vec3::splat(0.5);
        for k in 0..n {
            for j in 0..n {
                for i in 0..n {
                    let d = (l.node_position(i, j, k) - centre).length();
                    let idx = l.index(i, j, k);
                    l.coeffs.set_flat(idx, (1.0 - d / 0.35).clamp(0.0, 1.0));
                }
            }
        }
        l
    }

    #[test]
    fn a_box_inside_needs_no_growth_and_one_past_the_side_grows_by_whole_bricks() {
        let l = ball(20);
        assert_eq!(
            padding_to_cover(&l, Vec3::splat(0.3), Vec3::splat(0.7)).unwrap(),
            None
        );
        // 0.2 field units past the high x side: about 3.4 spans and the margin.
        let pad = padding_to_cover(&l, Vec3::splat(0.5), Vec3::new(1.2, 0.5, 0.5))
            .unwrap()
            .unwrap();
        assert_eq!(pad[1], 0);
        assert_eq!(pad[2], 0);
        assert!(pad[0] >= 8 && pad[0].is_multiple_of(BRICK), "{pad:?}");
        let grown = l.padded(pad, pad).unwrap();
        assert!(
            grown.to_lattice(Vec3::new(1.2, 0.5, 0.5)).x
                <= (grown.dims[0] - 1) as f32 - GROWTH_MARGIN_SPANS
        );
    }

    #[test]
    fn growing_keeps_the_density_and_the_centre_and_moves_the_paint_with_it() {
        let mut clay = Clay::single(ball(20));
        let mut colour = ColourField::matching(clay.base()).unwrap();
        colour.channels[0].coeffs.update_each(|n, c| {
            *c = (n % 7) as f32 / 7.0;
        });
        clay.colour = Some(colour);
        let before = clay.clone();
        let centre = |l: &BSplineLattice| {
            let (lo, hi) = l.support();
            (lo + hi) * 0.5
        };
        let growth = clay
            .grow_to_cover(Vec3::splat(-0.6), Vec3::splat(0.5))
            .unwrap()
            .unwrap();
        assert_eq!(growth.old_dims, [20; 3]);
        assert!(growth.new_dims.iter().all(|&n| n > 20));
        assert!((centre(clay.base()) - centre(before.base())).length() < 1e-5);
        for s in 0..200 {
            let t = s as f32 / 199.0;
            let x = Vec3::new(-0.3 + 1.6 * t, 0.5 + 0.3 * (7.0 * t).sin(), 0.45);
            let (a, b) = (before.density.value(x), clay.density.value(x));
            assert!((a - b).abs() < 1e-5, "{a} vs {b} at {x}");
            let (pa, pb) = (
                before.colour.as_ref().unwrap().rgba(x),
                clay.colour.as_ref().unwrap().rgba(x),
            );
            assert!((pa - pb).abs().max_element() < 1e-5);
        }
        assert!(clay.colour.as_ref().unwrap().is_consistent());
        assert_eq!(
            clay.colour.as_ref().unwrap().channels[0].dims,
            growth.new_dims
        );
    }

    #[test]
    fn growth_past_the_budget_and_a_box_at_infinity_are_refused_and_change_nothing() {
        let mut clay = Clay::single(ball(20));
        let before = clay.clone();
        let far = clay.grow_to_cover(Vec3::ZERO, Vec3::new(1e6, 0.5, 0.5));
        assert!(
            matches!(far, Err(GrowthError::ClayTooLarge { .. })),
            "{far:?}"
        );
        let nan = clay.grow_to_cover(Vec3::ZERO, Vec3::new(f32::NAN, 0.5, 0.5));
        assert!(matches!(nan, Err(GrowthError::NotFinite { .. })));
        assert_eq!(clay, before);
    }

    #[test]
    fn a_lump_far_past_the_old_box_wall_grows_the_clay_and_costs_only_its_bricks() {
        use crate::field::{DENSE_BRICK_BYTES, MAX_CLAY_COEFFS};
        use crate::tools::{ApplyOptions, GeometricTool, ToolAction, ToolPose, ToolShape};
        let mut clay = Clay::single(ball(40));
        let dense_before = clay.dense_brick_count();
        // 600 field units along x: more than 22 000 knot spans each side.
        let far = Vec3::new(600.0, 0.5, 0.5);
        let tool = GeometricTool {
            shape: ToolShape::Sphere { radius_fu: 0.1 },
            action: ToolAction::Add {
                deposit_rate_per_s: 4.0,
            },
            falloff_fu: 0.05,
        };
        let pose = ToolPose::at(far);
        let (lo, hi) = tool.influence_box(&pose, clay.base().spacing);
        let growth = clay.grow_to_cover(lo, hi).unwrap().unwrap();
        // The box is past the old wall (64 Mi coefficients, about 400³) …
        let box_coeffs = clay.box_coefficient_count();
        assert!(box_coeffs > MAX_CLAY_COEFFS, "{box_coeffs} coefficients");
        assert!(growth.new_dims[0] > 40_000, "{growth:?}");
        // … yet the growth made no brick dense: the new coefficients are empty space.
        assert_eq!(clay.dense_brick_count(), dense_before);
        apply_tool(&mut clay, &tool, &pose, 1.0, &ApplyOptions::default(), None).unwrap();
        assert!(
            clay.density.value(far) > clay.base().iso,
            "the lump is there"
        );
        assert!(
            clay.density.value(Vec3::splat(0.5)) > clay.base().iso,
            "the ball too"
        );
        // The lump costs a few bricks: memory follows the surface, not the box.
        let lump = clay.dense_brick_count() - dense_before;
        assert!((1..=64).contains(&lump), "{lump} bricks");
        let heap = clay.base().coeffs.heap_bytes();
        let dense_heap = clay.dense_brick_count() * DENSE_BRICK_BYTES;
        assert!(heap < dense_heap + (4 << 20), "{heap} bytes");
    }
}
