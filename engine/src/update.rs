//! The simulation's published state: boxes of coefficients (at most one per density patch) with
//! their current values, plus the stroke and step status the other loops need.
//!
//! Guarantee: [`FieldUpdate::capture`] never allocates once the update was built with
//! [`FieldUpdate::with_capacity_for`] for the field it carries (room for every coefficient of
//! every patch up to [`MAX_UPDATE_COEFFS`], and a box per patch) while the boxes it carries
//! hold at most that many coefficients: the simulation publishes a copy of the clay instead
//! of boxes past it (see `simulation/publication.rs`), so no snapshot buffer grows to the
//! clay's box. [`FieldUpdate::densify_for_copy`] never allocates (it
//! takes dense bricks' storage from a pool), and once it has returned `true`,
//! [`FieldUpdate::copy_into`] of the same update into the same field never allocates either:
//! the haptic loop's copy stays sparse (see [`dynaclay_core::field::BrickedCoeffs`]). All three
//! do work linear in the boxes' coefficient count, which is bounded by the field's size. They
//! are safe on the haptic path. [`FieldUpdate::apply_to`] may make bricks dense (it allocates:
//! the graphics loop's). The stroke
//! geometry has a fixed capacity ([`dynaclay_core::haptics::MAX_STROKE_POINTS`]) and is copied with
//! [`StrokeGeometry::copy_from`], which never allocates.

use glam::Vec3;

use dynaclay_core::field::{BSplineLattice, CoeffBox, MultiPatchField, SpareStorage};
use dynaclay_core::haptics::{FeltTool, StrokeGeometry};
use dynaclay_core::mesh::BrickOctree;

use super::motion_to_photon::StrokeStamps;

/// Most coefficients one [`FieldUpdate`] carries (4 Mi: 16 MiB in each of the six snapshot
/// buffers between the simulation and the haptic and graphics loops). A simulated region's
/// box stays far below it; boxes past it go to the loops as a copy of the clay.
pub const MAX_UPDATE_COEFFS: usize = 4 << 20;

/// One box of coefficients carried by a [`FieldUpdate`]: which density patch, and where.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ChangedBox {
    /// Index of the density patch (eq. (3)'s `i`).
    pub patch: u16,
    /// The coefficient box (inclusive), within the patch's lattice.
    pub coeff_box: CoeffBox,
}

/// Boxes of coefficients copied out of the simulation's field (the payload of the triple
/// buffers from the simulation to the haptic and graphics loops).
///
/// Readers keep a full copy of the field and patch these boxes into it. The boxes are always
/// the whole simulated region plus every coefficient changed elsewhere that some reader may
/// not have seen yet (see the simulation stage), so a reader that skips versions still ends up
/// with the simulation's field.
#[derive(Clone, Debug, PartialEq)]
pub struct FieldUpdate {
    /// The boxes carried, at most one per patch, in the order their coefficients follow.
    pub boxes: Vec<ChangedBox>,
    /// The boxes' coefficients, box after box, x fastest within a box.
    pub coeffs: Vec<f32>,
    /// Whether a stroke was armed by command (in addition to the device's button 0).
    pub stroke_armed: bool,
    /// The held tool, as the haptic loop renders it.
    pub tool: FeltTool,
    /// The held stroke's anchor, pivot, curve and targets (fixed capacity: the haptic loop
    /// copies it without allocating).
    pub stroke: StrokeGeometry,
    /// Simulated time at publication, seconds.
    pub sim_time_s: f64,
    /// Simulation steps taken when this was published.
    pub sim_step: u64,
    /// The patch layout the boxes belong to (see [`super::layout`]): a reader applies them
    /// only to a copy of this generation.
    pub layout: u64,
    /// The newest stroke's way to the screen so far (see [`super::motion_to_photon`]).
    pub stroke_stamps: StrokeStamps,
}

