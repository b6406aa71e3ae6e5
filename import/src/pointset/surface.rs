//! The point-set surface (Guo & Qin §3): points with position, normal and colour, each with
//! its local B-spline field ([`LocalField`]), and the global field of eq. (5) that blends them.
//!
//! Construction, in order (each stage timed in [`BuildTimes`]):
//! 1. a k-d tree of the points (`kiddo`) and each point's `k` nearest neighbours;
//! 2. normals from the neighbours' least-squares planes, oriented over a minimal spanning
//!    tree ([`super::normals`]), unless the cloud brings its own;
//! 3. each point's local field, fitted by weighted least squares to its neighbours and two
//!    off-surface points each ([`super::local::fit_local`]); the fits run on all cores.
//!
//! Eq. (5): `s(x) = Σ sᵢ(x) φᵢ(x) / Σ φᵢ(x)` with the Wendland weight
//! `φᵢ = (1 − t)⁴ (4t + 1)`, `t = ‖x − cᵢ‖ / ρᵢ`, compactly supported in the ball of radius
//! `ρᵢ` (the local cube's half edge) around the domain's centre, so the support never leaves
//! the local domain, as §3 asks. Where the weights thin out (less than [`FALLBACK_WEIGHT`]
//! in all) the nearest point's signed distance (§4: "its distance to the nearest point",
//! signed by that point's normal) is blended in with the missing weight, so the field is
//! continuous everywhere and keeps its sign far from the surface.
//!
//! Choices: `k` = 10 neighbours; the off-surface offset is half the local half edge; the
//! spacing `h` of the Gaussian `θ(d) = exp(−d²/h²)` is the mean nearest-neighbour distance.

use std::num::NonZero;
use std::sync::Arc;
use std::time::Instant;

use glam::Vec3;
use kiddo::{ImmutableKdTree, SquaredEuclidean};

use super::error::PointSetError;
use super::local::{FitSample, FitScratch, LocalField, fit_local};
use super::normals::{orient_over_mst, plane_normal};
use crate::fit::PointCloud;
use dynaclay_core::field::ImplicitField;
use dynaclay_core::mesh::ScalarField;

/// Below this total blending weight the nearest point's signed distance fills in.
pub const FALLBACK_WEIGHT: f32 = 1e-2;
/// The colour of a point whose file gave none.
pub const DEFAULT_COLOUR: [u8; 3] = [200, 200, 200];

/// How a point-set surface is built.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointSetOptions {
    /// Neighbours per point for the normal, the local domain and the fit (`k`).
    pub neighbours: usize,
    /// Off-surface offset as a fraction of the local half edge.
    pub off_surface: f32,
    /// Ridge toward the tangent plane, relative to the total sample weight.
    pub ridge: f32,
    /// Local half edge as a multiple of the distance to the farthest of the `k` neighbours.
    pub domain_scale: f32,
    /// Threads for the fits (0: all cores).
    pub threads: usize,
}

impl Default for PointSetOptions {
    fn default() -> Self {
        Self {
            neighbours: 10,
            off_surface: 0.5,
            ridge: 1e-3,
            domain_scale: 1.0,
            threads: 0,
        }
    }
}

/// Time spent in each stage of [`PointSet::build`], nanoseconds.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BuildTimes {
    pub neighbours_ns: u64,
    pub normals_ns: u64,
    pub orient_ns: u64,
    pub fit_ns: u64,
}

impl BuildTimes {
    /// All stages together.
    #[must_use]
    pub fn total_ns(&self) -> u64 {
        self.neighbours_ns + self.normals_ns + self.orient_ns + self.fit_ns
    }
}

/// A k-d tree over the local domains' centres, for evaluating eq. (5).
#[derive(Clone, Debug, Default)]
struct CentreIndex {
    /// Shared, so a clone of the point set shares the tree until either reindexes.
    tree: Option<Arc<ImmutableKdTree<f32, 3>>>,
    /// The largest support radius.
    reach_fu: f32,
}

