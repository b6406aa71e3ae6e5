//! The map between the device workspace (metres, device frame) and field coordinates.
//!
//! Guarantee: pure affine arithmetic, no allocation; the same map is used by the haptic loop
//! (device → field for the tool tip, field → device for forces) and by the script loader
//! (field → device for the simulated hand's waypoints), so both agree exactly.

use dynaclay_core::field::BSplineLattice;
use glam::Vec3;

/// Room the device reaches around the clay's starting lattice, per side, as a fraction of the
/// lattice's size: the hand can pull or add clay past the box the clay started in (the clay
/// grows under it), instead of meeting the arm's end stops at the box's faces.
pub const REACH_MARGIN: f32 = 0.125;

/// The field box a device's workspace is fitted around (see [`WorkspaceMap::fitting`]): the
/// nodes of `lattice` and [`REACH_MARGIN`] of its size beyond them on every side.
#[must_use]
pub fn reach_box(lattice: &BSplineLattice) -> (Vec3, Vec3) {
    let lo = lattice.origin;
    let hi = lattice.node_position(
        lattice.dims[0] - 1,
        lattice.dims[1] - 1,
        lattice.dims[2] - 1,
    );
    let margin = (hi - lo) * REACH_MARGIN;
    (lo - margin, hi + margin)
}

/// An isotropic affine map: `field = field_centre + (device_m − device_centre_m) · field_per_m`.
///
/// Forces scale separately: a reaction computed in field units (density × length, Hua & Qin
/// eq. 6) becomes `reaction · force_n_per_reaction` newtons in the device frame. Both frames share
/// their axes (right-handed, +y up), so directions carry over unchanged.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct WorkspaceMap {
    /// Device point that maps onto `field_centre`, metres.
    pub device_centre_m: Vec3,
    /// Field point under `device_centre_m`, field units.
    pub field_centre: Vec3,
    /// Field units per metre of device motion (positive).
    pub field_per_m: f32,
    /// Newtons at the device per unit of reaction force (density × field unit).
    #[serde(alias = "force_n_per_unit")]
    pub force_n_per_reaction: f32,
}

impl WorkspaceMap {
    /// A map that puts the device workspace box (`min_m`..`max_m`) around the field box
    /// (`field_min`..`field_max`): centres coincide and the smaller workspace half-extent maps
    /// onto the larger field half-extent, so every field point is reachable.
    #[must_use]
    pub fn fitting(
        min_m: Vec3,
        max_m: Vec3,
        field_min: Vec3,
        field_max: Vec3,
        force_n_per_reaction: f32,
    ) -> Self {
        let device_half = ((max_m - min_m) * 0.5).min_element().max(1e-6);
        let field_half = ((field_max - field_min) * 0.5).max_element().max(1e-6);
        Self {
            device_centre_m: (min_m + max_m) * 0.5,
            field_centre: (field_min + field_max) * 0.5,
            field_per_m: field_half / device_half,
            force_n_per_reaction,
        }
    }

    /// Device position (metres) to field coordinates.
    #[inline]
    #[must_use]
    pub fn to_field(&self, device_m: Vec3) -> Vec3 {
        self.field_centre + (device_m - self.device_centre_m) * self.field_per_m
    }

    /// Field coordinates to device position (metres).
    #[inline]
    #[must_use]
    pub fn to_device(&self, field: Vec3) -> Vec3 {
        self.device_centre_m + (field - self.field_centre) / self.field_per_m
    }

    /// A reaction force in field units to newtons at the device.
    #[inline]
    #[must_use]
    pub fn force_to_device(&self, reaction: Vec3) -> Vec3 {
        reaction * self.force_n_per_reaction
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_and_fits_the_field() {
        let map = WorkspaceMap::fitting(
            Vec3::splat(-0.1),
            Vec3::new(0.1, 0.1, 0.1),
            Vec3::ZERO,
            Vec3::splat(2.0),
            3.0,
        );
        assert!((map.field_per_m - 10.0).abs() < 1e-5);
        assert!(map.to_field(Vec3::ZERO).abs_diff_eq(Vec3::ONE, 1e-6));
        assert!(
            map.to_field(Vec3::splat(0.1))
                .abs_diff_eq(Vec3::splat(2.0), 1e-5)
        );
        let p = Vec3::new(0.3, 1.7, 0.9);
        assert!(map.to_field(map.to_device(p)).abs_diff_eq(p, 1e-5));
        assert_eq!(map.force_to_device(Vec3::X), Vec3::new(3.0, 0.0, 0.0));
    }

    #[test]
    fn the_reach_box_holds_the_lattice_and_room_past_every_face() {
        let lattice = BSplineLattice::zeros([9, 9, 9], 0.25, Vec3::new(1.0, 2.0, 3.0)).unwrap();
        let (lo, hi) = reach_box(&lattice);
        assert!(lo.abs_diff_eq(Vec3::new(0.75, 1.75, 2.75), 1e-6), "{lo}");
        assert!(hi.abs_diff_eq(Vec3::new(3.25, 4.25, 5.25), 1e-6), "{hi}");
    }
}
