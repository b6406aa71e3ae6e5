//! Which points of a cloud agree on a surface, and how noisy they are.
//!
//! Each point is compared with the plane its neighbours agree on (principal components of
//! the points within a radius of it, itself left out):
//!
//! - **Isolated** points, with far fewer neighbours than the cloud's typical point (under
//!   [`ISOLATED_FRACTION`] of the median count), are dropped: a stray return in empty space.
//!   Where the noise is well under the neighbour radius, a point with few neighbours that
//!   borders well-supported ones is not isolated but judged by the far test against both
//!   its own neighbours' plane and its nearest well-supported neighbour's: a point of a
//!   sparsely sampled area (a flat face beside a densely sampled edge) lies on them.
//! - Where the cloud is **sparsely sampled** (the side of a scan away from the scanner,
//!   an area fewer views saw), a point with too few neighbours within the radius is judged
//!   again by its [`SPARSE_NEIGHBOURS`] nearest points: kept when they lie on a plane, it
//!   lies amid them and near it, and at least [`SPARSE_GROUP`] such points are linked as
//!   each other's nearest. A stray in empty space has no such plane about it.
//! - **Far** points, whose distance to their neighbours' plane is over [`FAR_DEVIATIONS`]
//!   times the local scatter (the larger of the cloud's noise and the neighbours' own RMS
//!   distance to the plane, so that a crease or a tight curve does not count as an
//!   outlier), are dropped: a return off the consensus surface.
//!   A point well off the surface has few neighbours, those of a small cap of the surface
//!   within the radius, and a plane fitted to a cap no wider than the noise's thickness may
//!   lean anywhere, even through the point: a point with fewer neighbours than
//!   [`THIN_SUPPORT`] times what a point at the far test's limit would have is also judged
//!   against the plane of its nearest well-supported neighbour (fitted to a whole disc of
//!   the surface), and dropped when it lies over [`FAR_DEVIATIONS`] local deviations off
//!   it (where the noise is well under the radius, [`THIN_FAR_LIMIT`]).
//! - Where the cloud is **sparser than the spacing's grid** reads (see
//!   [`sparser_than_the_spacing_grid`]), the radius holds a median of a few points; it is
//!   widened for the median to hold [`SPARSE_MEDIAN_NEIGHBOURS`], and over it a point with
//!   fewer than [`LONE_NEIGHBOURS`] others within [`LONE_SPACINGS`] spacings is isolated.
//! - The **noise level** is the median of the neighbourhoods' RMS distances to their planes
//!   (a robust estimate of the per-point scatter across the surface), unless the caller
//!   gives it.
//! - Every kept point gets a **confidence** in `(0, 1]` that falls with its distance to the
//!   plane, `1 / (1 + (r / 2σ)²)` with `σ` the same local scatter, so the fit leans on the
//!   points that agree; on a clean cloud a point on a tight curve keeps its weight (its
//!   distance to the plane is the curve's, not noise).
//!
//! The neighbour radius is set by the cloud's own density (about [`NEIGHBOURS`] points
//! within it), widened to at least three noise levels so that the planes are not fitted to
//! the scatter. A dense cell of the search offers an even subset of its points (at most
//! [`CELL_OFFER`]), so the cost per point stays bounded on any cloud.

use super::disjoint_sets::DisjointSets;
use super::quadric::{QuadricHeights, median_scatter};
use glam::{DVec3, IVec3, Vec3};
use std::ops::Range;

/// The neighbours a plane is fitted to, aimed at.
pub const NEIGHBOURS: f32 = 30.0;
/// A point with fewer neighbours than this fraction of the median is isolated.
pub const ISOLATED_FRACTION: f32 = 0.15;
/// A point further from its neighbours' plane than this many local deviations is an outlier.
pub const FAR_DEVIATIONS: f32 = 3.5;
/// The smallest local scatter, as a fraction of the object's size: a few steps of `f32` at
/// the coordinates' scale, so that the rounding of a clean cloud's coordinates is not taken
/// for a deviation from the plane.
pub const PRECISION: f32 = 1e-6;
/// A point is also judged against its nearest well-supported neighbour's plane when it has
/// fewer neighbours than this fraction of those a point [`FAR_DEVIATIONS`] noise levels off a
/// flat surface would have (the median count times the share of the neighbour disc left in
/// a cap at that height, `1 − (FAR_DEVIATIONS σ / radius)²`): its own neighbours are a cap
/// too small to fix a plane. A point it finds on that plane keeps its own plane's distance.
pub const THIN_SUPPORT: f32 = 0.75;
/// Points are judged by their count of neighbours (see [`THIN_SUPPORT`]) only where the far
/// test's limit, [`FAR_DEVIATIONS`] noise levels, is at most this fraction of the radius:
/// where the noise is a larger share of it, a genuine point's count falls steeply with its
/// own scatter and tells nothing of an outlier.
pub const THIN_FAR_LIMIT: f32 = 0.5;
/// A point with few neighbours is judged by its well-supported neighbours' plane only where
/// [`FAR_DEVIATIONS`] noise levels are under this fraction of the neighbour radius (the far
/// test can tell a stray just off the surface from a point on it).
pub const RESCUE_RADII: f32 = 0.25;
/// Points a cell of the neighbour search offers, at most.
pub const CELL_OFFER: usize = 48;
/// A point left with too few neighbours within the radius is judged again by this many of
/// its nearest, found within [`SPARSE_RADII`] radii.
pub const SPARSE_NEIGHBOURS: usize = 16;
/// How far the nearest neighbours of a point with too few within the radius are looked for,
/// in neighbour radii: 16 times the area, so a surface sampled at a sixteenth of the typical
/// density still shows its [`SPARSE_NEIGHBOURS`].
pub const SPARSE_RADII: f32 = 4.0;
/// The nearest neighbours of a point with too few within the radius lie on a surface when
/// their plane's RMS distance is at most this share of the farthest one's distance (or
/// [`SPARSE_NOISE_ALLOWANCE`] noise levels): a disc of a surface reads the noise and its
/// curvature's sag, a few hundredths on a smooth surface; a ball of strays reads far more.
pub const SPARSE_FLATNESS: f32 = 0.15;
/// A point judged by its nearest neighbours where the cloud is sparse must lie among them:
/// its offset along their plane from their centroid at most this share of the farthest
/// one's distance. A point of a sparse surface lies amid its neighbours (under 0.4 of the
/// reach for 95 in 100 on a half sampled at a tenth of the density); a stray beside a
/// densely sampled surface has its nearest points in a patch to one side of it (over 0.55
/// for the peer clouds' strays that pass the other tests).
pub const SPARSE_AMID: f32 = 0.5;
/// Points judged by their nearest neighbours where the cloud is sparse are kept only in
/// groups of at least this many, linked by being among each other's nearest: a few strays
/// in thousands may pass the other tests by chance, and each kept alone is signed as a blob.
pub const SPARSE_GROUP: usize = 24;
/// See [`SPARSE_FLATNESS`]: a sparsely sampled surface's neighbours scatter by the noise
/// about their plane, which may be over [`SPARSE_FLATNESS`] of their reach in a noisy cloud.
pub const SPARSE_NOISE_ALLOWANCE: f32 = 2.0;
/// Where the cloud is sparser than [`typical_spacing`]'s grid reads and the median point has
/// fewer neighbours than this within the radius, the radius is widened for the median to hold
/// about this many and the planes fitted again (see [`isolate_lone_points`]).
///
/// NOTE: 12, not [`NEIGHBOURS`]: over 30 points of a 1 000-point cloud the radius reaches
/// across a fifth of the object, and the planes' scatter is its curvature (bench/RESULTS.md,
/// "The screening of sparse clouds over a widened radius").
pub const SPARSE_MEDIAN_NEIGHBOURS: f32 = 12.0;
/// A point of a sparse cloud screened over the widened radius is isolated with fewer than
/// [`LONE_NEIGHBOURS`] others within this many of the cloud's spacings.
pub const LONE_SPACINGS: f32 = 2.0;
/// See [`LONE_SPACINGS`].
pub const LONE_NEIGHBOURS: usize = 3;
/// Points whose neighbourhoods give the noise estimate, at most (an even subset).
const NOISE_SAMPLES: usize = 20_000;

/// The most cells a [`PointGrid`] lays out (its cells grow to stay within it).
const MAX_GRID_CELLS: usize = 1 << 21;

/// Points bucketed on a dense uniform grid over their box, for radius searches: each cell's
/// points lie together in one array (compressed rows), so a search reads 27 short slices.
pub struct PointGrid {
    origin: Vec3,
    cell: f32,
    dims: [i32; 3],
    /// Per cell, where its points start in [`PointGrid::members`] (one more entry at the end).
    starts: Vec<u32>,
    members: Vec<u32>,
    /// The members' positions, in the same order (a search reads them in sequence).
    positions: Vec<Vec3>,
}

