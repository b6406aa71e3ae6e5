//! A coarser index list for a brick mesh seen from afar: vertex clustering that keeps the
//! brick's border, so neighbouring bricks still meet without a crack.
//!
//! When a brick's triangles project to a pixel or two, a software rasterizer spends most of a
//! frame setting up triangles that cover no pixel centre. [`coarse_indices`] merges the
//! vertices of the brick's interior into clusters on a grid of `cluster_size`: every vertex of a
//! cluster is replaced by the one nearest the cluster's mean (an existing vertex, so the coarse
//! mesh reuses the brick's vertex buffer and its normals and paint), and triangles that
//! collapse are dropped. Two rules keep the result honest:
//! - **The border stays.** A vertex on the faces of the brick's bounding box keeps its place,
//!   and each neighbour's copy of it lies at the same position, so the seam between a coarse
//!   brick and a fine one (or another coarse one) is the same polyline on both sides.
//! - **Sheets stay apart.** The cluster key includes the vertex normal's dominant axis and
//!   sign, so the two sides of a wall thinner than a cluster are not merged into one sheet.
//!
//! The distance from the coarse surface to the fine one is under a cluster's diagonal.

use std::collections::HashMap;

/// Tolerance for "on the bounding box's face", relative to the box's largest extent.
const BORDER_TOLERANCE: f32 = 1.0e-5;

/// The mean length of the mesh's edges (each triangle's three edges, shared edges counted
/// twice), or `None` for a mesh without triangles.
#[must_use]
pub fn mean_edge_length(positions: &[[f32; 3]], indices: &[u32]) -> Option<f32> {
    let mut sum = 0.0f64;
    let mut count = 0usize;
    for t in indices.chunks_exact(3) {
        let p = [0, 1, 2].map(|k| glam::Vec3::from(positions[t[k] as usize]));
        for (a, b) in [(0, 1), (1, 2), (2, 0)] {
            sum += f64::from(p[a].distance(p[b]));
            count += 1;
        }
    }
    (count > 0).then(|| (sum / count as f64) as f32)
}

/// The dominant axis and sign of `n` as 0..6 (+x, −x, +y, −y, +z, −z).
fn normal_bin(n: [f32; 3]) -> u8 {
    let a = n.map(f32::abs);
    let axis = if a[0] >= a[1] && a[0] >= a[2] {
        0
    } else if a[1] >= a[2] {
        1
    } else {
        2
    };
    axis * 2 + u8::from(n[axis as usize] < 0.0)
}

