//! Thinning a cloud denser than the fit can use: the fit's finest knot span carries no more
//! detail from 1 000 points on it than from 9, while every neighbourhood search (screening,
//! the normals' vote, the moving planes) costs in proportion to the points. A cloud whose
//! typical spacing is below [`SPACING_PER_FINEST_SPAN`] of the finest knot span is thinned
//! to an even subset (every `stride`-th point, in the file's order) at about that spacing.
//!
//! A cloud of more than [`MAX_FITTED_POINTS`] points is thinned to that many whatever the
//! lattice: the fit's time and memory follow the points it keeps, so the count is the budget,
//! checked before the fit starts. A finer lattice (chosen from a larger count, see
//! `import::resolution_for_points`) would otherwise keep every point of a dense scan and take
//! four times as long for a fifth less error.

use glam::Vec3;

use super::consensus::typical_spacing;
use super::points::PointCloud;

/// The spacing a thinned cloud keeps, as a fraction of the fit's finest knot span: three
/// points per span along each direction of the surface, nine per span² (a cubic B-spline
/// patch is fixed by sixteen coefficients over its four spans in each direction, so each span²
/// still has more points than unknowns).
pub const SPACING_PER_FINEST_SPAN: f32 = 1.0 / 3.0;

/// Clouds with fewer points than this are never thinned.
pub const THIN_ABOVE_POINTS: usize = 200_000;

/// The most points a fit keeps (a denser cloud is thinned to about this many, evenly).
/// Chosen so that a 1 000 000-point scan fits within 10 s on a 2-core machine at the finest
/// lattice its count chooses (48 knots): the fit's time follows the points kept, about
/// 13 s for 987 000 kept and 3.3 s for 333 000 at 32 knots.
pub const MAX_FITTED_POINTS: usize = 400_000;

/// What thinning did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Thinned {
    /// Every `stride`-th point was kept.
    pub stride: usize,
    /// The cloud's typical spacing before, in its units.
    pub spacing_before: f32,
    /// The spacing wanted, in its units.
    pub spacing_wanted: f32,
    /// The count ([`MAX_FITTED_POINTS`]) set the stride, not the spacing wanted.
    pub limited_by_count: bool,
}

/// `cloud` thinned to about `finest_span × SPACING_PER_FINEST_SPAN` (same units as the
/// cloud) and to at most about [`MAX_FITTED_POINTS`] points, with what was done; `None` when
/// it is sparse enough already (or small).
#[must_use]
pub fn thin_for_span(cloud: &PointCloud, finest_span: f32) -> Option<(PointCloud, Thinned)> {
    let n = cloud.points.len();
    if n < THIN_ABOVE_POINTS || !(finest_span.is_finite() && finest_span > 0.0) {
        return None;
    }
    let (lo, hi) = cloud
        .points
        .iter()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(a, b), &p| {
            (a.min(p), b.max(p))
        });
    let size = (hi - lo).max_element();
    if !(size.is_finite() && size > 0.0) {
        return None;
    }
    let spacing_before = typical_spacing(&cloud.points, size);
    let spacing_wanted = SPACING_PER_FINEST_SPAN * finest_span;
    // Keeping every k-th point widens the spacing by √k.
    let for_span = ((spacing_wanted / spacing_before.max(f32::MIN_POSITIVE)).powi(2)).floor();
    // NaN (a degenerate cloud) is thinned by the count alone.
    let for_span = if for_span.is_nan() { 1.0 } else { for_span };
    let for_count = n.div_ceil(MAX_FITTED_POINTS) as f32;
    let stride = for_span.max(for_count);
    if stride < 2.0 {
        return None;
    }
    let stride = (stride as usize).min(n);
    let every = |v: &Vec<Vec3>| v.iter().step_by(stride).copied().collect::<Vec<Vec3>>();
    Some((
        PointCloud {
            points: every(&cloud.points),
            normals: cloud.normals.as_ref().map(every),
        },
        Thinned {
            stride,
            spacing_before,
            spacing_wanted,
            limited_by_count: for_count > for_span,
        },
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `n` points on a unit sphere (a Fibonacci lattice), with their normals.
    fn sphere(n: usize) -> PointCloud {
        let golden = std::f32::consts::PI * (3.0 - 5.0_f32.sqrt());
        let points: Vec<Vec3> = (0..n)
            .map(|i| {
                let y = 1.0 - 2.0 * (i as f32 + 0.5) / n as f32;
                let r = (1.0 - y * y).sqrt();
                let a = golden * i as f32;
                Vec3::new(r * a.cos(), y, r * a.sin())
            })
            .collect();
        PointCloud {
            normals: Some(points.clone()),
            points,
        }
    }

    #[test]
    fn the_spacing_of_an_even_sphere_cloud_is_its_area_per_point() {
        let cloud = sphere(300_000);
        let spacing = typical_spacing(&cloud.points, 2.0);
        let expected = (4.0 * std::f32::consts::PI / 300_000.0).sqrt();
        // The grid counts the cells a surface crosses, a little more than its area.
        assert!(
            spacing > expected && spacing < 1.5 * expected,
            "{spacing} against {expected}"
        );
    }

    #[test]
    fn a_dense_cloud_is_thinned_to_the_spacing_wanted_and_a_sparse_or_small_one_is_not() {
        let cloud = sphere(1_000_000);
        let span = 2.0 / 32.0;
        let (thin, done) = thin_for_span(&cloud, span).expect("a dense cloud is thinned");
        assert!(done.stride >= 2);
        assert!(!done.limited_by_count, "{done:?}");
        assert_eq!(thin.points.len(), cloud.points.len().div_ceil(done.stride));
        assert_eq!(thin.normals.as_ref().map(Vec::len), Some(thin.points.len()));
        let after = typical_spacing(&thin.points, 2.0);
        assert!(
            after <= done.spacing_wanted && after > 0.6 * done.spacing_wanted,
            "spacing {after} after, {} wanted",
            done.spacing_wanted
        );
        // The thinned cloud needs no more thinning ...
        assert!(thin_for_span(&thin, span).is_none());
        // ... and a small cloud is left as it is.
        assert!(thin_for_span(&sphere(100_000), 1.0).is_none());
    }

    #[test]
    fn a_cloud_denser_than_the_budget_keeps_at_most_the_budget_even_where_the_span_wants_all() {
        let cloud = sphere(1_000_000);
        // A span so fine that every point is wanted: only the count thins.
        let span = 1e-4;
        let (thin, done) = thin_for_span(&cloud, span).expect("over the budget: thinned");
        assert!(done.limited_by_count, "{done:?}");
        assert!(
            thin.points.len() <= MAX_FITTED_POINTS,
            "{}",
            thin.points.len()
        );
        // Evenly: about the budget, not far below it.
        assert!(
            thin.points.len() > MAX_FITTED_POINTS * 3 / 4,
            "{}",
            thin.points.len()
        );
        assert_eq!(thin.normals.as_ref().map(Vec::len), Some(thin.points.len()));
        // The points kept still cover the whole sphere: its extent is unchanged.
        let (lo, hi) = thin
            .points
            .iter()
            .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(a, b), &p| {
                (a.min(p), b.max(p))
            });
        assert!(
            (hi - lo - Vec3::splat(2.0)).abs().max_element() < 0.02,
            "{lo} {hi}"
        );
        // A cloud within the budget whose span wants all its points is left whole.
        assert!(thin_for_span(&sphere(MAX_FITTED_POINTS), span).is_none());
    }
}
