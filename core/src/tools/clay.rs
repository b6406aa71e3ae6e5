//! The editable sculpt state: density patches, the optional colour field and freeze mask, addressed by
//! [`FieldId`], with coefficient boxes ([`CoeffBox`], inclusive) naming the regions that an edit touched.
//!
//! Every tool, every force stroke and the undo history work on a [`Clay`]; the session file
//! stores one. Nothing here allocates after construction except [`ColourField::new`].

use glam::{Vec3, Vec4};

use super::freeze_mask::FreezeMask;
use crate::dynamics::Constraint;
use crate::field::{
    BSplineLattice, DenseBudgetError, DetailError, LatticeError, MAX_CLAY_BOX_COEFFS,
    MultiPatchField, check_dense_room,
};
pub use crate::field::{CoeffBox, sub_lattice};

/// Edge length (in coefficients) of the bricks the clay's coefficients are counted in: undo
/// deltas are stored per brick, and the clay grows by whole bricks.
pub const BRICK: usize = crate::field::COEFF_BRICK;

/// Which coefficient lattice of a [`Clay`] an edit or an undo delta refers to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum FieldId {
    /// The density lattice of patch `n`.
    Density(u16),
    /// Colour channel `0..4` (red, green, blue, coverage).
    Colour(u8),
    /// The freeze mask's holds over density patch `n` ([`crate::tools::FreezeMask`]).
    Mask(u16),
}

/// A colour carried with the clay: four B-spline lattices (red, green, blue, coverage) over
/// the same nodes as the density patch they paint. Coverage 0 means "unpainted: show the
/// material's base colour"; channel values are in `[0, 1]`.
#[derive(Clone, Debug, PartialEq)]
pub struct ColourField {
    /// Red, green, blue and coverage, each with identical dims, spacing and origin.
    pub channels: [BSplineLattice; 4],
}

impl ColourField {
    /// An unpainted colour field over the same nodes as `density`.
    ///
    /// # Errors
    /// When the density lattice's geometry is invalid (see [`BSplineLattice::zeros`]).
    pub fn matching(density: &BSplineLattice) -> Result<Self, LatticeError> {
        Self::new(density.dims, density.spacing, density.origin)
    }

    /// An unpainted colour field.
    ///
    /// # Errors
    /// As [`BSplineLattice::zeros`].
    pub fn new(dims: [usize; 3], spacing: f32, origin: Vec3) -> Result<Self, LatticeError> {
        let lattice = BSplineLattice::zeros(dims, spacing, origin)?;
        Ok(Self {
            channels: [lattice.clone(), lattice.clone(), lattice.clone(), lattice],
        })
    }

    /// Premultiplied-free colour and coverage at a world point, each clamped to `[0, 1]`.
    #[must_use]
    pub fn rgba(&self, x: Vec3) -> Vec4 {
        let c = |n: usize| self.channels[n].value(x).clamp(0.0, 1.0);
        Vec4::new(c(0), c(1), c(2), c(3))
    }

    /// Whether the four channels share one geometry.
    #[must_use]
    pub fn is_consistent(&self) -> bool {
        let first = &self.channels[0];
        self.channels.iter().all(|c| {
            c.dims == first.dims
                && c.spacing.to_bits() == first.spacing.to_bits()
                && c.origin == first.origin
                && c.coeffs.len() == first.coeffs.len()
        })
    }
}

/// The sculpt: the density of eq. (3) (a base patch and detail patches, each with its map
/// `T_i`), an optional colour field over the base patch's nodes, and the pins.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Clay {
    pub density: MultiPatchField,
    pub colour: Option<ColourField>,
    /// Geometric constraints (pins, Hua & Qin §7.3) the dynamics hold on the first patch.
    /// Changing them is an undo step like any edit.
    pub constraints: Vec<Constraint>,
    /// The freeze mask every tool and the dynamics respect (`None`: nothing held).
    pub mask: Option<FreezeMask>,
}

impl Clay {
    /// A clay made of one patch and no colour.
    #[must_use]
    pub fn single(patch: BSplineLattice) -> Self {
        Self {
            density: MultiPatchField::new(patch),
            colour: None,
            constraints: Vec::new(),
            mask: None,
        }
    }

