//! Room for the clay in the running stage: before a stroke's region or a tool that can add
//! clay reaches past the base patch, the base grows (see `dynaclay_core::tools::Clay::grow`) and
//! the new layout goes to the haptic and graphics loops, as a refine's does.
//!
//! What moves with the base: the colour field (in the clay), the undo history and the stroke
//! being recorded (their deltas move onto the grown lattice, so undo stays exact), the painted
//! material grids (carried over sample by sample). The live region retires first: its
//! coefficient box indexes the old lattice; the next step makes a new one on the grown base.

#[allow(clippy::wildcard_imports)] // the stage's own module: its types and imports
use super::*;
use crate::BudgetRefusal;
use dynaclay_core::tools::{BRICK, GeometricTool, GrowthError, padding_to_cover};

impl SimulationStage {
    /// Grows the base patch so that the world box `lo..=hi` lies well inside it; returns
    /// whether it grew. A box past one of the clay's budgets leaves the clay as it is (the
    /// edit is clipped to the box), counts a command error and publishes why
    /// ([`SimStatus::budget_refusal`]); [`Self::try_make_room`] also returns it.
    pub(super) fn make_room(&mut self, lo: Vec3, hi: Vec3) -> bool {
        self.try_make_room(lo, hi).unwrap_or(false)
    }

    /// [`Self::make_room`], with the growth refused (and published) as the error.
    pub(super) fn try_make_room(&mut self, lo: Vec3, hi: Vec3) -> Result<bool, GrowthError> {
        let pad = match self.growth_pad(lo, hi) {
            Ok(Some(pad)) => pad,
            Ok(None) => return Ok(false),
            Err(refused) => {
                self.counters.command_errors(1);
                return Err(refused);
            }
        };
        let old_base = (!self.material_grids.is_empty()).then(|| self.clay.base().clone());
        // The region indexes the old lattice: it retires (its coefficients are in the clay).
        self.retire_region();
        let growth = match self.clay.grow(pad) {
            Ok(growth) => growth,
            Err(refused) => {
                match refused {
                    GrowthError::DenseBudget(dense) => self.refuse_for_budget(dense),
                    GrowthError::ClayTooLarge { dims, total } => {
                        self.counters.command_errors(1);
                        self.note_budget_refusal(BudgetRefusal::ClayBox { dims, total });
                    }
                    _ => self.counters.command_errors(1),
                }
                return Err(refused);
            }
        };
        self.history.regrid(&growth);
        if let Some(rec) = self.recorder.as_mut() {
            rec.regrid(&growth);
        }
        if let Some(old) = old_base {
            let grown = self.clay.base();
            for grid in &mut self.material_grids {
                *grid = grid.grown(&old, grown);
            }
        }
        self.pending[0] = None;
        self.colour_dirty |= self.clay.colour.is_some();
        self.mask_dirty |= self.clay.mask.is_some();
        self.cancel_compact();
        self.clay_revision += 1;
        self.counters.clay_growths(1);
        self.publish_layout();
        Ok(true)
    }

    /// The padding per side [`Self::try_make_room`] grows the base by to take the world box
    /// `lo..=hi` (`None` when it lies well inside): whole bricks at a time, and at least an
    /// eighth of the clay per side, so that a pull that keeps going grows the clay a few
    /// times, not at every step.
    fn growth_pad(&self, lo: Vec3, hi: Vec3) -> Result<Option<[usize; 3]>, GrowthError> {
        Ok(padding_to_cover(self.clay.base(), lo, hi)?.map(|pad| {
            std::array::from_fn(|a| {
                let eighth = self.clay.base().dims[a] / 8;
                pad[a].max(if pad[a] > 0 {
                    eighth.div_ceil(BRICK) * BRICK
                } else {
                    0
                })
            })
        }))
    }

