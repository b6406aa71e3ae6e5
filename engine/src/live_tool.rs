//! The held tool during a live stroke, on the simulation thread: turns each tool sample into
//! this step's force vectors (push and force tools) or decides when a geometric tool is
//! applied along the tip's path and for how long a dwell.
//!
//! Where a stroke must land is kept as targets, each the end of a force vector that the
//! simulation drives the surface to and holds it at (see `Simulator::gather_forces`): a
//! chisel's or squirt's targets, planned along the tip's path on the clay as it was when the
//! stroke began (so the stroke's own spread ahead of the tip does not deepen the next one);
//! the push's path (and a grab's or pull's pressed into the clay), the deepest tip position
//! over each place, so the groove rests where the tip went. When the button is released the
//! stroke's targets (or the cursor where it was released) act for [`SETTLE_STEPS`] more steps
//! ([`PLANNED_SETTLE_STEPS`] for a chisel's or squirt's).
//!
//! Not real-time, but steady: the force buffer is allocated once, so a step with a force tool
//! allocates only when a chisel or squirt stroke starts (a copy of the clay to plan on) or
//! plans a new penetration target. Every decision depends on the tool samples (device time,
//! tip, buttons), never on wall time, so a lockstep run is reproducible bit for bit.

use glam::Vec3;

use super::command::{PushTool, ToolChoice};
use super::tool_sample::ToolSample;
use dynaclay_core::dynamics::{
    ToolBody, ToolForce, start_on_surface, start_on_surface_near_target,
};
use dynaclay_core::field::MultiPatchField;
use dynaclay_core::haptics::{FeltTool, MAX_STROKE_POINTS, StrokeGeometry, ToolShell};
use dynaclay_core::tools::{
    ForceInput, ForceTool, MAX_SEGMENT_APPLICATIONS, PenetrationTarget, anchor_normal, hold_weight,
    lerp, nearest_solid_point, plan_penetration_along, steps_along,
};

/// Most force vectors one step applies (an area tool's tracks, a curve's samples).
pub const MAX_FORCES: usize = dynaclay_core::haptics::MAX_TOOL_VECTORS;

/// Most penetration targets one chisel or squirt stroke plans.
pub const MAX_TARGETS: usize = MAX_STROKE_POINTS;

/// How fast a firmly pressed resting tool sinks into the clay, in its own smallest half
/// extents per second (a sphere of radius 0.25 sinks 0.25 field units a second): slow enough
/// that the hand follows the cut and feels it, fast enough that a firm press carves at once.
pub const FIRM_SINK_SIZES_PER_S: f32 = 1.0;

/// The tool and its per-stroke state.
#[derive(Debug)]
pub struct LiveTool {
    choice: ToolChoice,
    /// The held tool as the haptic loop renders it (a geometric tool's shell is built once).
    felt: FeltTool,
    /// Force vectors of the current step (first `len` valid).
    forces: Vec<ToolForce>,
    len: usize,
    /// Where a force stroke grabbed the clay.
    grab: Option<Vec3>,
    /// The clay's outward normal where the stroke took hold (zero before).
    normal: Vec3,
    /// Whether the stroke's tip has been pressed well into the clay (a grab or pull then
    /// keeps its path as targets, as the push does).
    pressing: bool,
    /// Chisel and squirt targets planned so far in this stroke.
    targets: Vec<PenetrationTarget>,
    /// The clay as it was when a chisel or squirt stroke began: its targets are planned on
    /// it, so the stroke's own spread ahead of the tip does not deepen the next target.
    plan_field: Option<MultiPatchField>,
    last_planned: Option<Vec3>,
    /// Device time and point of the last geometric application in this stroke.
    last_apply: Option<(u64, Vec3)>,
    /// The tip at the last step of the held stroke.
    last_tip: Vec3,
    /// Steps the released stroke's targets still act (see [`SETTLE_STEPS`]).
    settle_left: u32,
    /// Where the push's stroke entered the clay: its force vector's start when it first
    /// touched.
    mouth: Option<Vec3>,
    /// This step's tool bodies: the push's shaft ([`push_body`]) or the chisel's shafts over
    /// its targets ([`chisel_body`]); at most [`MAX_FORCES`], allocated once.
    bodies: Vec<ToolBody>,
}

fn felt_tool_of(choice: &ToolChoice) -> FeltTool {
    match choice {
        ToolChoice::Push(_) => FeltTool::Push,
        ToolChoice::Force { tool, .. } => FeltTool::Force(*tool),
        ToolChoice::Geometric(tool) => FeltTool::Geometric(ToolShell::of(&tool.shape)),
    }
}