    /// The lattice named by `id`, if it exists.
    #[must_use]
    pub fn field(&self, id: FieldId) -> Option<&BSplineLattice> {
        match id {
            FieldId::Density(n) => self.density.patches.get(usize::from(n)).map(|p| &p.lattice),
            FieldId::Colour(c) => self.colour.as_ref()?.channels.get(usize::from(c)),
            FieldId::Mask(n) => self.mask.as_ref()?.patches.get(usize::from(n)),
        }
    }

    /// The lattice named by `id`, mutably, if it exists.
    pub fn field_mut(&mut self, id: FieldId) -> Option<&mut BSplineLattice> {
        match id {
            FieldId::Density(n) => self
                .density
                .patches
                .get_mut(usize::from(n))
                .map(|p| &mut p.lattice),
            FieldId::Colour(c) => self.colour.as_mut()?.channels.get_mut(usize::from(c)),
            FieldId::Mask(n) => self.mask.as_mut()?.patches.get_mut(usize::from(n)),
        }
    }

    /// The base patch's lattice (the one the colour field and the pins live on).
    ///
    /// # Panics
    /// When the clay has no patch (every clay built or loaded has one).
    #[must_use]
    pub fn base(&self) -> &BSplineLattice {
        self.density.base()
    }

    /// The base patch's lattice, mutably.
    ///
    /// # Panics
    /// As [`Clay::base`].
    pub fn base_mut(&mut self) -> &mut BSplineLattice {
        self.density.base_mut()
    }

    /// Every lattice of the clay: the density patches, the colour channels, the mask's.
    pub fn lattices(&self) -> impl Iterator<Item = &BSplineLattice> {
        let density = self.density.patches.iter().map(|p| &p.lattice);
        let colour = self.colour.iter().flat_map(|c| c.channels.iter());
        let mask = self.mask.iter().flat_map(|m| m.patches.iter());
        density.chain(colour).chain(mask)
    }

    /// Dense bricks of every lattice of the clay together: what
    /// [`crate::field::MAX_DENSE_BRICKS`] bounds. Sums counts the stores keep (no walk).
    #[must_use]
    pub fn dense_brick_count(&self) -> usize {
        self.lattices().map(|l| l.coeffs.dense_brick_count()).sum()
    }

    /// Coefficients of box of every lattice of the clay together: what
    /// [`crate::field::MAX_CLAY_BOX_COEFFS`] bounds.
    #[must_use]
    pub fn box_coefficient_count(&self) -> usize {
        self.lattices().map(|l| l.coeffs.len()).sum()
    }

    /// [`MultiPatchField::refine`] within the clay's box budget counted over every lattice
    /// (as a growth and a session load count it): the new patch, its freeze-mask lattice
    /// when the clay has a mask, and every lattice there is must span at most
    /// [`crate::field::MAX_CLAY_BOX_COEFFS`] coefficients together, so a clay that refines
    /// saves and loads. Returns the new patch's index.
    ///
    /// # Errors
    /// As [`MultiPatchField::refine`]; the clay is unchanged then.
    pub fn refine(&mut self, lo: Vec3, hi: Vec3, level: u32) -> Result<usize, DetailError> {
        let coefficients = self.density.detail_coefficients(lo, hi, level)?;
        let copies = 1 + usize::from(self.mask.is_some());
        let total = self
            .box_coefficient_count()
            .saturating_add(coefficients.saturating_mul(copies));
        if total > MAX_CLAY_BOX_COEFFS {
            return Err(DetailError::ClayTooLarge { total });
        }
        self.density.refine(lo, hi, level)
    }

    /// Whether a write inside `region` of lattice `id` fits the clay's dense-brick budget,
    /// counting every uniform brick the box reaches as one it may make dense. A lattice the
    /// clay does not hold takes no room.
    ///
    /// # Errors
    /// [`DenseBudgetError`] when it may not fit; check before writing, so that the clay is
    /// unchanged then.
    pub fn check_dense_room(&self, id: FieldId, region: CoeffBox) -> Result<(), DenseBudgetError> {
        let more = self.field(id).map_or(0, |l| {
            l.coeffs.uniform_bricks_holding(region.min, region.max)
        });
        check_dense_room(self.dense_brick_count(), more, Some(region))
    }