    /// The refusal a region over the world box `lo..=hi` is sure to meet once the clay has
    /// grown to take it: the box spans more bricks of the base's spacing (the coarsest, so the
    /// fewest) than the clay may hold dense, and each brick it reaches is either dense already
    /// or one it may make dense. `None` when the box could fit, and when the clay cannot grow
    /// to take it (the region is then clipped to the clay's box, which may fit).
    pub(super) fn region_past_dense_budget(
        &self,
        lo: Vec3,
        hi: Vec3,
    ) -> Option<dynaclay_core::field::DenseBudgetError> {
        use dynaclay_core::field::{COEFF_BRICK, MAX_DENSE_BRICKS};
        match self.growth_pad(lo, hi) {
            Ok(Some(pad)) if self.clay.check_growth_box(pad).is_ok() => {}
            Ok(None) => {}
            _ => return None,
        }
        let spacing = self.clay.base().spacing;
        // Coefficients along each axis a region over the box holds at least: the box's knot
        // spans, and each brick holds COEFF_BRICK of them along an axis.
        let bricks = ((hi - lo) / spacing)
            .to_array()
            .iter()
            .try_fold(1.0_f64, |acc, &n| {
                (n.is_finite() && n >= 0.0)
                    .then(|| acc * (f64::from(n) / COEFF_BRICK as f64).ceil().max(1.0))
            })?;
        (bricks > MAX_DENSE_BRICKS as f64).then(|| {
            let dense = self.clay.dense_brick_count();
            dynaclay_core::field::DenseBudgetError {
                dense,
                more: (bricks.min(usize::MAX as f64) as usize).saturating_sub(dense),
                at: None,
            }
        })
    }

    /// [`Self::try_make_room`] for a geometric tool applied at `poses` on density patch
    /// `patch`: only a tool that can add clay, on the base, grows it.
    pub(super) fn make_room_for_tool(
        &mut self,
        tool: &GeometricTool,
        poses: &[ToolPose],
        patch: u16,
    ) -> Result<bool, GrowthError> {
        if patch != 0 || !tool.action.can_add_clay() || poses.is_empty() {
            return Ok(false);
        }
        let spacing = self.clay.base().spacing;
        let (lo, hi) = poses
            .iter()
            .map(|pose| tool.influence_box(pose, spacing))
            .reduce(|(alo, ahi), (blo, bhi)| (alo.min(blo), ahi.max(bhi)))
            .expect("poses is not empty");
        self.try_make_room(lo, hi)
    }

    /// Hands the clay's current patch layout to the haptic and graphics loops.
    ///
    /// The copy each reader is offered holds every coefficient as it is now, so the boxes
    /// pending for the old layout are dropped: publications from here on carry only what
    /// changes after the offer (with the new layout's patch indices). A reader skips updates
    /// until it has installed the copy and acknowledges none before, so those changes stay
    /// pending until both readers hold the new layout. Publishing the whole clay again here
    /// would be correct too, but every publication until both readers caught up would then
    /// copy every coefficient (on a large clay, hundreds of megabytes per buffer).
    pub(super) fn publish_layout(&mut self) {
        self.layout_generation += 1;
        for sender in &self.layout_senders {
            sender.offer(&self.clay.density, self.layout_generation);
        }
        self.pending = vec![None; self.clay.density.patches.len()];
        self.reader_reach = vec![reach::Reach::default(); self.clay.density.patches.len()];
        self.reader_dense_at_layout = self.clay.density.dense_brick_count();
        self.changed_since_publish = true;
    }
}

#[cfg(test)]
mod tests {
    use std::time::Instant;

    use super::super::super::Stages;
    use super::*;
    use dynaclay_core::dynamics::Distribution;
    use dynaclay_core::field::MAX_CLAY_BOX_COEFFS;
    use dynaclay_core::mesh::{BrickOctree, SampleGrid};
    use dynaclay_core::tools::{ForceTool, GeometricTool, ToolShape};

    fn add_ball(radius_fu: f32) -> GeometricTool {
        GeometricTool {
            shape: ToolShape::Sphere { radius_fu },
            action: ToolAction::Add {
                deposit_rate_per_s: 4.0,
            },
            falloff_fu: 0.1,
        }
    }

