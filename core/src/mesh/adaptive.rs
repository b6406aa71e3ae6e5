//! A multi-resolution mesher for the multi-patch field: each region is meshed at the finest
//! knot spacing of the patches that cover it, by octree dual contouring (Ju, Losasso,
//! Schaefer & Warren 2002, "Dual Contouring of Hermite Data").
//!
//! The octree's root is a cube around [`MultiPatchField::support`] with a margin of one
//! finest cell. A node is split while the field may cross the iso-level inside it (by the
//! convex-hull bound of [`super::ScalarField::bounds`], and a bound on the patches' slopes
//! over the node; a node the bounds show wholly inside or outside stays a leaf) and its edge
//! is longer than the target at the node: the smallest `world spacing / cells_per_span` of
//! the patches whose support meets it. Every leaf's edge is the root's divided by a power of
//! two, so every leaf corner lies on the integer lattice of the finest cell; corner samples
//! are keyed by those integer coordinates and taken once, so two leaves that share a corner
//! see the same value.
//!
//! Guarantees: the mesh is closed (the root's boundary counts as outside, whatever the
//! iso-level) and consistently oriented (triangles counter-clockwise seen from outside,
//! normals `−∇F/|∇F|` from the analytic gradient, taken where the vertex's last Newton step
//! started); it is welded by construction, one vertex per leaf that the surface crosses. Each
//! vertex lies in its leaf's box.
//!
//! Why there are no cracks between levels: polygons are not made per cell, as marching cubes
//! makes them, but per *minimal edge*: an edge of a leaf that no smaller leaf splits. The
//! recursive `cellProc`/`faceProc`/`edgeProc` traversal visits every minimal edge exactly
//! once, with the four leaves around it; where its two end samples differ in sign it joins
//! those leaves' vertices into one quad (a triangle where one larger leaf fills two of the four
//! places). A polygon edge joins the vertices of two leaves that share a face, and it belongs
//! to the polygons of the sign-changing minimal edges around that face; the face's corner
//! samples are shared by both leaves, whatever their sizes, so where the surface crosses the
//! face once there are exactly two such edges and two polygons on it. Nothing is made from
//! one side of a seam alone, so a change of level leaves no T-junction and no hole.
//!
//! A 2-manifold: as in the original method, one vertex per leaf cannot keep apart two sheets
//! that pass through one leaf: where a leaf face is ambiguous (its corners alternate in sign
//! around it, as where a saddle of the surface lies on the face, or a flat face of the clay
//! lies on the sample lattice) the two leaves' vertices are joined by an edge of four
//! triangles. [`mesh_adaptive`] then cuts the sheets apart with
//! [`super::split_non_manifold`]: the vertices there get one copy per sheet, at the same
//! place, so the mesh is closed, oriented and edge- and vertex-manifold, with the sheets
//! touching along the cut (manifold dual contouring, Schaefer, Ju & Warren 2007, would move
//! the copies apart inside the leaf; that is not done).
//!
//! Not real-time: it allocates (in proportion to its leaves, within
//! [`AdaptiveMeshOptions::max_cells`]) and samples the field point by point.
//!
//! Local re-meshing: an [`AdaptiveMesher`] keeps its octree, corner samples, vertices and
//! polygons between calls. After an edit, [`AdaptiveMesher::remesh_box`] is told the world
//! box outside which the field did not change (for changed coefficients, the union of their
//! supports: [`crate::field::Patch::coefficient_change_box`]). It decides again only the
//! nodes whose box meets that region (every split test reads the field inside its node's box
//! alone), samples again only the corners inside it, makes again the vertices of the leaves
//! that meet it or are new, drops the polygons that use a vertex made again or a leaf no
//! longer in the tree, and visits only the minimal edges that have such a leaf among their
//! four: every other minimal edge keeps its four leaves, its two end samples and its
//! vertices, so its polygon is the one a whole re-mesh would make. The result holds the
//! same triangles (the same vertex positions, bit for bit) as [`mesh_adaptive`] of the
//! edited field.
//!
//! A new patch layout is local too ([`AdaptiveMesher::remesh_layout`]): a patch that comes
//! or goes adds exactly zero beyond its support, so outside the supports of the patches that
//! came, went or changed every split test and sample is as before; those supports are
//! re-meshed as a changed box. Only where the octree's frame moves (a patch finer than every
//! other sets a new finest cell; a patch beyond the others' supports grows the root) is the
//! whole clay meshed again.
//!
//! What keeps a stroke-sized re-mesh short (`bench/mesh.rs` `adaptive_remesh`): the region
//! revisited is the change box grown by a 64th of a finest cell (more on a deep root: enough
//! for rounding), not by whole cells, so no shell of unchanged leaves around it is tested, sampled and meshed
//! again; the corners of the region (and two finest cells around it) are sampled together,
//! as a grid, by [`MultiPatchField::values_on_grid`] (the same values as one by one, each patch's weights
//! computed once per coordinate), and read back without a hash lookup; a count of their
//! inside corners over boxes (a summed-volume table) shows where a node, face or edge of the
//! traversal has corners all on one side, so no minimal edge there changes sign and the
//! traversal does not descend; the split tests read a node's block of coefficients from
//! window tables folded once per update over the coefficients near the region (a fold over
//! the block's rows, not its coefficients: `WindowTables`) and remember each patch's
//! blocks within one update, so the many small nodes of the region read the coarser
//! patches' blocks once; and the corner cache lives for one call (nothing of it needs
//! forgetting after an edit).

use std::collections::HashMap;
use std::hash::BuildHasherDefault;

use glam::{Affine3A, Vec3};

use super::manifold::split_non_manifold;
use super::octree::EdgeIdHasher;
use super::trimesh::TriMesh;
use crate::field::{MultiPatchField, Patch, larger, shared_ends, smaller};

/// Most levels below the root: corner coordinates then fit in 21 bits per axis.
pub const MAX_ADAPTIVE_DEPTH: u32 = 20;

/// How finely [`mesh_adaptive`] meshes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AdaptiveMeshOptions {
    /// Cells per knot span of the finest patch covering a region; at least 2.
    pub cells_per_span: u32,
    /// Most leaf cells the octree may hold; the mesher refuses with
    /// [`AdaptiveMeshError::OverBudget`] before it would split beyond this.
    pub max_cells: usize,
}

impl Default for AdaptiveMeshOptions {
    /// Two cells per span, at most 4 Mi leaves.
    fn default() -> Self {
        Self {
            cells_per_span: 2,
            max_cells: 1 << 22,
        }
    }
}

/// Why an adaptive mesh could not be made.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum AdaptiveMeshError {
    /// `cells_per_span` was below 2.
    #[error("cells per span must be at least 2, not {cells_per_span}")]
    CellsPerSpan {
        /// The value asked for.
        cells_per_span: u32,
    },
    /// The field has no patch to mesh.
    #[error("the field has no patch to mesh")]
    EmptyField,
    /// A patch's support or knot spacing is not a finite positive size.
    #[error("the field's support or knot spacing is not finite and positive")]
    BadField,
    /// The octree would need more than [`AdaptiveMeshOptions::max_cells`] leaves.
    #[error(
        "meshing needs more than {limit} leaf cells (refused at {leaves}); raise the budget or lower cells per span"
    )]
    OverBudget {
        /// The budget.
        limit: usize,
        /// Leaves the octree would have held after the refused split.
        leaves: usize,
    },
    /// The finest cell is too small for the field's extent.
    #[error(
        "the field spans {levels} octree levels of its finest cell, more than {MAX_ADAPTIVE_DEPTH}"
    )]
    TooDeep {
        /// Levels the root would need.
        levels: u32,
    },
    /// The change box given to [`AdaptiveMesher::remesh_box`] is not a finite box.
    #[error("the changed region {lo} ..= {hi} is not a finite box")]
    BadChangeBox {
        /// Its low corner.
        lo: Vec3,
        /// Its high corner.
        hi: Vec3,
    },
}

/// Builds the adaptive octree of `field` and dual-contours it into one welded mesh.
///
/// # Errors
/// [`AdaptiveMeshError`] on bad options, a field without patches or with a non-finite
/// support, a root deeper than [`MAX_ADAPTIVE_DEPTH`] levels, or more leaves than
/// `options.max_cells` (checked before each split, so nothing is allocated beyond it).
pub fn mesh_adaptive(
    field: &MultiPatchField,
    options: &AdaptiveMeshOptions,
) -> Result<TriMesh, AdaptiveMeshError> {
    AdaptiveMesher::new(field, options).map(|m| {
        let mut mesh = m.mesh();
        split_non_manifold(&mut mesh);
        mesh
    })
}

/// The number of leaf cells [`mesh_adaptive`] would build for `field`, without sampling
/// the field at any corner or meshing; costs the bound queries of the octree's descent and
/// the tree's nodes.
///
/// # Errors
/// As [`mesh_adaptive`] (so over the budget, [`AdaptiveMeshError::OverBudget`]).
pub fn adaptive_cell_count(
    field: &MultiPatchField,
    options: &AdaptiveMeshOptions,
) -> Result<usize, AdaptiveMeshError> {
    Tree::build(field, options).map(|t| t.leaves)
}

/// What one [`AdaptiveMesher::remesh_box`] did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct AdaptiveRemeshReport {
    /// The whole clay was meshed again: the octree's frame moved with the patches' layout,
    /// or the iso-level changed, or the last call had failed.
    pub whole: bool,
    /// The patches' layout changed and the supports of the patches that came, went or
    /// changed were meshed again locally, with the changed box.
    pub new_layout: bool,
    /// Leaves of the updated tree whose box meets the changed region or that are new: the
    /// leaves whose vertex and polygons were made again.
    pub leaves_revisited: usize,
    /// Leaves in the whole tree after the call.
    pub leaves: usize,
    /// Vertices made.
    pub vertices_made: usize,
    /// Polygons (quads or triangles) dropped from the kept mesh.
    pub polygons_dropped: usize,
    /// Polygons made.
    pub polygons_made: usize,
}

/// A multi-level mesh kept between edits: its octree, corner samples, vertices and polygons,
/// so that after a stroke only the leaves near the change are meshed again
/// ([`AdaptiveMesher::remesh_box`]).
///
/// Not real-time: a re-mesh allocates (new nodes, vertices, polygons, the output mesh).
#[derive(Clone, Debug)]
pub struct AdaptiveMesher {
    options: AdaptiveMeshOptions,
    tree: Tree,
    /// What fixes the tree's frame: each patch's lattice shape and map, and the iso-level.
    frame: Vec<PatchFrame>,
    iso: f32,
    /// Field value per integer corner (packed 21 bits per axis), sampled once within one
    /// call (a whole mesh, or a local re-mesh's corners beyond its region's block) and
    /// emptied after it: no sample outlives the field it was taken of. Keys are mixed by
    /// SplitMix64's finaliser rather than SipHash: the table is looked up twice per minimal
    /// edge and eight times per vertex.
    // NOTE: kept across calls, this cache made a local re-mesh drop every corner of its
    // block from it (a hash removal per corner, most of them absent) and put the used ones
    // back: about a tenth of the re-mesh in `bench/profile_adaptive.rs` at 4 cells per
    // span. Corners beyond the block are few and sampled again instead.
    corners: HashMap<u64, f32, BuildHasherDefault<EdgeIdHasher>>,
    /// Vertex slot per node (leaves only), [`NO_VERTEX`] until made.
    vertex_of: Vec<u32>,
    /// Per node: the re-mesh that created it (or collapsed it into a leaf).
    touched: Vec<u32>,
    /// Counts re-meshes; nodes touched by the current one carry its number.
    generation: u32,
    vertices: VertexSlots,
    /// Each minimal edge's polygon: the vertex slots of its four leaves in [`AROUND`] order,
    /// counter-clockwise seen from outside (a leaf that fills two places appears twice),
    /// kept in buckets by where the edge lies.
    polygons: PolygonBuckets,
    /// The integer box (inclusive) of the leaves whose vertex this call dropped: every
    /// polygon that used one lies on such a leaf's box.
    forgotten: Option<([u32; 3], [u32; 3])>,
    /// The last re-mesh failed part way: the next one meshes the whole clay.
    stale: bool,
    /// The triangles the last call took out of the kept mesh, with their centroids where
    /// they were (see [`AdaptiveMesher::removed_triangles`]).
    removed: Vec<SlotTriangle>,
    /// The vertex slots the last local re-mesh dropped (see
    /// [`AdaptiveMesher::dropped_slots`]).
    dropped: Vec<u32>,
    /// The polygons the last local re-mesh made (after a whole mesh, every polygon is new and
    /// this is empty).
    made: Vec<[u32; 4]>,
    /// The last call meshed the whole clay.
    made_whole: bool,
    /// The split tests' coefficient reads, kept within one update of the tree.
    reads: CoefficientReads,
    /// A local re-mesh's corner samples inside its region, taken together.
    region_samples: RegionSamples,
}

/// A triangle of an [`AdaptiveMesher`]'s kept mesh, named by the slots of its vertices
/// ([`AdaptiveMesher::slot_vertex`]), counter-clockwise seen from outside, with its centroid.
///
/// A slot names one vertex for as long as the vertex lives; a re-mesh that makes a vertex
/// again takes away every triangle that used the old one, and a later vertex may take the
/// freed slot.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SlotTriangle {
    /// The vertex slots.
    pub slots: [u32; 3],
    /// The mean of its three vertices' positions.
    pub centroid: Vec3,
}

/// How a field's patches differ from those a kept mesh was made of.
#[derive(Clone, Copy, Debug, PartialEq)]
enum LayoutChange {
    /// The same patches.
    Same,
    /// The octree's frame (its origin, finest cell or root) moved, or the iso-level changed.
    Frame,
    /// Some patches came, went or changed inside the world box `lo ..= hi` (the union of
    /// their supports), in the same frame.
    Patches { lo: Vec3, hi: Vec3 },
}

/// The shape of one patch that the octree's frame and targets depend on.
#[derive(Clone, Debug, PartialEq)]
struct PatchFrame {
    dims: [usize; 3],
    origin: Vec3,
    spacing: f32,
    world_to_patch: Affine3A,
}

impl PatchFrame {
    fn of(patch: &Patch) -> Self {
        Self {
            dims: patch.lattice.dims,
            origin: patch.lattice.origin,
            spacing: patch.lattice.spacing,
            world_to_patch: patch.world_to_patch,
        }
    }
}

/// Vertices by slot; a slot freed by a re-mesh is reused by a later vertex.
#[derive(Clone, Debug, Default)]
struct VertexSlots {
    positions: Vec<Vec3>,
    normals: Vec<Vec3>,
    /// World edge length of the leaf each vertex belongs to.
    cells: Vec<f32>,
    alive: Vec<bool>,
    free: Vec<u32>,
}

impl VertexSlots {
    fn add(&mut self, position: Vec3, normal: Vec3, cell: f32) -> u32 {
        if let Some(slot) = self.free.pop() {
            let s = slot as usize;
            self.positions[s] = position;
            self.normals[s] = normal;
            self.cells[s] = cell;
            self.alive[s] = true;
            return slot;
        }
        self.positions.push(position);
        self.normals.push(normal);
        self.cells.push(cell);
        self.alive.push(true);
        (self.positions.len() - 1) as u32
    }

    fn remove(&mut self, slot: u32) {
        self.alive[slot as usize] = false;
        self.free.push(slot);
    }
}

/// What an extraction produced: the mesh and, per vertex, the edge of its leaf.
#[derive(Clone, Debug, Default)]
struct Extraction {
    mesh: TriMesh,
    /// World edge length of the leaf each vertex belongs to.
    vertex_cells: Vec<f32>,
}

/// The integer corners of the region a re-mesh revisits: a node meets it when its closed
/// box reaches `lo` and starts at or below `hi` along every axis, so the nodes that meet it
/// are those whose closed box meets the change box grown by [`Region::slack_cells`] on every
/// side (every node whose bound query or samples may read a changed coefficient, whatever
/// the rounding of the box's and the nodes' world coordinates). Along an axis where the grown
/// box lies within one cell's open interior, `lo` is `hi + 1`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Region {
    lo: [i64; 3],
    hi: [i64; 3],
}

impl Region {
    /// How far, in finest cells, the change box is grown before it is rounded to the lattice,
    /// where the coordinates involved (the box's, the root's, the origin's, in cells) are at
    /// most `magnitude`: a 64th of a cell and 2^-18 of the magnitude, which is many times the
    /// rounding of `f32` world coordinates of that size (2^-23 of it per operation) and, for
    /// a root of up to 2^12 cells, under a fiftieth of a cell.
    // NOTE: a whole finest cell here (the region rounded outward and grown by one more)
    // revisited a shell of leaves around the change box whose split tests, corners and
    // vertices cannot change: the window's stroke re-mesh (`bench/mesh.rs` `graphics_stroke`)
    // took 1.3 times as long with it, in one loaded run.
    fn slack_cells(magnitude: f64) -> f64 {
        1.0 / 64.0 + magnitude * (-18.0_f64).exp2()
    }

