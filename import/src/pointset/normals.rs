//! Normals of a point cloud (Guo & Qin §3, after Hoppe et al. 1992): each point's normal is the
//! normal of its neighbours' least-squares plane (the covariance's smallest eigenvector), and
//! the signs are made consistent by walking a minimal spanning tree of the `k`-nearest-
//! neighbour graph whose edge cost is `1 − |n_i · n_j|`, so the walk crosses flat regions
//! first and sharp ones last.
//!
//! Choice: each connected part of the graph is rooted at its highest point (largest `z`),
//! whose normal is turned to `+z`: on a closed surface the highest point's outward normal
//! points up, so the whole part comes out facing outward.

use glam::{Mat3, Vec3};

/// The unit normal of the least-squares plane through `points` (unsigned), or `None` for
/// fewer than three points or a degenerate spread.
#[must_use]
pub fn plane_normal(points: impl Iterator<Item = Vec3> + Clone) -> Option<Vec3> {
    let (mut sum, mut n) = (Vec3::ZERO, 0usize);
    for p in points.clone() {
        sum += p;
        n += 1;
    }
    if n < 3 {
        return None;
    }
    let mean = sum / n as f32;
    let mut c = [0.0f32; 6];
    for p in points {
        let d = p - mean;
        c[0] += d.x * d.x;
        c[1] += d.x * d.y;
        c[2] += d.x * d.z;
        c[3] += d.y * d.y;
        c[4] += d.y * d.z;
        c[5] += d.z * d.z;
    }
    let m = Mat3::from_cols(
        Vec3::new(c[0], c[1], c[2]),
        Vec3::new(c[1], c[3], c[4]),
        Vec3::new(c[2], c[4], c[5]),
    );
    smallest_eigenvector(m)
}

/// The eigenvector of the smallest eigenvalue of a symmetric positive semi-definite 3×3
/// matrix: inverse iteration on `m − λ_min I` shifted slightly, seeded by the cross product
/// of the two largest rows. `None` when `m` is zero or not finite.
fn smallest_eigenvector(m: Mat3) -> Option<Vec3> {
    let trace = m.x_axis.x + m.y_axis.y + m.z_axis.z;
    if !(trace.is_finite() && trace > 0.0) {
        return None;
    }
    // Closed-form eigenvalues of a symmetric 3×3 (trigonometric method).
    let (a, b, c) = (m.x_axis.x, m.y_axis.y, m.z_axis.z);
    let (d, e, f) = (m.y_axis.x, m.z_axis.x, m.z_axis.y);
    let p1 = d * d + e * e + f * f;
    let q = trace / 3.0;
    let p2 = (a - q).powi(2) + (b - q).powi(2) + (c - q).powi(2) + 2.0 * p1;
    let p = (p2 / 6.0).sqrt();
    let lambda = if p <= f32::EPSILON * trace {
        q
    } else {
        let bm = (m - Mat3::from_diagonal(Vec3::splat(q))) * (1.0 / p);
        let r = (bm.determinant() / 2.0).clamp(-1.0, 1.0);
        let phi = r.acos() / 3.0;
        q + 2.0 * p * (phi + 2.0 * std::f32::consts::PI / 3.0).cos()
    };
    // The null vector of m − λI: the largest cross product of two of its rows.
    let s = m - Mat3::from_diagonal(Vec3::splat(lambda));
    let (r0, r1, r2) = (s.row(0), s.row(1), s.row(2));
    let candidates = [r0.cross(r1), r0.cross(r2), r1.cross(r2)];
    let best = candidates
        .into_iter()
        .max_by(|x, y| x.length_squared().total_cmp(&y.length_squared()))?;
    if best.length_squared() > (1e-12 * trace * trace).powi(2) {
        return Some(best.normalize());
    }
    // Degenerate (two small eigenvalues, a line of points): any vector orthogonal to the
    // largest row.
    let big = [r0, r1, r2]
        .into_iter()
        .max_by(|x, y| x.length_squared().total_cmp(&y.length_squared()))?;
    (big.length_squared() > 0.0).then(|| big.normalize().any_orthonormal_vector())
}

/// A binary min-heap of vertices keyed by their cheapest edge into the tree, on flat arrays
/// with decrease-key (Prim's algorithm in its eager form): each vertex sits in the heap at
/// most once, so the heap never holds more than the tree's frontier.
struct FrontierHeap {
    /// Vertices, heap-ordered by `key`.
    heap: Vec<u32>,
    /// Each vertex's place in `heap`, or `u32::MAX` when it is not there.
    place: Vec<u32>,
    /// Each vertex's cheapest known edge cost into the tree.
    key: Vec<f32>,
}

impl FrontierHeap {
    fn new(n: usize) -> Self {
        Self {
            heap: Vec::with_capacity(n.min(1 << 16)),
            place: vec![u32::MAX; n],
            key: vec![f32::INFINITY; n],
        }
    }

    /// Lowers `v`'s key to `cost` (inserting it if absent); `false` when `cost` is no lower.
    fn offer(&mut self, v: u32, cost: f32) -> bool {
        if cost >= self.key[v as usize] {
            return false;
        }
        self.key[v as usize] = cost;
        let at = match self.place[v as usize] {
            u32::MAX => {
                self.heap.push(v);
                self.heap.len() - 1
            }
            p => p as usize,
        };
        self.sift_up(at);
        true
    }

    fn pop(&mut self) -> Option<u32> {
        let top = *self.heap.first()?;
        let last = self.heap.pop()?;
        self.place[top as usize] = u32::MAX;
        if !self.heap.is_empty() {
            self.heap[0] = last;
            self.place[last as usize] = 0;
            self.sift_down(0);
        }
        Some(top)
    }