/// A held geometric tool's applications due this step: `count` points evenly spaced along the
/// segment from the previous application (`from`, not applied again) to the tip (`to`, the
/// last point), each for `dwell_s` seconds (the dwell since the previous application, split
/// evenly), so that the stroke's groove or bead is continuous.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GeometricDue {
    /// The previous application's point (the tip, on a stroke's first application).
    pub from: Vec3,
    /// The acting point (the tip, or the resting tool pressed toward it).
    pub to: Vec3,
    /// Applications along the segment, 1 to [`MAX_SEGMENT_APPLICATIONS`].
    pub count: u32,
    /// Dwell of each application, seconds (the device time, scaled by how hard the hand
    /// presses the resting tool).
    pub dwell_s: f32,
    /// The tool's orientation.
    pub rotation: glam::Quat,
}

impl GeometricDue {
    /// The `i`-th point (`0..count`), the last at the tip.
    #[must_use]
    pub fn point(&self, i: u32) -> Vec3 {
        lerp(
            self.from,
            self.to,
            (i + 1) as f32 / self.count.max(1) as f32,
        )
    }
}

/// Steps a released stroke keeps acting — the push's path targets, a force tool held at the
/// cursor where it was released — so the clay comes to rest at them rather than wherever the
/// stroke's end left it moving (the targets the tip passed last have had the least time).
/// Each force vanishes as the surface reaches its target, so a target already reached adds
/// nothing. Short: the hand has let go, and elastic clay should spring back soon after.
pub const SETTLE_STEPS: u32 = 400;

/// Steps a released chisel or squirt stroke keeps acting: its targets are where its control
/// says the clay goes, whatever the hand does, so the last ones get as long as the middle
/// ones had (at 400 steps a chisel's last stretch came out 11% short).
pub const PLANNED_SETTLE_STEPS: u32 = 800;

impl LiveTool {
    /// Holds `choice`, no stroke in progress.
    #[must_use]
    pub fn new(choice: ToolChoice) -> Self {
        let idle = ToolForce {
            start: Vec3::ZERO,
            end: Vec3::ZERO,
            distribution: dynaclay_core::dynamics::Distribution::Constant,
            radius: 0.0,
            gain: 0.0,
        };
        Self {
            felt: felt_tool_of(&choice),
            choice,
            forces: vec![idle; MAX_FORCES],
            len: 0,
            grab: None,
            normal: Vec3::ZERO,
            pressing: false,
            targets: Vec::with_capacity(MAX_TARGETS),
            plan_field: None,
            last_planned: None,
            last_apply: None,
            last_tip: Vec3::ZERO,
            settle_left: 0,
            mouth: None,
            bodies: Vec::with_capacity(MAX_FORCES),
        }
    }

    /// The tool held.
    #[must_use]
    pub fn choice(&self) -> &ToolChoice {
        &self.choice
    }

    /// Replaces the tool (and forgets the stroke state).
    pub fn set(&mut self, choice: ToolChoice) {
        self.felt = felt_tool_of(&choice);
        self.choice = choice;
        self.end_stroke();
    }

    /// The held tool as the haptic loop renders it.
    #[must_use]
    pub fn felt_tool(&self) -> FeltTool {
        self.felt
    }

    /// Writes the stroke's anchor, pivot, curve and targets into `out`, for the haptic loop
    /// (no anchor while no force tool holds the clay).
    pub fn stroke_geometry(&self, out: &mut StrokeGeometry) {
        match &self.choice {
            ToolChoice::Force { curve, pivot, .. } => {
                out.set(self.grab, *pivot, curve, &self.targets);
                out.normal = self.normal;
            }
            _ => out.clear(),
        }
    }

    /// The stroke's button was released: a push with path targets, or a force tool that took
    /// hold, keeps acting for [`SETTLE_STEPS`] more steps (toward where it was released; a
    /// chisel or squirt for [`PLANNED_SETTLE_STEPS`]); any other stroke ends now.
    pub fn release(&mut self) {
        let settle_steps = match &self.choice {
            ToolChoice::Push(_) if !self.targets.is_empty() => SETTLE_STEPS,
            ToolChoice::Force { tool, .. } if self.grab.is_some() => match tool {
                ForceTool::Chisel { .. } | ForceTool::Squirt { .. } => PLANNED_SETTLE_STEPS,
                _ => SETTLE_STEPS,
            },
            _ => 0,
        };
        if settle_steps > 0 {
            self.settle_left = settle_steps;
        } else {
            self.end_stroke();
        }
    }

