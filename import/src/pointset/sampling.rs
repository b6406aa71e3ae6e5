//! Dynamic sampling (Guo & Qin §4.3): insert points where the surface has stretched, remove
//! them where it is squeezed, so the spacing stays near a target `h`.
//!
//! - **Insertion** (the up-sampling of Alexa et al. that the paper uses): each point projects
//!   its neighbours within `3h` onto its tangent plane and clips its Voronoi cell there; the
//!   cell's farthest vertex is the centre of the largest empty disc touching the point. When
//!   its radius is above `insert_above · h` a point is inserted there, projected onto the
//!   surface by Newton steps on the parent's local field, with the parent's field re-expressed
//!   around it and the parent's colour.
//! - **Removal** (the paper leaves it out of its real-time loop; we run it): a point whose
//!   nearest neighbour is closer than `remove_below · h` is removed, the earlier of the two
//!   kept.
//!
//! - **Clearance**: a point is inserted only where, after its projection, it keeps
//!   [`INSERT_CLEARANCE`] times the removal distance from every point, those inserted in the
//!   same pass included. The empty disc is measured in the parent's tangent plane, and on a
//!   curved surface the projection can land the new point nearer than that to a neighbour;
//!   the next call would remove it and the same hole would call for it again.
//!
//! Why the defaults (insert above 0.72 h, remove below 0.7 h) keep the spacing within a factor
//! 1.5 of `h`: removal leaves no pair closer than `0.7 h`, and the clearance keeps every
//! inserted point `1.05 · 0.7 h = 0.735 h` from the others, so a call leaves no pair closer
//! than `0.7 h > h/1.5`; and a point whose nearest neighbour is `r` away has a Voronoi vertex
//! at least `r/2` away, so once no disc exceeds `0.72 h`, no nearest neighbour is farther than
//! `1.44 h`.
//!
//! Not real-time: it allocates and rebuilds a k-d tree per pass.

// NOTE: index loops over the 3×3×3 stencil and parallel per-point arrays read clearer than
// zipped iterators here.
#![allow(clippy::needless_range_loop)]

use std::num::NonZero;

use glam::{Vec2, Vec3};
use kiddo::{ImmutableKdTree, SquaredEuclidean};

use super::error::PointSetError;
use super::surface::PointSet;

/// Thresholds of [`resample`], as multiples of the target spacing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SamplingOptions {
    /// Target spacing `h`, world units.
    pub target_fu: f32,
    /// Insert where the largest empty disc's radius exceeds this many `h`.
    pub insert_above: f32,
    /// Remove where the nearest neighbour is closer than this many `h`.
    pub remove_below: f32,
    /// Most insertion passes per call.
    pub max_passes: usize,
    /// An inserted point keeps this many times `remove_below · h` from every point
    /// ([`INSERT_CLEARANCE`]; 0 measures the empty disc alone).
    pub insert_clearance: f32,
}

impl SamplingOptions {
    /// The defaults for a target spacing.
    #[must_use]
    pub fn for_target(target_fu: f32) -> Self {
        Self {
            target_fu,
            insert_above: 0.72,
            remove_below: 0.7,
            max_passes: 8,
            insert_clearance: INSERT_CLEARANCE,
        }
    }
}

/// What [`resample`] did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SamplingReport {
    pub inserted: usize,
    pub removed: usize,
    /// Insertion passes run.
    pub passes: usize,
}

/// Neighbours examined per point.
const NEIGHBOURS: usize = 16;

/// An inserted point keeps at least this many times the removal distance
/// (`remove_below · h`) from every other point, so removal never takes back what insertion
/// put (see the module's doc). The 5% margin covers the projection's residual moves and
/// rounding. [`resample`] and the point follower both insert by this rule.
pub const INSERT_CLEARANCE: f32 = 1.05;
/// Nearest points examined around a point about to be inserted (the clearance is under one
/// spacing, so few points can lie within it).
pub(crate) const CLEARANCE_NEIGHBOURS: usize = 8;

fn tree_of(points: &[Vec3]) -> Result<ImmutableKdTree<f32, 3>, PointSetError> {
    let arr: Vec<[f32; 3]> = points.iter().map(|p| [p.x, p.y, p.z]).collect();
    ImmutableKdTree::new_from_slice(&arr).map_err(|e| PointSetError::Index(format!("{e:?}")))
}

