//! The orbit camera: yaw, pitch and distance around a target, with view and projection matrices.
//!
//! World space is right-handed with +Y up. At yaw 0 and pitch 0 the eye sits on the +Z side of
//! the target looking toward −Z (the `front` view). Pitch is kept strictly inside ±90° so the
//! view matrix never degenerates; roll is not represented.

use std::str::FromStr;

use glam::{Mat4, Quat, Vec3};

/// A camera orbiting `target` at `distance`, described by yaw (about +Y) and pitch (elevation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// The point looked at and orbited around, in world units.
    pub target: Vec3,
    /// Rotation of the eye about the +Y axis through the target, radians.
    pub yaw_rad: f32,
    /// Elevation of the eye above the target's horizontal plane, radians.
    pub pitch_rad: f32,
    /// Eye-to-target distance, world units.
    pub distance: f32,
    /// Vertical field of view, radians.
    pub fov_y_rad: f32,
}

impl Default for Camera {
    fn default() -> Self {
        Self::named(NamedView::Iso, Vec3::splat(-1.0), Vec3::splat(1.0))
    }
}

impl Camera {
    /// Largest |pitch|: a hair short of the pole so `look_at` keeps a well-defined up vector.
    pub const MAX_PITCH_RAD: f32 = std::f32::consts::FRAC_PI_2 - 1.0e-3;
    /// Default vertical field of view (40°).
    pub const DEFAULT_FOV_Y_RAD: f32 = 40.0 * std::f32::consts::PI / 180.0;
    /// Smallest and largest distance `zoom` allows, world units.
    pub const MIN_DISTANCE: f32 = 1.0e-4;
    pub const MAX_DISTANCE: f32 = 1.0e6;
    /// Near and far clip planes as fractions/multiples of `distance`.
    const NEAR_RATIO: f32 = 0.01;
    const FAR_RATIO: f32 = 100.0;

    /// A camera showing the box `[lo, hi]` whole from the named direction, for any aspect ≥ 1
    /// (wider images only add margin).
    #[must_use]
    pub fn named(view: NamedView, lo: Vec3, hi: Vec3) -> Self {
        let (yaw_rad, pitch_rad) = view.angles();
        let mut camera = Self {
            target: Vec3::ZERO,
            yaw_rad,
            pitch_rad: pitch_rad.clamp(-Self::MAX_PITCH_RAD, Self::MAX_PITCH_RAD),
            distance: 1.0,
            fov_y_rad: Self::DEFAULT_FOV_Y_RAD,
        };
        camera.frame_box(lo, hi);
        camera
    }

    /// Moves the target to the box's centre and sets the distance so the box's bounding sphere
    /// fits the vertical field of view with a small margin.
    pub fn frame_box(&mut self, lo: Vec3, hi: Vec3) {
        let centre = (lo + hi) * 0.5;
        let radius = ((hi - lo).length() * 0.5).max(1.0e-3);
        self.target = if centre.is_finite() {
            centre
        } else {
            Vec3::ZERO
        };
        let half_fov = (self.fov_y_rad * 0.5).clamp(0.01, 1.5);
        self.distance =
            (1.05 * radius / half_fov.sin()).clamp(Self::MIN_DISTANCE, Self::MAX_DISTANCE);
    }

    /// Unit vector from the target toward the eye.
    #[must_use]
    pub fn eye_direction(&self) -> Vec3 {
        let (sy, cy) = self.yaw_rad.sin_cos();
        let (sp, cp) = self.pitch_rad.sin_cos();
        Vec3::new(cp * sy, sp, cp * cy)
    }

    /// Eye position in world units.
    #[must_use]
    pub fn eye(&self) -> Vec3 {
        self.target + self.eye_direction() * self.distance
    }

    /// The camera's right and up axes in world space (unit, orthogonal to the view direction).
    #[must_use]
    pub fn right_up(&self) -> (Vec3, Vec3) {
        let forward = -self.eye_direction();
        let right = forward.cross(Vec3::Y).normalize_or(Vec3::X);
        (right, right.cross(forward))
    }

    /// World → view matrix (right-handed, camera looks down −Z).
    #[must_use]
    pub fn view(&self) -> Mat4 {
        glam::camera::rh::view::look_at_mat4(self.eye(), self.target, Vec3::Y)
    }

    /// View → clip matrix for wgpu's depth range `[0, 1]`; `aspect` is width / height.
    #[must_use]
    pub fn projection(&self, aspect: f32) -> Mat4 {
        let aspect = if aspect.is_finite() && aspect > 0.0 {
            aspect
        } else {
            1.0
        };
        let near = self.distance * Self::NEAR_RATIO;
        // WebGPU's convention: right-handed view space, NDC depth in [0, 1], y up.
        glam::camera::rh::proj::directx::perspective(
            self.fov_y_rad,
            aspect,
            near,
            self.distance * Self::FAR_RATIO,
        )
    }

