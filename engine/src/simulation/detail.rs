//! Detail where the brush is fine: before a geometric tool is applied on the base (a script's
//! or a command's tool step, or the held tool's application in a stroke), a brush narrower than
//! [`BRUSH_WIDTH_SPANS`] knot spans of the patch under it gets a detail patch under itself first
//! (Hua & Qin eq. (3)), at the level its width needs, and the tool edits that patch. With
//! [`SimConfig::auto_detail_force`] on (the default, see there), a held force tool (the
//! push, a pull, a grab of an area...; not the curve or the bend) follows the same rule with
//! twice its spread radius as its width: the patch is added before the step's region is set up, so the region is
//! simulated on it and the forces spread over its mass points. The new
//! layout goes to the haptic and graphics loops as a refine's does (the haptic loop swaps its
//! copy in wait-free, between ticks).
//!
//! A patch is reused while it holds every application's influence box (the shape turned by
//! its pose, with its band: an elongated brush reaches far past its width) with two of its
//! spans to spare. Each automatic patch is that box and [`AUTO_DETAIL_ROOM_WIDTHS`] brush
//! widths around it (at least [`AUTO_DETAIL_MIN_ROOM_SPANS`] of its own spans), so a stroke
//! that moves on adds a patch each time it leaves the last one; the clay's patch and coefficient budgets
//! bound them ([`dynaclay_core::field::MAX_PATCHES`], [`dynaclay_core::field::MAX_CLAY_BOX_COEFFS`]):
//! past them the brush sculpts on the finest patch there is.
//!
//! Detail goes away the same way: when a step ends (a stroke let go, a tool command, a
//! script step), each detail patch it edited, and each holding detail that it reached (a
//! removal on the base can leave a patch's detail far inside or outside the clay), is folded
//! into a coarser patch if the surface moves by at most a quarter of its knot span
//! ([`dynaclay_core::field::plan_coarsening`]). A patch nothing has written (a refine waiting
//! for its first stroke, or an automatic patch an undo emptied) stays until a step edits it. The fold is part of the step, so
//! undo gives the patch back. A smoothing wipes detail because it smooths every patch under it,
//! each on its own term (see [`SimulationStage::patches_smoothed`]).
//!
//! The stage remembers the folds it found refused
//! ([`dynaclay_core::field::plan_coarsening_remembering`]): a step that reaches a patch without
//! changing it or the coarser patch under it (most steps, once the clay holds many patches)
//! plans it again for the cost of a fingerprint and one evaluation of the clay, not a refit;
//! the folds made are those [`dynaclay_core::field::plan_coarsening`] makes.

#[allow(clippy::wildcard_imports)] // the stage's own module: its types and imports
use super::*;
use dynaclay_core::field::{MAX_DETAIL_LEVEL, plan_coarsening_remembering};
use dynaclay_core::tools::GeometricTool;

/// Knot spans of the patch it sculpts that a brush's width (twice its smallest half extent)
/// must cover; a narrower brush refines under itself first.
pub const BRUSH_WIDTH_SPANS: f32 = 3.0;

/// Room an automatic detail patch keeps around the brush's influence box, per side, in brush
/// widths.
pub const AUTO_DETAIL_ROOM_WIDTHS: f32 = 4.0;

/// Least room an automatic detail patch keeps around the brush's influence box, per side, in
/// its own knot spans.
pub const AUTO_DETAIL_MIN_ROOM_SPANS: f32 = 8.0;

/// The detail level (each level halves the base's knot spacing) at which a brush of width
/// `width_fu` covers [`BRUSH_WIDTH_SPANS`] spans, on a base of knot spacing `base_spacing_fu`;
/// at most [`MAX_DETAIL_LEVEL`], and 0 when the base is fine enough.
#[must_use]
pub fn level_for_brush(width_fu: f32, base_spacing_fu: f32) -> u32 {
    if !(width_fu.is_finite() && width_fu > 0.0) {
        return 0;
    }
    let ratio = BRUSH_WIDTH_SPANS * base_spacing_fu / width_fu;
    if ratio <= 1.0 {
        return 0;
    }
    (ratio.log2().ceil() as u32).min(MAX_DETAIL_LEVEL)
}