    /// The region of the change box whose corners are `a ..= b` in (fractional) finest cells
    /// from the octree's origin, `origin` cells from the world's, clamped to a little beyond
    /// the root of `root_size` cells (so a far box stays a valid region that no node meets).
    fn of_cells(a: [f64; 3], b: [f64; 3], origin: [f64; 3], root_size: u32) -> Self {
        let magnitude = a
            .iter()
            .chain(&b)
            .chain(&origin)
            .map(|v| v.abs())
            .fold(f64::from(root_size), f64::max);
        let slack = Self::slack_cells(magnitude);
        let limit = f64::from(root_size) + 2.0;
        let clamp = |v: f64| v.clamp(-2.0, limit) as i64;
        // The lowest (highest) corner a node reaching the grown box may end (start) at.
        Self {
            lo: std::array::from_fn(|k| clamp((a[k] - slack).ceil())),
            hi: std::array::from_fn(|k| clamp((b[k] + slack).floor())),
        }
    }

    #[inline]
    fn meets(&self, node: &Node) -> bool {
        let meets_along = |a: usize| {
            let min = i64::from(node.min[a]);
            min <= self.hi[a] && min + i64::from(node.size) >= self.lo[a]
        };
        meets_along(0) && meets_along(1) && meets_along(2)
    }
}

impl AdaptiveMesher {
    /// Builds the octree of `field` and meshes it whole.
    ///
    /// # Errors
    /// As [`mesh_adaptive`].
    pub fn new(
        field: &MultiPatchField,
        options: &AdaptiveMeshOptions,
    ) -> Result<Self, AdaptiveMeshError> {
        let tree = Tree::frame(field, options)?;
        let mut mesher = Self {
            options: *options,
            tree,
            frame: field.patches.iter().map(PatchFrame::of).collect(),
            iso: field.iso(),
            corners: HashMap::default(),
            vertex_of: vec![NO_VERTEX],
            touched: vec![0],
            generation: 0,
            vertices: VertexSlots::default(),
            polygons: PolygonBuckets::default(),
            forgotten: None,
            stale: false,
            removed: Vec::new(),
            dropped: Vec::new(),
            made: Vec::new(),
            made_whole: true,
            reads: CoefficientReads::default(),
            region_samples: RegionSamples::default(),
        };
        mesher.update_tree(field, None)?;
        mesher.cell_proc(field, None, 0);
        mesher.corners = HashMap::default();
        mesher.forgotten = None;
        Ok(mesher)
    }

    /// Meshes again after `field` changed inside the world box `lo ..= hi` only (outside it
    /// every patch's value is as before): the nodes, corners, vertices and polygons near the
    /// box are made again and spliced into the kept mesh, which then equals what
    /// [`mesh_adaptive`] makes of `field`. Where the patches' layout changed too, the
    /// supports of the patches that came, went or changed are re-meshed with the box (see
    /// [`AdaptiveMesher::remesh_layout`]); where that moved the octree's frame, or the
    /// iso-level changed, or the last call failed, the whole clay is meshed again.
    ///
    /// # Errors
    /// [`AdaptiveMeshError::BadChangeBox`] for a box with a non-finite corner; otherwise as
    /// [`mesh_adaptive`] (over the budget, the mesher is left empty and the next call meshes
    /// the whole clay).
    pub fn remesh_box(
        &mut self,
        field: &MultiPatchField,
        lo: Vec3,
        hi: Vec3,
    ) -> Result<AdaptiveRemeshReport, AdaptiveMeshError> {
        if !(lo.is_finite() && hi.is_finite()) {
            return Err(AdaptiveMeshError::BadChangeBox { lo, hi });
        }
        self.remesh(field, Some((lo, hi)))
    }

    /// Meshes again after `field`'s patch layout changed (a patch added, removed or given
    /// another lattice or map) while every patch that kept its place kept its values: as
    /// [`AdaptiveMesher::remesh_box`] with the supports of the patches that came, went or
    /// changed as the changed box. Where the octree's frame moved (a patch finer than every
    /// other, a support beyond the clay's), or the iso-level changed, or the last call failed,
    /// the whole clay is meshed again.
    ///
    /// # Errors
    /// As [`mesh_adaptive`] (over the budget, the mesher is left empty and the next call
    /// meshes the whole clay).
    pub fn remesh_layout(
        &mut self,
        field: &MultiPatchField,
    ) -> Result<AdaptiveRemeshReport, AdaptiveMeshError> {
        self.remesh(field, None)
    }

    /// [`AdaptiveMesher::remesh_box`] of `change` (none: only the layout's change).
    fn remesh(
        &mut self,
        field: &MultiPatchField,
        change: Option<(Vec3, Vec3)>,
    ) -> Result<AdaptiveRemeshReport, AdaptiveMeshError> {
        let layout = if self.stale || field.iso() != self.iso {
            LayoutChange::Frame
        } else {
            self.layout_change(field)
        };
        let (lo, hi, new_layout) = match (layout, change) {
            (LayoutChange::Frame, _) => return self.remesh_whole(field),
            (LayoutChange::Same, Some((lo, hi))) => (lo, hi, false),
            (LayoutChange::Same, None) => (Vec3::ONE, Vec3::ZERO, false),
            (LayoutChange::Patches { lo, hi }, None) => (lo, hi, true),
            (LayoutChange::Patches { lo, hi }, Some((a, b))) if a.cmple(b).all() => {
                (lo.min(a), hi.max(b), true)
            }
            (LayoutChange::Patches { lo, hi }, Some(_)) => (lo, hi, true),
        };
        let mut report = self.remesh_region(field, lo, hi)?;
        report.new_layout = new_layout;
        Ok(report)
    }

    /// How `field`'s patches differ from those the kept mesh was made of; where only some
    /// patches differ and the octree's frame stays, the tree takes the new patches' targets.
    fn layout_change(&mut self, field: &MultiPatchField) -> LayoutChange {
        let frames: Vec<PatchFrame> = field.patches.iter().map(PatchFrame::of).collect();
        if frames == self.frame {
            return LayoutChange::Same;
        }
        let Ok(tree) = Tree::frame(field, &self.options) else {
            return LayoutChange::Frame;
        };
        let same =
            |a: Vec3, b: Vec3| a.to_array().map(f32::to_bits) == b.to_array().map(f32::to_bits);
        if !(same(tree.origin, self.tree.origin)
            && tree.unit.to_bits() == self.tree.unit.to_bits()
            && tree.root_size == self.tree.root_size)
        {
            return LayoutChange::Frame;
        }
        // The patches before the first difference and after the last keep their terms: a
        // patch that came or went adds exactly zero beyond its support, so outside the
        // supports of the patches between, every sum of terms (the field's value, gradient
        // and bounds) is the same, bit for bit.
        let (old, new) = (&self.frame, &frames);
        let (prefix, suffix) = shared_ends(old, new, PartialEq::eq);
        let gone = &self.tree.targets[prefix..old.len() - suffix];
        let came = &tree.targets[prefix..new.len() - suffix];
        let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
        for &(slo, shi, _) in gone.iter().chain(came) {
            lo = lo.min(slo);
            hi = hi.max(shi);
        }
        self.frame = frames;
        self.tree.targets = tree.targets;
        self.tree.floors = tree.floors;
        LayoutChange::Patches { lo, hi }
    }

    /// Meshes `field` whole in place of the kept mesh.
    fn remesh_whole(
        &mut self,
        field: &MultiPatchField,
    ) -> Result<AdaptiveRemeshReport, AdaptiveMeshError> {
        let options = self.options;
        // The kept mesh goes before the new one is made, so the two are never held at once.
        // (It is not what sets the peak of `bench/strokes1000.py`'s session: 2 532 324 kB
        // before this, 2 532 500 kB after, the same sculpt.)
        if let Ok(root) = Tree::frame(field, &options) {
            self.clear_after_failure();
            self.tree = root;
            self.vertex_of = vec![NO_VERTEX];
            self.touched = vec![0];
            self.corners = HashMap::default();
            self.polygons = PolygonBuckets::default();
            self.removed = Vec::new();
            self.dropped = Vec::new();
            self.made = Vec::new();
            self.reads = CoefficientReads::default();
            self.region_samples = RegionSamples::default();
        }
        *self = match Self::new(field, &options) {
            Ok(whole) => whole,
            Err(e) => {
                self.clear_after_failure();
                return Err(e);
            }
        };
        Ok(AdaptiveRemeshReport {
            whole: true,
            new_layout: false,
            leaves_revisited: self.tree.leaves,
            leaves: self.tree.leaves,
            vertices_made: self.vertices.positions.len(),
            polygons_dropped: 0,
            polygons_made: self.polygons.count,
        })
    }

    /// The local re-mesh of the world box `lo ..= hi` (none for an empty box), in the kept
    /// frame.
    fn remesh_region(
        &mut self,
        field: &MultiPatchField,
        lo: Vec3,
        hi: Vec3,
    ) -> Result<AdaptiveRemeshReport, AdaptiveMeshError> {
        let mut report = AdaptiveRemeshReport::default();
        self.removed.clear();
        self.dropped.clear();
        self.made.clear();
        self.made_whole = false;
        if lo.cmpgt(hi).any() {
            report.leaves = self.tree.leaves;
            return Ok(report);
        }
        self.generation += 1;
        let region = self.region(lo, hi);
        self.corners.clear();
        // A region too large for one block has its corners sampled one by one.
        self.sample_region(field, &region);
        report.leaves_revisited = match self.update_tree(field, Some(&region)) {
            Ok(n) => n,
            Err(e) => {
                self.clear_after_failure();
                return Err(e);
            }
        };
        let kept_vertices = self.vertices.positions.len() - self.vertices.free.len();
        // A dropped vertex's slot keeps its position until a vertex made below takes it, so
        // the dropped triangles are named here, split as they were made.
        if let Some((lo, hi)) = self.forgotten.take() {
            let (alive, positions) = (&self.vertices.alive, &self.vertices.positions);
            let removed = &mut self.removed;
            report.polygons_dropped = self.polygons.drop_where(lo, hi, |p| {
                let kept = p.iter().all(|&v| alive[v as usize]);
                if !kept {
                    removed.extend(slot_triangles(*p, positions));
                }
                !kept
            });
        }
        self.cell_proc(field, Some(&region), 0);
        self.region_samples.dims = [0; 3];
        self.corners.clear();
        report.polygons_made = self.made.len();
        report.vertices_made =
            self.vertices.positions.len() - self.vertices.free.len() - kept_vertices;
        report.leaves = self.tree.leaves;
        Ok(report)
    }

