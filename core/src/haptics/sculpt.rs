//! The sculpting reaction (Hua & Qin §7.2.2): what the hand feels while a force tool acts.
//!
//! Guarantee: [`SculptReaction::compute`] allocates nothing (its buffer is made once), takes
//! no lock and does bounded work: the tool's force vectors (plain arithmetic, plus at most
//! [`FELT_TARGETS`] bounded crossing searches for a chisel or squirt), then at most
//! [`MAX_FELT_VECTORS`] re-found starts and Gauss–Legendre integrals.
//!
//! The haptic loop integrates eq. (6) on its own copy of the field — the newest patch the
//! simulation published, at most a step old — along the same force vectors the simulation
//! applies ([`crate::tools::ForceTool::forces`] with the stroke's anchor, then
//! [`start_on_surface`]). The felt force is the sum over the vectors of the equal and opposite
//! of the sculpting force, summed with weights: `Σ wᵢ |fᵢ| (x0ᵢ − x1ᵢ)/lᵢ / max(1, Σ wᵢ)`, with
//! `wᵢ` a vector's share of the tool's gain (an area tool's β profile). The division keeps a
//! many-vector tool as stiff as a point grab: the plain sum over an area tool's fifty tracks
//! is fifty times stiffer than one vector, far past what an arm renders stably (it buzzed on
//! the recorded sessions of `tests/haptic_quality.rs`). Every start is a surface point, so
//! the force falls smoothly to zero as the surface reaches the cursor. Tools with more vectors
//! than [`MAX_FELT_VECTORS`] (a wide area tool) are felt through an evenly strided subset; a
//! chisel or squirt is felt through its last [`FELT_TARGETS`] targets, the ones near the tool
//! (earlier ones have reached their depth).
//!
//! A chisel's or squirt's targets arrive one at a time as the tip moves on, each with its whole
//! depth still to cut. Felt at once, each would step the force by its share of the depth (on a
//! narrow chisel, a fresh target steps a nearly finished cut's force from 0.002 N to 0.036 N in
//! one tick: the sawtooth of `tests/haptic_quality.rs`'s narrow chisel). So each target's
//! weight `wᵢ` ramps from 0 to 1 over the ramp time from the tick the haptic loop first sees it,
//! and the target it pushes out of the felt set ramps from 1 to 0 over the same ticks: the
//! felt force moves continuously as targets come and go.

use glam::Vec3;

use crate::dynamics::{
    Distribution, ToolForce, reaction_force, start_on_surface, start_on_surface_near_target,
};
use crate::field::MultiPatchField;
use crate::tools::{ForceInput, ForceTool, PenetrationTarget};

/// Most force vectors a tool may produce for the haptic loop (as many as the simulation
/// applies per step).
pub const MAX_TOOL_VECTORS: usize = 256;
/// Most force vectors integrated per tick.
pub const MAX_FELT_VECTORS: usize = 32;
/// Chisel and squirt targets felt (the newest).
pub const FELT_TARGETS: usize = 8;
/// Most curve points and chisel targets a stroke carries to the haptic loop.
pub const MAX_STROKE_POINTS: usize = 256;
/// Targets whose arrival times the reaction keeps: the felt ones and as many being let go.
const TARGET_ARRIVALS: usize = 2 * FELT_TARGETS;

/// What the haptic loop must know of the held tool (plain data).
// The haptic tick copies the held tool out of each field update: inline, a copy allocates
// nothing (a boxed shell would allocate on the haptic thread).
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FeltTool {
    /// A geometric tool. With its shell, a device that renders force feels the clay against
    /// the tool's whole shape, between strokes and while the tool acts, and the tool acts
    /// where it rests as the hand presses ([`super::ShapeProxy`]); without one (or on a device
    /// without force) the clay is touched at the tip between strokes and a stroke acts at the
    /// tip.
    Geometric(Option<super::ToolShell>),
    /// The contact push: the force vector runs from the touch proxy to the tip.
    Push,
    /// A force tool of the dynamics.
    Force(ForceTool),
}

