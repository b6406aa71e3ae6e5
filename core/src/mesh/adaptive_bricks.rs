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
//! Not real-time: it allocates (the mesher's re-mesh and each changed brick's buffers).

use std::collections::{HashMap, HashSet};

use glam::Vec3;

use super::adaptive::{
    AdaptiveMeshError, AdaptiveMeshOptions, AdaptiveMesher, SlotTriangle, finish_flat_normals,
};
use super::brick::{BrickMesh, shared_vertex_id};
use super::octree::{BrickOctree, RefreshReport};
use crate::field::MultiPatchField;

/// The adaptive mesh of a multi-patch field, kept cut into the bricks of a [`BrickOctree`].
#[derive(Clone, Debug)]
pub struct AdaptiveBricks {
    mesher: AdaptiveMesher,
    /// Per brick coordinate: the triangles whose centroid its box holds.
    triangles: HashMap<[u32; 3], Vec<[u32; 3]>>,
}

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
            triangles: HashMap::new(),
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
        let report = match self.mesher.remesh_box(field, lo, hi) {
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
        let mut removed: HashMap<[u32; 3], HashSet<[u32; 3]>> = HashMap::new();
        for t in self.mesher.removed_triangles() {
            removed
                .entry(octree.brick_at(t.centroid))
                .or_default()
                .insert(t.slots);
        }
        let mut dirty: HashSet<[u32; 3]> = HashSet::with_capacity(removed.len());
        for (coord, gone) in &removed {
            if let Some(held) = self.triangles.get_mut(coord) {
                held.retain(|t| !gone.contains(t));
            }
            dirty.insert(*coord);
        }
        for t in self.mesher.made_triangles() {
            let coord = octree.brick_at(t.centroid);
            self.triangles.entry(coord).or_default().push(t.slots);
            dirty.insert(coord);
        }
        let mut dirty: Vec<[u32; 3]> = dirty.into_iter().collect();
        dirty.sort_unstable();
        Ok(self.put(octree, dirty))
    }

    /// Bins every triangle again into `octree`'s bricks and puts every brick's piece in it:
    /// after a whole mesh, or to move the mesh to a new octree (another grid). Bricks that
    /// held something else and get nothing are removed.
    pub fn recut(&mut self, octree: &mut BrickOctree) -> RefreshReport {
        self.triangles.clear();
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
        self.triangles.retain(|_, t| !t.is_empty());
        let mesher = &self.mesher;
        let triangles = &self.triangles;
        let pieces = coords.into_iter().map(|c| {
            let mesh = triangles
                .get(&c)
                .map(|t| piece(mesher, t))
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
fn piece(mesher: &AdaptiveMesher, triangles: &[[u32; 3]]) -> BrickMesh {
    let mut mesh = BrickMesh::default();
    let mut local: HashMap<u32, u32> = HashMap::with_capacity(triangles.len());
    mesh.indices.reserve(3 * triangles.len());
    let mut flat = false;
    for t in triangles {
        for &slot in t {
            let index = *local.entry(slot).or_insert_with(|| {
                let (position, normal) =
                    mesher.slot_vertex(slot).unwrap_or((Vec3::ZERO, Vec3::ZERO));
                flat |= normal == Vec3::ZERO;
                mesh.positions.push(position);
                mesh.normals.push(normal);
                mesh.edge_ids.push(shared_vertex_id(slot));
                (mesh.positions.len() - 1) as u32
            });
            mesh.indices.push(index);
        }
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
        let span = octree.grid().cell_size * BRICK_CELLS as f32;
        let reach = SPACING / 8.0 + 2.0 * SPACING / 2.0;
        for c in report.changed.iter().chain(&report.removed) {
            let b_lo = octree.grid().origin + span * Vec3::from_array(c.map(|v| v as f32));
            let b_hi = b_lo + span;
            assert!(
                b_lo.cmple(hi + reach).all() && b_hi.cmpge(lo - reach).all(),
                "brick {c:?} far from the change {lo} ..= {hi}"
            );
        }
        matches_fresh_cut(&octree, &field);
        // Versions: only the reported bricks carry the new generation.
        let fresh: Vec<[u32; 3]> = octree
            .changed_since(report.generation - 1)
            .map(|b| b.coord)
            .collect();
        assert_eq!(fresh.len(), report.changed.len());
    }

    #[test]
    fn a_new_layout_is_cut_whole_and_a_rebuild_goes_back_to_marching_cubes() {
        let mut field = three_levels();
        let mut octree = octree_for(&field);
        let (mut cut, _) = AdaptiveBricks::new(&field, &options(), &mut octree).unwrap();
        let d = field
            .refine(Vec3::new(-0.7, -0.2, -0.2), Vec3::new(-0.3, 0.2, 0.2), 1)
            .unwrap();
        let (lo, hi) = dent(&mut field, d, Vec3::new(-0.5, 0.0, 0.0), 2, -0.2);
        let bricks_before = octree.brick_count();
        let report = cut.remesh_box(&field, lo, hi, &mut octree).unwrap();
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