    /// The kept mesh's triangles by vertex slot, the ones [`AdaptiveMesher::mesh`] holds (the
    /// same split of each polygon, in the same order).
    pub fn triangles(&self) -> impl Iterator<Item = SlotTriangle> + '_ {
        let positions = &self.vertices.positions;
        self.polygons
            .iter()
            .flat_map(move |p| slot_triangles(*p, positions))
    }

    /// The triangles the last [`AdaptiveMesher::remesh_box`] made (after a whole mesh, every
    /// triangle).
    pub fn made_triangles(&self) -> impl Iterator<Item = SlotTriangle> + '_ {
        let positions = &self.vertices.positions;
        let made: &[[u32; 4]] = if self.made_whole { &[] } else { &self.made };
        let all = self
            .made_whole
            .then(|| self.polygons.iter())
            .into_iter()
            .flatten();
        made.iter()
            .chain(all)
            .flat_map(move |p| slot_triangles(*p, positions))
    }

    /// The triangles the last [`AdaptiveMesher::remesh_box`] took out of the kept mesh (none
    /// after a whole mesh: then the whole mesh is new), each with its centroid where it
    /// was; their slots may name other vertices now.
    #[must_use]
    pub fn removed_triangles(&self) -> &[SlotTriangle] {
        &self.removed
    }

    /// The vertex slots whose vertex the last local re-mesh dropped (none after a whole
    /// mesh), each once: every kept triangle that used one is among
    /// [`AdaptiveMesher::removed_triangles`] (with the other triangle of its quad, which may
    /// use none). A later vertex of the same re-mesh may have taken the slot.
    pub(super) fn dropped_slots(&self) -> &[u32] {
        &self.dropped
    }

    /// The position and unit normal of the vertex in `slot`, while it lives. The normal is
    /// zero where the field's gradient vanished ([`AdaptiveMesher::mesh`] gives such a vertex
    /// its triangles' area-weighted normal).
    #[must_use]
    pub fn slot_vertex(&self, slot: u32) -> Option<(Vec3, Vec3)> {
        let s = slot as usize;
        self.vertices
            .alive
            .get(s)
            .copied()
            .unwrap_or(false)
            .then(|| (self.vertices.positions[s], self.vertices.normals[s]))
    }

    /// Leaves in the octree.
    #[must_use]
    pub fn leaf_count(&self) -> usize {
        self.tree.leaves
    }

    /// The kept mesh, welded and compact (vertices in slot order). Closed and oriented, but
    /// where two sheets pass through one leaf an edge carries four triangles: run
    /// [`super::split_non_manifold`] on it (as [`mesh_adaptive`] does) before export.
    #[must_use]
    pub fn mesh(&self) -> TriMesh {
        self.extraction().mesh
    }

    fn extraction(&self) -> Extraction {
        let slots = &self.vertices;
        let mut index = vec![NO_VERTEX; slots.positions.len()];
        let vertices = slots.positions.len() - slots.free.len();
        let mut out = Extraction {
            mesh: TriMesh {
                positions: Vec::with_capacity(vertices),
                normals: Vec::with_capacity(vertices),
                triangles: Vec::with_capacity(2 * self.polygons.count),
            },
            vertex_cells: Vec::with_capacity(vertices),
        };
        for (s, _) in slots.alive.iter().enumerate().filter(|(_, a)| **a) {
            index[s] = out.mesh.positions.len() as u32;
            out.mesh.positions.push(slots.positions[s]);
            out.mesh.normals.push(slots.normals[s]);
            out.vertex_cells.push(slots.cells[s]);
        }
        for polygon in self.polygons.iter() {
            triangulate(
                polygon.map(|s| index[s as usize]),
                &out.mesh.positions,
                &mut out.mesh.triangles,
            );
        }
        finish_normals(&mut out.mesh);
        out
    }

    /// The integer region of the world box `lo ..= hi` (see [`Region`]).
    fn region(&self, lo: Vec3, hi: Vec3) -> Region {
        let unit = f64::from(self.tree.unit);
        let origin = self.tree.origin.to_array().map(f64::from);
        let to_cells = |x: Vec3| std::array::from_fn(|k| (f64::from(x[k]) - origin[k]) / unit);
        let origin_cells = origin.map(|o| o / unit);
        Region::of_cells(
            to_cells(lo),
            to_cells(hi),
            origin_cells,
            self.tree.root_size,
        )
    }

    /// Samples every corner of `region` (clamped to the root) at once, where it holds at most
    /// [`RegionSamples::MAX_CORNERS`]: the corner samples of this re-mesh inside the region
    /// are then read from that block (see [`AdaptiveMesher::corner_value`]). A larger region
    /// gets no block: its corners are sampled one by one.
    fn sample_region(&mut self, field: &MultiPatchField, region: &Region) {
        let samples = &mut self.region_samples;
        samples.dims = [0; 3];
        let root = i64::from(self.tree.root_size);
        let margin = RegionSamples::MARGIN;
        let lo = region.lo.map(|v| (v - margin).clamp(0, root));
        let hi = region.hi.map(|v| (v + margin).clamp(0, root));
        if (0..3).any(|a| lo[a] > hi[a]) {
            // The region lies beyond the root: no corner of the tree is in it.
            return;
        }
        let dims: [usize; 3] = std::array::from_fn(|a| (hi[a] - lo[a] + 1) as usize);
        let count = dims.iter().product::<usize>();
        if count > RegionSamples::MAX_CORNERS {
            return;
        }
        // The corners' world coordinates along each axis, as `Tree::point` computes them.
        let coords = |a: usize, out: &mut Vec<f32>| {
            out.clear();
            out.extend((lo[a]..=hi[a]).map(|c| self.tree.origin[a] + self.tree.unit * c as f32));
        };
        coords(0, &mut samples.xs);
        coords(1, &mut samples.ys);
        coords(2, &mut samples.zs);
        samples.values.resize(count, 0.0);
        field.values_on_grid_with(
            &samples.xs,
            &samples.ys,
            &samples.zs,
            &mut samples.values,
            &mut samples.term,
        );
        // On the root's boundary no more than the iso-level (as `corner_value`).
        let on_boundary = (0..3).any(|a| lo[a] == 0 || hi[a] == root);
        let mut at = 0;
        for z in (lo[2]..=hi[2]).filter(|_| on_boundary) {
            for y in lo[1]..=hi[1] {
                for x in lo[0]..=hi[0] {
                    if [x, y, z].iter().any(|&c| c == 0 || c == root) {
                        samples.values[at] = samples.values[at].min(self.iso);
                    }
                    at += 1;
                }
            }
        }
        samples.lo = lo.map(|v| v as u32);
        samples.dims = dims;
        samples.count_inside(self.iso);
    }

    /// After a failed re-mesh: an empty mesh, and the next call meshes the whole clay.
    fn clear_after_failure(&mut self) {
        self.region_samples.dims = [0; 3];
        self.corners.clear();
        self.stale = true;
        self.removed.clear();
        self.dropped.clear();
        self.made.clear();
        self.made_whole = true;
        self.forgotten = None;
        self.polygons.clear();
        self.vertices = VertexSlots::default();
        self.vertex_of.iter_mut().for_each(|v| *v = NO_VERTEX);
    }

    /// Decides again whether each node meeting `region` (every node when `None`) splits,
    /// growing new subtrees in full and collapsing subtrees no longer needed; leaves meeting
    /// the region lose their vertex. Returns the leaves revisited: those meeting the region
    /// or new.
    fn update_tree(
        &mut self,
        field: &MultiPatchField,
        region: Option<&Region>,
    ) -> Result<usize, AdaptiveMeshError> {
        let mut revisited = 0;
        // The coefficients may have changed since the last update.
        self.reads.clear();
        self.reads.remember = region.is_some();
        if let Some(r) = region {
            // The small nodes of the region, and those reaching a little beyond it, read
            // their blocks from the window tables.
            let at = |p: [i64; 3]| {
                self.tree.origin + self.tree.unit * Vec3::new(p[0] as f32, p[1] as f32, p[2] as f32)
            };
            let reach = Vec3::splat(WindowTables::REACH_CELLS * self.tree.unit);
            self.reads
                .prepare_windows(field, at(r.lo) - reach, at(r.hi) + reach);
        }
        // (node, new in this call)
        let mut stack = vec![(0_u32, region.is_none())];
        while let Some((n, fresh)) = stack.pop() {
            let node = self.tree.nodes[n as usize];
            if !fresh && !region.is_some_and(|r| r.meets(&node)) {
                continue;
            }
            let split = self.tree.should_split(
                field,
                &node,
                region,
                &mut self.reads,
                Some(&self.region_samples),
            );
            if split {
                if node.is_leaf() {
                    self.forget_vertex(n);
                    let first = self.split(n)?;
                    stack.extend((0..8).map(|c| (first + c, true)));
                } else {
                    stack.extend((0..8).map(|c| (node.children + c, false)));
                }
            } else {
                if !node.is_leaf() {
                    self.collapse(n);
                }
                self.forget_vertex(n);
                revisited += 1;
            }
        }
        Ok(revisited)
    }

    /// Splits leaf `n` into eight new leaves (reusing a freed block of nodes when there is
    /// one); returns the first child.
    fn split(&mut self, n: u32) -> Result<u32, AdaptiveMeshError> {
        let tree = &mut self.tree;
        if tree.leaves + 7 > self.options.max_cells {
            return Err(AdaptiveMeshError::OverBudget {
                limit: self.options.max_cells,
                leaves: tree.leaves + 7,
            });
        }
        let node = tree.nodes[n as usize];
        let half = node.size / 2;
        let first = match tree.free_blocks.pop() {
            Some(first) => first,
            None => {
                let first = tree.nodes.len() as u32;
                let blank = Node {
                    min: [0; 3],
                    size: 0,
                    children: 0,
                };
                tree.nodes.extend([blank; 8]);
                self.vertex_of.extend([NO_VERTEX; 8]);
                self.touched.extend([0; 8]);
                first
            }
        };
        for c in 0..8_u32 {
            let at = (first + c) as usize;
            tree.nodes[at] = Node {
                min: std::array::from_fn(|a| node.min[a] + half * ((c >> a) & 1)),
                size: half,
                children: 0,
            };
            self.touched[at] = self.generation;
        }
        tree.nodes[n as usize].children = first;
        tree.leaves += 7;
        Ok(first)
    }

    /// Makes internal node `n` a leaf: its descendants' vertices are dropped and their blocks
    /// of nodes freed for reuse.
    fn collapse(&mut self, n: u32) {
        let mut stack = vec![n];
        while let Some(m) = stack.pop() {
            let node = self.tree.nodes[m as usize];
            if node.is_leaf() {
                self.forget_vertex(m);
                continue;
            }
            stack.extend((0..8).map(|c| node.children + c));
            self.tree.free_blocks.push(node.children);
            self.tree.nodes[m as usize].children = 0;
            self.tree.leaves -= 7;
        }
        self.touched[n as usize] = self.generation;
    }

    fn forget_vertex(&mut self, n: u32) {
        let slot = std::mem::replace(&mut self.vertex_of[n as usize], NO_VERTEX);
        if slot != NO_VERTEX {
            self.vertices.remove(slot);
            self.dropped.push(slot);
            let node = &self.tree.nodes[n as usize];
            let (lo, hi) = (node.min, node.corner(7));
            self.forgotten = Some(match self.forgotten {
                None => (lo, hi),
                Some((a, b)) => (
                    std::array::from_fn(|k| a[k].min(lo[k])),
                    std::array::from_fn(|k| b[k].max(hi[k])),
                ),
            });
        }
    }

    /// Whether node `n` may hold a leaf that this pass meshes again.
    fn revisits(&self, region: Option<&Region>, n: u32) -> bool {
        region.is_none_or(|r| {
            self.touched[n as usize] == self.generation || r.meets(&self.tree.nodes[n as usize])
        })
    }

    /// Whether the corners shared by the nodes `around` (the intersection of their closed
    /// boxes, where every minimal edge among them lies) all lie in the region's block and
    /// are all inside or all outside: then none of those edges makes a polygon.
    fn uniform_between(&self, around: &[u32]) -> bool {
        if self.region_samples.dims[0] == 0 {
            return false;
        }
        let mut lo = [0_u32; 3];
        let mut hi = [u32::MAX; 3];
        for &n in around {
            let node = &self.tree.nodes[n as usize];
            for a in 0..3 {
                lo[a] = lo[a].max(node.min[a]);
                hi[a] = hi[a].min(node.min[a] + node.size);
            }
        }
        self.region_samples.uniform(lo, hi)
    }

    /// The field at an integer corner; on the root's boundary no more than the iso-level, so
    /// everything outside the root counts as outside.
    #[inline]
    fn corner_value(&mut self, field: &MultiPatchField, p: [u32; 3]) -> f32 {
        match self.region_samples.index(p) {
            Some(at) => self.region_samples.values[at],
            None => self.corner_value_beyond_block(field, p),
        }
    }

    /// [`AdaptiveMesher::corner_value`] of a corner that the region's block does not hold:
    /// from the corner cache, or sampled.
    #[inline(never)]
    fn corner_value_beyond_block(&mut self, field: &MultiPatchField, p: [u32; 3]) -> f32 {
        let key = corner_key(p);
        if let Some(&v) = self.corners.get(&key) {
            return v;
        }
        let mut v = field.value(self.tree.point(p));
        if p.iter().any(|&c| c == 0 || c == self.tree.root_size) {
            v = v.min(self.iso);
        }
        self.corners.insert(key, v);
        v
    }

    fn inside(&self, v: f32) -> bool {
        v > self.iso
    }

    /// The vertex of leaf `n`, made on first use: the mass point of the crossings on the
    /// leaf's twelve edges (its centre when none crosses: the surface enters it only through
    /// smaller neighbours' edges), then two Newton steps toward `F = iso` along the gradient,
    /// each clamped to the leaf's box; its normal `−∇F/|∇F|` where the second step started.
    fn vertex(&mut self, field: &MultiPatchField, n: u32) -> u32 {
        if self.vertex_of[n as usize] != NO_VERTEX {
            return self.vertex_of[n as usize];
        }
        let node = self.tree.nodes[n as usize];
        let values: [f32; 8] = std::array::from_fn(|c| self.corner_value(field, node.corner(c)));
        let points: [Vec3; 8] = std::array::from_fn(|c| self.tree.point(node.corner(c)));
        let (lo, hi) = (points[0], points[7]);
        let (mut sum, mut count) = (Vec3::ZERO, 0_u32);
        for a in 0..3 {
            for c in (0..8).filter(|c| c & (1 << a) == 0) {
                let (v0, v1) = (values[c], values[c | 1 << a]);
                if self.inside(v0) != self.inside(v1) {
                    let t = ((self.iso - v0) / (v1 - v0)).clamp(0.0, 1.0);
                    let (p0, p1) = (points[c], points[c | 1 << a]);
                    sum += p0 + (p1 - p0) * t;
                    count += 1;
                }
            }
        }
        let mut x = if count > 0 {
            sum / count as f32
        } else {
            (lo + hi) * 0.5
        };
        // The normal is the last step's gradient, taken where that step started (within a
        // Newton step of the vertex, so nearly on the surface already): a third evaluation of
        // every patch at the vertex itself cost a twentieth of the window's re-mesh in
        // `bench/profile_adaptive.rs`.
        let mut gradient = Vec3::ZERO;
        for _ in 0..2 {
            let (v, g) = field.value_and_gradient(x);
            let g2 = g.length_squared();
            if g2 > 1e-20 && g2.is_finite() {
                x = (x - g * ((v - self.iso) / g2)).clamp(lo, hi);
            }
            gradient = g;
        }
        let normal = -gradient.normalize_or_zero();
        let slot = self
            .vertices
            .add(x, normal, node.size as f32 * self.tree.unit);
        self.vertex_of[n as usize] = slot;
        slot
    }

    /// All minimal edges inside node `n` that this pass meshes.
    fn cell_proc(&mut self, field: &MultiPatchField, region: Option<&Region>, n: u32) {
        let node = self.tree.nodes[n as usize];
        if node.is_leaf() || !self.revisits(region, n) {
            return;
        }
        if self.region_samples.uniform(node.min, node.corner(7)) {
            return;
        }
        let child = |c: usize| node.children + c as u32;
        for c in 0..8 {
            self.cell_proc(field, region, child(c));
        }
        for a in 0..3 {
            for c in (0..8).filter(|c| c & (1 << a) == 0) {
                self.face_proc(field, region, [child(c), child(c | 1 << a)], a);
            }
        }
        for a in 0..3 {
            let (p, r) = ((a + 1) % 3, (a + 2) % 3);
            for h in 0..2 {
                let cells = AROUND.map(|[qp, qr]| child(qp << p | qr << r | h << a));
                self.edge_proc(field, region, cells, a);
            }
        }
    }

    /// All minimal edges on the face between `pair[0]` (below along axis `a`) and `pair[1]`
    /// that this pass meshes.
    fn face_proc(
        &mut self,
        field: &MultiPatchField,
        region: Option<&Region>,
        pair: [u32; 2],
        a: usize,
    ) {
        let [low, high] = pair;
        if self.tree.nodes[low as usize].is_leaf() && self.tree.nodes[high as usize].is_leaf() {
            return;
        }
        if !pair.iter().any(|&n| self.revisits(region, n)) {
            return;
        }
        if self.uniform_between(&pair) {
            return;
        }
        let (b, c) = ((a + 1) % 3, (a + 2) % 3);
        for qb in 0..2 {
            for qc in 0..2 {
                let side = qb << b | qc << c;
                let pair = [
                    self.tree.child_or_leaf(low, side | 1 << a),
                    self.tree.child_or_leaf(high, side),
                ];
                self.face_proc(field, region, pair, a);
            }
        }
        // The four edges inside the face: along `e`, through the face's middle along `f`.
        for e in [b, c] {
            let f = 3 - a - e;
            let (p, r) = ((e + 1) % 3, (e + 2) % 3);
            for h in 0..2 {
                let mut cells = [0_u32; 4];
                for (cell, [qp, qr]) in cells.iter_mut().zip(AROUND) {
                    let mut bit = [0_usize; 3];
                    bit[p] = qp;
                    bit[r] = qr;
                    let node = if bit[a] == 0 { low } else { high };
                    *cell = self
                        .tree
                        .child_or_leaf(node, (1 - bit[a]) << a | bit[f] << f | h << e);
                }
                self.edge_proc(field, region, cells, e);
            }
        }
    }

    /// All minimal edges along the edge (axis `a`) that `cells` surround, in [`AROUND`]
    /// order, that this pass meshes.
    fn edge_proc(
        &mut self,
        field: &MultiPatchField,
        region: Option<&Region>,
        cells: [u32; 4],
        a: usize,
    ) {
        if !cells.iter().any(|&n| self.revisits(region, n)) {
            return;
        }
        // Four leaves: the minimal edge's own two samples decide, as the count over the
        // corners they share would (those corners lie on that edge, its ends among them).
        // NOTE: the count first cost a summed-volume query per minimal edge visited
        // (`bench/profile_adaptive.rs` `3000 local 4 cut`).
        if cells.iter().all(|&n| self.tree.nodes[n as usize].is_leaf()) {
            self.minimal_edge(field, cells, a);
            return;
        }
        if self.uniform_between(&cells) {
            return;
        }
        let (p, r) = ((a + 1) % 3, (a + 2) % 3);
        for h in 0..2 {
            let mut sub = cells;
            for (q, [qp, qr]) in AROUND.into_iter().enumerate() {
                sub[q] = self
                    .tree
                    .child_or_leaf(cells[q], (1 - qp) << p | (1 - qr) << r | h << a);
            }
            self.edge_proc(field, region, sub, a);
        }
    }

    /// The polygon of a minimal edge: the edge of the smallest of the four leaves around it.
    fn minimal_edge(&mut self, field: &MultiPatchField, cells: [u32; 4], a: usize) {
        let (q, &smallest) = cells
            .iter()
            .enumerate()
            .min_by_key(|(_, n)| self.tree.nodes[**n as usize].size)
            .expect("four cells");
        let node = self.tree.nodes[smallest as usize];
        let (p, r) = ((a + 1) % 3, (a + 2) % 3);
        let [qp, qr] = AROUND[q];
        let base = (1 - qp) << p | (1 - qr) << r;
        let v0 = self.corner_value(field, node.corner(base));
        let v1 = self.corner_value(field, node.corner(base | 1 << a));
        let (in0, in1) = (self.inside(v0), self.inside(v1));
        if in0 == in1 {
            return;
        }
        let mut ids = cells.map(|n| self.vertex(field, n));
        // AROUND runs counter-clockwise seen from +a; the outside is toward +a when the low
        // end is inside.
        if !in0 {
            ids.reverse();
        }
        self.polygons.push(node.corner(base), ids);
        if !self.made_whole {
            self.made.push(ids);
        }
    }
}

/// The kept polygons in buckets of 2^[`PolygonBuckets::SHIFT`] finest cells a side, by the low
/// end of their minimal edge, so that a local re-mesh looks for the polygons using a dropped
/// vertex only in the buckets that meet the dropped leaves' box (a polygon's minimal edge
/// lies on the box of each of its four leaves), not over the whole mesh: the sweep over every
/// polygon cost 6% of the window's re-mesh in `bench/profile_adaptive.rs`.
#[derive(Clone, Debug, Default)]
struct PolygonBuckets {
    /// The polygons of each bucket, buckets in the order they were first used.
    buckets: Vec<Vec<[u32; 4]>>,
    /// Each bucket's coordinates (integer corner shifted right by [`PolygonBuckets::SHIFT`]).
    coords: Vec<[u32; 3]>,
    /// The bucket at each coordinate key ([`corner_key`]).
    at: HashMap<u64, u32, BuildHasherDefault<EdgeIdHasher>>,
    /// Polygons held.
    count: usize,
}

impl PolygonBuckets {
    /// Log2 of a bucket's edge in finest cells.
    const SHIFT: u32 = 5;

    fn clear(&mut self) {
        self.buckets.clear();
        self.coords.clear();
        self.at.clear();
        self.count = 0;
    }

    /// Adds `polygon`, whose minimal edge's low end is the integer corner `edge`.
    fn push(&mut self, edge: [u32; 3], polygon: [u32; 4]) {
        let coord = edge.map(|c| c >> Self::SHIFT);
        let next = self.buckets.len() as u32;
        let b = *self.at.entry(corner_key(coord)).or_insert(next);
        if b == next {
            self.buckets.push(Vec::new());
            self.coords.push(coord);
        }
        self.buckets[b as usize].push(polygon);
        self.count += 1;
    }

    /// Every polygon, bucket by bucket.
    fn iter(&self) -> impl Iterator<Item = &[u32; 4]> {
        self.buckets.iter().flatten()
    }

    /// Drops the polygons for which `drop` holds among those whose minimal edge lies in the
    /// integer box `lo ..= hi` (and others of the buckets meeting it); returns how many.
    fn drop_where(
        &mut self,
        lo: [u32; 3],
        hi: [u32; 3],
        mut drop: impl FnMut(&[u32; 4]) -> bool,
    ) -> usize {
        let (a, b) = (lo.map(|c| c >> Self::SHIFT), hi.map(|c| c >> Self::SHIFT));
        let spanned: u64 = (0..3).map(|k| u64::from(b[k] - a[k]) + 1).product();
        let before = self.count;
        let mut sweep = |bucket: &mut Vec<[u32; 4]>, count: &mut usize| {
            let held = bucket.len();
            bucket.retain(|p| !drop(p));
            *count -= held - bucket.len();
        };
        if spanned <= self.buckets.len() as u64 {
            for z in a[2]..=b[2] {
                for y in a[1]..=b[1] {
                    for x in a[0]..=b[0] {
                        if let Some(&at) = self.at.get(&corner_key([x, y, z])) {
                            sweep(&mut self.buckets[at as usize], &mut self.count);
                        }
                    }
                }
            }
        } else {
            for (bucket, c) in self.buckets.iter_mut().zip(&self.coords) {
                if (0..3).all(|k| a[k] <= c[k] && c[k] <= b[k]) {
                    sweep(bucket, &mut self.count);
                }
            }
        }
        before - self.count
    }
}

