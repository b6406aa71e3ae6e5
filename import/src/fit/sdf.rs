//! The signed distance of a closed triangle mesh on a regular grid, in a narrow band around
//! its surface, as a [`Volume`] the volume fit takes (inside positive, surface at 0).
//!
//! **Distance.** Each triangle visits the voxels of its bounding box grown by the band and
//! keeps, per voxel, the smallest exact point-to-triangle distance
//! ([`dynaclay_core::mesh::point_triangle_distance`], the closest point by face, edge and vertex
//! regions); a voxel whose distance to the triangle's box is already above its best skips the
//! exact test, and each row of the box is cut to the part within the band of the triangle's
//! box. Voxels beyond the band keep the band's width: the fit only reads the distance
//! on its density ramp, which the band covers, and the sign everywhere else.
//!
//! **Sign.** Rays along each of the three axes through every row of voxel centres count the
//! signed crossings of the surface (the winding number along the ray: a face whose normal
//! points against the ray enters the solid, one along it leaves); a voxel is inside when the
//! winding number is positive on at least two of the three axes. A ray through an edge or a
//! vertex is counted exactly once: each edge's side test is computed once for both of its
//! faces (from its lower-numbered welded vertex), and a ray exactly on an edge is nudged by
//! a fixed infinitesimal offset (symbolic perturbation), so neighbouring faces never both
//! claim, or both miss, a ray. Faces seen edge-on along the ray are skipped (they enclose
//! nothing). The majority of three axes guards against the rounding of crossing depths at a
//! voxel that lies on the surface. The winding needs consistently wound faces
//! ([`super::watertight`]); if the enclosed volume comes out negative (normals pointing in),
//! every sign is flipped.

use glam::{DVec2, Vec3};

use super::volume::Volume;
use super::watertight::WeldedMesh;
use dynaclay_core::mesh::point_triangle_distance;

/// The most voxels a signed-distance grid may hold (about 200 MB with its scratch).
pub const MAX_SDF_VOXELS: usize = 40 << 20;

/// Where a signed-distance grid lies and how wide its band is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SdfGrid {
    /// File position of voxel (0, 0, 0).
    pub origin: Vec3,
    /// Voxel size, file units.
    pub voxel: f32,
    /// Voxels per axis.
    pub dims: [usize; 3],
    /// Distances are exact within this many voxels of the surface and clamped beyond.
    pub band_voxels: f32,
}

/// Why a signed-distance grid could not be laid out.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum SdfGridError {
    /// The mesh's box is empty or not finite.
    #[error("the mesh's box {lo}..{hi} has no size")]
    NoSize {
        /// The box's corners.
        lo: Vec3,
        hi: Vec3,
    },
    /// The grid would hold more than [`MAX_SDF_VOXELS`] voxels.
    #[error(
        "a signed-distance grid of {}×{}×{} voxels is more than {MAX_SDF_VOXELS}",
        dims[0],
        dims[1],
        dims[2]
    )]
    TooLarge {
        /// Voxels per axis.
        dims: [usize; 3],
    },
}

impl SdfGrid {
    /// A grid over the box `lo..hi` with `across` voxels along its longest side, `band_voxels`
    /// of band, and a margin of the band plus two voxels on every side (so the band never
    /// meets the grid's edge).
    ///
    /// # Errors
    /// [`SdfGridError`] when the box is empty or not finite, or the grid would pass
    /// [`MAX_SDF_VOXELS`].
    pub fn around(
        lo: Vec3,
        hi: Vec3,
        across: usize,
        band_voxels: f32,
    ) -> Result<Self, SdfGridError> {
        let size = (hi - lo).max_element();
        if !(size.is_finite() && size > 0.0 && lo.is_finite()) {
            return Err(SdfGridError::NoSize { lo, hi });
        }
        let voxel = size / across.max(1) as f32;
        let margin = band_voxels.ceil() + 2.0;
        let origin = lo - Vec3::splat(margin * voxel);
        let cells = ((hi - lo) / voxel).ceil() + Vec3::splat(2.0 * margin + 1.0);
        let dims = [cells.x as usize, cells.y as usize, cells.z as usize];
        let total = dims
            .iter()
            .try_fold(1usize, |a, &d| a.checked_mul(d))
            .unwrap_or(usize::MAX);
        if total > MAX_SDF_VOXELS {
            return Err(SdfGridError::TooLarge { dims });
        }
        Ok(Self {
            origin,
            voxel,
            dims,
            band_voxels,
        })
    }

