//! Publication: the changed box of the field to the haptic and graphics loops (with the
//! acknowledgement protocol that lets the simulation reuse a buffer once both have copied it),
//! the paint at a throttled rate, and the status for observers.

#[allow(clippy::wildcard_imports)] // the stage's own module: its types and imports
use super::*;
use dynaclay_core::field::MAX_DENSE_BRICKS;

/// Steps between two publications of a changing colour field. Painting changes it every step;
/// the graphics loop shows it at 60 Hz, so copying all four channels at the simulation's rate
/// would be wasted work.
const COLOUR_PUBLISH_EVERY_STEPS: u64 = 16;

impl SimulationStage {
    /// Records that box `b` of density patch `patch` changed outside the region's regular
    /// publication.
    pub(super) fn mark_changed(&mut self, patch: usize, b: CoeffBox) {
        self.changed_since_publish = true;
        if let Some(pending) = self.pending.get_mut(patch) {
            *pending = Some(pending.map_or(b, |p| p.union(&b)));
            self.pending_since = self.to_haptic.version() + 1;
        }
    }

    /// Records that every coefficient of every density patch changed (a load, an undo).
    pub(super) fn mark_all_changed(&mut self) {
        for patch in 0..self.clay.density.patches.len() {
            let whole = CoeffBox::whole(self.clay.density.patches[patch].lattice.dims);
            self.mark_changed(patch, whole);
        }
    }

    pub(super) fn publish(&mut self) {
        // NOTE: Acquire pairs with the readers' Release store of their ack: once a reader has
        // acknowledged a version, it holds every coefficient that version carried.
        let seen = self
            .acks
            .haptic
            .load(Ordering::Acquire)
            .min(self.acks.graphics.load(Ordering::Acquire));
        if seen >= self.pending_since {
            self.pending.fill(None);
        }
        for sender in &self.layout_senders {
            sender.drop_retired();
        }
        let mut region = self
            .region
            .as_ref()
            .map(|r| (self.region_patch, r.coeff_box()));
        // A publication carries at most MAX_UPDATE_COEFFS coefficients: boxes past that (an
        // edit over much of a large clay, an undo, boxes far apart whose union is the clay)
        // reach the readers as a copy of the clay instead, which is sparse (its dense bricks
        // and its directory), and only the region's box follows in the publication.
        if self.published_coefficients(region) > MAX_UPDATE_COEFFS {
            self.publish_layout();
            self.counters.updates_as_copies(1);
            // A region past the cap itself (never at the configured sizes) is carried by the
            // copies too, one per step.
            if self.published_coefficients(region) > MAX_UPDATE_COEFFS {
                region = None;
            }
        }
        // The readers' copies keep every brick a publication made dense (they are never
        // compacted, so that the haptic loop frees nothing): once the bricks the published
        // boxes reach could take them past the clay's dense-brick budget, they get a fresh
        // copy, as sparse as the clay.
        for n in 0..self.reader_reach.len() {
            if let Some(b) = self.box_to_publish(n, region) {
                self.reader_reach[n].add(b);
            }
        }
        if self.reader_dense_bound() > MAX_DENSE_BRICKS {
            self.publish_layout();
            self.counters.updates_as_copies(1);
            for n in 0..self.reader_reach.len() {
                self.reader_reach[n] = reach::Reach::of(self.box_to_publish(n, region));
            }
        }
        let field = &self.clay.density;
        for w in [&mut self.to_haptic, &mut self.to_graphics] {
            let patch = w.back_mut();
            patch.clear();
            for (n, pending) in self.pending.iter().enumerate() {
                let b = match (region, pending) {
                    (Some((rp, r)), p) if rp == n => Some(p.map_or(r, |p| p.union(&r))),
                    (_, p) => *p,
                };
                if let Some(b) = b {
                    patch.capture(field, n, b);
                }
            }
            patch.stroke_armed = self.stroke_armed;
            patch.tool = self.tool.felt_tool();
            self.tool.stroke_geometry(&mut patch.stroke);
            patch.sim_time_s = self.sim_time_s;
            patch.sim_step = self.steps;
            patch.layout = self.layout_generation;
        }
        // Stamped once the boxes are copied, just before the publication itself. NOTE: both
        // writers publish once per call, so their versions stay equal: the version stamped
        // here is the one each reader sees.
        self.track
            .published(self.to_graphics.version() + 1, self.clock.now_ns());
        let stroke_stamps = self.track.stamps();
        for w in [&mut self.to_haptic, &mut self.to_graphics] {
            w.back_mut().stroke_stamps = stroke_stamps;
            w.publish();
        }
        self.counters.snapshots_published(1);
        if std::mem::take(&mut self.changed_since_publish)
            && let Some(bell) = &self.graphics_wake
        {
            // After the publication: the tick it starts finds this snapshot.
            bell.ring();
        }
        if self.colour_dirty
            && self.steps >= self.colour_published_step + COLOUR_PUBLISH_EVERY_STEPS
        {
            self.publish_colour();
        }
        if self.mask_dirty {
            self.publish_mask();
        }
        self.publish_status();
    }

