//! A box mesh and a rounded box's point cloud for the fitting modules' tests.

use glam::Vec3;

use super::points::PointCloud;

/// The axis-aligned box from `lo` to `hi`: its 8 corners (corner `i` takes `hi` on axis `a`
/// where bit `a` of `i` is set) and 12 triangles wound outward; the first two are the face at
/// `z = lo.z`.
pub(crate) fn box_mesh(lo: Vec3, hi: Vec3) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let corners = (0..8)
        .map(|i| {
            Vec3::new(
                if i & 1 == 0 { lo.x } else { hi.x },
                if i & 2 == 0 { lo.y } else { hi.y },
                if i & 4 == 0 { lo.z } else { hi.z },
            )
        })
        .collect();
    let quads: [[u32; 4]; 6] = [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    let triangles = quads
        .iter()
        .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
        .collect();
    (corners, triangles)
}

/// The signed distance from `p` to the box of half extents `half` centred on the origin with
/// its edges and corners rounded by `round` (negative inside).
pub(crate) fn rounded_box_distance(p: Vec3, half: Vec3, round: f32) -> f32 {
    let q = p.abs() - (half - Vec3::splat(round));
    q.max(Vec3::ZERO).length() + q.max_element().min(0.0) - round
}

/// `count` points on the rounded box of [`rounded_box_distance`], without normals: random
/// points of the box grown by a fifth, each projected onto the surface along the distance's
/// gradient (so the faces' strips beside an edge are sampled more sparsely than the rounding).
pub(crate) fn rounded_box(count: usize, half: Vec3, round: f32) -> PointCloud {
    let sdf = |p: Vec3| rounded_box_distance(p, half, round);
    let mut seed = 0x2545_f491_u32;
    let mut unit = || {
        seed ^= seed << 13;
        seed ^= seed >> 17;
        seed ^= seed << 5;
        seed as f32 / u32::MAX as f32 * 2.0 - 1.0
    };
    let mut points = Vec::with_capacity(count);
    while points.len() < count {
        let mut p = Vec3::new(unit(), unit(), unit()) * half * 1.2;
        for _ in 0..4 {
            let h = 1e-3;
            let g = Vec3::new(
                sdf(p + Vec3::X * h) - sdf(p - Vec3::X * h),
                sdf(p + Vec3::Y * h) - sdf(p - Vec3::Y * h),
                sdf(p + Vec3::Z * h) - sdf(p - Vec3::Z * h),
            )
            .normalize_or_zero();
            p -= g * sdf(p);
        }
        if sdf(p).abs() < 1e-4 {
            points.push(p);
        }
    }
    PointCloud {
        points,
        normals: None,
    }
}