impl PointGrid {
    /// `points` (those where `keep` holds) bucketed in cubes of side `cell` at least (larger
    /// when the box would need more than [`MAX_GRID_CELLS`]); each cell keeps an even subset
    /// of at most `offer` of its points.
    ///
    /// NOTE: each kept point's cube is found once and read by the three counting passes that
    /// follow; each pass found it again, and the grids' builds were the screening's longest
    /// stretch on one thread (bench/RESULTS.md, "Import time: the signing's serial
    /// stretches"). Found on every core, the cubes took longer on a loaded machine (a
    /// thread's start waits for a core) than they saved on an idle one.
    #[must_use]
    pub fn new(points: &[Vec3], keep: impl Fn(usize) -> bool, cell: f32, offer: usize) -> Self {
        let (lo, hi) = points
            .iter()
            .enumerate()
            .filter(|&(i, _)| keep(i))
            .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(a, b), (_, &p)| {
                (a.min(p), b.max(p))
            });
        let (lo, hi) = if lo.x.is_finite() {
            (lo, hi)
        } else {
            (Vec3::ZERO, Vec3::ZERO)
        };
        let cubes = Cubes::covering(lo, hi, cell);
        let (cell, d) = (cubes.cell, cubes.dims);
        let dims = [d.x, d.y, d.z];
        let cells = cubes.count();
        // Each point's cube, or `DROPPED` where it is not kept.
        const DROPPED: u32 = u32::MAX;
        let cube: Vec<u32> = points
            .iter()
            .enumerate()
            .map(|(i, &p)| {
                if keep(i) {
                    cubes.cube_of(p) as u32
                } else {
                    DROPPED
                }
            })
            .collect();
        let mut counts = vec![0u32; cells + 1];
        for &c in &cube {
            if c != DROPPED {
                counts[c as usize + 1] += 1;
            }
        }
        // Each cell offers at most `offer`: the points are taken with a stride.
        let strides: Vec<u32> = counts[1..]
            .iter()
            .map(|&c| (c as usize).div_ceil(offer.max(1)).max(1) as u32)
            .collect();
        let mut seen = vec![0u32; cells];
        let mut offered = vec![0u32; cells + 1];
        for &c in &cube {
            if c != DROPPED {
                let c = c as usize;
                if seen[c].is_multiple_of(strides[c]) {
                    offered[c + 1] += 1;
                }
                seen[c] += 1;
            }
        }
        for c in 0..cells {
            offered[c + 1] += offered[c];
        }
        let mut members = vec![0u32; offered[cells] as usize];
        let mut fill = offered.clone();
        seen.fill(0);
        for (i, &c) in cube.iter().enumerate() {
            if c != DROPPED {
                let c = c as usize;
                if seen[c].is_multiple_of(strides[c]) {
                    members[fill[c] as usize] = i as u32;
                    fill[c] += 1;
                }
                seen[c] += 1;
            }
        }
        let positions = members.iter().map(|&i| points[i as usize]).collect();
        Self {
            origin: lo,
            cell,
            dims,
            starts: offered,
            members,
            positions,
        }
    }

    /// Per point of the `count` it was made from: whether its cell offers it (it was kept,
    /// and its cell's stride passed it).
    #[must_use]
    pub fn offered(&self, count: usize) -> Vec<bool> {
        let mut offered = vec![false; count];
        for &i in &self.members {
            offered[i as usize] = true;
        }
        offered
    }

    /// Occupied cells.
    #[must_use]
    pub fn occupied(&self) -> usize {
        self.starts.windows(2).filter(|w| w[1] > w[0]).count()
    }

    /// Calls `visit(index, position)` for every offered point within `radius` of `x` (any
    /// radius; the search is cheapest with `radius` one or two cell sides), in the order the
    /// grid holds them.
    ///
    /// Of the cells that the box of the sphere reaches, a row of cells along x whose y–z gap
    /// from `x` is beyond `radius` is passed over, and each other row is cut to the cells the
    /// sphere's section reaches: the cells left out hold no point within `radius`, so the
    /// visits are the same as a scan of every cell, in the same order, with fewer distance
    /// tests.
    pub fn for_each_near(&self, x: Vec3, radius: f32, mut visit: impl FnMut(usize, Vec3)) {
        self.for_each_slot_near(x, radius, |_, index, position| visit(index, position));
    }

    /// The points in the order the grid holds them: per slot, the index of its point.
    #[must_use]
    pub fn members(&self) -> &[u32] {
        &self.members
    }

    /// [`PointGrid::for_each_near`], each visit also told the point's slot in
    /// [`PointGrid::members`] (`visit(slot, index, position)`): data laid out in the grid's
    /// order is read in sequence.
    #[inline]
    pub fn for_each_slot_near(
        &self,
        x: Vec3,
        radius: f32,
        mut visit: impl FnMut(usize, usize, Vec3),
    ) {
        let r2 = radius * radius;
        self.for_each_row_near(x, radius, |slots| {
            // The row's points within reach are picked without a branch per point (its
            // outcome is a coin toss at the sphere's rim), a chunk at a time, then visited
            // in order.
            for first in slots.clone().step_by(ROW_CHUNK) {
                let positions = &self.positions[first..slots.end.min(first + ROW_CHUNK)];
                let mut within = [0u8; ROW_CHUNK];
                let mut count = 0;
                for (k, &p) in positions.iter().enumerate() {
                    within[count & (ROW_CHUNK - 1)] = k as u8;
                    count += usize::from((p - x).length_squared() <= r2);
                }
                for &k in &within[..count] {
                    let at = first + usize::from(k);
                    visit(at, self.members[at] as usize, self.positions[at]);
                }
            }
        });
    }

    /// The slots (in [`PointGrid::members`]) of the rows of cells that
    /// [`PointGrid::for_each_near`] passes over for a search within `radius` of `x`, a run of
    /// slots per row cut to the cells the sphere's section reaches, in the grid's order:
    /// every offered point within `radius` of `x` is in one of them (with others beyond it).
    #[inline(always)]
    pub fn for_each_row_near(&self, x: Vec3, radius: f32, mut visit: impl FnMut(Range<usize>)) {
        let u = (x - self.origin) / self.cell;
        // The reach in cells, widened by a hair so that rounding in the cell of a point (its
        // coordinates divided by the cell side) can never leave out a point within reach.
        let reach = radius / self.cell + CELL_ROUNDING;
        let reach2 = reach * reach;
        // The gap in cells from `u` to cell `i`'s extent along one axis.
        let gap = |u: f32, i: i32| (i as f32 - u).max(u - (i + 1) as f32).max(0.0);
        let [dx_, dy_, dz_] = self.dims;
        let cells = |u: f32, d: i32| {
            (
                floor_to_i32(u - reach).max(0),
                floor_to_i32(u + reach).min(d - 1),
            )
        };
        let (z0, z1) = cells(u.z, dz_);
        let (y0, y1) = cells(u.y, dy_);
        for z in z0..=z1 {
            let gap_z = (gap(u.z, z) - CELL_ROUNDING).max(0.0);
            for y in y0..=y1 {
                let gap_y = (gap(u.y, y) - CELL_ROUNDING).max(0.0);
                let left = reach2 - gap_y * gap_y - gap_z * gap_z;
                if left < 0.0 {
                    continue;
                }
                let half_chord = left.sqrt();
                let row = dx_ * (y + dy_ * z);
                let x0 = floor_to_i32(u.x - half_chord).max(0);
                let x1 = floor_to_i32(u.x + half_chord).min(dx_ - 1);
                if x0 > x1 {
                    continue;
                }
                let from = self.starts[(row + x0) as usize] as usize;
                let to = self.starts[(row + x1 + 1) as usize] as usize;
                if from < to {
                    visit(from..to);
                }
            }
        }
    }

    /// The members' positions, in the grid's order (slot by slot).
    #[must_use]
    pub fn positions(&self) -> &[Vec3] {
        &self.positions
    }
}

/// `v` rounded down to an integer (saturating at `i32`'s range; 0 for NaN), as
/// `v.floor() as i32` gives it.
///
/// NOTE: `f32::floor` is a call into the C library on the baseline x86-64 target (no
/// SSE4.1 `roundss`), and the radius search takes five per call: about 2% of an import's
/// time in a profile of `dynaclay import` on a 50 000-point cloud; a conversion and a
/// compare are inline.
#[must_use]
#[inline]
pub(crate) fn floor_to_i32(v: f32) -> i32 {
    let toward_zero = v as i32;
    toward_zero.saturating_sub(i32::from((toward_zero as f32) > v))
}

/// `e^(−t)` for `t ≥ 0` (0 from `t` = 87 on, where `e^(−t)` leaves `f32`'s normal range),
/// within 2·10⁻⁶ of it relative up to `t` = 20 (the rounding of `z` below): `2^(−z)` with
/// `z = t log₂ e` split into the nearest integer `k` (an exponent written into the bits) and
/// a remainder `k − z` in `[−½, ½]`, whose power of two is a degree-6 polynomial (Cephes'
/// `exp2f` coefficients).
///
/// NOTE: the Gaussian weights of the moving planes take one per neighbour; the C library's
/// `expf` (a call) was about 5% of an import's time in a profile of `dynaclay import` on a
/// 50 000-point cloud.
#[must_use]
#[inline]
pub(crate) fn exp_neg(t: f32) -> f32 {
    if t.is_nan() {
        return f32::NAN;
    }
    let z = t.max(0.0) * std::f32::consts::LOG2_E;
    if z >= 125.0 {
        return 0.0;
    }
    two_to_minus(z, (z + 0.5) as i32)
}

/// `2^(−z)` for `z ≥ 0` given `k`, the integer nearest `z` (at most 125): `2^(−k)` written
/// into a normal float's exponent field, times the degree-6 polynomial for `2^(k − z)`
/// ([`exp_neg`]'s and the lanes' shared step).
#[inline(always)]
pub(crate) fn two_to_minus(z: f32, k: i32) -> f32 {
    let x = k as f32 - z;
    let power = 1.0
        + x * (6.931_472e-1
            + x * (2.402_264_8e-1
                + x * (5.550_332_5e-2
                    + x * (9.618_437e-3 + x * (1.339_887_4e-3 + x * 1.535_336_2e-4)))));
    power * f32::from_bits(((127 - k) as u32) << 23)
}

/// Points of a row of cells [`PointGrid::for_each_near`] tests before it visits those within
/// reach (a power of two, at most 256).
///
/// NOTE: testing a chunk without a branch per point and then visiting the points within
/// reach took about a third off the radius searches, whose branch on the distance was
/// mispredicted at the sphere's rim (bench/RESULTS.md, "Import wall time").
const ROW_CHUNK: usize = 64;

/// The margin, in cells, that [`PointGrid::for_each_near`] keeps when it passes over cells
/// out of reach: far above the rounding of a coordinate divided by the cell side.
const CELL_ROUNDING: f32 = 1e-3;

/// Indices a [`parallel_map`] thread takes at a time, at least.
const PARALLEL_CHUNK_LEAST: usize = 256;
/// Chunks a [`parallel_map`] splits its indices into per thread, at most: enough that a
/// thread that finishes early (its indices cheaper, or its core shared) takes others'.
const PARALLEL_CHUNKS_PER_THREAD: usize = 16;

/// `(0..count).map(f)`, split over the machine's cores: the indices in contiguous chunks,
/// each taken by the next free thread (the calling thread one of them), returned in order.
///
/// NOTE: with each thread's share fixed (one contiguous run per thread), the stages whose
/// cost is uneven along the indices (the nodes' distances: the nodes near the surface are
/// in a few runs of z-planes) waited for one thread with a core's worth of work left
/// (bench/RESULTS.md, "Import time: the work shared out").
pub(crate) fn parallel_map<T: Send>(count: usize, f: impl Fn(usize) -> T + Sync) -> Vec<T> {
    parallel_map_by(count, PARALLEL_LEAST_PER_THREAD, f)
}

/// Indices per thread, at least, that [`parallel_map`] starts a thread for: fewer calls of a
/// neighbour search's cost take less time than a thread's start.
const PARALLEL_LEAST_PER_THREAD: usize = 4096;

/// [`parallel_map`] with a thread for every `least_per_thread` indices (up to the machine's
/// cores): for calls that cost far more than a neighbour search (a quadric's fit each), of
/// which a few hundred are worth a thread. The values are `f`'s, in order, whatever the
/// thread count.
pub(crate) fn parallel_map_by<T: Send>(
    count: usize,
    least_per_thread: usize,
    f: impl Fn(usize) -> T + Sync,
) -> Vec<T> {
    let threads = std::thread::available_parallelism()
        .map_or(1, std::num::NonZeroUsize::get)
        .min(count.div_ceil(least_per_thread.max(1)).max(1));
    if threads <= 1 {
        return (0..count).map(f).collect();
    }
    let chunk = count
        .div_ceil(threads * PARALLEL_CHUNKS_PER_THREAD)
        .max(PARALLEL_CHUNK_LEAST);
    let chunks = count.div_ceil(chunk);
    // NOTE: Relaxed: the counter only hands out chunk numbers, each exactly once (`fetch_add`
    // is atomic in any ordering); the values reach the caller through the threads' joins.
    let next = std::sync::atomic::AtomicUsize::new(0);
    let take = || {
        let mut done: Vec<(usize, Vec<T>)> = Vec::new();
        loop {
            let c = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            if c >= chunks {
                return done;
            }
            done.push((
                c,
                (c * chunk..((c + 1) * chunk).min(count)).map(&f).collect(),
            ));
        }
    };
    let (take, mut taken) = (&take, Vec::with_capacity(chunks));
    std::thread::scope(|scope| {
        let handles: Vec<_> = (1..threads).map(|_| scope.spawn(take)).collect();
        taken.extend(take());
        for handle in handles {
            taken.extend(
                handle
                    .join()
                    .unwrap_or_else(|e| std::panic::resume_unwind(e)),
            );
        }
    });
    taken.sort_unstable_by_key(|&(c, _)| c);
    let mut values = Vec::with_capacity(count);
    for (_, chunk_values) in taken {
        values.extend(chunk_values);
    }
    values
}