    /// Sends an add of a ball of radius 0.3 at `at` on the base, for one second of tool time;
    /// returns where its answer comes.
    fn add_lump(
        s: &mut Stages,
        at: Vec3,
    ) -> crossbeam::channel::Receiver<Result<EditOutcome, CommandError>> {
        let (tx, rx) = crossbeam::channel::bounded(1);
        s.commands
            .send(Command::ApplyTool {
                tool: add_ball(0.3),
                poses: vec![ToolPose::at(at)],
                duration_s: 1.0,
                patch: 0,
                reply: Some(tx),
            })
            .unwrap();
        rx
    }

    /// The process's peak resident set, bytes (`VmHWM` of `/proc/self/status`; 0 where it
    /// cannot be read).
    fn peak_rss_bytes() -> u64 {
        std::fs::read_to_string("/proc/self/status")
            .ok()
            .and_then(|status| {
                let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
                let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
                Some(kib * 1024)
            })
            .unwrap_or(0)
    }

    /// A figure for `bench/RESULTS.md`: a sphere clay grown by 400 knot spans on every side
    /// (828³ coefficients of box, past the old wall of 64 Mi) in every loop, with its dense
    /// bricks, its directory and the process's peak memory (no timing).
    #[test]
    #[ignore = "a figure for bench/RESULTS.md (a clay of 828³ coefficients of box)"]
    fn figure_a_clay_grown_past_the_old_box_wall_costs_its_surface() {
        let mut s = super::super::tests::stages_on_sphere(12);
        for _ in 0..3 {
            tick(&mut s, &ToolSample::IDLE);
        }
        let rss_before = peak_rss_bytes();
        let l = s.sim.lattice().clone();
        let reach = Vec3::splat(400.0 * l.spacing);
        let (lo, hi) = l.support();
        assert!(s.sim.make_room(lo - reach, hi + reach));
        for _ in 0..3 {
            tick(&mut s, &ToolSample::IDLE);
        }
        let dims = s.sim.lattice().dims;
        assert_eq!(s.haptic.field().base().dims, dims);
        assert_eq!(s.graphics.field().base().dims, dims);
        let coefficients: usize = dims.iter().product();
        assert!(coefficients > 64 << 20, "{dims:?}");
        eprintln!(
            "grown to {dims:?} ({coefficients} coefficients of box): {} dense bricks, \
             directory {} B, peak RSS {:.1} MB before, {:.1} MB after three ticks of every loop",
            s.sim.clay.dense_brick_count(),
            s.sim.clay.base().coeffs.heap_bytes()
                - s.sim.clay.base().coeffs.dense_brick_count()
                    * dynaclay_core::field::DENSE_BRICK_BYTES,
            rss_before as f64 / 1e6,
            peak_rss_bytes() as f64 / 1e6,
        );
    }

    fn tick(s: &mut Stages, sample: &ToolSample) {
        s.haptic.tick(Instant::now());
        s.sim.apply_commands();
        s.sim.step(sample);
        s.graphics.tick();
    }

    /// The largest x of the clay's surface as the graphics loop meshed it.
    fn meshed_max_x(s: &Stages) -> f32 {
        s.graphics
            .octree()
            .weld()
            .positions
            .iter()
            .map(|p| p.x)
            .fold(f32::NEG_INFINITY, f32::max)
    }

    /// The largest x of the surface of `field`, meshed afresh at 4 cells per span.
    fn surface_max_x(field: &MultiPatchField) -> f32 {
        let grid = SampleGrid::for_field(field, 4).unwrap();
        BrickOctree::build(grid, field)
            .weld()
            .positions
            .iter()
            .map(|p| p.x)
            .fold(f32::NEG_INFINITY, f32::max)
    }