/// The farthest vertex of the Voronoi cell of the origin among `sites` (2D), clipped to the
/// square `± bound`.
#[must_use]
pub fn farthest_voronoi_vertex(sites: &[Vec2], bound: f32) -> Vec2 {
    let mut poly = vec![
        Vec2::new(-bound, -bound),
        Vec2::new(bound, -bound),
        Vec2::new(bound, bound),
        Vec2::new(-bound, bound),
    ];
    let mut next = Vec::with_capacity(poly.len() + 4);
    for &q in sites {
        let c = 0.5 * q.length_squared();
        if c <= 0.0 {
            continue;
        }
        // Keep y with y·q ≤ |q|²/2.
        next.clear();
        for e in 0..poly.len() {
            let (a, b) = (poly[e], poly[(e + 1) % poly.len()]);
            let (fa, fb) = (a.dot(q) - c, b.dot(q) - c);
            if fa <= 0.0 {
                next.push(a);
            }
            if (fa < 0.0) != (fb < 0.0) && fa != fb {
                let t = fa / (fa - fb);
                next.push(a + t * (b - a));
            }
        }
        std::mem::swap(&mut poly, &mut next);
        if poly.is_empty() {
            return Vec2::ZERO;
        }
    }
    poly.into_iter()
        .max_by(|a, b| a.length_squared().total_cmp(&b.length_squared()))
        .unwrap_or(Vec2::ZERO)
}

/// Two points lie on the same sheet of the surface, for crowding, the insertion clearance and
/// the tangent-plane Voronoi cells (a splat's radius, an insertion's hole), only when their
/// normals' cosine exceeds this: a point across a wall thinner than the spacing (its normal
/// turned away) neither crowds a point out nor shrinks a cell, or the wall's ridge, sampled
/// from both sides, would be left with holes ([`resample`] and the follower alike).
pub const SAME_SHEET_COSINE: f32 = 0.0;

/// Whether points with normals `a` and `b` lie on the same sheet ([`SAME_SHEET_COSINE`]).
#[must_use]
pub fn same_sheet(a: Vec3, b: Vec3) -> bool {
    a.dot(b) > SAME_SHEET_COSINE
}

