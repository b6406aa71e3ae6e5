//! The sparse brick octree: bricks of 8³ cells exist only where the surface crosses them, so
//! memory grows with the surface's area, not the grid's volume, and a 512³ virtual grid costs
//! what its surface costs.
//!
//! Representation: a linear octree. Leaves (bricks) live in a `BTreeMap` keyed by the Morton
//! code of the brick coordinate, so every octree node's bricks form one contiguous key range;
//! interior nodes are implicit. Extraction descends from the root and skips any node whose
//! field bound ([`ScalarField::bounds`]) shows it is all inside or all outside; only bricks
//! that survive are sampled and meshed.
//!
//! A local refresh runs the same descent, restricted to the bricks a changed box touches and
//! starting at the octree level whose nodes are the size of the box. Each brick's samples and mesh depend only
//! on the brick and the field, and a culled node holds no surface (bounds are never tighter
//! than the true range), so a refresh yields exactly the bricks and meshes a full rebuild
//! would.
//!
//! Not real-time: this runs on the graphics thread and allocates.

use std::collections::{BTreeMap, HashMap};
use std::hash::{BuildHasherDefault, Hasher};
use std::sync::{Mutex, TryLockError};

use glam::Vec3;

use super::brick::{
    BRICK_CELLS, BRICK_SAMPLES, BrickMesh, BrickScratch, Face, MAX_BRICK_INDICES,
    SHARED_VERTEX_AXIS, brick_extent, edge_from_id, march_brick, sample_brick,
    sample_brick_sharing, upper_face,
};
use super::grid::SampleGrid;
use super::source::ScalarField;
use super::trimesh::TriMesh;
use super::work_split::WorkSplit;
use crate::field::BSplineLattice;

/// One stored brick: its mesh.
///
/// Its corner samples are not kept: every refresh samples the bricks it re-meshes again
/// (the field changed there), and nothing else reads them, so keeping them would only cost
/// 2.9 KB, an allocation and a copy per brick.
#[derive(Clone, Debug, PartialEq)]
pub struct Brick {
    /// Brick coordinate: the brick covers cells `coord · 8 .. coord · 8 + 8` per axis.
    pub coord: [u32; 3],
    pub mesh: BrickMesh,
    /// The octree generation in which this brick's mesh was last rebuilt.
    pub version: u64,
    /// How many of its vertices a weld takes from this brick rather than from a brick below
    /// it (see [`super::weld`]), counted when it was meshed: a weld on several threads knows
    /// where each brick's vertices go from these counts alone.
    pub(super) owned_vertices: u32,
}

impl Brick {
    /// A brick with no mesh yet.
    fn empty(coord: [u32; 3]) -> Self {
        Self {
            coord,
            mesh: BrickMesh::default(),
            version: 0,
            owned_vertices: 0,
        }
    }

    /// Meshes this brick, whose samples were just taken into `scratch`, and keeps its
    /// mesh, marked rebuilt in `generation`. A stored brick is meshed in its own buffers
    /// (lent to the scratch for the march); a new brick gets buffers the size of its mesh.
    fn remesh<F: ScalarField + ?Sized>(
        &mut self,
        field: &F,
        grid: &SampleGrid,
        scratch: &mut BrickScratch,
        generation: u64,
    ) {
        let reuse = self.mesh.positions.capacity() > 0;
        if reuse {
            std::mem::swap(&mut self.mesh, &mut scratch.mesh);
        }
        march_brick(field, grid, self.coord, scratch);
        if reuse {
            std::mem::swap(&mut self.mesh, &mut scratch.mesh);
            self.mesh.trim();
        } else {
            self.mesh.copy_from(&scratch.mesh);
        }
        self.version = generation;
        self.owned_vertices = scratch.owned_vertices;
    }
}

/// What a build or refresh changed, for a renderer that uploads only dirty bricks.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct RefreshReport {
    /// The generation the changed bricks now carry.
    pub generation: u64,
    /// Bricks whose mesh was rebuilt (new or replaced).
    pub changed: Vec<[u32; 3]>,
    /// Bricks that no longer exist (the surface left them).
    pub removed: Vec<[u32; 3]>,
    /// Bricks whose samples were evaluated.
    pub bricks_sampled: usize,
}

/// Memory held by an octree, in bytes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MemoryUsage {
    /// Per-brick mesh buffers (capacity).
    pub mesh_bytes: usize,
    /// Tree nodes, brick headers and scratch (estimated for the B-tree's node slack).
    pub structure_bytes: usize,
}

impl MemoryUsage {
    /// Everything together.
    #[must_use]
    pub fn total_bytes(&self) -> usize {
        self.mesh_bytes + self.structure_bytes
    }
}

/// A sparse octree of surface bricks over a [`SampleGrid`].
#[derive(Clone, Debug)]
pub struct BrickOctree {
    grid: SampleGrid,
    pub(super) bricks: BTreeMap<u64, Brick>,
    /// Bricks per axis (the last may be partial).
    pub(super) brick_counts: [u32; 3],
    /// The root covers `root_size` bricks per axis (a power of two).
    root_size: u32,
    generation: u64,
    scratch: BrickScratch,
    rebuild_scratch: RebuildScratch,
    /// The bricks hold the pieces of a multi-level mesh cut along the bricks' bounds
    /// ([`super::AdaptiveBricks`]), not marching cubes of the grid: they are welded by vertex
    /// id, and a refresh rebuilds them all.
    cut: bool,
}

impl BrickOctree {
    /// An empty octree over `grid`.
    #[must_use]
    pub fn new(grid: SampleGrid) -> Self {
        let brick_counts = grid.cells.map(|c| c.div_ceil(BRICK_CELLS));
        let root_size = brick_counts
            .iter()
            .copied()
            .max()
            .unwrap_or(1)
            .next_power_of_two();
        Self {
            grid,
            bricks: BTreeMap::new(),
            brick_counts,
            root_size,
            generation: 0,
            scratch: BrickScratch::default(),
            rebuild_scratch: RebuildScratch::default(),
            cut: false,
        }
    }

    /// How many bricks [`BrickOctree::build`] would sample for `field` on `grid`, counted
    /// without sampling anything: the same walk down the tree, pruned by the same
    /// [`ScalarField::bounds`], so it costs a small part of a build and allocates nothing.
    /// `None` as soon as the count passes `limit` (or the walk visits more than `16 × limit`
    /// nodes), so a grid far too large for memory is refused in bounded time.
    #[must_use]
    pub fn count_sampled_bricks<F: ScalarField + ?Sized>(
        grid: &SampleGrid,
        field: &F,
        limit: u64,
    ) -> Option<u64> {
        let shape = Self::new(*grid);
        let mut walk = CountWalk {
            tree: &shape,
            field,
            iso: field.iso(),
            sampled: 0,
            visited: 0,
            limit,
        };
        walk.visit([0; 3], shape.root_size).then_some(walk.sampled)
    }

    /// Extracts the whole surface of `field` on `grid`.
    pub fn build<F: ScalarField + ?Sized>(grid: SampleGrid, field: &F) -> Self {
        let mut tree = Self::new(grid);
        tree.rebuild(field);
        tree
    }

    /// Re-meshes everything (every brick of the result carries the new generation).
    ///
    /// The descent lists the bricks to sample; they are then built with x fastest, then y,
    /// then z, each taking the faces it shares with the bricks below it from them. A brick
    /// that is stored already is rebuilt in its own buffers (no allocation when its mesh
    /// fits them), so rebuilding a tree costs less than building a new one.
    pub fn rebuild<F: ScalarField + ?Sized>(&mut self, field: &F) -> RefreshReport {
        self.rebuild_on(field, |field, grid, counts, generation, jobs| {
            let mut all = Some(jobs);
            build_runs(field, grid, counts, generation, || all.take())
        })
    }

    /// [`BrickOctree::build`] with the bricks split over `threads` threads (1 or more):
    /// identical bricks and meshes, in a fraction of the time on a large grid.
    pub fn build_with_threads<F: ScalarField + Sync + ?Sized>(
        grid: SampleGrid,
        field: &F,
        threads: usize,
    ) -> Self {
        let mut tree = Self::new(grid);
        tree.rebuild_with_threads(field, threads);
        tree
    }

    /// [`BrickOctree::rebuild`] with the bricks split over `threads` threads; the result
    /// (bricks, meshes and report) is identical. The descent runs first on the caller and
    /// lists the bricks to sample; the threads then build them, each along a stretch of the
    /// build order, and one that runs out takes half of the largest stretch left.
    pub fn rebuild_with_threads<F: ScalarField + Sync + ?Sized>(
        &mut self,
        field: &F,
        threads: usize,
    ) -> RefreshReport {
        self.rebuild_on(field, |field, grid, counts, generation, jobs| {
            build_bricks_parallel(field, grid, counts, generation, jobs, threads)
        })
    }