    /// Voxel coordinates of file point `p`.
    #[must_use]
    pub fn to_voxel(&self, p: Vec3) -> Vec3 {
        (p - self.origin) / self.voxel
    }

    fn index(&self, i: usize, j: usize, k: usize) -> usize {
        i + self.dims[0] * (j + self.dims[1] * k)
    }
}

/// A closed mesh's signed distance on a grid.
#[derive(Clone, Debug, PartialEq)]
pub struct SignedDistance {
    /// The distance in voxels, inside positive, clamped to the band.
    pub volume: Volume,
    /// Whether the faces wound inward and the sign was flipped.
    pub flipped: bool,
    /// Voxels inside the mesh.
    pub inside: usize,
}

/// The signed distance to `mesh` (closed and consistently wound) on `grid`, in voxels, inside
/// positive, clamped to the band; `stop` is polled between stages and triangles in batches
/// (answer `true` to stop, which returns `None`).
#[must_use]
pub fn signed_distance(
    mesh: &WeldedMesh,
    grid: &SdfGrid,
    stop: &mut dyn FnMut() -> bool,
) -> Option<SignedDistance> {
    let at: Vec<Vec3> = mesh.positions.iter().map(|&p| grid.to_voxel(p)).collect();
    let mut values = distances(&at, &mesh.triangles, grid, stop)?;
    let outward = enclosed_volume(&at, &mesh.triangles) >= 0.0;
    let mut votes = vec![0u8; values.len()];
    for axis in 0..3 {
        if stop() {
            return None;
        }
        vote_inside(&at, &mesh.triangles, grid, axis, outward, &mut votes);
    }
    let mut inside = 0;
    for (v, &n) in values.iter_mut().zip(&votes) {
        // The volume wants inside positive.
        if n >= 2 {
            inside += 1;
        } else {
            *v = -*v;
        }
    }
    Some(SignedDistance {
        volume: Volume {
            dims: grid.dims,
            values,
        },
        flipped: !outward,
        inside,
    })
}

/// Unsigned distance in voxels, exact within the band, the band beyond.
fn distances(
    at: &[Vec3],
    triangles: &[[u32; 3]],
    grid: &SdfGrid,
    stop: &mut dyn FnMut() -> bool,
) -> Option<Vec<f32>> {
    let band = grid.band_voxels;
    let mut best = vec![band; grid.dims[0] * grid.dims[1] * grid.dims[2]];
    let top = |d: usize| (d - 1) as f32;
    for (n, t) in triangles.iter().enumerate() {
        if n % 4096 == 0 && stop() {
            return None;
        }
        let [a, b, c] = t.map(|i| at[i as usize]);
        let (lo, hi) = (a.min(b).min(c), a.max(b).max(c));
        let from = (lo - Vec3::splat(band)).ceil().max(Vec3::ZERO);
        let to = (hi + Vec3::splat(band)).floor().min(Vec3::new(
            top(grid.dims[0]),
            top(grid.dims[1]),
            top(grid.dims[2]),
        ));
        for k in from.z as usize..=to.z as usize {
            let gap_z = (lo.z - k as f32).max(k as f32 - hi.z).max(0.0);
            for j in from.y as usize..=to.y as usize {
                // Only the part of the row within the band of the triangle's box.
                let gap_y = (lo.y - j as f32).max(j as f32 - hi.y).max(0.0);
                let reach_sq = band * band - gap_y * gap_y - gap_z * gap_z;
                if reach_sq <= 0.0 {
                    continue;
                }
                let reach = reach_sq.sqrt();
                let first = (lo.x - reach).ceil().max(from.x) as usize;
                let last = (hi.x + reach).floor().min(to.x);
                if last < first as f32 {
                    continue;
                }
                for i in first..=last as usize {
                    let p = Vec3::new(i as f32, j as f32, k as f32);
                    let slot = &mut best[grid.index(i, j, k)];
                    // The distance to the triangle's box bounds its distance from below.
                    let gap = (lo - p).max(p - hi).max(Vec3::ZERO);
                    if gap.length_squared() >= *slot * *slot {
                        continue;
                    }
                    *slot = slot.min(point_triangle_distance(p, a, b, c));
                }
            }
        }
    }
    Some(best)
}

