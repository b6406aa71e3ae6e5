//! The graphics stage: turns the newest field patch into re-meshed octree bricks and hands
//! them to a [`MeshSink`] (the GUI renderer, or the headless counter).
//!
//! A clay of one patch is meshed by marching cubes on the octree's grid, brick by brick. A
//! clay with detail patches is meshed by the multi-level mesher, each region at the spacing
//! of the finest patch holding detail there (the engine's cells per span of that level), and
//! the mesh is cut into the octree's bricks ([`AdaptiveBricks`]): the sink gets bricks as
//! before, closed across the seams between levels, and a stroke re-meshes and reports only
//! the bricks near it. A new patch layout (a refine, a fold) re-meshes and reports only the
//! bricks near the patches that came or went, unless it moves the mesher's frame (a level
//! finer than any before, a patch or a grown base beyond the clay's support: then the clay is
//! meshed whole once); a clay the multi-level mesher refuses (over its cell budget) is meshed
//! on the grid, as a clay of one patch is.
//!
//! Not real-time: meshing allocates. It never blocks the other loops: it reads the newest
//! patch wait-free and works on its own copy of the field.
//!
//! After handing the sink the meshes of a new snapshot it publishes a [`MeshStamp`] (which
//! snapshot the meshes hold, when they were ready, the newest stroke's stamps). Published
//! after the sink's meshes, so a frame that fetches the stamp first and the meshes second
//! draws meshes at least as new as the stamp says: a change is never counted visible before
//! a frame drew it.
//!
//! Changes too small to see are not re-meshed at once: while the clay relaxes after a push,
//! every snapshot moves the whole region's coefficients by a little, and re-meshing the
//! region for each would take the frame's CPU for nothing a frame can show. A snapshot whose
//! change, added to what is already held back, moves no coefficient by
//! [`DEFERRED_COEFF_TOLERANCE`] or more is applied to the stage's field but not meshed (its
//! stamp is not published either: the meshes still hold the older snapshot). The held-back
//! box is re-meshed, exactly, as soon as the sum reaches the tolerance, a snapshot brings a
//! stroke's first change or settled shape, or a snapshot brings no change (the motion has
//! stopped): the meshes of a clay at rest are those of a full re-mesh.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use std::collections::VecDeque;

use dynaclay_loops::{SnapshotReader, SnapshotWriter};

use super::clock::EngineClock;
use super::motion_to_photon::{MeshStamp, SETTLED_COEFF_TOLERANCE};

use super::counters::EngineCounters;
use super::layout::LayoutPort;
use super::update::{AppliedChange, FieldUpdate};
use dynaclay_core::field::MultiPatchField;
pub use dynaclay_core::mesh::MeshSink;
use dynaclay_core::mesh::{
    AdaptiveBricks, AdaptiveMeshOptions, BrickOctree, GridError, RefreshReport, SampleGrid,
};
use dynaclay_core::tools::{ColourField, FreezeMask};
use glam::Vec3;

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

/// How far, in coefficient units summed over snapshots, the clay may move before the graphics
/// loop re-meshes it: a quarter of [`SETTLED_COEFF_TOLERANCE`] (a fiftieth of a mesh cell of
/// surface motion on the default clay, see there), so held-back changes are far below what
/// a frame shows and delay the drawing of a stroke's settled shape by at most a quarter of
/// the motion that tolerance allows. A coefficient's change bounds the field's change
/// everywhere, and the sum of each snapshot's largest change bounds the change of any one
/// coefficient since the last re-mesh.
pub const DEFERRED_COEFF_TOLERANCE: f32 = SETTLED_COEFF_TOLERANCE / 4.0;

/// The graphics loop's state.
pub struct GraphicsStage {
    /// Boxed so that a new layout moves in by pointer (see [`super::layout`]).
    field: Box<MultiPatchField>,
    /// The layout generation of `field`.
    layout: u64,
    layouts: LayoutPort,
    octree: BrickOctree,
    updates: SnapshotReader<FieldUpdate>,
    /// The clay's paint, published by the simulation when it changes.
    colours: SnapshotReader<Option<ColourField>>,
    /// The clay's freeze mask, published by the simulation when it changes (none: the sink
    /// is never told of a mask).
    masks: Option<SnapshotReader<Option<FreezeMask>>>,
    ack: Arc<AtomicU64>,
    sink: Box<dyn MeshSink>,
    counters: EngineCounters,
    /// The engine's clock: when each snapshot's meshes were ready.
    clock: EngineClock,
    /// Where the stamp of the meshes handed over goes (to whoever draws frames).
    stamps: SnapshotWriter<MeshStamp>,
    /// The stamp published last.
    stamp: MeshStamp,
    /// (snapshot version, meshes ready) of the snapshots applied lately, oldest first: a
    /// stroke's settled snapshot is named only after its meshes were made.
    applied: VecDeque<(u64, u64)>,
    /// Changes applied to `field` but not re-meshed yet (see [`DEFERRED_COEFF_TOLERANCE`]).
    held_back: Option<HeldBack>,
    /// Cells per knot span of each level (the grid's, and the multi-level mesher's).
    cells_per_span: u32,
    /// The multi-level mesh cut into `octree`'s bricks, while the clay has detail patches
    /// (none: the bricks are marching cubes of the grid).
    levels: Option<AdaptiveBricks>,
}