/// The corner samples of a local re-mesh's region (clamped to the root), taken together by
/// [`MultiPatchField::values_on_grid`] (the same values as one by one, with each patch's
/// weights computed once per coordinate of each axis): in `bench/mesh.rs`
/// `adaptive_remesh` nearly every corner of a stroke's region is a leaf corner, so sampling
/// the block costs less than sampling them one by one, and the re-mesh reads them without a
/// hash lookup. Buffers are kept between re-meshes.
#[derive(Clone, Debug, Default)]
struct RegionSamples {
    /// The block's lowest integer corner.
    lo: [u32; 3],
    /// Corners per axis; zero when there is no block.
    dims: [usize; 3],
    /// Field value per corner, x fastest.
    values: Vec<f32>,
    /// Summed-volume table of the inside corners: entry `(x, y, z)` (of `dims + 1` per axis,
    /// x fastest) counts the inside corners below `x`, `y` and `z`.
    inside_below: Vec<u32>,
    /// One patch's term per corner (scratch of [`MultiPatchField::values_on_grid_with`]).
    term: Vec<f32>,
    /// World coordinates of the corners along each axis.
    xs: Vec<f32>,
    ys: Vec<f32>,
    zs: Vec<f32>,
}

impl RegionSamples {
    /// Most corners a region is sampled in one block for (a region of 32³ corners); a larger
    /// one holds many corners that no leaf uses, and is sampled one by one.
    const MAX_CORNERS: usize = 1 << 15;

    /// Finest cells the block reaches beyond the region on every side: the leaves that meet
    /// the region and reach past it find their corners there too.
    const MARGIN: i64 = 2;

    /// Fills [`RegionSamples::inside_below`] from the values: the inside corners counted
    /// along x, then those counts summed along y, then along z (three passes of one addition
    /// per entry, over whole rows).
    fn count_inside(&mut self, iso: f32) {
        let [nx, ny, nz] = self.dims;
        let (sx, sy) = (nx + 1, (nx + 1) * (ny + 1));
        self.inside_below.clear();
        self.inside_below.resize(sy * (nz + 1), 0);
        let table = &mut self.inside_below;
        for (row, values) in self.values.chunks_exact(nx).enumerate() {
            let (y, z) = (row % ny, row / ny);
            let at = sx * (y + 1) + sy * (z + 1);
            let mut count = 0;
            for (x, &v) in values.iter().enumerate() {
                count += u32::from(v > iso);
                table[at + x + 1] = count;
            }
        }
        for z in 1..=nz {
            for y in 2..=ny {
                let at = sx * y + sy * z;
                let (below, row) = table[at - sx..at + sx].split_at_mut(sx);
                row.iter_mut().zip(below.iter()).for_each(|(t, b)| *t += b);
            }
        }
        for z in 2..=nz {
            let at = sy * z;
            let (below, plane) = table[at - sy..at + sy].split_at_mut(sy);
            plane
                .iter_mut()
                .zip(below.iter())
                .for_each(|(t, b)| *t += b);
        }
    }

    /// Whether the block holds every integer corner of the box `lo ..= hi` and they are all
    /// inside or all outside: then no minimal edge within that box changes sign.
    fn uniform(&self, lo: [u32; 3], hi: [u32; 3]) -> bool {
        let (Some(_), Some(_)) = (self.index(lo), self.index(hi)) else {
            return false;
        };
        let [nx, ny, _] = self.dims;
        let (sx, sy) = (nx + 1, (nx + 1) * (ny + 1));
        let a: [usize; 3] = std::array::from_fn(|k| (lo[k] - self.lo[k]) as usize);
        let b: [usize; 3] = std::array::from_fn(|k| (hi[k] - self.lo[k]) as usize + 1);
        let t = |x: usize, y: usize, z: usize| i64::from(self.inside_below[x + sx * y + sy * z]);
        let inside =
            t(b[0], b[1], b[2]) - t(a[0], b[1], b[2]) - t(b[0], a[1], b[2]) - t(b[0], b[1], a[2])
                + t(a[0], a[1], b[2])
                + t(a[0], b[1], a[2])
                + t(b[0], a[1], a[2])
                - t(a[0], a[1], a[2]);
        let corners: i64 = (0..3).map(|k| (b[k] - a[k]) as i64).product();
        inside == 0 || inside == corners
    }

    /// The field at integer corner `p` (not on the root's boundary), if the block holds it.
    fn value(&self, p: [u32; 3]) -> Option<f32> {
        self.index(p).map(|at| self.values[at])
    }

    /// Index of integer corner `p` in the block, if it lies there.
    #[inline]
    fn index(&self, p: [u32; 3]) -> Option<usize> {
        let d: [usize; 3] = std::array::from_fn(|a| p[a].wrapping_sub(self.lo[a]) as usize);
        (d[0] < self.dims[0] && d[1] < self.dims[1] && d[2] < self.dims[2])
            .then(|| d[0] + self.dims[0] * (d[1] + self.dims[1] * d[2]))
    }
}

/// The cache key of an integer corner: 21 bits per axis.
fn corner_key(p: [u32; 3]) -> u64 {
    u64::from(p[0]) | (u64::from(p[1]) << 21) | (u64::from(p[2]) << 42)
}

/// Appends the quad `ids` (counter-clockwise seen from outside) split along its shorter
/// diagonal, or the triangle left when one leaf fills two neighbouring places.
fn triangulate(ids: [u32; 4], positions: &[Vec3], triangles: &mut Vec<[u32; 3]>) {
    let (split, n) = split_polygon(ids, positions);
    triangles.extend_from_slice(&split[..n]);
}

/// The triangles of polygon `slots` (vertex slots, `positions` by slot) as [`triangulate`]
/// splits it, with their centroids.
fn slot_triangles(slots: [u32; 4], positions: &[Vec3]) -> impl Iterator<Item = SlotTriangle> {
    let (split, n) = split_polygon(slots, positions);
    split.into_iter().take(n).map(|t| SlotTriangle {
        slots: t,
        centroid: t
            .iter()
            .map(|&s| positions[s as usize])
            .fold(Vec3::ZERO, |sum, p| sum + p)
            / 3.0,
    })
}

/// The quad `ids` split along its shorter diagonal (two triangles), or the triangle left
/// when one leaf fills two neighbouring places (one), or nothing: the triangles and their
/// count.
fn split_polygon(ids: [u32; 4], positions: &[Vec3]) -> ([[u32; 3]; 2], usize) {
    let mut distinct = [0_u32; 4];
    let mut n = 0;
    for (k, &id) in ids.iter().enumerate() {
        if id != ids[(k + 3) % 4] {
            distinct[n] = id;
            n += 1;
        }
    }
    match n {
        3 => ([[distinct[0], distinct[1], distinct[2]], [0; 3]], 1),
        4 => {
            let at = |i: u32| positions[i as usize];
            let [i0, i1, i2, i3] = distinct;
            if at(i0).distance_squared(at(i2)) <= at(i1).distance_squared(at(i3)) {
                ([[i0, i1, i2], [i0, i2, i3]], 2)
            } else {
                ([[i1, i2, i3], [i1, i3, i0]], 2)
            }
        }
        _ => ([[0; 3]; 2], 0),
    }
}

/// Vertices where the gradient vanished take the area-weighted normal of their triangles
/// (or +z when they have none).
fn finish_normals(mesh: &mut TriMesh) {
    finish_flat_normals(
        &mesh.positions,
        &mut mesh.normals,
        mesh.triangles.iter().copied(),
    );
}

/// Gives each vertex whose normal is zero (its gradient vanished) the area-weighted normal of
/// `triangles` around it (+z when they have no area); other normals are kept.
pub(super) fn finish_flat_normals(
    positions: &[Vec3],
    normals: &mut [Vec3],
    triangles: impl Iterator<Item = [u32; 3]> + Clone,
) {
    if !normals.contains(&Vec3::ZERO) {
        return;
    }
    let flat: Vec<bool> = normals.iter().map(|n| *n == Vec3::ZERO).collect();
    for t in triangles {
        let [a, b, c] = t.map(|i| positions[i as usize]);
        let cross = (b - a).cross(c - a);
        for i in t {
            if flat[i as usize] {
                normals[i as usize] += cross;
            }
        }
    }
    for (n, &f) in normals.iter_mut().zip(&flat) {
        if f {
            *n = n.try_normalize().unwrap_or(Vec3::Z);
        }
    }
}

/// The whole mesh of `field` with each vertex's leaf edge (for tests).
#[cfg(test)]
fn extract(
    field: &MultiPatchField,
    options: &AdaptiveMeshOptions,
) -> Result<Extraction, AdaptiveMeshError> {
    AdaptiveMesher::new(field, options).map(|m| m.extraction())
}

/// A leaf without a vertex (yet).
const NO_VERTEX: u32 = u32::MAX;

/// The four places around an edge along axis `a`, as bits along the axes `a + 1` and `a + 2`
/// (cyclically): counter-clockwise seen from `+a`.
const AROUND: [[usize; 2]; 4] = [[0, 0], [1, 0], [1, 1], [0, 1]];

/// An octree node: a cube of `size` finest cells from integer corner `min`.
#[derive(Clone, Copy, Debug)]
struct Node {
    min: [u32; 3],
    size: u32,
    /// Index of the first of eight consecutive children (child `c` holds bit `a` of `c` as
    /// its half along axis `a`); 0 for a leaf (the root is no one's child).
    children: u32,
}

impl Node {
    fn is_leaf(&self) -> bool {
        self.children == 0
    }

    /// Integer coordinates of corner `c` (bit `a` of `c`: low or high along axis `a`).
    fn corner(&self, c: usize) -> [u32; 3] {
        std::array::from_fn(|a| self.min[a] + self.size * ((c >> a) & 1) as u32)
    }
}

/// The octree and the frame that maps its integer lattice to world space.
#[derive(Clone, Debug)]
struct Tree {
    nodes: Vec<Node>,
    leaves: usize,
    /// World position of integer corner (0, 0, 0).
    origin: Vec3,
    /// World edge of one finest cell.
    unit: f32,
    /// The root's edge, in finest cells (`2^depth`).
    root_size: u32,
    /// Per patch: its world support and its target cell edge (world units).
    targets: Vec<(Vec3, Vec3, f32)>,
    /// Per patch: its lattice coordinates' floors at the integer corners (`None` for a
    /// patch with a map), so a split test finds a node's coefficients without arithmetic.
    floors: Vec<Option<CornerFloors>>,
    /// First nodes of blocks of eight that a collapse took out of the tree, for reuse.
    free_blocks: Vec<u32>,
}

impl Tree {
    /// The root alone, after checking the options and the field.
    fn frame(
        field: &MultiPatchField,
        options: &AdaptiveMeshOptions,
    ) -> Result<Self, AdaptiveMeshError> {
        if options.cells_per_span < 2 {
            return Err(AdaptiveMeshError::CellsPerSpan {
                cells_per_span: options.cells_per_span,
            });
        }
        if field.patches.is_empty() {
            return Err(AdaptiveMeshError::EmptyField);
        }
        let per_span = options.cells_per_span as f32;
        // Each patch's world support and target cell.
        let targets: Vec<(Vec3, Vec3, f32)> = field
            .patches
            .iter()
            .map(|p| {
                let (lo, hi) = p.world_support();
                (lo, hi, p.world_spacing() / per_span)
            })
            .collect();
        let usable = |&(lo, hi, t): &(Vec3, Vec3, f32)| {
            lo.is_finite() && hi.is_finite() && lo.cmple(hi).all() && t.is_finite() && t > 0.0
        };
        if !targets.iter().all(usable) {
            return Err(AdaptiveMeshError::BadField);
        }
        let unit = targets.iter().map(|t| t.2).fold(f32::INFINITY, f32::min);
        let (lo, hi) = field.support();
        // A margin of one finest cell on every side, so the root's boundary is beyond every
        // support (where the field is exactly zero).
        let span = ((hi - lo).max_element() / unit + 2.0).max(1.0);
        let levels = span.log2().ceil().max(0.0);
        if levels.is_nan() || levels > MAX_ADAPTIVE_DEPTH as f32 {
            return Err(AdaptiveMeshError::TooDeep {
                levels: if levels.is_finite() {
                    levels as u32
                } else {
                    u32::MAX
                },
            });
        }
        let root_size = 1_u32 << levels as u32;
        let origin = lo - Vec3::splat(unit);
        if options.max_cells < 1 {
            return Err(AdaptiveMeshError::OverBudget {
                limit: options.max_cells,
                leaves: 1,
            });
        }
        let floors = field
            .patches
            .iter()
            .map(|p| CornerFloors::of(p, origin, unit, root_size))
            .collect();
        Ok(Self {
            nodes: vec![Node {
                min: [0; 3],
                size: root_size,
                children: 0,
            }],
            leaves: 1,
            origin,
            unit,
            root_size,
            targets: targets
                .into_iter()
                .map(|(lo, hi, t)| (lo, hi, t / unit))
                .collect(),
            floors,
            free_blocks: Vec::new(),
        })
    }

    /// The whole tree of `field`, without meshing it.
    fn build(
        field: &MultiPatchField,
        options: &AdaptiveMeshOptions,
    ) -> Result<Self, AdaptiveMeshError> {
        let mut tree = Self::frame(field, options)?;
        let mut reads = CoefficientReads::default();
        let mut stack = vec![0_usize];
        while let Some(n) = stack.pop() {
            let node = tree.nodes[n];
            if !tree.should_split(field, &node, None, &mut reads, None) {
                continue;
            }
            if tree.leaves + 7 > options.max_cells {
                return Err(AdaptiveMeshError::OverBudget {
                    limit: options.max_cells,
                    leaves: tree.leaves + 7,
                });
            }
            let first = tree.nodes.len();
            let half = node.size / 2;
            tree.nodes[n].children = first as u32;
            for c in 0..8 {
                let min = std::array::from_fn(|a| node.min[a] + half * ((c >> a) & 1) as u32);
                tree.nodes.push(Node {
                    min,
                    size: half,
                    children: 0,
                });
                stack.push(first + c);
            }
            tree.leaves += 7;
        }
        Ok(tree)
    }

    /// Nodes larger than this many finest cells a side, reaching beyond a local re-mesh's
    /// region, read the part inside it first (see [`Tree::should_split`]).
    const PART_FIRST_CELLS: u32 = 4;

    /// Whether `node` splits: while the field may cross the iso-level inside it and its edge
    /// is longer than the finest target among the patches holding detail there. Reads the
    /// field inside the node's box only (so a change elsewhere never changes the answer).
    ///
    /// `near`, when given, is a box of integer corners where the answer is likely to be
    /// decided (a local re-mesh's changed region): the coefficients over the part of a node
    /// larger than [`Tree::PART_FIRST_CELLS`] inside it are read first, and where they alone
    /// prove a split the rest are not read (see [`SplitInputs::splits`]); otherwise the whole
    /// node is read.
    fn should_split(
        &self,
        field: &MultiPatchField,
        node: &Node,
        near: Option<&Region>,
        reads: &mut CoefficientReads,
        samples: Option<&RegionSamples>,
    ) -> bool {
        if node.size == 1 {
            return false;
        }
        let (lo, hi) = (node.min, node.corner(7));
        // A small node's whole read costs little more than a part's: it is read once.
        if let Some(near) = near.filter(|_| node.size > Self::PART_FIRST_CELLS) {
            // The corners' world positions grow with their integer coordinates, so the part's
            // world box is the node's world box clipped to the region's.
            let part_lo: [u32; 3] = std::array::from_fn(|a| {
                i64::from(lo[a]).max(near.lo[a]).min(i64::from(u32::MAX)) as u32
            });
            let part_hi: [u32; 3] =
                std::array::from_fn(|a| i64::from(hi[a]).min(near.hi[a]).max(0) as u32);
            let smaller = part_lo != lo || part_hi != hi;
            if smaller
                && (0..3).all(|a| part_lo[a] <= part_hi[a])
                && self
                    .split_inputs(field, (lo, hi), (part_lo, part_hi), reads)
                    .splits(self, field, node, samples)
            {
                return true;
            }
        }
        self.split_inputs(field, (lo, hi), (lo, hi), reads)
            .splits(self, field, node, samples)
    }

    /// The split test's inputs for the node with integer box `node_box`, from the
    /// coefficients whose support meets `read_box` (the node's box or a part of it).
    fn split_inputs(
        &self,
        field: &MultiPatchField,
        node_box: ([u32; 3], [u32; 3]),
        read_box: ([u32; 3], [u32; 3]),
        reads: &mut CoefficientReads,
    ) -> SplitInputs {
        let (lo, hi) = (self.point(node_box.0), self.point(node_box.1));
        // One read of each patch's coefficients over the box gives the finest target among
        // the patches that hold detail in it (in cells), the field's convex-hull bound and a
        // bound on its slope.
        let half_diagonal = 0.5 * (hi - lo).length();
        let mut inputs = SplitInputs {
            target_cells: f32::INFINITY,
            bounds: Some((0.0, 0.0)),
            reach: 0.0,
        };
        for (n, (((slo, shi, cells), floors), patch)) in self
            .targets
            .iter()
            .zip(&self.floors)
            .zip(&field.patches)
            .enumerate()
        {
            let range = match floors {
                Some(floors) => floors.range(read_box.0, read_box.1, patch.lattice.dims),
                None => CoefficientRange::of(patch, self.point(read_box.0), self.point(read_box.1)),
            };
            let over = reads.over_box(n, patch, range);
            let meets = lo.cmplt(*shi).all() && hi.cmpgt(*slo).all();
            // A patch with corner floors has no map.
            let mapped = floors.is_none() && !patch.is_identity();
            if meets && (n == 0 || over.holds_detail(mapped)) {
                inputs.target_cells = inputs.target_cells.min(*cells);
            }
            inputs.bounds = inputs
                .bounds
                .zip(over.bounds)
                .map(|((a, b), (c, d))| (a + c, b + d));
            inputs.reach += over.reach(half_diagonal);
        }
        inputs
    }

