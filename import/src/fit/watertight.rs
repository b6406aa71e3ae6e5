//! Is a triangle mesh closed? Import fits a closed mesh from its signed distance
//! ([`super::sdf`]) and an open one as a point cloud ([`super::mesh`]); this module decides.
//!
//! 1. **Weld.** Vertices closer than [`WELD_TOLERANCE`] times the mesh's bounding-box diagonal
//!    are merged (an STL repeats each corner per triangle; exporters round differently), and
//!    triangles that collapse to an edge or a point after welding are dropped.
//! 2. **Edges.** Every undirected edge must be used by exactly two triangles. An edge used
//!    once is a *boundary* edge (a hole), more than twice a *non-manifold* one; either makes the
//!    mesh open.
//! 3. **Orientation.** On a closed, consistently wound mesh each edge is used once in each
//!    direction. Faces wound the other way (a common export fault) are repaired: a breadth-first
//!    walk over each connected piece flips a face whenever it disagrees with the neighbour it
//!    was reached from, and the piece keeps the winding most of its faces had. A piece that
//!    cannot be oriented (a Möbius-like strip closed on itself, which no solid bounds) makes the
//!    mesh open. The repaired faces are counted in [`MeshCheck::reoriented`].
//!
//! Which way the whole mesh faces (outward or inward normals) is not decided here: the signed
//! distance flips it when the enclosed volume comes out negative.

use std::collections::{HashMap, VecDeque};

use glam::Vec3;

/// Vertices closer than this fraction of the bounding-box diagonal are one vertex.
pub const WELD_TOLERANCE: f32 = 1e-6;

/// A mesh after welding: shared vertices, triangles indexing them.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct WeldedMesh {
    /// The welded vertices, file units.
    pub positions: Vec<Vec3>,
    /// Triangles; after [`check_closed`] on a closed mesh, consistently wound.
    pub triangles: Vec<[u32; 3]>,
}

/// What [`check_closed`] found.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MeshCheck {
    /// Vertices before and after welding.
    pub vertices_read: usize,
    /// See [`MeshCheck::vertices_read`].
    pub vertices_welded: usize,
    /// Triangles dropped because welding collapsed them.
    pub collapsed: usize,
    /// Undirected edges.
    pub edges: usize,
    /// Edges used by one triangle only.
    pub boundary_edges: usize,
    /// Edges used by three triangles or more.
    pub non_manifold_edges: usize,
    /// Two-triangle edges both triangles use in the same direction (before repair).
    pub misoriented_edges: usize,
    /// Faces whose winding was flipped to agree with their neighbours.
    pub reoriented: usize,
    /// Whether every piece could be consistently oriented.
    pub orientable: bool,
}

impl MeshCheck {
    /// Whether the mesh is closed: every edge shared by exactly two triangles, and the faces
    /// consistently wound (after repair).
    #[must_use]
    pub fn is_closed(&self) -> bool {
        self.edges > 0
            && self.boundary_edges == 0
            && self.non_manifold_edges == 0
            && self.orientable
    }

    /// One line for the import's log: closed or why not.
    #[must_use]
    pub fn describe(&self) -> String {
        let welded = format!(
            "{} vertices welded to {}, {} edges",
            self.vertices_read, self.vertices_welded, self.edges
        );
        if self.is_closed() {
            let repaired = if self.reoriented > 0 {
                format!(
                    "; {} faces wound against their neighbours were flipped",
                    self.reoriented
                )
            } else {
                String::new()
            };
            format!("the mesh is closed ({welded}, each shared by two triangles{repaired})")
        } else {
            let mut why = Vec::new();
            if self.edges == 0 {
                why.push("no triangles".to_owned());
            }
            if self.boundary_edges > 0 {
                why.push(format!(
                    "{} boundary edges (used by one triangle)",
                    self.boundary_edges
                ));
            }
            if self.non_manifold_edges > 0 {
                why.push(format!(
                    "{} non-manifold edges (used by three or more)",
                    self.non_manifold_edges
                ));
            }
            if !self.orientable && self.boundary_edges == 0 && self.non_manifold_edges == 0 {
                why.push("its faces cannot be wound consistently".to_owned());
            }
            format!("the mesh is open ({welded}; {})", why.join(", "))
        }
    }
}