    /// The rebuild, with the bricks to sample (in build order, see [`lend_in_build_order`])
    /// built by `build`, which marks each brick it finds crossed by the surface, rebuilds a
    /// stored one in place and returns the new ones. The result is that of the descent of
    /// [`BrickOctree::visit`] from the root.
    ///
    /// Only the bricks the surface crosses are kept in the tree: a brick to sample that is
    /// not stored is made only once the builder finds the surface in it, so the many empty
    /// bricks of a build without bounds cost the tree nothing. What runs on the caller alone
    /// (the descent, the lending, the bookkeeping after) is kept small, in buffers kept
    /// between rebuilds, since the other threads wait for it.
    fn rebuild_on<F: ScalarField + ?Sized>(
        &mut self,
        field: &F,
        build: impl FnOnce(&F, &SampleGrid, [u32; 3], u64, &mut [BrickJob<'_>]) -> Vec<Brick>,
    ) -> RefreshReport {
        self.cut = false;
        self.generation += 1;
        let generation = self.generation;
        let mut report = RefreshReport {
            generation,
            ..RefreshReport::default()
        };
        let mut scratch = std::mem::take(&mut self.rebuild_scratch);
        let RebuildScratch {
            leaves,
            culls,
            outcome,
            cells,
        } = &mut scratch;
        leaves.clear();
        culls.clear();
        let last = self.brick_counts.map(|c| c - 1);
        self.plan(field, [0; 3], self.root_size, ([0; 3], last), leaves, culls);
        let mut jobs = lend_in_build_order(leaves, self.brick_counts, &mut self.bricks, cells);
        let grid = self.grid;
        let fresh = build(field, &grid, self.brick_counts, generation, &mut jobs);
        // Per leaf: crossed (kept with the new generation), and whether it was stored.
        outcome.clear();
        outcome.resize(leaves.len(), (false, false));
        for job in &jobs {
            outcome[job.leaf as usize] = (job.crossed, job.stored.is_some());
        }
        drop(jobs);
        for brick in fresh {
            self.bricks.insert(morton(brick.coord), brick);
        }
        // Removals in the order of the descent: each culled node after the leaves met
        // before it.
        let mut culls_left = culls.iter().peekable();
        for (leaf, (&node, &(crossed, stored))) in leaves.iter().zip(outcome.iter()).enumerate() {
            while let Some(cull) = culls_left.next_if(|c| c.leaves_before as usize <= leaf) {
                self.remove_range(cull.node, cull.size, (cull.lo, cull.hi), &mut report);
            }
            report.bricks_sampled += 1;
            if crossed {
                report.changed.push(node);
            } else if stored {
                self.bricks.remove(&morton(node));
                report.removed.push(node);
            }
        }
        for cull in culls_left {
            self.remove_range(cull.node, cull.size, (cull.lo, cull.hi), &mut report);
        }
        self.rebuild_scratch = scratch;
        report
    }

    /// The descent of [`BrickOctree::visit`] from the root without building anything: the
    /// bricks to sample and the culled nodes, in the order `visit` meets them (the leaves
    /// in Morton order).
    fn plan<F: ScalarField + ?Sized>(
        &self,
        field: &F,
        node: [u32; 3],
        size: u32,
        query: ([u32; 3], [u32; 3]),
        leaves: &mut Vec<[u32; 3]>,
        culls: &mut Vec<CulledNode>,
    ) {
        let lo: [u32; 3] = std::array::from_fn(|a| node[a].max(query.0[a]));
        let hi: [u32; 3] = std::array::from_fn(|a| {
            (node[a] + size - 1)
                .min(query.1[a])
                .min(self.brick_counts[a] - 1)
        });
        if (0..3).any(|a| lo[a] > hi[a]) {
            return;
        }
        if self.culled(field, node, size) {
            culls.push(CulledNode {
                node,
                size,
                lo,
                hi,
                leaves_before: leaves.len() as u32,
            });
            return;
        }
        if size == 1 {
            leaves.push(node);
            return;
        }
        let half = size / 2;
        for child in 0..8u32 {
            let c = [
                node[0] + (child & 1) * half,
                node[1] + ((child >> 1) & 1) * half,
                node[2] + ((child >> 2) & 1) * half,
            ];
            self.plan(field, c, half, query, leaves, culls);
        }
    }

    /// Whether the field's bound shows node (`node`, `size`) all inside or all outside.
    fn culled<F: ScalarField + ?Sized>(&self, field: &F, node: [u32; 3], size: u32) -> bool {
        // The node's own box (not clipped to the query), so decisions repeat between passes.
        let node_hi: [u32; 3] =
            std::array::from_fn(|a| ((node[a] + size) * BRICK_CELLS).min(self.grid.cells[a]));
        let pmin = self.grid.point(node.map(|n| n * BRICK_CELLS));
        let pmax = self.grid.point(node_hi);
        field.bounds(pmin, pmax).is_some_and(|(vmin, vmax)| {
            let iso = field.iso();
            let margin = 1e-5 * iso.abs().max(1.0);
            vmax < iso - margin || vmin > iso + margin
        })
    }

    /// Re-meshes the bricks that hold a sample strictly inside the world box `min..max` (those
    /// it touches and, through shared faces, their neighbours), creating and removing bricks
    /// as the surface enters or leaves them.
    ///
    /// The field must be unchanged on and outside the box's faces (samples within 1e-4 cell of
    /// a face are taken as unchanged); then the result is identical to
    /// [`BrickOctree::rebuild`]. An octree that holds a cut multi-level mesh
    /// ([`BrickOctree::is_cut`]) is rebuilt whole. For a change of lattice coefficients, get the box from
    /// [`BrickOctree::coefficient_change_box`]: a cubic B-spline's change and its gradient
    /// vanish on that box's faces. A box with no sample inside changes nothing.
    pub fn refresh_box<F: ScalarField + ?Sized>(
        &mut self,
        field: &F,
        min: Vec3,
        max: Vec3,
    ) -> RefreshReport {
        if self.cut {
            return self.rebuild(field);
        }
        let Some((lo, hi)) = self.grid.interior_sample_range(min, max) else {
            return RefreshReport {
                generation: self.generation,
                ..RefreshReport::default()
            };
        };
        // Brick b holds samples 8b ..= 8b + 8.
        let first = lo.map(|s| s.saturating_sub(BRICK_CELLS).div_ceil(BRICK_CELLS));
        let last = std::array::from_fn(|a| (hi[a] / BRICK_CELLS).min(self.brick_counts[a] - 1));
        self.refresh_bricks(field, first, last)
    }

    /// [`BrickOctree::refresh_box`] for the engine: after a lattice's coefficients changed,
    /// re-mesh from the updated lattice. `min..max` is the world box of the changed
    /// coefficients' support, e.g. from [`BrickOctree::coefficient_change_box`].
    pub fn refresh_lattice(
        &mut self,
        lattice: &BSplineLattice,
        min: Vec3,
        max: Vec3,
    ) -> RefreshReport {
        self.refresh_box(lattice, min, max)
    }

    /// The world box where the field can change when the coefficients with indices
    /// `first ..= last` (per axis) change: their nodes widened by two knot spans, the reach
    /// of a cubic B-spline (the change is zero, with zero gradient, on the box's faces).
    #[must_use]
    pub fn coefficient_change_box(
        lattice: &BSplineLattice,
        first: [usize; 3],
        last: [usize; 3],
    ) -> (Vec3, Vec3) {
        let reach = Vec3::splat(2.0 * lattice.spacing);
        (
            lattice.node_position(first[0], first[1], first[2]) - reach,
            lattice.node_position(last[0], last[1], last[2]) + reach,
        )
    }

    fn refresh_bricks<F: ScalarField + ?Sized>(
        &mut self,
        field: &F,
        first: [u32; 3],
        last: [u32; 3],
    ) -> RefreshReport {
        self.generation += 1;
        let mut report = RefreshReport {
            generation: self.generation,
            ..RefreshReport::default()
        };
        if (0..3).any(|a| first[a] > last[a]) {
            return report;
        }
        // Start at the level whose nodes are as large as the query (at most two per axis hold
        // it): bounding the nodes above would only re-read coefficients far from the change.
        let span = (0..3).map(|a| last[a] - first[a] + 1).max().unwrap_or(1);
        let size = span.next_power_of_two().min(self.root_size);
        let start = first.map(|v| v / size * size);
        for dz in 0..2 {
            for dy in 0..2 {
                for dx in 0..2 {
                    let node = [
                        start[0] + dx * size,
                        start[1] + dy * size,
                        start[2] + dz * size,
                    ];
                    self.visit(field, node, size, (first, last), &mut report);
                }
            }
        }
        report
    }

    fn visit<F: ScalarField + ?Sized>(
        &mut self,
        field: &F,
        node: [u32; 3],
        size: u32,
        query: ([u32; 3], [u32; 3]),
        report: &mut RefreshReport,
    ) {
        let lo: [u32; 3] = std::array::from_fn(|a| node[a].max(query.0[a]));
        let hi: [u32; 3] = std::array::from_fn(|a| {
            (node[a] + size - 1)
                .min(query.1[a])
                .min(self.brick_counts[a] - 1)
        });
        if (0..3).any(|a| lo[a] > hi[a]) {
            return;
        }
        if self.culled(field, node, size) {
            self.remove_range(node, size, (lo, hi), report);
            return;
        }
        if size == 1 {
            report.bricks_sampled += 1;
            let key = morton(node);
            if sample_brick(field, &self.grid, node, &mut self.scratch) {
                self.bricks
                    .entry(key)
                    .or_insert_with(|| Brick::empty(node))
                    .remesh(field, &self.grid, &mut self.scratch, self.generation);
                report.changed.push(node);
            } else if self.bricks.remove(&key).is_some() {
                report.removed.push(node);
            }
            return;
        }
        let half = size / 2;
        for child in 0..8u32 {
            let c = [
                node[0] + (child & 1) * half,
                node[1] + ((child >> 1) & 1) * half,
                node[2] + ((child >> 2) & 1) * half,
            ];
            self.visit(field, c, half, query, report);
        }
    }

    /// Removes the stored bricks of node (`node`, `size`) that lie in `lo ..= hi`.
    fn remove_range(
        &mut self,
        node: [u32; 3],
        size: u32,
        (lo, hi): ([u32; 3], [u32; 3]),
        report: &mut RefreshReport,
    ) {
        let start = morton(node);
        let end = start + u64::from(size).pow(3);
        let doomed: Vec<u64> = self
            .bricks
            .range(start..end)
            .filter(|(_, b)| (0..3).all(|a| b.coord[a] >= lo[a] && b.coord[a] <= hi[a]))
            .map(|(&k, _)| k)
            .collect();
        for key in doomed {
            if let Some(brick) = self.bricks.remove(&key) {
                report.removed.push(brick.coord);
            }
        }
    }

    /// The sampling grid.
    #[must_use]
    pub fn grid(&self) -> &SampleGrid {
        &self.grid
    }

    /// The current generation (incremented by every build or refresh).
    #[must_use]
    pub fn generation(&self) -> u64 {
        self.generation
    }

    /// Number of stored bricks.
    #[must_use]
    pub fn brick_count(&self) -> usize {
        self.bricks.len()
    }

    /// Stored bricks in Morton order.
    pub fn bricks(&self) -> impl Iterator<Item = &Brick> {
        self.bricks.values()
    }

    /// The brick at a brick coordinate, if the surface crosses it.
    #[must_use]
    pub fn brick(&self, coord: [u32; 3]) -> Option<&Brick> {
        self.bricks.get(&morton(coord))
    }

    /// Bricks rebuilt after generation `seen` (a renderer passes the generation it last
    /// uploaded). Bricks that disappeared are reported by [`RefreshReport::removed`], or found
    /// by the renderer as keys it holds that [`BrickOctree::brick`] no longer has.
    pub fn changed_since(&self, seen: u64) -> impl Iterator<Item = &Brick> {
        self.bricks.values().filter(move |b| b.version > seen)
    }

    /// The brick whose box holds the world point `p`; a point outside the grid goes to the
    /// nearest brick (a point that is not finite, to brick 0 along that axis).
    #[must_use]
    pub fn brick_at(&self, p: Vec3) -> [u32; 3] {
        let span = self.grid.cell_size * BRICK_CELLS as f32;
        std::array::from_fn(|a| {
            // Compared before rounding down (x86-64's baseline has no rounding instruction):
            // below 1 (or NaN) the floor is at most 0, from `last` on it is at least `last`,
            // and between, truncation is the floor.
            let b = (p[a] - self.grid.origin[a]) / span;
            let last = self.brick_counts[a] - 1;
            if b.is_nan() || b < 1.0 {
                0
            } else if b >= last as f32 {
                last
            } else {
                b as u32
            }
        })
    }

    /// Whether the bricks hold the pieces of a multi-level mesh ([`super::AdaptiveBricks`])
    /// rather than the marching cubes of the grid.
    #[must_use]
    pub fn is_cut(&self) -> bool {
        self.cut
    }

    /// Puts pieces of a multi-level mesh in the bricks: each `(coord, mesh)` replaces the
    /// brick's mesh, or removes the brick where the mesh has no triangle (a brick not stored
    /// and given nothing is left out of the report). Every brick not named keeps its mesh;
    /// after the first call the octree is [cut](BrickOctree::is_cut) until a rebuild.
    pub(super) fn put_pieces(
        &mut self,
        pieces: impl IntoIterator<Item = ([u32; 3], BrickMesh)>,
    ) -> RefreshReport {
        self.cut = true;
        self.generation += 1;
        let mut report = RefreshReport {
            generation: self.generation,
            ..RefreshReport::default()
        };
        for (coord, mesh) in pieces {
            let key = morton(coord);
            if mesh.indices.is_empty() {
                if self.bricks.remove(&key).is_some() {
                    report.removed.push(coord);
                }
                continue;
            }
            let brick = self
                .bricks
                .entry(key)
                .or_insert_with(|| Brick::empty(coord));
            brick.mesh = mesh;
            brick.version = self.generation;
            brick.owned_vertices = 0;
            report.changed.push(coord);
        }
        report
    }

    /// Total triangles over all bricks.
    #[must_use]
    pub fn triangle_count(&self) -> usize {
        self.bricks.values().map(|b| b.mesh.triangle_count()).sum()
    }

    /// Memory held by meshes and structure.
    #[must_use]
    pub fn memory(&self) -> MemoryUsage {
        let mut usage = MemoryUsage::default();
        for b in self.bricks.values() {
            usage.mesh_bytes += b.mesh.heap_bytes();
        }
        // B-tree leaves hold up to 11 entries and are at least half full; count 1.5× the
        // entries as an upper estimate.
        let entry = size_of::<u64>() + size_of::<Brick>();
        usage.structure_bytes = self.bricks.len() * entry * 3 / 2
            + size_of::<Self>()
            + 3 * super::BRICK_SAMPLE_COUNT * size_of::<u32>()
            + super::BRICK_SAMPLE_COUNT * size_of::<f32>()
            + MAX_BRICK_INDICES * size_of::<u32>()
            + self.rebuild_scratch.heap_bytes();
        usage
    }

    /// The bricks welded by [`weld_pieces`], the weld the app's export uses (the reference
    /// the octree's faster weld is checked against).
    #[cfg(test)]
    fn weld_by_hash(&self) -> TriMesh {
        let pieces: Vec<WeldPiece<'_, Vec3>> = self
            .bricks
            .values()
            .map(|b| WeldPiece::of(&b.mesh))
            .collect();
        weld_pieces(&pieces)
    }
}

/// One brick's mesh as [`weld_pieces`] reads it: per vertex a position, a normal (as [`Vec3`]
/// or `[f32; 3]`) and the global edge id the vertex lies on ([`super::edge_id`]), and the
/// triangle list. Every slice but `indices` has one entry per vertex.
#[derive(Clone, Copy, Debug)]
pub struct WeldPiece<'a, V> {
    pub positions: &'a [V],
    pub normals: &'a [V],
    pub edge_ids: &'a [u64],
    /// Three vertex indices per triangle, each less than the vertex count.
    pub indices: &'a [u32],
}

impl<'a> WeldPiece<'a, Vec3> {
    /// The pieces of a brick's mesh.
    #[must_use]
    pub fn of(mesh: &'a BrickMesh) -> Self {
        Self {
            positions: &mesh.positions,
            normals: &mesh.normals,
            edge_ids: &mesh.edge_ids,
            indices: &mesh.indices,
        }
    }
}

/// Welding of brick meshes by edge id, for any set of pieces (the app's export of its
/// published chunks; [`BrickOctree::weld`] is the octree's faster path for its own bricks and
/// is tested to give exactly this mesh): vertices on a brick face are merged by their global
/// edge id, and so are the copies of a cut mesh's vertex ([`super::shared_vertex_id`]), so a
/// vertex two bricks share appears once; the others are unique to their brick. Vertex and
/// triangle order follow `pieces`.
///
/// # Panics
/// When a piece's slices disagree in length or an index is out of range (callers with
/// untrusted pieces check them first).
#[must_use]
pub fn weld_pieces<V: Copy + Into<Vec3>>(pieces: &[WeldPiece<'_, V>]) -> TriMesh {
    let vertices: usize = pieces.iter().map(|p| p.positions.len()).sum();
    let triangles: usize = pieces.iter().map(|p| p.indices.len() / 3).sum();
    let mut out = TriMesh {
        positions: Vec::with_capacity(vertices),
        normals: Vec::with_capacity(vertices),
        triangles: Vec::with_capacity(triangles),
    };
    // Only vertices on a brick face can be shared; the rest are unique to their brick.
    let mut shared: HashMap<u64, u32, BuildHasherDefault<EdgeIdHasher>> =
        HashMap::with_capacity_and_hasher(vertices / 4, Default::default());
    let mut local = Vec::new();
    for m in pieces {
        assert!(
            m.positions.len() == m.edge_ids.len() && m.normals.len() == m.edge_ids.len(),
            "a weld piece needs one position, normal and edge id per vertex"
        );
        local.clear();
        for (v, &id) in m.edge_ids.iter().enumerate() {
            let (corner, axis) = edge_from_id(id);
            let on_face = axis == SHARED_VERTEX_AXIS
                || (0..3).any(|a| a != axis as usize && corner[a] % BRICK_CELLS == 0);
            let next = out.positions.len() as u32;
            let index = if on_face {
                *shared.entry(id).or_insert(next)
            } else {
                next
            };
            if index == next {
                out.positions.push(m.positions[v].into());
                out.normals.push(m.normals[v].into());
            }
            local.push(index);
        }
        out.triangles.extend(m.indices.chunks_exact(3).map(|t| {
            [
                local[t[0] as usize],
                local[t[1] as usize],
                local[t[2] as usize],
            ]
        }));
    }
    out
}

/// The state of [`BrickOctree::count_sampled_bricks`]: the walk of `visit` without sampling.
struct CountWalk<'a, F: ScalarField + ?Sized> {
    tree: &'a BrickOctree,
    field: &'a F,
    iso: f32,
    sampled: u64,
    visited: u64,
    limit: u64,
}

impl<F: ScalarField + ?Sized> CountWalk<'_, F> {
    /// False once a limit is passed.
    fn visit(&mut self, node: [u32; 3], size: u32) -> bool {
        if (0..3).any(|a| node[a] >= self.tree.brick_counts[a]) {
            return true;
        }
        self.visited += 1;
        if self.visited > self.limit.saturating_mul(16) {
            return false;
        }
        let grid = &self.tree.grid;
        let node_hi: [u32; 3] =
            std::array::from_fn(|a| ((node[a] + size) * BRICK_CELLS).min(grid.cells[a]));
        let pmin = grid.point(node.map(|n| n * BRICK_CELLS));
        let pmax = grid.point(node_hi);
        if let Some((vmin, vmax)) = self.field.bounds(pmin, pmax) {
            let margin = 1e-5 * self.iso.abs().max(1.0);
            if vmax < self.iso - margin || vmin > self.iso + margin {
                return true;
            }
        }
        if size == 1 {
            self.sampled += 1;
            return self.sampled <= self.limit;
        }
        let half = size / 2;
        (0..8u32).all(|child| {
            self.visit(
                [
                    node[0] + (child & 1) * half,
                    node[1] + ((child >> 1) & 1) * half,
                    node[2] + ((child >> 2) & 1) * half,
                ],
                half,
            )
        })
    }
}

