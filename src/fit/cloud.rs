//! A clay fitted to a point cloud, on one lattice.
//!
//! 1. **Placement.** The cloud is scaled and centred so that its longest side spans the
//!    lattice less a margin of [`MARGIN_SPANS`] knot spans on each side (room for the density
//!    transition and the B-spline support); [`CloudFit::to_field`] maps file units to field
//!    units.
//! 2. **Distance.** On the fit's sample grid (`samples_per_span` points per knot span, the
//!    grid `fit_lattice` samples), every node within [`BAND_SPANS`] spans of a point gets its
//!    distance to the nearest point (each point visits the nodes around it: no search
//!    structure, `O(points · band nodes)`).
//! 3. **Sign.** Nodes farther than the gap `τ` from every point are flooded from the grid's
//!    boundary: the exterior, as in the tagging of Zhao, Osher & Fedkiw (2001). Gaps in the
//!    cloud narrower than `2τ` are closed; wider holes let the flood in. Each point needs an
//!    outward normal: the file's, or else the direction of least variance of its neighbours
//!    (principal components) turned toward the exterior (the side nearer the flooded region).
//!    A band node's signed distance is its distance to its nearest point's tangent plane,
//!    smooth across the surface (the distance to the nearest point alone would dimple between
//!    points); beyond the band, flooded nodes are outside and the rest inside.
//! 4. **Fit.** The signed distances become the clay's density profile
//!    (`clamp(0.5 − d / width, 0, 1)`, the profile the starting clays use), and the lattice is
//!    fitted to it by least squares with the Kronecker machinery (`field::fit_lattice`).
//!
//! Hua & Qin fit an octree of patches (§5) and Guo & Qin sign two off-surface samples per
//! point; this module fits one level on a densely signed grid. The hierarchical refinement
//! is not here yet.

use std::collections::VecDeque;

use glam::Vec3;

use super::points::PointCloud;
use crate::field::{BSplineLattice, FitError, density_profile, fit_lattice};

/// Empty knot spans kept around the object on each side.
pub const MARGIN_SPANS: f32 = 4.0;
/// How far from a point distances are computed, knot spans.
pub const BAND_SPANS: f32 = 2.0;
/// The gap the sign tagging closes by default, knot spans (holes narrower than twice this).
pub const DEFAULT_GAP_SPANS: f32 = 1.5;

/// How to fit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CloudFitOptions {
    /// Coefficients per axis of the (cubic) lattice.
    pub resolution: usize,
    /// Knot spacing, field units.
    pub spacing: f32,
    /// Samples per knot span of the fit (and of the signing grid).
    pub samples_per_span: usize,
    /// The gap `τ` of the sign tagging, knot spans.
    pub gap_spans: f32,
}

impl Default for CloudFitOptions {
    fn default() -> Self {
        Self {
            resolution: 32,
            spacing: crate::engine::CLAY_SPACING,
            samples_per_span: 2,
            gap_spans: DEFAULT_GAP_SPANS,
        }
    }
}

/// A fitted clay and where the cloud went.
#[derive(Clone, Debug)]
pub struct CloudFit {
    /// The fitted lattice (iso-level 0.5).
    pub lattice: BSplineLattice,
    /// Field units per file unit.
    pub scale: f32,
    /// Field position of the file's origin: `field = file · scale + offset`.
    pub offset: Vec3,
    /// How the signs were found.
    pub signed_by: SignedBy,
}

impl CloudFit {
    /// A file-unit point in field units.
    #[must_use]
    pub fn to_field(&self, p: Vec3) -> Vec3 {
        p * self.scale + self.offset
    }
}

/// Where the inside/outside decision came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SignedBy {
    /// The cloud's oriented normals.
    Normals,
    /// Flood tagging from the grid's boundary.
    Tagging,
}