/// A point-set surface: points, their normals and colours, and a local field per point.
#[derive(Clone, Debug, Default)]
pub struct PointSet {
    /// Positions, world units.
    pub points: Vec<Vec3>,
    /// Unit outward normals.
    pub normals: Vec<Vec3>,
    /// RGB colours.
    pub colours: Vec<[u8; 3]>,
    /// One local field per point.
    pub fields: Vec<LocalField>,
    /// The sampling spacing `h` (mean nearest-neighbour distance at construction).
    pub spacing_fu: f32,
    index: CentreIndex,
}

fn as_array(v: Vec3) -> [f32; 3] {
    [v.x, v.y, v.z]
}

fn thread_count(requested: usize, work: usize) -> usize {
    let all = std::thread::available_parallelism().map_or(1, NonZero::get);
    let t = if requested == 0 { all } else { requested };
    t.clamp(1, (work / 256).max(1))
}

/// Runs `job(first, chunk)` over `out` split into `threads` contiguous chunks, each a whole
/// number of `unit`s long.
fn par_chunks<T: Send>(
    out: &mut [T],
    unit: usize,
    threads: usize,
    job: impl Fn(usize, &mut [T]) + Sync,
) {
    if threads <= 1 || out.len() < 2 * unit {
        job(0, out);
        return;
    }
    let size = out.len().div_ceil(unit).div_ceil(threads) * unit;
    std::thread::scope(|s| {
        for (c, chunk) in out.chunks_mut(size).enumerate() {
            let job = &job;
            s.spawn(move || job(c * size, chunk));
        }
    });
}

/// The `k` nearest other points of every point (flat, `k` per point), nearest first.
///
/// # Errors
/// [`PointSetError::Index`] when the tree cannot be built.
pub fn nearest_neighbours(
    points: &[Vec3],
    k: usize,
    threads: usize,
) -> Result<Vec<u32>, PointSetError> {
    let arr: Vec<[f32; 3]> = points.iter().map(|&p| as_array(p)).collect();
    let tree: ImmutableKdTree<f32, 3> = ImmutableKdTree::new_from_slice(&arr)
        .map_err(|e| PointSetError::Index(format!("{e:?}")))?;
    let mut out = vec![0u32; points.len() * k];
    let want = NonZero::new(k + 1).unwrap_or(NonZero::<usize>::MIN);
    par_chunks(&mut out, k, threads, |first, chunk| {
        let first_point = first / k;
        for (n, slot) in chunk.chunks_mut(k).enumerate() {
            let i = first_point + n;
            let found = tree
                .query(&arr[i])
                .nearest_n::<SquaredEuclidean<f32>>(want)
                .execute();
            let mut w = 0;
            for r in &found {
                if r.item as usize != i && w < k {
                    slot[w] = r.item;
                    w += 1;
                }
            }
            // Duplicates of the point itself can crowd it out of its own list: pad.
            while w < k {
                slot[w] = found.get(w).map_or(i as u32, |r| r.item);
                w += 1;
            }
        }
    });
    Ok(out)
}

