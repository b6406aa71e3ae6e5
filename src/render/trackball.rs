//! Virtual trackball: turns a mouse drag into a rotation (Bell's sphere-plus-hyperbola sheet).
//!
//! Cursor positions are normalized viewport coordinates: x and y in `[-1, 1]` across the
//! shorter side, +y up. The drag grabs the scene and rotates it the way the cursor moved, so
//! the orbit camera turns the opposite way ([`Trackball::eye_rotation`]).

use glam::{Quat, Vec2, Vec3};

use super::camera::Camera;

/// A trackball of `radius` (in normalized viewport units) centred in the viewport.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Trackball {
    pub radius: f32,
}

impl Default for Trackball {
    fn default() -> Self {
        Self { radius: 0.8 }
    }
}

impl Trackball {
    /// Normalized viewport coordinates of a pixel position (`y` down, as window systems give
    /// it) in a `width × height` viewport; sizes are clamped to at least 1.
    #[must_use]
    pub fn normalize(pixel: Vec2, width: f32, height: f32) -> Vec2 {
        let (w, h) = (width.max(1.0), height.max(1.0));
        let half = 0.5 * w.min(h);
        Vec2::new((pixel.x - 0.5 * w) / half, (0.5 * h - pixel.y) / half)
    }

    /// Lifts a viewport point onto the trackball surface: the sphere near the centre, a
    /// hyperbolic sheet outside, so the map is smooth everywhere.
    #[must_use]
    pub fn lift(&self, p: Vec2) -> Vec3 {
        let r2 = self.radius * self.radius;
        let d2 = p.length_squared();
        let z = if d2 <= 0.5 * r2 {
            (r2 - d2).sqrt()
        } else {
            0.5 * r2 / d2.sqrt()
        };
        Vec3::new(p.x, p.y, z)
    }

    /// The rotation, in view space (x right, y up, z toward the viewer), that carries the
    /// grabbed point under `from` to `to`. Identity for a zero-length or non-finite drag.
    #[must_use]
    pub fn view_rotation(&self, from: Vec2, to: Vec2) -> Quat {
        if !(from.is_finite() && to.is_finite()) || (to - from).length_squared() < 1.0e-12 {
            return Quat::IDENTITY;
        }
        let (a, b) = (self.lift(from).normalize(), self.lift(to).normalize());
        let axis = a.cross(b);
        if axis.length_squared() < 1.0e-12 {
            return Quat::IDENTITY;
        }
        let angle = a.dot(b).clamp(-1.0, 1.0).acos();
        Quat::from_axis_angle(axis.normalize(), angle)
    }

    /// The world-space rotation to pass to [`Camera::rotate`] for a drag from `from` to `to`:
    /// the inverse of the scene's rotation, expressed in world axes.
    #[must_use]
    pub fn eye_rotation(&self, camera: &Camera, from: Vec2, to: Vec2) -> Quat {
        let q = self.view_rotation(from, to);
        let (axis_view, angle) = q.to_axis_angle();
        if angle.abs() < 1.0e-9 {
            return Quat::IDENTITY;
        }
        let (right, up) = camera.right_up();
        let back = camera.eye_direction();
        let axis_world = right * axis_view.x + up * axis_view.y + back * axis_view.z;
        Quat::from_axis_angle(axis_world.normalize_or(Vec3::Y), -angle)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::camera::NamedView;

    #[test]
    fn lift_is_continuous_at_the_seam() {
        let tb = Trackball::default();
        let seam = tb.radius / 2.0f32.sqrt();
        let inside = tb.lift(Vec2::new(seam - 1e-4, 0.0));
        let outside = tb.lift(Vec2::new(seam + 1e-4, 0.0));
        assert!((inside - outside).length() < 1e-3);
    }

    #[test]
    fn horizontal_drag_spins_about_view_up() {
        let tb = Trackball::default();
        let q = tb.view_rotation(Vec2::new(-0.1, 0.0), Vec2::new(0.1, 0.0));
        let (axis, angle) = q.to_axis_angle();
        assert!(angle > 0.0);
        assert!((axis - Vec3::Y).length() < 1e-4, "axis {axis}");
        assert_eq!(tb.view_rotation(Vec2::ZERO, Vec2::ZERO), Quat::IDENTITY);
        assert_eq!(tb.view_rotation(Vec2::NAN, Vec2::ZERO), Quat::IDENTITY);
    }

    #[test]
    fn dragging_right_orbits_the_eye_left() {
        let tb = Trackball::default();
        let mut cam = Camera::named(NamedView::Front, Vec3::splat(-1.0), Vec3::splat(1.0));
        let q = tb.eye_rotation(&cam, Vec2::new(0.0, 0.0), Vec2::new(0.2, 0.0));
        cam.rotate(q);
        // Scene turns right (+yaw of the object) ⇔ eye moves to −x.
        assert!(cam.eye().x < -1e-3, "eye {}", cam.eye());
        assert!(cam.pitch_rad.abs() < 1e-4);
    }

    #[test]
    fn normalize_maps_centre_and_corners() {
        assert_eq!(
            Trackball::normalize(Vec2::new(50.0, 25.0), 100.0, 50.0),
            Vec2::ZERO
        );
        assert_eq!(
            Trackball::normalize(Vec2::new(100.0, 0.0), 100.0, 50.0),
            Vec2::new(2.0, 1.0)
        );
    }
}