/// `f(i)` for every `i` of `order` (a permutation of `0..order.len()`), called in that
/// order, split over the machine's cores as [`parallel_map`] splits it, and returned by
/// index: the same values as `parallel_map(order.len(), f)`, found in another order.
///
/// NOTE: a pass over a cloud in its file's order (a scan's, or a random one) visits
/// neighbourhoods all over the object, whose points are mostly out of the cache; in
/// [`spatial_order`] each neighbourhood is mostly the last one's (bench/RESULTS.md, "Import
/// time against screened Poisson's").
pub(crate) fn parallel_map_in_order<T: Send + Default>(
    order: &[u32],
    f: impl Fn(usize) -> T + Sync,
) -> Vec<T> {
    let found = parallel_map(order.len(), |k| f(order[k] as usize));
    let mut by_index: Vec<T> = std::iter::repeat_with(T::default)
        .take(order.len())
        .collect();
    for (&i, value) in order.iter().zip(found) {
        by_index[i as usize] = value;
    }
    by_index
}

/// The indices of `points` ordered by the cube of side `cell` (at least; larger where the
/// box would need more than [`MAX_GRID_CELLS`] cubes) that each lies in: cubes in z-major
/// order, points in index order within a cube.
#[must_use]
pub(crate) fn spatial_order(points: &[Vec3], cell: f32) -> Vec<u32> {
    let (lo, hi) = points
        .iter()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(a, b), &p| {
            (a.min(p), b.max(p))
        });
    if !lo.is_finite() || !hi.is_finite() {
        return (0..points.len() as u32).collect();
    }
    let cubes = Cubes::covering(lo, hi, cell);
    order_by_bucket(points, cubes.count(), |p| cubes.cube_of(p))
}

/// The indices of `points` sorted by `bucket_of` (each below `buckets`), buckets in order and
/// points in index order within a bucket (a counting sort: two passes, no comparison).
#[must_use]
pub(crate) fn order_by_bucket(
    points: &[Vec3],
    buckets: usize,
    bucket_of: impl Fn(Vec3) -> usize,
) -> Vec<u32> {
    let mut starts = vec![0u32; buckets + 1];
    for &p in points {
        starts[bucket_of(p) + 1] += 1;
    }
    for b in 1..starts.len() {
        starts[b] += starts[b - 1];
    }
    let mut order = vec![0u32; points.len()];
    for (i, &p) in points.iter().enumerate() {
        let b = bucket_of(p);
        order[starts[b] as usize] = i as u32;
        starts[b] += 1;
    }
    order
}

/// Cubes of one side over a box, in z-major order: the side at least the one asked for, and
/// larger where the box would need more than [`MAX_GRID_CELLS`] of them.
#[derive(Clone, Copy, Debug)]
struct Cubes {
    lo: Vec3,
    cell: f32,
    dims: IVec3,
}

impl Cubes {
    /// Cubes of side `cell` (at least) from `lo` over the box to `hi` (both finite).
    fn covering(lo: Vec3, hi: Vec3, cell: f32) -> Self {
        let extent = (hi - lo).max(Vec3::splat(f32::MIN_POSITIVE));
        let mut cell = cell.max(extent.max_element() * 1e-6).max(f32::MIN_POSITIVE);
        let dims_for = |cell: f32| (extent / cell).floor().as_ivec3() + IVec3::ONE;
        while dims_for(cell).as_dvec3().element_product() > MAX_GRID_CELLS as f64 {
            cell *= 1.25;
        }
        Self {
            lo,
            cell,
            dims: dims_for(cell),
        }
    }

    /// How many cubes.
    fn count(&self) -> usize {
        (self.dims.x * self.dims.y * self.dims.z) as usize
    }

    /// The cube `p` lies in (a point outside the box: the nearest cube on the border).
    #[inline]
    fn cube_of(&self, p: Vec3) -> usize {
        // `floor_to_i32` is `floor` then `as i32` (a call into the C library each on the
        // baseline target; see its NOTE).
        let u = (p - self.lo) / self.cell;
        let d = self.dims;
        let c = IVec3::new(floor_to_i32(u.x), floor_to_i32(u.y), floor_to_i32(u.z))
            .clamp(IVec3::ZERO, d - IVec3::ONE);
        (c.x + d.x * (c.y + d.y * c.z)) as usize
    }
}

/// What [`screen`] found.
#[derive(Clone, Debug)]
pub struct Consensus {
    /// Per point: kept (`> 0`, its confidence) or dropped (`0`).
    pub confidence: Vec<f32>,
    /// The noise level: per-point scatter across the surface (standard deviation), in the
    /// points' units.
    pub noise: f32,
    /// Whether [`Consensus::noise`] was given rather than estimated.
    pub noise_given: bool,
    /// Where the radius was widened for a sparse cloud and the noise is estimated: the
    /// points' scatter off quadrics (the median RMS height of sampled points' neighbours off
    /// the quadric height function fitted to them: the noise itself), in the points' units. [`Consensus::noise`], the neighbours' planes' scatter, then holds the
    /// surface's curvature over the radius too, and is what the fit smooths over.
    pub noise_off_quadrics: Option<f32>,
    /// The typical distance between neighbouring points, in the points' units.
    pub point_spacing: f32,
    /// The neighbour radius the planes were fitted over.
    pub radius: f32,
    /// Points dropped for having too few neighbours.
    pub isolated: usize,
    /// Points dropped for lying off their neighbours' plane.
    pub far: usize,
    /// Points kept that had too few neighbours within the radius, judged by their nearest
    /// neighbours' plane where the cloud is sparsely sampled (see [`SPARSE_NEIGHBOURS`]).
    pub sparse: usize,
}

impl Consensus {
    /// Points kept.
    #[must_use]
    pub fn kept(&self) -> usize {
        self.confidence.iter().filter(|&&c| c > 0.0).count()
    }
}

/// A neighbourhood's plane: centroid, unit normal, RMS distance of the points it was fitted
/// to, and how many neighbours the point had (all of them, not only the plane's inliers: a
/// point beside a crease has its full share of neighbours even where the robust pass keeps
/// only one side of the crease, and is not isolated).
struct Plane {
    centre: Vec3,
    normal: Vec3,
    rms: f32,
    neighbours: usize,
}

fn plane_of(near: &[Vec3], off: &mut Vec<f32>, inliers: &mut Vec<Vec3>) -> Option<Plane> {
    let first = principal_plane(near)?;
    // Robust second pass: refit to the neighbours within three robust deviations (the median
    // absolute distance) of the first plane, so that a few strays among the neighbours do not
    // tilt the plane or inflate its scatter.
    off.clear();
    off.extend(
        near.iter()
            .map(|&q| (q - first.centre).dot(first.normal).abs()),
    );
    if !needs_refit(off) {
        return Some(first);
    }
    let mid = off.len() / 2;
    let keep = inlier_bound(*off.select_nth_unstable_by(mid, f32::total_cmp).1);
    inliers.clear();
    inliers.extend(
        near.iter()
            .copied()
            .filter(|&q| (q - first.centre).dot(first.normal).abs() <= keep),
    );
    let refit = principal_plane(inliers).unwrap_or(first);
    Some(Plane {
        neighbours: near.len(),
        ..refit
    })
}

/// The farthest a neighbour may lie from the first plane to be kept for the refit, given the
/// median of the neighbours' distances to it: three robust deviations (`1.4826 ×` the median
/// absolute distance).
#[inline]
fn inlier_bound(median: f32) -> f32 {
    let mad = median * 1.4826;
    3.0 * mad.max(f32::MIN_POSITIVE)
}

/// Whether some of the distances `off` (to the first plane) lie beyond [`inlier_bound`] of
/// their median, so the plane is fitted again to the others; `off` is left as it was.
///
/// NOTE: decided without finding the median: [`inlier_bound`] never falls as its argument
/// grows, so the distances whose bound is under the largest distance are the smallest ones,
/// and the median's bound is under it exactly when more than `len / 2` of them (the median's
/// rank) are. The selection for every plane showed as 3–5% of an import's CPU time in
/// `perf record`, and most planes need no refit (bench/RESULTS.md, "Import time: the
/// neighbourhoods").
fn needs_refit(off: &[f32]) -> bool {
    let mid = off.len() / 2;
    if off.iter().any(|d| !d.is_finite()) {
        // The median by the total order, as the refit finds it.
        let mut sorted = off.to_vec();
        let keep = inlier_bound(*sorted.select_nth_unstable_by(mid, f32::total_cmp).1);
        return !sorted[mid..].iter().all(|&d| d <= keep);
    }
    let widest = off.iter().fold(0.0f32, |a, &d| a.max(d));
    off.iter().filter(|&&d| inlier_bound(d) < widest).count() > mid
}

/// The least-squares plane through the points `near` (at least three).
fn principal_plane(near: &[Vec3]) -> Option<Plane> {
    let count = near.len();
    if count < 3 {
        return None;
    }
    let mean = near.iter().map(|q| q.as_dvec3()).sum::<DVec3>() / count as f64;
    // The six distinct entries of the symmetric covariance (`d[a] · d[b]` is `d[b] · d[a]`
    // to the bit).
    let (mut xx, mut xy, mut xz, mut yy, mut yz, mut zz) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    for q in near {
        let d = q.as_dvec3() - mean;
        xx += d.x * d.x;
        xy += d.x * d.y;
        xz += d.x * d.z;
        yy += d.y * d.y;
        yz += d.y * d.z;
        zz += d.z * d.z;
    }
    let cov = [[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]];
    let normal = least_variance_direction(cov)
        .try_normalize()
        .unwrap_or(Vec3::Y);
    let centre = mean.as_vec3();
    let ss: f32 = near.iter().map(|&q| (q - centre).dot(normal).powi(2)).sum();
    Some(Plane {
        centre,
        normal,
        rms: (ss / count as f32).sqrt(),
        neighbours: count,
    })
}

/// The typical distance between neighbouring points of `points`, whose box's longest side is
/// `size`: the surface crosses about `area / cell²` cells of a grid of 64 cells per side, so
/// the occupied cells give the area, and the area per point the spacing.
///
/// A cloud sparser than that grid's cubes reads as one cube's side apart at most (each point
/// alone in its cube): see [`sparser_than_the_spacing_grid`].
#[must_use]
pub fn typical_spacing(points: &[Vec3], size: f32) -> f32 {
    let coarse = size / SPACING_CUBES_PER_SIDE;
    let area = occupied_cubes(points, coarse) as f32 * coarse * coarse;
    (area / points.len().max(1) as f32).sqrt()
}

/// The cubes per side of the grid [`typical_spacing`] counts the surface's cubes on.
pub const SPACING_CUBES_PER_SIDE: f32 = 64.0;

/// The fewest points per occupied cube of [`typical_spacing`]'s grid for its count to measure
/// the surface rather than the points.
///
/// NOTE: with the points at random, one per cube of the surface, about 1.6 lie in each
/// occupied cube (a third of the cubes the surface crosses hold none). The peers bench's
/// 50 000-point clouds hold about 4 (bench/RESULTS.md, "Sparse clouds, and a cloud that samples
/// no surface").
pub const LEAST_POINTS_PER_OCCUPIED_CUBE: f32 = 2.0;

/// Whether `points` (their box's longest side `size`) hold fewer than
/// [`LEAST_POINTS_PER_OCCUPIED_CUBE`] points per occupied cube of [`typical_spacing`]'s grid:
/// its count then measures the points more than the surface, and the spacing it reads comes
/// near a cube's side however far apart the points lie (as they thin out, the reading stops
/// at the cube's side while their true spacing grows), so planes set by it may reach less far
/// than the next point.
#[must_use]
pub fn sparser_than_the_spacing_grid(points: &[Vec3], size: f32) -> bool {
    let occupied = occupied_cubes(points, size / SPACING_CUBES_PER_SIDE).max(1);
    (points.len() as f32) < LEAST_POINTS_PER_OCCUPIED_CUBE * occupied as f32
}

