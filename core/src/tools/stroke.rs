//! A geometric tool's stroke resampled along its length: applications at most
//! [`ToolShape::stroke_spacing_fu`] apart (a quarter of the tool's smallest half extent), so
//! that they overlap into one continuous groove or bead whatever the spacing of the points
//! the stroke was given by (script positions, or tool samples at the simulation's rate).
//!
//! Pure and cheap: a count and a few interpolations per segment. The resampled path of a
//! script allocates once.

use glam::Vec3;

use super::shape::{ToolPose, ToolShape};

/// Most applications one segment of a live stroke is split into (between two simulation
/// steps): a faster tip spaces them wider rather than stalling the simulation.
pub const MAX_SEGMENT_APPLICATIONS: u32 = 16;

/// Most poses a script stroke is resampled to: beyond it the spacing widens evenly.
pub const MAX_STROKE_POSES: usize = 100_000;

/// How many equal steps cover `length_fu` with none longer than `spacing_fu`, between 1 and
/// `max` (1 for a zero, non-finite or degenerate length).
#[must_use]
pub fn steps_along(length_fu: f32, spacing_fu: f32, max: u32) -> u32 {
    if !(length_fu.is_finite() && spacing_fu.is_finite() && spacing_fu > 0.0) {
        return 1;
    }
    // NOTE: a relative 1e-5 of slack, so a length that is a whole number of spacings up to
    // rounding is not split once more.
    let steps = (length_fu / spacing_fu * (1.0 - 1e-5)).ceil();
    if steps >= max as f32 {
        max.max(1)
    } else {
        (steps as u32).max(1)
    }
}

/// The poses of a stroke through `poses` for `shape`: every given pose is kept, and each
/// segment between two is split evenly so that no step is longer than the shape's stroke
/// spacing (positions interpolated linearly, rotations spherically). At most
/// [`MAX_STROKE_POSES`] poses: a longer path is spaced evenly wider.
#[must_use]
pub fn resample_stroke(poses: &[ToolPose], shape: &ToolShape) -> Vec<ToolPose> {
    let Some(first) = poses.first() else {
        return Vec::new();
    };
    let length: f32 = poses
        .windows(2)
        .map(|w| w[0].position_fu.distance(w[1].position_fu))
        .sum();
    // Widen the spacing evenly when the path would need too many poses.
    let budget = (MAX_STROKE_POSES - poses.len().min(MAX_STROKE_POSES)) as f32;
    let spacing = shape.stroke_spacing_fu().max(if budget > 0.0 {
        length / budget
    } else {
        f32::INFINITY
    });
    let mut out = Vec::with_capacity(poses.len());
    out.push(*first);
    for w in poses.windows(2) {
        let (a, b) = (w[0], w[1]);
        let n = steps_along(a.position_fu.distance(b.position_fu), spacing, u32::MAX);
        for i in 1..=n {
            let s = i as f32 / n as f32;
            out.push(ToolPose {
                position_fu: lerp(a.position_fu, b.position_fu, s),
                rotation: a.rotation.slerp(b.rotation, s),
            });
        }
    }
    out
}

/// `a + (b − a)·s`: exact at `s = 0` and keeps a coordinate `a` and `b` share.
#[must_use]
pub fn lerp(a: Vec3, b: Vec3, s: f32) -> Vec3 {
    a + (b - a) * s
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Quat;

    #[test]
    fn steps_cover_the_length_within_the_spacing_and_are_bounded() {
        assert_eq!(steps_along(0.0, 0.025, 16), 1);
        assert_eq!(steps_along(0.025, 0.025, 16), 1);
        assert_eq!(steps_along(0.026, 0.025, 16), 2);
        assert_eq!(steps_along(0.1, 0.025, 16), 4);
        assert_eq!(steps_along(10.0, 0.025, 16), 16);
        assert_eq!(steps_along(f32::NAN, 0.025, 16), 1);
        assert_eq!(steps_along(1.0, 0.0, 16), 1);
    }

    #[test]
    fn a_script_stroke_keeps_its_points_and_fills_between_them() {
        let shape = ToolShape::Sphere { radius_fu: 0.1 };
        let turn = Quat::from_rotation_y(1.0);
        let poses = [
            ToolPose::at(Vec3::ZERO),
            ToolPose {
                position_fu: Vec3::new(0.3, 0.0, 0.0),
                rotation: turn,
            },
            ToolPose::at(Vec3::new(0.3, 0.0, 0.01)),
        ];
        let out = resample_stroke(&poses, &shape);
        // 0.3 at 0.025: 12 steps; 0.01: 1 step; and the first pose.
        assert_eq!(out.len(), 1 + 12 + 1);
        assert_eq!(out[0], poses[0]);
        assert_eq!(out[12], poses[1]);
        assert_eq!(out[13], poses[2]);
        for w in out.windows(2) {
            assert!(w[0].position_fu.distance(w[1].position_fu) <= 0.025 + 1e-6);
        }
        assert!(out[6].rotation.angle_between(Quat::from_rotation_y(0.5)) < 1e-4);
        assert!(resample_stroke(&[], &shape).is_empty());
        assert_eq!(resample_stroke(&poses[..1], &shape), vec![poses[0]]);
        // A path that would need more poses than allowed is spaced wider, evenly.
        let far = [
            ToolPose::at(Vec3::ZERO),
            ToolPose::at(Vec3::new(1e4, 0.0, 0.0)),
        ];
        assert!(resample_stroke(&far, &shape).len() <= MAX_STROKE_POSES + 1);
    }
}