    #[test]
    fn a_lump_added_past_the_box_grows_the_clay_in_every_loop_and_undo_keeps_the_room() {
        let mut s = super::super::tests::stages_on_sphere(12);
        let old = s.sim.lattice().clone();
        let last = old.node_position(11, 11, 11);
        let centre = (old.origin + last) * 0.5;
        // Half a radius past the last node: clipped flat before the clay could grow.
        let at = Vec3::new(last.x + 0.15, centre.y, centre.z);
        let rx = add_lump(&mut s, at);
        for _ in 0..4 {
            tick(&mut s, &ToolSample::IDLE);
        }
        rx.try_recv().unwrap().unwrap();
        let grown = s.sim.lattice().clone();
        assert!(
            grown.dims.iter().all(|&n| n >= 12) && grown.dims[0] > 12,
            "{:?}",
            grown.dims
        );
        assert_eq!(s.counters.snapshot().clay_growths, 1);
        assert!(s.sim.clay.density.is_inside(at), "the lump is there");
        // Every loop holds the grown layout, and the mesh reaches past the old box.
        assert_eq!(s.haptic.field().base().dims, grown.dims);
        assert_eq!(s.graphics.field().base().dims, grown.dims);
        let (_, old_hi) = old.support();
        assert!(
            meshed_max_x(&s) > old_hi.x,
            "{} vs {}",
            meshed_max_x(&s),
            old_hi.x
        );
        assert!(
            (meshed_max_x(&s) - surface_max_x(&s.sim.clay.density)).abs() < 0.05,
            "the loop's mesh is the clay's"
        );
        // Undo takes the lump away on the grown lattice; redo brings it back bit for bit.
        s.commands.send(Command::Undo).unwrap();
        tick(&mut s, &ToolSample::IDLE);
        assert!(!s.sim.clay.density.is_inside(at));
        assert_eq!(s.sim.lattice().dims, grown.dims, "the room stays");
        s.commands.send(Command::Redo).unwrap();
        tick(&mut s, &ToolSample::IDLE);
        assert_eq!(s.sim.lattice(), &grown);
    }

    /// A lump so far out that the grown clay would pass the box budget (growth is symmetric,
    /// so 10 000 spans out on every axis asks for over 20 000³ coefficients): the clay keeps
    /// its box, the tool is applied clipped to it, and the answer and the status say why.
    #[test]
    fn a_lump_past_the_box_budget_is_clipped_and_says_why() {
        let mut s = super::super::tests::stages_on_sphere(12);
        let old = s.sim.lattice().clone();
        let at = old.origin + Vec3::splat(10_000.0 * old.spacing);
        let rx = add_lump(&mut s, at);
        for _ in 0..2 {
            tick(&mut s, &ToolSample::IDLE);
        }
        let error = rx.try_recv().unwrap().unwrap_err().to_string();
        assert!(error.contains("clipped to the clay's box"), "{error}");
        assert!(error.contains(&MAX_CLAY_BOX_COEFFS.to_string()), "{error}");
        assert_eq!(s.sim.lattice().dims, old.dims, "no growth");
        assert_eq!(s.counters.snapshot().clay_growths, 0);
        assert!(matches!(
            s.sim.budget_refusal,
            Some(BudgetRefusal::ClayBox { total, .. }) if total > MAX_CLAY_BOX_COEFFS
        ));
        // A lump just past the box still grows the clay.
        let last = old.node_position(11, 11, 11);
        let near = Vec3::new(last.x + 0.15, (old.origin.y + last.y) * 0.5, last.z * 0.5);
        let rx = add_lump(&mut s, near);
        tick(&mut s, &ToolSample::IDLE);
        rx.try_recv().unwrap().unwrap();
        assert_eq!(s.counters.snapshot().clay_growths, 1);
    }