/// A node the descent culled: its stored bricks in `lo ..= hi` go.
#[derive(Clone, Copy, Debug)]
struct CulledNode {
    node: [u32; 3],
    size: u32,
    lo: [u32; 3],
    hi: [u32; 3],
    /// How many bricks to sample the descent met before this node.
    leaves_before: u32,
}

/// The buffers of a rebuild's serial part, kept between rebuilds.
#[derive(Clone, Debug, Default)]
struct RebuildScratch {
    /// The bricks to sample, in the order of the descent.
    leaves: Vec<[u32; 3]>,
    culls: Vec<CulledNode>,
    /// Per leaf: crossed by the surface, and stored before the rebuild.
    outcome: Vec<(bool, bool)>,
    /// Per cell of the brick grid, for lending by place (see [`lend_in_build_order`]).
    cells: Vec<u32>,
}

impl RebuildScratch {
    fn heap_bytes(&self) -> usize {
        self.leaves.capacity() * size_of::<[u32; 3]>()
            + self.culls.capacity() * size_of::<CulledNode>()
            + self.outcome.capacity() * size_of::<(bool, bool)>()
            + self.cells.capacity() * size_of::<u32>()
    }
}

/// Most entries in a per-row or per-layer table of faces (16384 faces, 5.5 MB: a 1024² grid
/// of cells per layer); larger grids share fewer faces.
const MAX_FACE_TABLE: usize = 1 << 14;