    /// Forgets the stroke's grab point, targets and timing.
    pub fn end_stroke(&mut self) {
        self.settle_left = 0;
        self.grab = None;
        self.normal = Vec3::ZERO;
        self.pressing = false;
        self.targets.clear();
        self.last_planned = None;
        self.last_apply = None;
        self.len = 0;
        self.mouth = None;
        self.bodies.clear();
    }

    /// Where the held force stroke took hold of the clay (`None` before it has, and for the
    /// push and geometric tools).
    #[must_use]
    pub fn grab_point(&self) -> Option<Vec3> {
        self.grab
    }

    /// This step's force vectors, as computed by [`LiveTool::update_forces`].
    #[must_use]
    pub fn forces(&self) -> &[ToolForce] {
        &self.forces[..self.len]
    }

    /// This step's tool bodies (the push's shaft in the clay, see [`push_body`]; the
    /// chisel's over a cut a skin of clay has closed, see [`chisel_body`]).
    #[must_use]
    pub fn bodies(&self) -> &[ToolBody] {
        &self.bodies
    }

    /// The bounding box of this step's force vectors grown by their spread radii, if any.
    #[must_use]
    pub fn force_bounds(&self) -> Option<(Vec3, Vec3)> {
        self.forces().iter().fold(None, |acc, f| {
            let r = Vec3::splat(f.radius);
            let (lo, hi) = (f.start.min(f.end) - r, f.start.max(f.end) + r);
            Some(match acc {
                Some((a, b)) => (a.min(lo), b.max(hi)),
                None => (lo, hi),
            })
        })
    }

    /// Computes this step's force vectors from `sample` on the simulation's `field`;
    /// `mass_step` is the mass-point pitch (the grab snaps to it). A geometric tool, a released
    /// stroke or a push out of contact gives none.
    pub fn update_forces(&mut self, sample: &ToolSample, field: &MultiPatchField, mass_step: f32) {
        self.len = 0;
        self.bodies.clear();
        let settling = !sample.stroke_active && self.settle_left > 0;
        if settling {
            self.settle_left -= 1;
            if self.settle_left == 0 {
                self.end_stroke();
                return;
            }
        }
        match &self.choice {
            ToolChoice::Push(push) => {
                let push_on = sample.in_contact
                    && sample.force_from_fu.is_finite()
                    && sample.force_to_fu.is_finite()
                    && sample.force_from_fu != sample.force_to_fu;
                if push_on {
                    self.forces[0] = push_force(push, sample, mass_step);
                    self.len = 1;
                    let mouth = *self.mouth.get_or_insert(sample.force_from_fu);
                    self.bodies
                        .extend(push_body(&self.forces[0], mouth, mass_step));
                    let axis = (sample.force_from_fu - sample.force_to_fu).normalize_or_zero();
                    note_push_target(
                        &mut self.targets,
                        &mut self.last_planned,
                        (sample.force_to_fu, axis),
                        mass_step,
                    );
                }
                if sample.stroke_active || settling {
                    self.len += push_path_forces(
                        push.gain,
                        &self.targets,
                        field,
                        &mut self.forces[self.len..],
                    );
                }
            }
            ToolChoice::Force { tool, curve, pivot } => {
                let tip = if settling {
                    // The released stroke's targets only: the tip stays where it was
                    // released, so nothing new is planned.
                    Some(self.last_tip)
                } else {
                    (sample.stroke_active && sample.tip_fu.is_finite()).then_some(sample.tip_fu)
                };
                if let Some(tip) = tip {
                    self.last_tip = tip;
                    self.len = force_tool_step(
                        (*tool, curve, *pivot),
                        tip,
                        field,
                        mass_step,
                        (&mut self.grab, &mut self.normal, &mut self.pressing),
                        (&mut self.targets, &mut self.plan_field),
                        &mut self.last_planned,
                        (&mut self.forces, &mut self.bodies),
                    );
                }
            }
            ToolChoice::Geometric(_) => {}
        }
    }