/// Changes applied to the graphics stage's field and not re-meshed yet.
#[derive(Clone, Copy, Debug)]
struct HeldBack {
    /// Their box, with the sum of their snapshots' largest coefficient moves as
    /// `largest_move`.
    change: AppliedChange,
    /// The newest snapshot among them, and its stroke stamps.
    version: u64,
    strokes: super::StrokeStamps,
}

/// Snapshots remembered to find when a settled shape's meshes were ready (at 60 Hz, a minute;
/// a stroke is known settled well within a second of its meshes).
const APPLIED_KEPT: usize = 3600;

impl GraphicsStage {
    /// Builds the stage and meshes `field` in full; `cells_per_span` sets the resolution
    /// (cells per knot span: of the grid's spacing for marching cubes, of each level's for
    /// the multi-level mesh); paint arrives on `colours`, new patch layouts on `layouts`.
    ///
    /// # Errors
    /// When the sampling grid cannot be made for the lattice.
    #[allow(clippy::too_many_arguments)] // set-up only: each part is a distinct channel end
    pub fn new(
        field: MultiPatchField,
        layouts: LayoutPort,
        cells_per_span: u32,
        updates: SnapshotReader<FieldUpdate>,
        colours: SnapshotReader<Option<ColourField>>,
        ack: Arc<AtomicU64>,
        mut sink: Box<dyn MeshSink>,
        counters: EngineCounters,
        clock: EngineClock,
        stamps: SnapshotWriter<MeshStamp>,
    ) -> Result<Self, GridError> {
        let grid = SampleGrid::for_field(&field, cells_per_span)?;
        let mut octree = BrickOctree::new(grid);
        let (levels, report) = mesh_whole(&field, &level_mesh_options(cells_per_span), &mut octree);
        sink.update(&octree, &report);
        sink.field(&field);
        Ok(Self {
            cells_per_span,
            levels,
            field: Box::new(field),
            layout: 0,
            layouts,
            octree,
            updates,
            colours,
            masks: None,
            ack,
            sink,
            counters,
            clock,
            stamps,
            stamp: MeshStamp::default(),
            applied: VecDeque::with_capacity(APPLIED_KEPT),
            held_back: None,
        })
    }

    /// Hands the sink the clay's freeze mask from `masks` whenever it changes (for a sink
    /// that draws masked clay tinted).
    pub fn set_mask_reader(&mut self, masks: SnapshotReader<Option<FreezeMask>>) {
        self.masks = Some(masks);
    }

