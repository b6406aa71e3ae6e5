//! Judging a reconstructed mesh against the clean model it was sampled from.
//!
//! * **Distance, both ways**: points sampled area-weighted (seeded) on one mesh, each point's
//!   exact distance to the nearest triangle of the other. The nearest triangle is found with a
//!   k-d tree of triangle centroids (kiddo): the centroid nearest the point gives an upper
//!   bound `d`, and every triangle whose centroid lies within `d + R` (R the largest distance
//!   from any centroid to its corners) is tested exactly, so no nearer triangle is missed.
//! * **Topology**: the mesh is welded on exact vertex positions (triangles that collapse are
//!   dropped), split into edge-connected pieces, and each piece's genus is read from its Euler
//!   characteristic with its holes counted: `g = (2 − χ − b) / 2`, where `χ = V − E + F` and
//!   `b` is the number of boundary loops (connected sets of edges with a single triangle).
//!   Edges with three or more triangles are counted as non-manifold.

use std::collections::HashMap;
use std::num::NonZero;

use glam::Vec3;
use kiddo::{ImmutableKdTree, SquaredEuclidean};

use super::models::{AreaSampler, Mesh, Rng};

/// The closest point to `p` on triangle `abc` (Voronoi regions of the corners and edges).
#[must_use]
pub fn closest_on_triangle(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> Vec3 {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denom = 1.0 / (va + vb + vc);
    a + ab * (vb * denom) + ac * (vc * denom)
}

/// Exact nearest-triangle distances to one mesh.
pub struct TriangleIndex<'a> {
    mesh: &'a Mesh,
    tree: ImmutableKdTree<f32, 3>,
    /// Largest distance from a centroid to its triangle's corners.
    reach: f32,
}

impl<'a> TriangleIndex<'a> {
    /// `None` for a mesh without triangles.
    #[must_use]
    pub fn new(mesh: &'a Mesh) -> Option<Self> {
        if mesh.triangles.is_empty() {
            return None;
        }
        let mut reach = 0.0f32;
        let centroids: Vec<[f32; 3]> = mesh
            .triangles
            .iter()
            .map(|&t| {
                let [a, b, c] = mesh.corners(t);
                let g = (a + b + c) / 3.0;
                reach = reach.max(g.distance(a).max(g.distance(b)).max(g.distance(c)));
                g.to_array()
            })
            .collect();
        let tree = ImmutableKdTree::new_from_slice(&centroids).ok()?;
        Some(Self { mesh, tree, reach })
    }

    /// Distance from `p` to the nearest triangle.
    #[must_use]
    pub fn distance(&self, p: Vec3) -> f32 {
        self.nearest(p).map_or(f32::INFINITY, |(d, _, _)| d)
    }

    /// Distance from `p` to the nearest triangle, negative where `p` lies behind it (inside a
    /// mesh whose triangles wind counter-clockwise seen from outside): the sign of
    /// `(p − q) · n` for the nearest point `q` and that triangle's normal `n`.
    #[must_use]
    pub fn signed_distance(&self, p: Vec3) -> f32 {
        match self.nearest(p) {
            None => f32::INFINITY,
            Some((d, q, t)) => {
                let [a, b, c] = self.mesh.corners(self.mesh.triangles[t as usize]);
                if (p - q).dot((b - a).cross(c - a)) < 0.0 {
                    -d
                } else {
                    d
                }
            }
        }
    }