/// The detail a brush needs: the level and knot spacing of its patch, the brush's width and the
/// world box its applications read and write at that spacing.
#[derive(Clone, Copy, Debug)]
pub(super) struct BrushDetail {
    level: u32,
    spacing_fu: f32,
    width_fu: f32,
    lo: Vec3,
    hi: Vec3,
}

/// A brush's width: twice the smallest half extent of its shape.
#[must_use]
fn brush_width_fu(tool: &GeometricTool) -> f32 {
    2.0 * tool.shape.half_extents().min_element()
}

impl SimulationStage {
    /// The density patch `tool` applied at the brush poses `poses` edits: a detail patch fine
    /// enough for the brush, added first around the poses when the clay has none there that
    /// holds every application's influence box (see the module's docs); paint goes on the
    /// base, which the colour field covers.
    pub(super) fn patch_for_brush(&mut self, tool: &GeometricTool, poses: &[ToolPose]) -> u16 {
        match self.detail_for_brush(tool, poses) {
            Some(detail) => self.patch_for_detail(detail),
            None => 0,
        }
    }

    /// The patches a smoothing at `poses` edits when detail lies under it: the base and every
    /// detail patch its applications reach, each smoothed on its own term
    /// ([`dynaclay_core::tools::ApplyOptions::own_term`]; the blur is linear, so together that is the blur of the
    /// whole clay, and each level keeps what its spacing carries: a refit of the base alone
    /// cannot take detail finer than its spans away). `None` for other tools, or when no
    /// detail patch lies under the brush.
    pub(super) fn patches_smoothed(
        &self,
        tool: &GeometricTool,
        poses: &[ToolPose],
    ) -> Option<Vec<u16>> {
        if !matches!(tool.action, ToolAction::Smooth { .. }) {
            return None;
        }
        // At the base's spacing the band is widest.
        let spacing = self.clay.base().spacing;
        let (lo, hi) = poses
            .iter()
            .map(|pose| tool.influence_box(pose, spacing))
            .reduce(|(alo, ahi), (blo, bhi)| (alo.min(blo), ahi.max(bhi)))?;
        let patches: Vec<u16> = self
            .clay
            .density
            .patches
            .iter()
            .enumerate()
            .filter(|(n, p)| {
                let (plo, phi) = p.world_support();
                *n == 0 || (p.is_identity() && plo.cmple(hi).all() && phi.cmpge(lo).all())
            })
            .filter_map(|(n, _)| u16::try_from(n).ok())
            .collect();
        (patches.len() > 1).then_some(patches)
    }

    /// The detail `tool` at `poses` needs, or `None` when the base resolves it (or automatic
    /// detail is off, or the tool paints).
    pub(super) fn detail_for_brush(
        &self,
        tool: &GeometricTool,
        poses: &[ToolPose],
    ) -> Option<BrushDetail> {
        if tool.action.paints() {
            return None;
        }
        let width_fu = brush_width_fu(tool);
        let (level, spacing_fu) = self.detail_level(width_fu)?;
        // What the applications read and write on a patch of that spacing: the shape turned
        // by each pose, with its band (an elongated brush reaches far past its width).
        let (lo, hi) = poses
            .iter()
            .map(|pose| tool.influence_box(pose, spacing_fu))
            .reduce(|(alo, ahi), (blo, bhi)| (alo.min(blo), ahi.max(bhi)))?;
        Some(BrushDetail {
            level,
            spacing_fu,
            width_fu,
            lo,
            hi,
        })
    }

    /// The detail level a brush of width `width_fu` needs and that level's knot spacing, or
    /// `None` when the base resolves it or automatic detail is off.
    fn detail_level(&self, width_fu: f32) -> Option<(u32, f32)> {
        let base_spacing = self.clay.base().spacing;
        let level = level_for_brush(width_fu, base_spacing);
        if !self.config.auto_detail || level == 0 {
            return None;
        }
        Some((level, base_spacing / (1_u32 << level) as f32))
    }

