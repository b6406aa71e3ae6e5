//! What the particles sample: the zero set of a function `F`, positive inside.

use glam::Vec3;

use dynaclay_core::field::{BSplineLattice, MultiPatchField};

/// A surface given implicitly: `F(x) = 0` on it, `F > 0` inside. The clay is one (its value
/// less its iso-level); the RBF sculpt of Zhang et al. §5.4 (`h = I + β·g`) is the other.
pub trait ImplicitSurface {
    /// `(F(x), ∇F(x))`.
    fn eval(&self, x: Vec3) -> (f32, Vec3);
    /// A box holding the surface. The PDS covers it; particles outside are still found.
    fn bounds(&self) -> (Vec3, Vec3);
    /// The finest length the surface resolves (the clay's knot spacing): the seeding band's
    /// half-width and the scale of the smallest repulsion radius.
    fn resolution(&self) -> f32;
}

/// The clay's whole density (eq. (3)): particles sit on the sum of its patches.
impl ImplicitSurface for MultiPatchField {
    #[inline]
    fn eval(&self, x: Vec3) -> (f32, Vec3) {
        let (v, g) = self.value_and_gradient(x);
        (v - self.iso(), g)
    }

    fn bounds(&self) -> (Vec3, Vec3) {
        self.support()
    }

    fn resolution(&self) -> f32 {
        self.finest_spacing()
    }
}

impl ImplicitSurface for BSplineLattice {
    #[inline]
    fn eval(&self, x: Vec3) -> (f32, Vec3) {
        let (v, g) = self.value_and_gradient(x);
        (v - self.iso, g)
    }

    fn bounds(&self) -> (Vec3, Vec3) {
        self.support()
    }

    fn resolution(&self) -> f32 {
        self.spacing
    }
}