impl PointSet {
    /// Builds the surface of a cloud: normals (estimated and oriented when the cloud has
    /// none) and a local field per point. Colours default to [`DEFAULT_COLOUR`].
    ///
    /// # Errors
    /// Too few points, a non-finite coordinate, or a local fit that fails.
    pub fn build(
        cloud: &PointCloud,
        options: &PointSetOptions,
    ) -> Result<(Self, BuildTimes), PointSetError> {
        let k = options.neighbours.max(3);
        let points = &cloud.points;
        if points.len() < k + 1 {
            return Err(PointSetError::TooFewPoints {
                got: points.len(),
                need: k + 1,
            });
        }
        if let Some(i) = points.iter().position(|p| !p.is_finite()) {
            return Err(PointSetError::NotFinite { index: i });
        }
        let threads = thread_count(options.threads, points.len());
        let mut times = BuildTimes::default();

        let t = Instant::now();
        let nbrs = nearest_neighbours(points, k, threads)?;
        times.neighbours_ns = t.elapsed().as_nanos() as u64;
        let nearest: f64 = (0..points.len())
            .map(|i| f64::from((points[nbrs[i * k] as usize] - points[i]).length()))
            .sum();
        let spacing_fu = (nearest / points.len() as f64) as f32;
        if !(spacing_fu.is_finite() && spacing_fu > 0.0) {
            return Err(PointSetError::Degenerate);
        }

        let t = Instant::now();
        let normals = match &cloud.normals {
            Some(given) if given.len() == points.len() => given
                .iter()
                .map(|n| n.try_normalize().unwrap_or(Vec3::Z))
                .collect(),
            _ => {
                let mut normals = vec![Vec3::Z; points.len()];
                par_chunks(&mut normals, 1, threads, |first, chunk| {
                    for (n, slot) in chunk.iter_mut().enumerate() {
                        let i = first + n;
                        let around = std::iter::once(i as u32)
                            .chain(nbrs[i * k..(i + 1) * k].iter().copied())
                            .map(|j| points[j as usize]);
                        *slot = plane_normal(around).unwrap_or(Vec3::Z);
                    }
                });
                times.normals_ns = t.elapsed().as_nanos() as u64;
                let t = Instant::now();
                orient_over_mst(points, &mut normals, &nbrs, k);
                times.orient_ns = t.elapsed().as_nanos() as u64;
                normals
            }
        };

        let t = Instant::now();
        let mut fields = vec![LocalField::zero(Vec3::ZERO, 1.0); points.len()];
        let failed = std::sync::atomic::AtomicUsize::new(usize::MAX);
        par_chunks(&mut fields, 1, threads, |first, chunk| {
            let mut scratch = FitScratch::default();
            let mut samples = Vec::with_capacity(3 * (k + 1));
            for (n, slot) in chunk.iter_mut().enumerate() {
                let i = first + n;
                let list = &nbrs[i * k..(i + 1) * k];
                match fit_point(
                    i,
                    list,
                    points,
                    &normals,
                    spacing_fu,
                    options,
                    &mut samples,
                    &mut scratch,
                ) {
                    Some(f) => *slot = f,
                    None => {
                        failed.fetch_min(i, std::sync::atomic::Ordering::Relaxed);
                    }
                }
            }
        });
        let failed = failed.into_inner();
        if failed != usize::MAX {
            return Err(PointSetError::FitFailed { index: failed });
        }
        times.fit_ns = t.elapsed().as_nanos() as u64;

        let mut set = Self {
            points: points.clone(),
            normals,
            colours: vec![DEFAULT_COLOUR; points.len()],
            fields,
            spacing_fu,
            index: CentreIndex::default(),
        };
        set.reindex()?;
        Ok((set, times))
    }

    /// A point set from parts already made (points, normals, colours, fields); builds the
    /// index.
    ///
    /// # Errors
    /// When the lengths differ or the index cannot be built.
    pub fn from_parts(
        points: Vec<Vec3>,
        normals: Vec<Vec3>,
        colours: Vec<[u8; 3]>,
        fields: Vec<LocalField>,
        spacing_fu: f32,
    ) -> Result<Self, PointSetError> {
        let n = points.len();
        if normals.len() != n || colours.len() != n || fields.len() != n {
            return Err(PointSetError::LengthMismatch);
        }
        let mut set = Self {
            points,
            normals,
            colours,
            fields,
            spacing_fu,
            index: CentreIndex::default(),
        };
        set.reindex()?;
        Ok(set)
    }

    /// Number of points.
    #[must_use]
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Whether there are no points.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Rebuilds the index of local domains after points were added, removed or recentred.
    ///
    /// # Errors
    /// [`PointSetError::Index`] when the tree cannot be built.
    pub fn reindex(&mut self) -> Result<(), PointSetError> {
        if self.fields.is_empty() {
            self.index = CentreIndex::default();
            return Ok(());
        }
        let centres: Vec<[f32; 3]> = self.fields.iter().map(|f| as_array(f.centre)).collect();
        let tree = ImmutableKdTree::new_from_slice(&centres)
            .map_err(|e| PointSetError::Index(format!("{e:?}")))?;
        self.index = CentreIndex {
            tree: Some(Arc::new(tree)),
            reach_fu: self.fields.iter().map(|f| f.half_fu).fold(0.0, f32::max),
        };
        Ok(())
    }

    /// The axis-aligned box around every local domain.
    #[must_use]
    pub fn bounds(&self) -> (Vec3, Vec3) {
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        for f in &self.fields {
            lo = lo.min(f.centre - Vec3::splat(f.half_fu));
            hi = hi.max(f.centre + Vec3::splat(f.half_fu));
        }
        (lo, hi)
    }