    /// For a geometric tool during a held stroke: whether to apply it this step, where and
    /// with which dwell. Without tool-shaped contact the tool acts at the tip. With it, the
    /// tool acts ahead of where it rests (`resting_at`): the cut's lead toward the tip grows by
    /// the press times [`FIRM_SINK_SIZES_PER_S`] of the tool's size per second of dwell, up to
    /// the tip and a stroke spacing, and the dwell is scaled by the press; nothing acts while
    /// it only rests on the clay (press 0). Applications are at least `interval_us` of device time apart (a
    /// local refit costs milliseconds); each covers the path from the previous one to the tip
    /// with points at most the shape's [`stroke_spacing_fu`] apart (a quarter of its radius;
    /// at most [`MAX_SEGMENT_APPLICATIONS`] of them, wider for a faster tip), splitting the
    /// dwell, which is the device time since the previous application (capped at
    /// `4 · interval_us`; `interval_us` for the stroke's first, at the tip alone).
    ///
    /// [`stroke_spacing_fu`]: dynaclay_core::tools::ToolShape::stroke_spacing_fu
    pub fn geometric_due(&mut self, sample: &ToolSample, interval_us: u64) -> Option<GeometricDue> {
        let ToolChoice::Geometric(tool) = &self.choice else {
            return None;
        };
        if !sample.stroke_active || !sample.tip_fu.is_finite() {
            return None;
        }
        let press = if sample.press.is_finite() {
            sample.press.clamp(0.0, 1.0)
        } else {
            0.0
        };
        if press <= 0.0 {
            // The tool rests on the clay or touches nothing: nothing acts, and the next press
            // starts a new run of applications where it is (not a line from where the last one
            // ended).
            self.last_apply = None;
            return None;
        }
        let now = sample.device_time_us;
        let dwell_us = match self.last_apply {
            None => interval_us,
            Some((t, _)) if now >= t.saturating_add(interval_us) => (now - t).min(4 * interval_us),
            Some(_) => return None,
        };
        let at = match sample.resting_at {
            // A resting tool's cut runs ahead of it toward the tip, faster the harder the hand
            // presses: the lead grows by the sink of this dwell, up to the tip and at most a
            // stroke spacing ahead of where the tool rests (a refit carries small changes over
            // a few applications, so the lead, not each application, sets the pace).
            Some(rest) if rest.is_finite() => {
                let toward = sample.tip_fu - rest;
                let reach = toward.length();
                let dir = toward.normalize_or_zero();
                let lead = self
                    .last_apply
                    .map_or(0.0, |(_, last)| (last - rest).dot(dir).max(0.0));
                let sink_fu = press
                    * FIRM_SINK_SIZES_PER_S
                    * tool.shape.half_extents().min_element()
                    * dwell_us as f32
                    / 1e6;
                let lead = (lead + sink_fu)
                    .min(reach)
                    .min(tool.shape.stroke_spacing_fu());
                rest + dir * lead
            }
            _ => sample.tip_fu,
        };
        let from = match self.last_apply {
            Some((_, last)) => last,
            None => at,
        };
        let count = steps_along(
            from.distance(at),
            tool.shape.stroke_spacing_fu(),
            MAX_SEGMENT_APPLICATIONS,
        );
        self.last_apply = Some((now, at));
        Some(GeometricDue {
            from,
            to: at,
            count,
            dwell_s: press * dwell_us as f32 / 1e6 / count as f32,
            rotation: sample.rotation,
        })
    }
}

/// The narrowest spread of the push, mass steps of the patch it moves (a knot span and a
/// half at two mass points per span): a narrower spread holds too few mass points for the
/// spline to follow, and the surface stalls short of the tip.
const MIN_PUSH_SPREAD_MASS_STEPS: f32 = 3.0;

/// The push's live force vector, spread over at least [`MIN_PUSH_SPREAD_MASS_STEPS`].
fn push_force(push: &PushTool, sample: &ToolSample, mass_step: f32) -> ToolForce {
    ToolForce {
        start: sample.force_from_fu,
        end: sample.force_to_fu,
        distribution: push.distribution,
        radius: push.radius_fu.max(MIN_PUSH_SPREAD_MASS_STEPS * mass_step),
        gain: push.gain,
    }
}

/// The push's body: its shaft from a mass step above the start of its force vector (the
/// surface above the tip; the clay just above it is the vector's own, whose start the
/// simulation finds again on the clay as it moves) out along the vector's axis to the plane
/// through `mouth` (where the stroke entered the clay) square to the axis, as wide as the
/// force's spread; `None` while that shaft is shorter than a mass step. See [`ToolBody`] for
/// what it does.
fn push_body(force: &ToolForce, mouth: Vec3, mass_step: f32) -> Option<ToolBody> {
    let axis = (force.start - force.end).normalize_or_zero();
    let depth = (mouth - force.end).dot(axis);
    let outer = force.end + axis * depth;
    let inner = force.start + axis * mass_step;
    let shaft = (outer - inner).dot(axis);
    (axis != Vec3::ZERO && shaft.is_finite() && shaft > mass_step).then_some(ToolBody {
        inner,
        outer,
        distribution: force.distribution,
        radius: force.radius,
    })
}