    /// `projection(aspect) * view()`.
    #[must_use]
    pub fn view_projection(&self, aspect: f32) -> Mat4 {
        self.projection(aspect) * self.view()
    }

    /// The view ray through a point of the image, `ndc` in normalised device coordinates
    /// (x right, y up, both −1..1): its origin on the near plane and its unit direction.
    #[must_use]
    pub fn ray_through(&self, ndc: glam::Vec2, aspect: f32) -> (Vec3, Vec3) {
        let inverse = self.view_projection(aspect).inverse();
        let near = inverse.project_point3(Vec3::new(ndc.x, ndc.y, 0.0));
        let far = inverse.project_point3(Vec3::new(ndc.x, ndc.y, 1.0));
        (near, (far - near).normalize_or(-self.eye_direction()))
    }

    /// Turns the eye about the target: `d_yaw_rad` about +Y, `d_pitch_rad` up/down (clamped).
    pub fn orbit(&mut self, d_yaw_rad: f32, d_pitch_rad: f32) {
        if d_yaw_rad.is_finite() {
            self.yaw_rad = (self.yaw_rad + d_yaw_rad).rem_euclid(std::f32::consts::TAU);
        }
        if d_pitch_rad.is_finite() {
            self.pitch_rad =
                (self.pitch_rad + d_pitch_rad).clamp(-Self::MAX_PITCH_RAD, Self::MAX_PITCH_RAD);
        }
    }

    /// Slides the target (and eye) in the view plane. `dx`, `dy` are in units of the visible
    /// half-height at the target's depth, so a drag of the full viewport height is `dy = 2`;
    /// +x moves the scene content right on screen, +y up.
    pub fn pan(&mut self, dx: f32, dy: f32) {
        if !(dx.is_finite() && dy.is_finite()) {
            return;
        }
        let (right, up) = self.right_up();
        let half_height = self.distance * (self.fov_y_rad * 0.5).tan();
        // Moving the camera left makes the content move right.
        self.target -= (right * dx + up * dy) * half_height;
    }

    /// Multiplies the distance by `factor` (< 1 moves closer), clamped to the allowed range.
    pub fn zoom(&mut self, factor: f32) {
        if factor.is_finite() && factor > 0.0 {
            self.distance = (self.distance * factor).clamp(Self::MIN_DISTANCE, Self::MAX_DISTANCE);
        }
    }

    /// Rotates the eye about the target by `rotation` (a world-space rotation, for example from
    /// [`crate::render::Trackball`]); the new yaw and pitch are read back from the eye direction,
    /// so any roll in `rotation` is dropped.
    pub fn rotate(&mut self, rotation: Quat) {
        if !rotation.is_finite() {
            return;
        }
        let dir = (rotation * self.eye_direction()).normalize_or(self.eye_direction());
        self.pitch_rad = dir
            .y
            .clamp(-1.0, 1.0)
            .asin()
            .clamp(-Self::MAX_PITCH_RAD, Self::MAX_PITCH_RAD);
        if dir.x.abs() > 1.0e-6 || dir.z.abs() > 1.0e-6 {
            self.yaw_rad = dir.x.atan2(dir.z).rem_euclid(std::f32::consts::TAU);
        }
    }
}

/// Fixed viewpoints for offscreen renders (`--view front`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum NamedView {
    Front,
    Back,
    Left,
    Right,
    Top,
    Bottom,
    /// Isometric: 45° around, 35.26° up (the eye along (1, 1, 1)).
    Iso,
}

impl NamedView {
    /// Every view, in the order the CLI lists them.
    pub const ALL: [NamedView; 7] = [
        Self::Front,
        Self::Back,
        Self::Left,
        Self::Right,
        Self::Top,
        Self::Bottom,
        Self::Iso,
    ];

    /// The view's lowercase name, as parsed by `from_str`.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Front => "front",
            Self::Back => "back",
            Self::Left => "left",
            Self::Right => "right",
            Self::Top => "top",
            Self::Bottom => "bottom",
            Self::Iso => "iso",
        }
    }

    /// (yaw, pitch) in radians; the poles are clamped by [`Camera::named`].
    #[must_use]
    pub fn angles(self) -> (f32, f32) {
        use std::f32::consts::{FRAC_PI_2, FRAC_PI_4, PI};
        match self {
            Self::Front => (0.0, 0.0),
            Self::Back => (PI, 0.0),
            Self::Left => (-FRAC_PI_2, 0.0),
            Self::Right => (FRAC_PI_2, 0.0),
            Self::Top => (0.0, FRAC_PI_2),
            Self::Bottom => (0.0, -FRAC_PI_2),
            Self::Iso => (FRAC_PI_4, (1.0f32 / 3.0f32.sqrt()).asin()),
        }
    }
}