/// How many of the cubes of side `cell` that a [`PointGrid`] of `points` lays out hold a
/// point ([`PointGrid::occupied`]), counted from the points' cubes alone.
///
/// NOTE: a grid of the 64³ cubes over the box took some 4 MB for the count, which the import
/// now takes twice (the kept points' spacing is read again; bench/RESULTS.md, "Import time:
/// the neighbourhoods"); the sorted cube numbers took four bytes a point and a sort, on the
/// calling thread alone; a bit per cube is 32 kB.
fn occupied_cubes(points: &[Vec3], cell: f32) -> usize {
    let (lo, hi) = points
        .iter()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(a, b), &p| {
            (a.min(p), b.max(p))
        });
    let (lo, hi) = if lo.x.is_finite() {
        (lo, hi)
    } else {
        (Vec3::ZERO, Vec3::ZERO)
    };
    let cubes = Cubes::covering(lo, hi, cell);
    let mut occupied = vec![0u64; cubes.count().div_ceil(64)];
    for &p in points {
        let c = cubes.cube_of(p);
        occupied[c / 64] |= 1 << (c % 64);
    }
    occupied.iter().map(|w| w.count_ones() as usize).sum()
}

/// Screens `points` (see the module docs). `size` is the object's size (its box's longest
/// side) in the points' units; `noise` the scatter if known, same units.
#[must_use]
pub fn screen(points: &[Vec3], size: f32, noise: Option<f32>) -> Consensus {
    let point_spacing = typical_spacing(points, size);
    let mut radius = (NEIGHBOURS / std::f32::consts::PI).sqrt() * point_spacing;
    if let Some(s) = noise {
        radius = radius.max(3.0 * s);
    }
    let radius = radius.clamp(size * 1e-4, size / 8.0);
    let (mut planes, mut sigma, mut radius) = planes_and_noise(points, size, noise, radius);
    let mut median = median_neighbours(&planes);
    // The least local deviation the far test reads (see `curvature_floor`); none but where
    // the radius is widened.
    let mut far_floor = 0.0f32;
    // The noise read off quadrics, where the radius is widened (see `scatter_off_quadrics`).
    let mut off_quadrics = None;
    // Where the points lie further apart than the spacing's grid can read, the radius holds
    // far fewer than `NEIGHBOURS`: a plane through a few of them leaves a genuine point off it
    // by chance, and a third of a clean 1 000-point cloud was dropped.
    let wider = (radius * (SPARSE_MEDIAN_NEIGHBOURS / median.max(1) as f32).sqrt()).min(size / 8.0);
    if (median as f32) < SPARSE_MEDIAN_NEIGHBOURS
        && wider > radius
        && sparser_than_the_spacing_grid(points, size)
    {
        (planes, sigma, radius) = planes_and_noise(points, size, noise, wider);
        far_floor = curvature_floor(&planes);
        median = median_neighbours(&planes);
        isolate_lone_points(points, &mut planes, radius, median);
        if noise.is_none() {
            off_quadrics = scatter_off_quadrics(points, &planes, radius);
        }
    }
    let fewest = ((median as f32 * ISOLATED_FRACTION).ceil() as usize).max(3);
    let scatter = sigma.max(PRECISION * size).max(far_floor);
    let far_limit = FAR_DEVIATIONS * scatter / radius;
    let thin = if far_limit <= THIN_FAR_LIMIT {
        ((median as f32 * THIN_SUPPORT * (1.0 - far_limit * far_limit)).ceil() as usize).max(fewest)
    } else {
        fewest
    };
    let planes = bordering_support(points, planes, radius, [fewest, thin], scatter);
    let (planes, sparse) = sparse_support(points, planes, radius, thin, scatter);
    let (mut isolated, mut far) = (0, 0);
    let confidence = planes
        .iter()
        .map(|plane| match plane {
            Some((plane, off)) => {
                let local = sigma.max(plane.rms).max(PRECISION * size).max(far_floor);
                if *off > FAR_DEVIATIONS * local {
                    far += 1;
                    0.0
                } else {
                    let t = off / (2.0 * local);
                    1.0 / (1.0 + t * t)
                }
            }
            _ => {
                isolated += 1;
                0.0
            }
        })
        .collect();
    Consensus {
        confidence,
        noise: sigma,
        noise_given: noise.is_some(),
        noise_off_quadrics: off_quadrics,
        point_spacing,
        radius,
        isolated,
        far,
        sparse,
    }
}

/// The scatter of the points across the surface with its curvature taken out (see
/// [`super::quadric`]): the median, over an even subset of at most [`QUADRIC_SAMPLES`] of the
/// points with a plane, of their neighbours' (within `radius`) scatter off the quadric height
/// function fitted in the tangent frame of the point's plane; `None` where no point has
/// neighbours enough.
fn scatter_off_quadrics(
    points: &[Vec3],
    planes: &[Option<(Plane, f32)>],
    radius: f32,
) -> Option<f32> {
    let grid = PointGrid::new(points, |_| true, radius, CELL_OFFER);
    let stride = points.len().div_ceil(QUADRIC_SAMPLES).max(1);
    median_scatter(
        (0..points.len())
            .step_by(stride)
            .filter_map(|i| {
                let (plane, _) = planes[i].as_ref()?;
                let mut heights = QuadricHeights::about(
                    points[i].as_dvec3(),
                    plane.normal.as_dvec3().normalize(),
                    f64::from(radius),
                );
                grid.for_each_near(points[i], radius, |j, q| {
                    let along = |(near, _): &(Plane, f32)| {
                        near.normal.dot(plane.normal).abs() >= QUADRIC_NORMALS_COSINE
                    };
                    if planes[j].as_ref().is_some_and(along) {
                        heights.add(q);
                    }
                });
                heights.scatter().map(|scatter| scatter as f32)
            })
            .collect(),
    )
}

/// Points of an even subset, at most, whose neighbours' quadrics [`scatter_off_quadrics`]
/// fits.
const QUADRIC_SAMPLES: usize = 2000;

/// The least cosine between a neighbour's plane's normal and the point's (either sign) for
/// the neighbour to count in the point's quadric (about 26°).
///
/// NOTE: over the radius a sparse cloud widens to, a neighbourhood reaches round a fillet or
/// an edge, or across a hole, where no quadric follows the surface: with every neighbour in,
/// 16 clouds of the four bench models at 1 000 and 2 000 points with 0.25% and 1% noise read
/// 0.97–3.6 times their true noise (the planes: 0.80–3.9 times); with this cosine 0.78–1.25
/// times (0.85: 0.82–1.37; 0.95: 0.76–1.11, the 1% clouds reading lowest, their neighbours'
/// planes tilted by the noise) (bench/RESULTS.md, "A sparse cloud's noise read off
/// quadrics").
const QUADRIC_NORMALS_COSINE: f32 = 0.9;

/// The median of the points' neighbour counts within the radius their `planes` were fitted
/// over (a point with no plane counts none).
fn median_neighbours(planes: &[Option<(Plane, f32)>]) -> usize {
    let mut counts: Vec<usize> = planes
        .iter()
        .map(|p| p.as_ref().map_or(0, |(p, _)| p.neighbours))
        .collect();
    let mid = counts.len() / 2;
    if counts.is_empty() {
        0
    } else {
        *counts.select_nth_unstable(mid).1
    }
}

/// A robust scale of the points' distances to their neighbours' planes (`1.4826 ×` their
/// median): over a radius widened for a sparse cloud a plane spans a curved cap, and a
/// genuine point amid it lies off its neighbours' plane by the cap's sag, which their own
/// scatter need not show (on an evenly sampled sphere the neighbours within a radius are a
/// circle, and lie on their plane exactly). The far test reads no local deviation under it.
fn curvature_floor(planes: &[Option<(Plane, f32)>]) -> f32 {
    let mut offs: Vec<f32> = planes.iter().flatten().map(|(_, off)| *off).collect();
    if offs.is_empty() {
        return 0.0;
    }
    let mid = offs.len() / 2;
    1.4826 * *offs.select_nth_unstable_by(mid, f32::total_cmp).1
}

/// Takes the plane off (isolates) each point of `points` with fewer than [`LONE_NEIGHBOURS`]
/// others within [`LONE_SPACINGS`] of the cloud's spacing, read from the `median` count of
/// neighbours within `radius` (a disc of the surface of that radius holds `median` points).
///
/// Over a radius widened for a sparse cloud, a stray near the surface finds neighbours
/// enough to pass [`ISOLATED_FRACTION`], and a plane over a curved cap that wide has a
/// scatter that hides it from the far test; a genuine point has about 4π others within two
/// spacings, and fewer than three by chance about once in ten thousand (Poisson).
fn isolate_lone_points(
    points: &[Vec3],
    planes: &mut [Option<(Plane, f32)>],
    radius: f32,
    median: usize,
) {
    if median == 0 {
        return;
    }
    let near = LONE_SPACINGS * radius * (std::f32::consts::PI / median as f32).sqrt();
    let grid = PointGrid::new(points, |_| true, near, CELL_OFFER);
    let lone = parallel_map(points.len(), |i| {
        let mut others = 0;
        grid.for_each_near(points[i], near, |j, _| others += usize::from(j != i));
        others < LONE_NEIGHBOURS
    });
    for (plane, lone) in planes.iter_mut().zip(lone) {
        if lone {
            *plane = None;
        }
    }
}

/// Per point: the plane it is judged by, or `None` where it is isolated; `[fewest, thin]`
/// the neighbour counts that make a point supported and well supported. A point with at
/// least `thin` neighbours keeps its neighbours' plane and distance. One with fewer (but
/// at least three, for a plane) is also judged against the plane of its nearest neighbour
/// within the radius that is well supported (for a point with `fewest` or more: a stray
/// beside another may be supported by it) or supported (for one with fewer), by its
/// deviation from it over that plane's scatter, in noise levels `sigma`. A genuine point of
/// a sparsely sampled area (a flat face beside a densely sampled edge) lies among supported
/// points and on their planes, while a stray in empty space has none about it, and a stray
/// a few noise levels off the surface (its neighbours a small cap, their plane leaning
/// anywhere) lies off its nearest well-supported neighbour's plane. A point under `fewest`
/// is judged by the larger of its two deviations, and only where the noise is well under
/// the radius (see [`RESCUE_RADII`]; elsewhere, or with no supported neighbour, it is
/// isolated). A point with `fewest` or more keeps its own plane and distance unless the
/// deviation from its neighbour's plane is over [`FAR_DEVIATIONS`] (it is then dropped), or
/// where it has no well-supported neighbour.
fn bordering_support(
    points: &[Vec3],
    planes: Vec<Option<(Plane, f32)>>,
    radius: f32,
    [fewest, thin]: [usize; 2],
    sigma: f32,
) -> Vec<Option<(Plane, f32)>> {
    let count = |i: usize| planes[i].as_ref().map_or(0, |(p, _)| p.neighbours);
    // Where the noise is not well under the radius, a stray just off the surface has few
    // neighbours and lies within the far test's reach of their planes, like a sparse genuine
    // point: there, few neighbours mean isolated.
    let resolves = FAR_DEVIATIONS * sigma <= RESCUE_RADII * radius;
    let judged = |i: usize| {
        let c = count(i);
        c < thin && (c >= fewest || resolves)
    };
    let grid = PointGrid::new(points, |i| count(i) >= fewest, radius, CELL_OFFER);
    let bordering = parallel_map(points.len(), |i| {
        if !judged(i) {
            return None;
        }
        let p = points[i];
        // A supported point is judged against a well-supported one (another stray near it,
        // supported by it, may have a plane through it); a point under `fewest`, against a
        // supported one (in a sparsely sampled area, none may be well supported).
        let least = if count(i) >= fewest { thin } else { fewest };
        let mut nearest = (f32::INFINITY, None);
        grid.for_each_near(p, radius, |j, q| {
            let d = (q - p).length_squared();
            if j != i && d < nearest.0 && count(j) >= least {
                nearest = (d, Some(j));
            }
        });
        let (plane, _) = planes[nearest.1?].as_ref()?;
        let off = (p - plane.centre).dot(plane.normal).abs();
        Some((plane.rms, off))
    });
    planes
        .into_iter()
        .zip(bordering)
        .map(|(own, bordering)| match (own, bordering) {
            // Judged by the larger of its deviations from the two planes; a supported point
            // that lies on its nearest well-supported neighbour's plane keeps its own plane
            // and distance (and so its confidence).
            (Some((plane, off)), Some((rms, off_bordering))) => {
                let scale = |rms: f32| rms.max(sigma);
                let bordering = off_bordering / scale(rms);
                if plane.neighbours >= fewest && bordering <= FAR_DEVIATIONS {
                    return Some((plane, off));
                }
                let worst = (off / scale(plane.rms)).max(bordering);
                Some((Plane { rms: 0.0, ..plane }, worst * sigma))
            }
            (Some(own), None) if own.0.neighbours >= fewest => Some(own),
            _ => None,
        })
        .collect()
}