/// The chisel's body over one target whose cut a skin of clay has closed: the shaft from the
/// cut's roof (the crossing nearest the target toward `outermost`, the outermost surface
/// crossing on the target's line: the skin's underside) out to a mass step past `outermost`
/// (the skin's top), as wide as the force's spread; `None` while the cut is open (both
/// crossings the same) or the segment under the roof still holds clay (the cut is still on
/// its way down). The force vector of a target under a skin ends in the hole it has cut, so
/// its line integral cannot reach the skin: the clay's springs close a cut narrow against its
/// depth over the target, as they close a narrow push's hole (see [`ToolBody`]). A real
/// chisel is solid along its whole depth and keeps the cut open.
fn chisel_body(
    field: &MultiPatchField,
    force: &ToolForce,
    outermost: Vec3,
    mass_step: f32,
) -> Option<ToolBody> {
    let roof = start_on_surface(field, outermost, force.end);
    let axis = (roof - force.end).normalize_or_zero();
    let skin = (outermost - roof).dot(axis);
    let closed_over = axis != Vec3::ZERO
        && skin.is_finite()
        && skin > 0.25 * mass_step
        && !field.is_inside(0.5 * (roof + force.end));
    closed_over.then_some(ToolBody {
        inner: roof,
        outer: outermost + axis * mass_step,
        distribution: force.distribution,
        radius: force.radius,
    })
}

/// Notes the pressing tip (the push's, or a grab's or pull's cursor pressed into the clay) as a
/// target of the stroke's path along the outward `axis` when it has moved a mass step since
/// the last one (each target spreads over a knot span, two mass steps: the targets overlap,
/// and half as many as at every half step cost the simulation half as much).
fn note_push_target(
    targets: &mut Vec<PenetrationTarget>,
    last_planned: &mut Option<Vec3>,
    (tip, axis): (Vec3, Vec3),
    mass_step: f32,
) {
    let moved = last_planned.is_none_or(|p| p.distance(tip) >= 0.5 * mass_step);
    if axis == Vec3::ZERO || !moved {
        return;
    }
    *last_planned = Some(tip);
    // The groove is the union of where the tip went: over one place (within a quarter mass
    // step across the axis) only the deepest tip position is a target, so a shallower one
    // never fills the groove back up to itself.
    let same_place = |t: &PenetrationTarget| {
        let d = t.target - tip;
        (d - axis * d.dot(axis)).length() < 0.25 * mass_step
    };
    if targets
        .iter()
        .any(|t| same_place(t) && (t.target - tip).dot(axis) <= 0.0)
    {
        return;
    }
    targets.retain(|t| !same_place(t));
    if targets.len() < MAX_TARGETS {
        targets.push(PenetrationTarget {
            target: tip,
            normal: axis,
            depth_fu: 0.0,
        });
    }
}

/// The pressing path's targets: for each tip position of the held stroke, a force vector from
/// the surface above it (along the push's axis there) down to it, spread over one knot span.
/// The live vector carves with the push's full spread where the tip is; these finish and hold
/// the groove's bottom at the tip's path behind it (each vanishes as the surface reaches its
/// target and reverses if the surface passes it), so the groove rests where the tip went.
/// Writes at most `out.len()` vectors and returns how many.
fn push_path_forces(
    gain: f32,
    targets: &[PenetrationTarget],
    field: &MultiPatchField,
    out: &mut [ToolForce],
) -> usize {
    let spacing = field.finest_spacing();
    let reach = PUSH_PATH_REACH_SPANS * spacing;
    let mut n = 0;
    for t in targets {
        if n == out.len() {
            break;
        }
        // A target the surface rests on (within a fiftieth of a knot span) adds nothing this
        // step: one evaluation instead of a search and an integral. The clay springing back
        // off it brings it back.
        let (value, gradient) = field.value_and_gradient(t.target);
        if (value - field.iso()).abs() < REACHED_SPANS * spacing * gradient.length() {
            continue;
        }
        let above = t.target + t.normal * reach;
        let start = start_on_surface(field, above, t.target);
        if start == above && field.is_inside(t.target) {
            // No surface within reach above the target: the live spread has not brought the
            // groove near it yet, or something holds the clay there (a pin over the tip's
            // path). It waits; a target pressed against a pin would only stir the clay
            // around the pin and hold back the groove beyond it.
            continue;
        }
        out[n] = ToolForce {
            start,
            end: t.target,
            distribution: dynaclay_core::dynamics::Distribution::Gaussian,
            radius: spacing,
            gain,
        };
        n += 1;
    }
    n
}