/// An unknown view name.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("unknown view {0:?}: expected one of {names}", names = NamedView::ALL.map(NamedView::name).join(", "))]
pub struct UnknownView(pub String);

impl FromStr for NamedView {
    type Err = UnknownView;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let lower = s.trim().to_ascii_lowercase();
        Self::ALL
            .into_iter()
            .find(|v| v.name() == lower)
            .ok_or_else(|| UnknownView(s.to_owned()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: Vec3, b: Vec3) -> bool {
        (a - b).length() < 1.0e-4
    }

    #[test]
    fn front_view_looks_down_minus_z_and_projects_target_to_centre() {
        let cam = Camera::named(NamedView::Front, Vec3::splat(-1.0), Vec3::splat(1.0));
        assert!(close(cam.eye_direction(), Vec3::Z));
        let clip = cam.view_projection(1.5) * cam.target.extend(1.0);
        let ndc = clip.truncate() / clip.w;
        assert!(ndc.x.abs() < 1e-5 && ndc.y.abs() < 1e-5);
        assert!(ndc.z > 0.0 && ndc.z < 1.0);
    }

    #[test]
    fn named_views_frame_the_whole_box() {
        let (lo, hi) = (Vec3::new(-2.0, 0.0, 1.0), Vec3::new(1.0, 3.0, 2.0));
        for view in NamedView::ALL {
            let cam = Camera::named(view, lo, hi);
            let vp = cam.view_projection(1.0);
            for i in 0..8 {
                let corner = Vec3::new(
                    if i & 1 == 0 { lo.x } else { hi.x },
                    if i & 2 == 0 { lo.y } else { hi.y },
                    if i & 4 == 0 { lo.z } else { hi.z },
                );
                let clip = vp * corner.extend(1.0);
                let ndc = clip.truncate() / clip.w;
                assert!(
                    ndc.x.abs() <= 1.0 && ndc.y.abs() <= 1.0,
                    "{view:?} cuts {corner}"
                );
                assert!(
                    (0.0..=1.0).contains(&ndc.z),
                    "{view:?} clips {corner} in depth"
                );
            }
        }
    }

    #[test]
    fn iso_eye_lies_on_the_diagonal_and_names_round_trip() {
        let cam = Camera::named(NamedView::Iso, Vec3::splat(-1.0), Vec3::splat(1.0));
        assert!(close(cam.eye_direction(), Vec3::ONE.normalize()));
        for view in NamedView::ALL {
            assert_eq!(view.name().parse::<NamedView>(), Ok(view));
        }
        assert_eq!("ISO".parse::<NamedView>(), Ok(NamedView::Iso));
        let err = "sideways".parse::<NamedView>().unwrap_err();
        assert!(err.to_string().contains("front, back"));
    }

    #[test]
    fn orbit_clamps_pitch_and_zoom_clamps_distance() {
        let mut cam = Camera::default();
        cam.orbit(0.0, 10.0);
        assert_eq!(cam.pitch_rad, Camera::MAX_PITCH_RAD);
        assert!(cam.view().is_finite());
        cam.orbit(f32::NAN, f32::INFINITY);
        assert_eq!(cam.pitch_rad, Camera::MAX_PITCH_RAD);
        let d = cam.distance;
        cam.zoom(0.5);
        assert!((cam.distance - d * 0.5).abs() < 1e-6);
        cam.zoom(0.0);
        cam.zoom(1.0e-30);
        assert_eq!(cam.distance, Camera::MIN_DISTANCE);
    }

    #[test]
    fn pan_moves_content_with_the_cursor() {
        let mut cam = Camera::named(NamedView::Front, Vec3::splat(-1.0), Vec3::splat(1.0));
        let point = Vec3::ZERO;
        let before = cam.view_projection(1.0).project_point3(point);
        cam.pan(0.5, -0.25);
        let after = cam.view_projection(1.0).project_point3(point);
        // A pan of 0.5 half-heights moves a point at the target's depth 0.5 in NDC.
        assert!(
            (after.x - before.x - 0.5).abs() < 1e-4,
            "{before} -> {after}"
        );
        assert!(
            (after.y - before.y + 0.25).abs() < 1e-4,
            "{before} -> {after}"
        );
    }

    #[test]
    fn rotate_by_a_yaw_quaternion_matches_orbit() {
        let mut a = Camera::named(NamedView::Front, Vec3::splat(-1.0), Vec3::splat(1.0));
        let mut b = a;
        a.orbit(0.3, 0.0);
        b.rotate(Quat::from_rotation_y(0.3));
        assert!((a.yaw_rad - b.yaw_rad).abs() < 1e-5);
        assert!(close(a.eye(), b.eye()));
    }
}
