//! Mesh statistics: counts, area, enclosed volume and the topology checks that say whether a
//! mesh is a closed, consistently oriented 2-manifold.

use super::trimesh::TriMesh;

/// Measurements of a triangle mesh. Sums are accumulated in f64.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MeshStats {
    pub vertices: usize,
    pub triangles: usize,
    /// Distinct undirected edges.
    pub edges: usize,
    /// Total triangle area, in world units squared.
    pub area: f64,
    /// Signed enclosed volume (divergence theorem), in world units cubed; positive for a
    /// closed mesh whose triangles face outwards.
    pub volume: f64,
    /// Edges used by exactly one triangle (holes).
    pub boundary_edges: usize,
    /// Edges used by more than two triangles.
    pub non_manifold_edges: usize,
    /// Edges used by two triangles that traverse it in the same direction (flipped winding).
    pub misoriented_edges: usize,
    /// `V − E + F` (2 for a sphere, 0 for a torus).
    pub euler_characteristic: i64,
}

impl MeshStats {
    /// Measures `mesh`.
    #[must_use]
    pub fn of(mesh: &TriMesh) -> Self {
        let mut area = 0.0f64;
        let mut volume = 0.0f64;
        // Undirected edge key, with the low bit saying which direction this use went.
        let mut uses: Vec<u64> = Vec::with_capacity(mesh.triangles.len() * 3);
        for t in &mesh.triangles {
            let [a, b, c] = t.map(|i| mesh.positions[i as usize].as_dvec3());
            let cross = (b - a).cross(c - a);
            area += 0.5 * cross.length();
            volume += a.dot(b.cross(c)) / 6.0;
            for k in 0..3 {
                let (u, v) = (t[k], t[(k + 1) % 3]);
                let (lo, hi, forward) = if u < v { (u, v, 0) } else { (v, u, 1) };
                uses.push((u64::from(lo) << 33) | (u64::from(hi) << 1) | forward);
            }
        }
        uses.sort_unstable();
        let (mut edges, mut boundary, mut non_manifold, mut misoriented) = (0, 0, 0, 0);
        let mut i = 0;
        while i < uses.len() {
            let key = uses[i] >> 1;
            let mut j = i;
            let mut forward = 0;
            while j < uses.len() && uses[j] >> 1 == key {
                forward += (uses[j] & 1) as usize;
                j += 1;
            }
            let count = j - i;
            edges += 1;
            match count {
                1 => boundary += 1,
                2 if forward != 1 => misoriented += 1,
                2 => {}
                _ => non_manifold += 1,
            }
            i = j;
        }
        Self {
            vertices: mesh.positions.len(),
            triangles: mesh.triangles.len(),
            edges,
            area,
            volume,
            boundary_edges: boundary,
            non_manifold_edges: non_manifold,
            misoriented_edges: misoriented,
            euler_characteristic: mesh.positions.len() as i64 - edges as i64
                + mesh.triangles.len() as i64,
        }
    }

    /// No holes, no edge shared by more than two triangles, consistent winding.
    #[must_use]
    pub fn is_closed_manifold(&self) -> bool {
        self.boundary_edges == 0 && self.non_manifold_edges == 0 && self.misoriented_edges == 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn tetrahedron() -> TriMesh {
        TriMesh {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z],
            normals: vec![Vec3::ONE.normalize(); 4],
            triangles: vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
        }
    }

    #[test]
    fn tetrahedron_is_a_closed_sphere_with_known_area_and_volume() {
        let s = MeshStats::of(&tetrahedron());
        assert_eq!((s.vertices, s.edges, s.triangles), (4, 6, 4));
        assert_eq!(s.euler_characteristic, 2);
        assert!(s.is_closed_manifold());
        assert!((s.volume - 1.0 / 6.0).abs() < 1e-12);
        let expected_area = 1.5 + 3f64.sqrt() / 2.0;
        assert!((s.area - expected_area).abs() < 1e-9);
    }

    #[test]
    fn detects_holes_flips_and_fins() {
        let mut open = tetrahedron();
        open.triangles.pop();
        let s = MeshStats::of(&open);
        assert_eq!(s.boundary_edges, 3);

        let mut flipped = tetrahedron();
        flipped.triangles[3] = [1, 3, 2];
        let s = MeshStats::of(&flipped);
        assert_eq!(s.misoriented_edges, 3);
        assert!(!s.is_closed_manifold());

        let mut fin = tetrahedron();
        fin.positions.push(Vec3::NEG_Z);
        fin.normals.push(Vec3::NEG_Z);
        fin.triangles.push([0, 1, 4]);
        let s = MeshStats::of(&fin);
        assert_eq!(s.non_manifold_edges, 1);
    }
}
