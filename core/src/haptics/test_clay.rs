//! Clays the haptics unit tests share.

use glam::Vec3;

use crate::field::{MultiPatchField, Primitive, lattice_from_primitive};

/// A slab, solid below y = 1.0, 14 knots a side at 0.2 (its top's centre is (1.3, 1, 1.3)).
pub(super) fn slab() -> MultiPatchField {
    MultiPatchField::new(
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
        .unwrap(),
    )
}