    /// World position of an integer corner.
    fn point(&self, p: [u32; 3]) -> Vec3 {
        self.origin + self.unit * Vec3::new(p[0] as f32, p[1] as f32, p[2] as f32)
    }

    /// World box of a node.
    fn world_box(&self, node: &Node) -> (Vec3, Vec3) {
        (self.point(node.min), self.point(node.corner(7)))
    }

    /// `n` itself when it is a leaf, else its child `c`.
    #[inline]
    fn child_or_leaf(&self, n: u32, c: usize) -> u32 {
        let node = &self.nodes[n as usize];
        if node.is_leaf() {
            n
        } else {
            node.children + c as u32
        }
    }
}

/// What the split test reads from the patches' coefficients over a box.
///
/// Read over a part of a node's box (a subset of the coefficients the whole box reads) each
/// input errs only one way: the finest target is no finer (a patch proven to hold detail
/// over the part holds it over the node), the summed bound is no wider and the reach no
/// larger (each patch's slope bound and hull are no larger). Every condition of
/// [`SplitInputs::splits`] grows true with a finer target, a wider bound and a larger reach,
/// so a split the part proves is the split the whole node's read gives; a part that does not
/// prove one decides nothing.
struct SplitInputs {
    /// The finest target cell among the patches holding detail there, in finest cells.
    target_cells: f32,
    /// Sum of the patches' convex-hull bounds; `None` where a box is not finite in a
    /// patch's space.
    bounds: Option<(f32, f32)>,
    /// How far the field may move from its value at the node's centre anywhere in the node
    /// (density units): the sum over the patches of [`PatchOverBox::reach`].
    reach: f32,
}

impl SplitInputs {
    /// Whether `node` splits by these inputs: its edge is longer than the target and the
    /// field may cross the iso-level in it.
    ///
    /// `samples`, when given, are a local re-mesh's region samples: the value at the node's
    /// centre is read there when the centre is one of their corners.
    fn splits(
        &self,
        tree: &Tree,
        field: &MultiPatchField,
        node: &Node,
        samples: Option<&RegionSamples>,
    ) -> bool {
        let edge = node.size as f32;
        // A little slack so a target that is a power of two times the finest cell, up to
        // rounding, is met exactly rather than split once more.
        if edge <= self.target_cells * (1.0 + 1e-4) {
            return false;
        }
        // A node on the root's boundary holds corners forced outside (see
        // `AdaptiveMesher::corner_value`), whatever the field's value there.
        let on_boundary = node.min.contains(&0) || node.corner(7).contains(&tree.root_size);
        let iso = field.iso();
        let may_cross = match self.bounds {
            Some((vmin, vmax)) => (vmin <= iso || on_boundary) && vmax > iso,
            None => true,
        };
        // Whether the field's value at the centre is further from `iso` than the patches can
        // move within the node (so the surface cannot cross it): a test that holds where the
        // summed convex-hull bound is loose, inside a detail patch whose coefficients cancel
        // the base's.
        let far_from_iso = || {
            let (lo, hi) = tree.world_box(node);
            let reach = self.reach;
            let centre = 0.5 * (lo + hi);
            let sampled = samples.and_then(|s| {
                let corner = node.min.map(|m| m + node.size / 2);
                // The sample is the field at `Tree::point(corner)`: the same only where that
                // point is the centre, bit for bit.
                let same = tree.point(corner).to_array().map(f32::to_bits)
                    == centre.to_array().map(f32::to_bits);
                same.then(|| s.value(corner)).flatten()
            });
            let value = sampled.unwrap_or_else(|| field.value(centre));
            (value - iso).abs() > reach
        };
        may_cross && (on_boundary || !far_from_iso())
    }
}

/// Largest contribution, in density units, below which a detail patch counts as holding
/// nothing over a box (it moves the surface by less than a thousandth of a knot span's worth
/// of density): such a box is meshed at the coarser levels' size.
pub const DETAIL_EPSILON: f32 = 1e-3;

/// What one read of a patch's coefficients over a world box bounds: the patch's term there
/// and its slope.
#[derive(Clone, Copy, Debug)]
struct PatchOverBox {
    /// The convex-hull bound of the term: it is a convex combination of the coefficients
    /// whose support meets the box, those beyond the lattice counting as zero (the bound
    /// [`super::ScalarField::bounds`] of the lattice takes); `None` where the box is not
    /// finite in the patch's space.
    bounds: Option<(f32, f32)>,
    /// A bound on `|∇s|` over the box in world units: a cubic B-spline's derivative along an
    /// axis is a quadratic B-spline of the coefficient differences over the spacing, so
    /// `|∇s| ≤ √3 · max |Δc| / spacing`, the differences taken among the same coefficients
    /// and with the zeros beyond the lattice at its border. Local, so that a change to a
    /// patch's coefficients changes the bound only near the change.
    slope: f32,
}

impl PatchOverBox {
    /// How far the patch's term may differ between two points of a box whose half diagonal
    /// is `half_diagonal` (world units), one of them its centre: the slope bound times that
    /// reach, and never more than the width of the convex-hull bound, which holds the term at
    /// both points. On a large node the hull is the tighter: a dent of a few fine
    /// coefficients raises the fine patch's slope bound by the dent over the fine spacing
    /// but its hull only by the dent, so the nodes deep inside the clay around a stroke stay
    /// proven far from the iso-level. `slope · half_diagonal` alone where the hull is not
    /// known or not finite.
    fn reach(&self, half_diagonal: f32) -> f32 {
        let by_slope = self.slope * half_diagonal;
        match self.bounds {
            // The width is NaN or infinite where a coefficient is infinite, and negative where
            // every coefficient is NaN; the slope bound stands then.
            Some((vmin, vmax)) if (0.0..by_slope).contains(&(vmax - vmin)) => vmax - vmin,
            _ => by_slope,
        }
    }

    /// Whether the patch may add more than [`DETAIL_EPSILON`] anywhere in the box (a patch
    /// with a map, `mapped`, whose bound is taken over a larger box, always may).
    fn holds_detail(&self, mapped: bool) -> bool {
        if mapped {
            return true;
        }
        match self.bounds {
            Some((vmin, vmax)) => vmin < -DETAIL_EPSILON || vmax > DETAIL_EPSILON,
            None => true,
        }
    }
}

/// The coefficients of one patch whose support meets a world box: the index ranges (inclusive,
/// clamped to the lattice) and whether the unclamped ranges reached beyond the lattice.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum CoefficientRange {
    /// The box is not finite in the patch's space.
    NotFinite,
    /// No coefficient's support meets the box.
    Empty,
    /// The coefficients `first[a] ..= last[a]` per axis.
    Block {
        first: [usize; 3],
        last: [usize; 3],
        beyond: bool,
    },
}

impl CoefficientRange {
    /// The coefficients of `patch` whose support meets the world box `lo..=hi`.
    fn of(patch: &Patch, lo: Vec3, hi: Vec3) -> Self {
        let l = &patch.lattice;
        let (a, b) = patch.patch_box_of(lo, hi);
        let (ua, ub) = (l.to_lattice(a), l.to_lattice(b));
        if !(ua.is_finite() && ub.is_finite()) {
            return Self::NotFinite;
        }
        Self::from_floors(
            l.dims,
            std::array::from_fn(|a| floor_to_int(ua[a])),
            std::array::from_fn(|a| floor_to_int(ub[a])),
        )
    }

    /// The coefficients of a lattice of `dims` whose support meets a box whose corners'
    /// lattice coordinates have the floors `floor_lo` and `floor_hi` per axis: a cubic's
    /// support reaches one node below a point's floor and two above it.
    #[inline]
    fn from_floors(dims: [usize; 3], floor_lo: [i64; 3], floor_hi: [i64; 3]) -> Self {
        let mut first = [0_usize; 3];
        let mut last = [0_usize; 3];
        let mut beyond = false;
        for axis in 0..3 {
            let n = dims[axis] as i64;
            let from = floor_lo[axis] - 1;
            let to = floor_hi[axis] + 2;
            beyond |= from < 0 || to >= n;
            let (from, to) = (from.max(0), to.min(n - 1));
            if from > to {
                return Self::Empty;
            }
            first[axis] = from as usize;
            last[axis] = to as usize;
        }
        Self::Block {
            first,
            last,
            beyond,
        }
    }
}

/// One patch's lattice coordinates at the octree's integer corners, floored, per axis: the
/// coefficient range of a node's box ([`CoefficientRange::of`] of its world box) read from
/// six table entries instead of mapping the box's corners into the lattice and rounding them
/// per node and patch (a tenth of a local re-mesh in `bench/profile_adaptive.rs`). Only for a
/// patch without a map, whose lattice coordinates along an axis depend on that axis alone.
///
/// Each floor is saturated to `LOWEST ..= dims + 3`: the ranges [`CoefficientRange::of`]
/// makes from the floors (one below and two above, clamped to the lattice) are the same
/// for every floor beyond those. Corners before the table's first (after its last) along an
/// axis floor at or below (at or above) the table's first (last) entry, which is saturated:
/// so the table covers the patch's support and a little more, not the whole root.
#[derive(Clone, Debug)]
struct CornerFloors {
    /// Per axis: the integer coordinate of the table's first entry.
    first: [u32; 3],
    /// Per axis: the saturated floor of the lattice coordinate at each integer coordinate
    /// from `first`.
    floors: [Vec<i32>; 3],
    /// Per axis: the highest saturated floor, `dims + 3`.
    highest: [i32; 3],
}

impl CornerFloors {
    /// The lowest saturated floor.
    const LOWEST: i32 = -4;

    /// The tables of `patch` for the octree's corners `origin + unit · c`, `c` in
    /// `0 ..= root_size` per axis; `None` for a patch with a map, a lattice too large for
    /// the saturated floors, or a corner whose lattice coordinate is not finite.
    fn of(patch: &Patch, origin: Vec3, unit: f32, root_size: u32) -> Option<Self> {
        if !patch.is_identity() {
            return None;
        }
        let l = &patch.lattice;
        let mut first = [0_u32; 3];
        let mut floors: [Vec<i32>; 3] = Default::default();
        let mut highest = [0_i32; 3];
        for a in 0..3 {
            let n = i32::try_from(l.dims[a])
                .ok()
                .filter(|n| *n < i32::MAX - 3)?;
            highest[a] = n + 3;
            // As `Tree::point` and `BSplineLattice::to_lattice` compute it, axis by axis.
            let lattice_at = |c: u32| (origin[a] + unit * c as f32 - l.origin[a]) / l.spacing;
            let saturated =
                |u: f32| floor_to_int(u).clamp(i64::from(Self::LOWEST), i64::from(n + 3)) as i32;
            // A first guess at the corners where the floor leaves its saturated ends, then
            // widened until the ends are reached (or the root's sides).
            let corner_of = |x: f32| ((x - origin[a]) / unit).clamp(0.0, root_size as f32);
            let low_end = l.origin[a] + l.spacing * (Self::LOWEST as f32);
            let high_end = l.origin[a] + l.spacing * (n + 3) as f32;
            let mut from = (corner_of(low_end) as u32).saturating_sub(1);
            let mut to = ((corner_of(high_end) as u32).saturating_add(1))
                .min(root_size)
                .max(from);
            while from > 0 && saturated(lattice_at(from)) > Self::LOWEST {
                from -= 1;
            }
            while to < root_size && saturated(lattice_at(to)) < n + 3 {
                to += 1;
            }
            let mut table = Vec::with_capacity((to - from + 1) as usize);
            for c in from..=to {
                let u = lattice_at(c);
                if !u.is_finite() {
                    return None;
                }
                table.push(saturated(u));
            }
            first[a] = from;
            floors[a] = table;
        }
        Some(Self {
            first,
            floors,
            highest,
        })
    }

    /// The saturated floor at integer coordinate `c` along axis `a`.
    #[inline]
    fn floor(&self, a: usize, c: u32) -> i64 {
        let table = &self.floors[a];
        let at = c.wrapping_sub(self.first[a]) as usize;
        i64::from(match table.get(at) {
            Some(&f) => f,
            None if c < self.first[a] => Self::LOWEST,
            None => self.highest[a],
        })
    }

    /// [`CoefficientRange::of`] the world box of the integer corners `lo ..= hi` (for the
    /// lattice of `dims` these tables were made of).
    #[inline]
    fn range(&self, lo: [u32; 3], hi: [u32; 3], dims: [usize; 3]) -> CoefficientRange {
        CoefficientRange::from_floors(
            dims,
            std::array::from_fn(|a| self.floor(a, lo[a])),
            std::array::from_fn(|a| self.floor(a, hi[a])),
        )
    }
}

/// The split tests' reads of the patches' coefficients, remembered by patch and range for
/// as long as the coefficients stay as they are (one update of the tree) in a local update:
/// its nodes are small and close together, so most of them read the same blocks of the
/// coarser patches (in `bench/mesh.rs` `adaptive_remesh`, the three coarser patches' blocks
/// repeat over nearly every node of the stroke). A whole update reads each block directly
/// (its large nodes rarely share one: the lookups cost more than they save, in
/// `bench/profile_adaptive.rs`).
#[derive(Clone, Debug, Default)]
struct CoefficientReads {
    /// Per patch: the read of a block, keyed by [`CoefficientReads::key`].
    per_patch: Vec<HashMap<u64, PatchOverBox, BuildHasherDefault<EdgeIdHasher>>>,
    /// Per patch: its last read and key. Neighbouring nodes, visited one after another, read
    /// the same block of a coarser patch, so most reads are answered here without a lookup.
    last: Vec<Option<(u64, PatchOverBox)>>,
    /// Per patch: window tables over the coefficients near a local update's region.
    windows: Vec<WindowTables>,
    /// Whether reads are remembered (in a local update only).
    remember: bool,
}

impl CoefficientReads {
    /// Forgets every read (after the coefficients changed).
    fn clear(&mut self) {
        self.per_patch.iter_mut().for_each(HashMap::clear);
        self.last.iter_mut().for_each(|l| *l = None);
        self.windows.iter_mut().for_each(WindowTables::clear);
    }

    /// Builds each patch's window tables over its coefficients whose support meets the world
    /// box `lo ..= hi`.
    fn prepare_windows(&mut self, field: &MultiPatchField, lo: Vec3, hi: Vec3) {
        self.windows
            .resize_with(field.patches.len(), WindowTables::default);
        for (tables, patch) in self.windows.iter_mut().zip(&field.patches) {
            tables.build(patch, CoefficientRange::of(patch, lo, hi));
        }
    }

    /// The read of patch `n` (`patch`) of its coefficients `range`.
    fn over_box(&mut self, n: usize, patch: &Patch, range: CoefficientRange) -> PatchOverBox {
        if !self.remember {
            return read_coefficients(patch, range);
        }
        let CoefficientRange::Block {
            first,
            last,
            beyond,
        } = range
        else {
            return read_coefficients(patch, range);
        };
        let Some(key) = Self::key(patch, first, last, beyond) else {
            return read_coefficients(patch, range);
        };
        if self.per_patch.len() <= n {
            self.per_patch.resize_with(n + 1, HashMap::default);
            self.last.resize(n + 1, None);
        }
        if let Some((last_key, read)) = self.last[n]
            && last_key == key
        {
            return read;
        }
        let windows = self.windows.get(n).filter(|_| !beyond);
        let read = match windows.and_then(|w| w.read(patch, first, last)) {
            Some(read) => read,
            None => *self.per_patch[n]
                .entry(key)
                .or_insert_with(|| read_coefficients(patch, range)),
        };
        self.last[n] = Some((key, read));
        read
    }

    /// The block's first and last coefficients' linear indices and the `beyond` flag in one
    /// word; `None` for a lattice too large for 31-bit indices (read without remembering).
    fn key(patch: &Patch, first: [usize; 3], last: [usize; 3], beyond: bool) -> Option<u64> {
        let l = &patch.lattice;
        if l.coeffs.len() >= 1 << 31 {
            return None;
        }
        let from = l.index(first[0], first[1], first[2]) as u64;
        let to = l.index(last[0], last[1], last[2]) as u64;
        Some(from | to << 31 | u64::from(beyond) << 62)
    }
}