    /// Before a step of a held force tool (the push, or a grab, pull, area, chisel or squirt
    /// stroke; not the curve or the bend, whose reach is their path or arm) sets up its
    /// region, with [`SimConfig::auto_detail_force`] on: a
    /// tool whose spread is narrower than
    /// [`BRUSH_WIDTH_SPANS`] knot spans of the base gets a detail patch under itself first, by
    /// the rule a geometric brush follows, so the region is set up on that patch
    /// ([`SimulationStage::sculpted_patch_at`] picks the finest patch there) and this step's
    /// forces are spread over its mass points. The width is twice the tool's spread radius
    /// (the point grab has none and never refines). Under the tool means around the push's
    /// vector (the surface above the tip to the tip), or around the cursor and the point the
    /// stroke holds: a pull drawn out keeps its patch while it reaches both ends; and around
    /// the last step's forces, so a chisel's or squirt's targets planned along the whole
    /// stroke lie on the patch its region is simulated on (see
    /// [`SimulationStage::region_patch_for`]). A released stroke that settles keeps the patch
    /// it has.
    pub(super) fn refine_under_force_tool(&mut self, sample: &ToolSample) {
        if !self.config.auto_detail_force {
            return;
        }
        let (radius_fu, ends) = match self.tool.choice() {
            ToolChoice::Push(push) if sample.in_contact => {
                (push.radius_fu, [sample.force_from_fu, sample.force_to_fu])
            }
            // The curve and the bend move a recorded path or an arm about its pivot, not the
            // clay under the cursor: their reach is the path's, so they stay on the patches
            // there are (refined under the cursor alone, the curve in the window moved no clay
            // at all: `app::reach_tests`).
            ToolChoice::Force {
                tool: ForceTool::Curve { .. } | ForceTool::Bend { .. },
                ..
            } => return,
            ToolChoice::Force { tool, .. } if sample.stroke_active => {
                let Some(radius_fu) = tool.radius_fu() else {
                    return;
                };
                let held = self.tool.grab_point().unwrap_or(sample.tip_fu);
                (radius_fu, [sample.tip_fu, held])
            }
            _ => return,
        };
        if !ends.iter().all(|e| e.is_finite()) {
            return;
        }
        let width_fu = 2.0 * radius_fu;
        let Some((level, spacing_fu)) = self.detail_level(width_fu) else {
            return;
        };
        let reach = Vec3::splat(radius_fu);
        let (mut lo, mut hi) = (ends[0].min(ends[1]) - reach, ends[0].max(ends[1]) + reach);
        // The last step's forces with their spread: a chisel's or squirt's targets along the
        // whole stroke so far, below the path by their depth.
        if let Some((flo, fhi)) = self.tool.force_bounds() {
            (lo, hi) = (lo.min(flo), hi.max(fhi));
        }
        let detail = BrushDetail {
            level,
            spacing_fu,
            width_fu,
            lo,
            hi,
        };
        self.patch_for_detail(detail);
    }

    /// The patch that holds `detail`'s box at its spacing, added first when the clay has none.
    pub(super) fn patch_for_detail(&mut self, detail: BrushDetail) -> u16 {
        let BrushDetail {
            level,
            spacing_fu,
            width_fu,
            lo,
            hi,
        } = detail;
        if let Some(n) = self.patch_covering(lo, hi, spacing_fu) {
            return u16::try_from(n).unwrap_or(0);
        }
        let room =
            (AUTO_DETAIL_ROOM_WIDTHS * width_fu).max(AUTO_DETAIL_MIN_ROOM_SPANS * spacing_fu);
        let room = Vec3::splat(room);
        match self.clay.refine(lo - room, hi + room, level) {
            Ok(n) => {
                self.pending.push(None);
                self.clay_revision += 1;
                self.counters.auto_refines(1);
                self.publish_layout();
                u16::try_from(n).unwrap_or(0)
            }
            // Past the budgets: the finest patch that holds the brush, else the base.
            Err(_) => self
                .patch_covering(lo, hi, f32::INFINITY)
                .map_or(0, |n| u16::try_from(n).unwrap_or(0)),
        }
    }

