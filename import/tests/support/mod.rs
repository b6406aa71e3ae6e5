//! What the import's integration tests measure on a mesh (its pieces and genus, and how far
//! points lie from it), and the seeded generator they sample their clouds with. Each test
//! crate uses some of these.
#![allow(dead_code)]

use std::collections::HashMap;

use dynaclay_core::mesh::{TriMesh, point_triangle_distance};
use glam::Vec3;

/// Pieces of a mesh (connected by shared edges) and, per piece, its Euler characteristic and
/// whether every edge has two faces; largest piece first.
pub fn pieces(mesh: &TriMesh) -> Vec<(i64, bool)> {
    let n = mesh.positions.len();
    let mut parent: Vec<usize> = (0..n).collect();
    fn root(parent: &mut [usize], mut a: usize) -> usize {
        while parent[a] != a {
            parent[a] = parent[parent[a]];
            a = parent[a];
        }
        a
    }
    let mut edges: HashMap<(u32, u32), u32> = HashMap::new();
    for t in &mesh.triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            *edges.entry((a.min(b), a.max(b))).or_insert(0) += 1;
            let (ra, rb) = (root(&mut parent, a as usize), root(&mut parent, b as usize));
            parent[ra] = rb;
        }
    }
    // Per piece: vertices, edges, faces, and whether it is closed.
    let mut count: HashMap<usize, (i64, i64, i64, bool)> = HashMap::new();
    let mut used = vec![false; n];
    for t in &mesh.triangles {
        for &v in t {
            used[v as usize] = true;
        }
        count
            .entry(root(&mut parent, t[0] as usize))
            .or_insert((0, 0, 0, true))
            .2 += 1;
    }
    for (v, _) in used.iter().enumerate().filter(|(_, u)| **u) {
        count.get_mut(&root(&mut parent, v)).unwrap().0 += 1;
    }
    for (&(a, _), &uses) in &edges {
        let piece = count.get_mut(&root(&mut parent, a as usize)).unwrap();
        piece.1 += 1;
        piece.3 &= uses == 2;
    }
    let mut out: Vec<(i64, i64, bool)> = count
        .values()
        .map(|&(v, e, f, closed)| (f, v - e + f, closed))
        .collect();
    out.sort_by_key(|p| std::cmp::Reverse(p.0));
    out.into_iter()
        .map(|(_, chi, closed)| (chi, closed))
        .collect()
}

/// The `q` quantile of the distances from (up to 3000, evenly chosen) `points` to the
/// triangles of `mesh`.
pub fn quantile_distance(points: &[Vec3], mesh: &TriMesh, q: f32) -> f32 {
    let stride = points.len().div_ceil(3000).max(1);
    let mut d: Vec<f32> = points
        .iter()
        .step_by(stride)
        .map(|&p| {
            mesh.triangles
                .iter()
                .map(|t| {
                    let [a, b, c] = t.map(|i| mesh.positions[i as usize]);
                    point_triangle_distance(p, a, b, c)
                })
                .fold(f32::MAX, f32::min)
        })
        .collect();
    d.sort_by(f32::total_cmp);
    d[((d.len() - 1) as f32 * q).round() as usize]
}

/// A small seeded generator (a linear congruential step, the top 24 bits).
pub struct Uniform(pub u64);

impl Uniform {
    pub fn next(&mut self) -> f32 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (self.0 >> 40) as f32 / (1u64 << 24) as f32
    }

    /// Uniform in `lo..hi`.
    pub fn between(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.next()
    }

    /// A standard normal deviate (Box–Muller).
    pub fn normal(&mut self) -> f32 {
        let u = self.next().max(1e-7);
        let v = self.next();
        (-2.0 * u.ln()).sqrt() * (std::f32::consts::TAU * v).cos()
    }
}