    /// The box of patch `n` a publication of the pending boxes and the region's box `region`
    /// (its patch and box) carries, clipped to the patch's lattice.
    fn box_to_publish(&self, n: usize, region: Option<(usize, CoeffBox)>) -> Option<CoeffBox> {
        let b = match (region, self.pending.get(n)?) {
            (Some((rp, r)), p) if rp == n => Some(p.map_or(r, |p| p.union(&r))),
            (_, p) => *p,
        }?;
        b.clipped(self.clay.density.patches.get(n)?.lattice.dims)
    }

    /// Coefficients a publication of the pending boxes and the region's box would carry.
    fn published_coefficients(&self, region: Option<(usize, CoeffBox)>) -> usize {
        (0..self.pending.len())
            .filter_map(|n| self.box_to_publish(n, region))
            .map(|b| b.dims().iter().product::<usize>())
            .fold(0, usize::saturating_add)
    }

    /// The most dense bricks a reader's copy may hold: the clay's when the copies were made
    /// and every brick the boxes published since reach (as owner or through its apron).
    fn reader_dense_bound(&self) -> usize {
        self.reader_reach
            .iter()
            .map(reach::Reach::brick_bound)
            .fold(self.reader_dense_at_layout, usize::saturating_add)
    }

    /// Copies the clay's freeze mask into the mask buffer and publishes it (the simulation
    /// loop may allocate; the haptic loop never sees this buffer).
    pub(super) fn publish_mask(&mut self) {
        let mask = &self.clay.mask;
        self.mask_out.write_with(|m| m.clone_from(mask));
        self.mask_dirty = false;
    }

    /// Copies the clay's paint into the colour buffer and publishes it (the simulation loop
    /// may allocate; the haptic loop never sees this buffer).
    pub(super) fn publish_colour(&mut self) {
        let paint = &self.clay.colour;
        self.colour.write_with(|c| c.clone_from(paint));
        self.colour_dirty = false;
        self.colour_published_step = self.steps;
    }

    /// Publishes the current field, and the paint if it changed, without stepping (used at
    /// shutdown so readers catch up).
    pub fn publish_now(&mut self) {
        self.publish();
        if self.colour_dirty {
            self.publish_colour();
        }
        if self.mask_dirty {
            self.publish_mask();
        }
    }

    /// The graphics loop's end of the paint publications (there is one; the second call gets
    /// `None`).
    pub fn take_colour_reader(&mut self) -> Option<SnapshotReader<Option<ColourField>>> {
        self.colour_reader.take()
    }

    /// The graphics loop's end of the mask publications (there is one; the second call gets
    /// `None`).
    pub fn take_mask_reader(&mut self) -> Option<SnapshotReader<Option<FreezeMask>>> {
        self.mask_reader.take()
    }

    /// The observers' end of this stage's [`SimStatus`] (there is one; the second call gets
    /// `None`).
    pub fn take_status_reader(&mut self) -> Option<SnapshotReader<SimStatus>> {
        self.status_reader.take()
    }