    /// Folds away, as part of the step `rec` records, every detail patch whose detail the step
    /// wiped (see the module's docs); the new layout goes to the loops when any was folded.
    /// Nothing is folded while a region is being simulated (it holds a patch's index).
    pub(super) fn coarsen_wiped_detail(&mut self, rec: &mut StepRecorder) {
        if !self.config.auto_detail || self.region.is_some() {
            return;
        }
        let reached = self.step_world_box(rec);
        let mut folded = 0;
        for n in (1..self.clay.density.patches.len()).rev() {
            let patch = &self.clay.density.patches[n];
            let (plo, phi) = patch.world_support();
            let edited = rec.touched_box(density_id(n)).is_some();
            let reached =
                reached.is_some_and(|(lo, hi)| plo.cmple(hi).all() && phi.cmpge(lo).all());
            // A patch no step has written yet (a refine waiting for its first stroke) stays.
            let holds_detail = || patch.lattice.coeffs.iter().any(|&c| c != 0.0);
            if !(edited || (reached && holds_detail())) {
                continue;
            }
            let plan = plan_coarsening_remembering(&self.clay.density, n, &mut self.refused_folds);
            // A fold past the clay's dense-brick budget is not made (the detail stays).
            if let Ok(Some(plan)) = plan
                && rec.coarsen(&mut self.clay, &plan).is_ok()
            {
                folded += 1;
            }
        }
        if folded > 0 {
            // No region is live (see above): the last one's patch may be gone.
            self.region_patch = 0;
            self.pending = vec![None; self.clay.density.patches.len()];
            self.clay_revision += 1;
            self.counters.auto_coarsenings(folded);
            self.publish_layout();
        }
    }

    /// The world box around every density coefficient `rec` touched (`None` if none).
    fn step_world_box(&self, rec: &StepRecorder) -> Option<(Vec3, Vec3)> {
        (0..self.clay.density.patches.len())
            .filter_map(|n| {
                let b = rec.touched_box(density_id(n))?;
                let patch = &self.clay.density.patches[n];
                let (lo, hi) = b.world_support(&patch.lattice);
                Some(patch.world_box_of(lo, hi))
            })
            .reduce(|(alo, ahi), (blo, bhi)| (alo.min(blo), ahi.max(bhi)))
    }

    /// The finest detail patch in world coordinates, of knot spacing `wanted` or finer, whose
    /// coefficients hold the world box `lo..=hi` with two of its spans to spare (so every
    /// sample an application writes is written wholly by its coefficients).
    fn patch_covering(&self, lo: Vec3, hi: Vec3, wanted: f32) -> Option<usize> {
        self.clay
            .density
            .patches
            .iter()
            .enumerate()
            .skip(1)
            .filter(|(_, p)| p.is_identity() && p.lattice.spacing <= wanted * 1.001)
            .filter(|(_, p)| {
                let (plo, phi) = p.lattice.support();
                let margin = Vec3::splat(2.0 * p.lattice.spacing);
                lo.cmpge(plo + margin).all() && hi.cmple(phi - margin).all()
            })
            .min_by(|(_, a), (_, b)| a.lattice.spacing.total_cmp(&b.lattice.spacing))
            .map(|(n, _)| n)
    }
}

#[cfg(test)]
mod tests {
    use std::time::Instant;

    use super::super::super::Stages;
    use super::*;
    use dynaclay_core::tools::ToolShape;

    /// Sends the pull of a Gaussian spread `radius_fu` and gain 2e6 as the tool.
    fn set_pull(s: &Stages, radius_fu: f32) {
        s.commands
            .send(Command::SetTool(ToolChoice::Force {
                tool: dynaclay_core::tools::ForceTool::Pull {
                    distribution: dynaclay_core::dynamics::Distribution::Gaussian,
                    radius_fu,
                    gain: 2.0e6,
                },
                curve: Vec::new(),
                pivot: Vec3::ZERO,
            }))
            .unwrap();
    }

    /// The width of the outside of `field` along z around `at` (which is outside): from `at`
    /// both ways to the first inside sample, every 0.0005.
    fn outside_width(field: &MultiPatchField, at: Vec3) -> f32 {
        let step = 0.0005;
        let run = |dir: f32| {
            (1..400)
                .take_while(|&n| !field.is_inside(at + Vec3::Z * (dir * n as f32 * step)))
                .count() as f32
        };
        assert!(!field.is_inside(at), "no groove at {at}");
        (1.0 + run(1.0) + run(-1.0)) * step
    }