    /// The nearest triangle to `p`: its distance, the nearest point on it and its index.
    fn nearest(&self, p: Vec3) -> Option<(f32, Vec3, u32)> {
        let q = p.to_array();
        let closest = |i: u32| -> (f32, Vec3, u32) {
            let [a, b, c] = self.mesh.corners(self.mesh.triangles[i as usize]);
            let on = closest_on_triangle(p, a, b, c);
            (p.distance(on), on, i)
        };
        let first = self
            .tree
            .query(&q)
            .nearest_n::<SquaredEuclidean<f32>>(NonZero::<usize>::MIN)
            .execute();
        let mut best = closest(first.first()?.item);
        // A triangle nearer than `best` has its centroid within `best + reach` of `p`.
        let radius = best.0 + self.reach;
        for found in &self
            .tree
            .query(&q)
            .within::<SquaredEuclidean<f32>>(radius * radius)
            .unsorted()
            .execute()
        {
            // Its centroid is at least `reach` further than any of its points.
            if found.distance.sqrt() - self.reach < best.0 {
                let candidate = closest(found.item);
                if candidate.0 < best.0 {
                    best = candidate;
                }
            }
        }
        Some(best)
    }
}

/// Distances from `count` points sampled on `from` (seeded) to the nearest triangle of `to`.
#[must_use]
pub fn one_way_distances(from: &Mesh, to: &TriangleIndex<'_>, count: usize, seed: u64) -> Vec<f32> {
    let sampler = AreaSampler::new(from);
    if sampler.area() <= 0.0 {
        return Vec::new();
    }
    let mut rng = Rng::new(seed);
    (0..count)
        .map(|_| to.distance(sampler.sample(&mut rng).0))
        .collect()
}

/// Signed distances from `count` points sampled on `from` (seeded) to `to`'s triangles
/// (see [`TriangleIndex::signed_distance`]).
#[must_use]
pub fn one_way_signed_distances(
    from: &Mesh,
    to: &TriangleIndex<'_>,
    count: usize,
    seed: u64,
) -> Vec<f32> {
    let sampler = AreaSampler::new(from);
    if sampler.area() <= 0.0 {
        return Vec::new();
    }
    let mut rng = Rng::new(seed);
    (0..count)
        .map(|_| to.signed_distance(sampler.sample(&mut rng).0))
        .collect()
}

/// Points sampled on `from` (seeded, as [`one_way_signed_distances`]) with their signed
/// distances to `to`'s triangles.
#[must_use]
pub fn one_way_signed_samples(
    from: &Mesh,
    to: &TriangleIndex<'_>,
    count: usize,
    seed: u64,
) -> Vec<(Vec3, f32)> {
    let sampler = AreaSampler::new(from);
    if sampler.area() <= 0.0 {
        return Vec::new();
    }
    let mut rng = Rng::new(seed);
    (0..count)
        .map(|_| {
            let p = sampler.sample(&mut rng).0;
            (p, to.signed_distance(p))
        })
        .collect()
}

/// The `q`-quantile (0..=1) of `values` (sorted in place); NaN when empty.
#[must_use]
pub fn quantile(values: &mut [f32], q: f32) -> f32 {
    if values.is_empty() {
        return f32::NAN;
    }
    values.sort_by(f32::total_cmp);
    let i = ((values.len() - 1) as f32 * q).round() as usize;
    values[i]
}

/// One edge-connected piece of a welded mesh.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Piece {
    pub triangles: usize,
    /// `V − E + F`.
    pub euler: i64,
    /// Boundary loops (holes).
    pub boundary_loops: usize,
}

impl Piece {
    /// `(2 − χ − b) / 2`: the genus of the piece once its holes are capped.
    #[must_use]
    pub fn genus(&self) -> f64 {
        (2 - self.euler - self.boundary_loops as i64) as f64 / 2.0
    }
}

/// The pieces of a mesh, largest first, and its count of non-manifold edges.
#[derive(Clone, Debug)]
pub struct Topology {
    pub pieces: Vec<Piece>,
    pub non_manifold_edges: usize,
}

impl Topology {
    /// `pieces, genus of the largest (holes)`, e.g. `1, g=1 (b=0)`.
    #[must_use]
    pub fn summary(&self) -> String {
        match self.pieces.first() {
            None => "empty".to_owned(),
            Some(p) => {
                let nm = if self.non_manifold_edges > 0 {
                    format!(", {} non-manifold edges", self.non_manifold_edges)
                } else {
                    String::new()
                };
                format!(
                    "{}, g={} (b={}){nm}",
                    self.pieces.len(),
                    p.genus(),
                    p.boundary_loops
                )
            }
        }
    }
}