impl Default for FeltTool {
    fn default() -> Self {
        Self::Geometric(None)
    }
}

/// The held stroke as the simulation fixed it: the anchor where a force tool took hold, the
/// bend pivot, the user curve and the chisel targets. Fixed capacity: copying one into
/// another never allocates.
#[derive(Clone, Debug, PartialEq)]
pub struct StrokeGeometry {
    /// Where the stroke took hold of the clay (`None`: not yet, or out of reach).
    pub anchor: Option<Vec3>,
    /// Pivot of a bend, field coordinates.
    pub pivot: Vec3,
    /// The user curve of a curve tool, field coordinates (at most [`MAX_STROKE_POINTS`]).
    pub curve: Vec<Vec3>,
    /// The chisel or squirt targets planned so far (at most [`MAX_STROKE_POINTS`]).
    pub targets: Vec<PenetrationTarget>,
    /// The clay's outward normal where the stroke took hold (zero when unknown).
    pub normal: Vec3,
}

impl Default for StrokeGeometry {
    fn default() -> Self {
        Self {
            anchor: None,
            pivot: Vec3::ZERO,
            curve: Vec::with_capacity(MAX_STROKE_POINTS),
            targets: Vec::with_capacity(MAX_STROKE_POINTS),
            normal: Vec3::ZERO,
        }
    }
}

impl StrokeGeometry {
    /// Copies `other` in without allocating (a longer curve or target list is cut at
    /// [`MAX_STROKE_POINTS`]; the newest targets are kept).
    pub fn copy_from(&mut self, other: &StrokeGeometry) {
        self.anchor = other.anchor;
        self.pivot = other.pivot;
        self.normal = other.normal;
        self.curve.clear();
        let n = other.curve.len().min(self.curve.capacity());
        self.curve.extend_from_slice(&other.curve[..n]);
        self.targets.clear();
        let n = other.targets.len().min(self.targets.capacity());
        self.targets
            .extend_from_slice(&other.targets[other.targets.len() - n..]);
    }

    /// Sets the parts from the simulation's stroke state (may allocate: simulation thread).
    pub fn set(
        &mut self,
        anchor: Option<Vec3>,
        pivot: Vec3,
        curve: &[Vec3],
        targets: &[PenetrationTarget],
    ) {
        self.anchor = anchor;
        self.pivot = pivot;
        self.curve.clear();
        self.curve
            .extend_from_slice(&curve[..curve.len().min(MAX_STROKE_POINTS)]);
        self.targets.clear();
        self.targets
            .extend_from_slice(&targets[targets.len().saturating_sub(MAX_STROKE_POINTS)..]);
    }

    /// No stroke.
    pub fn clear(&mut self) {
        self.anchor = None;
        self.normal = Vec3::ZERO;
        self.curve.clear();
        self.targets.clear();
    }
}

/// The per-tick result of a force tool.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SculptForce {
    /// The felt reaction, field units (density × length).
    pub reaction: Vec3,
    /// The first felt vector (for display and the tool sample), if any.
    pub first: Option<(Vec3, Vec3)>,
    /// Vectors the tool produced this tick.
    pub vectors: usize,
}

/// Scratch for the force tools' vectors, allocated once, and the arrival of the held stroke's
/// chisel or squirt targets (module docs).
#[derive(Clone, Debug)]
pub struct SculptReaction {
    vectors: Vec<ToolForce>,
    /// Device time at which the haptic loop first saw each of the stroke's newest targets,
    /// microseconds, at the target's index in the stroke modulo [`TARGET_ARRIVALS`].
    target_seen_at_us: [u64; TARGET_ARRIVALS],
    /// How many of the held stroke's targets the haptic loop has seen.
    targets_seen: usize,
}