    /// Applies the newest patch if there is one and re-meshes what it changed (unless too
    /// small to see yet, see [`DEFERRED_COEFF_TOLERANCE`]), after handing the sink any new
    /// paint; returns the number of bricks re-meshed.
    pub fn tick(&mut self) -> usize {
        if let Some(paint) = self.colours.try_fresh() {
            self.sink.paint(&self.octree, paint.value.as_ref());
        }
        if let Some(mask) = self.masks.as_mut().and_then(SnapshotReader::try_fresh) {
            self.sink.mask(&self.octree, mask.value.as_ref());
        }
        // The new copy may hold changes beside the layout (a fold writes the base, and
        // snapshots this loop had not applied yet are in it): where the multi-level mesh is
        // re-meshed locally, they are found by comparing the copies.
        let compare = self.levels.is_some() || self.field.patches.len() == 1;
        let mut shared_change = None;
        let installed = self
            .layouts
            .install_inspecting(&mut self.field, |old, new| {
                if compare {
                    shared_change = new.shared_patches_change_box(old);
                }
            });
        if let Some(generation) = installed {
            // A new patch holds nothing yet and a grown base holds empty space where it grew:
            // the field is unchanged. The grid keeps the resolution the engine started with
            // and grows with the clay. The multi-level mesh follows the patches' layout: it
            // re-meshes the supports of the patches that came or went (the whole clay where
            // its frame moved), and a clay that gets its first detail patch or loses its last
            // one is meshed afresh.
            self.layout = generation;
            let regridded = !self.grid_covers_the_clay() && self.regrid();
            if !regridded {
                let detail = self.field.patches.len() > 1;
                if self.levels.is_some() && detail {
                    self.remesh_layout(shared_change);
                } else if self.levels.is_some() || detail {
                    // The first detail patch, or the last one gone (marching cubes again).
                    self.mesh_afresh();
                } else if let Some((lo, hi)) = shared_change {
                    // One patch before and after, its coefficients changed (a session loaded
                    // in place, changes this loop had not applied yet): marching cubes again
                    // where they did.
                    self.refresh_layout_change(lo, hi);
                }
            }
            self.sink.field(&self.field);
        }
        let stamped = self.updates.latest();
        if stamped.value.layout != self.layout
            || stamped.version == self.ack.load(Ordering::Relaxed)
        {
            // No new snapshot: whatever was held back is meshed now.
            if let Some(held) = self.held_back.take() {
                return self.remesh(held.change, held.version, held.strokes);
            }
            self.sink.idle(&self.field);
            return 0;
        }
        let change = stamped.value.apply_measured(&mut self.field);
        let (version, strokes) = (stamped.version, stamped.value.stroke_stamps);
        // NOTE: Release pairs with the simulation's Acquire load of the ack.
        self.ack.store(version, Ordering::Release);
        let held = match (self.held_back.take(), change) {
            (None, None) => {
                self.sink.idle(&self.field);
                self.publish_stamp(version, strokes);
                return 0;
            }
            // The motion has stopped: the held-back change is meshed, exactly.
            (Some(held), None) => return self.remesh(held.change, version, strokes),
            (None, Some(change)) => change,
            (Some(held), Some(change)) => AppliedChange {
                largest_move: held.change.largest_move + change.largest_move,
                ..held.change.union(&change)
            },
        };
        // A stroke's first change and its settled shape are shown as soon as they come.
        let news = strokes.stroke != self.stamp.stroke.stroke
            || strokes.first_change != self.stamp.stroke.first_change
            || strokes.settled != self.stamp.stroke.settled;
        if held.largest_move < DEFERRED_COEFF_TOLERANCE && !news {
            self.held_back = Some(HeldBack {
                change: held,
                version,
                strokes,
            });
            self.counters.graphics_deferred(1);
            self.sink.idle(&self.field);
            return 0;
        }
        self.remesh(held, version, strokes)
    }

    /// Re-meshes the box of `change`, hands the sink the meshes and publishes their stamp as
    /// those of snapshot `version` carrying `strokes`; returns the bricks re-meshed.
    fn remesh(
        &mut self,
        change: AppliedChange,
        version: u64,
        strokes: super::StrokeStamps,
    ) -> usize {
        let remeshed = self
            .levels
            .as_mut()
            .map(|levels| levels.remesh_box(&self.field, change.lo, change.hi, &mut self.octree));
        let report = match remeshed {
            Some(Ok(report)) => report,
            Some(Err(_)) => {
                // Over the multi-level mesher's budget: the grid meshes the clay.
                self.levels = None;
                self.octree.rebuild(&*self.field)
            }
            None => self.octree.refresh_box(&*self.field, change.lo, change.hi),
        };
        let n = report.changed.len() + report.removed.len();
        self.counters.graphics_updates(1);
        self.counters.bricks_remeshed(n as u64);
        self.sink.update(&self.octree, &report);
        self.sink.field(&self.field);
        self.publish_stamp(version, strokes);
        n
    }

    /// Publishes the stamp of the meshes of snapshot `version` just handed over, carrying
    /// `strokes` (the snapshot's stroke stamps) with when their changes' meshes were ready.
    fn publish_stamp(&mut self, version: u64, strokes: super::StrokeStamps) {
        let now = self.clock.now_ns();
        if self.applied.len() >= APPLIED_KEPT {
            self.applied.pop_front();
        }
        self.applied.push_back((version, now));
        let mut stamp = MeshStamp {
            snapshot_version: version,
            meshed_ns: now,
            stroke: strokes,
            ..MeshStamp::default()
        };
        if strokes.stroke == self.stamp.stroke.stroke {
            stamp.first_change_meshed_ns = self.stamp.first_change_meshed_ns;
            stamp.settled_meshed_ns = self.stamp.settled_meshed_ns;
        }
        let first_ready = |at: u64| {
            self.applied
                .iter()
                .find(|(v, _)| *v >= at)
                .map(|(_, ns)| *ns)
        };
        if stamp.first_change_meshed_ns.is_none()
            && let Some(first) = strokes.first_change
        {
            stamp.first_change_meshed_ns = first_ready(first.snapshot_version);
        }
        if stamp.settled_meshed_ns.is_none()
            && let Some(settled) = strokes.settled
        {
            stamp.settled_meshed_ns = first_ready(settled.snapshot_version);
        }
        self.stamp = stamp;
        *self.stamps.back_mut() = stamp;
        self.stamps.publish();
    }

    /// Whether the octree's grid still holds the support of every patch of the field.
    fn grid_covers_the_clay(&self) -> bool {
        let grid = self.octree.grid();
        let (lo, hi) = self.field.support();
        // A quarter cell of slack: the rounding of the corners' sums, never a brick.
        let slack = Vec3::splat(0.25 * grid.cell_size);
        let far = grid.point(grid.cells);
        lo.cmpge(grid.origin - slack).all() && hi.cmple(far + slack).all()
    }