    pub(super) fn publish_status(&mut self) {
        // NOTE: the patch index is read only while a region is live: once it retired, a fold
        // or an undo may have removed that patch since.
        let region = self.region.as_ref().map(|r| {
            let lattice = &self.clay.density.patches[self.region_patch].lattice;
            let b = r.coeff_box();
            (
                lattice.node_position(b.min[0], b.min[1], b.min[2]),
                lattice.node_position(b.max[0], b.max[1], b.max[2]),
            )
        });
        *self.status.back_mut() = SimStatus {
            undo_steps: self.history.undo_len(),
            redo_steps: self.history.redo_len(),
            material: self.config.material,
            region,
            sessions_loaded: self.sessions_loaded,
            sim_step: self.steps,
            sim_time_s: self.sim_time_s,
            pins_revision: self.pins_revision,
            compact: self.compact_status(),
            removal_question: self.removal.question,
            dense_bricks: self.clay.dense_brick_count(),
            budget_refusal: self.budget_refusal,
        };
        self.status.publish();
    }
}

#[cfg(test)]
mod tests {
    use std::time::Instant;

    use super::*;

    /// `steps` haptic ticks, each followed by a simulation step with the tool idle.
    fn haptic_and_sim(s: &mut super::super::super::Stages, steps: usize) {
        for _ in 0..steps {
            s.haptic.tick(Instant::now());
            s.sim.apply_commands();
            s.sim.step(&ToolSample::IDLE);
        }
    }

    /// Changes past what one publication carries (every coefficient of a clay grown past
    /// [`MAX_UPDATE_COEFFS`]) reach the haptic loop as a copy of the clay; no snapshot buffer
    /// grows past the cap, and the loop ends with the simulation's clay.
    #[test]
    fn changes_past_the_update_cap_reach_the_loops_as_a_copy_and_no_buffer_grows() {
        let mut s = super::super::tests::stages_on_sphere(12);
        haptic_and_sim(&mut s, 2);
        // Grow the base to 268 × 140 × 140 coefficients (5.25 Mi), as a stroke far out would.
        s.sim.retire_region();
        let growth = s.sim.clay.grow([128, 64, 64]).unwrap();
        s.sim.history.regrid(&growth);
        s.sim.publish_layout();
        let coefficients = s.sim.clay.base().coeffs.len();
        assert!(coefficients > MAX_UPDATE_COEFFS, "{coefficients}");
        haptic_and_sim(&mut s, 3);
        assert_eq!(s.haptic.field().base().dims, growth.new_dims);
        let copies = s.counters.snapshot().updates_as_copies;
        // A change everywhere (what a failed edit or an undo marks): one copy, not a box of
        // every coefficient in each buffer.
        let far = [260, 130, 130];
        let at = s.sim.clay.base().index(far[0], far[1], far[2]);
        s.sim.clay.base_mut().coeffs.set_flat(at, 0.25);
        s.sim.mark_all_changed();
        haptic_and_sim(&mut s, 4);
        assert_eq!(s.counters.snapshot().updates_as_copies, copies + 1);
        for w in [&mut s.sim.to_haptic, &mut s.sim.to_graphics] {
            assert!(w.back_mut().coeffs.capacity() <= MAX_UPDATE_COEFFS);
        }
        assert_eq!(
            s.haptic.field().base().coeffs.get(far[0], far[1], far[2]),
            0.25
        );
        assert_eq!(s.haptic.field(), &s.sim.clay.density);
    }