/// `planes` with each point about to be dropped that had fewer than `thin` neighbours within
/// `radius` (none: isolated; or a few, too few to fix the plane it is found far from) judged
/// again by its [`SPARSE_NEIGHBOURS`] nearest points within [`SPARSE_RADII`] radii, where
/// the cloud may be sampled far more sparsely than its median (the side of a scan away from
/// the scanner, or an area one view of several saw): the count within `radius` alone takes
/// such points for strays.
///
/// Such a point is judged by its nearest points' plane, like any other by its own, where:
/// - they lie on a plane (see [`SPARSE_FLATNESS`]): a ball of strays in empty space does not;
/// - it lies amid them (see [`SPARSE_AMID`]): a stray beside a densely sampled surface has
///   them all to one side;
/// - it lies within [`FAR_DEVIATIONS`] local deviations of the plane (noise levels `sigma`)
///   beyond the sag a curved surface's points leave about their plane;
/// - and at least [`SPARSE_GROUP`] points so judged are linked by being among each other's
///   nearest: a sparse surface is many such points, while a few strays in thousands may
///   pass the tests above by chance, and each kept alone would be signed as a blob.
///
/// Every other point stays as it was (isolated, or off its own few neighbours' plane).
/// Returns the planes and how many points were judged so.
fn sparse_support(
    points: &[Vec3],
    mut planes: Vec<Option<(Plane, f32)>>,
    radius: f32,
    thin: usize,
    sigma: f32,
) -> (Vec<Option<(Plane, f32)>>, usize) {
    // The points about to be dropped that had too few neighbours to judge them by.
    let dropped = |judged: &Option<(Plane, f32)>| match judged {
        None => true,
        Some((plane, off)) => {
            plane.neighbours < thin && *off > FAR_DEVIATIONS * sigma.max(plane.rms)
        }
    };
    let lone: Vec<usize> = (0..planes.len()).filter(|&i| dropped(&planes[i])).collect();
    if lone.is_empty() {
        return (planes, 0);
    }
    // `p` judged by the plane of `near` (its nearest, the farthest `reach` from it; the
    // plane fitted robustly, as every point's is): the plane and `p`'s distance to it, or
    // `None`.
    let judge = |p: Vec3, near: &[Vec3], reach: f32| {
        let plane = plane_of(near, &mut Vec::new(), &mut Vec::new())?;
        if plane.rms > (SPARSE_FLATNESS * reach).max(SPARSE_NOISE_ALLOWANCE * sigma) {
            return None;
        }
        let from_centre = p - plane.centre;
        let off = from_centre.dot(plane.normal);
        let along = (from_centre - off * plane.normal).length();
        // The part of the scatter that is not the noise is the surface's curvature's, and a
        // point amid a curved cap lies off its points' plane by up to √3 times that: the
        // point's distance from the surface is taken as its distance beyond that sag.
        let sag = 3f32.sqrt() * (plane.rms * plane.rms - sigma * sigma).max(0.0).sqrt();
        let off = (off.abs() - sag).max(0.0);
        let judged = along <= SPARSE_AMID * reach && off <= FAR_DEVIATIONS * sigma.max(plane.rms);
        judged.then_some((plane, off))
    };
    let search = SPARSE_RADII * radius;
    let grid = PointGrid::new(points, |_| true, search, CELL_OFFER);
    // First by all its nearest points: each point's nearest and their reach where judged.
    let first = parallel_map(lone.len(), |k| {
        let (i, p) = (lone[k], points[lone[k]]);
        let mut near: Vec<(f32, u32)> = Vec::new();
        grid.for_each_near(p, search, |j, q| {
            if j != i {
                near.push(((q - p).length_squared(), j as u32));
            }
        });
        if near.len() < SPARSE_NEIGHBOURS {
            return None;
        }
        let (nearest, farthest, _) =
            near.select_nth_unstable_by(SPARSE_NEIGHBOURS - 1, |a, b| a.0.total_cmp(&b.0));
        let reach = farthest.0.sqrt();
        let nearest: Vec<u32> = nearest.iter().chain([&*farthest]).map(|n| n.1).collect();
        let positions: Vec<Vec3> = nearest.iter().map(|&j| points[j as usize]).collect();
        judge(p, &positions, reach).map(|_| (nearest, reach))
    });
    // Where a point is judged, the index of its place in `lone`.
    let judged_at = |j: u32| {
        lone.binary_search(&(j as usize))
            .ok()
            .filter(|&m| first[m].is_some())
    };
    // Then again by those of its nearest that are supported or judged: strays among a
    // sparse surface's points lean the first planes toward them.
    let second = parallel_map(lone.len(), |k| {
        let (nearest, reach) = first[k].as_ref()?;
        let positions: Vec<Vec3> = nearest
            .iter()
            .filter(|&&j| !dropped(&planes[j as usize]) || judged_at(j).is_some())
            .map(|&j| points[j as usize])
            .collect();
        if positions.len() < SPARSE_NEIGHBOURS / 2 {
            return None;
        }
        judge(points[lone[k]], &positions, *reach)
    });
    // The points judged twice, linked through each other's nearest (sets over `lone`).
    let mut sets = DisjointSets::new(lone.len());
    for (k, (nearest, _)) in first
        .iter()
        .enumerate()
        .filter_map(|(k, f)| Some((k, f.as_ref()?)))
    {
        if second[k].is_none() {
            continue;
        }
        for m in nearest.iter().filter_map(|&j| judged_at(j)) {
            if second[m].is_some() {
                sets.join(k as u32, m as u32);
            }
        }
    }
    let mut members = vec![0usize; lone.len()];
    for k in 0..lone.len() {
        if second[k].is_some() {
            members[sets.root(k as u32) as usize] += 1;
        }
    }
    let mut kept = 0;
    for (k, judged) in second.into_iter().enumerate() {
        if judged.is_some() && members[sets.root(k as u32) as usize] >= SPARSE_GROUP {
            planes[lone[k]] = judged;
            kept += 1;
        }
    }
    (planes, kept)
}

/// Each point's neighbours' plane and its distance to it, the noise level (`noise`, or the
/// median of an even subset's planes' RMS distances) and the radius they were fitted over:
/// `radius`, or three noise levels where that is wider (the planes at `radius` were fitted
/// to the scatter; at most an eighth of `size`).
///
/// NOTE: the subset's planes are fitted first, and the others only where the radius stands:
/// a noisy cloud fitted every plane twice (bench/RESULTS.md, "Import wall time").
fn planes_and_noise(
    points: &[Vec3],
    size: f32,
    noise: Option<f32>,
    mut radius: f32,
) -> (Vec<Option<(Plane, f32)>>, f32, f32) {
    let n = points.len();
    // The noise is estimated from the planes of an even subset of the points (every
    // `stride`-th).
    let stride = n.div_ceil(NOISE_SAMPLES).max(1);
    let estimate = |sampled: &mut dyn Iterator<Item = &Option<(Plane, f32)>>| {
        let mut rms: Vec<f32> = sampled.flatten().map(|(p, _)| p.rms).collect();
        if rms.is_empty() {
            return 0.0;
        }
        let mid = rms.len() / 2;
        *rms.select_nth_unstable_by(mid, f32::total_cmp).1
    };
    // The planes are fitted in the grid's order (each is the same in any order), found on a
    // thread of its own beside the grid's build (both were on the main thread in turn).
    let (grid, order) = std::thread::scope(|scope| {
        let order = scope.spawn(|| spatial_order(points, radius));
        let grid = PointGrid::new(points, |_| true, radius, CELL_OFFER);
        let order = order
            .join()
            .unwrap_or_else(|e| std::panic::resume_unwind(e));
        (grid, order)
    });
    let (mut planes, mut sigma) = match noise {
        Some(sigma) => (fit_planes(points, &grid, &order, radius, 0), sigma),
        None => {
            // The subset's planes first: where they show the radius too narrow for the noise,
            // the others would be fitted again at a wider one.
            let sampled_order: Vec<u32> = order
                .iter()
                .filter(|&&i| (i as usize).is_multiple_of(stride))
                .map(|&i| i / stride as u32)
                .collect();
            let sampled = parallel_map_in_order(&sampled_order, |s| {
                plane_at(points, &grid, radius, s * stride)
            });
            let sigma = estimate(&mut sampled.iter());
            let mut sampled = sampled.into_iter();
            let planes = if radius < 3.0 * sigma && radius < size / 8.0 {
                Vec::new()
            } else {
                fit_planes(points, &grid, &order, radius, stride)
                    .into_iter()
                    .enumerate()
                    .map(|(i, plane)| {
                        if i % stride == 0 {
                            sampled.next().flatten()
                        } else {
                            plane
                        }
                    })
                    .collect()
            };
            (planes, sigma)
        }
    };
    drop(grid);
    if noise.is_none() && radius < 3.0 * sigma && radius < size / 8.0 {
        // The planes were fitted to the scatter: widen and estimate again.
        radius = (3.0 * sigma).min(size / 8.0);
        let grid = PointGrid::new(points, |_| true, radius, CELL_OFFER);
        planes = fit_planes(points, &grid, &order, radius, 0);
        sigma = estimate(&mut planes.iter().step_by(stride));
    }
    (planes, sigma, radius)
}

/// Each point's neighbours' plane (itself left out) and its distance to it, among the points
/// of `grid` (all of `points`, in cells of `radius`), fitted in `order` ([`spatial_order`];
/// the planes do not depend on it); with `skip_every` above 0, the points whose index is a
/// multiple of it are left out (`None`: their planes are known).
fn fit_planes(
    points: &[Vec3],
    grid: &PointGrid,
    order: &[u32],
    radius: f32,
    skip_every: usize,
) -> Vec<Option<(Plane, f32)>> {
    parallel_map_in_order(order, |i| {
        if skip_every > 0 && i % skip_every == 0 {
            return None;
        }
        plane_at(points, grid, radius, i)
    })
}

