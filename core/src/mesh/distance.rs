//! Distances between meshes: the symmetric Hausdorff distance, measured from each mesh's
//! vertices to the other mesh's triangles (exact point-to-triangle distances, found through a
//! uniform grid of triangle boxes).
//!
//! Vertex sampling measures `sup` over the vertices, not over every point of a triangle; for
//! meshes from the marching-cubes extractor the triangles are no larger than a grid cell, so
//! the difference is below the cell's size times the surfaces' angle, far under the cell.

use glam::Vec3;

use super::trimesh::TriMesh;

/// The two directed distances between meshes `a` and `b`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hausdorff {
    /// Largest distance from a vertex of `a` to the surface of `b`.
    pub a_to_b: f32,
    /// Largest distance from a vertex of `b` to the surface of `a`.
    pub b_to_a: f32,
    /// Mean distance from a vertex of `a` to `b`.
    pub mean_a_to_b: f32,
    /// Mean distance from a vertex of `b` to `a`.
    pub mean_b_to_a: f32,
}

impl Hausdorff {
    /// The symmetric distance: the larger of the two directions.
    #[must_use]
    pub fn max(&self) -> f32 {
        self.a_to_b.max(self.b_to_a)
    }
}

/// The Hausdorff distance between two meshes, both ways. `None` when either has no triangle.
#[must_use]
pub fn hausdorff(a: &TriMesh, b: &TriMesh) -> Option<Hausdorff> {
    if a.triangles.is_empty() || b.triangles.is_empty() {
        return None;
    }
    let (lo_a, hi_a) = bounds(&a.positions);
    let (lo_b, hi_b) = bounds(&b.positions);
    let (lo, hi) = (lo_a.min(lo_b), hi_a.max(hi_b));
    let to_b = TriangleGrid::new(b, lo, hi);
    let to_a = TriangleGrid::new(a, lo, hi);
    let (a_to_b, mean_a_to_b) = directed(&a.positions, &to_b);
    let (b_to_a, mean_b_to_a) = directed(&b.positions, &to_a);
    Some(Hausdorff {
        a_to_b,
        b_to_a,
        mean_a_to_b,
        mean_b_to_a,
    })
}

fn bounds(points: &[Vec3]) -> (Vec3, Vec3) {
    points.iter().fold(
        (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
        |(l, h), p| (l.min(*p), h.max(*p)),
    )
}

fn directed(points: &[Vec3], grid: &TriangleGrid<'_>) -> (f32, f32) {
    let mut worst = 0.0f32;
    let mut sum = 0.0f64;
    for &p in points {
        let d = grid.distance(p);
        worst = worst.max(d);
        sum += f64::from(d);
    }
    (worst, (sum / points.len().max(1) as f64) as f32)
}

/// Triangles bucketed by the grid cells their boxes overlap.
struct TriangleGrid<'a> {
    mesh: &'a TriMesh,
    origin: Vec3,
    cell: f32,
    dims: [i64; 3],
    /// `starts[c]..starts[c + 1]` indexes `items` for cell `c`.
    starts: Vec<u32>,
    items: Vec<u32>,
}

impl<'a> TriangleGrid<'a> {
    fn new(mesh: &'a TriMesh, lo: Vec3, hi: Vec3) -> Self {
        // About two triangles' worth of edge length per cell.
        let mut edge = 0.0f64;
        for t in &mesh.triangles {
            let [p, q, _] = t.map(|i| mesh.positions[i as usize]);
            edge += f64::from((q - p).length());
        }
        let extent = (hi - lo).max(Vec3::splat(1e-6));
        let mean_edge = (edge / mesh.triangles.len() as f64) as f32;
        // Enough cells that each holds a few triangles, at most 2²¹ of them.
        let limit = (extent.x * extent.y * extent.z / 2_097_152.0).cbrt();
        let cell = (2.0 * mean_edge).max(limit).max(1e-6);
        let dims = (extent / cell).ceil().as_ivec3().max(glam::IVec3::ONE);
        let dims = [i64::from(dims.x), i64::from(dims.y), i64::from(dims.z)];
        let total = (dims[0] * dims[1] * dims[2]) as usize;
        let mut grid = Self {
            mesh,
            origin: lo,
            cell,
            dims,
            starts: vec![0; total + 1],
            items: Vec::new(),
        };
        // Two passes: count, then fill.
        for pass in 0..2 {
            let mut fill = grid.starts.clone();
            for (ti, t) in mesh.triangles.iter().enumerate() {
                let [p, q, r] = t.map(|i| mesh.positions[i as usize]);
                let a = grid.cell_of(p.min(q).min(r));
                let b = grid.cell_of(p.max(q).max(r));
                for z in a[2]..=b[2] {
                    for y in a[1]..=b[1] {
                        for x in a[0]..=b[0] {
                            let c = grid.index([x, y, z]);
                            if pass == 0 {
                                grid.starts[c + 1] += 1;
                            } else {
                                grid.items[fill[c] as usize] = ti as u32;
                                fill[c] += 1;
                            }
                        }
                    }
                }
            }
            if pass == 0 {
                for c in 0..total {
                    grid.starts[c + 1] += grid.starts[c];
                }
                grid.items = vec![0; grid.starts[total] as usize];
            }
        }
        grid
    }

    fn cell_of(&self, p: Vec3) -> [i64; 3] {
        let c = ((p - self.origin) / self.cell).floor();
        let clamp = |v: f32, d: i64| (v as i64).clamp(0, d - 1);
        [
            clamp(c.x, self.dims[0]),
            clamp(c.y, self.dims[1]),
            clamp(c.z, self.dims[2]),
        ]
    }