    /// Carves a ball of `radius_fu` centred on the sphere clay's top along a short x stroke;
    /// returns the groove's width half a radius below the top, the chord's width there, the
    /// patches the clay holds after and the automatic refines counted.
    fn carve_top(radius_fu: f32, auto: bool) -> (f32, f32, usize, u64) {
        let mut s = super::super::tests::stages_on_sphere(12);
        let top = super::super::tests::sphere_top(&s);
        let poses: Vec<ToolPose> = (0..=20)
            .map(|n| ToolPose::at(top + Vec3::X * (-0.05 + 0.005 * n as f32)))
            .collect();
        s.sim.config.auto_detail = auto;
        s.commands
            .send(Command::ApplyTool {
                tool: GeometricTool {
                    shape: ToolShape::Sphere { radius_fu },
                    action: ToolAction::Remove,
                    falloff_fu: 0.25 * radius_fu,
                },
                poses,
                duration_s: 1.0,
                patch: 0,
                reply: None,
            })
            .unwrap();
        s.haptic.tick(Instant::now());
        s.sim.apply_commands();
        let below = top - Vec3::Y * (0.5 * radius_fu);
        let width = outside_width(&s.sim.clay.density, below);
        let chord = 2.0 * (radius_fu * radius_fu - (0.5 * radius_fu).powi(2)).sqrt();
        (
            width,
            chord,
            s.sim.clay.density.patches.len(),
            s.counters.snapshot().auto_refines,
        )
    }

    #[test]
    fn a_fine_brush_refines_under_itself_and_carves_a_groove_of_its_own_width() {
        // The base's knot spacing is 0.1: a ball of radius 0.02 (width 0.04) needs level 3.
        let (width, chord, patches, refines) = carve_top(0.02, true);
        assert_eq!((patches, refines), (2, 1));
        assert!(
            (width - chord).abs() <= 0.25 * chord,
            "groove {width} against the ball's chord {chord}"
        );
        let (coarse, _, patches, refines) = carve_top(0.02, false);
        eprintln!("groove {width:.4} (detail), {coarse:.4} (base only), chord {chord:.4}");
        assert_eq!((patches, refines), (1, 0));
        assert!(
            (coarse - chord).abs() > (width - chord).abs(),
            "on the base alone the groove is {coarse} wide"
        );
    }

    /// Sends a tool command over `poses` for `duration_s` and applies it.
    fn apply(s: &mut Stages, tool: GeometricTool, poses: Vec<ToolPose>, duration_s: f32) {
        s.commands
            .send(Command::ApplyTool {
                tool,
                poses,
                duration_s,
                patch: 0,
                reply: None,
            })
            .unwrap();
        s.haptic.tick(Instant::now());
        s.sim.apply_commands();
    }

    /// A ball of radius 0.02 carving a short groove along x over the top of the sphere clay
    /// (a level-3 detail patch under it); returns the stages, the top and a point inside the
    /// groove.
    fn grooved_sphere() -> (Stages, Vec3, Vec3) {
        let mut s = super::super::tests::stages_on_sphere(12);
        let top = super::super::tests::sphere_top(&s);
        let radius_fu = 0.02;
        let poses = (0..=20)
            .map(|n| ToolPose::at(top + Vec3::X * (-0.05 + 0.005 * n as f32)))
            .collect();
        let carve = GeometricTool {
            shape: ToolShape::Sphere { radius_fu },
            action: ToolAction::Remove,
            falloff_fu: 0.25 * radius_fu,
        };
        apply(&mut s, carve, poses, 1.0);
        let in_groove = top - Vec3::Y * (0.5 * radius_fu);
        assert!(
            !s.sim.clay.density.is_inside(in_groove),
            "the groove is cut"
        );
        assert_eq!(s.sim.clay.density.patches.len(), 2);
        (s, top, in_groove)
    }

    /// The height of `field`'s surface above the point `(x, z)` near `top`, found from above.
    fn surface_y(field: &MultiPatchField, top: Vec3, x: f32, z: f32) -> f32 {
        let mut at = Vec3::new(top.x + x, top.y + 0.1, top.z + z);
        while !field.is_inside(at) && at.y > top.y - 0.3 {
            at.y -= 0.0002;
        }
        at.y
    }

