//! Making a closed, consistently oriented mesh a 2-manifold by cutting it where sheets touch.
//!
//! Dual contouring keeps one vertex per leaf, so where two sheets of the surface pass through
//! one leaf (an ambiguous face: a saddle, two fingers of clay closer than a cell, a flat face
//! lying on the sample lattice) their polygons share that vertex, and the edge between two
//! such leaves carries four triangles instead of two. The mesh is still closed and oriented,
//! but a slicer or a mesh library that needs a 2-manifold refuses it.
//!
//! [`split_non_manifold`] cuts such places apart without moving anything: each edge with
//! more than two triangles has its triangles paired sheet by sheet (two triangles belong to
//! one sheet when a walk around one end of the edge, over ordinary edges, leads from one to
//! the other), and every vertex whose triangles then fall into several separate fans gets one
//! copy per fan. The sheets stay where they were, touching along the cut; positions, normals
//! and winding are kept, so area and enclosed volume do not change.

use super::trimesh::TriMesh;

/// What [`split_non_manifold`] changed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ManifoldRepair {
    /// Edges that carried more than two triangles and were paired sheet by sheet.
    pub edges_cut: usize,
    /// Vertex copies added (one per extra fan around a vertex).
    pub vertices_added: usize,
    /// Edges with more than two triangles whose sheets could not be told apart (paired by
    /// angle around the edge instead).
    pub edges_paired_by_angle: usize,
}

/// Corner `k` of triangle `t` is `3 t + k`.
fn corner(t: usize, k: usize) -> usize {
    3 * t + k
}

/// Union–find over the triangles' corners: two corners at one vertex are in one set when
/// their triangles are joined, around that vertex, by a chain of paired edges.
struct Fans {
    parent: Vec<u32>,
}

impl Fans {
    fn new(corners: usize) -> Self {
        Self {
            parent: (0..corners as u32).collect(),
        }
    }

    fn root(&mut self, mut c: usize) -> usize {
        while self.parent[c] as usize != c {
            let up = self.parent[c] as usize;
            self.parent[c] = self.parent[up];
            c = up;
        }
        c
    }

    fn join(&mut self, a: usize, b: usize) {
        let (ra, rb) = (self.root(a), self.root(b));
        if ra != rb {
            self.parent[ra.max(rb)] = ra.min(rb) as u32;
        }
    }
}

/// One use of an undirected edge: the triangle, and the corners at the edge's low and high
/// vertex.
#[derive(Clone, Copy, Debug)]
struct EdgeUse {
    triangle: usize,
    at_low: usize,
    at_high: usize,
    /// Whether the triangle runs the edge from its low vertex to its high one.
    forward: bool,
}

/// Joins the two uses of an edge: their corners at each end are one fan.
fn pair(fans: &mut Fans, a: EdgeUse, b: EdgeUse) {
    fans.join(a.at_low, b.at_low);
    fans.join(a.at_high, b.at_high);
}

/// Cuts `mesh` into a 2-manifold where more than two triangles share an edge or where
/// separate fans of triangles share a vertex, by pairing and copying vertices; nothing moves.
///
/// Expects a closed, consistently oriented mesh (what the meshers make); edges used once or
/// twice in the same direction are left as they are.
pub fn split_non_manifold(mesh: &mut TriMesh) -> ManifoldRepair {
    let mut repair = ManifoldRepair::default();
    let triangles = mesh.triangles.len();
    // Every edge use, keyed by its undirected edge; sorted so that one edge's uses are
    // neighbours.
    let mut uses: Vec<(u64, EdgeUse)> = Vec::with_capacity(triangles * 3);
    for (t, tri) in mesh.triangles.iter().enumerate() {
        for k in 0..3 {
            let (u, v) = (tri[k], tri[(k + 1) % 3]);
            let (ku, kv) = (corner(t, k), corner(t, (k + 1) % 3));
            let (lo, hi, at_low, at_high, forward) = if u < v {
                (u, v, ku, kv, true)
            } else {
                (v, u, kv, ku, false)
            };
            let key = (u64::from(lo) << 32) | u64::from(hi);
            let edge_use = EdgeUse {
                triangle: t,
                at_low,
                at_high,
                forward,
            };
            uses.push((key, edge_use));
        }
    }
    uses.sort_unstable_by_key(|(key, u)| (*key, u.triangle));

    let mut fans = Fans::new(triangles * 3);
    // Ordinary edges first: they define the fans that tell the sheets apart.
    let mut crowded: Vec<std::ops::Range<usize>> = Vec::new();
    let mut i = 0;
    while i < uses.len() {
        let mut j = i + 1;
        while j < uses.len() && uses[j].0 == uses[i].0 {
            j += 1;
        }
        match j - i {
            2 if uses[i].1.forward != uses[i + 1].1.forward => {
                pair(&mut fans, uses[i].1, uses[i + 1].1);
            }
            n if n > 2 => crowded.push(i..j),
            _ => {}
        }
        i = j;
    }
    repair.edges_cut = crowded.len();

    // A crowded edge's uses are paired by the fan each reaches around one of the edge's
    // ends without crossing it: the two uses of one sheet meet there. Pairing one crowded
    // edge can join the fans another needs, so repeat while anything is paired.
    let mut left = crowded;
    loop {
        let before = left.len();
        left.retain(|range| !pair_by_fans(&mut fans, &uses[range.clone()]));
        if left.is_empty() || left.len() == before {
            break;
        }
    }
    for range in &left {
        pair_by_angle(&mut fans, mesh, &uses[range.clone()]);
    }
    repair.edges_paired_by_angle = left.len();

    // Each vertex keeps its index for its first fan; every further fan gets a copy.
    let vertices = mesh.positions.len();
    let mut copy_of_root: Vec<u32> = vec![u32::MAX; triangles * 3];
    let mut first_root: Vec<u32> = vec![u32::MAX; vertices];
    for t in 0..triangles {
        for k in 0..3 {
            let c = corner(t, k);
            let v = mesh.triangles[t][k] as usize;
            let root = fans.root(c);
            if first_root[v] == u32::MAX {
                first_root[v] = root as u32;
            }
            if first_root[v] as usize == root {
                continue;
            }
            if copy_of_root[root] == u32::MAX {
                copy_of_root[root] = mesh.positions.len() as u32;
                mesh.positions.push(mesh.positions[v]);
                mesh.normals.push(mesh.normals[v]);
                repair.vertices_added += 1;
            }
            mesh.triangles[t][k] = copy_of_root[root];
        }
    }
    repair
}