/// How close the surface must be to a push path target for the target to rest this step,
/// knot spans (the simulation's own bound fades a column's share over a fiftieth of a span).
const REACHED_SPANS: f32 = 0.02;

/// How far above a push path target its vector looks for the surface, knot spans: the target
/// finishes and holds the last stretch of the groove that the live spread leaves (it leaves
/// the groove within a span or so of the tip's path), not the whole depth.
const PUSH_PATH_REACH_SPANS: f32 = 2.0;

/// One step of a force tool: sets the grab point (first tick in reach of the solid), plans
/// chisel and squirt targets along the tip's path, and writes the tool's force vectors, each
/// starting on the surface as it is now ([`start_on_surface`], the rule the haptic loop feels
/// by), so the surface can follow the cursor all the way.
#[allow(clippy::too_many_arguments)] // the stroke state is split so the buffers borrow apart
fn force_tool_step(
    (tool, curve, pivot): (ForceTool, &[Vec3], Vec3),
    tip: Vec3,
    field: &MultiPatchField,
    mass_step: f32,
    (grab, normal, pressing): (&mut Option<Vec3>, &mut Vec3, &mut bool),
    (targets, plan_field): (&mut Vec<PenetrationTarget>, &mut Option<MultiPatchField>),
    last_planned: &mut Option<Vec3>,
    (out, bodies): (&mut [ToolForce], &mut Vec<ToolBody>),
) -> usize {
    let penetration = match tool {
        ForceTool::Chisel { depth_fu, .. } => Some((depth_fu, false)),
        ForceTool::Squirt { depth_fu, .. } => Some((depth_fu, true)),
        _ => None,
    };
    if grab.is_none() {
        if penetration.is_some() {
            // The clay at the stroke's start, kept for planning (reusing the last copy's
            // memory when the shape matches).
            match plan_field {
                Some(copy) => copy.clone_from(field),
                None => *plan_field = Some(field.clone()),
            }
        }
        *grab = match tool {
            // These move with the cursor's displacement from where the stroke began.
            ForceTool::Curve { .. } | ForceTool::Chisel { .. } | ForceTool::Squirt { .. } => {
                Some(tip)
            }
            // These hold the nearest mass point of the solid within two knot spans.
            _ => nearest_solid_point(field, tip, 2.0 * field.finest_spacing(), mass_step),
        };
        if let Some(g) = *grab {
            *normal = anchor_normal(field, g);
        }
    }
    let Some(grab) = *grab else {
        return 0;
    };
    // A stroke presses once its tip has been well inside the clay (as the window's pointer
    // presses it, a knot span and a half), never while it stays at the surface (where a pull
    // starts) or is drawn out.
    *pressing |= hold_weight(field, tip) >= 1.0;
    if let Some((depth_fu, squirt)) = penetration {
        let moved = last_planned.is_none_or(|p| p.distance(tip) >= 0.5 * mass_step);
        if moved && targets.len() < MAX_TARGETS {
            let planned_on = plan_field.as_ref().unwrap_or(field);
            targets.extend(plan_penetration_along(
                planned_on,
                &[tip],
                depth_fu,
                squirt,
                *normal,
            ));
            *last_planned = Some(tip);
        }
    }
    let input = ForceInput {
        grab,
        cursor: tip,
        pivot,
        path: curve,
        targets,
        normal: *normal,
    };
    let mut n = tool.forces(field, &input, out);
    let chisel = matches!(tool, ForceTool::Chisel { .. });
    for f in &mut out[..n] {
        let outermost = f.start;
        f.start = if penetration.is_some() {
            start_on_surface_near_target(field, f.start, f.end)
        } else {
            start_on_surface(field, f.start, f.end)
        };
        if chisel && bodies.len() < bodies.capacity() {
            bodies.extend(chisel_body(field, f, outermost, mass_step));
        }
    }
    // A grab or pull pressed into the clay pushes the surface down to the cursor (see
    // `ForceTool::forces`): like the push, a stroke that took hold pressed in keeps its path
    // as targets, so the groove rests where the cursor went. (A pull from the surface keeps
    // none: a cursor it has drawn the clay out past is braked, not a place to hold.)
    if matches!(tool, ForceTool::PointGrab { .. } | ForceTool::Pull { .. })
        && *normal != Vec3::ZERO
        && *pressing
    {
        if field.is_inside(tip) {
            note_push_target(targets, last_planned, (tip, *normal), mass_step);
        }
        n += push_path_forces(tool.gain(), targets, field, &mut out[n..]);
    }
    n
}

