//! A welded, indexed triangle mesh: what export and statistics work on.

use glam::Vec3;

/// An indexed triangle mesh; triangles wind counter-clockwise seen from outside.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriMesh {
    pub positions: Vec<Vec3>,
    /// Unit outward normal per vertex.
    pub normals: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
}

impl TriMesh {
    /// Number of vertices.
    #[must_use]
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    /// Number of triangles.
    #[must_use]
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// Whether every triangle refers to existing vertices and normals match positions.
    #[must_use]
    pub fn is_well_formed(&self) -> bool {
        let n = self.positions.len();
        self.normals.len() == n
            && self
                .triangles
                .iter()
                .all(|t| t.iter().all(|&i| (i as usize) < n))
    }
}
