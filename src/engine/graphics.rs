//! The graphics stage: turns the newest field patch into re-meshed octree bricks and hands
//! them to a [`MeshSink`] (the GUI renderer, or the headless counter).
//!
//! Not real-time: meshing allocates. It never blocks the other loops: it reads the newest
//! patch wait-free and works on its own copy of the field.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use dynaclay_loops::SnapshotReader;

use super::counters::EngineCounters;
use super::patch::FieldPatch;
use crate::field::BSplineLattice;
use crate::mesh::{BrickOctree, GridError, RefreshReport, SampleGrid};

/// Receives the meshes after every update. Implemented by the GUI's renderer bridge and by
/// [`HeadlessSink`].
pub trait MeshSink: Send {
    /// Called once the octree was refreshed; `report` lists the bricks that changed.
    fn update(&mut self, octree: &BrickOctree, report: &RefreshReport);
}

/// A sink that only counts (headless runs export the final mesh separately).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct HeadlessSink {
    /// Updates received.
    pub updates: u64,
    /// Bricks changed over all updates.
    pub bricks_changed: u64,
    /// Triangles in the latest mesh.
    pub triangles: usize,
}

impl MeshSink for HeadlessSink {
    fn update(&mut self, octree: &BrickOctree, report: &RefreshReport) {
        self.updates += 1;
        self.bricks_changed += report.changed.len() as u64 + report.removed.len() as u64;
        self.triangles = octree.triangle_count();
    }
}

/// The graphics loop's state.
pub struct GraphicsStage {
    field: BSplineLattice,
    octree: BrickOctree,
    patches: SnapshotReader<FieldPatch>,
    ack: Arc<AtomicU64>,
    sink: Box<dyn MeshSink>,
    counters: EngineCounters,
}

impl GraphicsStage {
    /// Builds the stage and meshes `field` in full; `cells_per_span` sets the marching-cubes
    /// resolution (cells per knot span).
    ///
    /// # Errors
    /// When the sampling grid cannot be made for the lattice.
    pub fn new(
        field: BSplineLattice,
        cells_per_span: u32,
        patches: SnapshotReader<FieldPatch>,
        ack: Arc<AtomicU64>,
        mut sink: Box<dyn MeshSink>,
        counters: EngineCounters,
    ) -> Result<Self, GridError> {
        let grid = SampleGrid::for_lattice(&field, cells_per_span)?;
        let mut octree = BrickOctree::new(grid);
        let report = octree.rebuild(&field);
        sink.update(&octree, &report);
        Ok(Self {
            field,
            octree,
            patches,
            ack,
            sink,
            counters,
        })
    }

    /// Applies the newest patch if there is one and re-meshes what it changed; returns the
    /// number of bricks re-meshed.
    pub fn tick(&mut self) -> usize {
        let Some(stamped) = self.patches.try_fresh() else {
            return 0;
        };
        let changed = stamped.value.apply_to(&mut self.field);
        // NOTE: Release pairs with the simulation's Acquire load of the ack.
        self.ack.store(stamped.version, Ordering::Release);
        let Some(b) = changed else {
            return 0;
        };
        let (lo, hi) = BrickOctree::coefficient_change_box(&self.field, b.min, b.max);
        let report = self.octree.refresh_lattice(&self.field, lo, hi);
        let n = report.changed.len() + report.removed.len();
        self.counters.graphics_updates(1);
        self.counters.bricks_remeshed(n as u64);
        self.sink.update(&self.octree, &report);
        n
    }

    /// This stage's field copy.
    #[must_use]
    pub fn field(&self) -> &BSplineLattice {
        &self.field
    }

    /// The octree.
    #[must_use]
    pub fn octree(&self) -> &BrickOctree {
        &self.octree
    }
}
