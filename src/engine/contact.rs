//! Contact between the tool tip and the clay, and the reaction force the user feels.
//!
//! Guarantee: [`Contact::update`] does bounded work — at most [`MAX_PROBES`] field evaluations
//! plus one gradient — allocates nothing and takes no lock, so it runs on the haptic path.
//!
//! The push tool follows Hua & Qin §4.2 and §7.2: while a stroke is active and the tip is
//! inside the clay, the force vector runs from `x0`, the clay's surface above the tip, to
//! `x1`, the tip. The force on the clay is `f = −l ∫₀¹ (s(x0 + t(x1 − x0)) − c0) dt`
//! (4-point Gauss–Legendre, [`force_integral`]), negative here (it removes density along the vector), and the user
//! feels the equal and opposite force: magnitude `|f|` pointing from the tip back toward the
//! surface. As the dent catches up with the tip the integral, and so the force, falls smoothly
//! to zero (§7.2.2).
//!
//! `x0` is found by marching from the tip along the outward surface normal taken where the
//! tip entered the clay (inside a saturated solid the field's own gradient is zero, so the
//! entry normal is the stable direction), then bisecting the crossing.

use glam::Vec3;

pub use crate::dynamics::force_integral;
use crate::field::BSplineLattice;

/// Marching steps used to find the surface above the tip.
const MARCH_STEPS: usize = 16;
/// Bisection steps after the march.
const BISECT_STEPS: usize = 10;
/// Upper bound on field evaluations in one [`Contact::update`].
pub const MAX_PROBES: usize = MARCH_STEPS + BISECT_STEPS + 4 + 2;

/// Settings of the push tool.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ContactConfig {
    /// Farthest the surface is searched for above the tip, field units (the deepest push that
    /// still renders a force).
    pub max_depth: f32,
}

impl Default for ContactConfig {
    fn default() -> Self {
        Self { max_depth: 0.6 }
    }
}

/// One tick's contact result.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ContactForce {
    /// Whether the tip is pushing into the clay.
    pub in_contact: bool,
    /// Start of the force vector (surface), field coordinates.
    pub from: Vec3,
    /// End of the force vector (tip), field coordinates.
    pub to: Vec3,
    /// Eq. (6) along the vector (≤ 0 while pushing), field units.
    pub integral: f32,
    /// The reaction on the tool, field units (pointing from the tip toward the surface).
    pub reaction: Vec3,
}

impl ContactForce {
    /// No contact at `tip`.
    #[must_use]
    pub fn none(tip: Vec3) -> Self {
        Self {
            in_contact: false,
            from: tip,
            to: tip,
            integral: 0.0,
            reaction: Vec3::ZERO,
        }
    }
}

/// The contact state carried from tick to tick.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Contact {
    config: ContactConfig,
    /// Outward normal where the tip entered the clay, while in contact.
    entry_normal: Option<Vec3>,
    /// Last tip position seen outside the clay.
    last_outside: Option<Vec3>,
}

impl Contact {
    /// A tool not touching anything.
    #[must_use]
    pub fn new(config: ContactConfig) -> Self {
        Self {
            config,
            entry_normal: None,
            last_outside: None,
        }
    }

    /// Ends any contact (stroke released, device fault).
    pub fn release(&mut self) {
        self.entry_normal = None;
    }

    /// Updates the contact for the tip at `tip` on `field` and returns the force.
    pub fn update(
        &mut self,
        field: &BSplineLattice,
        tip: Vec3,
        stroke_active: bool,
    ) -> ContactForce {
        let inside = field.value(tip) > field.iso;
        if !inside || !stroke_active || !tip.is_finite() {
            self.entry_normal = None;
            if !inside && tip.is_finite() {
                self.last_outside = Some(tip);
            }
            return ContactForce::none(tip);
        }
        let normal = match self.entry_normal {
            Some(n) => n,
            None => {
                let n = self.entry_direction(field, tip);
                self.entry_normal = Some(n);
                n
            }
        };
        let Some(from) = self.surface_above(field, tip, normal) else {
            // Deeper than the search reaches: render nothing rather than a wrong force.
            return ContactForce::none(tip);
        };
        let integral = force_integral(field, from, tip);
        let d = from - tip;
        let l = d.length();
        let reaction = if l > 0.0 && integral < 0.0 {
            d * (-integral / l)
        } else {
            Vec3::ZERO
        };
        ContactForce {
            in_contact: true,
            from,
            to: tip,
            integral,
            reaction,
        }
    }