    /// Asserts that `clay` holds the detail patches of `want` bit for bit and the same field
    /// around the top (the base may have grown since, so its bits moved).
    fn assert_same_clay(clay: &Clay, want: &Clay, top: Vec3, what: &str) {
        let patches = |c: &Clay| c.density.patches.len();
        assert_eq!(patches(clay), patches(want), "{what}: patch count");
        for (n, (a, b)) in clay
            .density
            .patches
            .iter()
            .zip(&want.density.patches)
            .enumerate()
            .skip(1)
        {
            assert_eq!(
                a.lattice.dims, b.lattice.dims,
                "{what}: patch {n}'s dimensions"
            );
            let differ = a
                .lattice
                .coeffs
                .iter()
                .zip(&b.lattice.coeffs)
                .filter(|(x, y)| x.to_bits() != y.to_bits())
                .count();
            assert_eq!(differ, 0, "{what}: coefficients of patch {n} differ");
        }
        for n in 0..1000 {
            let f = Vec3::new((n % 10) as f32, (n / 10 % 10) as f32, (n / 100) as f32) / 9.0;
            let x = top + (f - Vec3::splat(0.5)) * 0.3;
            let (got, wanted) = (clay.density.value(x), want.density.value(x));
            assert!(
                (got - wanted).abs() < 1e-5,
                "{what}: at {x} {got} against {wanted}"
            );
        }
    }

    /// A ball of radius 0.25 smoothing with a kernel of 1.5 base spans along x over `top`
    /// for 3 s.
    fn smooth_top(s: &mut Stages, top: Vec3) {
        let smooth = GeometricTool {
            shape: ToolShape::Sphere { radius_fu: 0.25 },
            action: ToolAction::Smooth {
                rate_per_s: 20.0,
                kernel_fu: 0.15,
            },
            falloff_fu: 0.05,
        };
        let poses = (0..=10)
            .map(|n| ToolPose::at(top + Vec3::X * (-0.05 + 0.01 * n as f32)))
            .collect();
        apply(s, smooth, poses, 3.0);
    }

    #[test]
    fn a_broad_smoothing_wipes_fine_detail_and_its_patch_folds_back_until_undone() {
        let (mut s, top, in_groove) = grooved_sphere();
        let carved = s.sim.clay.clone();
        smooth_top(&mut s, top);
        // The reference: the same smoothing on the clay that was never carved.
        let mut reference = super::super::tests::stages_on_sphere(12);
        smooth_top(&mut reference, top);
        let field = &s.sim.clay.density;
        let tolerance = 0.25 * 0.1 / 8.0;
        for (x, z) in [
            (0.0, 0.0),
            (-0.03, 0.0),
            (0.03, 0.0),
            (0.0, 0.02),
            (0.0, -0.02),
        ] {
            let (y, want) = (
                surface_y(field, top, x, z),
                surface_y(&reference.sim.clay.density, top, x, z),
            );
            eprintln!("surface at ({x}, {z}): {y:.4}, never carved {want:.4}");
            assert!(
                (y - want).abs() <= tolerance + 0.0005,
                "at ({x}, {z}) the smoothed groove's surface is {y}, the smoothed clay's {want}"
            );
        }
        assert!(!carved.density.is_inside(in_groove));
        let smoothed = s.sim.clay.clone();
        s.commands.send(Command::Undo).unwrap();
        s.sim.apply_commands();
        assert_same_clay(
            &s.sim.clay,
            &carved,
            top,
            "undo gives back the patch and the groove",
        );
        s.commands.send(Command::Redo).unwrap();
        s.sim.apply_commands();
        assert_same_clay(&s.sim.clay, &smoothed, top, "redo folds it again");
    }

    #[test]
    fn a_smoothing_beside_the_detail_keeps_it() {
        let (mut s, top, in_groove) = grooved_sphere();
        let smooth = GeometricTool {
            shape: ToolShape::Sphere { radius_fu: 0.1 },
            action: ToolAction::Smooth {
                rate_per_s: 20.0,
                kernel_fu: 0.15,
            },
            falloff_fu: 0.05,
        };
        // On the sphere's side, away from the groove on its top.
        let side = top.with_y(top.y - 0.5) + Vec3::Z * 0.5;
        apply(&mut s, smooth, vec![ToolPose::at(side)], 1.0);
        assert_eq!(s.sim.clay.density.patches.len(), 2);
        assert!(
            !s.sim.clay.density.is_inside(in_groove),
            "the groove is kept"
        );
        assert_eq!(s.counters.snapshot().auto_coarsenings, 0);
    }