/// Why a cloud could not be fitted.
#[derive(Debug, thiserror::Error)]
pub enum CloudFitError {
    /// The options are out of range.
    #[error("{0}")]
    Options(String),
    /// All points coincide: nothing to fit.
    #[error("the points all lie at one place; a cloud needs extent")]
    Degenerate,
    /// The least-squares fit failed.
    #[error("fit: {0}")]
    Fit(#[from] FitError),
}

/// Fits a clay to `cloud` (see the module docs).
///
/// # Errors
/// [`CloudFitError`] for bad options, a cloud without extent, or a failed fit.
pub fn fit_point_cloud(
    cloud: &PointCloud,
    options: &CloudFitOptions,
) -> Result<CloudFit, CloudFitError> {
    let n = options.resolution;
    let sps = options.samples_per_span;
    if !(12..=256).contains(&n) {
        return Err(CloudFitError::Options(format!(
            "resolution {n}: must be 12 to 256 coefficients"
        )));
    }
    if !(1..=4).contains(&sps) {
        return Err(CloudFitError::Options(format!(
            "samples per span {sps}: must be 1 to 4"
        )));
    }
    if !(options.gap_spans > 0.0 && options.gap_spans < BAND_SPANS) {
        return Err(CloudFitError::Options(format!(
            "gap {} spans: must be above 0 and below the band's {BAND_SPANS}",
            options.gap_spans
        )));
    }
    let spacing = options.spacing;
    let (lo, hi) = cloud
        .points
        .iter()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(a, b), &p| {
            (a.min(p), b.max(p))
        });
    let extent = (hi - lo).max_element();
    if !extent.is_finite() || extent <= 0.0 {
        return Err(CloudFitError::Degenerate);
    }
    let span_total = (n - 1) as f32 - 2.0 * MARGIN_SPANS;
    let scale = span_total * spacing / extent;
    let centre_field = Vec3::splat((n - 1) as f32 * spacing * 0.5);
    let offset = centre_field - (lo + hi) * 0.5 * scale;
    let points: Vec<Vec3> = cloud.points.iter().map(|&p| p * scale + offset).collect();

    let grid = SignGrid::new(n, spacing, sps);
    let (dist, nearest) = grid.band_distances(&points, BAND_SPANS * spacing);
    let gap = options.gap_spans * spacing;
    let exterior = grid.flood_exterior(&dist, gap);
    let given = cloud
        .normals
        .as_ref()
        .filter(|ns| ns.len() == points.len() && ns.iter().all(|n| *n != Vec3::ZERO));
    let to_exterior = grid.distance_to(&exterior);
    let (normals, signed_by) = match given {
        Some(ns) => (ns.clone(), SignedBy::Normals),
        None => {
            // Each point's normal: the least-variance direction of its neighbours within the
            // band, turned toward the flooded exterior.
            let side = |p: Vec3, n: Vec3| {
                let probe = 2.0 * grid.h;
                to_exterior[grid.nearest_node(p - n * probe)]
                    - to_exterior[grid.nearest_node(p + n * probe)]
            };
            (
                estimate_normals(&points, BAND_SPANS * spacing, side),
                SignedBy::Tagging,
            )
        }
    };
    let width = 2.0 * spacing;
    let far = 2.0 * width;
    // Signed distance, positive outside: in the band, the distance from the node to its
    // nearest point's tangent plane (smooth across the surface, where the distance to the
    // nearest point would dimple between points); beyond it, the flood's verdict.
    let density: Vec<f32> = (0..grid.count())
        .map(|i| {
            let signed = if dist[i].is_finite() {
                let p = nearest[i] as usize;
                (grid.position(i) - points[p]).dot(normals[p])
            } else if exterior[i] {
                far
            } else {
                -far
            };
            density_profile(signed, width)
        })
        .collect();

    let mut lattice = BSplineLattice::zeros([n; 3], spacing, Vec3::ZERO).map_err(|_| {
        CloudFitError::Options(format!("a {n}³ lattice at spacing {spacing} is not valid"))
    })?;
    fit_lattice(&mut lattice, sps, |x| density[grid.nearest_node(x)])?;
    Ok(CloudFit {
        lattice,
        scale,
        offset,
        signed_by,
    })
}