/// One patch's coefficients over a block, folded along x in windows of every length up to
/// [`WindowTables::MAX_WINDOW`], so that the split test's read of a range inside the block
/// costs a fold over its rows rather than over its coefficients (the read that
/// [`read_coefficients`] makes coefficient by coefficient: most of a local re-mesh's split
/// tests in `bench/profile_adaptive.rs` at 4 cells per span). Minima, maxima and absolute
/// differences are exact and the folds skip NaN as [`larger`] and [`smaller`] do, so a read
/// from the tables is, bit for bit, the one [`read_coefficients`] makes.
#[derive(Clone, Debug, Default)]
struct WindowTables {
    /// The block's first coefficient per axis.
    lo: [usize; 3],
    /// Coefficients per axis; zero when there is no block.
    dims: [usize; 3],
    /// Per quantity (see [`WindowTables::QUANTITIES`]) and window length `w` (from 1): at
    /// block coordinate `(i, j, k)` (x fastest), the fold of the quantity over `i .. i + w`.
    folds: Vec<f32>,
    /// The patch's [`Patch::world_spacing`], which scales its slope bounds.
    world_spacing: f32,
}

impl WindowTables {
    /// The longest window along x (a read of a longer range goes to the coefficients).
    const MAX_WINDOW: usize = 8;
    /// The folded quantities: the coefficients' minimum and maximum, and the largest step
    /// along x, y and z from a coefficient to the next one (within the block).
    const QUANTITIES: usize = 5;
    /// Most coefficients in a block (a larger local update reads coefficient by coefficient).
    const MAX_BLOCK: usize = 1 << 15;
    /// Finest cells beyond a local update's region that the block still serves: the nodes
    /// that meet the region and are at most this large.
    const REACH_CELLS: f32 = 4.0;

    fn clear(&mut self) {
        self.dims = [0; 3];
    }

    /// Folds `patch`'s coefficients in `range` (nothing for a range that is not a block).
    fn build(&mut self, patch: &Patch, range: CoefficientRange) {
        self.dims = [0; 3];
        let CoefficientRange::Block { first, last, .. } = range else {
            return;
        };
        let dims: [usize; 3] = std::array::from_fn(|a| last[a] - first[a] + 1);
        let count = dims.iter().product::<usize>();
        if count > Self::MAX_BLOCK {
            return;
        }
        let l = &patch.lattice;
        let [nx, ny, nz] = dims;
        let plane = Self::QUANTITIES * count;
        self.folds.clear();
        self.folds.resize(Self::MAX_WINDOW * plane, 0.0);
        let c =
            |i: usize, j: usize, k: usize| l.coeffs.get(first[0] + i, first[1] + j, first[2] + k);
        // Windows of length 1: the quantities themselves (a step out of the block counts as
        // none).
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    let at = i + nx * (j + ny * k);
                    let v = c(i, j, k);
                    let step = |q: Option<f32>| {
                        q.map_or(f32::NEG_INFINITY, |q| {
                            larger(f32::NEG_INFINITY, (q - v).abs())
                        })
                    };
                    self.folds[at] = smaller(f32::INFINITY, v);
                    self.folds[count + at] = larger(f32::NEG_INFINITY, v);
                    self.folds[2 * count + at] = step((i + 1 < nx).then(|| c(i + 1, j, k)));
                    self.folds[3 * count + at] = step((j + 1 < ny).then(|| c(i, j + 1, k)));
                    self.folds[4 * count + at] = step((k + 1 < nz).then(|| c(i, j, k + 1)));
                }
            }
        }
        // Window `w` at `i`: window `w - 1` at `i` with the length-1 entry at `i + w - 1`.
        for w in 2..=Self::MAX_WINDOW.min(nx) {
            let (prev, next) = self.folds.split_at_mut((w - 1) * plane);
            let (prev, ones) = (&prev[(w - 2) * plane..], &prev[..plane]);
            let next = &mut next[..plane];
            for q in 0..Self::QUANTITIES {
                let fold = if q == 0 { smaller } else { larger };
                for row in 0..ny * nz {
                    let base = q * count + row * nx;
                    for i in 0..=nx - w {
                        next[base + i] = fold(prev[base + i], ones[base + i + w - 1]);
                    }
                }
            }
        }
        self.lo = first;
        self.dims = dims;
        self.world_spacing = patch.world_spacing();
    }

    /// The read of the coefficients `first ..= last` of `patch` (every one inside its
    /// lattice), if the tables answer it: the range lies in the block, no row of it lies on
    /// the lattice's border (where [`read_coefficients`] counts steps to the zeros beyond)
    /// and it is at most [`WindowTables::MAX_WINDOW`] long along x.
    fn read(&self, patch: &Patch, first: [usize; 3], last: [usize; 3]) -> Option<PatchOverBox> {
        let l = &patch.lattice;
        let interior = (0..3).all(|a| first[a] > 0 && last[a] + 1 < l.dims[a]);
        let len = last[0] - first[0] + 1;
        let inside = (0..3).all(|a| first[a] >= self.lo[a] && last[a] < self.lo[a] + self.dims[a]);
        if !(interior && inside && len <= Self::MAX_WINDOW) {
            return None;
        }
        let [nx, ny, nz] = self.dims;
        let count = nx * ny * nz;
        let plane = Self::QUANTITIES * count;
        let i = first[0] - self.lo[0];
        let (j0, j1) = (first[1] - self.lo[1], last[1] - self.lo[1]);
        let (k0, k1) = (first[2] - self.lo[2], last[2] - self.lo[2]);
        // Each quantity's table for its window length.
        let table = |w: usize, q: usize| &self.folds[(w - 1) * plane + q * count..][..count];
        let (mins, maxs) = (table(len, 0), table(len, 1));
        let (y_steps, z_steps) = (table(len, 3), table(len, 4));
        let x_steps = (len > 1).then(|| table(len - 1, 2));
        // The steps are folded per axis and joined at the end: they are absolute values or
        // −∞, never NaN or −0, so their largest is the same in any order (the minima and
        // maxima keep [`read_coefficients`]' order, which decides the sign of a zero).
        let (mut vmin, mut vmax) = (f32::INFINITY, f32::NEG_INFINITY);
        let mut steepest = [0.0_f32; 3];
        for k in k0..=k1 {
            for j in j0..=j1 {
                let row = i + nx * (j + ny * k);
                vmin = smaller(vmin, mins[row]);
                vmax = larger(vmax, maxs[row]);
                if let Some(x_steps) = x_steps {
                    steepest[0] = larger(steepest[0], x_steps[row]);
                }
                if j < j1 {
                    steepest[1] = larger(steepest[1], y_steps[row]);
                }
                if k < k1 {
                    steepest[2] = larger(steepest[2], z_steps[row]);
                }
            }
        }
        let steepest = larger(larger(steepest[0], steepest[1]), steepest[2]);
        Some(PatchOverBox {
            bounds: Some((vmin, vmax)),
            slope: 3.0_f32.sqrt() * steepest / self.world_spacing,
        })
    }
}

/// Reads `patch`'s coefficients in `range` once, for both bounds of [`PatchOverBox`].
fn read_coefficients(patch: &Patch, range: CoefficientRange) -> PatchOverBox {
    let (first, last, beyond) = match range {
        CoefficientRange::NotFinite => {
            return PatchOverBox {
                bounds: None,
                slope: f32::INFINITY,
            };
        }
        CoefficientRange::Empty => {
            return PatchOverBox {
                bounds: Some((0.0, 0.0)),
                slope: 0.0,
            };
        }
        CoefficientRange::Block {
            first,
            last,
            beyond,
        } => (first, last, beyond),
    };
    let l = &patch.lattice;
    // Brick by brick: most of a whole clay's bricks are uniform, one value each.
    let inside = l.coeffs.box_summary(first, last, true);
    let (mut vmin, mut vmax) = if beyond {
        (0.0_f32, 0.0_f32)
    } else {
        (f32::INFINITY, f32::NEG_INFINITY)
    };
    vmin = smaller(vmin, inside.min);
    vmax = larger(vmax, inside.max);
    let mut steepest = inside.max_step;
    // Beyond the lattice the coefficients count as zero: a coefficient on its border is a
    // step of its own size.
    for axis in 0..3 {
        let border_faces = [
            (first[axis] == 0).then_some(0),
            (last[axis] + 1 == l.dims[axis]).then_some(last[axis]),
        ];
        for face in border_faces.into_iter().flatten() {
            let (mut face_first, mut face_last) = (first, last);
            face_first[axis] = face;
            face_last[axis] = face;
            let on_face = l.coeffs.box_summary(face_first, face_last, false);
            steepest = larger(steepest, larger(on_face.min.abs(), on_face.max.abs()));
        }
    }
    PatchOverBox {
        bounds: Some((vmin, vmax)),
        slope: 3.0_f32.sqrt() * steepest / patch.world_spacing(),
    }
}

/// `x.floor() as i64` for a finite `x`, without a call to `floorf` (x86-64's baseline has
/// no rounding instruction): truncate, then step down where that rounded a negative value up.
#[inline]
fn floor_to_int(x: f32) -> i64 {
    let t = x as i64;
    if (t as f32) > x {
        t.saturating_sub(1)
    } else {
        t
    }
}

#[cfg(test)]
pub(super) mod tests {
    use std::collections::HashMap;
    use std::f64::consts::PI;

    use glam::Vec3;

    use super::super::{BrickOctree, MeshStats, SampleGrid, hausdorff};
    use super::*;
    use crate::field::{BSplineLattice, fit_lattice};

    /// Base knot spacing of the test fields.
    pub(in crate::mesh) const SPACING: f32 = 0.1;

    /// A smooth density of the solid at signed distance `d` (positive inside): one half on the
    /// surface, 0 and 1 a few spans away.
    fn density(d: f32) -> f32 {
        0.5 + 0.5 * (d / (3.0 * SPACING)).tanh()
    }

    /// A base lattice fitted to `target` over the cube `-half ..= half` (plus padding).
    fn fitted_base(half: f32, target: impl Fn(Vec3) -> f32) -> MultiPatchField {
        let reach = half + 6.0 * SPACING;
        let n = (2.0 * reach / SPACING).ceil() as usize + 1;
        let mut lattice =
            BSplineLattice::zeros([n; 3], SPACING, Vec3::splat(-reach)).expect("lattice");
        fit_lattice(&mut lattice, 2, target).expect("fit");
        MultiPatchField::new(lattice)
    }

    fn sphere(radius: f32) -> impl Fn(Vec3) -> f32 {
        move |x: Vec3| density(radius - x.length())
    }

    /// Sorted, deduplicated cell sizes.
    fn sizes(cells: &[f32]) -> Vec<f32> {
        let mut s = cells.to_vec();
        s.sort_by(f32::total_cmp);
        s.dedup();
        s
    }

    /// Connected components of the triangles (through shared vertices).
    fn components(mesh: &TriMesh) -> usize {
        let mut parent: Vec<u32> = (0..mesh.positions.len() as u32).collect();
        fn root(parent: &mut [u32], mut i: u32) -> u32 {
            while parent[i as usize] != i {
                parent[i as usize] = parent[parent[i as usize] as usize];
                i = parent[i as usize];
            }
            i
        }
        for t in &mesh.triangles {
            for k in 1..3 {
                let (a, b) = (root(&mut parent, t[0]), root(&mut parent, t[k]));
                parent[a as usize] = b;
            }
        }
        let mut roots: Vec<u32> = mesh
            .triangles
            .iter()
            .map(|t| root(&mut parent, t[0]))
            .collect();
        roots.sort_unstable();
        roots.dedup();
        roots.len()
    }

    /// Asserts a closed, edge-manifold, consistently oriented mesh of one piece facing out.
    fn closed(mesh: &TriMesh) -> MeshStats {
        assert!(mesh.is_well_formed());
        let s = MeshStats::of(mesh);
        assert_eq!(s.boundary_edges, 0, "{s:?}");
        assert_eq!(s.non_manifold_edges, 0, "{s:?}");
        assert_eq!(s.misoriented_edges, 0, "{s:?}");
        assert!(s.volume > 0.0, "{s:?}");
        assert_eq!(components(mesh), 1);
        s
    }

    /// Largest `|F − iso| / |∇F| / cell` over the vertices: each vertex's distance to the
    /// field's surface (first order) in units of its own leaf's edge.
    fn worst_surface_offset(field: &MultiPatchField, e: &Extraction) -> f32 {
        e.mesh
            .positions
            .iter()
            .zip(&e.vertex_cells)
            .map(|(&x, &cell)| {
                let (v, g) = field.value_and_gradient(x);
                (v - field.iso()).abs() / g.length() / cell
            })
            .fold(0.0, f32::max)
    }

    fn options(cells_per_span: u32) -> AdaptiveMeshOptions {
        AdaptiveMeshOptions {
            cells_per_span,
            max_cells: 4_000_000,
        }
    }

    #[test]
    fn adaptive_single_level_sphere_is_closed_and_on_the_sphere() {
        let radius = 0.5;
        let field = fitted_base(radius, sphere(radius));
        let e = extract(&field, &options(2)).unwrap();
        let s = closed(&e.mesh);
        assert_eq!(s.euler_characteristic, 2, "{s:?}");
        let cell = SPACING / 2.0;
        assert_eq!(sizes(&e.vertex_cells), vec![cell]);
        let worst = e
            .mesh
            .positions
            .iter()
            .map(|p| (p.length() - radius).abs())
            .fold(0.0, f32::max);
        let r = f64::from(radius);
        let area_err = (s.area / (4.0 * PI * r * r) - 1.0).abs();
        let volume_err = (s.volume / (4.0 / 3.0 * PI * r * r * r) - 1.0).abs();
        println!(
            "single level: {} vertices, {} triangles, worst |r - R| = {worst:.5} (cell {cell}), \
             area error {:.3}%, volume error {:.3}%",
            s.vertices,
            s.triangles,
            100.0 * area_err,
            100.0 * volume_err
        );
        assert!(worst <= 0.5 * cell, "{worst}");
        assert!(
            area_err < 0.03 && volume_err < 0.03,
            "{area_err} {volume_err}"
        );
        for (p, n) in e.mesh.positions.iter().zip(&e.mesh.normals) {
            assert!(n.dot(p.normalize()) > 0.98);
        }
        assert_eq!(
            adaptive_cell_count(&field, &options(2)).unwrap(),
            Tree::build(&field, &options(2)).unwrap().leaves
        );
    }

    /// A Gaussian bump of `height` and width `sigma` centred at `at`.
    fn bump(x: Vec3, at: Vec3, height: f32, sigma: f32) -> f32 {
        height * (-(x - at).length_squared() / (sigma * sigma)).exp()
    }

    /// The three-level field: a sphere of radius 0.5 at the origin, a level-1 patch over the
    /// +x half's cap with a bump of width 0.06 in it, and nested in that a level-2 patch
    /// around the +x pole with a bump of width 0.03 (finer than level 1's spans). Every
    /// patch's box crosses the surface.
    pub(in crate::mesh) fn three_levels() -> MultiPatchField {
        let radius = 0.5;
        let mut field = fitted_base(radius, sphere(radius));
        let p1 = radius * Vec3::new(1.0, -0.6, 0.3).normalize();
        let p2 = radius * Vec3::new(1.0, 0.05, 0.05).normalize();
        let target =
            move |x: Vec3| sphere(radius)(x) + bump(x, p1, 0.08, 0.06) + bump(x, p2, 0.08, 0.03);
        let l1 = field
            .refine(Vec3::new(0.0, -0.45, -0.45), Vec3::new(0.8, 0.45, 0.45), 1)
            .unwrap();
        field.fit_detail(l1, 2, target).unwrap();
        let l2 = field
            .refine(Vec3::new(0.3, -0.15, -0.15), Vec3::new(0.7, 0.15, 0.15), 2)
            .unwrap();
        field.fit_detail(l2, 2, target).unwrap();
        field
    }