/// Pairs the uses of one crowded edge by the fans around its low end, or else its high end;
/// `false` (nothing joined) when neither end splits them into opposite-running pairs.
fn pair_by_fans(fans: &mut Fans, uses: &[(u64, EdgeUse)]) -> bool {
    for at_low in [true, false] {
        let end = |u: &EdgeUse| if at_low { u.at_low } else { u.at_high };
        let mut pairs: Vec<(EdgeUse, EdgeUse)> = Vec::with_capacity(uses.len() / 2);
        let mut taken = vec![false; uses.len()];
        let mut clean = true;
        for a in 0..uses.len() {
            if taken[a] {
                continue;
            }
            let ra = fans.root(end(&uses[a].1));
            let partners: Vec<usize> = (a + 1..uses.len())
                .filter(|&b| !taken[b] && fans.root(end(&uses[b].1)) == ra)
                .collect();
            match partners.as_slice() {
                [b] if uses[*b].1.forward != uses[a].1.forward => {
                    taken[a] = true;
                    taken[*b] = true;
                    pairs.push((uses[a].1, uses[*b].1));
                }
                _ => {
                    clean = false;
                    break;
                }
            }
        }
        if clean {
            for (a, b) in pairs {
                pair(fans, a, b);
            }
            return true;
        }
    }
    false
}