impl FieldUpdate {
    /// An empty update with room for every coefficient of every patch of `field`, at most
    /// [`MAX_UPDATE_COEFFS`], so later captures of boxes that hold at most that many never
    /// allocate.
    #[must_use]
    pub fn with_capacity_for(field: &MultiPatchField) -> Self {
        let total = field
            .patches
            .iter()
            .map(|p| p.lattice.coeffs.len())
            .sum::<usize>()
            .min(MAX_UPDATE_COEFFS);
        Self {
            boxes: Vec::with_capacity(field.patches.len()),
            coeffs: Vec::with_capacity(total),
            stroke_armed: false,
            tool: FeltTool::Push,
            stroke: StrokeGeometry::default(),
            sim_time_s: 0.0,
            sim_step: 0,
            layout: 0,
            stroke_stamps: StrokeStamps::default(),
        }
    }

    /// Forgets the boxes carried.
    pub fn clear(&mut self) {
        self.boxes.clear();
        self.coeffs.clear();
    }

    /// Adds `coeff_box` of patch `patch` of `field` to the boxes carried. A box that does not
    /// fit the lattice is clamped to it; one outside it, or of a patch that does not exist,
    /// adds nothing. Does not allocate when the update has capacity for the field and carries
    /// at most one box per patch.
    pub fn capture(&mut self, field: &MultiPatchField, patch: usize, coeff_box: CoeffBox) {
        let (Some(p), Ok(index)) = (field.patches.get(patch), u16::try_from(patch)) else {
            return;
        };
        let lattice = &p.lattice;
        let Some(b) = coeff_box.clipped(lattice.dims) else {
            return;
        };
        for k in b.min[2]..=b.max[2] {
            for j in b.min[1]..=b.max[1] {
                let row = lattice.index(b.min[0], j, k);
                let len = b.max[0] + 1 - b.min[0];
                lattice.coeffs.extend_row_into(row, len, &mut self.coeffs);
            }
        }
        self.boxes.push(ChangedBox {
            patch: index,
            coeff_box: b,
        });
    }

    /// Whether every box names a patch of `field` and fits its lattice, and the coefficients
    /// add up.
    fn fits(&self, field: &MultiPatchField) -> bool {
        let mut total = 0;
        for b in &self.boxes {
            let Some(p) = field.patches.get(usize::from(b.patch)) else {
                return false;
            };
            if !b.coeff_box.fits(p.lattice.dims) {
                return false;
            }
            total += b.coeff_box.count();
        }
        total == self.coeffs.len()
    }

    /// Makes dense, with storage taken from `spares`, every uniform brick of `field` that
    /// [`FieldUpdate::copy_into`] of this update would make dense, changing no value. Returns
    /// whether `field` is ready: then that copy allocates nothing. `false` means `spares` ran
    /// dry first; the bricks made dense stay so, and a later call (with the pool refilled)
    /// goes on from there. An update that does not fit `field` needs nothing (`true`).
    /// Never allocates.
    pub fn densify_for_copy(
        &self,
        field: &mut MultiPatchField,
        spares: &mut impl SpareStorage,
    ) -> bool {
        if !self.fits(field) {
            return true;
        }
        let mut rest = self.coeffs.as_slice();
        for b in &self.boxes {
            let coeffs = &mut field.patches[usize::from(b.patch)].lattice.coeffs;
            let (mine, after) = rest.split_at(b.coeff_box.count());
            if !coeffs.densify_for_box(b.coeff_box.min, b.coeff_box.dims(), mine, spares) {
                return false;
            }
            rest = after;
        }
        true
    }

    /// Writes the carried coefficients into `field` without tracking what changed: a row copy
    /// per line of each box, for the haptic path, which needs the values but not the changed
    /// box (the per-coefficient comparison in [`FieldUpdate::apply_to`] is the bulk of its
    /// cost). Returns whether the update fitted; one that does not changes nothing.
    pub fn copy_into(&self, field: &mut MultiPatchField) -> bool {
        if self.boxes.is_empty() || !self.fits(field) {
            return false;
        }
        let mut rest = self.coeffs.as_slice();
        for b in &self.boxes {
            let lattice = &mut field.patches[usize::from(b.patch)].lattice;
            let (mine, after) = rest.split_at(b.coeff_box.count());
            copy_box(mine, b.coeff_box, lattice);
            rest = after;
        }
        true
    }

    /// Writes the carried coefficients into `field` and returns the world box outside which
    /// the field did not change (the reach of the coefficients whose value actually changed,
    /// `None` if none did). An update that does not fit the field changes nothing and returns
    /// `None`.
    pub fn apply_to(&self, field: &mut MultiPatchField) -> Option<(Vec3, Vec3)> {
        self.apply_measured(field).map(|c| (c.lo, c.hi))
    }

