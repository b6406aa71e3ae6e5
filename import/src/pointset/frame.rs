//! A cloud's unit frame: the similarity that takes its bounding box to one centred at the
//! origin whose longest half-side is 1. The point-set surface's arithmetic (squared lengths,
//! local fits, the sculpting lattice) runs in `f32` at unit scale, so a cloud in any units
//! (a scan in metres at 1e-30 or in a survey's 1e30) is built in its unit frame and its
//! outputs taken back to the file's units.

use glam::Vec3;

use crate::fit::PointCloud;

/// `file = unit · scale + centre`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UnitFrame {
    /// The box's centre, file units.
    pub centre: Vec3,
    /// The box's longest half-side, file units (1 for a cloud without extent).
    pub scale: f32,
}

impl UnitFrame {
    /// The unit frame of `points`: the identity for an empty cloud or one without a finite,
    /// positive extent (the build then reports what is wrong with it).
    #[must_use]
    pub fn of(points: &[Vec3]) -> Self {
        let (lo, hi) = points.iter().fold(
            (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
            |(lo, hi), &p| (lo.min(p), hi.max(p)),
        );
        // Halves first, so that a box near f32::MAX does not overflow.
        let centre = 0.5 * lo + 0.5 * hi;
        let scale = (0.5 * hi - 0.5 * lo).max_element();
        if centre.is_finite() && scale.is_finite() && scale > 0.0 {
            Self { centre, scale }
        } else {
            Self {
                centre: Vec3::ZERO,
                scale: 1.0,
            }
        }
    }

    /// A file point in the unit frame.
    #[must_use]
    pub fn to_unit(&self, p: Vec3) -> Vec3 {
        (p - self.centre) / self.scale
    }

    /// A unit-frame point in file units.
    #[must_use]
    pub fn to_file(&self, p: Vec3) -> Vec3 {
        p * self.scale + self.centre
    }

    /// The cloud in the unit frame (normals are unchanged by a similarity).
    #[must_use]
    pub fn cloud_to_unit(&self, cloud: &PointCloud) -> PointCloud {
        PointCloud {
            points: cloud.points.iter().map(|&p| self.to_unit(p)).collect(),
            normals: cloud.normals.clone(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_frame_takes_the_box_to_unit_size_and_back_at_any_scale() {
        for s in [1e-30_f32, 1.0, 1e30] {
            let points = [Vec3::new(1.0, 2.0, 3.0) * s, Vec3::new(3.0, 2.5, 4.0) * s];
            let f = UnitFrame::of(&points);
            let unit: Vec<Vec3> = points.iter().map(|&p| f.to_unit(p)).collect();
            assert!(
                (unit[0] - Vec3::new(-1.0, -0.25, -0.5)).length() < 1e-5,
                "{s}: {unit:?}"
            );
            assert!(
                (unit[1] - Vec3::new(1.0, 0.25, 0.5)).length() < 1e-5,
                "{s}: {unit:?}"
            );
            let back = f.to_file(unit[1]);
            assert!(
                (back - points[1]).length() <= 1e-5 * points[1].length(),
                "{s}"
            );
        }
        assert_eq!(UnitFrame::of(&[Vec3::ONE; 3]).scale, 1.0);
        assert_eq!(UnitFrame::of(&[]).centre, Vec3::ZERO);
    }
}
