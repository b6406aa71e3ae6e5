//! The mouse (or pen) as the sculpting tool: picks the clay under the pointer and places the
//! pointer device's tip there, on the window's thread.
//!
//! Guarantee: each call does bounded work — one [`pick_surface`] (bounded marching) and one
//! wait-free [`PointerFeed::set`] — and never waits for a loop. A stroke copies the field once,
//! when it begins (so the tip's depth is measured from the clay as it was, and a held button
//! does not dig on and on as the dent deepens under it).
//!
//! Where the tip goes:
//! - hovering over the clay: [`PointerTool::HOVER_GAP`] above the surface under the pointer;
//! - during a stroke: `depth` below the surface under the pointer (the surface as it was when
//!   the stroke began), on the surface normal;
//! - off the clay: along the pointer's ray, as far as the clay last was, so it is in the air.

use dynaclay_devices::{PointerFeed, PointerPose};
use glam::Vec3;

use crate::engine::WorkspaceMap;
use crate::field::{BSplineLattice, RayHit, pick_surface};

/// What a pointer ray is: an origin and a unit direction, world units.
pub type Ray = (Vec3, Vec3);

/// The pointer tool's state.
#[derive(Debug)]
pub struct PointerTool {
    feed: PointerFeed,
    map: WorkspaceMap,
    /// How deep a stroke presses under the surface, field units.
    pub depth: f32,
    /// The clay as it was when the held stroke began.
    stroke_field: Option<BSplineLattice>,
    /// Distance along the ray of the last hit (where the tip goes off the clay).
    last_distance: Option<f32>,
    /// The last tip placed, field units, and the surface hit under it (for the cursor).
    last_tip: Option<Vec3>,
    last_hit: Option<RayHit>,
}

impl PointerTool {
    /// How far above the surface a hovering tip stays, field units.
    pub const HOVER_GAP: f32 = 0.02;
    /// Default stroke depth, field units (half a knot span of the default clay).
    pub const DEFAULT_DEPTH: f32 = 0.05;
    /// Shallowest and deepest stroke, field units.
    pub const DEPTH_RANGE: std::ops::RangeInclusive<f32> = 0.005..=0.5;

    /// A tool feeding `feed`, mapping field coordinates to device metres with `map`.
    #[must_use]
    pub fn new(feed: PointerFeed, map: WorkspaceMap) -> Self {
        Self {
            feed,
            map,
            depth: Self::DEFAULT_DEPTH,
            stroke_field: None,
            last_distance: None,
            last_tip: None,
            last_hit: None,
        }
    }

    /// Whether a stroke is held.
    #[must_use]
    pub fn is_stroking(&self) -> bool {
        self.stroke_field.is_some()
    }

    /// The last tip placed, field units.
    #[must_use]
    pub fn tip(&self) -> Option<Vec3> {
        self.last_tip
    }

    /// The surface under the pointer at the last call, if any.
    #[must_use]
    pub fn hit(&self) -> Option<RayHit> {
        self.last_hit
    }

    /// Scales the stroke depth by `factor`, within [`PointerTool::DEPTH_RANGE`].
    pub fn scale_depth(&mut self, factor: f32) {
        if factor.is_finite() && factor > 0.0 {
            self.depth =
                (self.depth * factor).clamp(*Self::DEPTH_RANGE.start(), *Self::DEPTH_RANGE.end());
        }
    }

    /// The pointer moved over the view with no stroke: the tip hovers above the surface
    /// under it (button up). Returns the hit.
    pub fn hover(&mut self, ray: Ray, field: &BSplineLattice) -> Option<RayHit> {
        let hit = pick_surface(field, ray.0, ray.1);
        let tip = self.place(ray, hit, Self::HOVER_GAP);
        self.send(tip, false);
        hit
    }

    /// Starts a stroke if the pointer is over the clay (then returns true and the tip goes
    /// `depth` under the surface, button down); off the clay nothing starts.
    pub fn begin_stroke(&mut self, ray: Ray, field: &BSplineLattice) -> bool {
        let Some(hit) = pick_surface(field, ray.0, ray.1) else {
            return false;
        };
        self.stroke_field = Some(field.clone());
        let tip = self.place(ray, Some(hit), -self.depth);
        self.send(tip, true);
        true
    }

    /// Moves the held stroke's tip under the pointer.
    pub fn drag(&mut self, ray: Ray) {
        let Some(field) = self.stroke_field.as_ref() else {
            return;
        };
        let hit = pick_surface(field, ray.0, ray.1);
        let tip = self.place(ray, hit, -self.depth);
        self.send(tip, true);
    }

