//! Particles that follow the clay while it is sculpted, in the graphics loop: a [`MeshSink`]
//! wrapper that, each time the graphics loop hands over its refreshed field copy, takes a fixed
//! budget of particle steps on it and publishes the positions through a triple buffer that a
//! viewer reads wait-free.
//!
//! The haptic loop never waits on it: the work runs on the graphics thread, after that loop's
//! own meshing, on the copy the graphics loop already keeps, and publication is a wait-free
//! buffer swap. The budget is a step count (`steps_per_update`), so the work per update is
//! bounded by `steps_per_update` PDS steps of `N` particles whatever the clay does. The count
//! `N` is read from an atomic that a viewer may set at any time, and a second atomic turns the
//! particles on and off: off, an update only forwards to the wrapped sink (the particles are
//! dropped and an empty view published once), so a follower that is off costs nothing.
//!
//! The graphics loop hands over a new copy only when the clay changes; on its idle ticks it
//! calls [`MeshSink::idle`], where the follower takes up to `settle_updates` more updates
//! after each change (of the clay, of `N`, or turning on), so particles settle on a still clay
//! and then stop costing anything.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use dynaclay_loops::{SnapshotReader, SnapshotWriter, snapshot_channel};
use glam::Vec3;

use super::system::{ParticleError, ParticleParams, ParticleSystem};
use crate::particles::ImplicitSurface;
use dynaclay_core::field::MultiPatchField;
use dynaclay_core::mesh::{BrickOctree, MeshSink, RefreshReport};
use dynaclay_core::tools::ColourField;

/// What a viewer draws: each particle's position, outward unit normal and world radius.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ParticleView {
    /// Particle positions.
    pub positions: Vec<Vec3>,
    /// Outward unit normals (the discs' orientation).
    pub normals: Vec<Vec3>,
    /// Repulsion radii `σᵢ` in world units (the discs' size).
    pub radii: Vec<f32>,
    /// Field updates followed so far.
    pub updates: u64,
}

/// A [`MeshSink`] that passes everything to `inner` and moves particles along with the clay.
pub struct ParticleFollower<S: MeshSink> {
    inner: S,
    system: ParticleSystem,
    steps_per_update: usize,
    seed: u64,
    count: Arc<AtomicUsize>,
    /// Whether particles are shown; off, updates only forward to `inner`.
    on: Arc<AtomicBool>,
    /// Whether the last update ran with the particles on.
    was_on: bool,
    /// Idle updates still to take after the last change.
    idle_left: usize,
    /// Idle updates taken after each change.
    settle_updates: usize,
    writer: SnapshotWriter<ParticleView>,
    updates: u64,
    /// The last failure to place particles (the clay had no surface), if any.
    last_error: Option<ParticleError>,
}

impl<S: MeshSink> ParticleFollower<S> {
    /// Follows with `count` particles and `steps_per_update` steps per field update; returns
    /// the follower and the reader a viewer draws from.
    ///
    /// # Errors
    /// [`ParticleError::ZeroCount`] for `count == 0`.
    pub fn new(
        inner: S,
        count: usize,
        steps_per_update: usize,
    ) -> Result<(Self, SnapshotReader<ParticleView>), ParticleError> {
        if count == 0 {
            return Err(ParticleError::ZeroCount);
        }
        let (writer, reader) = snapshot_channel(&ParticleView::default());
        let follower = Self::with_handles(
            inner,
            writer,
            Arc::new(AtomicUsize::new(count)),
            Arc::new(AtomicBool::new(true)),
            steps_per_update,
        );
        Ok((follower, reader))
    }

    /// Follows with the count and the on/off switch a viewer already holds, publishing on
    /// `writer`; `N` starts at the count's value (at least 1).
    #[must_use]
    pub fn with_handles(
        inner: S,
        writer: SnapshotWriter<ParticleView>,
        count: Arc<AtomicUsize>,
        on: Arc<AtomicBool>,
        steps_per_update: usize,
    ) -> Self {
        let n = count.load(Ordering::Relaxed).max(1);
        let system = ParticleSystem::new(ParticleParams::new(n))
            .unwrap_or_else(|e| unreachable!("a count of at least 1 is valid: {e}"));
        Self {
            inner,
            system,
            steps_per_update,
            seed: 1,
            count,
            on,
            was_on: false,
            idle_left: 0,
            settle_updates: Self::SETTLE_UPDATES,
            writer,
            updates: 0,
            last_error: None,
        }
    }

    /// Idle updates taken after each change, by default.
    pub const SETTLE_UPDATES: usize = 60;

    /// Sets how many idle updates follow each change (0: particles move only when the clay
    /// changes).
    pub fn set_settle_updates(&mut self, updates: usize) {
        self.settle_updates = updates;
    }

