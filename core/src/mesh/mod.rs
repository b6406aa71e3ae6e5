//! Surface extraction: a sparse brick octree over the sampled field, marching cubes per
//! brick with shared edge vertices, dirty-box re-meshing, mesh statistics and export.
//!
//! Guarantees: the mesh of a field that is outside on the grid's boundary is closed,
//! edge-manifold and consistently oriented (triangles counter-clockwise seen from outside,
//! normals `−∇s/|∇s|` from the analytic gradient); a local refresh gives exactly the bricks a
//! full rebuild gives; memory grows with the surface's area. Not real-time: it allocates and
//! belongs on the graphics thread.
//!
//! How the rest of the engine uses it:
//! - Engine: [`SampleGrid::for_lattice`] (cell = spacing / k), then [`BrickOctree::build`];
//!   after applying each region snapshot to its lattice copy,
//!   [`BrickOctree::coefficient_change_box`] on the snapshot's dirty coefficient range and
//!   [`BrickOctree::refresh_lattice`] with that box.
//! - Renderer: per-brick buffers from [`Brick::mesh`]; upload the bricks named in
//!   [`RefreshReport::changed`] (or [`BrickOctree::changed_since`] its last generation) and
//!   drop those in [`RefreshReport::removed`].
//! - Export: [`BrickOctree::weld`] (or [`weld_pieces`] over copies of brick meshes, as the
//!   app's published chunks are) to a [`TriMesh`], then [`write_mesh`]; [`MeshStats::of`]
//!   for counts, area, volume and topology. A caller that re-extracts often keeps the tree
//!   (a [`BrickOctree::rebuild`] refills the stored bricks' buffers) and welds with
//!   [`BrickOctree::weld_into`] into a kept mesh.
//! - Multi-resolution export: [`mesh_adaptive`] dual-contours a
//!   [`crate::field::MultiPatchField`] on an octree whose cells follow the finest patch over
//!   each region, crack-free across levels ([`adaptive_cell_count`] checks a budget first);
//!   an [`AdaptiveMesher`] keeps that mesh and, after a stroke, meshes again only the leaves
//!   near the change ([`AdaptiveMesher::remesh_box`]).
//! - Multi-resolution drawing: [`AdaptiveBricks`] keeps that mesh cut into a
//!   [`BrickOctree`]'s bricks (each triangle in the brick that holds its centroid), so the
//!   graphics loop hands a clay with detail patches to its sink brick by brick, each level at
//!   its own spacing, and a stroke changes only the bricks near it.

mod adaptive;
mod adaptive_bricks;
mod brick;
mod distance;
mod error;
mod export;
mod grid;
mod manifold;
mod octree;
mod sink;
mod source;
mod stats;
mod tables;
mod trimesh;
mod weld;
mod work_split;

pub use adaptive::{
    AdaptiveMeshError, AdaptiveMeshOptions, AdaptiveMesher, AdaptiveRemeshReport,
    MAX_ADAPTIVE_DEPTH, SlotTriangle, adaptive_cell_count, mesh_adaptive,
};
pub use adaptive_bricks::AdaptiveBricks;
pub use brick::{
    BRICK_CELLS, BRICK_SAMPLE_COUNT, BRICK_SAMPLES, BrickMesh, BrickScratch, SHARED_VERTEX_AXIS,
    brick_extent, edge_from_id, edge_id, march_brick, sample_brick, shared_vertex_id,
};
pub use distance::{Hausdorff, hausdorff, point_triangle_distance};
pub use error::GridError;
pub use export::{ExportError, MeshFormat, encode_obj, encode_ply, encode_stl, write_mesh};
pub use grid::SampleGrid;
pub use manifold::{ManifoldRepair, split_non_manifold};
pub use octree::{Brick, BrickOctree, MemoryUsage, RefreshReport, WeldPiece, weld_pieces};
pub use sink::MeshSink;
pub use source::{FnField, MAX_BLOCK, ScalarField};
pub use stats::MeshStats;
pub use tables::{
    CASES, CORNER_OFFSETS, CaseTriangles, EDGE_AXIS, EDGE_CORNERS, MAX_CASE_TRIANGLES,
};
pub use trimesh::TriMesh;
pub use weld::WeldScratch;