    /// [`FieldUpdate::apply_to`], also measuring the largest change of any one coefficient.
    pub fn apply_measured(&self, field: &mut MultiPatchField) -> Option<AppliedChange> {
        if !self.fits(field) {
            return None;
        }
        let mut applied: Option<AppliedChange> = None;
        let mut rest = self.coeffs.as_slice();
        for b in &self.boxes {
            let patch = &mut field.patches[usize::from(b.patch)];
            let (mine, after) = rest.split_at(b.coeff_box.count());
            rest = after;
            let Some((changed, largest_move)) = apply_box(mine, b.coeff_box, &mut patch.lattice)
            else {
                continue;
            };
            let (lo, hi) =
                BrickOctree::coefficient_change_box(&patch.lattice, changed.min, changed.max);
            let (lo, hi) = patch.world_box_of(lo, hi);
            let here = AppliedChange {
                lo,
                hi,
                largest_move,
            };
            applied = Some(applied.map_or(here, |a| a.union(&here)));
        }
        applied
    }
}

/// What applying an update changed: the world box outside which the field did not change,
/// and the largest change of a coefficient inside it (coefficient units; infinite when a
/// value was or became non-finite). A coefficient's change bounds the change of the field's
/// value anywhere (a B-spline value is a convex combination of coefficients).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AppliedChange {
    /// The box's low corner, world units.
    pub lo: Vec3,
    /// The box's high corner, world units.
    pub hi: Vec3,
    /// The largest change of any one coefficient, coefficient units.
    pub largest_move: f32,
}

impl AppliedChange {
    /// Both changes: the box holding both boxes, the larger move.
    #[must_use]
    pub fn union(&self, other: &Self) -> Self {
        Self {
            lo: self.lo.min(other.lo),
            hi: self.hi.max(other.hi),
            largest_move: self.largest_move.max(other.largest_move),
        }
    }
}

/// Copies `coeffs` (the box's values, x fastest) into `lattice`; the caller checked the fit.
fn copy_box(coeffs: &[f32], b: CoeffBox, lattice: &mut BSplineLattice) {
    lattice.coeffs.write_box(b.min, b.dims(), coeffs);
}

/// Writes `coeffs` into `lattice` and returns the box of coefficients whose value changed
/// with the largest change (infinite for a non-finite value); the caller checked the fit.
fn apply_box(coeffs: &[f32], b: CoeffBox, lattice: &mut BSplineLattice) -> Option<(CoeffBox, f32)> {
    let mut changed: Option<CoeffBox> = None;
    let mut largest = 0.0f32;
    let len = b.max[0] + 1 - b.min[0];
    let mut src = 0;
    for k in b.min[2]..=b.max[2] {
        for j in b.min[1]..=b.max[1] {
            let from = &coeffs[src..src + len];
            for (n, s) in from.iter().enumerate() {
                let i = b.min[0] + n;
                let d = lattice.coeffs.get(i, j, k);
                // Bit comparison: a changed NaN payload or signed zero still counts.
                if d.to_bits() != s.to_bits() {
                    let moved = (*s - d).abs();
                    largest = largest.max(if moved.is_finite() {
                        moved
                    } else {
                        f32::INFINITY
                    });
                    // May make a uniform brick dense (an allocation: the graphics loop's).
                    lattice.coeffs.set(i, j, k, *s);
                    let p = [i, j, k];
                    changed = Some(changed.map_or(CoeffBox::point(p), |c| c.grown_to(p)));
                }
            }
            src += len;
        }
    }
    changed.map(|c| (c, largest))
}

#[cfg(test)]
mod tests {
    use glam::{Affine3A, Vec3};

    use super::*;
    use dynaclay_core::field::{Patch, SpareBrick, SpareGroup};

    fn lattice(seed: f32) -> BSplineLattice {
        let mut l = BSplineLattice::zeros([6, 5, 7], 0.5, Vec3::ZERO).unwrap();
        l.coeffs.update_each(|i, c| {
            *c = (i as f32 * 0.37 + seed).sin();
        });
        l
    }