/// The upper faces of recently sampled bricks, so a brick takes its three lower faces from
/// the bricks below it instead of sampling them again. Bricks are met with x fastest, then
/// y, then z; each table keeps the latest brick per line (x: one; y: per column; z: per
/// column of the layer) and is checked against the coordinate it was made for, so a stale
/// entry is never used.
struct FaceCache {
    /// Brick counts per axis.
    counts: [u32; 3],
    x: ([u32; 3], Face),
    y: Vec<([u32; 3], Face)>,
    z: Vec<([u32; 3], Face)>,
}

impl FaceCache {
    const NONE: [u32; 3] = [u32::MAX; 3];

    fn new(counts: [u32; 3]) -> Self {
        let per_row = counts[0] as usize;
        let per_layer = per_row.saturating_mul(counts[1] as usize);
        let empty = (Self::NONE, [0.0; BRICK_SAMPLES * BRICK_SAMPLES]);
        Self {
            counts,
            x: empty,
            y: if per_row <= MAX_FACE_TABLE {
                vec![empty; per_row]
            } else {
                Vec::new()
            },
            z: if per_layer <= MAX_FACE_TABLE {
                vec![empty; per_layer]
            } else {
                Vec::new()
            },
        }
    }

    /// Slot of brick `node` in the table of `axis` (0: the single x slot).
    fn slot(&self, axis: usize, node: [u32; 3]) -> Option<usize> {
        match axis {
            0 => Some(0),
            1 => (!self.y.is_empty()).then_some(node[0] as usize),
            _ => (!self.z.is_empty())
                .then(|| node[0] as usize + self.counts[0] as usize * node[1] as usize),
        }
    }

    fn entry(&self, axis: usize, slot: usize) -> &([u32; 3], Face) {
        match axis {
            0 => &self.x,
            1 => &self.y[slot],
            _ => &self.z[slot],
        }
    }

    fn entry_mut(&mut self, axis: usize, slot: usize) -> &mut ([u32; 3], Face) {
        match axis {
            0 => &mut self.x,
            1 => &mut self.y[slot],
            _ => &mut self.z[slot],
        }
    }

    /// The upper faces of the bricks just below `node` along each axis, where held.
    fn near(&self, node: [u32; 3]) -> [Option<&Face>; 3] {
        std::array::from_fn(|axis| {
            if node[axis] == 0 {
                return None;
            }
            let mut below = node;
            below[axis] -= 1;
            let slot = self.slot(axis, node)?;
            let (coord, face) = self.entry(axis, slot);
            (*coord == below).then_some(face)
        })
    }

    /// Keeps the upper faces of brick `node`, just sampled into `scratch` (not those of a
    /// brick partial along that axis: nothing lies above it).
    fn keep(&mut self, node: [u32; 3], grid: &SampleGrid, scratch: &BrickScratch) {
        let (_, cells) = brick_extent(grid, node);
        for (axis, &n) in cells.iter().enumerate() {
            if n != BRICK_CELLS {
                continue;
            }
            let Some(slot) = self.slot(axis, node) else {
                continue;
            };
            let entry = self.entry_mut(axis, slot);
            entry.0 = node;
            upper_face(scratch, axis, &mut entry.1);
        }
    }
}

/// One brick to sample in a rebuild, as the builders get it.
struct BrickJob<'a> {
    coord: [u32; 3],
    /// The stored brick, rebuilt in its own buffers, or `None` for a brick not in the tree.
    stored: Option<&'a mut Brick>,
    /// Its index among the descent's leaves.
    leaf: u32,
    /// Set by the builder: the surface crosses the brick (it now carries the generation).
    crossed: bool,
}

/// The jobs of a rebuild: the bricks of `leaves` (distinct bricks of a grid of `counts`
/// bricks, listed by the descent in Morton order) with x fastest, then y, then z, which is
/// the order in which each brick follows the bricks below it, each lent its stored brick
/// from `bricks` where there is one.
///
/// When the leaves fill a good part of the grid (a field without bounds samples every
/// brick) they are placed by one scan of the grid and the stored bricks found by their
/// place in it; otherwise the leaves are sorted and the stored ones found by one merge of
/// keys. Either way this is a small part of a rebuild, which matters because it runs on
/// the caller alone while the other threads wait.
fn lend_in_build_order<'a>(
    leaves: &[[u32; 3]],
    counts: [u32; 3],
    bricks: &'a mut BTreeMap<u64, Brick>,
    at: &mut Vec<u32>,
) -> Vec<BrickJob<'a>> {
    let job = |leaf: usize| BrickJob {
        coord: leaves[leaf],
        stored: None,
        leaf: leaf as u32,
        crossed: false,
    };
    let cells = counts.iter().map(|&c| c as usize).product::<usize>();
    if cells <= 8 * leaves.len() {
        let linear = |c: [u32; 3]| {
            c[0] as usize
                + counts[0] as usize * (c[1] as usize + counts[1] as usize * c[2] as usize)
        };
        at.clear();
        at.resize(cells, u32::MAX);
        for (i, &c) in leaves.iter().enumerate() {
            at[linear(c)] = i as u32;
        }
        // Job index per cell, then the stored bricks lent by their cell.
        let mut jobs = Vec::with_capacity(leaves.len());
        for slot in at.iter_mut() {
            if *slot != u32::MAX {
                jobs.push(job(*slot as usize));
                *slot = (jobs.len() - 1) as u32;
            }
        }
        for brick in bricks.values_mut() {
            if let Some(&j) = at.get(linear(brick.coord))
                && j != u32::MAX
            {
                jobs[j as usize].stored = Some(brick);
            }
        }
        return jobs;
    }
    let mut keyed: Vec<(u64, u32)> = leaves
        .iter()
        .enumerate()
        .map(|(i, &node)| (morton(node), i as u32))
        .collect();
    // Already in order from the descent: one pass.
    keyed.sort_unstable();
    let mut lent: Vec<Option<&'a mut Brick>> = Vec::with_capacity(leaves.len());
    lent.resize_with(leaves.len(), || None);
    if let (Some(&(first, _)), Some(&(end, _))) = (keyed.first(), keyed.last()) {
        let mut wanted = keyed.iter().peekable();
        for (key, brick) in bricks.range_mut(first..=end) {
            while wanted.next_if(|&&(k, _)| k < *key).is_some() {}
            if let Some(&(_, i)) = wanted.next_if(|&&(k, _)| k == *key) {
                lent[i as usize] = Some(brick);
            }
        }
    }
    let mut order: Vec<u32> = (0..leaves.len() as u32).collect();
    order.sort_unstable_by_key(|&i| {
        let c = leaves[i as usize];
        (c[2], c[1], c[0])
    });
    order
        .into_iter()
        .map(|i| BrickJob {
            stored: lent[i as usize].take(),
            ..job(i as usize)
        })
        .collect()
}