    /// Eq. (5): the blended value and gradient at `x`.
    #[must_use]
    pub fn blend(&self, x: Vec3) -> (f32, Vec3) {
        let Some(tree) = &self.index.tree else {
            return (-1.0, Vec3::ZERO);
        };
        let q = as_array(x);
        let reach = self.index.reach_fu;
        let found = tree
            .query(&q)
            .within::<SquaredEuclidean<f32>>(reach * reach)
            .unsorted()
            .execute();
        let (mut sw, mut swv) = (0.0f32, 0.0f32);
        let (mut gw, mut gwv) = (Vec3::ZERO, Vec3::ZERO);
        for r in &found {
            let f = &self.fields[r.item as usize];
            let d = x - f.centre;
            let dist = r.distance.sqrt();
            let t = dist / f.half_fu;
            if t >= 1.0 {
                continue;
            }
            let om = 1.0 - t;
            let w = om * om * om * om * (4.0 * t + 1.0);
            // dφ/dt = −20 t (1 − t)³.
            let dw = -20.0 * t * om * om * om;
            let gw_i = if dist > 0.0 {
                d * (dw / (dist * f.half_fu))
            } else {
                Vec3::ZERO
            };
            let (s, g) = f.value_and_gradient(x);
            sw += w;
            swv += w * s;
            gw += gw_i;
            gwv += g * w + gw_i * s;
        }
        if sw < FALLBACK_WEIGHT {
            let near = tree
                .query(&q)
                .nearest_one::<SquaredEuclidean<f32>>()
                .execute();
            let i = near.item as usize;
            let (fs, fg) = self.nearest_distance(i.min(self.points.len() - 1), x);
            let wf = FALLBACK_WEIGHT - sw;
            // d(wf)/dx = −∇sw.
            let total = sw + wf;
            let value = (swv + wf * fs) / total;
            let grad = (gwv + fg * wf - gw * fs) / total;
            return (value, grad);
        }
        let value = swv / sw;
        (value, (gwv - gw * value) / sw)
    }

    /// The signed distance to point `i` (positive on the inner side of its normal) and its
    /// gradient.
    fn nearest_distance(&self, i: usize, x: Vec3) -> (f32, Vec3) {
        let d = x - self.points[i];
        let len = d.length();
        if len <= 0.0 {
            return (0.0, -self.normals[i]);
        }
        let sign = if self.normals[i].dot(d) > 0.0 {
            -1.0
        } else {
            1.0
        };
        (sign * len, d * (sign / len))
    }
}

/// Fits point `i`'s local field (eq. 2's weighted least squares).
#[allow(clippy::too_many_arguments)]
pub(crate) fn fit_point(
    i: usize,
    neighbours: &[u32],
    points: &[Vec3],
    normals: &[Vec3],
    spacing_fu: f32,
    options: &PointSetOptions,
    samples: &mut Vec<FitSample>,
    scratch: &mut FitScratch,
) -> Option<LocalField> {
    let p = points[i];
    let far = neighbours
        .iter()
        .map(|&j| (points[j as usize] - p).length())
        .fold(0.0f32, f32::max);
    let half = (far * options.domain_scale).max(spacing_fu);
    let eps = options.off_surface * half;
    let inv_h2 = 1.0 / (spacing_fu * spacing_fu);
    samples.clear();
    for j in std::iter::once(i as u32).chain(neighbours.iter().copied()) {
        let (pj, nj) = (points[j as usize], normals[j as usize]);
        let w = (-(pj - p).length_squared() * inv_h2).exp();
        samples.push(FitSample {
            position: pj,
            distance: 0.0,
            weight: w,
        });
        samples.push(FitSample {
            position: pj + eps * nj,
            distance: -eps,
            weight: w,
        });
        samples.push(FitSample {
            position: pj - eps * nj,
            distance: eps,
            weight: w,
        });
    }
    fit_local(p, half, p, normals[i], samples, options.ridge, scratch)
}

impl ImplicitField for PointSet {
    fn iso(&self) -> f32 {
        0.0
    }

    fn value(&self, p: Vec3) -> f32 {
        self.blend(p).0
    }

    fn value_and_gradient(&self, p: Vec3) -> (f32, Vec3) {
        self.blend(p)
    }
}