impl Default for SculptReaction {
    fn default() -> Self {
        let idle = ToolForce {
            start: Vec3::ZERO,
            end: Vec3::ZERO,
            distribution: Distribution::Constant,
            radius: 0.0,
            gain: 0.0,
        };
        Self {
            vectors: vec![idle; MAX_TOOL_VECTORS],
            target_seen_at_us: [0; TARGET_ARRIVALS],
            targets_seen: 0,
        }
    }
}

impl SculptReaction {
    /// The felt reaction of `tool` held at `cursor` for the stroke `stroke` on `field`, at
    /// device time `time_us`; zero until the stroke has an anchor. A chisel's or squirt's
    /// targets ramp in and out over `target_ramp_s` (module docs).
    pub fn compute(
        &mut self,
        tool: &ForceTool,
        field: &MultiPatchField,
        cursor: Vec3,
        stroke: &StrokeGeometry,
        (time_us, target_ramp_s): (u64, f32),
    ) -> SculptForce {
        let none = SculptForce {
            reaction: Vec3::ZERO,
            first: None,
            vectors: 0,
        };
        self.note_targets(&stroke.targets, time_us);
        let Some(anchor) = stroke.anchor else {
            return none;
        };
        if !cursor.is_finite() {
            return none;
        }
        let penetration = matches!(tool, ForceTool::Chisel { .. } | ForceTool::Squirt { .. });
        let planned = stroke.targets.len();
        let seen_at_us = self.target_seen_at_us;
        let weight = |index: usize| {
            if penetration {
                target_weight(&seen_at_us, index, planned, time_us, target_ramp_s)
            } else {
                1.0
            }
        };
        // The newest targets, and before them those still being let go.
        let mut first_felt = planned.saturating_sub(FELT_TARGETS);
        while first_felt > 0
            && planned - first_felt < TARGET_ARRIVALS
            && weight(first_felt - 1) > 0.0
        {
            first_felt -= 1;
        }
        let targets = &stroke.targets[first_felt..];
        let input = ForceInput {
            grab: anchor,
            cursor,
            pivot: stroke.pivot,
            path: &stroke.curve,
            targets,
            normal: stroke.normal,
        };
        let n = tool.forces(field, &input, &mut self.vectors);
        if n == 0 {
            return none;
        }
        let stride = n.div_ceil(MAX_FELT_VECTORS);
        let tool_gain = tool.gain();
        let mut reaction = Vec3::ZERO;
        let mut first = None;
        let mut shares = 0.0_f32;
        for (index, v) in self.vectors[..n].iter().enumerate().step_by(stride) {
            // A chisel's or squirt's vectors are its targets', in order.
            let arrival = weight(first_felt + index);
            if arrival <= 0.0 {
                continue;
            }
            let start = if penetration {
                start_on_surface_near_target(field, v.start, v.end)
            } else {
                start_on_surface(field, v.start, v.end)
            };
            if first.is_none() {
                first = Some((start, v.end));
            }
            let share = arrival
                * if tool_gain > 0.0 {
                    v.gain / tool_gain
                } else {
                    1.0
                };
            reaction += reaction_force(field, start, v.end) * share;
            // Strided: each felt vector stands for `stride` of them.
            shares += share * stride as f32;
        }
        reaction *= stride as f32 / shares.max(1.0);
        SculptForce {
            reaction: if reaction.is_finite() {
                reaction
            } else {
                Vec3::ZERO
            },
            first,
            vectors: n,
        }
    }

    /// Notes the device time at which each target of the held stroke not seen before arrived
    /// (a shorter list than seen is a new stroke).
    fn note_targets(&mut self, targets: &[PenetrationTarget], time_us: u64) {
        if targets.len() < self.targets_seen {
            self.targets_seen = 0;
        }
        let newest = targets.len().saturating_sub(TARGET_ARRIVALS);
        for index in self.targets_seen.max(newest)..targets.len() {
            self.target_seen_at_us[index % TARGET_ARRIVALS] = time_us;
        }
        self.targets_seen = targets.len();
    }

