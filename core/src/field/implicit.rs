//! What a point query of the clay needs: a scalar field's value and analytic gradient at a
//! world point, and the iso-level its surface sits at. The force integrals, the coast field
//! and the tools ask only this; the mesher's block sampling builds on it
//! ([`crate::mesh::ScalarField`]).

use glam::Vec3;

use super::{BSplineLattice, MultiPatchField};

/// A scalar field whose solid is where the value is greater than [`ImplicitField::iso`],
/// queried one world point at a time.
pub trait ImplicitField {
    /// The iso-level of the surface.
    fn iso(&self) -> f32;

    /// Value at a world point.
    fn value(&self, p: Vec3) -> f32;

    /// Value and gradient (per world unit) at a world point.
    fn value_and_gradient(&self, p: Vec3) -> (f32, Vec3);

    /// Gradient (per world unit) at a world point: the gradient of
    /// [`ImplicitField::value_and_gradient`], bit for bit. The mesher asks only for this at
    /// each vertex; a field that gets it for less than value and gradient overrides it.
    #[inline]
    fn gradient(&self, p: Vec3) -> Vec3 {
        self.value_and_gradient(p).1
    }
}

impl ImplicitField for BSplineLattice {
    #[inline]
    fn iso(&self) -> f32 {
        self.iso
    }

    #[inline]
    fn value(&self, p: Vec3) -> f32 {
        BSplineLattice::value(self, p)
    }

    /// The lattice's own evaluation (with its interior fast path): one summation order for
    /// the mesher, the haptic loop and the tools.
    #[inline]
    fn value_and_gradient(&self, p: Vec3) -> (f32, Vec3) {
        BSplineLattice::value_and_gradient(self, p)
    }
}

/// The clay's density, `Σ s_i(T_i x)` (Hua & Qin eq. (3)), at the base patch's iso-level.
impl ImplicitField for MultiPatchField {
    #[inline]
    fn iso(&self) -> f32 {
        MultiPatchField::iso(self)
    }

    #[inline]
    fn value(&self, p: Vec3) -> f32 {
        MultiPatchField::value(self, p)
    }

    #[inline]
    fn value_and_gradient(&self, p: Vec3) -> (f32, Vec3) {
        MultiPatchField::value_and_gradient(self, p)
    }
}