    /// Meshes the clay afresh on a grid of the same cell size over its grown support, and
    /// tells the sink that every old brick went and every new one came (brick coordinates
    /// are counted from the grid's corner, which moved); false when no grid could hold the
    /// clay (nothing was meshed).
    fn regrid(&mut self) -> bool {
        let cell = self.octree.grid().cell_size;
        let (lo, hi) = self.field.support();
        let Ok(grid) = SampleGrid::covering(lo, hi, cell) else {
            // A clay too large for a grid keeps the old one (and its clipped mesh).
            return false;
        };
        let removed: Vec<[u32; 3]> = self.octree.bricks().map(|b| b.coord).collect();
        self.octree = BrickOctree::new(grid);
        // Everything is meshed afresh, held-back changes with the rest.
        self.held_back = None;
        let (levels, mut report) = mesh_whole(
            &self.field,
            &level_mesh_options(self.cells_per_span),
            &mut self.octree,
        );
        self.levels = levels;
        report.removed = removed;
        self.counters.graphics_updates(1);
        self.counters
            .bricks_remeshed((report.changed.len() + report.removed.len()) as u64);
        self.sink.update(&self.octree, &report);
        true
    }

    /// Meshes the clay afresh on the same grid (after a new patch layout) and hands the sink
    /// the bricks that changed or went.
    fn mesh_afresh(&mut self) {
        // Everything is meshed afresh, held-back changes with the rest.
        self.held_back = None;
        let (levels, report) = mesh_whole(
            &self.field,
            &level_mesh_options(self.cells_per_span),
            &mut self.octree,
        );
        self.levels = levels;
        self.counters.graphics_updates(1);
        self.counters
            .bricks_remeshed((report.changed.len() + report.removed.len()) as u64);
        self.sink.update(&self.octree, &report);
    }

    /// Re-meshes the marching cubes of a one-patch clay inside the world box `lo..=hi`,
    /// where a new copy of the clay differs from the one it replaced, and hands the sink the
    /// bricks that changed or went. Held-back changes stay held back.
    fn refresh_layout_change(&mut self, lo: Vec3, hi: Vec3) {
        let report = self.octree.refresh_box(&*self.field, lo, hi);
        self.counters.graphics_updates(1);
        self.counters
            .bricks_remeshed((report.changed.len() + report.removed.len()) as u64);
        self.sink.update(&self.octree, &report);
    }

    /// Re-meshes the multi-level mesh after a new patch layout (see
    /// [`AdaptiveBricks::remesh_layout`]), with `change` the box where the patches the old
    /// copy shared with the new one changed their coefficients, and hands the sink the bricks
    /// that changed or went. Held-back changes stay held back: outside them the mesh is of the
    /// field as it is.
    fn remesh_layout(&mut self, change: Option<(Vec3, Vec3)>) {
        let Some(levels) = self.levels.as_mut() else {
            return;
        };
        let remeshed = match change {
            Some((lo, hi)) => levels.remesh_box(&self.field, lo, hi, &mut self.octree),
            None => levels.remesh_layout(&self.field, &mut self.octree),
        };
        let report = match remeshed {
            Ok(report) => report,
            Err(_) => {
                // Over the multi-level mesher's budget: the grid meshes the clay.
                self.levels = None;
                self.held_back = None;
                self.octree.rebuild(&*self.field)
            }
        };
        self.counters.graphics_updates(1);
        self.counters
            .bricks_remeshed((report.changed.len() + report.removed.len()) as u64);
        self.sink.update(&self.octree, &report);
    }

    /// Whether the bricks hold the multi-level mesh (the clay has detail patches) rather
    /// than marching cubes of the grid.
    #[must_use]
    pub fn meshes_levels(&self) -> bool {
        self.levels.is_some()
    }

    /// This stage's field copy.
    #[must_use]
    pub fn field(&self) -> &MultiPatchField {
        &self.field
    }

    /// The octree.
    #[must_use]
    pub fn octree(&self) -> &BrickOctree {
        &self.octree
    }

    /// The sink, handed back when the engine stops to start again on another clay.
    #[must_use]
    pub fn into_sink(self) -> Box<dyn MeshSink> {
        self.sink
    }
}

/// The multi-level mesher's options for the stage: `cells_per_span` per knot span of the
/// base, half as many per knot span of a detail patch (at least the two every level needs),
/// and its default cell budget.
///
/// Why half on detail: a level-1 patch's span is half the base's, so at half the cells per
/// span its cells are the base's size, and each finer level's are half the coarser's: the
/// detail is never drawn coarser than the base, and each level is sampled at least twice per
/// knot span, as the export samples every level. At the window's 4 cells per base span, the
/// full 4 on a level-3 patch would be 32 cells per base span, and a stroke's local re-mesh
/// there, where strokes happen, does four times the work per span for relief its spline
/// resolves at two (`bench/RESULTS.md`, "The window's detail at two cells per span").
#[must_use]
pub fn level_mesh_options(cells_per_span: u32) -> AdaptiveMeshOptions {
    let cells_per_span = cells_per_span.max(2);
    AdaptiveMeshOptions {
        cells_per_span,
        detail_cells_per_span: (cells_per_span / 2).max(2),
        ..AdaptiveMeshOptions::default()
    }
}