    /// A base patch and a finer detail patch shifted by a map.
    fn two_patches(seed: f32) -> MultiPatchField {
        let mut field = MultiPatchField::new(lattice(seed));
        let mut detail = BSplineLattice::zeros([5, 5, 5], 0.25, Vec3::ONE).unwrap();
        detail.coeffs.update_each(|i, c| {
            *c = (i as f32 * 0.11 + seed).cos();
        });
        field.patches.push(Patch {
            lattice: detail,
            world_to_patch: Affine3A::from_translation(Vec3::new(0.5, 0.0, 0.0)),
        });
        field
    }

    /// The measured apply reports the largest change of any one coefficient over every
    /// patch, and an infinite one for a value that became non-finite.
    #[test]
    fn apply_measured_reports_the_largest_coefficient_move() {
        let src = two_patches(1.0);
        let mut moved = src.clone();
        moved.patches[0].lattice.coeffs.add_flat(7, 0.25);
        moved.patches[1].lattice.coeffs.add_flat(11, -0.5);
        let capture = |field: &MultiPatchField| {
            let mut update = FieldUpdate::with_capacity_for(field);
            for (n, p) in field.patches.iter().enumerate() {
                update.capture(field, n, CoeffBox::whole(p.lattice.dims));
            }
            update
        };
        let mut dst = src.clone();
        let change = capture(&moved)
            .apply_measured(&mut dst)
            .expect("the field changed");
        assert_eq!(dst, moved);
        assert!(
            (change.largest_move - 0.5).abs() < 1e-6,
            "{}",
            change.largest_move
        );
        assert_eq!(capture(&moved).apply_measured(&mut dst), None);

        moved.patches[0].lattice.coeffs.set_flat(3, f32::NAN);
        let change = capture(&moved).apply_measured(&mut dst).expect("changed");
        assert_eq!(change.largest_move, f32::INFINITY);
    }

    #[test]
    fn capture_then_apply_copies_the_boxes_and_reports_the_changed_world_box() {
        let src = two_patches(1.0);
        let mut dst = two_patches(1.0);
        let b = CoeffBox {
            min: [1, 1, 2],
            max: [3, 4, 4],
        };
        let mut update = FieldUpdate::with_capacity_for(&src);
        update.capture(&src, 0, b);
        update.capture(&src, 1, b);
        assert_eq!(update.coeffs.len(), 2 * b.count());
        assert_eq!(
            update.apply_to(&mut dst),
            None,
            "identical field: nothing changed"
        );

        let mut moved = src.clone();
        let detail = &mut moved.patches[1].lattice;
        let idx = detail.index(2, 3, 4);
        detail.coeffs.add_flat(idx, 1.0);
        let cap = update.coeffs.capacity();
        update.clear();
        update.capture(&moved, 0, b);
        update.capture(&moved, 1, b);
        assert_eq!(update.coeffs.capacity(), cap, "no reallocation");
        let (lo, hi) = update.apply_to(&mut dst).unwrap();
        assert_eq!(dst, moved);
        // The changed coefficient's reach, mapped back to world space (x shifted by −0.5).
        let node = moved.patches[1].lattice.node_position(2, 3, 4) - Vec3::new(0.5, 0.0, 0.0);
        assert!((lo - (node - Vec3::splat(0.5))).length() < 1e-6, "{lo}");
        assert!((hi - (node + Vec3::splat(0.5))).length() < 1e-6, "{hi}");
    }

    #[test]
    fn copy_into_writes_the_same_field_as_apply_to() {
        let mut moved = two_patches(1.0);
        for n in 40..90 {
            let coeffs = &mut moved.patches[0].lattice.coeffs;
            coeffs.set_flat(n, -coeffs[n]);
        }
        for n in 10..30 {
            let coeffs = &mut moved.patches[1].lattice.coeffs;
            coeffs.set_flat(n, -coeffs[n]);
        }
        let b = CoeffBox {
            min: [0, 1, 1],
            max: [4, 3, 4],
        };
        let mut update = FieldUpdate::with_capacity_for(&moved);
        update.capture(&moved, 1, b);
        update.capture(&moved, 0, b);
        let mut by_apply = two_patches(1.0);
        let mut by_copy = two_patches(1.0);
        assert!(update.apply_to(&mut by_apply).is_some());
        assert!(update.copy_into(&mut by_copy));
        assert_eq!(by_copy, by_apply);
        assert_ne!(by_copy, two_patches(1.0), "the update changed something");
    }

