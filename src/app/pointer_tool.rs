//! The mouse or pen as the sculpting tool: turns the pointer over the view into the tool tip
//! that the pointer device hands to the haptic loop.
//!
//! Work per frame is one pick (bounded, see [`crate::field::pick_surface`]) and one wait-free
//! hand-over ([`PointerHandle::set`]). While a stroke is held the pick is made on the clay as
//! it was when the stroke began, so a drag carves a groove of the set depth instead of digging
//! deeper every frame as the clay gives way.
//!
//! The press depth is signed: below zero the pressing tip is held that far *above* the
//! surface, and the point grab pulls the clay out toward it ([`raising_choice`]), so a mouse
//! raises clay as well as pressing it in. A pulling stroke's first frame puts the tip on the
//! surface, where the tool takes hold, and the following frames lift it.

use glam::{Vec2, Vec3};

use dynaclay_devices::pointer::PointerHandle;

use crate::engine::WorkspaceMap;
use crate::field::{MultiPatchField, Ray, pick_surface};
use crate::render::Camera;

/// Depth step per scroll point with the depth modifier held, as a fraction of the depth range.
const DEPTH_PER_SCROLL_POINT: f32 = 0.002;
/// Deepest the tip goes below the surface (and, for a negative depth, highest above it),
/// knot spans.
pub const MAX_DEPTH_SPANS: f32 = 4.0;

/// Where the tool is this frame, field coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TipPose {
    /// The point of the clay under the pointer (on the view ray at the last depth when off
    /// the clay).
    pub surface: Vec3,
    /// The clay's outward normal there (toward the eye when off the clay).
    pub normal: Vec3,
    /// The tool tip handed to the device.
    pub tip: Vec3,
    /// Whether the ray met the clay.
    pub on_clay: bool,
    /// Whether the tip presses (a stroke is held).
    pub pressed: bool,
}

/// The pointer as a tool.
#[derive(Default)]
pub struct PointerTool {
    handle: Option<PointerHandle>,
    /// Field → device map of the engine the handle feeds.
    map: Option<WorkspaceMap>,
    /// How far below the surface a pressing tip goes, knot spans; negative: how far above it
    /// a pulling tip is held.
    pub depth_spans: f32,
    /// The clay as it was when the held stroke began.
    stroke_field: Option<MultiPatchField>,
    /// Distance along the view ray of the last hit, to hover off the clay.
    last_distance: Option<f32>,
    /// This frame's tip.
    pub pose: Option<TipPose>,
}

impl PointerTool {
    /// A tool feeding `handle`, whose engine maps field to device with `map`.
    #[must_use]
    pub fn new(handle: PointerHandle, map: WorkspaceMap) -> Self {
        Self {
            handle: Some(handle),
            map: Some(map),
            depth_spans: 1.5,
            ..Self::default()
        }
    }

    /// Follows an engine restarted on another clay, mapped by `map`.
    pub fn set_map(&mut self, map: WorkspaceMap) {
        if self.handle.is_some() {
            self.map = Some(map);
        }
    }

    /// Whether a pointer device is connected to this tool.
    #[must_use]
    pub fn is_connected(&self) -> bool {
        self.handle.is_some()
    }

    /// The last sample handed to the device, for tests and the status line.
    #[must_use]
    pub fn last_sample(&self) -> Option<dynaclay_devices::pointer::PointerSample> {
        self.handle.as_ref().map(PointerHandle::last)
    }

    /// Changes the press depth for a scroll of `scroll_points` (up: deeper; through zero to
    /// a pull above the surface).
    pub fn scroll_depth(&mut self, scroll_points: f32) {
        if scroll_points.is_finite() {
            self.depth_spans = (self.depth_spans
                + scroll_points * DEPTH_PER_SCROLL_POINT * MAX_DEPTH_SPANS)
                .clamp(-MAX_DEPTH_SPANS, MAX_DEPTH_SPANS);
        }
    }

    /// Aims the tool along the view ray under `pointer_ndc` and hands the tip to the device.
    /// `pressing` holds a stroke; `pressure` (0..1, a pen's) scales the depth, 1 for a mouse.
    /// A negative depth holds the pressing tip above the surface (on it in the stroke's first
    /// frame, so the tool takes hold there).
    pub fn aim(
        &mut self,
        field: &MultiPatchField,
        camera: &Camera,
        pointer_ndc: Vec2,
        aspect: f32,
        pressing: bool,
        pressure: f32,
    ) -> TipPose {
        let first_pressed = pressing && self.stroke_field.is_none();
        if first_pressed {
            self.stroke_field = Some(field.clone());
        } else if !pressing {
            self.stroke_field = None;
        }
        let picked_on = self.stroke_field.as_ref().unwrap_or(field);
        let (origin, direction) = camera.ray_through(pointer_ndc, aspect);
        let hover = 0.5 * field.finest_spacing();
        let pose = match pick_surface(picked_on, Ray { origin, direction }) {
            Some(hit) => {
                self.last_distance = Some(hit.distance);
                let mut depth =
                    self.depth_spans * field.finest_spacing() * pressure.clamp(0.0, 1.0);
                if first_pressed && depth < 0.0 {
                    depth = 0.0;
                }
                let tip = if pressing {
                    hit.point - hit.normal * depth
                } else {
                    hit.point + hit.normal * hover
                };
                TipPose {
                    surface: hit.point,
                    normal: hit.normal,
                    tip,
                    on_clay: true,
                    pressed: pressing,
                }
            }
            None => {
                let distance = self.last_distance.unwrap_or(camera.distance);
                let at = origin + direction * distance;
                TipPose {
                    surface: at,
                    normal: -direction,
                    tip: at,
                    on_clay: false,
                    pressed: pressing,
                }
            }
        };
        if let (Some(handle), Some(map)) = (self.handle.as_mut(), self.map.as_ref()) {
            handle.set(map.to_device(pose.tip), pressing);
        }
        self.pose = Some(pose);
        pose
    }

