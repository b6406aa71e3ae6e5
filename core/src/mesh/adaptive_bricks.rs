//! The multi-level mesh cut into a [`BrickOctree`]'s bricks, so that whoever takes brick
//! meshes (a [`super::MeshSink`]: the window's renderer, the followers) draws a clay with
//! detail patches at each level's own spacing.
//!
//! An [`AdaptiveBricks`] keeps an [`AdaptiveMesher`] and, per brick of the octree, the
//! triangles (by vertex slot) whose centroid lies in that brick's box. Each brick's mesh
//! holds its triangles with a copy of every vertex they use, named by
//! [`super::shared_vertex_id`] of its slot, so a weld of all bricks
//! ([`BrickOctree::weld`], [`super::weld_pieces`]) gives back the mesher's welded mesh: closed
//! and crack-free across levels wherever the mesher's is.
//!
//! Local: after a change inside a box, [`AdaptiveMesher::remesh_box`] makes again only the
//! polygons near it and names the triangles it took away and made; only the bricks that
//! held or now hold one of those are meshed again and reported changed. A vertex made again
//! takes away every triangle that used it, so every brick holding a copy of a changed vertex
//! is among them: the copies never disagree.
//!
//! A new patch layout is local the same way ([`AdaptiveBricks::remesh_layout`]): only the
//! bricks near the patches that came, went or changed are cut again, unless the mesher's
//! frame moved and it meshed the whole clay.
//!
//! Not real-time: it allocates (the mesher's re-mesh and each changed brick's buffers).

use std::collections::HashMap;
use std::hash::BuildHasherDefault;

use glam::Vec3;

use super::adaptive::{
    AdaptiveMeshError, AdaptiveMeshOptions, AdaptiveMesher, AdaptiveRemeshReport, SlotTriangle,
    finish_flat_normals,
};
use super::brick::{BrickMesh, shared_vertex_id};
use super::octree::{BrickOctree, EdgeIdHasher, RefreshReport};
use crate::field::MultiPatchField;

/// Brick coordinates to what a brick holds, hashed by the octree's mixer rather than SipHash.
type ByBrick<T> = HashMap<[u32; 3], T, BuildHasherDefault<EdgeIdHasher>>;

/// The adaptive mesh of a multi-patch field, kept cut into the bricks of a [`BrickOctree`].
#[derive(Clone, Debug)]
pub struct AdaptiveBricks {
    mesher: AdaptiveMesher,
    /// Per brick coordinate: the triangles whose centroid its box holds.
    triangles: ByBrick<Vec<[u32; 3]>>,
    /// Per vertex slot: its index in the piece being made, [`NOT_IN_PIECE`] elsewhere.
    piece_index: Vec<u32>,
    /// Per vertex slot: `mark` where the last cut's re-mesh dropped its vertex, `mark + 1`
    /// where that cut removed a triangle using it and no dropped slot; older marks elsewhere.
    slot_marks: Vec<u32>,
    /// Counts the cuts by two, from 2 (0 marks no slot); where it wraps, every slot's mark is
    /// cleared.
    mark: u32,
}

/// Gives `slot` the mark `value`.
fn mark_slot(marks: &mut Vec<u32>, slot: u32, value: u32) {
    let s = slot as usize;
    if s >= marks.len() {
        marks.resize(s + 1, 0);
    }
    marks[s] = value;
}

/// The mark of `slot` (0 where it has none).
#[inline]
fn slot_mark(marks: &[u32], slot: u32) -> u32 {
    marks.get(slot as usize).copied().unwrap_or(0)
}

/// A slot that the piece being made does not use (yet).
const NOT_IN_PIECE: u32 = u32::MAX;