/// Smallest-index representative with path halving.
fn find(parent: &mut [usize], mut i: usize) -> usize {
    while parent[i] != i {
        parent[i] = parent[parent[i]];
        i = parent[i];
    }
    i
}

fn union(parent: &mut [usize], a: usize, b: usize) {
    let (ra, rb) = (find(parent, a), find(parent, b));
    if ra != rb {
        parent[ra.max(rb)] = ra.min(rb);
    }
}

/// Welds `mesh` on exact positions and counts its pieces, their Euler characteristics and
/// boundary loops (see the module docs).
#[must_use]
pub fn topology(mesh: &Mesh) -> Topology {
    // Weld on exact positions.
    let mut ids: HashMap<[u32; 3], u32> = HashMap::new();
    let remap: Vec<u32> = mesh
        .positions
        .iter()
        .map(|p| {
            let next = ids.len() as u32;
            *ids.entry(p.to_array().map(f32::to_bits)).or_insert(next)
        })
        .collect();
    let vertex_count = ids.len();
    let triangles: Vec<[u32; 3]> = mesh
        .triangles
        .iter()
        .map(|t| t.map(|i| remap[i as usize]))
        .filter(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2])
        .collect();
    // Edges with their triangle counts.
    let mut edges: HashMap<(u32, u32), u32> = HashMap::new();
    for t in &triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            *edges.entry((a.min(b), a.max(b))).or_insert(0) += 1;
        }
    }
    // Pieces: vertices joined by edges.
    let mut parent: Vec<usize> = (0..vertex_count).collect();
    for &(a, b) in edges.keys() {
        union(&mut parent, a as usize, b as usize);
    }
    let mut index_of_root: HashMap<usize, usize> = HashMap::new();
    let mut pieces: Vec<Piece> = Vec::new();
    let mut vertices_per_piece: Vec<i64> = Vec::new();
    let mut used = vec![false; vertex_count];
    for t in &triangles {
        let root = find(&mut parent, t[0] as usize);
        let piece = *index_of_root.entry(root).or_insert_with(|| {
            pieces.push(Piece {
                triangles: 0,
                euler: 0,
                boundary_loops: 0,
            });
            vertices_per_piece.push(0);
            pieces.len() - 1
        });
        pieces[piece].triangles += 1;
        pieces[piece].euler += 1;
        for &v in t {
            if !std::mem::replace(&mut used[v as usize], true) {
                vertices_per_piece[piece] += 1;
            }
        }
    }
    for (piece, v) in pieces.iter_mut().zip(&vertices_per_piece) {
        piece.euler += v;
    }
    // Edges, and boundary loops: boundary edges joined at shared vertices.
    let mut boundary_parent: Vec<usize> = (0..vertex_count).collect();
    let mut on_boundary = vec![false; vertex_count];
    let mut non_manifold_edges = 0;
    for (&(a, b), &count) in &edges {
        let piece = index_of_root[&find(&mut parent, a as usize)];
        pieces[piece].euler -= 1;
        if count == 1 {
            union(&mut boundary_parent, a as usize, b as usize);
            on_boundary[a as usize] = true;
            on_boundary[b as usize] = true;
        } else if count > 2 {
            non_manifold_edges += 1;
        }
    }
    for v in 0..vertex_count {
        if on_boundary[v] && find(&mut boundary_parent, v) == v {
            let piece = index_of_root[&find(&mut parent, v)];
            pieces[piece].boundary_loops += 1;
        }
    }
    pieces.sort_by_key(|p| std::cmp::Reverse(p.triangles));
    Topology {
        pieces,
        non_manifold_edges,
    }
}