/// The signing grid: the fit's sample grid over the whole lattice.
struct SignGrid {
    dims: [usize; 3],
    /// Node spacing, field units.
    h: f32,
}

impl SignGrid {
    fn new(resolution: usize, spacing: f32, samples_per_span: usize) -> Self {
        let m = (resolution - 1) * samples_per_span + 1;
        Self {
            dims: [m; 3],
            h: spacing / samples_per_span as f32,
        }
    }

    fn count(&self) -> usize {
        self.dims.iter().product()
    }

    fn index(&self, i: usize, j: usize, k: usize) -> usize {
        i + self.dims[0] * (j + self.dims[1] * k)
    }

    fn coords(&self, index: usize) -> [usize; 3] {
        let [mx, my, _] = self.dims;
        [index % mx, (index / mx) % my, index / (mx * my)]
    }

    fn position(&self, index: usize) -> Vec3 {
        let [i, j, k] = self.coords(index);
        Vec3::new(i as f32, j as f32, k as f32) * self.h
    }

    /// The node at (or nearest to) field point `x`: the fit samples exactly at the nodes.
    fn nearest_node(&self, x: Vec3) -> usize {
        let c = |a: usize| ((x[a] / self.h).round().max(0.0) as usize).min(self.dims[a] - 1);
        self.index(c(0), c(1), c(2))
    }

    /// Distance from each node within `band` of a point to its nearest point (infinite
    /// elsewhere), and that point's index.
    fn band_distances(&self, points: &[Vec3], band: f32) -> (Vec<f32>, Vec<u32>) {
        let mut dist = vec![f32::INFINITY; self.count()];
        let mut nearest = vec![0u32; self.count()];
        let reach = (band / self.h).ceil() as i64;
        for (p_index, &p) in points.iter().enumerate() {
            let c = (p / self.h).round();
            let lo = |a: usize| (c[a] as i64 - reach).max(0) as usize;
            let hi = |a: usize| ((c[a] as i64 + reach).max(0) as usize).min(self.dims[a] - 1);
            for k in lo(2)..=hi(2) {
                for j in lo(1)..=hi(1) {
                    for i in lo(0)..=hi(0) {
                        let at = self.index(i, j, k);
                        let d = (Vec3::new(i as f32, j as f32, k as f32) * self.h - p).length();
                        if d <= band && d < dist[at] {
                            dist[at] = d;
                            nearest[at] = p_index as u32;
                        }
                    }
                }
            }
        }
        (dist, nearest)
    }

    /// The nodes farther than `gap` from every point that connect to the grid's boundary
    /// through such nodes (6-connected flood).
    fn flood_exterior(&self, dist: &[f32], gap: f32) -> Vec<bool> {
        let [mx, my, mz] = self.dims;
        let open = |at: usize| dist[at] > gap;
        let mut outside = vec![false; self.count()];
        let mut queue = VecDeque::new();
        for k in 0..mz {
            for j in 0..my {
                for i in 0..mx {
                    let on_face =
                        i == 0 || j == 0 || k == 0 || i == mx - 1 || j == my - 1 || k == mz - 1;
                    let at = self.index(i, j, k);
                    if on_face && open(at) {
                        outside[at] = true;
                        queue.push_back(at);
                    }
                }
            }
        }
        while let Some(at) = queue.pop_front() {
            let [i, j, k] = self.coords(at);
            let mut visit = |ni: usize, nj: usize, nk: usize| {
                let n = self.index(ni, nj, nk);
                if !outside[n] && open(n) {
                    outside[n] = true;
                    queue.push_back(n);
                }
            };
            if i > 0 {
                visit(i - 1, j, k);
            }
            if i + 1 < mx {
                visit(i + 1, j, k);
            }
            if j > 0 {
                visit(i, j - 1, k);
            }
            if j + 1 < my {
                visit(i, j + 1, k);
            }
            if k > 0 {
                visit(i, j, k - 1);
            }
            if k + 1 < mz {
                visit(i, j, k + 1);
            }
        }
        outside
    }

