//! Surface extraction: a sparse brick octree over the sampled field, marching cubes per
//! brick with shared edge vertices, dirty-box re-meshing, mesh statistics and export.
//!
//! The engine builds a [`BrickOctree`] once ([`BrickOctree::build`]) and, after each region
//! snapshot, calls [`BrickOctree::refresh_lattice`] with the changed world box; the renderer
//! uploads the bricks in [`RefreshReport::changed`] (or [`BrickOctree::changed_since`]) and
//! drops those in [`RefreshReport::removed`]; export takes [`BrickOctree::weld`] to
//! [`write_mesh`].

mod brick;
mod error;
mod export;
mod grid;
mod octree;
mod source;
mod stats;
mod tables;
mod trimesh;

pub use brick::{
    BRICK_CELLS, BRICK_SAMPLE_COUNT, BRICK_SAMPLES, BrickMesh, BrickScratch, brick_extent,
    edge_from_id, edge_id, march_brick, sample_brick,
};
pub use error::GridError;
pub use export::{
    ExportError, MeshFormat, encode_obj, encode_ply, encode_stl, write_atomically, write_mesh,
};
pub use grid::SampleGrid;
pub use octree::{Brick, BrickOctree, MemoryUsage, RefreshReport};
pub use source::{FnField, MAX_BLOCK, ScalarField};
pub use stats::MeshStats;
pub use tables::{
    CASES, CORNER_OFFSETS, CaseTriangles, EDGE_AXIS, EDGE_CORNERS, MAX_CASE_TRIANGLES,
};
pub use trimesh::TriMesh;