    fn index(&self, c: [i64; 3]) -> usize {
        ((c[2] * self.dims[1] + c[1]) * self.dims[0] + c[0]) as usize
    }

    fn visit(&self, p: Vec3, c: [i64; 3], best: &mut f32) {
        let c = self.index(c);
        let (s, e) = (self.starts[c] as usize, self.starts[c + 1] as usize);
        for &ti in &self.items[s..e] {
            let [a, b, c] =
                self.mesh.triangles[ti as usize].map(|i| self.mesh.positions[i as usize]);
            *best = best.min(point_triangle_distance(p, a, b, c));
        }
    }

    /// Distance from `p` to the nearest triangle: cells in shells of growing Chebyshev radius
    /// around `p`'s cell, until every unvisited cell is farther than the best found. (For a
    /// point outside the grid, its cell is that of its projection onto the grid's box, and
    /// the distance to any cell is at least the projection's.)
    fn distance(&self, p: Vec3) -> f32 {
        let home = self.cell_of(p);
        let reach = self.dims.into_iter().max().unwrap_or(1);
        let mut best = f32::MAX;
        for r in 0..=reach {
            for z in (home[2] - r).max(0)..=(home[2] + r).min(self.dims[2] - 1) {
                for y in (home[1] - r).max(0)..=(home[1] + r).min(self.dims[1] - 1) {
                    if (z - home[2]).abs() == r || (y - home[1]).abs() == r {
                        let x0 = (home[0] - r).max(0);
                        let x1 = (home[0] + r).min(self.dims[0] - 1);
                        for x in x0..=x1 {
                            self.visit(p, [x, y, z], &mut best);
                        }
                    } else {
                        // Inside the shell's extent in y and z: only its two x faces.
                        if home[0] - r >= 0 {
                            self.visit(p, [home[0] - r, y, z], &mut best);
                        }
                        if r > 0 && home[0] + r < self.dims[0] {
                            self.visit(p, [home[0] + r, y, z], &mut best);
                        }
                    }
                }
            }
            // Cells beyond shell `r` are at least `r · cell` from `p`'s cell.
            if best <= r as f32 * self.cell {
                break;
            }
        }
        best
    }
}

/// Distance from `p` to the triangle `abc` (closest point by Voronoi regions).
#[must_use]
pub fn point_triangle_distance(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> f32 {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(ap);
    let d2 = ac.dot(ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return ap.length();
    }
    let bp = p - b;
    let d3 = ab.dot(bp);
    let d4 = ac.dot(bp);
    if d3 >= 0.0 && d4 <= d3 {
        return bp.length();
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return (p - (a + ab * v)).length();
    }
    let cp = p - c;
    let d5 = ab.dot(cp);
    let d6 = ac.dot(cp);
    if d6 >= 0.0 && d5 <= d6 {
        return cp.length();
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return (p - (a + ac * w)).length();
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (p - (b + (c - b) * w)).length();
    }
    let denom = va + vb + vc;
    if denom.abs() <= f32::MIN_POSITIVE {
        // Degenerate (zero-area) triangle: its edges.
        return segment(p, a, b).min(segment(p, b, c)).min(segment(p, a, c));
    }
    let v = vb / denom;
    let w = vc / denom;
    (p - (a + ab * v + ac * w)).length()
}

fn segment(p: Vec3, a: Vec3, b: Vec3) -> f32 {
    let d = b - a;
    let len2 = d.length_squared();
    let t = if len2 > 0.0 {
        ((p - a).dot(d) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (p - (a + d * t)).length()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quad(z: f32, size: f32) -> TriMesh {
        TriMesh {
            positions: vec![
                Vec3::new(0.0, 0.0, z),
                Vec3::new(size, 0.0, z),
                Vec3::new(size, size, z),
                Vec3::new(0.0, size, z),
            ],
            normals: vec![Vec3::Z; 4],
            triangles: vec![[0, 1, 2], [0, 2, 3]],
        }
    }

    #[test]
    fn point_triangle_regions() {
        let (a, b, c) = (Vec3::ZERO, Vec3::X, Vec3::Y);
        assert!((point_triangle_distance(Vec3::new(0.2, 0.2, 0.5), a, b, c) - 0.5).abs() < 1e-6);
        assert!(
            (point_triangle_distance(Vec3::new(-1.0, -1.0, 0.0), a, b, c) - 2f32.sqrt()).abs()
                < 1e-6
        );
        assert!((point_triangle_distance(Vec3::new(0.5, -2.0, 0.0), a, b, c) - 2.0).abs() < 1e-6);
        assert!(
            (point_triangle_distance(Vec3::new(1.0, 1.0, 0.0), a, b, c) - 0.5f32.sqrt()).abs()
                < 1e-6
        );
        assert!((point_triangle_distance(Vec3::new(3.0, 0.0, 0.0), a, b, c) - 2.0).abs() < 1e-6);
    }

    #[test]
    fn parallel_squares_are_their_gap_apart() {
        let h = hausdorff(&quad(0.0, 1.0), &quad(0.3, 1.0)).unwrap();
        assert!(
            (h.a_to_b - 0.3).abs() < 1e-6 && (h.b_to_a - 0.3).abs() < 1e-6,
            "{h:?}"
        );
        // A larger square: its far corner is the worst point one way only.
        let h = hausdorff(&quad(0.0, 1.0), &quad(0.0, 2.0)).unwrap();
        assert!(h.a_to_b < 1e-6, "{h:?}");
        assert!((h.b_to_a - 2f32.sqrt()).abs() < 1e-5, "{h:?}");
        assert!(hausdorff(&quad(0.0, 1.0), &TriMesh::default()).is_none());
    }
}
