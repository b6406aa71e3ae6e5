//! How much of the clay's volume one step would remove, estimated before the step is applied,
//! so that a step removing most of the clay is never a surprise (the window asks first, a
//! script prints a warning).
//!
//! Cheap and bounded: volume is counted on coefficient nodes. A node is inside when the
//! clay's density there (the patch's coefficient plus the other patches' density, the value
//! a tool's rule reads) is above the iso-level; each node stands for one knot cell, so a
//! count times `spacing³` is a volume in field units³, good to about a knot span at the
//! surface. A tool's change is the action's own rule run on a scratch copy of the nodes in
//! the tool's reach, pose after pose; a CSG's is the rule at every node of the patch with the
//! other clay's density as the tool. Nothing here allocates more than that copy.

use glam::Vec3;

use super::action::ToolAction;
use super::apply::GeometricTool;
use super::clay::{Clay, CoeffBox};
use super::shape::ToolPose;
use crate::field::{BSplineLattice, coeff_box_around};

/// The largest share of the clay's volume one step may remove unasked.
pub const MOST_REMOVED_UNASKED: f32 = 0.5;

/// A step's estimated change of volume, field units³.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct VolumeChange {
    /// Volume inside before and outside after.
    pub removed_fu3: f32,
    /// Volume outside before and inside after.
    pub added_fu3: f32,
}

impl VolumeChange {
    /// Removed less added (negative when the step adds clay).
    #[must_use]
    pub fn net_removed_fu3(&self) -> f32 {
        self.removed_fu3 - self.added_fu3
    }

    /// The sum of two steps' changes (a stroke's applications).
    #[must_use]
    pub fn plus(self, other: Self) -> Self {
        Self {
            removed_fu3: self.removed_fu3 + other.removed_fu3,
            added_fu3: self.added_fu3 + other.added_fu3,
        }
    }
}

/// The share of a clay of `volume_fu3` that a net removal of `removed_fu3` takes (0 for an
/// empty clay or a step that adds).
#[must_use]
pub fn removed_fraction(removed_fu3: f32, volume_fu3: f32) -> f32 {
    if volume_fu3 > 0.0 && removed_fu3 > 0.0 {
        (removed_fu3 / volume_fu3).min(1.0)
    } else {
        0.0
    }
}

/// The clay's volume, field units³: the base patch's nodes inside the whole clay.
#[must_use]
pub fn clay_volume_fu3(clay: &Clay) -> f32 {
    let base = clay.base();
    let cell = base.spacing.powi(3);
    let inside = if clay.density.patches.len() == 1 {
        base.coeffs.iter().filter(|&&c| c > base.iso).count()
    } else {
        let [nx, ny, nz] = base.dims;
        let mut n = 0;
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    let x = base.node_position(i, j, k);
                    let v = base.coeffs[base.index(i, j, k)] + others_value(clay, 0, x);
                    n += usize::from(v > base.iso);
                }
            }
        }
        n
    };
    inside as f32 * cell
}

/// The other patches' summed density at `x` (the patch edited is `patch`).
fn others_value(clay: &Clay, patch: usize, x: Vec3) -> f32 {
    clay.density
        .patches
        .iter()
        .enumerate()
        .filter(|&(n, _)| n != patch)
        .map(|(_, p)| p.value(x))
        .sum()
}

/// The nodes of `region` of `lattice` with the clay's density at each, in box order.
fn densities(clay: &Clay, patch: usize, lattice: &BSplineLattice, region: &CoeffBox) -> Vec<f32> {
    let alone = clay.density.patches.len() == 1;
    let mut out = Vec::with_capacity(region.count());
    for k in region.min[2]..=region.max[2] {
        for j in region.min[1]..=region.max[1] {
            for i in region.min[0]..=region.max[0] {
                let c = lattice.coeffs[lattice.index(i, j, k)];
                out.push(if alone {
                    c
                } else {
                    c + others_value(clay, patch, lattice.node_position(i, j, k))
                });
            }
        }
    }
    out
}

/// Counts what went from inside to outside and back between `before` and `after`.
fn compare(before: &[f32], after: &[f32], iso: f32, cell_fu3: f32) -> VolumeChange {
    let (mut removed, mut added) = (0_usize, 0_usize);
    for (&b, &a) in before.iter().zip(after) {
        removed += usize::from(b > iso && a <= iso);
        added += usize::from(b <= iso && a > iso);
    }
    VolumeChange {
        removed_fu3: removed as f32 * cell_fu3,
        added_fu3: added as f32 * cell_fu3,
    }
}