    /// Euclidean distance from each node to the nearest node of `set` (infinite when `set` is
    /// empty): the exact squared-distance transform of Felzenszwalb & Huttenlocher, one pass
    /// per axis.
    fn distance_to(&self, set: &[bool]) -> Vec<f32> {
        let [mx, my, mz] = self.dims;
        let mut sq: Vec<f32> = set
            .iter()
            .map(|&s| if s { 0.0 } else { f32::INFINITY })
            .collect();
        let longest = mx.max(my).max(mz);
        let mut line = vec![0.0f32; longest];
        let mut out = vec![0.0f32; longest];
        let mut hull = vec![0usize; longest];
        let mut bounds = vec![0.0f32; longest + 1];
        for axis in 0..3 {
            let len = self.dims[axis];
            let (stride, others): (usize, Vec<usize>) = match axis {
                0 => (1, (0..my * mz).map(|r| r * mx).collect()),
                1 => (
                    mx,
                    (0..mz)
                        .flat_map(|k| (0..mx).map(move |i| i + mx * my * k))
                        .collect(),
                ),
                _ => (mx * my, (0..mx * my).collect()),
            };
            for start in others {
                for (t, v) in line[..len].iter_mut().enumerate() {
                    *v = sq[start + t * stride];
                }
                squared_distance_1d(&line[..len], &mut out[..len], &mut hull, &mut bounds);
                for (t, v) in out[..len].iter().enumerate() {
                    sq[start + t * stride] = *v;
                }
            }
        }
        sq.iter().map(|d| d.sqrt() * self.h).collect()
    }
}

/// The 1-D squared distance transform `out[q] = min_p (q − p)² + f[p]` (lower envelope of
/// parabolas); infinite entries of `f` are no source.
fn squared_distance_1d(f: &[f32], out: &mut [f32], hull: &mut [usize], bounds: &mut [f32]) {
    let n = f.len();
    let mut k = 0usize;
    let mut any = false;
    for q in 0..n {
        if !f[q].is_finite() {
            continue;
        }
        if !any {
            hull[0] = q;
            bounds[0] = f32::NEG_INFINITY;
            bounds[1] = f32::INFINITY;
            any = true;
            continue;
        }
        loop {
            let p = hull[k];
            let s = ((f[q] + (q * q) as f32) - (f[p] + (p * p) as f32)) / (2.0 * (q - p) as f32);
            if s <= bounds[k] && k > 0 {
                k -= 1;
                continue;
            }
            if s <= bounds[k] {
                // The new parabola is lower everywhere the first one ruled.
                hull[0] = q;
                bounds[0] = f32::NEG_INFINITY;
                bounds[1] = f32::INFINITY;
                break;
            }
            k += 1;
            hull[k] = q;
            bounds[k] = s;
            bounds[k + 1] = f32::INFINITY;
            break;
        }
    }
    if !any {
        out.fill(f32::INFINITY);
        return;
    }
    let mut k = 0;
    for (q, o) in out.iter_mut().enumerate() {
        while bounds[k + 1] < q as f32 {
            k += 1;
        }
        let p = hull[k];
        let d = q as f32 - p as f32;
        *o = d * d + f[p];
    }
}