/// Point `i`'s neighbours' plane (itself left out) and its distance to it.
fn plane_at(points: &[Vec3], grid: &PointGrid, radius: f32, i: usize) -> Option<(Plane, f32)> {
    thread_local! {
        /// The neighbours' positions and their distances to the first plane, kept per thread
        /// across the planes it fits.
        static SCRATCH: std::cell::RefCell<(Vec<Vec3>, Vec<f32>, Vec<Vec3>)> =
            const { std::cell::RefCell::new((Vec::new(), Vec::new(), Vec::new())) };
    }
    let p = points[i];
    SCRATCH.with_borrow_mut(|(near, off, inliers)| {
        near.clear();
        grid.for_each_near(p, radius, |j, q| {
            if j != i {
                near.push(q);
            }
        });
        plane_of(near, off, inliers).map(|plane| {
            let off = (p - plane.centre).dot(plane.normal).abs();
            (plane, off)
        })
    })
}

/// The eigenvector of the symmetric positive semi-definite `cov` with the smallest eigenvalue:
/// power iteration on the fourth power of the adjugate of `cov`. The adjugate's eigenvalues
/// are the products of `cov`'s in pairs (`λ₁λ₂ ≥ λ₁λ₃ ≥ λ₂λ₃`, with the same eigenvectors),
/// so a step on it gains a factor `λ₃ / λ₂`, and a step on its fourth power (two squarings,
/// 54 products) `(λ₃ / λ₂)⁴`: a few steps for a neighbourhood of a surface, exact in one for a
/// flat one (the adjugate of a rank-2 `cov` is `λ₁λ₂ v₃v₃ᵀ`). Where `cov` is near rank 1
/// (points along a line: any direction across it is as good) the adjugate vanishes, and
/// [`least_variance_by_shift`] answers.
///
/// NOTE: [`least_variance_by_shift`] alone gains only `(λ₁ + λ₃) / (λ₁ + λ₂)` per step,
/// about ½ for a neighbourhood of a surface: twenty to forty steps, about 6% of an import's
/// time in `perf record` on a 50 000-point cloud (bench/RESULTS.md, "Import time against
/// screened Poisson's"). On the adjugate itself a normal took 23–25 steps on average on the
/// 1% clouds of the peer bench and 7 on the 0.25% ones, 5% of an import's CPU time
/// (bench/RESULTS.md, "Import time: the work shared out"; "Import time toward a fifth of
/// PoissonRecon's").
pub(crate) fn least_variance_direction(cov: [[f64; 3]; 3]) -> Vec3 {
    let c = cov;
    let adjugate = [
        [
            c[1][1] * c[2][2] - c[1][2] * c[2][1],
            c[0][2] * c[2][1] - c[0][1] * c[2][2],
            c[0][1] * c[1][2] - c[0][2] * c[1][1],
        ],
        [
            c[1][2] * c[2][0] - c[1][0] * c[2][2],
            c[0][0] * c[2][2] - c[0][2] * c[2][0],
            c[0][2] * c[1][0] - c[0][0] * c[1][2],
        ],
        [
            c[1][0] * c[2][1] - c[1][1] * c[2][0],
            c[0][1] * c[2][0] - c[0][0] * c[2][1],
            c[0][0] * c[1][1] - c[0][1] * c[1][0],
        ],
    ];
    let trace = c[0][0] + c[1][1] + c[2][2];
    // `λ₁λ₂` under this share of `trace²` (a line's neighbourhood, or nothing at all) leaves
    // the adjugate to rounding.
    let smallest_product = 1e-10 * trace * trace;
    // The first step on the adjugate itself tells whether it vanishes.
    let start = least_variance_start(cov);
    let first = times(adjugate, start);
    let len = first.length();
    if len.is_nan() || len <= smallest_product {
        return least_variance_by_shift(cov);
    }
    let fourth = squared_scaled(squared_scaled(adjugate));
    match power_iteration(fourth, first / len) {
        Some(v) => v.as_vec3(),
        None => least_variance_by_shift(cov),
    }
}

/// `m v` for a 3 × 3 `m`.
#[inline]
fn times(m: [[f64; 3]; 3], v: glam::DVec3) -> glam::DVec3 {
    glam::DVec3::new(
        m[0][0] * v.x + m[0][1] * v.y + m[0][2] * v.z,
        m[1][0] * v.x + m[1][1] * v.y + m[1][2] * v.z,
        m[2][0] * v.x + m[2][1] * v.y + m[2][2] * v.z,
    )
}