impl AdaptiveBricks {
    /// Meshes `field` whole with `options` and puts the mesh in `octree`'s bricks, in place
    /// of whatever they held (the report names every brick that changed or went).
    ///
    /// # Errors
    /// As [`AdaptiveMesher::new`]; then `octree` is left as it was.
    pub fn new(
        field: &MultiPatchField,
        options: &AdaptiveMeshOptions,
        octree: &mut BrickOctree,
    ) -> Result<(Self, RefreshReport), AdaptiveMeshError> {
        let mut cut = Self {
            mesher: AdaptiveMesher::new(field, options)?,
            triangles: ByBrick::default(),
            piece_index: Vec::new(),
            slot_marks: Vec::new(),
            mark: 0,
        };
        let report = cut.recut(octree);
        Ok((cut, report))
    }

    /// Meshes again after `field` changed inside the world box `lo ..= hi` only (see
    /// [`AdaptiveMesher::remesh_box`]) and puts the new pieces in `octree`: only the bricks
    /// that held or now hold a triangle made again are meshed again and reported. Where the
    /// mesher meshed the whole clay again (the patches' layout changed), every brick is.
    ///
    /// `octree` must be the one the pieces were put in last (or a new one: then call
    /// [`AdaptiveBricks::recut`] first).
    ///
    /// # Errors
    /// As [`AdaptiveMesher::remesh_box`]; then the kept mesh is empty and `octree` still
    /// holds the last pieces (a caller rebuilds it some other way).
    pub fn remesh_box(
        &mut self,
        field: &MultiPatchField,
        lo: Vec3,
        hi: Vec3,
        octree: &mut BrickOctree,
    ) -> Result<RefreshReport, AdaptiveMeshError> {
        let report = self.mesher.remesh_box(field, lo, hi);
        self.cut_again(report, octree)
    }

    /// Meshes again after `field`'s patch layout changed (see
    /// [`AdaptiveMesher::remesh_layout`]) and puts the new pieces in `octree`: only the
    /// bricks near the patches that came, went or changed are meshed again and reported,
    /// unless the octree's frame moved (then every brick is).
    ///
    /// # Errors
    /// As [`AdaptiveBricks::remesh_box`].
    pub fn remesh_layout(
        &mut self,
        field: &MultiPatchField,
        octree: &mut BrickOctree,
    ) -> Result<RefreshReport, AdaptiveMeshError> {
        let report = self.mesher.remesh_layout(field);
        self.cut_again(report, octree)
    }

    /// Puts in `octree` the pieces a re-mesh that gave `report` changed.
    fn cut_again(
        &mut self,
        report: Result<AdaptiveRemeshReport, AdaptiveMeshError>,
        octree: &mut BrickOctree,
    ) -> Result<RefreshReport, AdaptiveMeshError> {
        let report = match report {
            Ok(report) => report,
            Err(e) => {
                self.triangles.clear();
                return Err(e);
            }
        };
        if report.whole {
            return Ok(self.recut(octree));
        }
        // Taken away first: a slot freed by a removed triangle may name a vertex of a made one.
        // A kept triangle using a dropped slot was removed (its polygon was); the other
        // triangle of such a quad may use none: those are looked up among the removed
        // triangles that use no dropped slot, by brick and sorted, where all three of their
        // slots are so marked.
        // NOTE: every removed triangle sorted, and searched for from each kept one whose slots
        // all a removed one used, was about a tenth of the window's stroke re-mesh in
        // `bench/profile_adaptive.rs` (`1500 local 4 cut`).
        self.mark = self.mark.wrapping_add(2);
        if self.mark == 0 {
            self.slot_marks.fill(0);
            self.mark = 2;
        }
        let (dropped, kept_in_removed) = (self.mark, self.mark + 1);
        for &slot in self.mesher.dropped_slots() {
            mark_slot(&mut self.slot_marks, slot, dropped);
        }
        let mut dirty: Vec<[u32; 3]> = Vec::new();
        let mut without_dropped: Vec<([u32; 3], [u32; 3])> = Vec::new();
        for t in self.mesher.removed_triangles() {
            let coord = octree.brick_at(t.centroid);
            if dirty.last() != Some(&coord) {
                dirty.push(coord);
            }
            if !t
                .slots
                .iter()
                .any(|&s| slot_mark(&self.slot_marks, s) == dropped)
            {
                without_dropped.push((coord, t.slots));
                for &slot in &t.slots {
                    mark_slot(&mut self.slot_marks, slot, kept_in_removed);
                }
            }
        }
        dirty.sort_unstable();
        dirty.dedup();
        without_dropped.sort_unstable();
        let marks = &self.slot_marks;
        for &coord in &dirty {
            let from = without_dropped.partition_point(|g| g.0 < coord);
            let here = without_dropped[from..].partition_point(|g| g.0 == coord);
            let gone_here = &without_dropped[from..from + here];
            if let Some(held) = self.triangles.get_mut(&coord) {
                // A brick's triangles are distinct (each names its own slots).
                held.retain(|t| {
                    let mark = |s: u32| slot_mark(marks, s);
                    let removed = t.iter().any(|&s| mark(s) == dropped)
                        || (t.iter().all(|&s| mark(s) == kept_in_removed)
                            && gone_here.binary_search_by(|g| g.1.cmp(t)).is_ok());
                    !removed
                });
            }
        }
        let mesher = &self.mesher;
        // Consecutive made triangles mostly fall in one brick: its list is looked up once.
        let mut current: Option<([u32; 3], &mut Vec<[u32; 3]>)> = None;
        for t in mesher.made_triangles() {
            let coord = octree.brick_at(t.centroid);
            let held = match current.take() {
                Some((c, held)) if c == coord => held,
                _ => {
                    dirty.push(coord);
                    self.triangles.entry(coord).or_default()
                }
            };
            held.push(t.slots);
            current = Some((coord, held));
        }
        dirty.sort_unstable();
        dirty.dedup();
        Ok(self.put(octree, dirty))
    }