/// The volume enclosed by the faces (positive when they wind outward).
fn enclosed_volume(at: &[Vec3], triangles: &[[u32; 3]]) -> f64 {
    triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| at[i as usize].as_dvec3());
            a.dot(b.cross(c))
        })
        .sum::<f64>()
        / 6.0
}

/// Adds one to `votes` at each voxel whose winding number along `axis` is positive.
fn vote_inside(
    at: &[Vec3],
    triangles: &[[u32; 3]],
    grid: &SdfGrid,
    axis: usize,
    outward: bool,
    votes: &mut [u8],
) {
    let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
    let (nu, nv, na) = (grid.dims[u], grid.dims[v], grid.dims[axis]);
    // (row, depth along the axis, winding step)
    let mut crossings: Vec<(u32, f32, i8)> = Vec::new();
    let flat = |p: Vec3| DVec2::new(f64::from(p[u]), f64::from(p[v]));
    for t in triangles {
        let corners = t.map(|i| flat(at[i as usize]));
        let (lo, hi) = (
            corners[0].min(corners[1]).min(corners[2]),
            corners[0].max(corners[1]).max(corners[2]),
        );
        let (j0, j1) = (lo.x.ceil().max(0.0), hi.x.floor().min((nu - 1) as f64));
        let (k0, k1) = (lo.y.ceil().max(0.0), hi.y.floor().min((nv - 1) as f64));
        if j0 > j1 || k0 > k1 {
            continue;
        }
        for k in k0 as usize..=k1 as usize {
            for j in j0 as usize..=j1 as usize {
                let p = DVec2::new(j as f64, k as f64);
                let Some((weights, sign)) = covers(t, &corners, p) else {
                    continue;
                };
                let depth = weights
                    .iter()
                    .zip(t)
                    .map(|(w, &i)| w * f64::from(at[i as usize][axis]))
                    .sum::<f64>();
                // Facing along the ray (normal · axis > 0 for an outward face) leaves the
                // solid: the winding drops.
                let step = if (sign > 0) == outward { -1 } else { 1 };
                crossings.push(((j + nu * k) as u32, depth as f32, step));
            }
        }
    }
    crossings.sort_unstable_by(|x, y| x.0.cmp(&y.0).then(x.1.total_cmp(&y.1)));
    let mut start = 0;
    while start < crossings.len() {
        let row = crossings[start].0 as usize;
        let end = start
            + crossings[start..]
                .iter()
                .position(|c| c.0 as usize != row)
                .unwrap_or(crossings.len() - start);
        let (j, k) = (row % nu, row / nu);
        let mut winding = 0i32;
        let mut next = start;
        for s in 0..na {
            while next < end && crossings[next].1 < s as f32 {
                winding += i32::from(crossings[next].2);
                next += 1;
            }
            if winding > 0 {
                let mut cell = [0usize; 3];
                cell[axis] = s;
                cell[u] = j;
                cell[v] = k;
                votes[grid.index(cell[0], cell[1], cell[2])] += 1;
            }
        }
        start = end;
    }
}