/// Merges vertices within [`WELD_TOLERANCE`] of the diagonal and drops collapsed triangles
/// (their count is returned with the mesh).
#[must_use]
pub fn weld(vertices: &[Vec3], triangles: &[[u32; 3]]) -> (WeldedMesh, usize) {
    let (lo, hi) = vertices
        .iter()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(a, b), &p| {
            (a.min(p), b.max(p))
        });
    let diagonal = if vertices.is_empty() {
        0.0
    } else {
        (hi - lo).length()
    };
    let tolerance = (WELD_TOLERANCE * diagonal).max(f32::MIN_POSITIVE);
    // Cells as large as the tolerance: a vertex's match lies in its cell or a neighbour.
    let cell_of = |p: Vec3| ((p - lo) / tolerance).floor().as_i64vec3();
    let mut cells: HashMap<glam::I64Vec3, Vec<u32>> = HashMap::new();
    let mut positions: Vec<Vec3> = Vec::new();
    let mut remap = Vec::with_capacity(vertices.len());
    for &p in vertices {
        let c = cell_of(p);
        let mut found = None;
        'search: for dz in -1..=1 {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    if let Some(list) = cells.get(&(c + glam::I64Vec3::new(dx, dy, dz)))
                        && let Some(&w) = list
                            .iter()
                            .find(|&&w| positions[w as usize].distance(p) <= tolerance)
                    {
                        found = Some(w);
                        break 'search;
                    }
                }
            }
        }
        let w = found.unwrap_or_else(|| {
            let w = positions.len() as u32;
            positions.push(p);
            cells.entry(c).or_default().push(w);
            w
        });
        remap.push(w);
    }
    let mut kept = Vec::with_capacity(triangles.len());
    for t in triangles {
        let [a, b, c] = t.map(|i| remap[i as usize]);
        if a != b && b != c && c != a {
            kept.push([a, b, c]);
        }
    }
    let collapsed = triangles.len() - kept.len();
    (
        WeldedMesh {
            positions,
            triangles: kept,
        },
        collapsed,
    )
}

/// Welds `vertices`/`triangles` and checks that the result is closed, repairing the winding
/// of faces that disagree with their neighbours (see the module's notes).
#[must_use]
pub fn check_closed(vertices: &[Vec3], triangles: &[[u32; 3]]) -> (WeldedMesh, MeshCheck) {
    let (mut mesh, collapsed) = weld(vertices, triangles);
    // Per undirected edge (low, high): the triangles using it and whether each goes low→high.
    let mut uses: HashMap<(u32, u32), Vec<(u32, bool)>> = HashMap::new();
    for (n, t) in mesh.triangles.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            uses.entry((a.min(b), a.max(b)))
                .or_default()
                .push((n as u32, a < b));
        }
    }
    let mut check = MeshCheck {
        vertices_read: vertices.len(),
        vertices_welded: mesh.positions.len(),
        collapsed,
        edges: uses.len(),
        orientable: true,
        ..MeshCheck::default()
    };
    for list in uses.values() {
        match list.len() {
            1 => check.boundary_edges += 1,
            2 if list[0].1 == list[1].1 => check.misoriented_edges += 1,
            2 => {}
            _ => check.non_manifold_edges += 1,
        }
    }
    if check.boundary_edges > 0 || check.non_manifold_edges > 0 || check.edges == 0 {
        check.orientable = check.misoriented_edges == 0;
        return (mesh, check);
    }
    if check.misoriented_edges > 0 {
        match reorient(&mesh.triangles, &uses) {
            Some(flip) => {
                for (t, &f) in mesh.triangles.iter_mut().zip(&flip) {
                    if f {
                        t.swap(1, 2);
                        check.reoriented += 1;
                    }
                }
            }
            None => check.orientable = false,
        }
    }
    (mesh, check)
}