    /// Lifts the tool (the pointer left the view or the drag ended elsewhere): the tip stays
    /// where it was and stops pressing.
    pub fn release(&mut self) {
        self.stroke_field = None;
        if let Some(pose) = self.pose.as_mut() {
            pose.pressed = false;
        }
        if let Some(handle) = self.handle.as_mut() {
            let last = handle.last();
            if last.pressed {
                handle.set(last.position_m, false);
            }
        }
    }
}

/// The tool a stroke uses at a press depth below zero (`raising`): the point grab's contact
/// push cannot reach a tip above the surface, so it becomes the pull (the same spread and
/// gain) that draws the clay out toward the tip; every other tool is unchanged (the area and
/// force tools already pull toward a tip above the surface, and the chisel and squirt keep
/// their own depth).
#[must_use]
pub fn raising_choice(
    choice: crate::engine::ToolChoice,
    raising: bool,
) -> crate::engine::ToolChoice {
    match choice {
        crate::engine::ToolChoice::Push(push) if raising => crate::tools::ForceTool::Pull {
            distribution: push.distribution,
            radius_fu: push.radius_fu,
            gain: push.gain,
        }
        .into(),
        other => other,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::NamedView;
    use dynaclay_devices::pointer::{PointerConfig, pointer_device};

    fn ball() -> MultiPatchField {
        MultiPatchField::new(
            crate::field::lattice_from_primitive(
                [17, 17, 17],
                0.2,
                Vec3::ZERO,
                &crate::field::Primitive::Sphere {
                    centre: Vec3::splat(1.6),
                    radius: 1.0,
                },
                0.4,
                2,
            )
            .unwrap(),
        )
    }

    #[test]
    fn the_tip_hovers_above_presses_below_and_keeps_its_depth_off_the_clay() {
        let field = ball();
        let config = PointerConfig::default();
        let (_device, handle) = pointer_device(config);
        let map = WorkspaceMap::fitting(
            config.workspace_min_m,
            config.workspace_max_m,
            Vec3::ZERO,
            Vec3::splat(3.2),
            30.0,
        );
        let mut tool = PointerTool::new(handle, map);
        let camera = Camera::named(NamedView::Front, Vec3::splat(0.6), Vec3::splat(2.6));
        let centre = Vec2::ZERO;
        let hover = tool.aim(&field, &camera, centre, 1.0, false, 1.0);
        assert!(hover.on_clay && !hover.pressed);
        assert!(
            field.value(hover.tip) < field.iso(),
            "hovers outside the clay"
        );
        let press = tool.aim(&field, &camera, centre, 1.0, true, 1.0);
        assert!(
            field.value(press.tip) > field.iso(),
            "presses into the clay"
        );
        let depth = (press.surface - press.tip).length();
        assert!((depth - 1.5 * 0.2).abs() < 1e-4, "depth {depth}");
        let sent = tool.last_sample().unwrap();
        assert!(sent.pressed);
        assert!((sent.position_m - map.to_device(press.tip)).length() < 1e-6);
        // A pen's half pressure goes half as deep.
        let light = tool.aim(&field, &camera, centre, 1.0, true, 0.5);
        assert!(((light.surface - light.tip).length() - 0.15).abs() < 1e-4);
        // Off the clay: on the ray at the last hit's distance, not pressing into anything.
        let off = tool.aim(&field, &camera, Vec2::new(0.95, 0.95), 1.0, false, 1.0);
        assert!(!off.on_clay);
        assert!(field.value(off.tip) < field.iso());
        tool.release();
        assert!(!tool.last_sample().unwrap().pressed);
        tool.scroll_depth(1.0e6);
        assert_eq!(tool.depth_spans, MAX_DEPTH_SPANS);
        tool.scroll_depth(f32::NAN);
        assert_eq!(tool.depth_spans, MAX_DEPTH_SPANS);
        tool.scroll_depth(-1.0e6);
        assert_eq!(tool.depth_spans, -MAX_DEPTH_SPANS);
    }

    #[test]
    fn a_negative_depth_holds_the_pressing_tip_above_the_surface_after_the_first_frame() {
        let field = ball();
        let config = PointerConfig::default();
        let (_device, handle) = pointer_device(config);
        let map = WorkspaceMap::fitting(
            config.workspace_min_m,
            config.workspace_max_m,
            Vec3::ZERO,
            Vec3::splat(3.2),
            30.0,
        );
        let mut tool = PointerTool::new(handle, map);
        tool.depth_spans = -1.5;
        let camera = Camera::named(NamedView::Front, Vec3::splat(0.6), Vec3::splat(2.6));
        let first = tool.aim(&field, &camera, Vec2::ZERO, 1.0, true, 1.0);
        assert!(
            (first.tip - first.surface).length() < 1e-6,
            "first frame on the surface"
        );
        let lifted = tool.aim(&field, &camera, Vec2::ZERO, 1.0, true, 1.0);
        let height = (lifted.tip - lifted.surface).dot(lifted.normal);
        assert!(
            (height - 0.3).abs() < 1e-4,
            "held 1.5 spans above: {height}"
        );
        assert!(field.value(lifted.tip) < field.iso());
        // The point grab pulls out at a negative depth; other tools stay.
        let push = crate::engine::ToolChoice::default();
        assert!(matches!(
            raising_choice(push.clone(), true),
            crate::engine::ToolChoice::Force {
                tool: crate::tools::ForceTool::Pull { .. },
                ..
            }
        ));
        assert_eq!(raising_choice(push.clone(), false), push);
    }
}