/// Unit normals of `points`: for each, the direction of least variance of the points within
/// `radius` (principal components of their covariance), pointing where `side(p, n)` is
/// positive (flipped otherwise). A point with fewer than three neighbours starts from the x
/// axis, turned the same way.
fn estimate_normals(points: &[Vec3], radius: f32, side: impl Fn(Vec3, Vec3) -> f32) -> Vec<Vec3> {
    use std::collections::HashMap;
    let cell = |p: Vec3| (p / radius).floor().as_ivec3();
    let mut buckets: HashMap<glam::IVec3, Vec<u32>> = HashMap::new();
    for (i, &p) in points.iter().enumerate() {
        buckets.entry(cell(p)).or_default().push(i as u32);
    }
    let r2 = radius * radius;
    let mut near = Vec::new();
    points
        .iter()
        .map(|&p| {
            let c = cell(p);
            near.clear();
            for dz in -1..=1 {
                for dy in -1..=1 {
                    for dx in -1..=1 {
                        if let Some(b) = buckets.get(&(c + glam::IVec3::new(dx, dy, dz))) {
                            near.extend(
                                b.iter()
                                    .map(|&j| points[j as usize])
                                    .filter(|q| (*q - p).length_squared() <= r2)
                                    .map(Vec3::as_dvec3),
                            );
                        }
                    }
                }
            }
            let n = if near.len() >= 3 {
                let mean = near.iter().sum::<glam::DVec3>() / near.len() as f64;
                let mut cov = [[0.0f64; 3]; 3];
                for q in &near {
                    let d = *q - mean;
                    for (a, row) in cov.iter_mut().enumerate() {
                        for (b, c) in row.iter_mut().enumerate() {
                            *c += d[a] * d[b];
                        }
                    }
                }
                least_variance_direction(cov)
            } else {
                Vec3::X
            };
            let n = if side(p, n) >= 0.0 { n } else { -n };
            n.try_normalize().unwrap_or(Vec3::Y)
        })
        .collect()
}

