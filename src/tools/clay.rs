//! The editable sculpt state: density patches and the optional colour field, addressed by
//! [`FieldId`], with coefficient boxes ([`CoeffBox`]) naming the regions that an edit touched.
//!
//! Every tool, every force stroke and the undo history work on a [`Clay`]; the session file
//! stores one. Nothing here allocates after construction except [`ColourField::new`].

use glam::{Vec3, Vec4};

use crate::field::{BSplineLattice, LatticeError};

/// Which coefficient lattice of a [`Clay`] an edit or an undo delta refers to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum FieldId {
    /// The density lattice of patch `n`.
    Density(u16),
    /// Colour channel `0..4` (red, green, blue, coverage).
    Colour(u8),
}

/// A half-open box of coefficient indices `min ..< max` per axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct CoeffBox {
    pub min: [usize; 3],
    pub max: [usize; 3],
}

impl CoeffBox {
    /// The whole lattice of the given dimensions.
    #[must_use]
    pub fn full(dims: [usize; 3]) -> Self {
        Self {
            min: [0; 3],
            max: dims,
        }
    }

    /// Whether the box holds no coefficient.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        (0..3).any(|a| self.max[a] <= self.min[a])
    }

    /// Number of coefficients in the box.
    #[must_use]
    pub fn count(&self) -> usize {
        if self.is_empty() {
            0
        } else {
            (0..3).map(|a| self.max[a] - self.min[a]).product()
        }
    }

    /// The smallest box holding both (an empty box is ignored).
    #[must_use]
    pub fn union(&self, other: &Self) -> Self {
        if self.is_empty() {
            return *other;
        }
        if other.is_empty() {
            return *self;
        }
        Self {
            min: std::array::from_fn(|a| self.min[a].min(other.min[a])),
            max: std::array::from_fn(|a| self.max[a].max(other.max[a])),
        }
    }

    /// This box clipped to a lattice of the given dimensions.
    #[must_use]
    pub fn clamp_to(&self, dims: [usize; 3]) -> Self {
        Self {
            min: std::array::from_fn(|a| self.min[a].min(dims[a])),
            max: std::array::from_fn(|a| self.max[a].min(dims[a])),
        }
    }

    /// The coefficients of `lattice` whose support (two knot spans either side of the
    /// coefficient's node) meets the world box `lo ..= hi`, clipped to the lattice.
    #[must_use]
    pub fn covering(lattice: &BSplineLattice, lo: Vec3, hi: Vec3) -> Self {
        let (u0, u1) = (lattice.to_lattice(lo), lattice.to_lattice(hi));
        let mut out = Self {
            min: [0; 3],
            max: [0; 3],
        };
        for a in 0..3 {
            let n = lattice.dims[a] as f32;
            if !(u0[a].is_finite() && u1[a].is_finite()) {
                return out;
            }
            // Coefficient c influences lattice coordinates (c - 2, c + 2).
            let first = (u0[a] - 2.0).floor().max(0.0);
            let last = (u1[a] + 2.0).ceil().min(n - 1.0);
            if last < first || first > n - 1.0 || last < 0.0 {
                return out;
            }
            out.min[a] = first as usize;
            out.max[a] = last as usize + 1;
        }
        out
    }

    /// The world box (min, max corners) where a change of these coefficients can show.
    #[must_use]
    pub fn world_support(&self, lattice: &BSplineLattice) -> (Vec3, Vec3) {
        let lo = Vec3::new(self.min[0] as f32, self.min[1] as f32, self.min[2] as f32);
        let hi = Vec3::new(
            self.max[0] as f32 - 1.0,
            self.max[1] as f32 - 1.0,
            self.max[2] as f32 - 1.0,
        );
        (
            lattice.origin + (lo - 2.0) * lattice.spacing,
            lattice.origin + (hi + 2.0) * lattice.spacing,
        )
    }
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

/// The sculpt: density patches (the paper's eq. (3) sums them) and an optional colour field.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Clay {
    pub patches: Vec<BSplineLattice>,
    pub colour: Option<ColourField>,
}

impl Clay {
    /// A clay made of one patch and no colour.
    #[must_use]
    pub fn single(patch: BSplineLattice) -> Self {
        Self {
            patches: vec![patch],
            colour: None,
        }
    }

    /// The lattice named by `id`, if it exists.
    #[must_use]
    pub fn field(&self, id: FieldId) -> Option<&BSplineLattice> {
        match id {
            FieldId::Density(n) => self.patches.get(usize::from(n)),
            FieldId::Colour(c) => self.colour.as_ref()?.channels.get(usize::from(c)),
        }
    }

    /// The lattice named by `id`, mutably, if it exists.
    pub fn field_mut(&mut self, id: FieldId) -> Option<&mut BSplineLattice> {
        match id {
            FieldId::Density(n) => self.patches.get_mut(usize::from(n)),
            FieldId::Colour(c) => self.colour.as_mut()?.channels.get_mut(usize::from(c)),
        }
    }

    /// The summed density of all patches at a world point (eq. (3) with identity maps).
    #[must_use]
    pub fn density(&self, x: Vec3) -> f32 {
        self.patches.iter().map(|p| p.value(x)).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn covering_box_holds_every_coefficient_that_reaches_the_world_box() {
        let lattice = BSplineLattice::zeros([20, 20, 20], 0.1, Vec3::ZERO).unwrap();
        let b = CoeffBox::covering(&lattice, Vec3::splat(0.5), Vec3::splat(0.7));
        assert_eq!(b.min, [3; 3]);
        assert_eq!(b.max, [10; 3]);
        let (lo, hi) = b.world_support(&lattice);
        assert!(lo.cmple(Vec3::splat(0.5)).all() && hi.cmpge(Vec3::splat(0.7)).all());
        let outside = CoeffBox::covering(&lattice, Vec3::splat(5.0), Vec3::splat(6.0));
        assert!(outside.is_empty());
        let edge = CoeffBox::covering(&lattice, Vec3::splat(-1.0), Vec3::splat(0.05));
        assert_eq!(edge.min, [0; 3]);
        assert_eq!(edge.max, [4; 3]);
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