    fn sift_up(&mut self, mut at: usize) {
        let v = self.heap[at];
        let kv = self.key[v as usize];
        while at > 0 {
            let up = (at - 1) / 2;
            let u = self.heap[up];
            if self.key[u as usize] <= kv {
                break;
            }
            self.heap[at] = u;
            self.place[u as usize] = at as u32;
            at = up;
        }
        self.heap[at] = v;
        self.place[v as usize] = at as u32;
    }

    fn sift_down(&mut self, mut at: usize) {
        let v = self.heap[at];
        let kv = self.key[v as usize];
        let len = self.heap.len();
        loop {
            let left = 2 * at + 1;
            if left >= len {
                break;
            }
            let right = left + 1;
            let child = if right < len
                && self.key[self.heap[right] as usize] < self.key[self.heap[left] as usize]
            {
                right
            } else {
                left
            };
            let c = self.heap[child];
            if self.key[c as usize] >= kv {
                break;
            }
            self.heap[at] = c;
            self.place[c as usize] = at as u32;
            at = child;
        }
        self.heap[at] = v;
        self.place[v as usize] = at as u32;
    }
}

/// Flips normals in place so neighbours agree, by Prim's minimal spanning tree over the
/// neighbour lists (`k` indices per point, flat: point `i`'s are `neighbours[i k .. (i + 1) k]`;
/// they need not be symmetric, each is used both ways). Each connected part is rooted at its
/// highest point, turned to face `+z`. The frontier is an indexed binary heap with
/// decrease-key, so each point enters it once rather than once per edge.
///
/// # Panics
/// When `neighbours` is not `k` entries per point or names a point that does not exist.
pub fn orient_over_mst(points: &[Vec3], normals: &mut [Vec3], neighbours: &[u32], k: usize) {
    let n = points.len();
    assert_eq!(neighbours.len(), n * k, "k neighbours per point");
    // Symmetric adjacency in one flat array (CSR): each list plus its reverse.
    let mut start = vec![0u32; n + 1];
    for (i, list) in neighbours.chunks(k.max(1)).enumerate() {
        start[i + 1] += list.len() as u32;
        for &j in list {
            start[j as usize + 1] += 1;
        }
    }
    for i in 0..n {
        start[i + 1] += start[i];
    }
    let mut fill = start.clone();
    let mut adj = vec![0u32; start[n] as usize];
    for (i, list) in neighbours.chunks(k.max(1)).enumerate() {
        for &j in list {
            adj[fill[i] as usize] = j;
            fill[i] += 1;
            adj[fill[j as usize] as usize] = i as u32;
            fill[j as usize] += 1;
        }
    }
    drop(fill);
    // The root of each part: the highest point not yet reached.
    let mut order: Vec<u32> = (0..n as u32).collect();
    order.sort_unstable_by(|&a, &b| points[b as usize].z.total_cmp(&points[a as usize].z));
    let mut done = vec![false; n];
    let mut from = vec![u32::MAX; n];
    let mut frontier = FrontierHeap::new(n);
    for &root in &order {
        if done[root as usize] {
            continue;
        }
        if normals[root as usize].z < 0.0 {
            normals[root as usize] = -normals[root as usize];
        }
        let mut next = Some(root);
        while let Some(v) = next {
            let vi = v as usize;
            done[vi] = true;
            let f = from[vi];
            if f != u32::MAX && normals[vi].dot(normals[f as usize]) < 0.0 {
                normals[vi] = -normals[vi];
            }
            let nv = normals[vi];
            for &to in &adj[start[vi] as usize..start[vi + 1] as usize] {
                if !done[to as usize] {
                    let cost = 1.0 - nv.dot(normals[to as usize]).abs();
                    if frontier.offer(to, cost) {
                        from[to as usize] = v;
                    }
                }
            }
            next = frontier.pop();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plane_normal_of_a_tilted_patch() {
        let n = Vec3::new(0.2, -0.5, 1.0).normalize();
        let t = n.any_orthonormal_vector();
        let b = n.cross(t);
        let pts: Vec<Vec3> = (0..25)
            .map(|i| (i % 5) as f32 * t + (i / 5) as f32 * 0.7 * b)
            .collect();
        let got = plane_normal(pts.iter().copied()).unwrap();
        assert!(got.dot(n).abs() > 0.9999, "{got}");
    }

    #[test]
    fn mst_turns_a_sphere_outward() {
        // A Fibonacci sphere with random signs.
        let count = 400;
        let mut points = Vec::new();
        let mut normals = Vec::new();
        for i in 0..count {
            let z = 1.0 - 2.0 * (i as f32 + 0.5) / count as f32;
            let r = (1.0 - z * z).sqrt();
            let a = i as f32 * 2.399_963;
            let p = Vec3::new(r * a.cos(), r * a.sin(), z);
            points.push(p);
            normals.push(if i % 3 == 0 { -p } else { p });
        }
        let neighbours: Vec<u32> = points
            .iter()
            .flat_map(|p| {
                let mut idx: Vec<u32> = (0..count as u32).collect();
                idx.sort_by(|&a, &b| {
                    (points[a as usize] - *p)
                        .length_squared()
                        .total_cmp(&(points[b as usize] - *p).length_squared())
                });
                idx[1..9].to_vec()
            })
            .collect();
        orient_over_mst(&points, &mut normals, &neighbours, 8);
        assert!(points.iter().zip(&normals).all(|(p, n)| p.dot(*n) > 0.0));
    }
}