    #[test]
    fn bad_updates_change_nothing() {
        let src = two_patches(0.0);
        let mut dst = two_patches(2.0);
        let before = dst.clone();
        let mut update = FieldUpdate::with_capacity_for(&src);
        let b = CoeffBox {
            min: [0; 3],
            max: [1, 1, 1],
        };
        update.capture(&src, 0, b);
        update.capture(&src, 1, b);
        update.coeffs.pop();
        assert_eq!(update.apply_to(&mut dst), None);
        assert!(!update.copy_into(&mut dst));
        assert_eq!(dst, before);
        // A field with fewer patches than the update names.
        update.coeffs.push(0.0);
        let mut one = MultiPatchField::new(lattice(2.0));
        let one_before = one.clone();
        assert!(!update.copy_into(&mut one));
        assert_eq!(one, one_before);
        update.clear();
        update.capture(
            &src,
            0,
            CoeffBox {
                min: [9, 0, 0],
                max: [9, 1, 1],
            },
        );
        update.capture(&src, 7, b);
        assert!(update.boxes.is_empty());
    }

    /// Spares that run dry after the counts given.
    struct Pool {
        bricks: usize,
        groups: usize,
    }

    impl SpareStorage for Pool {
        fn spare_brick(&mut self) -> Option<SpareBrick> {
            (self.bricks > 0).then(|| {
                self.bricks -= 1;
                SpareBrick::new()
            })
        }
        fn spare_group(&mut self) -> Option<SpareGroup> {
            (self.groups > 0).then(|| {
                self.groups -= 1;
                SpareGroup::new()
            })
        }
    }

    fn dense_bricks(field: &MultiPatchField) -> usize {
        field
            .patches
            .iter()
            .map(|p| p.lattice.coeffs.dense_brick_count())
            .sum()
    }

    /// A sparse copy takes an update that makes uniform bricks dense: the pool's bricks go
    /// where the values changed, a dry pool holds the copy back until it is refilled, and the
    /// copy then writes what `apply_to` writes without making any further brick dense.
    #[test]
    fn a_sparse_copy_prepared_from_spares_takes_the_update_without_new_bricks() {
        let empty =
            MultiPatchField::new(BSplineLattice::zeros([30, 20, 20], 0.5, Vec3::ZERO).unwrap());
        let mut moved = empty.clone();
        // Two coefficients far apart, each in one brick only (no apron copies it).
        moved.patches[0].lattice.coeffs.set(2, 2, 2, 0.5);
        moved.patches[0].lattice.coeffs.set(28, 12, 12, 0.25);
        let mut update = FieldUpdate::with_capacity_for(&moved);
        update.capture(&moved, 0, CoeffBox::whole([30, 20, 20]));

        let mut copy = empty.clone();
        assert_eq!(dense_bricks(&copy), 0);
        let mut pool = Pool {
            bricks: 1,
            groups: 1,
        };
        assert!(
            !update.densify_for_copy(&mut copy, &mut pool),
            "one spare is short"
        );
        assert_eq!(copy, empty, "no value changed meanwhile");
        assert_eq!(dense_bricks(&copy), 1);
        assert_eq!(pool.groups, 0, "the bricks' group took entries once");
        let mut pool = Pool {
            bricks: 1,
            groups: 0,
        };
        assert!(update.densify_for_copy(&mut copy, &mut pool));
        assert_eq!(dense_bricks(&copy), 2);
        assert!(update.copy_into(&mut copy));
        assert_eq!(copy, moved);
        assert_eq!(
            dense_bricks(&copy),
            2,
            "only the bricks whose values changed"
        );

        let mut applied = empty.clone();
        assert!(update.apply_to(&mut applied).is_some());
        assert_eq!(dense_bricks(&applied), dense_bricks(&copy));
        // A second pass needs no spare at all.
        assert!(update.densify_for_copy(
            &mut copy,
            &mut Pool {
                bricks: 0,
                groups: 0
            }
        ));
    }
}
