//! How sharp a cloud's surface is, beside its noise: what tells a smooth shape (which a
//! coarser, smoother fit serves best) from one with edges, thin walls or fine relief (which
//! needs the lattice's finest knots and the least smoothing).
//!
//! An even subset of the kept points ([`SHARPNESS_SAMPLES`] at most) each fits a quadric
//! height field `z = a x² + b x y + c y² + d x + e y + f` to its neighbours within a radius,
//! in the frame of their least-squares plane. On a smooth surface the quadric takes the shape
//! and leaves the noise: the residual's RMS is the points' scatter `σ` across the surface. At a
//! sharp edge, a corner, a thin wall whose far side is within the radius, or relief finer than
//! the radius, no quadric follows the points, and the residual is structured and larger. Each
//! sample's reading is its residual's RMS over `σ` (1 where the surface is smooth at the
//! radius's scale).

use super::consensus::{PointGrid, least_variance_direction, parallel_map_by};
use super::quadric::QuadricHeights;
use glam::{DVec3, Vec3};

/// Points whose neighbourhoods are read, at most (an even subset of the kept points): the
/// statistic is a fraction, which a few thousand readings fix to about a per cent.
pub const SHARPNESS_SAMPLES: usize = 4096;
/// The fewest neighbours a quadric is fitted to (six coefficients, and a margin for the
/// noise).
pub const SHARPNESS_LEAST_NEIGHBOURS: usize = 16;
/// Points a cell of the neighbour search offers, at most: an even subset of a dense
/// neighbourhood fixes a quadric as well as all of it. Fewer (16) left each reading's RMS
/// noisy enough that the sharpest of the readings near a coefficient read a smooth surface
/// as sharp (bench/RESULTS.md, "The bending by the surface's sharpness").
const SHARPNESS_CELL_OFFER: usize = 64;

/// What [`read_sharpness`] found: per sampled point, its quadric's residual RMS over the noise,
/// sorted ascending.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SharpnessReadings {
    /// Sorted, ascending.
    pub sorted: Vec<f32>,
}

impl SharpnessReadings {
    /// The `fraction` quantile of the readings (`0` the least, `1` the most), `None` where
    /// there are none.
    #[must_use]
    pub fn quantile(&self, fraction: f32) -> Option<f32> {
        let last = self.sorted.len().checked_sub(1)?;
        let at = (fraction.clamp(0.0, 1.0) * last as f32).round() as usize;
        self.sorted.get(at).copied()
    }

    /// The fraction of the readings over `ratio` (`None` where there are none).
    #[must_use]
    pub fn fraction_over(&self, ratio: f32) -> Option<f32> {
        if self.sorted.is_empty() {
            return None;
        }
        let at_most = self.sorted.partition_point(|&r| r <= ratio);
        Some((self.sorted.len() - at_most) as f32 / self.sorted.len() as f32)
    }
}

/// Reads how sharp the surface through `points` (those `kept`, in the points' units) is over
/// neighbourhoods of `radius`, the points' scatter across the surface being `noise` (see the
/// module docs). Neighbourhoods with fewer than [`SHARPNESS_LEAST_NEIGHBOURS`] points, or
/// whose quadric is degenerate, give no reading; so does every one where `noise` is not
/// positive.
#[must_use]
pub fn read_sharpness(
    points: &[Vec3],
    kept: &[usize],
    noise: f32,
    radius: f32,
) -> SharpnessReadings {
    let mut sorted: Vec<f32> = sharpness_at(points, kept, noise, radius)
        .into_iter()
        .map(|(_, r)| r)
        .collect();
    sorted.sort_unstable_by(f32::total_cmp);
    SharpnessReadings { sorted }
}

/// [`read_sharpness`]'s readings with the sampled points they were read at, in the order of
/// `kept`.
#[must_use]
pub fn sharpness_at(points: &[Vec3], kept: &[usize], noise: f32, radius: f32) -> Vec<(Vec3, f32)> {
    if kept.is_empty()
        || !(radius.is_finite() && radius > 0.0)
        || !(noise.is_finite() && noise > 0.0)
    {
        return Vec::new();
    }
    let kept_points: Vec<Vec3> = kept.iter().map(|&i| points[i]).collect();
    let grid = PointGrid::new(&kept_points, |_| true, radius, SHARPNESS_CELL_OFFER);
    let stride = kept_points.len().div_ceil(SHARPNESS_SAMPLES).max(1);
    let sampled = kept_points.len().div_ceil(stride);
    // A quadric's fit per sample: a few hundred samples are worth a thread.
    parallel_map_by(sampled, SHARPNESS_SAMPLES_PER_THREAD, |s| {
        let p = kept_points[s * stride];
        let mut near = Vec::with_capacity(4 * SHARPNESS_CELL_OFFER);
        grid.for_each_near(p, radius, |_, q| near.push(q));
        quadric_residual(p, &near, radius)
            .filter(|&(_, offset)| offset <= BORDER_OFFSET)
            .map(|(r, _)| (p, r / noise))
    })
    .into_iter()
    .flatten()
    .collect()
}

