//! Mirror symmetry of strokes: the planes x, y and z through the clay's centre, each on or off.
//!
//! Pure value arithmetic, no allocation: [`Symmetry::images`] yields the mirrored copies of a
//! point (up to seven with all three planes on, one per non-empty subset of the planes), and the
//! simulation applies the held tool or its forces at each of them in the same step as the
//! original, recorded in the same undo step.

use glam::Vec3;

use dynaclay_core::dynamics::{ToolBody, ToolForce};
use dynaclay_core::field::BSplineLattice;

/// Which mirror planes are on.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Symmetry {
    /// Mirror across the plane x = centre.x.
    pub x: bool,
    /// Mirror across the plane y = centre.y.
    pub y: bool,
    /// Mirror across the plane z = centre.z.
    pub z: bool,
}

impl Symmetry {
    /// No mirroring.
    pub const OFF: Self = Self {
        x: false,
        y: false,
        z: false,
    };

    /// Whether any plane is on.
    #[must_use]
    pub fn any(self) -> bool {
        self.x || self.y || self.z
    }

    /// The sign flips of every mirrored copy: each non-empty combination of the planes that
    /// are on, as a vector of ±1 per axis (−1 where that axis is mirrored).
    pub fn flips(self) -> impl Iterator<Item = Vec3> {
        let on = [self.x, self.y, self.z];
        (1u8..8).filter_map(move |mask| {
            let uses = |axis: usize| mask & (1 << axis) != 0;
            if (0..3).any(|a| uses(a) && !on[a]) {
                return None;
            }
            Some(Vec3::new(
                if uses(0) { -1.0 } else { 1.0 },
                if uses(1) { -1.0 } else { 1.0 },
                if uses(2) { -1.0 } else { 1.0 },
            ))
        })
    }

    /// The mirrored copies of `p` about `centre`.
    pub fn images(self, p: Vec3, centre: Vec3) -> impl Iterator<Item = Vec3> {
        self.flips().map(move |s| mirror(p, centre, s))
    }
}

/// `p` reflected about `centre` along the axes where `flip` is −1.
#[inline]
#[must_use]
pub fn mirror(p: Vec3, centre: Vec3, flip: Vec3) -> Vec3 {
    centre + (p - centre) * flip
}

/// A force vector reflected about `centre` (both ends, so its direction is reflected too).
#[inline]
#[must_use]
pub fn mirror_force(f: &ToolForce, centre: Vec3, flip: Vec3) -> ToolForce {
    ToolForce {
        start: mirror(f.start, centre, flip),
        end: mirror(f.end, centre, flip),
        ..*f
    }
}

/// A tool body reflected about `centre` (both ends of its shaft).
#[inline]
#[must_use]
pub fn mirror_body(b: &ToolBody, centre: Vec3, flip: Vec3) -> ToolBody {
    ToolBody {
        inner: mirror(b.inner, centre, flip),
        outer: mirror(b.outer, centre, flip),
        ..*b
    }
}

/// The clay's centre: the middle of the lattice's coefficient box, which the starting block
/// and sphere are centred on.
#[must_use]
pub fn clay_centre(lattice: &BSplineLattice) -> Vec3 {
    let last = lattice.node_position(
        lattice.dims[0] - 1,
        lattice.dims[1] - 1,
        lattice.dims[2] - 1,
    );
    (lattice.origin + last) * 0.5
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_plane_combination_gives_one_image() {
        let c = Vec3::splat(1.0);
        let p = Vec3::new(1.5, 0.25, 2.0);
        assert_eq!(Symmetry::OFF.images(p, c).count(), 0);
        let x = Symmetry {
            x: true,
            ..Symmetry::OFF
        };
        assert_eq!(
            x.images(p, c).collect::<Vec<_>>(),
            [Vec3::new(0.5, 0.25, 2.0)]
        );
        let xz = Symmetry {
            x: true,
            z: true,
            ..Symmetry::OFF
        };
        let images: Vec<Vec3> = xz.images(p, c).collect();
        assert_eq!(
            images,
            [
                Vec3::new(0.5, 0.25, 2.0),
                Vec3::new(1.5, 0.25, 0.0),
                Vec3::new(0.5, 0.25, 0.0)
            ]
        );
        let all = Symmetry {
            x: true,
            y: true,
            z: true,
        };
        assert_eq!(all.images(p, c).count(), 7);
        let f = ToolForce {
            start: Vec3::new(1.5, 1.0, 1.0),
            end: Vec3::new(1.25, 1.0, 1.0),
            distribution: dynaclay_core::dynamics::Distribution::Gaussian,
            radius: 0.1,
            gain: 1.0,
        };
        let m = mirror_force(&f, c, Vec3::new(-1.0, 1.0, 1.0));
        assert_eq!(m.start, Vec3::new(0.5, 1.0, 1.0));
        assert_eq!(
            m.end - m.start,
            Vec3::new(0.25, 0.0, 0.0),
            "direction mirrored"
        );
    }
}