/// Writes into `out` the triangles of `indices` after clustering the interior vertices on a
/// grid of `cluster_size` (see the module docs). `out` is cleared first; the triangles keep
/// their winding.
///
/// # Panics
/// If an index is out of range for `positions` or `normals` (callers pass validated chunks).
pub fn coarse_indices(
    positions: &[[f32; 3]],
    normals: &[[f32; 3]],
    indices: &[u32],
    cluster_size: f32,
    out: &mut Vec<u32>,
) {
    out.clear();
    if positions.is_empty() || cluster_size.is_nan() || cluster_size <= 0.0 {
        out.extend_from_slice(indices);
        return;
    }
    let (mut lo, mut hi) = (glam::Vec3::splat(f32::MAX), glam::Vec3::splat(f32::MIN));
    for &p in positions {
        lo = lo.min(p.into());
        hi = hi.max(p.into());
    }
    let tolerance = BORDER_TOLERANCE * (hi - lo).max_element().max(f32::MIN_POSITIVE);
    let on_border =
        |p: glam::Vec3| (p - lo).min_element() <= tolerance || (hi - p).min_element() <= tolerance;

    // Pass 1: each interior vertex's cluster, and each cluster's mean.
    let mut slot_of: HashMap<(i32, i32, i32, u8), u32> = HashMap::new();
    let mut sums: Vec<(glam::Vec3, u32)> = Vec::new();
    let mut cluster = vec![u32::MAX; positions.len()];
    for (i, (&p, &n)) in positions.iter().zip(normals).enumerate() {
        let p = glam::Vec3::from(p);
        if on_border(p) {
            continue;
        }
        let cell = ((p - lo) / cluster_size).floor();
        let key = (cell.x as i32, cell.y as i32, cell.z as i32, normal_bin(n));
        let next = sums.len() as u32;
        let slot = *slot_of.entry(key).or_insert(next);
        if slot == next {
            sums.push((glam::Vec3::ZERO, 0));
        }
        sums[slot as usize].0 += p;
        sums[slot as usize].1 += 1;
        cluster[i] = slot;
    }
    // Pass 2: each cluster's representative, the member nearest its mean.
    let mut best = vec![(u32::MAX, f32::MAX); sums.len()];
    for (i, &slot) in cluster.iter().enumerate() {
        if slot == u32::MAX {
            continue;
        }
        let (sum, count) = sums[slot as usize];
        let d = glam::Vec3::from(positions[i]).distance_squared(sum / count as f32);
        if d < best[slot as usize].1 {
            best[slot as usize] = (i as u32, d);
        }
    }
    let remap = |v: u32| match cluster[v as usize] {
        u32::MAX => v,
        slot => best[slot as usize].0,
    };
    for t in indices.chunks_exact(3) {
        let (a, b, c) = (remap(t[0]), remap(t[1]), remap(t[2]));
        if a != b && b != c && c != a {
            out.extend_from_slice(&[a, b, c]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;
    use std::collections::HashSet;

    /// A sphere of radius `r` cut to the box `[lo, hi]`, as a latitude–longitude grid of
    /// `n` × `2n` quads, counter-clockwise from outside; the parts outside the box are clipped
    /// by dropping triangles, so the box's faces cut through it like a brick's.
    fn sphere(r: f32, n: u32) -> (Vec<[f32; 3]>, Vec<[f32; 3]>, Vec<u32>) {
        let (mut positions, mut normals, mut indices) = (Vec::new(), Vec::new(), Vec::new());
        for i in 0..=n {
            let theta = std::f32::consts::PI * i as f32 / n as f32;
            for j in 0..=2 * n {
                let phi = std::f32::consts::PI * j as f32 / n as f32;
                let d = Vec3::new(
                    theta.sin() * phi.cos(),
                    theta.cos(),
                    theta.sin() * phi.sin(),
                );
                positions.push((d * r).to_array());
                normals.push(d.to_array());
            }
        }
        let row = 2 * n + 1;
        for i in 0..n {
            for j in 0..2 * n {
                let (a, b, c, d) = (
                    i * row + j,
                    i * row + j + 1,
                    (i + 1) * row + j,
                    (i + 1) * row + j + 1,
                );
                indices.extend_from_slice(&[a, b, d, a, d, c]);
            }
        }
        (positions, normals, indices)
    }

    /// Distance from `p` to the sphere of radius `r` at the origin.
    fn off_sphere(p: [f32; 3], r: f32) -> f32 {
        (Vec3::from(p).length() - r).abs()
    }

    #[test]
    fn a_fine_sphere_loses_most_triangles_and_stays_within_a_cluster_of_itself() {
        let (positions, normals, indices) = sphere(1.0, 96);
        let edge = mean_edge_length(&positions, &indices).unwrap();
        let mut out = Vec::new();
        coarse_indices(&positions, &normals, &indices, 2.0 * edge, &mut out);
        let (fine, coarse) = (indices.len() / 3, out.len() / 3);
        assert!(coarse * 3 <= fine, "{fine} triangles became {coarse}");
        assert!(coarse * 20 >= fine, "{fine} triangles became only {coarse}");
        // Every kept vertex is a fine vertex, so on the sphere; a triangle's centroid may cut
        // the chord of a cluster: under a cluster's diagonal from the surface.
        let limit = 2.0 * edge * 3f32.sqrt();
        for t in out.chunks_exact(3) {
            let c = t
                .iter()
                .map(|&v| Vec3::from(positions[v as usize]))
                .sum::<Vec3>()
                / 3.0;
            assert!(
                off_sphere(c.to_array(), 1.0) < limit,
                "a centroid {} off",
                off_sphere(c.to_array(), 1.0)
            );
        }
    }

    #[test]
    fn every_vertex_on_the_bounding_box_keeps_its_place_and_its_border_edges() {
        // A patch of a plane z = 0 over [0, 1]², a brick's slice: the four sides are the border.
        let n = 40u32;
        let mut positions = Vec::new();
        for i in 0..=n {
            for j in 0..=n {
                // A gentle bump so the interior is not flat.
                let (x, y) = (i as f32 / n as f32, j as f32 / n as f32);
                let z = 0.05 * (std::f32::consts::PI * x).sin() * (std::f32::consts::PI * y).sin();
                positions.push([x, y, z]);
            }
        }
        let normals = vec![[0.0, 0.0, 1.0]; positions.len()];
        let mut indices = Vec::new();
        for i in 0..n {
            for j in 0..n {
                let (a, b, c, d) = (
                    i * (n + 1) + j,
                    i * (n + 1) + j + 1,
                    (i + 1) * (n + 1) + j,
                    (i + 1) * (n + 1) + j + 1,
                );
                indices.extend_from_slice(&[a, c, d, a, d, b]);
            }
        }
        let mut out = Vec::new();
        coarse_indices(&positions, &normals, &indices, 3.0 / n as f32, &mut out);
        assert!(
            out.len() * 2 < indices.len(),
            "{} of {} indices",
            out.len(),
            indices.len()
        );
        // The boundary edges (one triangle each) of both meshes: the same set.
        let boundary = |tris: &[u32]| {
            let mut count: HashMap<(u32, u32), u32> = HashMap::new();
            for t in tris.chunks_exact(3) {
                for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
                    *count.entry((a.min(b), a.max(b))).or_default() += 1;
                }
            }
            count
                .into_iter()
                .filter(|&(_, c)| c == 1)
                .map(|(e, _)| e)
                .collect::<HashSet<_>>()
        };
        assert_eq!(boundary(&out), boundary(&indices));
    }

    #[test]
    fn the_two_sides_of_a_thin_wall_are_not_merged() {
        // Two parallel sheets 0.01 apart with opposite normals, clustered at 0.1.
        let n = 20u32;
        let (mut positions, mut normals, mut indices) = (Vec::new(), Vec::new(), Vec::new());
        for (side, z, nz) in [(0u32, 0.0f32, -1.0f32), (1, 0.01, 1.0)] {
            let base = side * (n + 1) * (n + 1);
            for i in 0..=n {
                for j in 0..=n {
                    positions.push([i as f32 / n as f32, j as f32 / n as f32, z]);
                    normals.push([0.0, 0.0, nz]);
                }
            }
            for i in 0..n {
                for j in 0..n {
                    let (a, b, c, d) = (
                        base + i * (n + 1) + j,
                        base + i * (n + 1) + j + 1,
                        base + (i + 1) * (n + 1) + j,
                        base + (i + 1) * (n + 1) + j + 1,
                    );
                    indices.extend_from_slice(&[a, c, d, a, d, b]);
                }
            }
        }
        let mut out = Vec::new();
        coarse_indices(&positions, &normals, &indices, 0.1, &mut out);
        assert!(!out.is_empty());
        for t in out.chunks_exact(3) {
            let z: Vec<f32> = t.iter().map(|&v| positions[v as usize][2]).collect();
            assert!(
                z.iter().all(|&v| v == z[0]),
                "a triangle joins both sheets: {z:?}"
            );
        }
    }

    #[test]
    fn no_cluster_size_or_no_vertices_keeps_the_triangles() {
        let (positions, normals, indices) = sphere(1.0, 8);
        let mut out = vec![7];
        coarse_indices(&positions, &normals, &indices, 0.0, &mut out);
        assert_eq!(out, indices);
        coarse_indices(&[], &[], &[], 1.0, &mut out);
        assert!(out.is_empty());
        assert_eq!(mean_edge_length(&positions, &[]), None);
    }
}