/// Sampled points per thread, at least, of the quadrics' fits: each fit's 6×6 normal
/// equations and neighbour search cost far more than one neighbour search alone, so unlike
/// [`super::consensus::parallel_map`]'s thousands, a few hundred are worth a thread (the
/// stage on one thread was the sharpness rule's whole cost in wall time).
const SHARPNESS_SAMPLES_PER_THREAD: usize = 256;

/// A neighbourhood whose centroid lies further than this fraction of the radius from its
/// sampled point along their least-squares plane holds the surface on one side of the point
/// only: the point lies on the data's border (a hole's rim, a scan's edge), where the residual
/// reads the border, not the surface, and no reading is taken. A point on a straight border
/// reads `4 / 3π ≈ 0.42`; one on a crease or a rounded edge, whose neighbours lie on both
/// sides, about 0.
pub const BORDER_OFFSET: f32 = 0.25;

/// The RMS residual (the points' units) of the quadric height field fitted to `near` by least
/// squares in the frame of their least-squares plane, with the six coefficients' degrees of
/// freedom taken off, and how far (in radii) their centroid lies from `at` along that plane;
/// `radius` scales the fit for its conditioning.
fn quadric_residual(at: Vec3, near: &[Vec3], radius: f32) -> Option<(f32, f32)> {
    if near.len() < SHARPNESS_LEAST_NEIGHBOURS {
        return None;
    }
    let count = near.len() as f64;
    let mean = near.iter().map(|q| q.as_dvec3()).sum::<DVec3>() / count;
    let mut cov = [[0.0f64; 3]; 3];
    for q in near {
        let d = q.as_dvec3() - mean;
        let d = [d.x, d.y, d.z];
        for (row, &da) in cov.iter_mut().zip(&d) {
            for (entry, &db) in row.iter_mut().zip(&d) {
                *entry += da * db;
            }
        }
    }
    let normal = least_variance_direction(cov).as_dvec3().try_normalize()?;
    let mut heights = QuadricHeights::about(mean, normal, f64::from(radius));
    for &q in near {
        heights.add(q);
    }
    let value = heights.scatter()? as f32;
    let from = mean - at.as_dvec3();
    let offset = ((from - normal * from.dot(normal)).length() / f64::from(radius)) as f32;
    Some((value, offset))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Uniform deviates in `[0, 1)` and standard normal ones from a seeded LCG.
    struct Deviates(u64);

    impl Deviates {
        fn unit(&mut self) -> f32 {
            self.0 = self
                .0
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            ((self.0 >> 40) as f32 + 0.5) / (1u64 << 24) as f32
        }

        fn normal(&mut self) -> f32 {
            let (a, b) = (self.unit(), self.unit());
            (-2.0 * a.ln()).sqrt() * (std::f32::consts::TAU * b).cos()
        }

        fn vector(&mut self) -> Vec3 {
            Vec3::new(self.normal(), self.normal(), self.normal())
        }
    }

    /// `count` points even on a sphere of radius 1, with Gaussian noise of `noise` each way.
    fn noisy_sphere(count: usize, noise: f32, seed: u64) -> Vec<Vec3> {
        let mut deviates = Deviates(seed);
        (0..count)
            .map(|_| {
                let direction = loop {
                    if let Some(v) = deviates.vector().try_normalize() {
                        break v;
                    }
                };
                direction + deviates.vector() * noise
            })
            .collect()
    }

    /// `count` points even on the faces of the cube `[-1, 1]³`, with Gaussian noise of `noise`
    /// each way.
    fn noisy_cube(count: usize, noise: f32, seed: u64) -> Vec<Vec3> {
        let mut deviates = Deviates(seed);
        (0..count)
            .map(|_| {
                let face = (deviates.unit() * 6.0) as usize % 6;
                let (u, v) = (deviates.unit() * 2.0 - 1.0, deviates.unit() * 2.0 - 1.0);
                let side = if face.is_multiple_of(2) { 1.0 } else { -1.0 };
                let p = match face / 2 {
                    0 => Vec3::new(side, u, v),
                    1 => Vec3::new(u, side, v),
                    _ => Vec3::new(u, v, side),
                };
                p + deviates.vector() * noise
            })
            .collect()
    }

    #[test]
    fn a_noisy_sphere_reads_its_noise_and_a_cubes_edges_read_sharp() {
        let noise = 0.005;
        let radius = 0.25;
        let sphere = noisy_sphere(40_000, noise, 7);
        let kept: Vec<usize> = (0..sphere.len()).collect();
        let round = read_sharpness(&sphere, &kept, noise, radius);
        assert!(round.sorted.len() > 3000, "{} readings", round.sorted.len());
        let median = round.quantile(0.5).unwrap();
        assert!((0.9..1.15).contains(&median), "sphere's median {median}");
        let round_over = round.fraction_over(2.0).unwrap();
        assert!(round_over < 0.01, "sphere over 2: {round_over}");

        // The cube's faces are as flat as a plane; within a radius of its 12 edges (a band of
        // 2 · 0.25 on faces of side 2: about a quarter of its area) no quadric follows them.
        let cube = noisy_cube(60_000, noise, 11);
        let kept: Vec<usize> = (0..cube.len()).collect();
        let square = read_sharpness(&cube, &kept, noise, radius);
        let median = square.quantile(0.5).unwrap();
        assert!((0.9..1.3).contains(&median), "cube's median {median}");
        let cube_over = square.fraction_over(2.0).unwrap();
        assert!(cube_over > 0.15, "cube over 2: {cube_over}");
    }

    #[test]
    fn no_reading_is_taken_on_the_datas_border_and_a_crease_still_reads() {
        // The upper half of a noisy sphere: open along its equator, whose points have
        // neighbours on one side only.
        let noise = 0.005;
        let radius = 0.25;
        let dome: Vec<Vec3> = noisy_sphere(40_000, noise, 5)
            .into_iter()
            .filter(|p| p.z > 0.0)
            .collect();
        let kept: Vec<usize> = (0..dome.len()).collect();
        let readings = sharpness_at(&dome, &kept, noise, radius);
        assert!(readings.len() > 1500, "{} readings", readings.len());
        // Within a tenth of the radius of the rim the centroid lies about 0.4 radii inward
        // along the surface: no reading.
        let on_rim = readings.iter().filter(|(p, _)| p.z < 0.1 * radius).count();
        assert_eq!(on_rim, 0, "readings on the rim");
        // A radius inside the rim the neighbourhood is whole again, and reads.
        let inside = readings
            .iter()
            .filter(|(p, _)| p.z > radius && p.z < 1.5 * radius)
            .count();
        assert!(inside > 100, "{inside} readings a radius inside the rim");
        // On the cube's edges (neighbours on both faces) the readings are kept, and sharp.
        let cube = noisy_cube(60_000, noise, 11);
        let kept: Vec<usize> = (0..cube.len()).collect();
        let edges = sharpness_at(&cube, &kept, noise, radius)
            .into_iter()
            .filter(|(p, _)| {
                let a = p.abs();
                // Near an edge (two coordinates near 1), away from the corners.
                let near = [a.x, a.y, a.z].iter().filter(|&&c| c > 0.97).count();
                near == 2 && a.min_element() < 0.5
            })
            .map(|(_, r)| r)
            .collect::<Vec<_>>();
        assert!(
            edges.len() > 20,
            "{} readings on the cube's edges",
            edges.len()
        );
        let sharp = edges.iter().filter(|&&r| r > 2.0).count();
        assert!(
            10 * sharp >= 9 * edges.len(),
            "{sharp} of {} over 2",
            edges.len()
        );
    }

    #[test]
    fn no_noise_or_no_points_give_no_reading() {
        let sphere = noisy_sphere(2_000, 0.0, 3);
        let kept: Vec<usize> = (0..sphere.len()).collect();
        assert!(read_sharpness(&sphere, &kept, 0.0, 0.3).sorted.is_empty());
        assert!(read_sharpness(&sphere, &[], 0.01, 0.3).sorted.is_empty());
        assert_eq!(SharpnessReadings::default().quantile(0.5), None);
        assert_eq!(SharpnessReadings::default().fraction_over(1.0), None);
    }
}