    #[test]
    fn a_refined_patch_waits_for_its_first_stroke_and_an_emptied_one_folds_when_edited() {
        let (mut s, top, _) = grooved_sphere();
        s.commands.send(Command::Undo).unwrap();
        s.sim.apply_commands();
        assert_eq!(s.sim.clay.density.patches.len(), 2, "undo keeps the layout");
        // A step over the emptied patch that does not write it (an add on the base with a
        // brush of several base spans) leaves it.
        let add = GeometricTool {
            shape: ToolShape::Sphere { radius_fu: 0.2 },
            action: ToolAction::Add {
                deposit_rate_per_s: 0.5,
            },
            falloff_fu: 0.05,
        };
        apply(&mut s, add, vec![ToolPose::at(top + Vec3::Y * 0.1)], 0.2);
        assert_eq!(s.sim.clay.density.patches.len(), 2);
        assert_eq!(s.counters.snapshot().auto_coarsenings, 0);
        // A smoothing over it writes it and folds it (it holds nothing the base cannot).
        smooth_top(&mut s, top);
        assert_eq!(s.sim.clay.density.patches.len(), 1);
        assert_eq!(s.counters.snapshot().auto_coarsenings, 1);
    }

    #[test]
    fn a_brush_of_three_spans_needs_no_detail_and_each_halving_adds_a_level() {
        assert_eq!(level_for_brush(0.3, 0.1), 0);
        assert_eq!(level_for_brush(0.29, 0.1), 1);
        assert_eq!(level_for_brush(0.15, 0.1), 1);
        assert_eq!(level_for_brush(0.14, 0.1), 2);
        assert_eq!(level_for_brush(0.0001, 0.1), MAX_DETAIL_LEVEL);
        assert_eq!(level_for_brush(0.0, 0.1), 0);
        assert_eq!(level_for_brush(f32::NAN, 0.1), 0);
    }

    #[test]
    fn a_held_fine_brush_refines_under_itself_and_carves_a_groove_of_its_own_width() {
        let radius_fu = 0.02;
        let mut s = super::super::tests::stages_on_sphere(12);
        let top = super::super::tests::sphere_top(&s);
        s.commands
            .send(Command::SetTool(ToolChoice::Geometric(GeometricTool {
                shape: ToolShape::Sphere { radius_fu },
                action: ToolAction::Remove,
                falloff_fu: 0.25 * radius_fu,
            })))
            .unwrap();
        // Along x over the top, 0.1 in 0.5 s, then let go.
        let along = |t: f32| top + Vec3::X * (-0.05 + 0.1 * t);
        super::super::tests::drag_tip(&mut s, along, 500, 20);
        let refines = s.counters.snapshot().auto_refines;
        assert!(refines >= 1, "the held brush refined under itself");
        assert!(s.sim.clay.density.patches.len() > 1);
        assert_eq!(
            s.haptic.field().patches.len(),
            s.sim.clay.density.patches.len(),
            "the haptic loop took the new layout"
        );
        let below = top - Vec3::Y * (0.5 * radius_fu);
        let width = outside_width(&s.sim.clay.density, below);
        let chord = 2.0 * (radius_fu * radius_fu - (0.5 * radius_fu).powi(2)).sqrt();
        eprintln!("held: groove {width:.4}, chord {chord:.4}, {refines} refines");
        assert!(
            (width - chord).abs() <= 0.25 * chord,
            "groove {width} against the ball's chord {chord}"
        );
        // One stroke, one undo step: undo gives back the untouched top.
        s.commands.send(Command::Undo).unwrap();
        s.sim.apply_commands();
        assert!(
            s.sim.clay.density.is_inside(below),
            "undo refilled the groove"
        );
    }

