//! Publication: the changed box of the field to the haptic and graphics loops (with the
//! acknowledgement protocol that lets the simulation reuse a buffer once both have copied it),
//! the paint at a throttled rate, and the status for observers.

#[allow(clippy::wildcard_imports)] // the stage's own module: its types and imports
use super::*;

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

    /// Coefficients a publication of the pending boxes and the region's box `region` (its
    /// patch and box) would carry, each box clipped to its lattice.
    fn published_coefficients(&self, region: Option<(usize, CoeffBox)>) -> usize {
        let patches = &self.clay.density.patches;
        self.pending
            .iter()
            .enumerate()
            .filter_map(|(n, pending)| {
                let b = match (region, pending) {
                    (Some((rp, r)), p) if rp == n => Some(p.map_or(r, |p| p.union(&r))),
                    (_, p) => *p,
                }?;
                let clipped = b.clipped(patches.get(n)?.lattice.dims)?;
                Some(clipped.dims().iter().product::<usize>())
            })
            .fold(0, usize::saturating_add)
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