    /// Both readers end with the simulation's clay, value for value, when new layouts (a
    /// refine, a growth) and edits on every patch come while one reader or both lag behind:
    /// a new layout's copy plus the changes published after it lose nothing, without the
    /// whole clay published again.
    #[test]
    fn lagging_readers_get_every_change_across_new_layouts() {
        let mut s = super::super::tests::stages_on_sphere(12);
        let last = s.sim.lattice().node_position(11, 11, 11);
        let centre = (s.sim.lattice().origin + last) * 0.5;
        let top = centre + Vec3::Y * 0.27;
        let carve = GeometricTool {
            shape: ToolShape::Sphere { radius_fu: 0.05 },
            action: ToolAction::Remove,
            falloff_fu: 0.01,
        };
        let edit = |s: &mut Stages, tool: GeometricTool, at: Vec3, patch: u16| {
            s.commands
                .send(Command::ApplyTool {
                    tool,
                    poses: vec![ToolPose::at(at), ToolPose::at(at + Vec3::X * 0.02)],
                    duration_s: 0.5,
                    patch,
                    reply: None,
                })
                .unwrap();
        };
        let sim_only = |s: &mut Stages, steps: usize| {
            for _ in 0..steps {
                s.sim.apply_commands();
                s.sim.step(&ToolSample::IDLE);
            }
        };
        for _ in 0..3 {
            tick(&mut s, &ToolSample::IDLE);
        }
        // A refine and edits on both patches while neither reader runs.
        s.commands
            .send(Command::Refine {
                lo: top - Vec3::splat(0.15),
                hi: top + Vec3::splat(0.15),
                level: 2,
                reply: None,
            })
            .unwrap();
        edit(&mut s, carve.clone(), top, 1);
        sim_only(&mut s, 3);
        edit(&mut s, carve.clone(), top + Vec3::Z * 0.05, 1);
        edit(&mut s, carve.clone(), centre - Vec3::Y * 0.27, 0);
        sim_only(&mut s, 2);
        // The haptic loop catches up; the graphics loop still lags. Then the clay grows
        // (a newer layout) and an edit lands on the detail patch again.
        for _ in 0..3 {
            s.haptic.tick(Instant::now());
            s.sim.apply_commands();
            s.sim.step(&ToolSample::IDLE);
        }
        edit(
            &mut s,
            add_ball(0.3),
            Vec3::new(last.x + 0.15, centre.y, centre.z),
            0,
        );
        sim_only(&mut s, 1);
        edit(&mut s, carve.clone(), top - Vec3::Z * 0.05, 1);
        s.haptic.tick(Instant::now());
        sim_only(&mut s, 2);
        for _ in 0..4 {
            tick(&mut s, &ToolSample::IDLE);
        }
        // Both readers hold everything now. Undo and redo publish the step's bricks alone:
        // two edits undone (the last carve on the detail patch, the lump), one redone.
        s.commands.send(Command::Undo).unwrap();
        sim_only(&mut s, 1);
        s.haptic.tick(Instant::now());
        s.commands.send(Command::Undo).unwrap();
        s.commands.send(Command::Redo).unwrap();
        sim_only(&mut s, 2);
        for _ in 0..4 {
            tick(&mut s, &ToolSample::IDLE);
        }
        let counters = s.counters.snapshot();
        assert_eq!(counters.clay_growths, 1);
        // The refine's patch, and the one the narrow carve on the base made under itself.
        assert_eq!(
            (s.sim.clay.density.patches.len(), counters.auto_refines),
            (3, 1)
        );
        assert!(
            !s.sim.clay.density.is_inside(top),
            "the carve on the detail patch is in the clay"
        );
        assert!(
            s.haptic.field() == &s.sim.clay.density,
            "the haptic loop's copy is the clay's"
        );
        assert!(
            s.graphics.field() == &s.sim.clay.density,
            "the graphics loop's copy is the clay's"
        );
    }

