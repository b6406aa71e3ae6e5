//! The meshes the graphics loop publishes: one [`ChunkMesh`] per octree brick, shared by
//! `Arc`, so a publication copies pointers and unchanged bricks are never copied.
//!
//! The renderer reads a chunk's data only when its version changed ([`crate::render`]), so the
//! app hands it every chunk every frame.

use std::sync::Arc;

use crate::mesh::BrickMesh;
use crate::render::MeshChunk;

/// One brick's mesh, owned.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ChunkMesh {
    /// Stable brick identity (see [`brick_id`]).
    pub id: u64,
    /// Changes whenever the mesh does (the octree generation of its last rebuild).
    pub version: u64,
    pub positions: Vec<[f32; 3]>,
    pub normals: Vec<[f32; 3]>,
    /// Paint per vertex, linear RGBA with coverage in alpha; empty when unpainted.
    pub colors: Vec<[f32; 4]>,
    pub indices: Vec<u32>,
}

/// The full set of chunks on screen.
pub type MeshSet = Vec<Arc<ChunkMesh>>;

/// A brick coordinate packed into a stable id: 21 bits per axis.
#[must_use]
pub fn brick_id(coord: [u32; 3]) -> u64 {
    let m = (1u64 << 21) - 1;
    (u64::from(coord[0]) & m)
        | ((u64::from(coord[1]) & m) << 21)
        | ((u64::from(coord[2]) & m) << 42)
}

impl ChunkMesh {
    /// Copies a brick's mesh (from [`crate::mesh::BrickOctree`]) for publication; `colors`
    /// is the per-vertex paint, or empty.
    #[must_use]
    pub fn from_brick(
        coord: [u32; 3],
        version: u64,
        mesh: &BrickMesh,
        colors: Vec<[f32; 4]>,
    ) -> Self {
        Self {
            id: brick_id(coord),
            version,
            positions: mesh.positions.iter().map(|p| p.to_array()).collect(),
            normals: mesh.normals.iter().map(|n| n.to_array()).collect(),
            colors,
            indices: mesh.indices.clone(),
        }
    }

    /// A borrowed view for [`crate::render::SceneRenderer::sync_chunks`].
    #[must_use]
    pub fn as_chunk(&self) -> MeshChunk<'_> {
        MeshChunk {
            id: self.id,
            version: self.version,
            positions: &self.positions,
            normals: &self.normals,
            colors: &self.colors,
            indices: &self.indices,
        }
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;

    #[test]
    fn brick_ids_are_distinct_per_axis() {
        let ids = [[1, 0, 0], [0, 1, 0], [0, 0, 1], [0, 0, 0], [5, 9, 1]].map(brick_id);
        for (i, a) in ids.iter().enumerate() {
            for b in &ids[i + 1..] {
                assert_ne!(a, b);
            }
        }
    }

    #[test]
    fn a_brick_mesh_becomes_a_valid_chunk() {
        let mesh = BrickMesh {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y],
            normals: vec![Vec3::Z; 3],
            edge_ids: vec![0, 1, 2],
            indices: vec![0, 1, 2],
        };
        let c = ChunkMesh::from_brick([2, 3, 4], 7, &mesh, Vec::new());
        let chunk = c.as_chunk();
        assert_eq!(chunk.validate(), Ok(()));
        assert_eq!((chunk.id, chunk.version), (brick_id([2, 3, 4]), 7));
        assert_eq!(chunk.positions[1], [1.0, 0.0, 0.0]);
        assert_eq!(chunk.triangle_count(), 1);
    }
}