/// One thread's share of a build: the runs of the build order that `next_run` hands out,
/// until it has none left. Within a run, each brick takes the faces it shares with the bricks
/// below it from them (about one sample per cell instead of 1.42). A brick the surface
/// crosses is marked, and filled with the generation: a stored one in place, a new one made
/// and returned; the others are left as they were.
fn build_runs<'a, 'b: 'a, F: ScalarField + ?Sized>(
    field: &F,
    grid: &SampleGrid,
    counts: [u32; 3],
    generation: u64,
    mut next_run: impl FnMut() -> Option<&'a mut [BrickJob<'b>]>,
) -> Vec<Brick> {
    let mut scratch = BrickScratch::default();
    let mut cache = FaceCache::new(counts);
    let mut fresh = Vec::new();
    while let Some(run) = next_run() {
        for at in 0..run.len() {
            // Once this brick is sampled, ask the cache for the next stored brick's mesh,
            // which its remesh will write (see `BrickMesh::prefetch`). A new brick has
            // nothing to fetch.
            let node = run[at].coord;
            let crossed = sample_brick_sharing(field, grid, node, cache.near(node), &mut scratch);
            cache.keep(node, grid, &scratch);
            if let Some(BrickJob {
                stored: Some(next), ..
            }) = run.get(at + 1)
            {
                next.mesh.prefetch();
            }
            let job = &mut run[at];
            job.crossed = crossed;
            if crossed {
                match job.stored.as_deref_mut() {
                    Some(brick) => brick.remesh(field, grid, &mut scratch, generation),
                    None => {
                        let mut brick = Brick::empty(node);
                        brick.remesh(field, grid, &mut scratch, generation);
                        fresh.push(brick);
                    }
                }
            }
        }
    }
    fresh
}

/// How many units of the build order a rebuild on several threads hands out per thread
/// (see [`build_bricks_parallel`]): enough that the threads finish within a small part of
/// the build of each other.
const BUILD_UNITS_PER_THREAD: usize = 64;