/// Pairs the uses of one crowded edge by their angle around it: each triangle with the
/// next one, counter-clockwise, that runs the edge the other way, starting where the space
/// between the two is inside the solid.
fn pair_by_angle(fans: &mut Fans, mesh: &TriMesh, uses: &[(u64, EdgeUse)]) {
    let tri = |u: &EdgeUse| mesh.triangles[u.triangle];
    let first = tri(&uses[0].1);
    let low_vertex = first[uses[0].1.at_low % 3] as usize;
    let high_vertex = first[uses[0].1.at_high % 3] as usize;
    let (p0, p1) = (mesh.positions[low_vertex], mesh.positions[high_vertex]);
    let axis = (p1 - p0).normalize_or_zero();
    let reference = axis.any_orthonormal_vector();
    let binormal = axis.cross(reference);
    // Angle of each triangle's third vertex around the axis, and whether the space just
    // past it (counter-clockwise about the axis) is outside.
    let mut around: Vec<(f32, bool, EdgeUse)> = uses
        .iter()
        .map(|&(_, u)| {
            let t = tri(&u);
            let third = (0..3)
                .map(|k| t[k] as usize)
                .find(|&v| v != low_vertex && v != high_vertex)
                .unwrap_or(low_vertex);
            let w = mesh.positions[third] - p0;
            let radial = w - axis * w.dot(axis);
            let angle = radial.dot(binormal).atan2(radial.dot(reference));
            let [a, b, c] = t.map(|i| mesh.positions[i as usize]);
            let outward = (b - a).cross(c - a);
            let turning = axis.cross(radial);
            (angle, outward.dot(turning) > 0.0, u)
        })
        .collect();
    around.sort_by(|a, b| a.0.total_cmp(&b.0));
    let n = around.len();
    let start = (0..n).find(|&i| !around[i].1).unwrap_or(0);
    let mut k = 0;
    while k + 1 < n {
        let (a, b) = (around[(start + k) % n].2, around[(start + k + 1) % n].2);
        if a.forward != b.forward {
            pair(fans, a, b);
        }
        k += 2;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::MeshStats;
    use glam::Vec3;

    /// A mesh of `positions` (normals +y) and closed tetrahedra on the given corner ids,
    /// each wound outward (the fourth corner lies on the side the first three turn
    /// counter-clockwise toward).
    fn tetrahedra(positions: Vec<Vec3>, solids: &[[u32; 4]]) -> TriMesh {
        let normals = vec![Vec3::Y; positions.len()];
        let triangles = solids
            .iter()
            .flat_map(|&[a, b, c, d]| [[a, c, b], [a, b, d], [a, d, c], [b, c, d]])
            .collect();
        TriMesh {
            positions,
            normals,
            triangles,
        }
    }

    /// Two tetrahedra on opposite sides of a shared edge (vertices 0 and 1): that edge has
    /// four triangles.
    fn two_tetrahedra_on_one_edge() -> TriMesh {
        let positions = vec![
            Vec3::ZERO,
            Vec3::X,
            Vec3::new(0.3, 1.0, 0.2),
            Vec3::new(0.5, 0.4, 1.0),
            Vec3::new(0.4, -1.0, -0.1),
            Vec3::new(0.6, -0.5, -1.0),
        ];
        tetrahedra(positions, &[[0, 1, 2, 3], [0, 1, 4, 5]])
    }

    #[test]
    fn an_edge_of_four_triangles_is_cut_into_two_sheets() {
        let mut mesh = two_tetrahedra_on_one_edge();
        let before = MeshStats::of(&mesh);
        assert_eq!(before.non_manifold_edges, 1);
        let repair = split_non_manifold(&mut mesh);
        let after = MeshStats::of(&mesh);
        assert!(after.is_closed_manifold(), "{after:?}");
        assert_eq!(
            repair,
            ManifoldRepair {
                edges_cut: 1,
                vertices_added: 2,
                edges_paired_by_angle: 0
            }
        );
        // Two spheres: Euler characteristic 4; nothing moved.
        assert_eq!(after.euler_characteristic, 4);
        assert!((after.volume - before.volume).abs() < 1e-12);
        assert!((after.area - before.area).abs() < 1e-12);
        assert!(mesh.is_well_formed());
    }

    #[test]
    fn two_solids_touching_at_a_vertex_get_a_vertex_each() {
        let positions = vec![
            Vec3::ZERO,
            Vec3::X,
            Vec3::Y,
            Vec3::Z,
            -Vec3::X,
            -Vec3::Z,
            -Vec3::Y,
        ];
        let mut mesh = tetrahedra(positions, &[[0, 1, 2, 3], [0, 4, 5, 6]]);
        let before = MeshStats::of(&mesh);
        assert_eq!(before.non_manifold_edges, 0);
        let repair = split_non_manifold(&mut mesh);
        assert_eq!(repair.vertices_added, 1);
        assert_eq!(repair.edges_cut, 0);
        let after = MeshStats::of(&mesh);
        assert!(after.is_closed_manifold());
        assert_eq!(after.euler_characteristic, 4);
    }

    #[test]
    fn a_manifold_mesh_is_left_exactly_as_it_was() {
        let mut mesh = tetrahedra(vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z], &[[0, 1, 2, 3]]);
        let kept = mesh.clone();
        assert_eq!(split_non_manifold(&mut mesh), ManifoldRepair::default());
        assert_eq!(mesh, kept);
    }

    #[test]
    fn sheets_that_no_fan_tells_apart_are_paired_by_angle() {
        // The fallback on its own, with no fan joined: each triangle at the crowded edge is
        // paired with the other triangle of its own solid, the one across the solid's inside.
        let mesh = two_tetrahedra_on_one_edge();
        let uses: Vec<(u64, EdgeUse)> = mesh
            .triangles
            .iter()
            .enumerate()
            .flat_map(|(t, tri)| {
                (0..3).filter_map(move |k| {
                    let (u, v) = (tri[k], tri[(k + 1) % 3]);
                    let (lo, hi) = (u.min(v), u.max(v));
                    ((lo, hi) == (0, 1)).then(|| {
                        let (ku, kv) = (corner(t, k), corner(t, (k + 1) % 3));
                        let (at_low, at_high) = if u < v { (ku, kv) } else { (kv, ku) };
                        (
                            1_u64,
                            EdgeUse {
                                triangle: t,
                                at_low,
                                at_high,
                                forward: u < v,
                            },
                        )
                    })
                })
            })
            .collect();
        assert_eq!(uses.len(), 4);
        let mut fans = Fans::new(mesh.triangles.len() * 3);
        pair_by_angle(&mut fans, &mesh, &uses);
        // Each triangle's corner at the edge's low end is joined to exactly one other, of its
        // own tetrahedron (triangles 0..4 and 4..8).
        for &(_, u) in &uses {
            let partners: Vec<usize> = uses
                .iter()
                .filter(|(_, w)| w.triangle != u.triangle)
                .filter(|(_, w)| fans.root(w.at_low) == fans.root(u.at_low))
                .map(|(_, w)| w.triangle)
                .collect();
            assert_eq!(partners.len(), 1, "{partners:?}");
            assert_eq!(partners[0] / 4, u.triangle / 4);
        }
    }
}