    /// Bins every triangle again into `octree`'s bricks and puts every brick's piece in it:
    /// after a whole mesh, or to move the mesh to a new octree (another grid). Bricks that
    /// held something else and get nothing are removed.
    pub fn recut(&mut self, octree: &mut BrickOctree) -> RefreshReport {
        self.triangles.clear();
        self.piece_index.clear();
        for SlotTriangle { slots, centroid } in self.mesher.triangles() {
            self.triangles
                .entry(octree.brick_at(centroid))
                .or_default()
                .push(slots);
        }
        let mut bricks: Vec<[u32; 3]> = octree
            .bricks()
            .map(|b| b.coord)
            .chain(self.triangles.keys().copied())
            .collect();
        bricks.sort_unstable();
        bricks.dedup();
        self.put(octree, bricks)
    }

    /// The kept mesher (its whole mesh, leaf count).
    #[must_use]
    pub fn mesher(&self) -> &AdaptiveMesher {
        &self.mesher
    }

    /// Meshes the bricks `coords` from their triangles and puts them in `octree` (a brick
    /// left without triangles is removed).
    fn put(&mut self, octree: &mut BrickOctree, coords: Vec<[u32; 3]>) -> RefreshReport {
        for c in &coords {
            if self.triangles.get(c).is_some_and(Vec::is_empty) {
                self.triangles.remove(c);
            }
        }
        let mesher = &self.mesher;
        let triangles = &self.triangles;
        let piece_index = &mut self.piece_index;
        let pieces = coords.into_iter().map(|c| {
            let mesh = triangles
                .get(&c)
                .map(|t| piece(mesher, t, piece_index))
                .unwrap_or_default();
            (c, mesh)
        });
        octree.put_pieces(pieces)
    }
}