    #[test]
    fn a_grown_and_refined_clay_saves_and_loads_whole() {
        let mut s = super::super::tests::stages_on_sphere(12);
        let last = s.sim.lattice().node_position(11, 11, 11);
        let centre = (s.sim.lattice().origin + last) * 0.5;
        for (tool, at) in [
            // Past the box: the clay grows.
            (add_ball(0.3), Vec3::new(last.x + 0.15, centre.y, centre.z)),
            // A fine brush: a detail patch under it.
            (
                GeometricTool {
                    shape: ToolShape::Sphere { radius_fu: 0.02 },
                    action: ToolAction::Remove,
                    falloff_fu: 0.005,
                },
                centre + Vec3::Y * 0.27,
            ),
        ] {
            s.commands
                .send(Command::ApplyTool {
                    tool,
                    poses: vec![ToolPose::at(at)],
                    duration_s: 1.0,
                    patch: 0,
                    reply: None,
                })
                .unwrap();
        }
        tick(&mut s, &ToolSample::IDLE);
        let counters = s.counters.snapshot();
        assert_eq!((counters.clay_growths, counters.auto_refines), (1, 1));
        let session = s.sim.session();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("grown.dclay");
        dynaclay_core::io::save_session(&path, &session).unwrap();
        let back = dynaclay_core::io::load_session(&path).unwrap();
        assert_eq!(
            back.clay, session.clay,
            "every patch, the grown base and the detail"
        );
        assert_eq!(back.clay.density.patches.len(), 2);
    }

    #[test]
    fn a_held_add_stroke_dragged_out_of_the_box_extends_the_clay_as_one_undo_step() {
        let mut s = super::super::tests::stages_on_sphere(12);
        let old = s.sim.lattice().clone();
        let before = s.sim.clay.density.clone();
        let last = old.node_position(11, 11, 11);
        let centre = (old.origin + last) * 0.5;
        s.commands
            .send(Command::SetTool(ToolChoice::Geometric(add_ball(0.2))))
            .unwrap();
        // From the sphere's surface out along +x, 0.8 past the last node, over 2 s.
        let from = centre.x + 0.2;
        let to = last.x + 0.8;
        let along = |t: f32| Vec3::new(from + (to - from) * t, centre.y, centre.z);
        super::super::tests::drag_tip(&mut s, along, 2000, 50);
        let (_, old_hi) = old.support();
        let reach = surface_max_x(&s.sim.clay.density);
        assert!(
            reach > to,
            "the bead follows the tip past the box: surface to x = {reach}, tip to {to}, old box to {}",
            old_hi.x
        );
        assert!(s.counters.snapshot().clay_growths >= 1);
        assert!(meshed_max_x(&s) > old_hi.x);
        // One stroke, one undo step, which gives back the sphere.
        s.commands.send(Command::Undo).unwrap();
        tick(&mut s, &ToolSample::IDLE);
        let back = surface_max_x(&s.sim.clay.density);
        assert!(
            (back - surface_max_x(&before)).abs() < 0.02,
            "undo gives back the sphere: {back} vs {}",
            surface_max_x(&before)
        );
    }
    #[test]
    fn a_pull_stroke_dragged_out_of_the_box_extends_the_clay_past_it() {
        let mut s = super::super::tests::stages_on_sphere(12);
        let old = s.sim.lattice().clone();
        let last = old.node_position(11, 11, 11);
        let centre = (old.origin + last) * 0.5;
        let mut surface = centre;
        while s.sim.clay.density.is_inside(surface + Vec3::X * 0.005) {
            surface.x += 0.005;
        }
        s.commands
            .send(Command::SetTool(ToolChoice::Force {
                tool: ForceTool::Pull {
                    distribution: Distribution::Gaussian,
                    radius_fu: 0.2,
                    gain: 2.0e6,
                },
                curve: Vec::new(),
                pivot: Vec3::ZERO,
            }))
            .unwrap();
        // From the sphere's surface out along +x, 0.5 past the last node, over 3 s.
        let from = surface.x;
        let to = last.x + 0.5;
        let along = |t: f32| Vec3::new(from + (to - from) * t, centre.y, centre.z);
        super::super::tests::drag_tip(&mut s, along, 3000, 500);
        let (_, old_hi) = old.support();
        let reach = surface_max_x(&s.sim.clay.density);
        eprintln!(
            "pulled from x = {from}: surface to x = {reach}, tip to {to}, last node {}, old support {}, growths {}",
            last.x,
            old_hi.x,
            s.counters.snapshot().clay_growths
        );
        assert!(s.counters.snapshot().clay_growths >= 1);
        assert!(
            reach > last.x + 0.2,
            "the pulled clay leaves the box: surface to x = {reach}, last node {}",
            last.x
        );
    }
}