/// Meshes `field` whole into `octree`: a clay with detail patches by the multi-level mesher
/// with `options` (returned, to re-mesh locally after), else (or where that mesher refuses
/// the clay, over its cell budget) by marching cubes on the octree's grid.
fn mesh_whole(
    field: &MultiPatchField,
    options: &AdaptiveMeshOptions,
    octree: &mut BrickOctree,
) -> (Option<AdaptiveBricks>, RefreshReport) {
    if field.patches.len() > 1
        && let Ok((levels, report)) = AdaptiveBricks::new(field, options, octree)
    {
        return (Some(levels), report);
    }
    (None, octree.rebuild(field))
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use dynaclay_devices::{SimArmConfig, SimulatedArm, Trajectory};
    use glam::Vec3;
    use parking_lot::Mutex;

    use super::super::{Command, EngineConfig, ToolSample, build, build_clay};
    use super::*;
    use dynaclay_core::field::BSplineLattice;
    use dynaclay_core::io::{ClayShape, ClaySpec};
    use dynaclay_core::tools::{GeometricTool, ToolAction, ToolPose, ToolShape};

    /// Keeps the last paint handed over.
    struct PaintSink(Arc<Mutex<Option<Option<ColourField>>>>);

    impl MeshSink for PaintSink {
        fn update(&mut self, _: &BrickOctree, _: &RefreshReport) {}
        fn paint(&mut self, _: &BrickOctree, colour: Option<&ColourField>) {
            *self.0.lock() = Some(colour.cloned());
        }
    }

    /// Keeps every report handed over.
    struct ReportSink(Arc<Mutex<Vec<RefreshReport>>>);

    impl MeshSink for ReportSink {
        fn update(&mut self, _: &BrickOctree, report: &RefreshReport) {
            self.0.lock().push(report.clone());
        }
    }

    /// Triangles of `mesh` whose centroid lies in `lo ..= hi`, and their mean edge length.
    fn triangles_in(mesh: &dynaclay_core::mesh::TriMesh, lo: Vec3, hi: Vec3) -> (usize, f32) {
        let (mut count, mut edges) = (0, 0.0);
        for t in &mesh.triangles {
            let p = t.map(|i| mesh.positions[i as usize]);
            let c = (p[0] + p[1] + p[2]) / 3.0;
            if c.cmpge(lo).all() && c.cmple(hi).all() {
                count += 1;
                edges += p[0].distance(p[1]) + p[1].distance(p[2]) + p[2].distance(p[0]);
            }
        }
        (count, edges / (3 * count.max(1)) as f32)
    }

    /// The stages on a sphere clay of `resolution` coefficients a side, with a simulated arm
    /// held away from it and `sink` in the graphics loop.
    struct SphereScene {
        s: super::super::Stages,
        config: EngineConfig,
        /// The starting clay.
        lattice: BSplineLattice,
        /// Its centre, and a point on its surface (the +x side, a quarter of its size out).
        centre: Vec3,
        surface: Vec3,
    }

    fn sphere_scene(resolution: usize, sink: Box<dyn MeshSink>) -> SphereScene {
        let lattice = build_clay(&ClaySpec {
            shape: ClayShape::Sphere,
            resolution,
            ..ClaySpec::default()
        })
        .unwrap();
        let size = (resolution - 1) as f32 * lattice.spacing;
        let config = EngineConfig::for_field(&lattice, &SimArmConfig::default_info());
        let centre = Vec3::splat(size * 0.5);
        let arm = SimulatedArm::with_trajectory(Trajectory::hold(Vec3::splat(-0.09)));
        let s = build(&config, lattice.clone(), Box::new(arm), sink, true).unwrap();
        SphereScene {
            s,
            config,
            lattice,
            centre,
            surface: centre + Vec3::new(size * 0.25, 0.0, 0.0),
        }
    }

    /// `steps` idle simulation steps, each followed by a graphics tick.
    fn run_idle(s: &mut super::super::Stages, steps: usize) {
        for _ in 0..steps {
            s.sim.apply_commands();
            s.sim.step(&ToolSample::IDLE);
            s.graphics.tick();
        }
    }

    /// A clay refined at level 2 and carved inside the patch: the sink's bricks weld into the
    /// multi-level mesh the export makes of the same clay (each level at its own spacing,
    /// finer inside the patch than the base's grid draws it), closed across the patch's
    /// seams; the carve re-meshed only bricks near it; undoing the patch's layout (a clay of
    /// one patch again) goes back to the grid's marching cubes.
    #[test]
    fn a_detail_patch_is_drawn_at_its_own_spacing_closed_and_re_meshed_locally() {
        use dynaclay_core::mesh::{MeshStats, mesh_adaptive};

        // Large enough for a carve to reach a small part of the bricks.
        let reports = Arc::new(Mutex::new(Vec::new()));
        let SphereScene {
            mut s,
            config,
            lattice: base,
            centre,
            surface,
        } = sphere_scene(24, Box::new(ReportSink(Arc::clone(&reports))));
        let spacing = base.spacing;
        let size = 23.0 * spacing;
        let run = run_idle;
        run(&mut s, 10);
        assert!(!s.graphics.meshes_levels(), "one patch: marching cubes");
        let grid_cells = s.graphics.octree().triangle_count();

        let half = Vec3::splat(1.2 * spacing);
        s.commands
            .send(Command::Refine {
                lo: surface - half,
                hi: surface + half,
                level: 2,
                reply: None,
            })
            .unwrap();
        run(&mut s, 10);
        assert_eq!(s.graphics.field().patches.len(), 2);
        assert!(
            s.graphics.meshes_levels(),
            "a detail patch: the levels' mesh"
        );
        let bricks = s.graphics.octree().brick_count();
        reports.lock().clear();

        // A carve a quarter of a base span wide, on the detail patch.
        let tool = GeometricTool {
            shape: ToolShape::Sphere {
                radius_fu: 0.25 * spacing,
            },
            action: ToolAction::Remove,
            falloff_fu: 0.05 * spacing,
        };
        s.commands
            .send(Command::ApplyTool {
                tool,
                poses: vec![ToolPose::at(surface)],
                duration_s: 0.1,
                patch: 1,
                reply: None,
            })
            .unwrap();
        run(&mut s, 300);
        assert_eq!(
            s.graphics.field().patches.len(),
            2,
            "the carve keeps its detail patch"
        );
        assert!(s.graphics.meshes_levels());

        // Local: every brick the carve re-meshed lies near it, and they are few.
        let octree = s.graphics.octree();
        let span = octree.grid().cell_size * dynaclay_core::mesh::BRICK_CELLS as f32;
        let mut touched: Vec<[u32; 3]> = reports
            .lock()
            .iter()
            .flat_map(|r| r.changed.iter().chain(&r.removed).copied())
            .collect();
        touched.sort_unstable();
        touched.dedup();
        assert!(!touched.is_empty(), "the carve reached the sink");
        let reach = 3.0 * spacing;
        for c in &touched {
            let lo = octree.grid().origin + span * Vec3::from_array(c.map(|v| v as f32));
            assert!(
                lo.cmple(surface + reach).all() && (lo + span).cmpge(surface - reach).all(),
                "brick {c:?} re-meshed far from the carve"
            );
        }
        assert!(
            touched.len() * 3 < bricks,
            "{} of {bricks} bricks re-meshed",
            touched.len()
        );

        // The bricks weld into the export's multi-level mesh, closed and oriented.
        let window = octree.weld();
        let stats = MeshStats::of(&window);
        assert_eq!(stats.boundary_edges, 0, "{stats:?}");
        assert_eq!(stats.misoriented_edges, 0, "{stats:?}");
        let exported = mesh_adaptive(
            s.graphics.field(),
            &level_mesh_options(config.cells_per_span),
        )
        .unwrap();
        assert_eq!(window.canonical_triangles(), exported.canonical_triangles());

        // Inside the patch it is finer than the base's grid draws the same clay.
        let grid = SampleGrid::for_lattice(&base, config.cells_per_span).unwrap();
        let uniform = BrickOctree::build(grid, s.graphics.field()).weld();
        let inner = Vec3::splat(0.8 * spacing);
        let (fine, fine_edge) = triangles_in(&window, surface - inner, surface + inner);
        let (coarse, coarse_edge) = triangles_in(&uniform, surface - inner, surface + inner);
        assert!(
            fine > 4 * coarse && fine_edge < 0.5 * coarse_edge,
            "{fine} triangles of edge {fine_edge} in the patch against {coarse} of {coarse_edge}"
        );
        assert!(window.triangle_count() > grid_cells);

        // A second patch of the same level on the far side: a new layout, re-meshed near the
        // new patch alone, and the bricks still weld into the multi-level mesh of the clay.
        reports.lock().clear();
        let far_side = centre - Vec3::new(size * 0.25, 0.0, 0.0);
        s.commands
            .send(Command::Refine {
                lo: far_side - half,
                hi: far_side + half,
                level: 2,
                reply: None,
            })
            .unwrap();
        run(&mut s, 10);
        assert_eq!(s.graphics.field().patches.len(), 3);
        let octree = s.graphics.octree();
        let touched: Vec<[u32; 3]> = reports
            .lock()
            .iter()
            .flat_map(|r| r.changed.iter().chain(&r.removed).copied())
            .collect();
        assert!(!touched.is_empty(), "the new patch's support was re-meshed");
        let (slo, shi) = s.graphics.field().patches[2].world_support();
        for c in &touched {
            let lo = octree.grid().origin + span * Vec3::from_array(c.map(|v| v as f32));
            assert!(
                lo.cmple(shi + reach).all() && (lo + span).cmpge(slo - reach).all(),
                "brick {c:?} re-meshed far from the new patch {slo} ..= {shi}"
            );
        }
        let window = octree.weld();
        let exported = mesh_adaptive(
            s.graphics.field(),
            &level_mesh_options(config.cells_per_span),
        )
        .unwrap();
        assert_eq!(window.canonical_triangles(), exported.canonical_triangles());

        // The detail taken away again: the carve undone (its patch emptied), then a smoothing
        // over each patch, which writes it and folds it (it holds nothing the base cannot). A
        // clay of one patch is drawn by marching cubes on the grid again.
        s.commands.send(Command::Undo).unwrap();
        run(&mut s, 10);
        let smooth = GeometricTool {
            shape: ToolShape::Sphere {
                radius_fu: 1.5 * spacing,
            },
            action: ToolAction::Smooth {
                rate_per_s: 1.0,
                kernel_fu: spacing,
            },
            falloff_fu: 0.25 * spacing,
        };
        for at in [surface, far_side] {
            s.commands
                .send(Command::ApplyTool {
                    tool: smooth.clone(),
                    poses: vec![ToolPose::at(at)],
                    duration_s: 0.1,
                    patch: 0,
                    reply: None,
                })
                .unwrap();
            run(&mut s, 300);
        }
        assert_eq!(s.graphics.field().patches.len(), 1, "both patches folded");
        assert!(
            !s.graphics.meshes_levels(),
            "one patch again: marching cubes"
        );
        let grid = *s.graphics.octree().grid();
        let fresh = BrickOctree::build(grid, s.graphics.field()).weld();
        assert_eq!(
            s.graphics.octree().weld().canonical_triangles(),
            fresh.canonical_triangles()
        );
    }

    /// A clay that starts with a detail patch holding detail (a loaded session) is drawn
    /// from the multi-level mesh from the first update: closed, and finer where the detail is.
    #[test]
    fn a_clay_that_starts_with_detail_is_drawn_from_its_levels() {
        let lattice = build_clay(&ClaySpec {
            shape: ClayShape::Sphere,
            resolution: 12,
            ..ClaySpec::default()
        })
        .unwrap();
        let spacing = lattice.spacing;
        let config = EngineConfig::for_field(&lattice, &SimArmConfig::default_info());
        let centre = Vec3::splat(11.0 * spacing * 0.5);
        let pole = centre + Vec3::new(11.0 * spacing * 0.25, 0.0, 0.0);
        let mut field = MultiPatchField::new(lattice.clone());
        let half = Vec3::splat(spacing);
        let detail = field.refine(pole - half, pole + half, 2).unwrap();
        // A dimple a quarter of a base span wide at the pole.
        let target = |x: Vec3| {
            lattice.value(x) - 0.3 * (-(x - pole).length_squared() / (0.06 * spacing)).exp()
        };
        field.fit_detail(detail, 2, target).unwrap();
        let arm = SimulatedArm::with_trajectory(Trajectory::hold(Vec3::splat(-0.09)));
        let s = build(
            &config,
            field.clone(),
            Box::new(arm),
            Box::new(HeadlessSink::default()),
            true,
        )
        .unwrap();
        assert!(s.graphics.meshes_levels());
        assert!(s.graphics.octree().is_cut());
        let window = s.graphics.octree().weld();
        let stats = dynaclay_core::mesh::MeshStats::of(&window);
        assert_eq!(stats.boundary_edges, 0, "{stats:?}");
        assert_eq!(stats.misoriented_edges, 0, "{stats:?}");
        let exported =
            dynaclay_core::mesh::mesh_adaptive(&field, &level_mesh_options(config.cells_per_span))
                .unwrap();
        assert_eq!(window.canonical_triangles(), exported.canonical_triangles());
        let inner = Vec3::splat(0.3 * spacing);
        let (_, fine_edge) = triangles_in(&window, pole - inner, pole + inner);
        let far = centre - Vec3::new(11.0 * spacing * 0.25, 0.0, 0.0);
        let (_, base_edge) = triangles_in(&window, far - inner, far + inner);
        assert!(
            fine_edge < 0.5 * base_edge,
            "edge {fine_edge} at the dimple against {base_edge} on the base"
        );
    }

    /// A clay with detail whose multi-level mesh would pass the cell budget is meshed by
    /// marching cubes on the grid instead: no multi-level mesher is kept, the octree is not
    /// cut, and its bricks weld into a closed mesh of the clay.
    #[test]
    fn a_clay_over_the_multi_level_budget_is_meshed_by_marching_cubes() {
        let lattice = build_clay(&ClaySpec {
            shape: ClayShape::Sphere,
            resolution: 12,
            ..ClaySpec::default()
        })
        .unwrap();
        let spacing = lattice.spacing;
        let pole = Vec3::splat(11.0 * spacing * 0.5) + Vec3::new(11.0 * spacing * 0.25, 0.0, 0.0);
        let mut field = MultiPatchField::new(lattice.clone());
        field
            .refine(pole - Vec3::splat(spacing), pole + Vec3::splat(spacing), 2)
            .unwrap();
        let mut octree = BrickOctree::new(SampleGrid::for_lattice(&lattice, 4).unwrap());
        let within = level_mesh_options(4);
        let (levels, _) = mesh_whole(&field, &within, &mut octree);
        assert!(
            levels.is_some() && octree.is_cut(),
            "within budget: multi-level"
        );

        let tight = AdaptiveMeshOptions {
            max_cells: 64,
            ..within
        };
        let mut octree = BrickOctree::new(SampleGrid::for_lattice(&lattice, 4).unwrap());
        let (levels, report) = mesh_whole(&field, &tight, &mut octree);
        assert!(levels.is_none(), "over budget: no multi-level mesher kept");
        assert!(!octree.is_cut());
        assert!(!report.changed.is_empty(), "the grid's bricks were meshed");
        let stats = dynaclay_core::mesh::MeshStats::of(&octree.weld());
        assert!(stats.triangles > 0);
        assert_eq!(stats.boundary_edges, 0, "{stats:?}");
    }

    /// A step that changes the clay rings the graphics loop's bell once it has published, and
    /// the tick it starts re-meshes the change; steps that change nothing do not ring.
    #[test]
    fn a_publication_that_changes_the_clay_wakes_the_graphics_loop_to_remesh_it() {
        let SphereScene {
            mut s,
            config,
            surface,
            ..
        } = sphere_scene(12, Box::new(HeadlessSink::default()));
        let (bell, waiter) = dynaclay_loops::wake_bell(config.graphics_max_rate_hz).unwrap();
        s.sim.set_graphics_wake(bell);
        for _ in 0..20 {
            s.sim.apply_commands();
            s.sim.step(&ToolSample::IDLE);
        }
        assert!(!waiter.is_rung(), "nothing changed, nothing rang");
        assert_eq!(s.graphics.tick(), 0, "and nothing to re-mesh");

        let tool = GeometricTool {
            shape: ToolShape::Sphere { radius_fu: 0.25 },
            action: ToolAction::Remove,
            falloff_fu: 0.1,
        };
        s.commands
            .send(Command::ApplyTool {
                tool,
                poses: vec![ToolPose::at(surface)],
                duration_s: 0.1,
                patch: 0,
                reply: None,
            })
            .unwrap();
        for _ in 0..200 {
            s.sim.apply_commands();
            s.sim.step(&ToolSample::IDLE);
            if waiter.is_rung() {
                break;
            }
        }
        assert!(waiter.is_rung(), "the publication of the cut rang");
        assert!(s.graphics.tick() > 0, "the woken tick re-meshed the cut");
    }

    /// A paint stroke applied by the simulation reaches the graphics loop's sink, and so does
    /// its undo.
    #[test]
    fn paint_travels_from_the_simulation_to_the_sink_and_undo_takes_it_back() {
        let seen = Arc::new(Mutex::new(None));
        let SphereScene { mut s, surface, .. } =
            sphere_scene(12, Box::new(PaintSink(Arc::clone(&seen))));
        let run = |s: &mut super::super::Stages| run_idle(s, 40);
        run(&mut s);
        assert!(seen.lock().is_none(), "no paint, no call");

        let tool = GeometricTool {
            shape: ToolShape::Sphere { radius_fu: 0.25 },
            action: ToolAction::Paint {
                rgb: [1.0, 0.0, 0.0],
            },
            falloff_fu: 0.2,
        };
        s.commands
            .send(Command::ApplyTool {
                tool,
                poses: vec![ToolPose::at(surface)],
                duration_s: 0.1,
                patch: 0,
                reply: None,
            })
            .unwrap();
        run(&mut s);
        let painted = seen.lock().clone().expect("paint handed over");
        let rgba = painted.expect("the clay carries colour").rgba(surface);
        assert!(rgba.w > 0.5 && rgba.x > 0.9, "red at the stroke: {rgba}");

        s.commands.send(Command::Undo).unwrap();
        run(&mut s);
        let after = seen.lock().clone().expect("undo handed over");
        let coverage = after.map_or(0.0, |c| c.rgba(surface).w);
        assert!(coverage < 0.01, "undo took the paint off: {coverage}");
    }
}