/// Meshed by per-sample queries (the trait's default block sampling).
impl ScalarField for PointSet {}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A Fibonacci sphere of `count` points, no normals.
    pub(crate) fn sphere_cloud(centre: Vec3, radius: f32, count: usize) -> PointCloud {
        let points = (0..count)
            .map(|i| {
                let z = 1.0 - 2.0 * (i as f32 + 0.5) / count as f32;
                let r = (1.0 - z * z).sqrt();
                let a = i as f32 * 2.399_963;
                centre + radius * Vec3::new(r * a.cos(), r * a.sin(), z)
            })
            .collect();
        PointCloud {
            points,
            normals: None,
        }
    }

    #[test]
    fn a_sphere_cloud_gives_outward_normals_and_a_distance_field() {
        let c = Vec3::new(0.1, -0.2, 0.3);
        let cloud = sphere_cloud(c, 0.5, 1500);
        let (set, _) = PointSet::build(&cloud, &PointSetOptions::default()).unwrap();
        for (p, n) in set.points.iter().zip(&set.normals) {
            assert!((*p - c).normalize().dot(*n) > 0.95, "normal {n} at {p}");
        }
        // On the surface, inside and just outside.
        for dir in [Vec3::X, Vec3::new(0.3, 0.5, -0.8).normalize(), -Vec3::Z] {
            let on = set.value(c + 0.5 * dir);
            assert!(on.abs() < 0.01, "on-surface value {on}");
            let inside = set.value(c + 0.45 * dir);
            assert!((inside - 0.05).abs() < 0.015, "inside value {inside}");
            let outside = set.value(c + 0.55 * dir);
            assert!((outside + 0.05).abs() < 0.015, "outside value {outside}");
            let (_, g) = set.value_and_gradient(c + 0.5 * dir);
            assert!((-g.normalize()).dot(dir) > 0.98, "gradient {g}");
        }
        // Far away: signed by the nearest point.
        assert!(set.value(c) > 0.0);
        assert!(set.value(c + Vec3::splat(2.0)) < 0.0);
    }

    #[test]
    fn blended_gradient_matches_finite_differences() {
        let cloud = sphere_cloud(Vec3::ZERO, 0.5, 800);
        let (set, _) = PointSet::build(&cloud, &PointSetOptions::default()).unwrap();
        let x = Vec3::new(0.31, 0.22, 0.3);
        let (_, g) = set.value_and_gradient(x);
        let e = 1e-3;
        let fd = Vec3::new(
            set.value(x + Vec3::X * e) - set.value(x - Vec3::X * e),
            set.value(x + Vec3::Y * e) - set.value(x - Vec3::Y * e),
            set.value(x + Vec3::Z * e) - set.value(x - Vec3::Z * e),
        ) / (2.0 * e);
        assert!(
            (g - fd).length() < 0.05 * fd.length().max(1.0),
            "{g} vs {fd}"
        );
    }

    /// The neighbour lists, normals and fits split over threads give the very same surface as
    /// one thread: each point's work reads only shared inputs and writes only its own slot.
    #[test]
    fn threads_build_the_same_surface_bit_for_bit() {
        let cloud = sphere_cloud(Vec3::ZERO, 0.5, 3000);
        let one = PointSetOptions {
            threads: 1,
            ..PointSetOptions::default()
        };
        let (a, _) = PointSet::build(&cloud, &one).unwrap();
        for threads in [2, 3] {
            let (b, _) = PointSet::build(&cloud, &PointSetOptions { threads, ..one }).unwrap();
            assert_eq!(a.spacing_fu.to_bits(), b.spacing_fu.to_bits());
            assert_eq!(a.normals, b.normals, "{threads} threads");
            assert_eq!(a.fields, b.fields, "{threads} threads");
        }
        assert_eq!(
            nearest_neighbours(&cloud.points, 10, 1).unwrap(),
            nearest_neighbours(&cloud.points, 10, 2).unwrap()
        );
    }

    #[test]
    fn too_few_points_are_refused() {
        let cloud = sphere_cloud(Vec3::ZERO, 1.0, 5);
        assert!(matches!(
            PointSet::build(&cloud, &PointSetOptions::default()),
            Err(PointSetError::TooFewPoints { .. })
        ));
    }
}