/// Whether the flattened triangle `corners` (welded indices `t`) covers point `p`, with the
/// ray-on-edge ties broken by a fixed perturbation: the barycentric weights of `p` and the
/// sign of the triangle's flattened area. `None` when it does not cover `p`, or is seen
/// edge-on.
fn covers(t: &[u32; 3], corners: &[DVec2; 3], p: DVec2) -> Option<([f64; 3], i32)> {
    let mut side = [0f64; 3];
    let mut sign = [0i32; 3];
    for e in 0..3 {
        let (a, b) = (e, (e + 1) % 3);
        // Computed from the lower-numbered vertex, so both faces of an edge agree exactly.
        let (from, to, flip) = if t[a] < t[b] {
            (a, b, 1.0)
        } else {
            (b, a, -1.0)
        };
        let (q, r) = (corners[from], corners[to]);
        let d = r - q;
        let value = d.x * (p.y - q.y) - d.y * (p.x - q.x);
        let s = if value != 0.0 {
            value.signum()
        } else if d.y != 0.0 {
            // p nudged by (ε, ε²): the sign of the edge function's change.
            -d.y.signum()
        } else if d.x != 0.0 {
            d.x.signum()
        } else {
            return None;
        };
        side[e] = flip * value;
        sign[e] = (flip * s) as i32;
    }
    if sign[0] != sign[1] || sign[1] != sign[2] {
        return None;
    }
    let total = side[0] + side[1] + side[2];
    if total == 0.0 {
        return None;
    }
    // Edge e faces the corner opposite it, (e + 2) % 3.
    let weights = [side[1] / total, side[2] / total, side[0] / total];
    Some((weights, sign[0]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::watertight::check_closed;

    /// An axis-aligned box from `lo` to `hi` as 12 triangles, wound `outward` or inward.
    fn cuboid(lo: Vec3, hi: Vec3, outward: bool) -> WeldedMesh {
        let (positions, mut triangles) = crate::fit::test_boxes::box_mesh(lo, hi);
        if !outward {
            for tri in &mut triangles {
                tri.swap(1, 2);
            }
        }
        let (mesh, check) = check_closed(&positions, &triangles);
        assert!(check.is_closed());
        mesh
    }

    #[test]
    fn a_grid_aligned_box_gets_exact_distances_and_signs_either_winding() {
        // The box's faces lie exactly on voxel centres: every ray meets edges and vertices.
        let (lo, hi) = (Vec3::splat(0.0), Vec3::new(4.0, 3.0, 2.0));
        for outward in [true, false] {
            let mesh = cuboid(lo, hi, outward);
            let grid = SdfGrid::around(lo, hi, 8, 3.0).unwrap();
            assert_eq!(grid.voxel, 0.5);
            let sdf = signed_distance(&mesh, &grid, &mut || false).unwrap();
            assert_eq!(sdf.flipped, !outward);
            let volume = sdf.volume;
            for k in 0..grid.dims[2] {
                for j in 0..grid.dims[1] {
                    for i in 0..grid.dims[0] {
                        let p = grid.origin + Vec3::new(i as f32, j as f32, k as f32) * grid.voxel;
                        // The exact signed distance to the box, outside positive, in voxels.
                        let c = 0.5 * (lo + hi);
                        let q = (p - c).abs() - 0.5 * (hi - lo);
                        let truth =
                            (q.max(Vec3::ZERO).length() + q.max_element().min(0.0)) / grid.voxel;
                        let want = -truth.clamp(-3.0, 3.0);
                        let got = volume.values[grid.index(i, j, k)];
                        assert!(
                            (got - want).abs() < 1e-4,
                            "outward {outward}: voxel {i} {j} {k}: {got} for {want}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn grids_over_the_limit_or_without_size_are_refused() {
        let e = SdfGrid::around(Vec3::ZERO, Vec3::ONE, 100_000, 4.0).unwrap_err();
        assert!(matches!(e, SdfGridError::TooLarge { .. }), "{e}");
        assert!(e.to_string().contains("more than"), "{e}");
        let e = SdfGrid::around(Vec3::ONE, Vec3::ONE, 64, 4.0).unwrap_err();
        assert!(matches!(e, SdfGridError::NoSize { .. }), "{e}");
        assert!(e.to_string().contains("no size"), "{e}");
    }
}