    /// The readers' copies never free a brick a publication made dense: once the bricks the
    /// boxes published since their copies were made reach could take them past the clay's
    /// budget, they get a fresh, compact copy.
    #[test]
    fn readers_get_a_fresh_copy_before_their_bricks_could_pass_the_budget() {
        let mut s = super::super::tests::stages_on_sphere(12);
        haptic_and_sim(&mut s, 2);
        let copies = s.counters.snapshot().updates_as_copies;
        let change = CoeffBox {
            min: [2; 3],
            max: [9; 3],
        };
        // Far from the budget: boxes go as boxes, and the reach grows by theirs.
        s.sim.mark_changed(0, change);
        s.sim.publish();
        assert_eq!(s.counters.snapshot().updates_as_copies, copies);
        assert!(s.sim.reader_reach[0].contains_box(&change));
        let bound = s.sim.reader_dense_bound();
        assert!(
            bound >= s.sim.clay.density.dense_brick_count() + 8,
            "{bound}"
        );
        // Near it (as if the readers' copies had been made of a clay at its budget): the next
        // change goes as a copy and the count starts again from the clay's.
        s.sim.reader_dense_at_layout = MAX_DENSE_BRICKS - 1;
        s.sim.mark_changed(0, change);
        s.sim.publish();
        assert_eq!(s.counters.snapshot().updates_as_copies, copies + 1);
        assert_eq!(
            s.sim.reader_dense_at_layout,
            s.sim.clay.density.dense_brick_count()
        );
        assert!(s.sim.reader_dense_bound() < MAX_DENSE_BRICKS);
        haptic_and_sim(&mut s, 3);
        assert_eq!(s.haptic.field(), &s.sim.clay.density);
    }

    /// Two small edits far apart are bounded as two boxes, not as the box spanning both: on a
    /// clay near its budget they go as boxes, where their union would have sent a copy of
    /// the whole clay.
    #[test]
    fn edits_far_apart_near_the_budget_go_as_boxes() {
        let mut s = super::super::tests::stages_on_sphere(40);
        haptic_and_sim(&mut s, 2);
        let copies = s.counters.snapshot().updates_as_copies;
        let near = CoeffBox {
            min: [2; 3],
            max: [5; 3],
        };
        let far = CoeffBox {
            min: [32; 3],
            max: [35; 3],
        };
        // The two reach 1 + 8 bricks; the box spanning both, 125.
        s.sim.reader_dense_at_layout = MAX_DENSE_BRICKS - 50;
        s.sim.mark_changed(0, near);
        s.sim.publish();
        // Both readers take it, so the next edit is pending alone.
        for _ in 0..2 {
            s.haptic.tick(Instant::now());
            s.graphics.tick();
            s.sim.apply_commands();
            s.sim.step(&ToolSample::IDLE);
        }
        s.sim.mark_changed(0, far);
        s.sim.publish();
        assert_eq!(s.counters.snapshot().updates_as_copies, copies);
        assert!(s.sim.reader_dense_bound() < MAX_DENSE_BRICKS);
        assert!(s.sim.reader_reach[0].contains_box(&near));
        assert!(s.sim.reader_reach[0].contains_box(&far));
        haptic_and_sim(&mut s, 3);
        assert_eq!(s.haptic.field(), &s.sim.clay.density);
    }

    /// An edit refused for the clay's dense-brick budget is counted and published in the
    /// status with what and where, and leaves the clay as it was.
    #[test]
    fn a_refused_edit_is_counted_and_published_in_the_status() {
        let mut s = super::super::tests::stages_on_sphere(12);
        let mut status = s.sim.take_status_reader().unwrap();
        let whole = CoeffBox::whole(s.sim.clay.base().dims);
        // A small clay has room for a region over all of it …
        assert!(s.sim.clay.check_dense_room(density_id(0), whole).is_ok());
        // … and a clay at the budget has none.
        let refused = dynaclay_core::field::check_dense_room(
            dynaclay_core::field::MAX_DENSE_BRICKS,
            1,
            Some(whole),
        )
        .unwrap_err();
        let before = s.sim.clay.clone();
        s.sim.refuse_for_budget(refused);
        s.sim.publish();
        let published = status.latest().value;
        assert_eq!(published.budget_refusal, Some(refused.into()));
        assert_eq!(published.dense_bricks, s.sim.clay.dense_brick_count());
        assert!(published.dense_bricks > 0);
        assert_eq!(s.counters.snapshot().command_errors, 1);
        assert_eq!(s.counters.snapshot().budget_refusals, 1);
        assert_eq!(s.sim.last_budget_refusal(), Some(refused.into()));
        assert_eq!(s.sim.clay, before);
    }
}