    /// Whether the clay as it is fits its budgets: its dense bricks within
    /// [`crate::field::MAX_DENSE_BRICKS`] (a clay made elsewhere, an import, before it is
    /// taken in).
    ///
    /// # Errors
    /// [`DenseBudgetError`] when it holds more.
    pub fn check_dense_budget(&self) -> Result<(), DenseBudgetError> {
        check_dense_room(self.dense_brick_count(), 0, None)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_refine_counts_every_lattice_of_the_clay_against_the_box_budget() {
        // A base of 1024 × 1024 × 500 coefficients of empty space (a 16 MiB directory) and a
        // level-1 patch of 253³ (16 Mi coefficients) over a box of 1.25 field units.
        let base = BSplineLattice::zeros([1024, 1024, 500], 0.01, Vec3::ZERO).unwrap();
        let mut clay = Clay::single(base);
        let (lo, hi) = (Vec3::splat(1.0), Vec3::splat(2.25));
        let mut masked = clay.clone();
        masked.mask = Some(FreezeMask::matching(&masked.density).unwrap());
        assert_eq!(clay.refine(lo, hi, 1), Ok(1));
        assert_eq!(clay.density.patches.len(), 2);
        // With a freeze mask the base counts twice and the patch would too: past the budget.
        let refused = masked.refine(lo, hi, 1);
        assert!(
            matches!(refused, Err(DetailError::ClayTooLarge { total }) if total > MAX_CLAY_BOX_COEFFS),
            "{refused:?}"
        );
        assert_eq!(masked.density.patches.len(), 1);
    }

    #[test]
    fn boxes_union_clip_and_bound_their_support() {
        let lattice = BSplineLattice::zeros([20, 20, 20], 0.1, Vec3::ZERO).unwrap();
        let a = CoeffBox {
            min: [3; 3],
            max: [9; 3],
        };
        let b = CoeffBox {
            min: [1, 5, 5],
            max: [4, 30, 6],
        };
        let u = a.union(&b);
        assert_eq!(
            u,
            CoeffBox {
                min: [1, 3, 3],
                max: [9, 30, 9]
            }
        );
        assert_eq!(u.clipped([20; 3]).unwrap().max, [9, 19, 9]);
        assert!(
            CoeffBox {
                min: [25; 3],
                max: [30; 3]
            }
            .clipped([20; 3])
            .is_none()
        );
        let (lo, hi) = a.world_support(&lattice);
        assert!((lo - Vec3::splat(0.1)).length() < 1e-6);
        assert!((hi - Vec3::splat(1.1)).length() < 1e-6);
    }

    #[test]
    fn a_sub_lattice_evaluates_like_the_original_inside_its_margin() {
        let mut lattice =
            BSplineLattice::zeros([16, 12, 10], 0.2, Vec3::new(0.3, -0.1, 0.0)).unwrap();
        lattice.coeffs.update_each(|n, c| {
            *c = ((n * 37) % 23) as f32 / 23.0;
        });
        let region = CoeffBox {
            min: [5, 0, 3],
            max: [8, 4, 9],
        };
        let sub = sub_lattice(&lattice, &region, 4);
        let (lo, hi) = region.world_support(&lattice);
        for s in 0..300 {
            let f = Vec3::new(
                (s * 7 % 31) as f32 / 31.0,
                (s * 11 % 29) as f32 / 29.0,
                (s * 13 % 37) as f32 / 37.0,
            );
            let x = lo + (hi - lo) * f;
            // Equal up to the rounding of the shifted origin.
            assert!((sub.value(x) - lattice.value(x)).abs() < 1e-5, "at {x}");
        }
    }

    #[test]
    fn field_ids_address_patches_and_colour_channels() {
        let lattice = BSplineLattice::zeros([4, 4, 4], 1.0, Vec3::ZERO).unwrap();
        let mut clay = Clay::single(lattice.clone());
        assert!(clay.field(FieldId::Colour(0)).is_none());
        clay.colour = Some(ColourField::matching(&lattice).unwrap());
        assert!(clay.field(FieldId::Colour(3)).is_some());
        assert!(clay.field(FieldId::Colour(4)).is_none());
        assert!(clay.field_mut(FieldId::Density(1)).is_none());
        assert!(clay.colour.as_ref().unwrap().is_consistent());
    }
}
