//! Camera navigation: mouse drags and scrolling on the viewport (virtual trackball, pan,
//! zoom) and, when one is plugged in, a SpaceMouse (object mode: the scene follows the cap).
//!
//! The mappings are pure functions of the camera and the input, so they are tested without a
//! window. The SpaceMouse is read on the GUI thread with non-blocking HID reads (bounded work
//! per frame); it is never the haptic device at the same time.

use glam::{Quat, Vec2, Vec3};

use dynaclay_devices::HapticDevice;
use dynaclay_devices::pose_input::PoseInputConfig;
use dynaclay_devices::spacemouse::SpaceMouse;

use crate::render::{Camera, Trackball};

/// Zoom factor per scroll point: one notch (≈ 50 points) changes the distance by about 10 %.
const ZOOM_PER_SCROLL_POINT: f32 = 0.002;

/// Rotates the camera for a drag from `from_px` to `to_px` in a `size_px` viewport.
pub fn drag_rotate(
    camera: &mut Camera,
    trackball: &Trackball,
    from_px: Vec2,
    to_px: Vec2,
    size_px: Vec2,
) {
    let a = Trackball::normalize(from_px, size_px.x, size_px.y);
    let b = Trackball::normalize(to_px, size_px.x, size_px.y);
    let q = trackball.eye_rotation(camera, a, b);
    camera.rotate(q);
}

/// Pans so the content under the cursor follows a drag of `delta_px` in a viewport
/// `height_px` tall.
pub fn drag_pan(camera: &mut Camera, delta_px: Vec2, height_px: f32) {
    let h = height_px.max(1.0);
    // Camera::pan takes half-heights, +y up; screen y grows downward.
    camera.pan(2.0 * delta_px.x / h, -2.0 * delta_px.y / h);
}

/// Zooms for a vertical scroll of `scroll_points` (positive: scroll up, move closer).
pub fn scroll_zoom(camera: &mut Camera, scroll_points: f32) {
    camera.zoom((-scroll_points * ZOOM_PER_SCROLL_POINT).exp());
}

/// Applies a SpaceMouse motion in object mode: `translation` in view axes (x right, y up, z
/// toward the viewer) in half-heights of the view, `rotation` a view-space rotation of the
/// scene. The camera moves the opposite way so the scene follows the cap.
pub fn spacemouse_move(camera: &mut Camera, translation: Vec3, rotation: Quat) {
    if translation.is_finite() {
        camera.pan(translation.x, translation.y);
        camera.zoom((-translation.z).exp());
    }
    if !rotation.is_finite() {
        return;
    }
    let (axis_view, angle) = rotation.to_axis_angle();
    if angle.abs() < 1.0e-7 {
        return;
    }
    let (right, up) = camera.right_up();
    let back = camera.eye_direction();
    let axis_world = right * axis_view.x + up * axis_view.y + back * axis_view.z;
    camera.rotate(Quat::from_axis_angle(
        axis_world.normalize_or(Vec3::Y),
        -angle,
    ));
}

/// Pose-integrator settings for camera use: speeds in view half-heights per second, and a
/// workspace too large to clamp.
#[must_use]
pub fn camera_pose_config() -> PoseInputConfig {
    PoseInputConfig {
        max_speed_m_per_s: 1.5,
        max_turn_rad_per_s: 1.5,
        workspace_min_m: Vec3::splat(-1.0e6),
        workspace_max_m: Vec3::splat(1.0e6),
        ..PoseInputConfig::default()
    }
}

/// A SpaceMouse driving the camera.
#[derive(Default)]
pub struct SpaceMouseCamera {
    device: Option<SpaceMouse>,
    last: Option<(Vec3, Quat)>,
    /// Why the last attempt to open or read failed, for the device panel.
    pub status: String,
}

impl SpaceMouseCamera {
    /// Tries to open a SpaceMouse; on failure keeps the reason in `status`.
    pub fn connect(&mut self) {
        let mut dev = SpaceMouse::new(camera_pose_config());
        match dev.open() {
            Ok(()) => {
                self.device = Some(dev);
                self.last = None;
                self.status = "SpaceMouse drives the camera".into();
            }
            Err(e) => {
                self.device = None;
                self.status = format!("no SpaceMouse for the camera: {e}");
            }
        }
    }