    /// Ends the stroke where it is (button up; the tip stays until the pointer moves).
    pub fn end_stroke(&mut self) {
        self.stroke_field = None;
        if let Some(tip) = self.last_tip {
            self.send(Some(tip), false);
        }
    }

    /// The tip for `hit` on `ray`, `offset` along the surface normal (negative: into the
    /// clay); off the clay, on the ray as far as the clay last was.
    fn place(&mut self, ray: Ray, hit: Option<RayHit>, offset: f32) -> Option<Vec3> {
        self.last_hit = hit;
        match hit {
            Some(h) => {
                self.last_distance = Some(h.distance);
                let normal = if h.normal == Vec3::ZERO {
                    -ray.1
                } else {
                    h.normal
                };
                Some(h.point + normal * offset)
            }
            None => self.last_distance.map(|d| ray.0 + ray.1 * d),
        }
    }

    fn send(&mut self, tip: Option<Vec3>, held: bool) {
        let Some(tip) = tip.filter(|t| t.is_finite()) else {
            return;
        };
        self.last_tip = Some(tip);
        self.feed.set(PointerPose {
            position_m: self.map.to_device(tip),
            buttons: u32::from(held),
        });
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

    fn map() -> WorkspaceMap {
        WorkspaceMap::fitting(
            Vec3::splat(-0.1),
            Vec3::splat(0.1),
            Vec3::ZERO,
            Vec3::splat(2.6),
            1.0,
        )
    }

    fn down_at(x: f32) -> Ray {
        (Vec3::new(x, 2.5, 1.3), -Vec3::Y)
    }

    #[test]
    fn hover_stroke_and_release_place_the_tip_and_the_button() {
        let field = slab();
        let feed = PointerFeed::new();
        let mut tool = PointerTool::new(feed.clone(), map());
        let hit = tool.hover(down_at(1.3), &field).expect("over the clay");
        assert!((hit.point.y - 1.0).abs() < 0.01);
        let (pose, _) = feed.get().unwrap();
        assert_eq!(pose.buttons, 0);
        let tip = map().to_field(pose.position_m);
        assert!((tip.y - (hit.point.y + PointerTool::HOVER_GAP)).abs() < 1e-4);

        assert!(tool.begin_stroke(down_at(1.3), &field));
        let (pose, _) = feed.get().unwrap();
        assert_eq!(pose.buttons, 1);
        let tip = map().to_field(pose.position_m);
        assert!((tip.y - (hit.point.y - tool.depth)).abs() < 1e-4, "{tip}");

        // Dragging follows the pointer at the same depth under the stroke's starting clay.
        tool.drag(down_at(1.6));
        let tip = map().to_field(feed.get().unwrap().0.position_m);
        assert!(
            (tip.x - 1.6).abs() < 1e-3 && (tip.y - (hit.point.y - tool.depth)).abs() < 1e-3,
            "{tip}"
        );
        tool.end_stroke();
        assert_eq!(feed.get().unwrap().0.buttons, 0);
        assert!(!tool.is_stroking());
    }

    #[test]
    fn off_the_clay_no_stroke_starts_and_the_tip_stays_in_the_air() {
        let field = slab();
        let feed = PointerFeed::new();
        let mut tool = PointerTool::new(feed.clone(), map());
        tool.hover(down_at(1.3), &field);
        // A ray that misses (looking up, away from the clay).
        let up = (Vec3::new(1.3, 2.5, 1.3), Vec3::Y);
        assert!(tool.hover(up, &field).is_none());
        assert!(!tool.begin_stroke(up, &field));
        let tip = map().to_field(feed.get().unwrap().0.position_m);
        assert!(!field.is_inside(tip), "in the air: {tip}");
        assert_eq!(feed.get().unwrap().0.buttons, 0);
    }

    #[test]
    fn the_depth_stays_within_its_range() {
        let mut tool = PointerTool::new(PointerFeed::new(), map());
        tool.scale_depth(1e6);
        assert_eq!(tool.depth, *PointerTool::DEPTH_RANGE.end());
        tool.scale_depth(1e-9);
        assert_eq!(tool.depth, *PointerTool::DEPTH_RANGE.start());
        tool.scale_depth(f32::NAN);
        assert_eq!(tool.depth, *PointerTool::DEPTH_RANGE.start());
    }
}
