//! The meshes the graphics loop publishes to the app: one [`ChunkMesh`] per octree brick,
//! shared by `Arc`, so a publication copies pointers and unchanged bricks are never copied.
//!
//! The renderer reads a chunk's data only when its version changed ([`crate::render`]), so the
//! app hands it every chunk every frame. The brick-to-chunk adapter itself lives in
//! [`crate::render::from_mesh`], shared with the `render` and `run --png` commands.

use std::sync::Arc;

pub use crate::render::{ChunkMesh, brick_id};

/// The full set of chunks on screen.
pub type MeshSet = Vec<Arc<ChunkMesh>>;