/// One brick's mesh: its triangles, with a copy of each vertex they use, named by
/// [`shared_vertex_id`] of its slot.
///
/// A vertex where the field's gradient vanished (the mesher gives it no normal) takes the
/// area-weighted normal of its triangles in this brick (the mesher's whole mesh weighs all its
/// triangles; such vertices are rare and their copies can differ in normal, never in place).
///
/// `piece_index` is scratch, [`NOT_IN_PIECE`] for every slot before and after.
fn piece(mesher: &AdaptiveMesher, triangles: &[[u32; 3]], piece_index: &mut Vec<u32>) -> BrickMesh {
    let mut mesh = BrickMesh::default();
    mesh.indices.reserve(3 * triangles.len());
    // About one vertex per two triangles on a closed mesh, a few more along the brick's sides.
    let vertices = triangles.len() / 2 + 8;
    mesh.positions.reserve(vertices);
    mesh.normals.reserve(vertices);
    mesh.edge_ids.reserve(vertices);
    let mut slots: Vec<u32> = Vec::with_capacity(vertices);
    let mut flat = false;
    for t in triangles {
        for &slot in t {
            let s = slot as usize;
            if s >= piece_index.len() {
                piece_index.resize(s + 1, NOT_IN_PIECE);
            }
            if piece_index[s] == NOT_IN_PIECE {
                let (position, normal) =
                    mesher.slot_vertex(slot).unwrap_or((Vec3::ZERO, Vec3::ZERO));
                flat |= normal == Vec3::ZERO;
                piece_index[s] = mesh.positions.len() as u32;
                mesh.positions.push(position);
                mesh.normals.push(normal);
                mesh.edge_ids.push(shared_vertex_id(slot));
                slots.push(slot);
            }
            mesh.indices.push(piece_index[s]);
        }
    }
    for s in slots {
        piece_index[s as usize] = NOT_IN_PIECE;
    }
    if flat {
        let triangles = mesh.indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]]);
        finish_flat_normals(&mesh.positions, &mut mesh.normals, triangles);
    }
    mesh
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::super::adaptive::tests::{SPACING, dent, three_levels};
    use super::super::{BRICK_CELLS, MeshStats, SampleGrid, TriMesh};
    use super::*;

    fn options() -> AdaptiveMeshOptions {
        AdaptiveMeshOptions {
            cells_per_span: 2,
            detail_cells_per_span: 2,
            max_cells: 4_000_000,
        }
    }

    /// An octree over `field` at base cells of half a span (bricks of four base spans).
    fn octree_for(field: &MultiPatchField) -> BrickOctree {
        let (lo, hi) = field.support();
        BrickOctree::new(SampleGrid::covering(lo, hi, SPACING / 2.0).unwrap())
    }

    /// Asserts that `octree`'s bricks hold, per brick, what a fresh cut of `field` puts there,
    /// and that their weld is the mesher's whole mesh, closed and oriented.
    fn matches_fresh_cut(octree: &BrickOctree, field: &MultiPatchField) {
        let mut fresh = octree_for(field);
        let (whole, _) = AdaptiveBricks::new(field, &options(), &mut fresh).unwrap();
        assert_eq!(octree.brick_count(), fresh.brick_count());
        for brick in fresh.bricks() {
            let mine = octree
                .brick(brick.coord)
                .unwrap_or_else(|| panic!("brick {:?} missing", brick.coord));
            let one = |m: &BrickMesh| {
                (TriMesh {
                    positions: m.positions.clone(),
                    normals: m.normals.clone(),
                    triangles: m
                        .indices
                        .chunks_exact(3)
                        .map(|t| [t[0], t[1], t[2]])
                        .collect(),
                })
                .canonical_triangles()
            };
            assert_eq!(one(&mine.mesh), one(&brick.mesh), "brick {:?}", brick.coord);
        }
        let welded = octree.weld();
        assert_eq!(
            welded.canonical_triangles(),
            whole.mesher().mesh().canonical_triangles()
        );
        let s = MeshStats::of(&welded);
        assert_eq!(s.boundary_edges, 0, "{s:?}");
        assert_eq!(s.misoriented_edges, 0, "{s:?}");
    }

    /// How far from a changed box a reported brick may lie: a finest cell (the leaves that
    /// meet the box) and two base cells (a changed triangle's other vertices).
    const NEAR_CHANGE: f32 = SPACING / 8.0 + 2.0 * SPACING / 2.0;

    fn brick_span(octree: &BrickOctree) -> f32 {
        octree.grid().cell_size * BRICK_CELLS as f32
    }

    /// Every brick `report` changed or took away lies within [`NEAR_CHANGE`] of `lo ..= hi`.
    fn assert_reported_bricks_near(
        octree: &BrickOctree,
        report: &RefreshReport,
        lo: Vec3,
        hi: Vec3,
    ) {
        let span = brick_span(octree);
        for c in report.changed.iter().chain(&report.removed) {
            let b_lo = octree.grid().origin + span * Vec3::from_array(c.map(|v| v as f32));
            let b_hi = b_lo + span;
            assert!(
                b_lo.cmple(hi + NEAR_CHANGE).all() && b_hi.cmpge(lo - NEAR_CHANGE).all(),
                "brick {c:?} far from the change {lo} ..= {hi}"
            );
        }
    }

    #[test]
    fn the_bricks_weld_into_the_multi_level_mesh_closed_across_its_seams() {
        let field = three_levels();
        let mut octree = octree_for(&field);
        let (cut, report) = AdaptiveBricks::new(&field, &options(), &mut octree).unwrap();
        assert!(octree.is_cut());
        assert_eq!(report.changed.len(), octree.brick_count());
        assert!(report.removed.is_empty());
        assert!(octree.brick_count() > 8, "{} bricks", octree.brick_count());
        // Every triangle sits in the brick that holds its centroid.
        let span = octree.grid().cell_size * BRICK_CELLS as f32;
        for b in octree.bricks() {
            let lo = octree.grid().origin + span * Vec3::from_array(b.coord.map(|c| c as f32));
            for t in b.mesh.indices.chunks_exact(3) {
                let c = t
                    .iter()
                    .map(|&i| b.mesh.positions[i as usize])
                    .fold(Vec3::ZERO, |s, p| s + p)
                    / 3.0;
                assert!(c.cmpge(lo - 1e-5).all() && c.cmple(lo + span + 1e-5).all());
            }
        }
        // The weld is the mesher's mesh: the seams between levels and between bricks close.
        let welded = octree.weld();
        assert_eq!(
            welded.triangle_count(),
            cut.mesher().mesh().triangle_count()
        );
        assert_eq!(
            welded.positions.len(),
            cut.mesher().mesh().positions.len(),
            "each vertex's copies weld into one"
        );
        matches_fresh_cut(&octree, &field);
    }

    #[test]
    fn a_fine_stroke_changes_only_the_bricks_near_it_and_equals_a_fresh_cut() {
        let mut field = three_levels();
        let mut octree = octree_for(&field);
        let (mut cut, _) = AdaptiveBricks::new(&field, &options(), &mut octree).unwrap();
        let pole = 0.5 * Vec3::new(1.0, 0.05, 0.05).normalize();
        let (lo, hi) = dent(&mut field, 2, pole, 3, 0.05);
        let report = cut.remesh_box(&field, lo, hi, &mut octree).unwrap();
        assert!(!report.changed.is_empty());
        assert!(
            (report.changed.len() + report.removed.len()) * 4 < octree.brick_count(),
            "{} of {} bricks",
            report.changed.len() + report.removed.len(),
            octree.brick_count()
        );
        // A changed triangle uses a vertex made again, in a leaf meeting the box grown by a
        // finest cell; its other vertices lie within two base cells of it.
        assert_reported_bricks_near(&octree, &report, lo, hi);
        matches_fresh_cut(&octree, &field);
        // Versions: only the reported bricks carry the new generation.
        let fresh: Vec<[u32; 3]> = octree
            .changed_since(report.generation - 1)
            .map(|b| b.coord)
            .collect();
        assert_eq!(fresh.len(), report.changed.len());
    }

    #[test]
    fn strokes_and_undos_take_out_exactly_the_removed_triangles_from_the_bricks() {
        let mut field = three_levels();
        let original = field.clone();
        let mut octree = octree_for(&field);
        let (mut cut, _) = AdaptiveBricks::new(&field, &options(), &mut octree).unwrap();
        // Strokes on three levels, each followed by a cut compared with a fresh one; then back
        // to the first field in one re-mesh over all their boxes.
        let strokes: [(usize, Vec3, usize, f32); 3] = [
            (2, 0.5 * Vec3::new(1.0, 0.05, 0.05).normalize(), 3, 0.05),
            (1, 0.5 * Vec3::new(0.9, 0.3, -0.2).normalize(), 2, 0.2),
            (0, Vec3::new(0.0, 0.5, 0.0), 1, 0.3),
        ];
        let (mut all_lo, mut all_hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
        let mut quads_halved = 0;
        for (patch, at, count, depth) in strokes {
            let (lo, hi) = dent(&mut field, patch, at, count, depth);
            (all_lo, all_hi) = (all_lo.min(lo), all_hi.max(hi));
            cut.remesh_box(&field, lo, hi, &mut octree).unwrap();
            // The plain test: a removed triangle is one whose polygon used a dropped vertex;
            // some keep all three of their slots (the other half of a quad).
            let dropped = cut.mesher().dropped_slots();
            assert!(!dropped.is_empty());
            quads_halved += cut
                .mesher()
                .removed_triangles()
                .iter()
                .filter(|t| !t.slots.iter().any(|s| dropped.contains(s)))
                .count();
            matches_fresh_cut(&octree, &field);
        }
        assert!(
            quads_halved > 0,
            "every removed triangle used a dropped slot"
        );
        cut.remesh_box(&original, all_lo, all_hi, &mut octree)
            .unwrap();
        matches_fresh_cut(&octree, &original);
    }

    #[test]
    fn a_new_layout_is_cut_near_the_new_patch_and_a_rebuild_goes_back_to_marching_cubes() {
        let mut field = three_levels();
        let mut octree = octree_for(&field);
        let (mut cut, _) = AdaptiveBricks::new(&field, &options(), &mut octree).unwrap();
        let bricks_before = octree.brick_count();
        let d = field
            .refine(Vec3::new(-0.7, -0.2, -0.2), Vec3::new(-0.3, 0.2, 0.2), 1)
            .unwrap();
        let report = cut.remesh_layout(&field, &mut octree).unwrap();
        matches_fresh_cut(&octree, &field);
        // Only bricks near the new patch's support were cut again: a triangle taken out or
        // made has its vertices in leaves meeting the support grown by a finest cell, and
        // its centroid within two base cells of them.
        let (slo, shi) = field.patches[d].world_support();
        assert_reported_bricks_near(&octree, &report, slo, shi);
        let (span, reach) = (brick_span(&octree), NEAR_CHANGE);
        // and bricks far from it there are, kept as they were.
        let far = octree
            .bricks()
            .filter(|b| {
                let b_lo =
                    octree.grid().origin + span * Vec3::from_array(b.coord.map(|v| v as f32));
                b_lo.cmpgt(shi + reach).any() || (b_lo + span).cmplt(slo - reach).any()
            })
            .count();
        assert!(
            far * 4 >= bricks_before,
            "{far} of {bricks_before} bricks far"
        );
        // Its first stroke is local as ever.
        let (lo, hi) = dent(&mut field, d, Vec3::new(-0.5, 0.0, 0.0), 2, -0.2);
        let report = cut.remesh_box(&field, lo, hi, &mut octree).unwrap();
        assert!(!report.changed.is_empty());
        matches_fresh_cut(&octree, &field);
        // A level finer than every other moves the mesher's frame: every brick is cut again.
        field
            .refine(Vec3::new(0.4, -0.1, -0.1), Vec3::new(0.6, 0.1, 0.1), 3)
            .unwrap();
        let bricks_before = octree.brick_count();
        let report = cut.remesh_layout(&field, &mut octree).unwrap();
        assert!(report.changed.len() + report.removed.len() >= bricks_before);
        matches_fresh_cut(&octree, &field);

        // Back to one level: a rebuild meshes every brick by marching cubes again, and its
        // weld is the uniform mesh's.
        let report = octree.rebuild(&field);
        assert!(!octree.is_cut());
        assert_eq!(report.changed.len(), octree.brick_count());
        let mut uniform = octree_for(&field);
        uniform.rebuild(&field);
        assert_eq!(octree.weld(), uniform.weld());
    }
}