    /// Closes the SpaceMouse (for example before it is opened as the haptic device).
    pub fn disconnect(&mut self) {
        if let Some(mut d) = self.device.take() {
            let _ = d.close();
        }
        self.last = None;
        self.status = "SpaceMouse camera off".into();
    }

    #[must_use]
    pub fn is_connected(&self) -> bool {
        self.device.is_some()
    }

    /// Reads queued reports (non-blocking) and moves the camera; true when it moved.
    pub fn poll(&mut self, camera: &mut Camera) -> bool {
        let Some(dev) = self.device.as_mut() else {
            return false;
        };
        let state = match dev.read() {
            Ok(s) => s,
            Err(e) => {
                self.status = format!("SpaceMouse camera stopped: {e}");
                self.device = None;
                self.last = None;
                return false;
            }
        };
        let pose = (
            state.position_m,
            state.orientation.unwrap_or(Quat::IDENTITY),
        );
        let Some((p0, q0)) = self.last.replace(pose) else {
            return false;
        };
        let dp = pose.0 - p0;
        let dq = pose.1 * q0.inverse();
        if dp.length_squared() < 1.0e-12 && dq.to_axis_angle().1.abs() < 1.0e-7 {
            return false;
        }
        spacemouse_move(camera, dp, dq);
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::NamedView;

    fn front() -> Camera {
        Camera::named(NamedView::Front, Vec3::splat(-1.0), Vec3::splat(1.0))
    }

    #[test]
    fn dragging_right_turns_the_eye_left_and_pan_follows_the_cursor() {
        let mut cam = front();
        let size = Vec2::new(400.0, 300.0);
        drag_rotate(
            &mut cam,
            &Trackball::default(),
            Vec2::new(200.0, 150.0),
            Vec2::new(260.0, 150.0),
            size,
        );
        assert!(cam.eye().x < -1e-3, "eye {}", cam.eye());

        let mut cam = front();
        let (right, up) = cam.right_up();
        drag_pan(&mut cam, Vec2::new(30.0, -20.0), 300.0);
        // Content moves right and up, so the target moves left and down.
        assert!(
            cam.target.dot(right) < 0.0 && cam.target.dot(up) < 0.0,
            "{}",
            cam.target
        );
    }

    #[test]
    fn scrolling_up_moves_closer_and_back_restores() {
        let mut cam = front();
        let d0 = cam.distance;
        scroll_zoom(&mut cam, 100.0);
        assert!(cam.distance < d0);
        scroll_zoom(&mut cam, -100.0);
        assert!((cam.distance - d0).abs() < 1e-4 * d0);
        scroll_zoom(&mut cam, f32::NAN);
        assert!(cam.distance.is_finite());
    }

    #[test]
    fn spacemouse_twist_turns_the_scene_with_the_cap() {
        let mut cam = front();
        // Twisting the cap about view up (scene turns right) moves the eye to -x, like a
        // rightward trackball drag.
        spacemouse_move(&mut cam, Vec3::ZERO, Quat::from_rotation_y(0.2));
        assert!(cam.eye().x < -1e-3, "eye {}", cam.eye());
        let mut cam = front();
        let d0 = cam.distance;
        spacemouse_move(&mut cam, Vec3::new(0.0, 0.0, 0.5), Quat::IDENTITY);
        assert!(
            cam.distance < d0,
            "pulling the cap toward the user brings the scene closer"
        );
        spacemouse_move(&mut cam, Vec3::NAN, Quat::NAN);
        assert!(cam.eye().is_finite());
    }

    #[test]
    fn an_absent_spacemouse_never_moves_the_camera() {
        let mut sm = SpaceMouseCamera::default();
        let mut cam = front();
        assert!(!sm.poll(&mut cam));
        assert_eq!(cam, front());
    }
}