    #[test]
    fn adaptive_three_levels_are_closed_graded_and_match_the_finest_mesh() {
        let field = three_levels();
        let e = extract(&field, &options(2)).unwrap();
        let s = closed(&e.mesh);
        assert_eq!(s.euler_characteristic, 2, "{s:?}");
        let (base, mid, fine) = (SPACING / 2.0, SPACING / 4.0, SPACING / 8.0);
        assert_eq!(sizes(&e.vertex_cells), vec![fine, mid, base]);

        // Each region is meshed at its own patch's cell where the patch holds detail (a
        // corner of a patch whose fit left it below `DETAIL_EPSILON` keeps the coarser cell),
        // and the vertex density per area grows about fourfold per level.
        let in_fine = |p: Vec3| p.x >= 0.3 && p.x <= 0.7 && p.y.abs() <= 0.15 && p.z.abs() <= 0.15;
        let in_mid = |p: Vec3| {
            p.x >= 0.05
                && p.x <= 0.75
                && p.y.abs() <= 0.4
                && p.z.abs() <= 0.4
                && !(p.x > 0.18 && p.y.abs() < 0.27 && p.z.abs() < 0.27)
        };
        let in_base = |p: Vec3| p.x < -0.25;
        let regions: [(&dyn Fn(Vec3) -> bool, f32); 3] =
            [(&in_base, base), (&in_mid, mid), (&in_fine, fine)];
        let mut density = [0.0_f64; 3];
        for (r, (inside, cell)) in regions.iter().enumerate() {
            // Where the region's own patch adds more than ten times `DETAIL_EPSILON`, every
            // vertex is at the region's cell; elsewhere it may be coarser, never finer.
            let holds = |p: Vec3| r == 0 || field.patches[r].value(p).abs() > 10.0 * DETAIL_EPSILON;
            let own_cell = |p: Vec3, c: f32| inside(p) && c == *cell;
            let (mut vertices, mut own) = (0_u32, 0_u32);
            for (p, c) in e.mesh.positions.iter().zip(&e.vertex_cells) {
                if inside(*p) {
                    assert!(
                        *c >= *cell && *c <= base,
                        "vertex at {p} in region {r}: {c}"
                    );
                    if holds(*p) {
                        assert_eq!(
                            c, cell,
                            "vertex at {p} in region {r}, where its patch holds detail"
                        );
                    }
                    vertices += 1;
                    own += u32::from(c == cell);
                }
            }
            println!("region {r}: {own} of {vertices} vertices at its own cell {cell}");
            // The density of vertices per area over the triangles at the region's own cell.
            let area: f64 = e
                .mesh
                .triangles
                .iter()
                .filter(|t| {
                    t.iter().all(|&i| {
                        own_cell(e.mesh.positions[i as usize], e.vertex_cells[i as usize])
                    })
                })
                .map(|t| t.map(|i| e.mesh.positions[i as usize]))
                .map(|[a, b, c]| 0.5 * f64::from((b - a).cross(c - a).length()))
                .sum();
            assert!(own > 50, "region {r}: {own} vertices at its own cell");
            density[r] = f64::from(own) / area;
        }
        let ratios = [density[1] / density[0], density[2] / density[1]];
        println!("vertices per unit area (base, level 1, level 2): {density:?}, ratios {ratios:?}");
        // Four per level, give or take the surface's slant to the grid: a face square to an
        // axis (the fine region, around the +x pole) takes fewer vertices per area than a
        // slanted one (most of the base region).
        for ratio in ratios {
            assert!((2.5..6.0).contains(&ratio), "{ratios:?}");
        }

        let worst = worst_surface_offset(&field, &e);
        println!("worst vertex offset from the field's surface: {worst:.2e} of its cell");
        assert!(worst <= 0.5, "{worst}");

        // Against marching cubes at the finest cell everywhere: the seams add no gap.
        let (lo, hi) = field.support();
        let grid = SampleGrid::covering(lo, hi, fine).unwrap();
        let reference = BrickOctree::build(grid, &field).weld();
        let h = hausdorff(&e.mesh, &reference).unwrap();
        println!(
            "adaptive {} vertices, {} triangles; finest marching cubes {} vertices; \
             hausdorff adaptive->finest {:.5} (mean {:.6}), finest->adaptive {:.5} (mean {:.6}), \
             finest cell {fine}",
            s.vertices,
            s.triangles,
            reference.vertex_count(),
            h.a_to_b,
            h.mean_a_to_b,
            h.b_to_a,
            h.mean_b_to_a
        );
        assert!(h.a_to_b <= fine && h.b_to_a <= fine, "{h:?}");
        assert!(
            s.vertices * 3 < reference.vertex_count(),
            "adaptive saved little"
        );
    }

    #[test]
    fn adaptive_torus_has_euler_characteristic_zero_on_two_levels() {
        let (major, minor) = (0.6_f32, 0.25_f32);
        let torus = move |x: Vec3| density(minor - (x.x.hypot(x.y) - major).hypot(x.z));
        let mut field = fitted_base(major + minor, torus);
        let d = field
            .refine(Vec3::new(0.0, -1.0, -1.0), Vec3::new(1.0, 1.0, 1.0), 1)
            .unwrap();
        field.fit_detail(d, 2, torus).unwrap();
        let e = extract(&field, &options(2)).unwrap();
        let s = closed(&e.mesh);
        println!("torus: {s:?}");
        assert_eq!(s.euler_characteristic, 0, "{s:?}");
        assert_eq!(sizes(&e.vertex_cells), vec![SPACING / 4.0, SPACING / 2.0]);
        assert!(worst_surface_offset(&field, &e) <= 0.5);
        let volume = 2.0 * PI * PI * f64::from(major) * f64::from(minor).powi(2);
        assert!(
            (s.volume / volume - 1.0).abs() < 0.05,
            "{} vs {volume}",
            s.volume
        );
    }

    #[test]
    fn adaptive_budget_is_checked_before_the_tree_grows() {
        let field = fitted_base(0.5, sphere(0.5));
        let needed = adaptive_cell_count(&field, &options(2)).unwrap();
        let tight = AdaptiveMeshOptions {
            cells_per_span: 2,
            max_cells: needed - 1,
        };
        match mesh_adaptive(&field, &tight) {
            Err(AdaptiveMeshError::OverBudget { limit, leaves }) => {
                assert_eq!(limit, needed - 1);
                // Refused at the first split that would pass the budget: at most one split's
                // seven new leaves beyond it.
                assert!(leaves > limit && leaves <= limit + 7, "{leaves}");
            }
            other => panic!("{other:?}"),
        }
        let exact = AdaptiveMeshOptions {
            max_cells: needed,
            ..tight
        };
        assert!(mesh_adaptive(&field, &exact).is_ok());

        // A budget far below what 4096 cells per span would need (about 10^11 leaves) is
        // refused after a few thousand leaves, not after allocating them.
        let absurd = AdaptiveMeshOptions {
            cells_per_span: 4096,
            max_cells: 10_000,
        };
        assert!(matches!(
            mesh_adaptive(&field, &absurd),
            Err(AdaptiveMeshError::OverBudget { limit: 10_000, leaves }) if leaves <= 10_007
        ));
        assert!(matches!(
            adaptive_cell_count(
                &field,
                &AdaptiveMeshOptions {
                    max_cells: 0,
                    ..tight
                }
            ),
            Err(AdaptiveMeshError::OverBudget {
                limit: 0,
                leaves: 1
            })
        ));
        assert_eq!(
            mesh_adaptive(
                &field,
                &AdaptiveMeshOptions {
                    cells_per_span: 1,
                    ..tight
                }
            ),
            Err(AdaptiveMeshError::CellsPerSpan { cells_per_span: 1 })
        );
        assert_eq!(
            mesh_adaptive(&MultiPatchField::default(), &options(2)),
            Err(AdaptiveMeshError::EmptyField)
        );
    }