/// Which faces to flip so every two-triangle edge is used once each way, or `None` when a
/// piece cannot be oriented. Each piece keeps the winding of the majority of its faces.
fn reorient(
    triangles: &[[u32; 3]],
    uses: &HashMap<(u32, u32), Vec<(u32, bool)>>,
) -> Option<Vec<bool>> {
    let n = triangles.len();
    let mut flip = vec![false; n];
    let mut seen = vec![false; n];
    let mut queue = VecDeque::new();
    let mut piece = Vec::new();
    for seed in 0..n {
        if seen[seed] {
            continue;
        }
        seen[seed] = true;
        queue.push_back(seed as u32);
        piece.clear();
        while let Some(t) = queue.pop_front() {
            piece.push(t);
            let tri = triangles[t as usize];
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                let list = &uses[&(a.min(b), a.max(b))];
                let forward_t = (a < b) ^ flip[t as usize];
                for &(m, forward_m) in list {
                    if m == t {
                        continue;
                    }
                    // The neighbour must run the edge the other way.
                    let want = !forward_t ^ forward_m;
                    if seen[m as usize] {
                        if flip[m as usize] != want {
                            return None;
                        }
                    } else {
                        seen[m as usize] = true;
                        flip[m as usize] = want;
                        queue.push_back(m);
                    }
                }
            }
        }
        let flipped = piece.iter().filter(|&&t| flip[t as usize]).count();
        if 2 * flipped > piece.len() {
            for &t in &piece {
                flip[t as usize] = !flip[t as usize];
            }
        }
    }
    Some(flip)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit cube, twelve triangles wound outward, with every corner repeated per triangle
    /// (as an STL stores it).
    fn cube_soup() -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let (corners, triangles) = crate::fit::test_boxes::box_mesh(Vec3::ZERO, Vec3::ONE);
        let (mut v, mut t) = (Vec::new(), Vec::new());
        for tri in triangles {
            let base = v.len() as u32;
            v.extend(tri.map(|i| corners[i as usize]));
            t.push([base, base + 1, base + 2]);
        }
        (v, t)
    }

    #[test]
    fn a_triangle_soup_cube_welds_closed() {
        let (v, t) = cube_soup();
        let (mesh, check) = check_closed(&v, &t);
        assert_eq!(mesh.positions.len(), 8);
        assert_eq!(check.edges, 18);
        assert!(check.is_closed(), "{}", check.describe());
        assert_eq!(check.reoriented, 0);
        assert!(check.describe().contains("closed"), "{}", check.describe());
    }

    #[test]
    fn a_missing_face_leaves_three_boundary_edges() {
        let (v, mut t) = cube_soup();
        t.pop();
        let (_, check) = check_closed(&v, &t);
        assert!(!check.is_closed());
        assert_eq!(check.boundary_edges, 3);
        assert!(
            check.describe().contains("3 boundary edges"),
            "{}",
            check.describe()
        );
    }

    #[test]
    fn faces_wound_against_their_neighbours_are_flipped_back() {
        let (v, mut t) = cube_soup();
        for k in [1, 4, 7] {
            t[k].swap(0, 1);
        }
        let (mesh, check) = check_closed(&v, &t);
        assert!(check.is_closed(), "{}", check.describe());
        assert!(check.misoriented_edges > 0);
        assert_eq!(check.reoriented, 3);
        // Every edge is now used once each way.
        let mut directed = std::collections::HashSet::new();
        for tri in &mesh.triangles {
            for k in 0..3 {
                assert!(directed.insert((tri[k], tri[(k + 1) % 3])));
            }
        }
    }

    #[test]
    fn a_fin_is_non_manifold_and_near_vertices_weld() {
        let (mut v, mut t) = cube_soup();
        // A fin on the edge from (0,0,0) to (1,0,0), its corners off by a hair.
        let base = v.len() as u32;
        v.extend([
            Vec3::new(1e-8, 0.0, 0.0),
            Vec3::new(1.0, 1e-8, 0.0),
            Vec3::new(0.5, -1.0, -1.0),
        ]);
        t.push([base, base + 1, base + 2]);
        let (mesh, check) = check_closed(&v, &t);
        assert_eq!(mesh.positions.len(), 9);
        assert_eq!(check.non_manifold_edges, 1);
        assert_eq!(check.boundary_edges, 2);
        assert!(!check.is_closed());
    }
}