    /// The switch a viewer stores `false` in to drop the particles and stop the work, `true`
    /// to start again (from a fresh seeding).
    #[must_use]
    pub fn switch_handle(&self) -> Arc<AtomicBool> {
        Arc::clone(&self.on)
    }

    /// The particle count `N` the follower reads before each update; a viewer stores a new
    /// value (0 is ignored).
    #[must_use]
    pub fn count_handle(&self) -> Arc<AtomicUsize> {
        Arc::clone(&self.count)
    }

    /// The wrapped sink.
    #[must_use]
    pub fn inner(&self) -> &S {
        &self.inner
    }

    /// The particles.
    #[must_use]
    pub fn particles(&self) -> &ParticleSystem {
        &self.system
    }

    /// Why the particles could not be placed at the last update, if they could not.
    #[must_use]
    pub fn last_error(&self) -> Option<&ParticleError> {
        self.last_error.as_ref()
    }

    /// One update on `field`: the count from the handle, a seeded start if there are no
    /// particles, `steps_per_update` steps, a projection onto the surface, and publication.
    /// Switched off, it drops the particles and publishes an empty view (once) instead.
    pub fn follow(&mut self, field: &MultiPatchField) {
        if !self.on.load(Ordering::Relaxed) {
            self.was_on = false;
            self.idle_left = 0;
            if !self.system.is_empty() || self.updates == 0 {
                self.system.from_positions(&[], 0.0);
                self.updates += 1;
                let updates = self.updates;
                self.writer.write_with(|view| {
                    view.positions.clear();
                    view.normals.clear();
                    view.radii.clear();
                    view.updates = updates;
                });
            }
            return;
        }
        self.was_on = true;
        let wanted = self.count.load(Ordering::Relaxed);
        if wanted > 0 && wanted != self.system.params().target_count {
            // NOTE: only a zero count is refused, and it is excluded above.
            let _ = self.system.set_target_count(wanted);
        }
        self.last_error = None;
        if self.system.is_empty() {
            let n = self.system.params().target_count;
            if let Err(e) = self.system.seed_random(field, n, self.seed) {
                self.last_error = Some(e);
            }
            self.seed += 1;
        }
        if !self.system.is_empty() {
            for _ in 0..self.steps_per_update {
                // NOTE: `step` refuses only a bad `dt`, and DEFAULT_DT is valid.
                let _ = self.system.step(field, ParticleSystem::DEFAULT_DT);
            }
            self.system.project(field, 2);
        }
        self.updates += 1;
        let (system, updates) = (&self.system, self.updates);
        self.writer.write_with(|view| {
            view.positions.clear();
            view.positions.extend_from_slice(system.positions());
            view.normals.clear();
            view.normals.extend(
                system
                    .positions()
                    .iter()
                    .map(|p| -field.eval(*p).1.normalize_or_zero()),
            );
            view.radii.clear();
            view.radii.extend(
                system
                    .sigmas()
                    .iter()
                    .zip(system.wanted_density())
                    .map(|(s, d)| s / d.sqrt()),
            );
            view.updates = updates;
        });
    }
}

impl<S: MeshSink> MeshSink for ParticleFollower<S> {
    fn update(&mut self, octree: &BrickOctree, report: &RefreshReport) {
        self.inner.update(octree, report);
    }

    fn paint(&mut self, octree: &BrickOctree, colour: Option<&ColourField>) {
        self.inner.paint(octree, colour);
    }

    fn field(&mut self, field: &MultiPatchField) {
        self.inner.field(field);
        self.follow(field);
        self.idle_left = self.settle_updates;
    }

    /// The clay is replaced (the engine restarts on another one): the inner sink forgets its
    /// meshes, and the particles, which sat on the old clay, are dropped so that they are
    /// seeded afresh on the new one.
    fn restart(&mut self) {
        self.inner.restart();
        if let Ok(fresh) = ParticleSystem::new(*self.system.params()) {
            self.system = fresh;
        }
        self.idle_left = self.settle_updates;
    }

    /// Settles the particles on a still clay: up to `settle_updates` updates after each change
    /// of the clay, of `N` or of the switch; nothing otherwise.
    fn idle(&mut self, field: &MultiPatchField) {
        self.inner.idle(field);
        let on = self.on.load(Ordering::Relaxed);
        if !on {
            if self.was_on {
                self.follow(field);
            }
            return;
        }
        let wanted = self.count.load(Ordering::Relaxed);
        if !self.was_on || (wanted > 0 && wanted != self.system.params().target_count) {
            self.idle_left = self.settle_updates;
        }
        if self.idle_left > 0 {
            self.idle_left -= 1;
            self.follow(field);
        }
    }
}