    #[test]
    fn a_fine_pull_refines_under_itself_before_its_region_is_set_up() {
        let mut s = super::super::tests::stages_on_sphere(12);
        s.sim.config.auto_detail_force = true;
        let top = super::super::tests::sphere_top(&s);
        // A spread of a fifth of the base's knot span (0.1): level 3.
        let radius_fu = 0.02;
        set_pull(&s, radius_fu);
        // From the top straight up by a knot span over 0.2 s, held.
        let up = |t: f32| top + Vec3::Y * (0.1 * t);
        super::super::tests::drag_tip(&mut s, up, 200, 0);
        let refines = s.counters.snapshot().auto_refines;
        assert_eq!(refines, 1, "one patch under the pull");
        let patch = &s.sim.clay.density.patches[1];
        assert!(
            (patch.lattice.spacing - 0.1 / 8.0).abs() < 1e-6,
            "at the level its spread needs: {}",
            patch.lattice.spacing
        );
        assert_eq!(s.sim.region_patch, 1, "the region is simulated on it");
        assert_eq!(
            s.haptic.field().patches.len(),
            2,
            "the haptic loop took the new layout"
        );
        // The pull drew the surface up above the old top, on the detail patch.
        assert!(
            s.sim.clay.density.is_inside(top + Vec3::Y * 0.01),
            "the surface rose under the pull"
        );
        assert!(
            s.sim.clay.density.patches[1]
                .lattice
                .coeffs
                .iter()
                .any(|&c| c != 0.0),
            "the pull moved the detail patch"
        );
        // With automatic detail for force tools off (on by default), the same pull stays on
        // the base.
        let mut off = super::super::tests::stages_on_sphere(12);
        off.sim.config.auto_detail_force = false;
        off.commands
            .send(Command::SetTool(s.sim.tool().clone()))
            .unwrap();
        super::super::tests::drag_tip(&mut off, up, 200, 0);
        assert_eq!(off.sim.clay.density.patches.len(), 1);
        assert_eq!(off.counters.snapshot().auto_refines, 0);
    }

    /// With the two-level material on, a region on a level-2 patch takes coarse springs one
    /// base mass spacing apart (every fourth mass point) and steps a pull without a refused
    /// step; with it off (the default) the region has none, as the base.
    #[test]
    fn a_two_level_region_on_a_detail_patch_has_coarse_springs_at_the_base_spacing() {
        for two_level in [false, true] {
            let mut s = super::super::tests::stages_on_sphere(12);
            s.sim.config.two_level_detail = two_level;
            let top = super::super::tests::sphere_top(&s);
            let n = s
                .sim
                .clay
                .density
                .refine(top - Vec3::splat(0.3), top + Vec3::splat(0.3), 2)
                .unwrap();
            set_pull(&s, 0.05);
            let up = |t: f32| top + Vec3::Y * (0.05 * t);
            super::super::tests::drag_tip(&mut s, up, 150, 0);
            assert_eq!(s.sim.region_patch, n, "the pull is simulated on the patch");
            let region = s.sim.region.as_ref().expect("a region");
            let want = if two_level { (4, 4) } else { (1, 1) };
            assert_eq!((region.coarse_stride, region.spacing_ratio), want);
            assert_eq!(s.counters.snapshot().sim_nonfinite_rejected, 0);
            assert!(
                s.sim.clay.density.is_inside(top + Vec3::Y * 0.01),
                "the surface rose under the pull (two-level {two_level})"
            );
        }
    }

    #[test]
    fn a_region_on_a_detail_patch_holds_as_many_knot_spans_as_on_the_base() {
        // A lattice large enough that the base's region is not clipped by its box.
        let mut s = super::super::tests::stages_on_sphere(32);
        let lattice = s.sim.lattice().clone();
        let centre = (lattice.origin + lattice.node_position(31, 31, 31)) * 0.5;
        let top = centre + Vec3::Y * 0.3;
        let reach = Vec3::splat(0.01);
        s.sim.ensure_region(top - reach, top + reach);
        let on_base = s.sim.region.as_ref().expect("a region").coeff_box().dims();
        assert_eq!(s.sim.region_patch, 0);
        s.sim.retire_region();
        let n = s
            .sim
            .clay
            .density
            .refine(top - Vec3::splat(0.5), top + Vec3::splat(0.5), 2)
            .unwrap();
        s.sim.ensure_region(top - reach, top + reach);
        assert_eq!(s.sim.region_patch, n, "the region is on the detail patch");
        let on_detail = s.sim.region.as_ref().expect("a region").coeff_box().dims();
        // Up to one coefficient either way, from where the box's ends fall on each lattice.
        for a in 0..3 {
            assert!(
                on_detail[a].abs_diff(on_base[a]) <= 1,
                "the same knot spans, so the same step: {on_detail:?} against {on_base:?}"
            );
        }
    }
}