#[cfg(test)]
mod tests {
    use super::*;
    use dynaclay_core::field::BSplineLattice;
    use dynaclay_core::field::{Primitive, lattice_from_primitive};
    use dynaclay_core::tools::{GeometricTool, ToolAction, ToolShape};

    fn ball() -> BSplineLattice {
        let s = Primitive::Sphere {
            centre: Vec3::splat(0.95),
            radius: 0.5,
        };
        lattice_from_primitive([20; 3], 0.1, Vec3::ZERO, &s, 0.2, 2).unwrap()
    }

    fn sample(tip: Vec3, active: bool, time_us: u64) -> ToolSample {
        ToolSample {
            tip_fu: tip,
            force_from_fu: tip,
            force_to_fu: tip,
            stroke_active: active,
            device_time_us: time_us,
            ..ToolSample::IDLE
        }
    }

    /// The ball with a hole under its top: the coefficients around its vertical axis from
    /// y = 0.8 to 1.1 emptied, so a skin of clay stands over a void.
    fn ball_with_a_hole_under_its_top() -> MultiPatchField {
        let mut lattice = ball();
        let [nx, ny, nz] = lattice.dims;
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    let p = lattice.node_position(i, j, k);
                    let near_axis = (p.x - 0.95).abs() <= 0.15 && (p.z - 0.95).abs() <= 0.15;
                    if near_axis && (0.75..=1.15).contains(&p.y) {
                        let n = lattice.index(i, j, k);
                        lattice.coeffs.set_flat(n, 0.0);
                    }
                }
            }
        }
        MultiPatchField::new(lattice)
    }

    #[test]
    fn a_chisel_body_stands_only_over_a_cut_a_skin_has_closed() {
        let field = ball_with_a_hole_under_its_top();
        let on_axis = |y: f32| Vec3::new(0.95, y, 0.95);
        // The scene: clay over the hole, the hole, clay under it.
        assert!(field.is_inside(on_axis(1.35)), "the skin");
        assert!(!field.is_inside(on_axis(0.95)), "the hole");
        assert!(field.is_inside(on_axis(0.55)), "the clay under the hole");
        let mass_step = 0.05;
        let above = on_axis(1.7);
        // The ball's top: the crossing on the way down from above the ball into the skin.
        let top = start_on_surface(&field, above, on_axis(1.4));
        assert!((top.y - 1.45).abs() < 0.05, "top {top}");
        let force = |start: Vec3, end: Vec3| ToolForce {
            start,
            end,
            distribution: dynaclay_core::dynamics::Distribution::Gaussian,
            radius: 0.05,
            gain: 1.0,
        };

        // A target in the hole: its vector starts again under the skin (the hole's ceiling),
        // and the body stands from there out past the skin's top.
        let target = on_axis(0.9);
        let ceiling = start_on_surface(&field, top, target);
        assert!(ceiling.y < top.y - 0.1, "ceiling {ceiling}");
        let body = chisel_body(&field, &force(ceiling, target), top, mass_step)
            .expect("a body over the skin");
        assert_eq!(body.inner, ceiling);
        assert!((body.outer - (top + Vec3::Y * mass_step)).length() < 1e-5);
        assert_eq!(body.radius, 0.05);

        // An open cut: the vector starts at the outermost crossing, no body.
        let open_target = on_axis(1.3);
        assert!(chisel_body(&field, &force(top, open_target), top, mass_step).is_none());

        // A target under the hole's floor: the vector starts on the floor and runs through
        // clay; the cut is still on its way down there, no body.
        let deep = on_axis(0.6);
        let floor = start_on_surface(&field, top, deep);
        assert!(floor.y < 0.9 && floor.y > 0.6, "floor {floor}");
        assert!(chisel_body(&field, &force(floor, deep), top, mass_step).is_none());
    }

    #[test]
    fn a_grab_holds_the_nearest_solid_point_and_pulls_toward_the_cursor() {
        let lattice = ball();
        let mut live = LiveTool::new(ToolChoice::from(ForceTool::PointGrab { gain: 1.0 }));
        // Out of reach: nothing grabbed, no force.
        live.update_forces(
            &sample(Vec3::splat(0.1), true, 0),
            &MultiPatchField::new(lattice.clone()),
            0.05,
        );
        assert!(live.forces().is_empty());
        // At the surface (+x pole): grabbed; dragging out pulls from the grab to the cursor.
        let pole = Vec3::new(1.45, 0.95, 0.95);
        live.update_forces(
            &sample(pole, true, 1000),
            &MultiPatchField::new(lattice.clone()),
            0.05,
        );
        // The grab is the stroke's anchor (the cursor on the surface pulls nothing yet).
        let mut geometry = StrokeGeometry::default();
        live.stroke_geometry(&mut geometry);
        let grab = geometry.anchor.unwrap();
        assert!(lattice.is_inside(grab) && grab.distance(pole) <= 0.2 + 1e-4);
        let out = pole + Vec3::X * 0.2;
        live.update_forces(
            &sample(out, true, 2000),
            &MultiPatchField::new(lattice.clone()),
            0.05,
        );
        assert_eq!(live.forces().len(), 1);
        let (start, end) = (live.forces()[0].start, live.forces()[0].end);
        assert_eq!(end, out);
        // The start is the surface on the way from the grab to the cursor, found again.
        assert!((start.x - 1.45).abs() < 0.01, "start {start}");
        assert!(start.x >= grab.x - 1e-4);
        let (lo, hi) = live.force_bounds().unwrap();
        assert!(lo.x <= start.x && hi.x >= out.x);
        live.stroke_geometry(&mut geometry);
        assert_eq!(geometry.anchor, Some(grab));
        assert!(matches!(live.felt_tool(), FeltTool::Force(_)));
        // Released: no force.
        live.update_forces(
            &sample(out, false, 3000),
            &MultiPatchField::new(lattice.clone()),
            0.05,
        );
        assert!(live.forces().is_empty());
    }

    #[test]
    fn geometric_applications_are_spaced_by_device_time() {
        let mut live = LiveTool::new(ToolChoice::Geometric(GeometricTool {
            shape: ToolShape::Sphere { radius_fu: 0.1 },
            action: ToolAction::Remove,
            falloff_fu: 0.05,
        }));
        let at = |t| sample(Vec3::ONE, true, t);
        let due = |d: Option<GeometricDue>| d.map(|d| (d.count, d.dwell_s));
        assert_eq!(due(live.geometric_due(&at(0), 10_000)), Some((1, 0.01)));
        assert_eq!(live.geometric_due(&at(5_000), 10_000), None);
        assert_eq!(
            due(live.geometric_due(&at(12_000), 10_000)),
            Some((1, 0.012))
        );
        // A long gap is capped.
        assert_eq!(
            due(live.geometric_due(&at(1_000_000), 10_000)),
            Some((1, 0.04))
        );
        assert_eq!(
            live.geometric_due(&sample(Vec3::ONE, false, 2_000_000), 10_000),
            None
        );
        // The push tool never applies geometry.
        live.set(ToolChoice::default());
        assert_eq!(live.geometric_due(&at(3_000_000), 10_000), None);
    }

    /// A tip that moved 0.1 since the last application (radius 0.1: spacing 0.025) is
    /// covered by four applications ending at the tip, the dwell split between them; a tip
    /// that jumped far is covered by the bounded count.
    #[test]
    fn a_moved_tip_is_reached_by_applications_a_quarter_radius_apart() {
        let mut live = LiveTool::new(ToolChoice::Geometric(GeometricTool {
            shape: ToolShape::Sphere { radius_fu: 0.1 },
            action: ToolAction::Remove,
            falloff_fu: 0.05,
        }));
        let a = Vec3::new(1.0, 1.0, 1.0);
        let first = live.geometric_due(&sample(a, true, 0), 10_000).unwrap();
        assert_eq!((first.count, first.point(0)), (1, a));
        let b = a + Vec3::X * 0.1;
        let due = live
            .geometric_due(&sample(b, true, 20_000), 10_000)
            .unwrap();
        assert_eq!(due.count, 4);
        assert!((due.dwell_s - 0.005).abs() < 1e-7);
        let points: Vec<Vec3> = (0..due.count).map(|i| due.point(i)).collect();
        assert_eq!(points[3], b);
        let mut last = a;
        for p in points {
            assert!(p.distance(last) <= 0.025 + 1e-6 && p.x > last.x);
            last = p;
        }
        let far = live
            .geometric_due(&sample(b + Vec3::X * 5.0, true, 30_000), 10_000)
            .unwrap();
        assert_eq!(far.count, MAX_SEGMENT_APPLICATIONS);
        // A new stroke starts at its own tip.
        live.end_stroke();
        let again = live
            .geometric_due(&sample(a, true, 40_000), 10_000)
            .unwrap();
        assert_eq!((again.count, again.from), (1, a));
    }
}