/// `m²` of the symmetric `m`, divided by its largest entry's magnitude (the eigenvectors are
/// `m`'s, the eigenvalues squared and scaled alike; the scale keeps repeated squarings
/// within `f64`'s range). A zero `m` stays zero.
#[inline]
fn squared_scaled(m: [[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let mut square = [[0.0; 3]; 3];
    for (r, row) in square.iter_mut().enumerate() {
        for (k, value) in row.iter_mut().enumerate() {
            *value = m[r][0] * m[0][k] + m[r][1] * m[1][k] + m[r][2] * m[2][k];
        }
    }
    let largest = square.iter().flatten().fold(0.0f64, |a, &v| a.max(v.abs()));
    if largest > 0.0 && largest.is_finite() {
        for value in square.iter_mut().flatten() {
            *value /= largest;
        }
    }
    square
}

/// The axis of `cov`'s least variance, nudged off the axis in case it is orthogonal to the
/// answer: where the power iterations start.
fn least_variance_start(cov: [[f64; 3]; 3]) -> glam::DVec3 {
    let start = (0..3)
        .min_by(|&a, &b| cov[a][a].total_cmp(&cov[b][b]))
        .unwrap_or(0);
    let mut v = glam::DVec3::splat(1e-3);
    v[start] = 1.0;
    v
}

/// Power iteration on the symmetric positive semi-definite `m` from the unit `v` (at most 60
/// steps, until a step moves the unit vector by under 10⁻⁶): its eigenvector of the largest
/// eigenvalue, or `None` when a step's image vanishes (or is not a number).
fn power_iteration(m: [[f64; 3]; 3], mut v: glam::DVec3) -> Option<glam::DVec3> {
    for _ in 0..60 {
        let w = times(m, v);
        let len = w.length();
        if len.is_nan() || len <= 0.0 {
            return None;
        }
        let next = w / len;
        let settled = (next - v).length_squared() < 1e-12;
        v = next;
        if settled {
            break;
        }
    }
    Some(v)
}

/// [`least_variance_direction`] by power iteration on `trace · I − cov`, whose largest
/// eigenvalue it is (`trace − λ₃`): slower (see there), but it answers for any `cov`.
pub(crate) fn least_variance_by_shift(cov: [[f64; 3]; 3]) -> Vec3 {
    let trace = cov[0][0] + cov[1][1] + cov[2][2];
    let mut v = least_variance_start(cov);
    for _ in 0..60 {
        let w = glam::DVec3::new(
            trace * v.x - (cov[0][0] * v.x + cov[0][1] * v.y + cov[0][2] * v.z),
            trace * v.y - (cov[1][0] * v.x + cov[1][1] * v.y + cov[1][2] * v.z),
            trace * v.z - (cov[2][0] * v.x + cov[2][1] * v.y + cov[2][2] * v.z),
        );
        let len = w.length();
        if len.is_nan() || len <= 0.0 {
            break;
        }
        let next = w / len;
        let settled = (next - v).length_squared() < 1e-12;
        v = next;
        if settled {
            break;
        }
    }
    v.as_vec3()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A flat square of `side`² points at unit spacing, each lifted by a deterministic
    /// pseudo-random height of standard deviation about `sigma`.
    fn noisy_square(side: usize, sigma: f32) -> Vec<Vec3> {
        let mut seed = 0x1234_5678_u64;
        let mut gauss = || {
            // Sum of twelve uniforms less six: close to a standard normal.
            (0..12)
                .map(|_| {
                    seed = seed
                        .wrapping_mul(6_364_136_223_846_793_005)
                        .wrapping_add(1_442_695_040_888_963_407);
                    (seed >> 40) as f32 / (1u64 << 24) as f32
                })
                .sum::<f32>()
                - 6.0
        };
        let mut out = Vec::new();
        for i in 0..side {
            for j in 0..side {
                out.push(Vec3::new(i as f32, j as f32, sigma * gauss()));
            }
        }
        out
    }

    #[test]
    fn the_noise_of_a_flat_cloud_is_estimated_within_a_fifth() {
        for sigma in [0.05f32, 0.2, 0.5] {
            let points = noisy_square(120, sigma);
            let c = screen(&points, 120.0, None);
            assert!(
                (c.noise / sigma - 1.0).abs() < 0.2,
                "σ {sigma}: estimated {}",
                c.noise
            );
            assert!(c.far < points.len() / 200, "σ {sigma}: {} dropped", c.far);
            assert_eq!(c.isolated, 0);
        }
    }

    #[test]
    fn strays_a_few_noise_levels_outside_a_noisy_rod_are_dropped_and_the_rod_kept() {
        // A rod (a cylinder of radius 5) of points scattered at random, one per unit of area,
        // with noise σ = 0.4 across it (the neighbour radius about eight noise levels, as on
        // a 50 000-point scan at 0.25% noise), and strays 5 to 7.5 σ outside it: each has a
        // small cap of the rod's points within the radius, whose own plane, fitted to a cap
        // hardly wider than the noise on a curved surface, may lean through it. Every stray
        // must be dropped, and the rod's points kept.
        let sigma = 0.4f32;
        let mut seed = 0x9e37_79b9_u64;
        let mut unit = || {
            seed = seed
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (seed >> 40) as f32 / (1u64 << 24) as f32
        };
        let (side, radius) = (120.0f32, 5.0f32);
        let around = std::f32::consts::TAU * radius;
        let on_cylinder = |along: f32, angle: f32, height: f32| {
            Vec3::new(
                (radius + height) * angle.cos(),
                along,
                (radius + height) * angle.sin(),
            )
        };
        let mut points: Vec<Vec3> = (0..(side * around) as usize)
            .map(|_| {
                // Sum of twelve uniforms less six: close to a standard normal.
                let gauss: f32 = (0..12).map(|_| unit()).sum::<f32>() - 6.0;
                on_cylinder(side * unit(), std::f32::consts::TAU * unit(), sigma * gauss)
            })
            .collect();
        let sheet = points.len();
        // One stray per block of 4 along the rod and quarter turn around it: some are
        // within the neighbour radius of each other.
        for block in 1..30 {
            for turn in 0..4 {
                points.push(on_cylinder(
                    block as f32 * 4.0 + 2.0 * unit(),
                    (turn as f32 + unit() * 0.5) * std::f32::consts::FRAC_PI_2,
                    sigma * (5.0 + 2.5 * unit()),
                ));
            }
        }
        let c = screen(&points, side, None);
        let kept_strays: Vec<Vec3> = (sheet..points.len())
            .filter(|&i| c.confidence[i] > 0.0)
            .map(|i| points[i])
            .collect();
        assert!(
            kept_strays.is_empty(),
            "{} of {} strays kept: {kept_strays:?}",
            kept_strays.len(),
            points.len() - sheet
        );
        let dropped = (0..sheet).filter(|&i| c.confidence[i] == 0.0).count();
        assert!(
            dropped < sheet / 200,
            "{dropped} of the sheet's points dropped"
        );
    }

    #[test]
    fn the_planes_and_the_noise_are_those_of_fitting_every_plane_first() {
        // Sheets of more points than the noise takes its estimate from (every other point
        // sampled), the noise estimated or given: the planes, the noise and the radius are
        // bit for bit those of the plain order, every plane at the first radius, then the
        // estimate (and every plane again at a wider radius where the first is too narrow).
        let bits = |planes: &[Option<(Plane, f32)>]| -> Vec<Option<[u32; 10]>> {
            planes
                .iter()
                .map(|p| {
                    p.as_ref().map(|(p, off)| {
                        [
                            p.centre.x.to_bits(),
                            p.centre.y.to_bits(),
                            p.centre.z.to_bits(),
                            p.normal.x.to_bits(),
                            p.normal.y.to_bits(),
                            p.normal.z.to_bits(),
                            p.rms.to_bits(),
                            p.neighbours as u32,
                            off.to_bits(),
                            0,
                        ]
                    })
                })
                .collect()
        };
        let median_rms = |planes: &[Option<(Plane, f32)>], stride: usize| {
            let mut rms: Vec<f32> = planes
                .iter()
                .step_by(stride)
                .flatten()
                .map(|(p, _)| p.rms)
                .collect();
            let mid = rms.len() / 2;
            *rms.select_nth_unstable_by(mid, f32::total_cmp).1
        };
        for (sigma, given) in [(0.05f32, None), (0.3, None), (0.3, Some(0.25))] {
            let points = noisy_square(160, sigma);
            let size = 160.0;
            let stride = points.len().div_ceil(NOISE_SAMPLES);
            assert_eq!(stride, 2);
            let first = 3.0;
            let (planes, noise, radius) = planes_and_noise(&points, size, given, first);
            let grid = PointGrid::new(&points, |_| true, first, CELL_OFFER);
            let by_index: Vec<u32> = (0..points.len() as u32).collect();
            let mut plain = fit_planes(&points, &grid, &by_index, first, 0);
            let mut plain_noise = given.unwrap_or_else(|| median_rms(&plain, stride));
            let mut plain_radius = first;
            if given.is_none() && first < 3.0 * plain_noise {
                plain_radius = 3.0 * plain_noise;
                let grid = PointGrid::new(&points, |_| true, plain_radius, CELL_OFFER);
                plain = fit_planes(&points, &grid, &by_index, plain_radius, 0);
                plain_noise = median_rms(&plain, stride);
            }
            assert_eq!(bits(&planes), bits(&plain), "σ {sigma}");
            assert_eq!(noise.to_bits(), plain_noise.to_bits(), "σ {sigma}");
            assert_eq!(radius.to_bits(), plain_radius.to_bits(), "σ {sigma}");
        }
    }

    #[test]
    fn a_spatial_order_is_a_permutation_by_cube_and_a_map_in_it_returns_by_index() {
        // Points in a scrambled order: the order lists each index once, cube by cube (z-major)
        // and by index within a cube; a map in that order gives each index its own value.
        let mut points = noisy_square(70, 0.3);
        let count = points.len();
        for i in 0..count {
            points.swap(i, (i * 7919 + 13) % count);
        }
        let cell = 4.0;
        let order = spatial_order(&points, cell);
        let mut seen = vec![false; count];
        for &i in &order {
            assert!(!std::mem::replace(&mut seen[i as usize], true), "{i} twice");
        }
        assert!(seen.iter().all(|&s| s), "an index missing");
        let lo = points.iter().fold(Vec3::INFINITY, |a, &p| a.min(p));
        let hi = points.iter().fold(Vec3::NEG_INFINITY, |a, &p| a.max(p));
        let dims = ((hi - lo) / cell).floor().as_ivec3() + IVec3::ONE;
        let key = |i: u32| {
            let c = ((points[i as usize] - lo) / cell).floor().as_ivec3();
            ((c.x + dims.x * (c.y + dims.y * c.z)) as usize, i)
        };
        assert!(order.windows(2).all(|w| key(w[0]) < key(w[1])));
        let values = parallel_map_in_order(&order, |i| points[i].x * 3.0 + i as f32);
        let plain = parallel_map(count, |i| points[i].x * 3.0 + i as f32);
        assert_eq!(values, plain);
    }

    #[test]
    fn a_parallel_map_returns_every_value_in_order_however_uneven_the_work() {
        // The first indices cost far more than the rest (as the nodes near a surface do), so
        // the chunks are taken out of turn; the values still come back by index, once each.
        let value = |i: usize| {
            let rounds = if i < 3000 { 400 } else { 1 };
            (0..rounds).fold(i as u64, |h, r| {
                h.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(r)
            })
        };
        for count in [0, 1, 4095, 4097, 70_001] {
            let plain: Vec<u64> = (0..count).map(value).collect();
            assert_eq!(parallel_map(count, value), plain, "{count}");
            // A thread for every few indices (the costly calls' split), and the smallest.
            for least in [0, 1, 256] {
                assert_eq!(
                    parallel_map_by(count, least, value),
                    plain,
                    "{count}, {least}"
                );
            }
        }
    }

    #[test]
    fn the_grid_holds_each_cells_kept_points_by_stride_in_index_order() {
        // A noisy sheet of 40 000 points, some left out, each cell offering at most 3: per
        // cell, the kept points in index order, every stride-th of them, as a plain scan of
        // each cell finds.
        let points = noisy_square(200, 0.3);
        let keep = |i: usize| i % 7 != 3;
        let (cell, offer) = (2.5, 3);
        let grid = PointGrid::new(&points, keep, cell, offer);
        let kept: Vec<usize> = (0..points.len()).filter(|&i| keep(i)).collect();
        let (lo, hi) = kept
            .iter()
            .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(a, b), &i| {
                (a.min(points[i]), b.max(points[i]))
            });
        let cubes = Cubes::covering(lo, hi, cell);
        assert_eq!(grid.starts.len(), cubes.count() + 1);
        let mut cells: Vec<Vec<usize>> = vec![Vec::new(); cubes.count()];
        for &i in &kept {
            cells[cubes.cube_of(points[i])].push(i);
        }
        let mut offered_anywhere = 0;
        for (c, in_cell) in cells.iter().enumerate() {
            let stride = in_cell.len().div_ceil(offer).max(1);
            let expected: Vec<u32> = in_cell.iter().step_by(stride).map(|&i| i as u32).collect();
            let held = &grid.members[grid.starts[c] as usize..grid.starts[c + 1] as usize];
            assert_eq!(held, expected.as_slice(), "cell {c}");
            offered_anywhere += expected.len();
        }
        assert_eq!(grid.members.len(), offered_anywhere);
        for (slot, &i) in grid.members.iter().enumerate() {
            assert_eq!(grid.positions[slot], points[i as usize]);
        }
        // Some cells held more than they offer, and the left-out points are in none.
        assert!(offered_anywhere < kept.len());
        assert!(grid.members.iter().all(|&i| keep(i as usize)));
    }

    #[test]
    fn a_radius_search_visits_exactly_the_points_within_reach_in_the_grid_order() {
        // A noisy sheet, searched at points on it, off it and outside its box, at radii up to
        // two and a half cell sides: the visits are the points within the radius, each once,
        // in the order the grid holds them (its cells in order, as a scan of every cell gives
        // them).
        let points = noisy_square(40, 0.3);
        let cell = 2.0;
        let grid = PointGrid::new(&points, |_| true, cell, usize::MAX);
        let order: Vec<usize> = grid.members.iter().map(|&j| j as usize).collect();
        let mut seed = 99u32;
        let mut uniform = |lo: f32, hi: f32| {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            lo + (hi - lo) * ((seed >> 8) as f32 / (1u32 << 24) as f32)
        };
        for _ in 0..500 {
            let x = Vec3::new(uniform(-3.0, 42.0), uniform(-3.0, 42.0), uniform(-2.0, 2.0));
            let radius = uniform(0.1, 2.5 * grid.cell);
            let mut visited = Vec::new();
            grid.for_each_near(x, radius, |j, p| {
                assert_eq!(p, points[j]);
                visited.push(j);
            });
            let within: Vec<usize> = order
                .iter()
                .copied()
                .filter(|&j| (points[j] - x).length_squared() <= radius * radius)
                .collect();
            assert_eq!(visited, within, "at {x} within {radius}");
        }
    }

    #[test]
    fn the_least_variance_direction_is_the_shifted_iterations_and_lines_are_answered() {
        // Covariances of random rotations of a diagonal `(a, b, c)`: the adjugate's iteration
        // finds the axis of `c` (up to sign) within f32 rounding, from nearly isotropic
        // spreads to flat ones, including an exact plane, as the shifted iteration does.
        let mut seed = 0x2545_f491_u64;
        let mut uniform = || {
            seed = seed
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let spreads = [
            [1.0, 0.9, 0.5],
            [1.0, 1.0, 1e-2],
            [2.0, 0.5, 1e-4],
            [1.0, 0.7, 0.0],
            [3.0, 0.2, 1e-6],
        ];
        for trial in 0..200 {
            let [a, b, c] = spreads[trial % spreads.len()];
            let axis =
                glam::DVec3::new(uniform() - 0.5, uniform() - 0.5, uniform() - 0.5).normalize();
            let rotation = glam::DMat3::from_axis_angle(axis, 6.0 * uniform());
            let m = rotation
                * glam::DMat3::from_diagonal(glam::DVec3::new(a, b, c))
                * rotation.transpose();
            let cov = [0, 1, 2].map(|r| [0, 1, 2].map(|k| m.col(k)[r]));
            let truth = rotation.col(2);
            let fast = least_variance_direction(cov).as_dvec3();
            let shifted = least_variance_by_shift(cov).as_dvec3();
            assert!(
                fast.dot(truth).abs() > 1.0 - 1e-6,
                "trial {trial}: {fast} against {truth}"
            );
            // The shifted iteration gains `(a + c) / (a + b)` per step and stops when a step
            // moves under 10⁻⁶, short of the answer where that is near 1 (a nearly isotropic
            // spread, or a long narrow one): compared where it settles within f32 rounding.
            if (a + c) / (a + b) < 0.7 {
                assert!(
                    fast.dot(shifted).abs() > 1.0 - 1e-6,
                    "trial {trial}: {fast} against the shifted iteration's {shifted}"
                );
            }
        }
        // Points along a line, and no spread at all: any unit direction across the line.
        let line = [[4.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]];
        let across = least_variance_direction(line);
        assert!(
            (across.length() - 1.0).abs() < 1e-6 && across.x.abs() < 1e-6,
            "{across}"
        );
        let none = least_variance_direction([[0.0; 3]; 3]);
        assert!(none.is_finite(), "{none}");
    }

    #[test]
    fn the_inline_floor_and_falloff_match_the_library_ones() {
        for v in [
            -3.5f32, -3.0, -2.999, -0.5, -1e-7, 0.0, 1e-7, 0.5, 0.999_999, 1.0, 7.25, 1e6,
        ] {
            assert_eq!(floor_to_i32(v), v.floor() as i32, "floor of {v}");
        }
        assert_eq!(floor_to_i32(f32::NAN), 0);
        assert_eq!(floor_to_i32(-1e20), i32::MIN);
        assert_eq!(floor_to_i32(1e20), i32::MAX);
        let mut worst = 0.0f32;
        for step in 0..=20_000 {
            let t = step as f32 * 1e-3;
            let exact = (-t).exp();
            worst = worst.max((exp_neg(t) - exact).abs() / exact);
        }
        assert!(worst < 2e-6, "relative error {worst}");
        assert_eq!(exp_neg(0.0), 1.0);
        assert_eq!(exp_neg(200.0), 0.0);
        assert!(exp_neg(f32::NAN).is_nan());
    }

    #[test]
    fn strays_off_the_surface_and_in_empty_space_are_dropped() {
        let mut points = noisy_square(100, 0.05);
        let clean = points.len();
        // Off the surface by 2 units, over its middle.
        for i in 0..40 {
            points.push(Vec3::new(20.0 + i as f32 * 1.5, 50.0, 2.0));
        }
        // Far away, one by one.
        for i in 0..30 {
            points.push(Vec3::new(i as f32 * 10.0, -300.0, 80.0 + i as f32));
        }
        let c = screen(&points, 300.0, None);
        assert!(c.confidence[clean..].iter().all(|&w| w == 0.0));
        assert!(c.far + c.isolated >= 70);
        assert!(c.kept() > clean - clean / 200, "{} of {clean}", c.kept());
        // A given noise level is used as given.
        let given = screen(&points, 300.0, Some(0.1));
        assert!(given.noise_given && given.noise == 0.1);
    }

    /// A sphere of radius 50 about the origin: `count` points spread evenly (a Fibonacci
    /// spiral) with noise of about `sigma` along the radius, of which those with `x < 0`
    /// are kept one in `sparse_every`; then `strays` points uniform in the box of side 140.
    /// Returns the points and how many lie on the sphere.
    fn sparse_sided_sphere(
        count: usize,
        sigma: f32,
        sparse_every: usize,
        strays: usize,
    ) -> (Vec<Vec3>, usize) {
        let mut seed = 0x9e37_79b9_7f4a_7c15_u64;
        let mut uniform = move || {
            seed = seed
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (seed >> 40) as f32 / (1u64 << 24) as f32
        };
        let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
        let mut points = Vec::new();
        for i in 0..count {
            let y = 1.0 - 2.0 * (i as f32 + 0.5) / count as f32;
            let ring = (1.0 - y * y).sqrt();
            let turn = golden * i as f32;
            let dir = Vec3::new(ring * turn.cos(), y, ring * turn.sin());
            let height = sigma * ((0..12).map(|_| uniform()).sum::<f32>() - 6.0);
            if dir.x >= 0.0 || i % sparse_every == 0 {
                points.push(dir * (50.0 + height));
            }
        }
        let on_sphere = points.len();
        for _ in 0..strays {
            points.push(Vec3::new(uniform(), uniform(), uniform()) * 140.0 - Vec3::splat(70.0));
        }
        (points, on_sphere)
    }

    #[test]
    fn a_side_sampled_at_a_tenth_of_the_density_is_kept_and_strays_are_not() {
        let (points, on_sphere) = sparse_sided_sphere(40_000, 0.1, 10, 1_100);
        let c = screen(&points, 140.0, None);
        let sparse: Vec<usize> = (0..on_sphere).filter(|&i| points[i].x < 0.0).collect();
        let kept_sparse = sparse.iter().filter(|&&i| c.confidence[i] > 0.0).count();
        // Its points have a tenth of the typical count within the radius, under the
        // isolated fraction: by the count alone most were dropped.
        assert!(
            kept_sparse * 100 >= sparse.len() * 95,
            "{kept_sparse} of the sparse side's {} kept ({} isolated, {} far in all)",
            sparse.len(),
            c.isolated,
            c.far
        );
        let dense_kept = (0..on_sphere)
            .filter(|&i| points[i].x >= 0.0 && c.confidence[i] > 0.0)
            .count();
        assert!(dense_kept * 100 >= (on_sphere - sparse.len()) * 99);
        // A stray kept lies within a few noise levels of the sphere: none is kept in
        // empty space, where it would be signed as a blob of its own.
        let kept_strays: Vec<f32> = (on_sphere..points.len())
            .filter(|&i| c.confidence[i] > 0.0)
            .map(|i| (points[i].length() - 50.0).abs())
            .collect();
        assert!(kept_strays.iter().all(|&d| d < 1.0), "{kept_strays:?}");
        assert!(kept_strays.len() <= 10, "{} strays kept", kept_strays.len());
    }

    #[test]
    fn strays_alone_are_not_taken_for_a_sparse_surface() {
        // A twentieth of the points in a ball of strays around a dense sphere: the count
        // finds them isolated and the nearest-neighbour planes must not bring them back.
        let (points, on_sphere) = sparse_sided_sphere(20_000, 0.1, 1, 1_000);
        let c = screen(&points, 140.0, None);
        let far_kept = (on_sphere..points.len())
            .filter(|&i| c.confidence[i] > 0.0 && (points[i].length() - 50.0).abs() > 1.0)
            .count();
        assert_eq!(far_kept, 0);
        assert!(c.isolated + c.far >= 900, "{} + {}", c.isolated, c.far);
    }

    /// The robust plane as it was fitted before [`needs_refit`]: the median found by
    /// selection for every plane.
    fn plane_by_selected_median(near: &[Vec3]) -> Option<Plane> {
        let first = principal_plane(near)?;
        let mut off: Vec<f32> = near
            .iter()
            .map(|&q| (q - first.centre).dot(first.normal).abs())
            .collect();
        let mid = off.len() / 2;
        let keep = inlier_bound(*off.select_nth_unstable_by(mid, f32::total_cmp).1);
        if off[mid..].iter().all(|&d| d <= keep) {
            return Some(first);
        }
        let inliers: Vec<Vec3> = near
            .iter()
            .copied()
            .filter(|&q| (q - first.centre).dot(first.normal).abs() <= keep)
            .collect();
        let refit = principal_plane(&inliers).unwrap_or(first);
        Some(Plane {
            neighbours: near.len(),
            ..refit
        })
    }

    #[test]
    fn the_refit_is_decided_as_by_the_selected_median() {
        // Neighbourhoods of 3 to 60 points on a tilted, curved, noisy patch, some with strays
        // off it, some flat to the last bit (every distance 0), some with repeated points.
        let mut seed = 0x9e37_79b9_7f4a_7c15_u64;
        let mut uniform = || {
            seed = seed
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (seed >> 40) as f32 / (1u64 << 24) as f32
        };
        let (mut refitted, mut kept) = (0, 0);
        let (mut off, mut inliers) = (Vec::new(), Vec::new());
        for case in 0..4000 {
            let count = 3 + case % 58;
            let noise = [0.0, 0.001, 0.02, 0.1][case % 4];
            let bend = [0.0, 0.3][(case / 4) % 2];
            let mut near: Vec<Vec3> = (0..count)
                .map(|_| {
                    let (u, v) = (uniform() * 2.0 - 1.0, uniform() * 2.0 - 1.0);
                    let h = bend * u * u + noise * (uniform() - 0.5);
                    Vec3::new(u, v + 0.5 * h, h + 0.2 * u)
                })
                .collect();
            for _ in 0..(case / 8) % 4 {
                let at = (uniform() * count as f32) as usize % count;
                near[at].z += 0.5 + uniform();
            }
            if case % 7 == 0 {
                let copy = near[0];
                near[count / 2] = copy;
            }
            let plane = plane_of(&near, &mut off, &mut inliers);
            let reference = plane_by_selected_median(&near);
            match (plane, reference) {
                (Some(a), Some(b)) => {
                    assert_eq!(a.centre, b.centre, "case {case}");
                    assert_eq!(a.normal, b.normal, "case {case}");
                    assert_eq!(a.rms.to_bits(), b.rms.to_bits(), "case {case}");
                    assert_eq!(a.neighbours, b.neighbours, "case {case}");
                }
                (None, None) => {}
                _ => panic!("case {case}: one plane and not the other"),
            }
            let first = principal_plane(&near).unwrap();
            let distances: Vec<f32> = near
                .iter()
                .map(|&q| (q - first.centre).dot(first.normal).abs())
                .collect();
            if needs_refit(&distances) {
                refitted += 1;
            } else {
                kept += 1;
            }
        }
        // Both outcomes are exercised.
        assert!(
            refitted > 500 && kept > 500,
            "{refitted} refitted, {kept} kept"
        );
    }

    #[test]
    fn a_point_with_too_few_others_within_two_spacings_is_isolated() {
        // A 20² square at unit spacing, and a pair of points a unit apart five units over it.
        // The radius holds 12 points of the surface's disc, so the spacing reads 1 and two
        // spacings are 2: every point of the square (a corner has 5 others within 2) keeps
        // its plane, and each of the pair, with one other, is isolated.
        let mut points = noisy_square(20, 0.0);
        let square = points.len();
        points.extend([Vec3::new(9.5, 9.5, 5.0), Vec3::new(10.5, 9.5, 5.0)]);
        let plane = || Plane {
            centre: Vec3::ZERO,
            normal: Vec3::Z,
            rms: 0.0,
            neighbours: 12,
        };
        let mut planes: Vec<_> = points.iter().map(|_| Some((plane(), 0.0))).collect();
        let radius = (12.0 / std::f32::consts::PI).sqrt();
        isolate_lone_points(&points, &mut planes, radius, 12);
        assert!(planes[..square].iter().all(Option::is_some));
        assert!(planes[square..].iter().all(Option::is_none));
    }

    #[test]
    fn a_clean_cloud_sparser_than_the_spacing_grid_keeps_its_points() {
        // 1 000 points spread evenly over a sphere of radius 50 (about 5.6 apart), noise 0.25,
        // in a box of 140: the spacing's grid reads 2.2, the radius first holds a few points,
        // and planes through so few dropped 289 of them. Over the widened radius every
        // point but a few is kept, and the strays spread over the box off it are dropped.
        let (points, on_sphere) = sparse_sided_sphere(1000, 0.25, 1, 20);
        assert!(sparser_than_the_spacing_grid(&points, 140.0));
        let c = screen(&points, 140.0, None);
        let kept = c.confidence[..on_sphere]
            .iter()
            .filter(|&&w| w > 0.0)
            .count();
        assert!(kept >= 990, "{kept} of {on_sphere} kept");
        // Within about a spacing of the sphere a stray is hidden by the sag of the widened
        // planes' caps (see `curvature_floor`); the others go.
        for (p, w) in points.iter().zip(&c.confidence).skip(on_sphere) {
            let off = (p.length() - 50.0).abs();
            assert!(off < 5.0 || *w == 0.0, "a stray {off} off the sphere kept");
        }
    }

    #[test]
    fn a_cloud_sparser_than_the_spacing_grid_is_told_apart_and_reads_short() {
        // 40² points at unit spacing, 39 across: the grid's cubes are 0.61 wide, so each
        // point is alone in its cube and the spacing reads as a cube's side.
        let sparse = noisy_square(40, 0.0);
        assert!(sparser_than_the_spacing_grid(&sparse, 39.0));
        let read = typical_spacing(&sparse, 39.0);
        assert!(
            (read - 39.0 / SPACING_CUBES_PER_SIDE).abs() < 0.01,
            "{read}"
        );
        // 200² points, 199 across: about 9.7 in each 3.1-wide cube, and the spacing reads
        // true.
        let dense = noisy_square(200, 0.0);
        assert!(!sparser_than_the_spacing_grid(&dense, 199.0));
        let read = typical_spacing(&dense, 199.0);
        assert!((read - 1.0).abs() < 0.05, "{read}");
    }

    #[test]
    fn the_occupied_cubes_are_the_grids_occupied_cells() {
        for (points, cell) in [
            (noisy_square(60, 0.3), 1.7),
            (noisy_square(40, 0.05), 0.4),
            (noisy_square(30, 2.0), 6.0),
            (vec![Vec3::ONE; 5], 1.0),
            (Vec::new(), 1.0),
        ] {
            let grid = PointGrid::new(&points, |_| true, cell, 1);
            assert_eq!(occupied_cubes(&points, cell), grid.occupied());
        }
    }
}
