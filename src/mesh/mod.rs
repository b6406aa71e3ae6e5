//! Surface extraction: a sparse brick octree over the sampled field, marching cubes per
//! brick with shared edge vertices, dirty-box re-meshing, mesh statistics and export.

mod brick;
mod error;
mod grid;
mod source;
mod tables;

pub use brick::{
    BRICK_CELLS, BRICK_SAMPLE_COUNT, BRICK_SAMPLES, BrickMesh, BrickScratch, brick_extent,
    edge_from_id, edge_id, march_brick, sample_brick,
};
pub use error::GridError;
pub use grid::SampleGrid;
pub use source::{FnField, MAX_BLOCK, ScalarField};
pub use tables::{
    CASES, CORNER_OFFSETS, CaseTriangles, EDGE_AXIS, EDGE_CORNERS, MAX_CASE_TRIANGLES,
};
