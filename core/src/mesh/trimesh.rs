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

    /// The triangles as their corners' position bits, each rotated to start at its least
    /// corner (so the winding is kept), sorted: equal for two meshes exactly when they hold
    /// the same triangles at the same positions, whatever their vertex order and sharing.
    #[must_use]
    pub fn canonical_triangles(&self) -> Vec<[[u32; 3]; 3]> {
        let mut set: Vec<_> = self
            .triangles
            .iter()
            .map(|t| {
                let p = t.map(|i| self.positions[i as usize].to_array().map(f32::to_bits));
                let k = (0..3).min_by_key(|&k| p[k]).unwrap_or(0);
                [p[k], p[(k + 1) % 3], p[(k + 2) % 3]]
            })
            .collect();
        set.sort_unstable();
        set
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