    #[test]
    fn adaptive_seam_through_the_surface_stays_closed_and_oriented() {
        // A level-2 patch whose box ends halfway up the sphere (z = 0.05), fitted to a
        // ripple that is still at full strength there: the detail fades out within the
        // patch's last spans, across the surface, next to base cells four times larger.
        let radius = 0.5;
        let mut field = fitted_base(radius, sphere(radius));
        let d = field
            .refine(Vec3::new(-0.1, -0.7, -0.7), Vec3::new(0.7, 0.7, 0.05), 2)
            .unwrap();
        let ripple =
            move |x: Vec3| sphere(radius)(x) + 0.04 * (40.0 * x.x).sin() * (40.0 * x.y).sin();
        field.fit_detail(d, 2, ripple).unwrap();
        let e = extract(&field, &options(2)).unwrap();
        let mesh = &e.mesh;
        assert!(mesh.is_well_formed());
        let s = MeshStats::of(mesh);
        println!("seam through the surface: {s:?}");
        assert_eq!(s.boundary_edges, 0, "{s:?}");
        assert_eq!(s.misoriented_edges, 0, "{s:?}");
        assert!(s.volume > 0.0, "{s:?}");
        assert_eq!(components(mesh), 1);
        // Finest and base cells, and at the seam the cells a split base leaf leaves outside
        // the detail's support.
        let found = sizes(&e.vertex_cells);
        assert_eq!(found.first(), Some(&(SPACING / 8.0)), "{found:?}");
        assert_eq!(found.last(), Some(&(SPACING / 2.0)), "{found:?}");
        assert!(worst_surface_offset(&field, &e) <= 0.5);
        // Both sides of the seam are meshed: vertices of both sizes above and below it.
        let (low_z, high_z): (Vec<_>, Vec<_>) = mesh
            .positions
            .iter()
            .zip(&e.vertex_cells)
            .partition(|(p, _)| p.z < 0.05);
        assert!(low_z.iter().any(|&(_, &c)| c == SPACING / 8.0));
        assert!(high_z.iter().any(|&(_, &c)| c == SPACING / 2.0));
        // One vertex per leaf cannot separate two sheets through one leaf: at the ripple's
        // saddles a leaf face can be ambiguous (corners alternating in sign) and its edge is
        // then used by four triangles. None of those lies at a seam: every triangle on such
        // an edge has all three vertices in leaves of one size.
        let mut uses: HashMap<(u32, u32), Vec<[u32; 3]>> = HashMap::new();
        for t in &mesh.triangles {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                uses.entry((a.min(b), a.max(b))).or_default().push(*t);
            }
        }
        let mut shared = 0;
        for triangles in uses.values().filter(|t| t.len() > 2) {
            shared += 1;
            for t in triangles {
                let cells = t.map(|i| e.vertex_cells[i as usize]);
                assert!(cells.iter().all(|&c| c == cells[0]), "{t:?}: {cells:?}");
            }
        }
        assert_eq!(shared, s.non_manifold_edges);
        println!("edges on four triangles (ambiguous faces, none at a seam): {shared}");
    }

    #[test]
    fn adaptive_mesh_cuts_ambiguous_faces_into_a_manifold_without_moving_anything() {
        // The rippled seam above: its ambiguous leaf faces give edges of four triangles in
        // the extraction; the exported mesh has none, and the same area and volume.
        let radius = 0.5;
        let mut field = fitted_base(radius, sphere(radius));
        let d = field
            .refine(Vec3::new(-0.1, -0.7, -0.7), Vec3::new(0.7, 0.7, 0.05), 2)
            .unwrap();
        let ripple =
            move |x: Vec3| sphere(radius)(x) + 0.04 * (40.0 * x.x).sin() * (40.0 * x.y).sin();
        field.fit_detail(d, 2, ripple).unwrap();
        let raw = MeshStats::of(&extract(&field, &options(2)).unwrap().mesh);
        assert!(raw.non_manifold_edges > 0, "{raw:?}");
        let mesh = mesh_adaptive(&field, &options(2)).unwrap();
        let s = closed(&mesh);
        assert_eq!(s.triangles, raw.triangles);
        assert!(s.vertices > raw.vertices);
        assert!(
            (s.area - raw.area).abs() <= 1e-9 * raw.area,
            "{s:?} {raw:?}"
        );
        assert!(
            (s.volume - raw.volume).abs() <= 1e-9 * raw.volume,
            "{s:?} {raw:?}"
        );
    }

    #[test]
    fn adaptive_outside_the_root_counts_as_outside_even_below_zero_iso() {
        // With a negative iso-level, the zero field beyond the supports would be inside; the
        // root's boundary is forced outside so the mesh still closes (around the root).
        let mut field = fitted_base(0.3, sphere(0.3));
        field.base_mut().iso = -0.25;
        let e = extract(&field, &options(2)).unwrap();
        let s = closed(&e.mesh);
        assert_eq!(s.euler_characteristic, 2, "{s:?}");
        assert!(
            e.mesh
                .normals
                .iter()
                .all(|n| (n.length() - 1.0).abs() < 1e-4)
        );
    }

    /// The vertices as (position, normal) bits, sorted.
    fn vertex_set(mesh: &TriMesh) -> Vec<[u32; 6]> {
        let mut set: Vec<_> = mesh
            .positions
            .iter()
            .zip(&mesh.normals)
            .map(|(p, n)| {
                let (p, n) = (p.to_array(), n.to_array());
                [p[0], p[1], p[2], n[0], n[1], n[2]].map(f32::to_bits)
            })
            .collect();
        set.sort_unstable();
        set
    }

    /// Asserts that the kept mesh is closed and oriented and holds the same vertices and
    /// triangles as a whole mesh of `field`, and that the trees have as many leaves.
    fn matches_whole(mesher: &AdaptiveMesher, field: &MultiPatchField) -> MeshStats {
        let local = mesher.mesh();
        assert!(local.is_well_formed());
        let s = MeshStats::of(&local);
        assert_eq!(s.boundary_edges, 0, "{s:?}");
        assert_eq!(s.misoriented_edges, 0, "{s:?}");
        // The whole path's kept mesh, before the manifold cut that `mesh_adaptive` adds.
        let whole = AdaptiveMesher::new(field, &options(2)).unwrap().mesh();
        assert_eq!(local.triangle_count(), whole.triangle_count());
        assert_eq!(vertex_set(&local), vertex_set(&whole));
        assert_eq!(local.canonical_triangles(), whole.canonical_triangles());
        assert_eq!(
            mesher.leaf_count(),
            adaptive_cell_count(field, &options(2)).unwrap()
        );
        s
    }

    /// Subtracts `depth` from the coefficients of patch `patch` at the nodes from the one
    /// nearest `at` to `count - 1` nodes further along +x; returns the box where the field
    /// changed.
    pub(in crate::mesh) fn dent(
        field: &mut MultiPatchField,
        patch: usize,
        at: Vec3,
        count: usize,
        depth: f32,
    ) -> (Vec3, Vec3) {
        let p = &mut field.patches[patch];
        let node = ((at - p.lattice.origin) / p.lattice.spacing)
            .round()
            .to_array()
            .map(|v| v as usize);
        for step in 0..count {
            let idx = p.lattice.index(node[0] + step, node[1], node[2]);
            p.lattice.coeffs.add_flat(idx, -depth);
        }
        p.coefficient_change_box(node, [node[0] + count - 1, node[1], node[2]])
    }

    #[test]
    fn adaptive_local_remesh_after_a_fine_stroke_equals_a_whole_remesh() {
        let mut field = three_levels();
        let original = field.clone();
        let mut mesher = AdaptiveMesher::new(&field, &options(2)).unwrap();
        let before = mesher.mesh();
        // A stroke as fine as the finest patch, on the surface at the +x pole: three of its
        // coefficients dented.
        let pole = 0.5 * Vec3::new(1.0, 0.05, 0.05).normalize();
        let (lo, hi) = dent(&mut field, 2, pole, 3, 0.05);
        let report = mesher.remesh_box(&field, lo, hi).unwrap();
        let s = matches_whole(&mesher, &field);
        println!("fine stroke: {report:?}; {s:?}");
        assert!(!report.whole);
        assert_ne!(
            mesher.mesh().canonical_triangles(),
            before.canonical_triangles()
        );
        assert!(report.polygons_made > 0 && report.polygons_dropped > 0);
        assert!(report.vertices_made > 0 && report.vertices_made <= report.leaves_revisited);
        // Only the leaves near the stroke were visited: under a tenth of the tree (the change
        // box is meshed at the finest cell throughout, inside and outside the clay too).
        assert!(
            report.leaves_revisited * 10 < report.leaves,
            "{} of {} leaves",
            report.leaves_revisited,
            report.leaves
        );
        // Every revisited leaf meets the change box (grown by a 64th of a finest cell) or is
        // new: the vertices made lie in it, grown by a leaf.
        let made: Vec<Vec3> = {
            let whole = vertex_set(&before);
            mesher
                .mesh()
                .positions
                .iter()
                .zip(&mesher.mesh().normals)
                .filter(|(p, n)| {
                    let (p, n) = (p.to_array(), n.to_array());
                    let key = [p[0], p[1], p[2], n[0], n[1], n[2]].map(f32::to_bits);
                    whole.binary_search(&key).is_err()
                })
                .map(|(p, _)| *p)
                .collect()
        };
        assert!(!made.is_empty());
        // A revisited leaf meets the box grown by a 64th of a finest cell; a vertex lies in
        // its leaf, at most a base cell.
        let grown = SPACING / 8.0 / 64.0 + SPACING / 2.0 + 1e-5;
        for p in made {
            assert!(
                p.cmpge(lo - grown).all() && p.cmple(hi + grown).all(),
                "{p} outside {lo} ..= {hi}"
            );
        }

        // Undoing the stroke gives back the first mesh.
        let report = mesher.remesh_box(&original, lo, hi).unwrap();
        assert!(!report.whole);
        matches_whole(&mesher, &original);
        assert_eq!(
            mesher.mesh().canonical_triangles(),
            before.canonical_triangles()
        );
    }

    #[test]
    fn adaptive_local_remesh_follows_strokes_that_refine_and_coarsen_the_tree() {
        let mut field = three_levels();
        let mut mesher = AdaptiveMesher::new(&field, &options(2)).unwrap();
        let leaves = mesher.leaf_count();
        // Detail where the level-1 patch held none (the tree grows finer there), then a
        // deep base dent on the far side (the surface leaves its old leaves), then the
        // level-1 detail taken out again (the tree coarsens and reuses the freed nodes).
        let quiet = 0.5 * Vec3::new(0.6, 0.6, -0.5).normalize();
        let strokes: [(usize, Vec3, usize, f32); 4] = [
            (1, quiet, 2, -0.3),
            (0, Vec3::new(-0.5, 0.0, 0.0), 1, 0.4),
            (2, 0.5 * Vec3::new(1.0, 0.05, 0.05).normalize(), 3, 0.05),
            (1, quiet, 2, 0.3),
        ];
        let (mut grew, mut shrank, mut previous) = (false, false, leaves);
        for (patch, at, count, depth) in strokes {
            let (lo, hi) = dent(&mut field, patch, at, count, depth);
            let report = mesher.remesh_box(&field, lo, hi).unwrap();
            let s = matches_whole(&mesher, &field);
            println!("stroke on patch {patch}: {report:?}; {s:?}");
            assert!(!report.whole);
            grew |= report.leaves > previous;
            shrank |= report.leaves < previous;
            previous = report.leaves;
        }
        assert!(
            grew && shrank,
            "the strokes did not both refine and coarsen the tree"
        );
    }

    #[test]
    fn adaptive_local_remesh_of_a_region_too_large_for_one_block_equals_a_whole_remesh() {
        // A change box around the whole clay: its region holds far more corners than
        // `RegionSamples::MAX_CORNERS`, so the corners are sampled one by one.
        let mut field = three_levels();
        let mut mesher = AdaptiveMesher::new(&field, &options(2)).unwrap();
        let root = mesher.tree.root_size as usize + 1;
        assert!(root.pow(3) > RegionSamples::MAX_CORNERS);
        let pole = 0.5 * Vec3::new(1.0, 0.05, 0.05).normalize();
        let (lo, hi) = dent(&mut field, 2, pole, 3, 0.05);
        let (all_lo, all_hi) = field.support();
        let report = mesher
            .remesh_box(&field, lo.min(all_lo), hi.max(all_hi))
            .unwrap();
        assert!(!report.whole);
        assert_eq!(report.leaves_revisited, report.leaves);
        matches_whole(&mesher, &field);
        // Then a stroke-sized change is sampled as one block again.
        let (lo, hi) = dent(&mut field, 2, pole, 3, -0.05);
        let report = mesher.remesh_box(&field, lo, hi).unwrap();
        assert!(report.leaves_revisited * 10 < report.leaves, "{report:?}");
        matches_whole(&mesher, &field);
    }

    #[test]
    fn a_region_meets_the_nodes_whose_closed_box_meets_the_slightly_grown_change_box() {
        // The origin's 144 cells are the largest coordinate: every box's slack is theirs.
        let origin = [144.0, 0.0, 0.0];
        let slack = Region::slack_cells(144.0);
        // Change boxes on the lattice, a little off it either way, thinner than a cell and
        // beyond the root's sides (of 64 cells).
        let edges = [
            (10.0, 14.0),
            (10.0 + 1e-3, 14.0 - 1e-3),
            (10.0 - 1e-3, 14.0 + 1e-3),
            (10.0 + 0.05, 14.0 - 0.05),
            (10.3, 13.7),
            (10.2, 10.4),
            (10.0, 10.0),
            (-5.0, 3.5),
            (60.5, 80.0),
        ];
        let mut met = 0;
        for &(a, b) in &edges {
            let region = Region::of_cells([a, 12.0, 12.0], [b, 12.0, 12.0], origin, 64);
            for size in [1_u32, 2, 4, 8] {
                for m in (0..=64 - size).step_by(size as usize) {
                    let node = Node {
                        min: [m, 12 - size / 2, 12 - size / 2],
                        size,
                        children: 0,
                    };
                    // Along y and z every node holds 12, the box's one corner there; along
                    // x, the plain test in f64: the closed boxes meet.
                    let (lo, hi) = (f64::from(m), f64::from(m + size));
                    let plain = hi >= a - slack && lo <= b + slack;
                    assert_eq!(region.meets(&node), plain, "{a} ..= {b}, node {node:?}");
                    met += usize::from(plain);
                }
            }
        }
        assert!(met > 50, "{met} nodes met");
        // A change box on the lattice keeps the nodes that only touch it, not one beyond.
        let region = Region::of_cells([10.0; 3], [14.0; 3], [0.0; 3], 64);
        assert_eq!(
            region,
            Region {
                lo: [10; 3],
                hi: [14; 3]
            }
        );
    }

    #[test]
    fn region_samples_find_uniform_boxes_as_a_corner_by_corner_count_does() {
        // A block of 7 × 5 × 6 corners from (3, 4, 5), inside where x + 2y - z > 6.
        let (lo, dims) = ([3_u32, 4, 5], [7_usize, 5, 6]);
        let mut samples = RegionSamples {
            lo,
            dims,
            ..RegionSamples::default()
        };
        let value = |p: [u32; 3]| p[0] as f32 + 2.0 * p[1] as f32 - p[2] as f32;
        for z in 0..dims[2] as u32 {
            for y in 0..dims[1] as u32 {
                for x in 0..dims[0] as u32 {
                    samples
                        .values
                        .push(value([lo[0] + x, lo[1] + y, lo[2] + z]));
                }
            }
        }
        samples.count_inside(6.0);
        // Every entry of the table counts the inside corners below it, as one by one.
        let (sx, sy) = (dims[0] + 1, (dims[0] + 1) * (dims[1] + 1));
        for z in 0..=dims[2] {
            for y in 0..=dims[1] {
                for x in 0..=dims[0] {
                    let below = (0..z)
                        .flat_map(|k| (0..y).flat_map(move |j| (0..x).map(move |i| [i, j, k])))
                        .filter(|p| value(std::array::from_fn(|a| lo[a] + p[a] as u32)) > 6.0)
                        .count();
                    assert_eq!(
                        samples.inside_below[x + sx * y + sy * z] as usize,
                        below,
                        "below ({x}, {y}, {z})"
                    );
                }
            }
        }
        let (mut uniform, mut mixed) = (0, 0);
        for (a, b) in [
            ([3, 4, 5], [9, 8, 10]),
            ([3, 4, 5], [3, 4, 5]),
            ([3, 4, 10], [4, 5, 10]),
            ([8, 7, 5], [9, 8, 6]),
            ([5, 6, 7], [6, 7, 8]),
            ([3, 4, 9], [5, 4, 10]),
            ([2, 4, 5], [4, 5, 6]),
            ([8, 7, 9], [9, 8, 11]),
            ([3, 4, 5], [4, 5, 6]),
            ([3, 4, 8], [5, 5, 9]),
        ] {
            let mut inside = 0;
            let mut corners = 0;
            for z in a[2]..=b[2] {
                for y in a[1]..=b[1] {
                    for x in a[0]..=b[0] {
                        inside += usize::from(value([x, y, z]) > 6.0);
                        corners += 1;
                    }
                }
            }
            let held = samples.index(a).is_some() && samples.index(b).is_some();
            let expected = held && (inside == 0 || inside == corners);
            assert_eq!(samples.uniform(a, b), expected, "{a:?} ..= {b:?}");
            uniform += usize::from(expected);
            mixed += usize::from(held && !expected);
        }
        assert!(
            uniform >= 2 && mixed >= 2,
            "{uniform} uniform, {mixed} mixed"
        );
    }

    #[test]
    fn corner_floors_give_the_coefficient_ranges_of_the_world_boxes() {
        // The three-level clay's patches, one more whose origin and spacing are off the
        // octree's lattice, and one with a map (which gets no tables).
        let mut field = three_levels();
        let odd =
            BSplineLattice::zeros([7, 5, 6], SPACING / 3.0, Vec3::new(-0.123, 0.071, 0.2)).unwrap();
        field.patches.push(Patch::identity(odd.clone()));
        let mut mapped = Patch::identity(odd);
        mapped.world_to_patch = Affine3A::from_rotation_z(0.3);
        field.patches.push(mapped);
        let tree = Tree::frame(&field, &options(4)).unwrap();
        let last = field.patches.len() - 1;
        assert!(tree.floors[last].is_none());
        assert!(tree.floors[..last].iter().all(Option::is_some));
        let root = tree.root_size;
        let mut state = 0x9e37_79b9_7f4a_7c15_u64;
        let mut below = |m: u32| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state % (u64::from(m) + 1)) as u32
        };
        let (mut empty, mut beyond, mut interior) = (0, 0, 0);
        for _ in 0..20_000 {
            let size = 1 << below(root.trailing_zeros());
            let lo: [u32; 3] = std::array::from_fn(|_| below(root - size));
            let hi: [u32; 3] = std::array::from_fn(|a| lo[a] + below(size));
            for (patch, floors) in field.patches.iter().zip(&tree.floors).take(last) {
                let range = floors.as_ref().unwrap().range(lo, hi, patch.lattice.dims);
                let world = CoefficientRange::of(patch, tree.point(lo), tree.point(hi));
                assert_eq!(range, world, "{lo:?} ..= {hi:?}");
                match range {
                    CoefficientRange::Empty => empty += 1,
                    CoefficientRange::Block { beyond: true, .. } => beyond += 1,
                    CoefficientRange::Block { .. } => interior += 1,
                    CoefficientRange::NotFinite => unreachable!(),
                }
            }
        }
        assert!(
            empty > 100 && beyond > 100 && interior > 100,
            "{empty} empty, {beyond} beyond, {interior} interior"
        );
    }

    #[test]
    fn a_patch_moves_no_further_within_a_box_than_its_reach() {
        // A smooth slope with a dent of a few coefficients (the stroke the reach is for) and
        // a steep wall: over large boxes the hull binds, over small ones the slope bound.
        let mut lattice = BSplineLattice::zeros([14, 13, 12], 0.25, Vec3::ZERO).unwrap();
        lattice.coeffs.update_each(|n, c| {
            let (i, j) = (n % 14, (n / 14) % 13);
            *c = 0.05 * i as f32 + if j > 8 { 0.8 } else { 0.0 };
        });
        for (i, j, k) in [(6, 5, 6), (7, 5, 6), (6, 6, 6)] {
            let at = lattice.index(i, j, k);
            lattice.coeffs.set_flat(at, lattice.coeffs[at] - 0.05);
        }
        let rotated = Affine3A::from_scale_rotation_translation(
            Vec3::splat(1.3),
            glam::Quat::from_rotation_y(0.4),
            Vec3::new(0.2, -0.1, 0.3),
        );
        let mut seed = 12_345_u32;
        let mut unit = move || {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (seed >> 8) as f32 / (1u32 << 24) as f32
        };
        let (mut by_hull, mut by_slope) = (0, 0);
        for patch in [
            Patch::identity(lattice.clone()),
            Patch {
                lattice,
                world_to_patch: rotated,
            },
        ] {
            for _ in 0..200 {
                // Sizes from a tenth of a span to a few spans, most of them small.
                let size = unit().powi(3) * 1.2 + 0.02;
                let half = Vec3::new(unit(), unit(), unit()) * size + Vec3::splat(0.01);
                let centre = Vec3::new(unit(), unit(), unit()) * 2.5 + Vec3::splat(0.3);
                let (lo, hi) = (centre - half, centre + half);
                let over = read_coefficients(&patch, CoefficientRange::of(&patch, lo, hi));
                let half_diagonal = 0.5 * (hi - lo).length();
                let reach = over.reach(half_diagonal);
                if reach < over.slope * half_diagonal {
                    by_hull += 1;
                } else {
                    by_slope += 1;
                }
                let at_centre = patch.value(centre);
                for _ in 0..64 {
                    let x = lo + (hi - lo) * Vec3::new(unit(), unit(), unit());
                    let moved = (patch.value(x) - at_centre).abs();
                    assert!(
                        moved <= reach * (1.0 + 1e-4) + 1e-5,
                        "box {lo}..{hi}: the term moves {moved} at {x}, reach {reach}"
                    );
                }
            }
        }
        assert!(
            by_hull > 20 && by_slope > 20,
            "{by_hull} by the hull, {by_slope} by the slope"
        );
    }

    #[test]
    fn window_tables_read_as_the_coefficients_do() {
        // A lattice of scattered values, with a NaN and both infinities among them.
        let mut lattice = BSplineLattice::zeros([12, 10, 11], 0.25, Vec3::ZERO).unwrap();
        lattice.coeffs.update_each(|n, c| {
            *c = ((n * 7919) % 113) as f32 / 17.0 - 3.0;
        });
        let nan_at = lattice.index(5, 4, 6);
        lattice.coeffs.set_flat(nan_at, f32::NAN);
        let inf_at = lattice.index(3, 5, 5);
        lattice.coeffs.set_flat(inf_at, f32::INFINITY);
        let neg_at = lattice.index(7, 3, 4);
        lattice.coeffs.set_flat(neg_at, f32::NEG_INFINITY);
        let patch = Patch::identity(lattice);
        let mut tables = WindowTables::default();
        tables.build(
            &patch,
            CoefficientRange::Block {
                first: [1, 1, 2],
                last: [10, 8, 9],
                beyond: false,
            },
        );
        let bits = |r: PatchOverBox| {
            let (a, b) = r.bounds.unwrap();
            [a.to_bits(), b.to_bits(), r.slope.to_bits()]
        };
        let mut answered = 0;
        for (first, last) in [
            ([1, 1, 2], [4, 4, 5]),
            ([2, 2, 3], [6, 5, 7]),
            ([4, 3, 4], [8, 6, 8]),
            ([3, 2, 5], [3, 2, 5]),
            ([1, 1, 2], [8, 8, 9]),
            ([5, 4, 6], [6, 4, 6]),
            ([2, 1, 2], [10, 3, 3]),
        ] {
            let range = CoefficientRange::Block {
                first,
                last,
                beyond: false,
            };
            let expected = read_coefficients(&patch, range);
            match tables.read(&patch, first, last) {
                Some(read) => {
                    assert_eq!(bits(read), bits(expected), "{first:?} ..= {last:?}");
                    answered += 1;
                }
                // Longer than the longest window along x.
                None => assert!(last[0] - first[0] + 1 > WindowTables::MAX_WINDOW),
            }
        }
        assert_eq!(answered, 6);
        // On the lattice's border, or beyond the block: the coefficients answer.
        assert!(tables.read(&patch, [0, 1, 2], [3, 3, 4]).is_none());
        assert!(tables.read(&patch, [2, 2, 2], [5, 9, 4]).is_none());
        assert!(tables.read(&patch, [2, 2, 1], [5, 5, 4]).is_none());
    }

    #[test]
    fn adaptive_new_patch_layout_is_re_meshed_over_the_new_patch_alone() {
        let mut field = three_levels();
        let mut mesher = AdaptiveMesher::new(&field, &options(2)).unwrap();
        let leaves = mesher.leaf_count();
        // A level-1 patch on the far side of the clay, as a refine adds it: it holds nothing
        // yet, so the mesh stays as it was, and only its support is visited.
        let d = field
            .refine(Vec3::new(-0.7, -0.2, -0.2), Vec3::new(-0.3, 0.2, 0.2), 1)
            .unwrap();
        let report = mesher.remesh_layout(&field).unwrap();
        assert!(!report.whole && report.new_layout, "{report:?}");
        assert!(report.leaves_revisited > 0, "{report:?}");
        assert!(report.leaves_revisited * 4 < leaves, "{report:?}");
        // Beyond the new patch's support no triangle was taken out or made.
        let (slo, shi) = field.patches[d].world_support();
        let margin = Vec3::splat(SPACING);
        let made: Vec<SlotTriangle> = mesher.made_triangles().collect();
        for t in mesher.removed_triangles().iter().chain(&made) {
            assert!(
                t.centroid.cmpge(slo - margin).all() && t.centroid.cmple(shi + margin).all(),
                "{t:?} beyond the new patch's support {slo} ..= {shi}"
            );
        }
        matches_whole(&mesher, &field);
        // Its detail, with the layout changed in the same call: a dent and the patch's
        // support together.
        let mut dented = field.clone();
        let e = dented
            .refine(Vec3::new(-0.2, -0.7, -0.2), Vec3::new(0.2, -0.3, 0.2), 2)
            .unwrap();
        let (lo, hi) = dent(&mut dented, e, Vec3::new(0.0, -0.5, 0.0), 2, -0.2);
        let report = mesher.remesh_box(&dented, lo, hi).unwrap();
        assert!(!report.whole && report.new_layout, "{report:?}");
        matches_whole(&mesher, &dented);
        // A patch that goes (the level-1 patch, from the middle of the list): local too.
        dented.patches.remove(d);
        let report = mesher.remesh_layout(&dented).unwrap();
        assert!(!report.whole && report.new_layout, "{report:?}");
        matches_whole(&mesher, &dented);
        // A patch finer than every other sets a new finest cell: the whole clay.
        dented
            .refine(Vec3::new(0.4, -0.1, -0.1), Vec3::new(0.6, 0.1, 0.1), 3)
            .unwrap();
        let report = mesher.remesh_layout(&dented).unwrap();
        assert!(report.whole, "{report:?}");
        matches_whole(&mesher, &dented);
        // The same layout again: nothing to do.
        let report = mesher.remesh_layout(&dented).unwrap();
        assert_eq!(
            (report.whole, report.new_layout, report.leaves_revisited),
            (false, false, 0)
        );
        assert!(matches!(
            mesher.remesh_box(&dented, Vec3::new(0.0, f32::NAN, 0.0), hi),
            Err(AdaptiveMeshError::BadChangeBox { hi: h, .. }) if h == hi
        ));
        let field = dented;
        // A box beyond the clay changes nothing.
        let far = Vec3::splat(50.0);
        let report = mesher.remesh_box(&field, far, far + 1.0).unwrap();
        assert_eq!((report.leaves_revisited, report.polygons_made), (0, 0));
        matches_whole(&mesher, &field);
    }
}