    /// Forgets the held stroke's targets (the stroke ended).
    pub fn end_stroke(&mut self) {
        self.targets_seen = 0;
    }
}

/// The weight of target `index` of the `planned` ones at `time_us`, the targets having been
/// first seen at `seen_at_us` (by index modulo [`TARGET_ARRIVALS`]): how far it has ramped in
/// over `ramp_s`, times how far the target [`FELT_TARGETS`] after it (which pushes it out of
/// the felt set) has not.
fn target_weight(
    seen_at_us: &[u64; TARGET_ARRIVALS],
    index: usize,
    planned: usize,
    time_us: u64,
    ramp_s: f32,
) -> f32 {
    let ramped_in = |i: usize| {
        if i >= planned {
            0.0
        } else if planned - i > TARGET_ARRIVALS || ramp_s <= 0.0 {
            1.0
        } else {
            let age_s = time_us.saturating_sub(seen_at_us[i % TARGET_ARRIVALS]) as f32 * 1e-6;
            (age_s / ramp_s).min(1.0)
        }
    };
    ramped_in(index) * (1.0 - ramped_in(index + FELT_TARGETS))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::{Primitive, lattice_from_primitive};

    fn ball() -> MultiPatchField {
        let s = Primitive::Sphere {
            centre: Vec3::splat(0.95),
            radius: 0.4,
        };
        MultiPatchField::new(lattice_from_primitive([20; 3], 0.1, Vec3::ZERO, &s, 0.2, 2).unwrap())
    }

    fn stroke_at(anchor: Vec3) -> StrokeGeometry {
        let mut s = StrokeGeometry::default();
        s.set(Some(anchor), Vec3::ZERO, &[], &[]);
        s
    }

    #[test]
    fn a_pull_is_felt_toward_the_surface_and_vanishes_when_the_surface_reaches_the_cursor() {
        let field = ball();
        let mut r = SculptReaction::default();
        let anchor = Vec3::new(1.3, 0.95, 0.95);
        let tool = ForceTool::PointGrab { gain: 1.0 };
        let mut last = 0.0;
        for out in [0.05, 0.1, 0.2] {
            let cursor = Vec3::new(1.35 + out, 0.95, 0.95);
            let f = r.compute(&tool, &field, cursor, &stroke_at(anchor), (0, 0.0));
            assert!(
                f.reaction.x < 0.0,
                "pulled back toward the clay: {}",
                f.reaction
            );
            assert!(f.reaction.x.abs() > last, "grows with the pull");
            last = f.reaction.x.abs();
            let (start, _) = f.first.unwrap();
            assert!(
                (start.x - 1.35).abs() < 0.02,
                "start re-found on the surface: {start}"
            );
        }
        // A cursor on the surface feels nothing.
        let f = r.compute(
            &tool,
            &field,
            Vec3::new(1.351, 0.95, 0.95),
            &stroke_at(anchor),
            (0, 0.0),
        );
        assert!(f.reaction.length() < 1e-3 * last, "{}", f.reaction);
        // No anchor, no force.
        let f = r.compute(
            &tool,
            &field,
            Vec3::splat(2.0),
            &StrokeGeometry::default(),
            (0, 0.0),
        );
        assert_eq!(f.reaction, Vec3::ZERO);
    }

    #[test]
    fn a_wide_area_tool_is_felt_as_the_weighted_mean_over_its_tracks() {
        let field = ball();
        let mut r = SculptReaction::default();
        let anchor = Vec3::new(1.3, 0.95, 0.95);
        let cursor = Vec3::new(1.45, 0.95, 0.95);
        let area = |tracks| ForceTool::Area {
            distribution: Distribution::Constant,
            radius_fu: 0.05,
            tracks,
            gain: 1.0,
        };
        let one = r.compute(&area(1), &field, cursor, &stroke_at(anchor), (0, 0.0));
        let many = r.compute(&area(12), &field, cursor, &stroke_at(anchor), (0, 0.0));
        assert!(many.vectors > MAX_FELT_VECTORS);
        assert!(one.reaction.x < 0.0 && many.reaction.x < 0.0);
        // About the single track (the disc is nearly flat over 5 cm), not a hundred times it.
        let ratio = many.reaction.x / one.reaction.x;
        assert!((0.6..1.2).contains(&ratio), "ratio {ratio}");
    }

    /// A chisel stroke on the ball's top with `count` targets along x, 0.03 deep.
    fn chisel_stroke(count: usize) -> StrokeGeometry {
        let top = Vec3::new(0.95, 1.35, 0.95);
        let targets: Vec<PenetrationTarget> = (0..count)
            .map(|i| PenetrationTarget {
                target: top + Vec3::new(0.01 * i as f32 - 0.05, -0.03, 0.0),
                normal: Vec3::Y,
                depth_fu: 0.03,
            })
            .collect();
        let mut s = StrokeGeometry::default();
        s.set(Some(top), Vec3::ZERO, &[], &targets);
        s
    }

    #[test]
    fn a_chisel_target_ramps_in_and_the_one_it_pushes_out_ramps_out() {
        let field = ball();
        let tool = ForceTool::Chisel {
            depth_fu: 0.03,
            radius_fu: 0.02,
            gain: 1.0,
        };
        let cursor = Vec3::new(0.95, 1.34, 0.95);
        let ramp_s = 0.02;
        let at = |r: &mut SculptReaction, stroke: &StrokeGeometry, time_us: u64, ramp_s: f32| {
            r.compute(&tool, &field, cursor, stroke, (time_us, ramp_s))
                .reaction
        };
        // The first target: nothing on the tick it arrives, a quarter 5 ms on, all of it after
        // the ramp (as without one).
        let mut r = SculptReaction::default();
        let one = chisel_stroke(1);
        let full = at(&mut SculptReaction::default(), &one, 0, 0.0);
        assert!(full.y > 0.0, "the cut pushes the hand back up: {full}");
        assert_eq!(at(&mut r, &one, 1_000_000, ramp_s), Vec3::ZERO);
        let quarter = at(&mut r, &one, 1_005_000, ramp_s);
        assert!(
            (quarter - 0.25 * full).length() < 1e-4 * full.length(),
            "{quarter} {full}"
        );
        assert_eq!(at(&mut r, &one, 1_020_000, ramp_s), full);
        // Eight targets felt, then a ninth: the force does not step when it arrives, and once
        // it has ramped in the force is the newest eight's.
        let mut r = SculptReaction::default();
        let eight = chisel_stroke(FELT_TARGETS);
        let nine = chisel_stroke(FELT_TARGETS + 1);
        assert_eq!(at(&mut r, &eight, 2_000_000, ramp_s), Vec3::ZERO);
        let settled = at(&mut r, &eight, 2_030_000, ramp_s);
        assert_eq!(settled, at(&mut SculptReaction::default(), &eight, 0, 0.0));
        let arriving = at(&mut r, &nine, 2_031_000, ramp_s);
        assert!(
            (arriving - settled).length() < 1e-4 * settled.length(),
            "{arriving} against {settled}"
        );
        let newest = at(&mut SculptReaction::default(), &nine, 0, 0.0);
        assert_ne!(newest, settled, "the ninth target changes the felt force");
        let midway = at(&mut r, &nine, 2_041_000, ramp_s);
        assert!(
            (midway - 0.5 * (settled + newest)).length() < 1e-3 * settled.length(),
            "{midway} halfway between {settled} and {newest}"
        );
        assert_eq!(at(&mut r, &nine, 2_051_000, ramp_s), newest);
        // A new stroke (a shorter list) ramps its targets in afresh.
        assert_eq!(at(&mut r, &one, 3_000_000, ramp_s), Vec3::ZERO);
    }
}
