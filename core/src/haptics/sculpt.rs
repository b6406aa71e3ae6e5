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

use glam::Vec3;

use crate::dynamics::{Distribution, ToolForce, reaction_force, start_on_surface};
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

/// Scratch for the force tools' vectors, allocated once.
#[derive(Clone, Debug)]
pub struct SculptReaction {
    vectors: Vec<ToolForce>,
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
        }
    }
}

impl SculptReaction {
    /// The felt reaction of `tool` held at `cursor` for the stroke `stroke` on `field`; zero
    /// until the stroke has an anchor.
    pub fn compute(
        &mut self,
        tool: &ForceTool,
        field: &MultiPatchField,
        cursor: Vec3,
        stroke: &StrokeGeometry,
    ) -> SculptForce {
        let none = SculptForce {
            reaction: Vec3::ZERO,
            first: None,
            vectors: 0,
        };
        let Some(anchor) = stroke.anchor else {
            return none;
        };
        if !cursor.is_finite() {
            return none;
        }
        let targets = &stroke.targets[stroke.targets.len().saturating_sub(FELT_TARGETS)..];
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
        for v in self.vectors[..n].iter().step_by(stride) {
            let start = start_on_surface(field, v.start, v.end);
            if first.is_none() {
                first = Some((start, v.end));
            }
            let share = if tool_gain > 0.0 {
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
            let f = r.compute(&tool, &field, cursor, &stroke_at(anchor));
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
        );
        assert!(f.reaction.length() < 1e-3 * last, "{}", f.reaction);
        // No anchor, no force.
        let f = r.compute(&tool, &field, Vec3::splat(2.0), &StrokeGeometry::default());
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
        let one = r.compute(&area(1), &field, cursor, &stroke_at(anchor));
        let many = r.compute(&area(12), &field, cursor, &stroke_at(anchor));
        assert!(many.vectors > MAX_FELT_VECTORS);
        assert!(one.reaction.x < 0.0 && many.reaction.x < 0.0);
        // About the single track (the disc is nearly flat over 5 cm), not a hundred times it.
        let ratio = many.reaction.x / one.reaction.x;
        assert!((0.6..1.2).contains(&ratio), "ratio {ratio}");
    }
}