/// Builds `jobs` (in build order) on `threads` threads (the caller and `threads − 1`
/// more) and returns the new bricks. A brick's samples and mesh depend only on the brick
/// and the field, so the split changes nothing in the result.
///
/// The order is cut into units, [`BUILD_UNITS_PER_THREAD`] per thread, which a
/// [`WorkSplit`] hands out: each thread builds one contiguous stretch of the order, so
/// every brick but the first after a steal takes its lower faces from bricks its own thread
/// built just before, and a thread that runs out takes the back half of the largest
/// stretch left. The threads so finish together whether the surface (and with it the
/// marching) lies evenly or mostly in one thread's stretch, and when the operating system
/// holds one thread back.
fn build_bricks_parallel<F: ScalarField + Sync + ?Sized>(
    field: &F,
    grid: &SampleGrid,
    counts: [u32; 3],
    generation: u64,
    jobs: &mut [BrickJob<'_>],
    threads: usize,
) -> Vec<Brick> {
    let threads = threads.clamp(1, jobs.len().max(1));
    if threads == 1 {
        let mut all = Some(jobs);
        return build_runs(field, grid, counts, generation, || all.take());
    }
    let unit = jobs.len().div_ceil(threads * BUILD_UNITS_PER_THREAD);
    // NOTE: a unit's lock is tried once, by the one thread the split handed the unit to, so
    // it is never contended and never waited on (`try_lock`); it only moves the unit's jobs
    // to that thread.
    let units: Vec<Mutex<Option<&mut [BrickJob<'_>]>>> = jobs
        .chunks_mut(unit)
        .map(|unit| Mutex::new(Some(unit)))
        .collect();
    let split = WorkSplit::new(units.len(), threads);
    let work = |thread: usize| {
        build_runs(field, grid, counts, generation, || {
            let unit = split.next(thread)?;
            match units[unit].try_lock() {
                Ok(mut slot) => slot.take(),
                Err(TryLockError::Poisoned(poisoned)) => poisoned.into_inner().take(),
                Err(TryLockError::WouldBlock) => {
                    unreachable!("the split hands unit {unit} to one thread only")
                }
            }
        })
    };
    let work = &work;
    std::thread::scope(|scope| {
        let helpers: Vec<_> = (1..threads)
            .map(|thread| scope.spawn(move || work(thread)))
            .collect();
        let mut fresh = work(0);
        for h in helpers {
            match h.join() {
                Ok(more) => fresh.extend(more),
                Err(panic) => std::panic::resume_unwind(panic),
            }
        }
        fresh
    })
}

/// Interleaves the low 21 bits of each coordinate (x lowest).
#[inline]
#[must_use]
pub(super) fn morton(c: [u32; 3]) -> u64 {
    fn spread(v: u32) -> u64 {
        let mut x = u64::from(v) & 0x1f_ffff;
        x = (x | x << 32) & 0x1f_0000_0000_ffff;
        x = (x | x << 16) & 0x1f_0000_ff00_00ff;
        x = (x | x << 8) & 0x100f_00f0_0f00_f00f;
        x = (x | x << 4) & 0x10c3_0c30_c30c_30c3;
        x = (x | x << 2) & 0x1249_2492_4924_9249;
        x
    }
    spread(c[0]) | spread(c[1]) << 1 | spread(c[2]) << 2
}

/// A fast mixing hash for edge ids (the weld's fallback and its test reference).
#[derive(Default)]
pub(super) struct EdgeIdHasher(u64);

impl Hasher for EdgeIdHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0.rotate_left(8) ^ u64::from(b)).wrapping_mul(0x9e37_79b9_7f4a_7c15);
        }
    }
    fn write_u64(&mut self, v: u64) {
        // SplitMix64's finaliser: every input bit reaches the low bits the table indexes by.
        let mut x = v ^ (v >> 30);
        x = x.wrapping_mul(0xbf58_476d_1ce4_e5b9);
        x ^= x >> 27;
        x = x.wrapping_mul(0x94d0_49bb_1331_11eb);
        self.0 = x ^ (x >> 31);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::weld::{MAX_ORDINAL_TABLE, WeldScratch, weld_parallel};
    use crate::mesh::{FnField, MeshStats};
    use std::f64::consts::PI;

    fn sphere_fn(
        centre: Vec3,
        radius: f32,
    ) -> FnField<impl Fn(Vec3) -> f32 + Copy, impl Fn(Vec3) -> Vec3 + Copy> {
        FnField {
            value: move |p: Vec3| radius - (p - centre).length(),
            gradient: move |p: Vec3| -(p - centre).normalize_or_zero(),
            iso: 0.0,
            lipschitz: Some(1.0),
        }
    }

    /// A lattice whose level set 0.5 approximates a sphere: coefficients sample a linear ramp
    /// of the signed distance, 6 knot spans wide, clamped to [0, 1].
    fn sphere_lattice(radius_spans: f32) -> (BSplineLattice, Vec3, f32) {
        let spacing = 0.1;
        let n = (2.0 * radius_spans + 12.0).ceil() as usize;
        let mut lattice = BSplineLattice::zeros([n; 3], spacing, Vec3::ZERO).unwrap();
        let centre = Vec3::splat((n - 1) as f32 * spacing / 2.0);
        let radius = radius_spans * spacing;
        for k in 0..n {
            for j in 0..n {
                for i in 0..n {
                    let d = radius - (lattice.node_position(i, j, k) - centre).length();
                    let idx = lattice.index(i, j, k);
                    lattice
                        .coeffs
                        .set_flat(idx, (0.5 + d / (6.0 * spacing)).clamp(0.0, 1.0));
                }
            }
        }
        (lattice, centre, radius)
    }

    fn closed_stats(tree: &BrickOctree) -> MeshStats {
        let mesh = tree.weld();
        assert!(mesh.is_well_formed());
        let stats = MeshStats::of(&mesh);
        assert_eq!(stats.boundary_edges, 0, "{stats:?}");
        assert_eq!(stats.non_manifold_edges, 0, "{stats:?}");
        assert_eq!(stats.misoriented_edges, 0, "{stats:?}");
        stats
    }

    fn assert_same_bricks(a: &BrickOctree, b: &BrickOctree) {
        assert_eq!(a.brick_count(), b.brick_count());
        for (x, y) in a.bricks().zip(b.bricks()) {
            assert_eq!(x.coord, y.coord);
            assert_eq!(x.mesh, y.mesh, "brick {:?} differs", x.coord);
        }
    }

    #[test]
    fn analytic_sphere_is_closed_and_converges_to_area_and_volume() {
        let radius = 1.0f32;
        let centre = Vec3::new(0.013, -0.021, 0.007);
        let field = sphere_fn(centre, radius);
        let exact_area = 4.0 * PI;
        let exact_volume = 4.0 / 3.0 * PI;
        let mut last = (f64::INFINITY, f64::INFINITY);
        for cells_per_radius in [6.0f32, 12.0, 24.0, 48.0] {
            let h = radius / cells_per_radius;
            let grid = SampleGrid::covering(centre - 1.3, centre + 1.3, h).unwrap();
            let tree = BrickOctree::build(grid, &field);
            let s = closed_stats(&tree);
            assert_eq!(s.euler_characteristic, 2, "at h = {h}: {s:?}");
            let area_err = (s.area - exact_area).abs() / exact_area;
            let volume_err = (s.volume - exact_volume).abs() / exact_volume;
            assert!(
                area_err < last.0 && volume_err < last.1,
                "error grew at h = {h}"
            );
            last = (area_err, volume_err);
            let mesh = tree.weld();
            for (p, n) in mesh.positions.iter().zip(&mesh.normals) {
                assert!(((*p - centre).length() - radius).abs() < h * h / radius + 1e-4);
                assert!(
                    n.dot((*p - centre).normalize()) > 0.999,
                    "normal points inwards"
                );
            }
        }
        assert!(last.0 < 0.01, "area error {}", last.0);
        assert!(last.1 < 0.01, "volume error {}", last.1);
    }

    #[test]
    fn lattice_sphere_is_closed_and_accurate_at_several_spacings() {
        let (lattice, centre, radius) = sphere_lattice(20.0);
        let exact_area = 4.0 * PI * f64::from(radius).powi(2);
        let exact_volume = 4.0 / 3.0 * PI * f64::from(radius).powi(3);
        let mut last = f64::INFINITY;
        for cells_per_span in [1, 2, 4] {
            let grid = SampleGrid::for_lattice(&lattice, cells_per_span).unwrap();
            let tree = BrickOctree::build(grid, &lattice);
            let s = closed_stats(&tree);
            assert_eq!(s.euler_characteristic, 2);
            let err = (s.area - exact_area).abs() / exact_area
                + (s.volume - exact_volume).abs() / exact_volume;
            assert!(err < last, "error grew at {cells_per_span} cells per span");
            last = err;
            if cells_per_span == 4 {
                assert!((s.area - exact_area).abs() / exact_area < 0.01, "{s:?}");
                assert!(
                    (s.volume - exact_volume).abs() / exact_volume < 0.01,
                    "{s:?}"
                );
                let mesh = tree.weld();
                for (p, n) in mesh.positions.iter().zip(&mesh.normals) {
                    assert!(n.dot((*p - centre).normalize()) > 0.99);
                }
            }
        }
    }

    #[test]
    fn torus_is_closed_with_euler_characteristic_zero() {
        let (major, minor) = (1.0f32, 0.35f32);
        let field = FnField {
            value: move |p: Vec3| {
                let q = (p.x.hypot(p.y) - major).hypot(p.z);
                minor - q
            },
            gradient: move |p: Vec3| {
                let rho = p.x.hypot(p.y).max(1e-12);
                let d = Vec3::new(p.x / rho * (rho - major), p.y / rho * (rho - major), p.z);
                -d.normalize_or_zero()
            },
            iso: 0.0,
            lipschitz: Some(1.0),
        };
        for h in [0.1f32, 0.05, 0.025] {
            let grid = SampleGrid::covering(Vec3::splat(-1.5), Vec3::splat(1.5), h).unwrap();
            let tree = BrickOctree::build(grid, &field);
            let s = closed_stats(&tree);
            assert_eq!(s.euler_characteristic, 0, "at h = {h}: {s:?}");
            let volume = 2.0 * PI * PI * f64::from(major) * f64::from(minor).powi(2);
            assert!((s.volume - volume).abs() / volume < 0.05);
        }
    }

    #[test]
    fn random_fields_give_closed_manifolds() {
        // Noise exercises every case, ambiguous faces included; zero padding closes it.
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        for trial in 0..6 {
            let mut lattice = BSplineLattice::zeros([9, 8, 10], 1.0, Vec3::ZERO).unwrap();
            lattice.coeffs.update_each(|_, c| {
                seed ^= seed << 13;
                seed ^= seed >> 7;
                seed ^= seed << 17;
                *c = (seed >> 40) as f32 / (1u64 << 24) as f32 * 1.4;
            });
            let grid = SampleGrid::for_lattice(&lattice, 1 + trial % 3).unwrap();
            let tree = BrickOctree::build(grid, &lattice);
            assert!(tree.triangle_count() > 100);
            closed_stats(&tree);
        }
    }

    #[test]
    fn culled_build_matches_exhaustive_sampling() {
        let field = sphere_fn(Vec3::splat(0.5), 0.3);
        let unbounded = FnField {
            lipschitz: None,
            ..field
        };
        let grid = SampleGrid::new(Vec3::ZERO, 1.0 / 64.0, [64; 3]).unwrap();
        let culled = BrickOctree::build(grid, &field);
        let full = BrickOctree::build(grid, &unbounded);
        assert_same_bricks(&culled, &full);
        assert!(culled.brick_count() < 8 * 8 * 8);
    }

    #[test]
    fn local_refresh_equals_full_rebuild_after_edits() {
        let (mut lattice, centre, radius) = sphere_lattice(12.0);
        let grid = SampleGrid::for_lattice(&lattice, 3).unwrap();
        let mut tree = BrickOctree::build(grid, &lattice);
        let full_sampled = tree.rebuild(&lattice).bricks_sampled;

        let n = lattice.dims[0];
        let node = |p: Vec3| {
            let u = lattice.to_lattice(p).round();
            [u.x as usize, u.y as usize, u.z as usize]
        };
        // A dent where the surface is, a new blob in empty space, then the blob removed.
        let surface_point = centre + Vec3::new(radius, 0.0, 0.0);
        let blob = [2usize, 3, n - 4];
        let edits: [([usize; 3], [usize; 3], f32); 3] = [
            (
                node(surface_point).map(|c| c - 2),
                node(surface_point).map(|c| c + 2),
                -0.6,
            ),
            (blob, blob.map(|c| c + 1), 1.0),
            (blob, blob.map(|c| c + 1), -1.0),
        ];
        let mut expected_chi = [2, 4, 2].into_iter();
        for (first, last, delta) in edits {
            for k in first[2]..=last[2] {
                for j in first[1]..=last[1] {
                    for i in first[0]..=last[0] {
                        let idx = lattice.index(i, j, k);
                        lattice.coeffs.add_flat(idx, delta);
                    }
                }
            }
            let (min, max) = BrickOctree::coefficient_change_box(&lattice, first, last);
            let report = tree.refresh_lattice(&lattice, min, max);
            assert!(report.bricks_sampled * 4 < full_sampled, "{report:?}");
            assert!(!report.changed.is_empty() || !report.removed.is_empty());
            for c in &report.changed {
                assert_eq!(tree.brick(*c).unwrap().version, report.generation);
            }
            for c in &report.removed {
                assert!(tree.brick(*c).is_none());
            }
            let fresh = BrickOctree::build(grid, &lattice);
            assert_same_bricks(&tree, &fresh);
            assert_eq!(tree.weld(), fresh.weld());
            let s = closed_stats(&tree);
            assert_eq!(Some(s.euler_characteristic), expected_chi.next(), "{s:?}");
        }
    }

    /// The weld on `threads` threads, into a kept mesh and scratch that held another mesh
    /// first, as bits.
    fn threaded_weld_bits(tree: &BrickOctree, threads: usize) -> (Vec<u32>, Vec<[u32; 3]>) {
        let (lattice, _, _) = sphere_lattice(5.0);
        let other = BrickOctree::build(SampleGrid::for_lattice(&lattice, 2).unwrap(), &lattice);
        let mut out = TriMesh::default();
        let mut scratch = WeldScratch::default();
        other.weld_into_with_threads(&mut out, &mut scratch, threads);
        tree.weld_into_with_threads(&mut out, &mut scratch, threads);
        assert_eq!(out, tree.weld_with_threads(threads));
        // The threads' own weld, not the one-thread weld it gives way to on a stray vertex.
        let bricks: Vec<&Brick> = tree.bricks().collect();
        let mut direct = TriMesh::default();
        assert!(weld_parallel(
            &bricks,
            tree.brick_counts,
            &mut direct,
            &mut scratch,
            threads
        ));
        assert_eq!(direct, out);
        mesh_bits(&out)
    }

    #[test]
    fn weld_on_threads_equals_the_one_thread_weld_bit_for_bit() {
        // A lattice sphere (sparse bricks), a ball in a grid too large for the table of
        // ordinals (found among the keys), and a dense surface with partial bricks.
        let (lattice, _, _) = sphere_lattice(12.0);
        let sphere = BrickOctree::build(SampleGrid::for_lattice(&lattice, 3).unwrap(), &lattice);
        let grid = SampleGrid::new(Vec3::ZERO, 1.0, [1040; 3]).unwrap();
        let ball = BrickOctree::build(grid, &sphere_fn(Vec3::new(501.3, 498.7, 500.2), 23.0));
        const W: f32 = 9.0;
        let gyroid = FnField {
            value: |p: Vec3| {
                (W * p.x).sin() * (W * p.y).cos()
                    + (W * p.y).sin() * (W * p.z).cos()
                    + (W * p.z).sin() * (W * p.x).cos()
            },
            gradient: |p: Vec3| Vec3::new(p.y.cos(), p.z.sin(), 1.0 + p.x * p.x),
            iso: 0.1,
            lipschitz: None,
        };
        let grid = SampleGrid::new(Vec3::splat(-0.2), 1.0 / 29.0, [37, 45, 41]).unwrap();
        let dense = BrickOctree::build(grid, &gyroid);
        for tree in [&sphere, &ball, &dense] {
            let one = mesh_bits(&tree.weld());
            assert!(!one.1.is_empty());
            for threads in [1, 2, 3, 7] {
                assert_eq!(threaded_weld_bits(tree, threads), one, "{threads} threads");
            }
        }
        // The closed surfaces welded on threads are closed: every edge in exactly two
        // triangles, wound the same way.
        for tree in [&sphere, &ball] {
            let mesh = tree.weld_with_threads(3);
            assert!(mesh.is_well_formed());
            let stats = MeshStats::of(&mesh);
            assert_eq!(
                (
                    stats.boundary_edges,
                    stats.non_manifold_edges,
                    stats.misoriented_edges
                ),
                (0, 0, 0),
                "{stats:?}"
            );
        }
        // More threads than bricks, and an empty tree.
        let (tiny_lattice, _, _) = sphere_lattice(1.5);
        let tiny = BrickOctree::build(
            SampleGrid::for_lattice(&tiny_lattice, 1).unwrap(),
            &tiny_lattice,
        );
        assert!(tiny.brick_count() < 16);
        assert_eq!(tiny.weld_with_threads(16), tiny.weld());
        let empty = BrickOctree::new(SampleGrid::new(Vec3::ZERO, 1.0, [20; 3]).unwrap());
        assert_eq!(empty.weld_with_threads(2), TriMesh::default());
    }

    #[test]
    fn weld_on_threads_merges_vertices_whose_owner_is_missing_by_edge_id() {
        // Bricks taken out of the tree leave the bricks above them with lower-face vertices
        // whose owner is gone: the weld on threads gives way to the one-thread weld, which
        // merges them by edge id, as the reference weld does.
        let (lattice, _, _) = sphere_lattice(12.0);
        let mut tree = BrickOctree::build(SampleGrid::for_lattice(&lattice, 3).unwrap(), &lattice);
        let keys: Vec<u64> = tree.bricks.keys().copied().collect();
        for key in keys.iter().step_by(5) {
            tree.bricks.remove(key);
        }
        let reference = tree.weld_by_hash();
        assert_eq!(tree.weld(), reference);
        for threads in [2, 3] {
            assert_eq!(tree.weld_with_threads(threads), reference);
        }
    }

    #[test]
    fn weld_by_owner_equals_weld_by_hash() {
        let (lattice, _, _) = sphere_lattice(12.0);
        let grid = SampleGrid::for_lattice(&lattice, 3).unwrap();
        let tree = BrickOctree::build(grid, &lattice);
        assert_eq!(tree.weld(), tree.weld_by_hash());
        // More bricks in the grid than the weld's table of ordinals holds: the bricks below
        // are searched among the keys.
        let grid = SampleGrid::new(Vec3::ZERO, 1.0, [1040; 3]).unwrap();
        assert!(1040usize.div_ceil(BRICK_CELLS as usize).pow(3) > MAX_ORDINAL_TABLE);
        let ball = sphere_fn(Vec3::new(501.3, 498.7, 500.2), 23.0);
        let tree = BrickOctree::build(grid, &ball);
        assert!(tree.brick_count() > 50);
        assert_eq!(tree.weld(), tree.weld_by_hash());
        // A dense surface that meets every brick face, and partial bricks at the far faces.
        const W: f32 = 9.0;
        let gyroid = FnField {
            value: |p: Vec3| {
                (W * p.x).sin() * (W * p.y).cos()
                    + (W * p.y).sin() * (W * p.z).cos()
                    + (W * p.z).sin() * (W * p.x).cos()
            },
            gradient: |_| Vec3::X,
            iso: 0.1,
            lipschitz: None,
        };
        let grid = SampleGrid::new(Vec3::splat(-0.2), 1.0 / 29.0, [37, 45, 41]).unwrap();
        let tree = BrickOctree::build(grid, &gyroid);
        let welded = tree.weld();
        assert_eq!(welded, tree.weld_by_hash());
        assert!(welded.triangle_count() > 5000);
        // The same bricks as meshing each brick on its own.
        let mut alone = BrickOctree::new(grid);
        alone.refresh_box(&gyroid, Vec3::splat(-10.0), Vec3::splat(10.0));
        assert_same_bricks(&tree, &alone);
        // Runs of the build order split over threads start without the faces below them.
        for threads in [2, 3] {
            let many = BrickOctree::build_with_threads(grid, &gyroid, threads);
            assert_same_bricks(&tree, &many);
        }
    }

    #[test]
    fn bricks_split_over_threads_equal_one_thread() {
        let (mut lattice, centre, radius) = sphere_lattice(12.0);
        let grid = SampleGrid::for_lattice(&lattice, 3).unwrap();
        let mut one = BrickOctree::build(grid, &lattice);
        for threads in [2, 3] {
            let many = BrickOctree::build_with_threads(grid, &lattice, threads);
            assert_same_bricks(&one, &many);
            assert_eq!(one.weld(), many.weld());
        }
        // A rebuild after an edit that removes part of the surface: the same report too.
        let mut many = BrickOctree::build_with_threads(grid, &lattice, 2);
        let p = lattice
            .to_lattice(centre + Vec3::new(radius, 0.0, 0.0))
            .round();
        let at = [p.x as usize, p.y as usize, p.z as usize];
        for k in at[2] - 3..=at[2] + 3 {
            for j in at[1] - 3..=at[1] + 3 {
                for i in at[0] - 3..=at[0] + 3 {
                    let idx = lattice.index(i, j, k);
                    lattice.coeffs.add_flat(idx, -0.8);
                }
            }
        }
        let a = one.rebuild(&lattice);
        let b = many.rebuild_with_threads(&lattice, 2);
        assert_eq!(a, b);
        assert!(!a.removed.is_empty() || !a.changed.is_empty());
        assert_same_bricks(&one, &many);
        for (x, y) in one.bricks().zip(many.bricks()) {
            assert_eq!(x.version, y.version);
        }
    }

    /// Every brick's coordinate, positions, normals, edge ids and triangles, floats as their
    /// bits (so `-0.0` and `0.0`, or two NaNs, are told apart).
    #[allow(clippy::type_complexity)]
    fn brick_bits(tree: &BrickOctree) -> Vec<([u32; 3], Vec<u32>, Vec<u64>, Vec<u32>)> {
        let floats = |v: &[Vec3]| {
            v.iter()
                .flat_map(|p| p.to_array().map(f32::to_bits))
                .collect()
        };
        tree.bricks()
            .map(|b| {
                let m = &b.mesh;
                let mut vertices: Vec<u32> = floats(&m.positions);
                vertices.extend(floats(&m.normals).iter());
                (b.coord, vertices, m.edge_ids.clone(), m.indices.clone())
            })
            .collect()
    }

    fn mesh_bits(mesh: &TriMesh) -> (Vec<u32>, Vec<[u32; 3]>) {
        let mut floats: Vec<u32> = Vec::new();
        for p in mesh.positions.iter().chain(&mesh.normals) {
            floats.extend(p.to_array().map(f32::to_bits));
        }
        (floats, mesh.triangles.clone())
    }

    #[test]
    fn two_threads_and_kept_buffers_equal_a_fresh_one_thread_build_bit_for_bit() {
        // Two dense surfaces with partial bricks at the far faces; the second moves the
        // surface everywhere, so bricks appear, go, and change their meshes' sizes.
        fn wave(w: f32, iso: f32) -> FnField<impl Fn(Vec3) -> f32, impl Fn(Vec3) -> Vec3> {
            FnField {
                value: move |p: Vec3| {
                    (w * p.x).sin() * (w * p.y).cos()
                        + (w * p.y).sin() * (w * p.z).cos()
                        + (w * p.z).sin() * (w * p.x).cos()
                },
                gradient: move |p: Vec3| {
                    let (sx, cx) = (w * p.x).sin_cos();
                    let (sy, cy) = (w * p.y).sin_cos();
                    let (sz, cz) = (w * p.z).sin_cos();
                    w * Vec3::new(cx * cy - sz * sx, cy * cz - sx * sy, cz * cx - sy * sz)
                },
                iso,
                lipschitz: None,
            }
        }
        let (a, b) = (wave(9.0, 0.1), wave(6.5, 0.9));
        let grid = SampleGrid::new(Vec3::splat(-0.2), 1.0 / 29.0, [45, 37, 41]).unwrap();
        let fresh_a = BrickOctree::build(grid, &a);
        let fresh_b = BrickOctree::build(grid, &b);
        let weld_a = mesh_bits(&fresh_a.weld());
        let weld_b = mesh_bits(&fresh_b.weld());
        assert!(fresh_a.triangle_count() > 5000 && fresh_b.triangle_count() > 1000);
        assert_ne!(fresh_a.brick_count(), fresh_b.brick_count());
        let two = BrickOctree::build_with_threads(grid, &a, 2);
        assert_eq!(brick_bits(&two), brick_bits(&fresh_a));
        // One tree and one welded mesh kept through rebuilds from one surface to the other.
        let mut kept = BrickOctree::build(grid, &a);
        let mut out = TriMesh::default();
        let mut scratch = WeldScratch::default();
        kept.weld_into(&mut out, &mut scratch);
        assert_eq!(mesh_bits(&out), weld_a);
        for (field, fresh, weld, threads) in [
            (&b, &fresh_b, &weld_b, 2),
            (&a, &fresh_a, &weld_a, 2),
            (&b, &fresh_b, &weld_b, 1),
            (&a, &fresh_a, &weld_a, 3),
        ] {
            let before: Vec<[u32; 3]> = kept.bricks().map(|x| x.coord).collect();
            let report = if threads == 1 {
                kept.rebuild(field)
            } else {
                kept.rebuild_with_threads(field, threads)
            };
            assert_eq!(brick_bits(&kept), brick_bits(fresh), "{threads} threads");
            assert!(kept.bricks().all(|x| x.version == report.generation));
            let now: Vec<[u32; 3]> = kept.bricks().map(|x| x.coord).collect();
            let mut gone: Vec<[u32; 3]> = before.into_iter().filter(|c| !now.contains(c)).collect();
            let mut removed = report.removed.clone();
            gone.sort_unstable();
            removed.sort_unstable();
            assert_eq!(removed, gone);
            assert_eq!(report.changed.len(), now.len());
            kept.weld_into(&mut out, &mut scratch);
            assert_eq!(&mesh_bits(&out), weld);
        }
    }

    #[test]
    fn bricks_built_in_stolen_stretches_equal_one_thread_bit_for_bit() {
        // The order a thread of a rebuild on four threads takes the build order's units in
        // when the other three never run: its own quarter, then back halves of the others'
        // (each starting where the bricks below it were built by no one yet, or long ago,
        // so the faces kept for them are stale). A kept tree rebuilt so, from a surface to
        // another, holds the bricks of a fresh one-thread build, with the report of a
        // one-thread rebuild.
        const W: f32 = 8.0;
        let wave = |iso: f32| FnField {
            value: |p: Vec3| {
                (W * p.x).sin() * (W * p.y).cos()
                    + (W * p.y).sin() * (W * p.z).cos()
                    + (W * p.z).sin() * (W * p.x).cos()
            },
            gradient: |p: Vec3| Vec3::new(p.y.cos(), p.z.sin(), 1.0 + p.x * p.x),
            iso,
            lipschitz: None,
        };
        let (a, b) = (wave(0.2), wave(-0.4));
        let grid = SampleGrid::new(Vec3::splat(-0.2), 1.0 / 31.0, [43, 50, 39]).unwrap();
        let mut kept = BrickOctree::build(grid, &a);
        for field in [&b, &a] {
            let fresh = BrickOctree::build(grid, field);
            let mut one_thread = kept.clone();
            let expected = one_thread.rebuild(field);
            let (mut order, mut unit_count) = (Vec::new(), 0);
            let report = kept.rebuild_on(field, |field, grid, counts, generation, jobs| {
                let unit = jobs.len().div_ceil(4 * 7);
                let mut units: Vec<Option<&mut [BrickJob<'_>]>> =
                    jobs.chunks_mut(unit).map(Some).collect();
                unit_count = units.len();
                let split = WorkSplit::new(unit_count, 4);
                build_runs(field, grid, counts, generation, || {
                    let at = split.next(0)?;
                    order.push(at);
                    units[at].take()
                })
            });
            assert!(order.windows(2).any(|w| w[1] < w[0]), "{order:?}");
            let mut sorted = order.clone();
            sorted.sort_unstable();
            assert_eq!(sorted, (0..unit_count).collect::<Vec<_>>());
            assert!(unit_count > 20);
            assert_eq!(report, expected);
            assert!(!report.removed.is_empty());
            assert_eq!(brick_bits(&kept), brick_bits(&fresh));
            assert_eq!(brick_bits(&kept), brick_bits(&one_thread));
        }
    }

    #[test]
    fn local_refresh_of_a_closure_field_equals_full_rebuild() {
        // A smooth bump of compact support (radius r around q) added to a sphere.
        let (centre, radius) = (Vec3::splat(0.5), 0.3f32);
        let q = Vec3::new(0.8, 0.52, 0.47);
        let r = 0.09f32;
        let bumped = move |p: Vec3| {
            let w = (1.0 - (p - q).length_squared() / (r * r)).max(0.0);
            radius - (p - centre).length() + 0.05 * w * w * w
        };
        let bumped_gradient = move |p: Vec3| {
            let w = (1.0 - (p - q).length_squared() / (r * r)).max(0.0);
            -(p - centre).normalize_or_zero() - 0.05 * 3.0 * w * w * 2.0 * (p - q) / (r * r)
        };
        let before = sphere_fn(centre, radius);
        let after = FnField {
            value: bumped,
            gradient: bumped_gradient,
            iso: 0.0,
            lipschitz: Some(2.0),
        };
        let grid = SampleGrid::new(Vec3::ZERO, 1.0 / 80.0, [80; 3]).unwrap();
        let mut tree = BrickOctree::build(grid, &before);
        let report = tree.refresh_box(&after, q - r, q + r);
        assert!(
            report.bricks_sampled > 0 && report.bricks_sampled < 30,
            "{report:?}"
        );
        let fresh = BrickOctree::build(grid, &after);
        assert_same_bricks(&tree, &fresh);
        assert_eq!(closed_stats(&tree).euler_characteristic, 2);
    }

    #[test]
    fn changed_since_lists_only_refreshed_bricks() {
        let (mut lattice, _, _) = sphere_lattice(8.0);
        let grid = SampleGrid::for_lattice(&lattice, 2).unwrap();
        let mut tree = BrickOctree::build(grid, &lattice);
        let seen = tree.generation();
        assert_eq!(tree.changed_since(seen).count(), 0);
        let idx = lattice.index(6, 14, 14);
        lattice.coeffs.set_flat(idx, 1.0);
        let (min, max) = BrickOctree::coefficient_change_box(&lattice, [6, 14, 14], [6, 14, 14]);
        let report = tree.refresh_lattice(&lattice, min, max);
        let mut changed: Vec<_> = tree.changed_since(seen).map(|b| b.coord).collect();
        changed.sort_unstable();
        let mut reported = report.changed.clone();
        reported.sort_unstable();
        assert_eq!(changed, reported);
        assert!(!changed.is_empty() && changed.len() < tree.brick_count());
    }

    #[test]
    fn a_box_outside_the_grid_changes_nothing() {
        let field = sphere_fn(Vec3::splat(0.5), 0.3);
        let grid = SampleGrid::new(Vec3::ZERO, 1.0 / 32.0, [32; 3]).unwrap();
        let mut tree = BrickOctree::build(grid, &field);
        let before = tree.weld();
        let report = tree.refresh_box(&field, Vec3::splat(5.0), Vec3::splat(6.0));
        assert_eq!(report.bricks_sampled, 0);
        assert_eq!(tree.weld(), before);
    }

    #[test]
    fn sphere_at_512_cubed_fits_in_200_megabytes() {
        let (lattice, _, _) = sphere_lattice(56.5);
        let grid = SampleGrid::for_lattice(&lattice, 4).unwrap();
        assert_eq!(grid.cells, [512; 3]);
        let tree = BrickOctree::build(grid, &lattice);
        let memory = tree.memory();
        // Dense storage would be 513³ samples (540 MB) before any mesh.
        assert!(memory.total_bytes() < 200_000_000, "{memory:?}");
        assert!(tree.brick_count() < 64 * 64 * 64 / 8);
        assert!(tree.triangle_count() > 1_000_000);
    }

    #[test]
    fn jobs_run_z_then_y_then_x_and_lend_the_stored_bricks_for_dense_and_sparse_leaves() {
        let counts = [5, 7, 6];
        let all: Vec<[u32; 3]> = (0..6)
            .flat_map(|z| (0..7).flat_map(move |y| (0..5).map(move |x| [x, y, z])))
            .collect();
        // Every brick and every third (placed by a scan of the grid), every eleventh
        // (sorted); leaves in Morton order, as the descent lists them. Every fourth brick
        // of the grid is stored.
        let mut bricks: BTreeMap<u64, Brick> = all
            .iter()
            .step_by(4)
            .map(|&c| (morton(c), Brick::empty(c)))
            .collect();
        for keep_every in [1usize, 3, 11] {
            let mut leaves: Vec<[u32; 3]> = all.iter().copied().step_by(keep_every).collect();
            leaves.sort_unstable_by_key(|&c| morton(c));
            let stored: Vec<bool> = leaves
                .iter()
                .map(|&c| bricks.contains_key(&morton(c)))
                .collect();
            let jobs = lend_in_build_order(&leaves, counts, &mut bricks, &mut Vec::new());
            let mut expected = leaves.clone();
            expected.sort_unstable_by_key(|c| (c[2], c[1], c[0]));
            let coords: Vec<[u32; 3]> = jobs.iter().map(|j| j.coord).collect();
            assert_eq!(coords, expected, "every {keep_every}th brick");
            for job in &jobs {
                assert_eq!(leaves[job.leaf as usize], job.coord);
                assert_eq!(job.stored.is_some(), stored[job.leaf as usize]);
                if let Some(brick) = &job.stored {
                    assert_eq!(brick.coord, job.coord);
                }
            }
        }
    }

    #[test]
    fn morton_codes_keep_octree_nodes_contiguous() {
        // All 8 children of node (2,4,6) at size 2 fall in [morton(node), +8).
        let base = morton([2, 4, 6]);
        for c in 0..8u32 {
            let m = morton([2 + (c & 1), 4 + ((c >> 1) & 1), 6 + (c >> 2)]);
            assert!(m >= base && m < base + 8);
        }
        assert_eq!(morton([1, 0, 0]), 1);
        assert_eq!(morton([0, 1, 0]), 2);
        assert_eq!(morton([0, 0, 1]), 4);
        assert_eq!(morton([0x1f_ffff, 0, 0]), 0x1249_2492_4924_9249);
    }

    /// The weld's `set_len` and the threaded build under Miri (`cargo +nightly miri test -p
    /// dynaclay-core --lib miri_`): a small ball over a couple of bricks welds as the
    /// reference weld does, and two threads build the same bricks as one.
    #[test]
    fn miri_a_small_ball_welds_and_builds_on_two_threads_as_on_one() {
        let grid = SampleGrid::new(Vec3::ZERO, 1.0, [12, 12, 12]).unwrap();
        let ball = sphere_fn(Vec3::new(6.1, 5.7, 6.2), 3.3);
        let tree = BrickOctree::build(grid, &ball);
        assert!(tree.brick_count() >= 2);
        let welded = tree.weld();
        assert!(welded.triangle_count() > 50);
        assert_eq!(welded, tree.weld_by_hash());
        let many = BrickOctree::build_with_threads(grid, &ball, 2);
        assert_same_bricks(&tree, &many);
    }
}