/// The eigenvector of the symmetric `cov` with the smallest eigenvalue: power iteration on
/// `trace · I − cov`, whose largest eigenvalue it is, started near the axis of least variance.
fn least_variance_direction(cov: [[f64; 3]; 3]) -> Vec3 {
    let trace = cov[0][0] + cov[1][1] + cov[2][2];
    let start = (0..3)
        .min_by(|&a, &b| cov[a][a].total_cmp(&cov[b][b]))
        .unwrap_or(0);
    // A nudge off the axis, in case the axis is orthogonal to the answer.
    let mut v = glam::DVec3::splat(1e-3);
    v[start] = 1.0;
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
        v = w / len;
    }
    v.as_vec3()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `count` points spread evenly over a sphere of `radius` (a Fibonacci lattice), with
    /// outward normals.
    pub(crate) fn sphere_cloud(count: usize, radius: f32) -> PointCloud {
        let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
        let (mut points, mut normals) = (Vec::new(), Vec::new());
        for i in 0..count {
            let y = 1.0 - 2.0 * (i as f32 + 0.5) / count as f32;
            let r = (1.0 - y * y).sqrt();
            let n = Vec3::new(
                r * (golden * i as f32).cos(),
                y,
                r * (golden * i as f32).sin(),
            );
            points.push(n * radius);
            normals.push(n);
        }
        PointCloud {
            points,
            normals: Some(normals),
        }
    }

    /// The fitted surface's distance from the centre along `dir`, by bisection.
    fn radius_along(lattice: &BSplineLattice, centre: Vec3, dir: Vec3, reach: f32) -> f32 {
        let (mut a, mut b) = (0.0, reach);
        assert!(lattice.value(centre) > lattice.iso, "the centre is inside");
        for _ in 0..40 {
            let m = 0.5 * (a + b);
            if lattice.value(centre + dir * m) > lattice.iso {
                a = m;
            } else {
                b = m;
            }
        }
        0.5 * (a + b)
    }

    fn worst_radius_error(fit: &CloudFit, radius_file: f32) -> f32 {
        let centre = fit.to_field(Vec3::ZERO);
        let truth = radius_file * fit.scale;
        let mut worst = 0.0f32;
        for s in 0..200 {
            let dir = sphere_cloud(200, 1.0).points[s];
            let r = radius_along(&fit.lattice, centre, dir, 2.0 * truth);
            worst = worst.max((r - truth).abs());
        }
        worst / (2.0 * truth)
    }

    #[test]
    fn a_sphere_cloud_fits_within_one_percent_of_its_size_with_and_without_normals() {
        let cloud = sphere_cloud(4000, 3.0);
        let with = fit_point_cloud(&cloud, &CloudFitOptions::default()).unwrap();
        assert_eq!(with.signed_by, SignedBy::Normals);
        let e = worst_radius_error(&with, 3.0);
        assert!(e < 0.01, "with normals: {:.3}% of the diameter", e * 100.0);

        let bare = PointCloud {
            points: cloud.points.clone(),
            normals: None,
        };
        let without = fit_point_cloud(&bare, &CloudFitOptions::default()).unwrap();
        assert_eq!(without.signed_by, SignedBy::Tagging);
        let e = worst_radius_error(&without, 3.0);
        assert!(e < 0.01, "tagged: {:.3}% of the diameter", e * 100.0);
    }

    #[test]
    fn a_torus_cloud_keeps_its_hole_and_noise_does_not_break_the_fit() {
        // Torus: tube radius 1, ring radius 3, 6000 points, 1% noise (of its size), no normals.
        let mut points = Vec::new();
        let mut seed = 12345u32;
        let mut noise = || {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (seed >> 8) as f32 / (1u32 << 24) as f32 - 0.5
        };
        for i in 0..120 {
            for j in 0..50 {
                let (u, v) = (
                    i as f32 / 120.0 * std::f32::consts::TAU,
                    j as f32 / 50.0 * std::f32::consts::TAU,
                );
                let ring = Vec3::new(u.cos(), 0.0, u.sin());
                let p = ring * (3.0 + v.cos()) + Vec3::Y * v.sin();
                let jitter = Vec3::new(noise(), noise(), noise()) * 0.08;
                points.push(p + jitter);
            }
        }
        let fit = fit_point_cloud(
            &PointCloud {
                points,
                normals: None,
            },
            &CloudFitOptions::default(),
        )
        .unwrap();
        let l = &fit.lattice;
        assert!(
            l.value(fit.to_field(Vec3::ZERO)) < l.iso,
            "the hole is open"
        );
        for u in [0.0f32, 1.0, 2.0, 4.0, 5.5] {
            let tube = Vec3::new(u.cos(), 0.0, u.sin()) * 3.0;
            assert!(
                l.value(fit.to_field(tube)) > l.iso,
                "the tube is solid at {u}"
            );
            let beyond = Vec3::new(u.cos(), 0.0, u.sin()) * 4.4;
            assert!(l.value(fit.to_field(beyond)) < l.iso, "outside at {u}");
        }
    }

    #[test]
    fn the_distance_transform_is_exact_on_a_few_sources() {
        let grid = SignGrid::new(6, 0.1, 2);
        let mut set = vec![false; grid.count()];
        let sources = [
            grid.index(0, 0, 0),
            grid.index(7, 3, 9),
            grid.index(10, 10, 2),
        ];
        for &s in &sources {
            set[s] = true;
        }
        let d = grid.distance_to(&set);
        for (at, got) in d.iter().enumerate() {
            let want = sources
                .iter()
                .map(|&s| (grid.position(at) - grid.position(s)).length())
                .fold(f32::INFINITY, f32::min);
            assert!((got - want).abs() < 1e-5, "node {at}: {got} vs {want}");
        }
        assert!(grid.distance_to(&vec![false; grid.count()])[0].is_infinite());
    }

    #[test]
    fn bad_options_and_a_point_are_refused() {
        let cloud = sphere_cloud(100, 1.0);
        for options in [
            CloudFitOptions {
                resolution: 4,
                ..CloudFitOptions::default()
            },
            CloudFitOptions {
                samples_per_span: 0,
                ..CloudFitOptions::default()
            },
            CloudFitOptions {
                gap_spans: 3.0,
                ..CloudFitOptions::default()
            },
        ] {
            assert!(matches!(
                fit_point_cloud(&cloud, &options),
                Err(CloudFitError::Options(_))
            ));
        }
        let point = PointCloud {
            points: vec![Vec3::ONE; 3],
            normals: None,
        };
        assert!(matches!(
            fit_point_cloud(&point, &CloudFitOptions::default()),
            Err(CloudFitError::Degenerate)
        ));
    }
}