/// Resamples the points of `set` whose position lies in `lo..=hi` (all when `None`): removal
/// first, then insertion passes until none inserts. Returns what it did and the old index of
/// every surviving point (new points have `None`). The point set is reindexed.
///
/// # Errors
/// When a k-d tree cannot be built.
pub fn resample(
    set: &mut PointSet,
    within: Option<(Vec3, Vec3)>,
    options: &SamplingOptions,
) -> Result<(SamplingReport, Vec<Option<usize>>), PointSetError> {
    let inside = |p: Vec3| within.is_none_or(|(lo, hi)| p.cmpge(lo).all() && p.cmple(hi).all());
    let h = options.target_fu;
    let mut report = SamplingReport::default();
    let mut origin: Vec<Option<usize>> = (0..set.len()).map(Some).collect();

    // Removal.
    if set.len() > 1 {
        let tree = tree_of(&set.points)?;
        let mut gone = vec![false; set.len()];
        let r = options.remove_below * h;
        for i in 0..set.len() {
            if gone[i] || !inside(set.points[i]) {
                continue;
            }
            let p = set.points[i];
            let close = tree
                .query(&[p.x, p.y, p.z])
                .within::<SquaredEuclidean<f32>>(r * r)
                .unsorted()
                .execute();
            for c in close {
                let j = c.item as usize;
                if j > i
                    && !gone[j]
                    && inside(set.points[j])
                    && same_sheet(set.normals[j], set.normals[i])
                {
                    gone[j] = true;
                    report.removed += 1;
                }
            }
        }
        if report.removed > 0 {
            let mut w = 0;
            for i in 0..set.len() {
                if !gone[i] {
                    set.points[w] = set.points[i];
                    set.normals[w] = set.normals[i];
                    set.colours[w] = set.colours[i];
                    set.fields[w] = set.fields[i];
                    origin[w] = origin[i];
                    w += 1;
                }
            }
            set.points.truncate(w);
            set.normals.truncate(w);
            set.colours.truncate(w);
            set.fields.truncate(w);
            origin.truncate(w);
        }
    }

    // Insertion.
    let want = NonZero::new(NEIGHBOURS + 1).unwrap_or(NonZero::<usize>::MIN);
    let near = NonZero::new(CLEARANCE_NEIGHBOURS).unwrap_or(NonZero::<usize>::MIN);
    let clearance_sq = (options.insert_clearance * options.remove_below * h).powi(2);
    let mut sites = Vec::with_capacity(NEIGHBOURS);
    for _ in 0..options.max_passes {
        report.passes += 1;
        let tree = tree_of(&set.points)?;
        // Points inserted in this pass: position and normal.
        let mut added: Vec<(Vec3, Vec3)> = Vec::new();
        let count = set.len();
        for i in 0..count {
            let p = set.points[i];
            if !inside(p) {
                continue;
            }
            let n = set.normals[i];
            let t1 = n.any_orthonormal_vector();
            let t2 = n.cross(t1);
            sites.clear();
            let found = tree
                .query(&[p.x, p.y, p.z])
                .nearest_n::<SquaredEuclidean<f32>>(want)
                .execute();
            for r in found {
                let j = r.item as usize;
                if j != i && r.distance < 9.0 * h * h && same_sheet(set.normals[j], n) {
                    let d = set.points[j] - p;
                    sites.push(Vec2::new(d.dot(t1), d.dot(t2)));
                }
            }
            for &(q, m) in &added {
                let d = q - p;
                if d.length_squared() < 9.0 * h * h && same_sheet(m, n) {
                    sites.push(Vec2::new(d.dot(t1), d.dot(t2)));
                }
            }
            let v = farthest_voronoi_vertex(&sites, 3.0 * h);
            let r = v.length();
            if r <= options.insert_above * h {
                continue;
            }
            // An open cell (the vertex on the clipping square) is a wide hole: step in by h.
            let v = if r > 2.9 * h { v * (h / r) } else { v };
            let parent = set.fields[i];
            let mut y = p + v.x * t1 + v.y * t2;
            for _ in 0..4 {
                let (s, g) = parent.value_and_gradient(y);
                let g2 = g.length_squared();
                if !(g2 > 0.0 && g2.is_finite()) {
                    break;
                }
                y -= g * (s / g2);
            }
            if !y.is_finite() || (y - p).length() > 3.0 * h {
                continue;
            }
            let (_, g) = parent.value_and_gradient(y);
            let normal = (-g).try_normalize().unwrap_or(n);
            let crowded = tree
                .query(&[y.x, y.y, y.z])
                .nearest_n::<SquaredEuclidean<f32>>(near)
                .execute()
                .iter()
                .any(|r| {
                    r.distance < clearance_sq && same_sheet(set.normals[r.item as usize], normal)
                })
                || added
                    .iter()
                    .any(|&(q, m)| q.distance_squared(y) < clearance_sq && same_sheet(m, normal));
            if crowded {
                continue;
            }
            set.points.push(y);
            set.normals.push(normal);
            set.colours.push(set.colours[i]);
            set.fields.push(parent.recentred(y, parent.half_fu));
            origin.push(None);
            added.push((y, normal));
            report.inserted += 1;
        }
        if added.is_empty() {
            break;
        }
    }
    set.reindex()?;
    Ok((report, origin))
}