/// The change of `tool` applied at each of `poses` in turn for `dt_each_s` each, on density
/// patch `patch` (none for a missing patch or a painting action). Smoothing is counted as
/// changing nothing: it moves the surface by less than its kernel.
#[must_use]
pub fn tool_volume_change(
    clay: &Clay,
    tool: &GeometricTool,
    poses: &[ToolPose],
    dt_each_s: f32,
    patch: u16,
) -> VolumeChange {
    let n = usize::from(patch);
    let Some(lattice) = clay.density.patches.get(n).map(|p| &p.lattice) else {
        return VolumeChange::default();
    };
    if tool.action.paints() || matches!(tool.action, ToolAction::Smooth { .. }) {
        return VolumeChange::default();
    }
    let half = tool.shape.influence_half_extents(tool.falloff_fu);
    let region = poses
        .iter()
        .filter_map(|pose| {
            let (lo, hi) = pose.world_bounds(half);
            coeff_box_around(lattice, lo, hi, 0)
        })
        .reduce(|a, b| a.union(&b));
    let Some(region) = region else {
        return VolumeChange::default();
    };
    let before = densities(clay, n, lattice, &region);
    let mut after = before.clone();
    let iso = lattice.iso;
    let [nx, ny, _] = region.dims();
    for pose in poses {
        let (lo, hi) = pose.world_bounds(half);
        let Some(b) = coeff_box_around(lattice, lo, hi, 0) else {
            continue;
        };
        for k in b.min[2]..=b.max[2] {
            for j in b.min[1]..=b.max[1] {
                for i in b.min[0]..=b.max[0] {
                    let local = pose.to_local(lattice.node_position(i, j, k));
                    if !local.abs().cmple(half).all() {
                        continue;
                    }
                    let t = tool.shape.density(local, tool.falloff_fu);
                    let at =
                        (i - region.min[0]) + nx * ((j - region.min[1]) + ny * (k - region.min[2]));
                    let old = after[at];
                    after[at] = tool.action.density(old, t, old, iso, dt_each_s);
                }
            }
        }
    }
    compare(&before, &after, iso, lattice.spacing.powi(3))
}

/// The change of CSG `op` (union, intersection or difference) with `other` on density patch
/// `patch`, over the whole patch (none for a missing patch).
#[must_use]
pub fn csg_volume_change(clay: &Clay, other: &Clay, op: ToolAction, patch: u16) -> VolumeChange {
    let n = usize::from(patch);
    let Some(lattice) = clay.density.patches.get(n).map(|p| &p.lattice) else {
        return VolumeChange::default();
    };
    let whole = CoeffBox::whole(lattice.dims);
    let before = densities(clay, n, lattice, &whole);
    let iso = lattice.iso;
    let mut after = Vec::with_capacity(before.len());
    let mut at = 0;
    for k in 0..lattice.dims[2] {
        for j in 0..lattice.dims[1] {
            for i in 0..lattice.dims[0] {
                let t = other
                    .density
                    .value(lattice.node_position(i, j, k))
                    .clamp(0.0, 1.0);
                after.push(op.density(before[at], t, 0.0, iso, 0.0));
                at += 1;
            }
        }
    }
    compare(&before, &after, iso, lattice.spacing.powi(3))
}

#[cfg(test)]
mod tests {
    use std::f32::consts::PI;

    use super::*;
    use crate::field::{Primitive, lattice_from_primitive};
    use crate::tools::ToolShape;

    const H: f32 = 0.1;

    fn ball(centre: Vec3, radius: f32) -> Clay {
        let s = Primitive::Sphere { centre, radius };
        Clay::single(lattice_from_primitive([24; 3], H, Vec3::ZERO, &s, 2.0 * H, 2).unwrap())
    }

    #[test]
    fn the_volume_count_is_the_balls_volume_within_a_knot_cell_of_surface() {
        let r = 0.6;
        let v = clay_volume_fu3(&ball(Vec3::splat(1.15), r));
        let exact = 4.0 / 3.0 * PI * r * r * r;
        // A shell one knot span thick holds the count's error.
        let shell = 4.0 * PI * r * r * H;
        assert!((v - exact).abs() < 0.5 * shell, "{v} vs {exact}");
    }

    #[test]
    fn a_tool_that_takes_most_of_the_clay_is_seen_before_it_is_applied() {
        let centre = Vec3::splat(1.15);
        let clay = ball(centre, 0.5);
        let volume = clay_volume_fu3(&clay);
        let remove = |radius_fu| GeometricTool {
            shape: ToolShape::Sphere { radius_fu },
            action: ToolAction::Remove,
            falloff_fu: H,
        };
        // A tool of radius 0.45 over the ball's centre takes (0.45/0.5)³ = 73% of it.
        let big = tool_volume_change(&clay, &remove(0.45), &[ToolPose::at(centre)], 0.01, 0);
        let share = removed_fraction(big.net_removed_fu3(), volume);
        assert!((share - 0.73).abs() < 0.1, "{share}");
        // A small one at the surface takes a few percent; adding takes nothing.
        let small = tool_volume_change(
            &clay,
            &remove(0.15),
            &[ToolPose::at(centre + Vec3::X * 0.5)],
            0.01,
            0,
        );
        let share = removed_fraction(small.net_removed_fu3(), volume);
        assert!(share > 0.0 && share < 0.05, "{share}");
        let add = GeometricTool {
            action: ToolAction::Add {
                deposit_rate_per_s: 100.0,
            },
            ..remove(0.3)
        };
        let grown =
            tool_volume_change(&clay, &add, &[ToolPose::at(centre + Vec3::X * 0.5)], 1.0, 0);
        assert!(grown.net_removed_fu3() < 0.0 && grown.removed_fu3 == 0.0);
        // The clay itself is untouched by the estimate.
        assert_eq!(clay, ball(centre, 0.5));
    }

    #[test]
    fn an_intersection_with_a_far_clay_removes_everything_and_a_union_nothing() {
        let clay = ball(Vec3::splat(0.8), 0.4);
        let far = ball(Vec3::splat(1.6), 0.3);
        let volume = clay_volume_fu3(&clay);
        let cut = csg_volume_change(&clay, &far, ToolAction::Intersection, 0);
        assert!(removed_fraction(cut.net_removed_fu3(), volume) > 0.99);
        let joined = csg_volume_change(&clay, &far, ToolAction::Union, 0);
        assert_eq!(joined.removed_fu3, 0.0);
        assert!(joined.added_fu3 > 0.0);
    }
}