    /// Outward direction at entry: the field's falling gradient at the tip, else the way the
    /// tip came in, else +y.
    fn entry_direction(&self, field: &BSplineLattice, tip: Vec3) -> Vec3 {
        let g = -field.gradient(tip);
        if let Some(n) = g.try_normalize() {
            return n;
        }
        self.last_outside
            .and_then(|p| (p - tip).try_normalize())
            .unwrap_or(Vec3::Y)
    }

    /// The first point outside the clay from `tip` along `normal` (within `max_depth`).
    fn surface_above(&self, field: &BSplineLattice, tip: Vec3, normal: Vec3) -> Option<Vec3> {
        let step = self.config.max_depth / MARCH_STEPS as f32;
        let mut inner = 0.0f32;
        let mut outer = None;
        for i in 1..=MARCH_STEPS {
            let t = step * i as f32;
            if field.value(tip + normal * t) <= field.iso {
                outer = Some(t);
                break;
            }
            inner = t;
        }
        let mut outer = outer?;
        for _ in 0..BISECT_STEPS {
            let mid = 0.5 * (inner + outer);
            if field.value(tip + normal * mid) > field.iso {
                inner = mid;
            } else {
                outer = mid;
            }
        }
        Some(tip + normal * outer)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::{Primitive, lattice_from_primitive};

    fn slab() -> BSplineLattice {
        // Solid below y = 1.0.
        lattice_from_primitive(
            [14, 14, 14],
            0.2,
            Vec3::ZERO,
            &Primitive::Box {
                centre: Vec3::new(1.3, 0.5, 1.3),
                half_extents: Vec3::new(2.0, 0.5, 2.0),
            },
            0.4,
            2,
        )
        .unwrap()
    }

    #[test]
    fn gauss_legendre_is_exact_for_a_cubic_line() {
        // A lattice of a linear function restricted to a segment is linear; check eq. (6)
        // against the closed form on a field with s = y (iso 0).
        let mut l = BSplineLattice::zeros([8, 8, 8], 0.5, Vec3::ZERO).unwrap();
        for k in 0..8 {
            for j in 0..8 {
                for i in 0..8 {
                    let idx = l.index(i, j, k);
                    l.coeffs[idx] = l.node_position(i, j, k).y;
                }
            }
        }
        l.iso = 0.0;
        let (a, b) = (Vec3::new(1.0, 1.0, 1.0), Vec3::new(1.0, 2.0, 2.0));
        // ∫ y along the segment = l · mean(y) = √2 · 1.5.
        let want = -(2.0f32).sqrt() * 1.5;
        assert!((force_integral(&l, a, b) - want).abs() < 1e-4);
    }

    #[test]
    fn pushing_in_gives_a_force_back_out_that_grows_with_depth() {
        let field = slab();
        let mut c = Contact::new(ContactConfig::default());
        let above = Vec3::new(1.3, 1.2, 1.3);
        assert!(!c.update(&field, above, true).in_contact);
        let mut last = 0.0;
        for depth in [0.05, 0.1, 0.2, 0.3] {
            let tip = Vec3::new(1.3, 1.0 - depth, 1.3);
            let f = c.update(&field, tip, true);
            assert!(f.in_contact);
            assert!((f.from.y - 1.0).abs() < 0.03, "surface at {}", f.from);
            assert!(f.reaction.y > last, "depth {depth}: {:?}", f.reaction);
            assert!(f.reaction.x.abs() < 1e-3 && f.reaction.z.abs() < 1e-3);
            last = f.reaction.y;
        }
        // Without a stroke nothing is rendered.
        let f = c.update(&field, Vec3::new(1.3, 0.8, 1.3), false);
        assert_eq!(f.reaction, Vec3::ZERO);
    }
}