/// Each point's nearest-neighbour distance (for the points inside `lo..=hi`, all when
/// `None`).
///
/// # Errors
/// When the k-d tree cannot be built.
pub fn nearest_spacings(
    points: &[Vec3],
    within: Option<(Vec3, Vec3)>,
) -> Result<Vec<f32>, PointSetError> {
    let tree = tree_of(points)?;
    let two = NonZero::new(2).unwrap_or(NonZero::<usize>::MIN);
    Ok(points
        .iter()
        .enumerate()
        .filter(|(_, p)| within.is_none_or(|(lo, hi)| p.cmpge(lo).all() && p.cmple(hi).all()))
        .map(|(i, p)| {
            tree.query(&[p.x, p.y, p.z])
                .nearest_n::<SquaredEuclidean<f32>>(two)
                .execute()
                .into_iter()
                .find(|r| r.item as usize != i)
                .map_or(f32::INFINITY, |r| r.distance.sqrt())
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::PointCloud;
    use crate::pointset::PointSetOptions;
    use crate::pointset::surface::tests::sphere_cloud;

    /// Densifies a Fibonacci sphere of `count` points to `fraction` of its spacing, then
    /// resamples once more at the same target: (points inserted by the first call, the
    /// closest pair after it in units of the target, points the second call removes).
    fn densify_then_resample(count: usize, fraction: f32) -> (usize, f32, usize) {
        let cloud = sphere_cloud(Vec3::ZERO, 0.5, count);
        let (mut set, _) = PointSet::build(&cloud, &PointSetOptions::default()).unwrap();
        let options = SamplingOptions::for_target(fraction * set.spacing_fu);
        let (first, _) = resample(&mut set, None, &options).unwrap();
        let closest = nearest_spacings(&set.points, None)
            .unwrap()
            .into_iter()
            .fold(f32::INFINITY, f32::min);
        let (second, _) = resample(&mut set, None, &options).unwrap();
        (first.inserted, closest / options.target_fu, second.removed)
    }

    #[test]
    fn a_second_resample_removes_nothing_the_first_inserted() {
        // Measured with the clearance off (the empty disc alone): (400, 0.35) inserts 4 306
        // points, of which the second call removes one; with it on, 4 132 and none.
        for (count, fraction) in [(60, 0.7f32), (400, 0.5), (400, 0.35)] {
            let (inserted, closest, removed) = densify_then_resample(count, fraction);
            assert!(
                inserted > 100,
                "{count} points to {fraction}: inserted {inserted}"
            );
            assert!(
                closest >= 0.7 && removed == 0,
                "{count} points to {fraction}: closest pair {closest} h, then {removed} removed"
            );
        }
    }

    /// A wall a fifth of the spacing thick, its two faces sampled on the same grid with
    /// opposite normals: each point's twin across the wall is far closer than the removal
    /// distance (0.2 h against 0.7 h), yet on another sheet, so resampling the wall's inner
    /// part (away from its open borders) removes and inserts nothing.
    #[test]
    fn a_point_across_a_thin_wall_is_not_a_crowding_neighbour() {
        let h = 0.05;
        let mut points = Vec::new();
        let mut normals = Vec::new();
        for (z, n) in [(0.0, -Vec3::Z), (0.2 * h, Vec3::Z)] {
            for i in 0..16 {
                for j in 0..16 {
                    points.push(Vec3::new(i as f32 * h, j as f32 * h, z));
                    normals.push(n);
                }
            }
        }
        let cloud = PointCloud {
            points,
            normals: Some(normals),
        };
        let (mut set, _) = PointSet::build(&cloud, &PointSetOptions::default()).unwrap();
        let before = set.len();
        let options = SamplingOptions::for_target(h);
        assert!(0.2 * h < options.remove_below * h);
        let inner = (
            Vec3::new(4.0 * h, 4.0 * h, -h),
            Vec3::new(11.0 * h, 11.0 * h, h),
        );
        let (report, _) = resample(&mut set, Some(inner), &options).unwrap();
        assert_eq!(report.removed, 0, "{report:?}");
        assert_eq!(report.inserted, 0, "{report:?}");
        assert_eq!(set.len(), before);
    }

    #[test]
    fn voronoi_vertex_of_a_square_lattice_is_the_diagonal() {
        let sites = [Vec2::X, -Vec2::X, Vec2::Y, -Vec2::Y, Vec2::ONE, -Vec2::ONE];
        let v = farthest_voronoi_vertex(&sites, 3.0);
        assert!((v.length() - 0.5f32.sqrt()).abs() < 1e-5, "{v}");
    }

    #[test]
    fn a_missing_neighbour_opens_the_cell_toward_it() {
        let sites = [-Vec2::X, Vec2::Y, -Vec2::Y];
        let v = farthest_voronoi_vertex(&sites, 3.0);
        assert!(v.x > 2.9, "{v}");
    }
}
