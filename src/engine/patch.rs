//! The simulation's published state: a box of coefficients with their current values, plus the
//! stroke and step status the other loops need.
//!
//! Guarantee: [`FieldPatch::capture`] and [`FieldPatch::apply_to`] never allocate once the
//! patch was built with [`FieldPatch::with_capacity_for`] for the lattice it carries (capacity
//! for every coefficient), and do work linear in the box's coefficient count, which is bounded
//! by the lattice size. They are safe on the haptic path. The stroke geometry has a fixed
//! capacity ([`crate::haptics::MAX_STROKE_POINTS`]) and is copied with
//! [`StrokeGeometry::copy_from`], which never allocates.

use crate::field::{BSplineLattice, CoeffBox};
use crate::haptics::{FeltTool, StrokeGeometry};

/// A box of coefficients copied out of the simulation's lattice (the payload of the triple
/// buffers from the simulation to the haptic and graphics loops).
///
/// Readers keep a full copy of the lattice and patch this box into it. The box is always the
/// whole simulated region plus every coefficient changed elsewhere that some reader may not
/// have seen yet (see the simulation stage), so a reader that skips versions still ends up
/// with the simulation's field.
#[derive(Clone, Debug, PartialEq)]
pub struct FieldPatch {
    /// The coefficient box carried (inclusive); `None` for a patch that carries nothing.
    pub coeff_box: Option<CoeffBox>,
    /// The box's coefficients, x fastest within the box.
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
}

impl FieldPatch {
    /// An empty patch with room for every coefficient of `lattice`, so later captures of any
    /// box never allocate.
    #[must_use]
    pub fn with_capacity_for(lattice: &BSplineLattice) -> Self {
        Self {
            coeff_box: None,
            coeffs: Vec::with_capacity(lattice.coeffs.len()),
            stroke_armed: false,
            tool: FeltTool::Push,
            stroke: StrokeGeometry::default(),
            sim_time_s: 0.0,
            sim_step: 0,
        }
    }

    /// Copies `coeff_box` of `lattice` into this patch (replacing what it held).
    ///
    /// A box that does not fit the lattice is clamped to it. Does not allocate when the patch
    /// has capacity for the lattice.
    pub fn capture(&mut self, lattice: &BSplineLattice, coeff_box: CoeffBox) {
        self.coeffs.clear();
        let Some(b) = coeff_box.clipped(lattice.dims) else {
            self.coeff_box = None;
            return;
        };
        for k in b.min[2]..=b.max[2] {
            for j in b.min[1]..=b.max[1] {
                let row = lattice.index(b.min[0], j, k);
                let len = b.max[0] + 1 - b.min[0];
                self.coeffs
                    .extend_from_slice(&lattice.coeffs[row..row + len]);
            }
        }
        self.coeff_box = Some(b);
    }

    /// Writes the carried coefficients into `lattice` without tracking what changed: a row
    /// copy per line of the box, for the haptic path, which needs the values but not the
    /// changed box (the per-coefficient comparison in [`FieldPatch::apply_to`] is the bulk of
    /// its cost). Returns whether the patch fitted; one that does not changes nothing.
    pub fn copy_into(&self, lattice: &mut BSplineLattice) -> bool {
        let Some(b) = self.coeff_box else {
            return false;
        };
        if !b.fits(lattice.dims) || b.count() != self.coeffs.len() {
            return false;
        }
        let len = b.max[0] + 1 - b.min[0];
        let mut rows = self.coeffs.chunks_exact(len);
        for k in b.min[2]..=b.max[2] {
            for j in b.min[1]..=b.max[1] {
                let row = lattice.index(b.min[0], j, k);
                // The length check above guarantees one chunk per row.
                if let Some(from) = rows.next() {
                    lattice.coeffs[row..row + len].copy_from_slice(from);
                }
            }
        }
        true
    }

    /// Writes the carried coefficients into `lattice` and returns the box of coefficients
    /// whose value actually changed (`None` if none did). A patch whose box does not fit the
    /// lattice, or whose length is wrong, changes nothing and returns `None`.
    pub fn apply_to(&self, lattice: &mut BSplineLattice) -> Option<CoeffBox> {
        let b = self.coeff_box?;
        if !b.fits(lattice.dims) || b.count() != self.coeffs.len() {
            return None;
        }
        let mut changed: Option<CoeffBox> = None;
        let len = b.max[0] + 1 - b.min[0];
        let mut src = 0;
        for k in b.min[2]..=b.max[2] {
            for j in b.min[1]..=b.max[1] {
                let row = lattice.index(b.min[0], j, k);
                let dst = &mut lattice.coeffs[row..row + len];
                let from = &self.coeffs[src..src + len];
                for (i, (d, s)) in dst.iter_mut().zip(from).enumerate() {
                    // Bit comparison: a changed NaN payload or signed zero still counts.
                    if d.to_bits() != s.to_bits() {
                        *d = *s;
                        let p = [b.min[0] + i, j, k];
                        changed = Some(changed.map_or(CoeffBox::point(p), |c| c.grown_to(p)));
                    }
                }
                src += len;
            }
        }
        changed
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn lattice(seed: f32) -> BSplineLattice {
        let mut l = BSplineLattice::zeros([6, 5, 7], 0.5, Vec3::ZERO).unwrap();
        for (i, c) in l.coeffs.iter_mut().enumerate() {
            *c = (i as f32 * 0.37 + seed).sin();
        }
        l
    }

    #[test]
    fn capture_then_apply_copies_the_box_and_reports_changes() {
        let src = lattice(1.0);
        let mut dst = lattice(1.0);
        let b = CoeffBox {
            min: [1, 1, 2],
            max: [3, 4, 5],
        };
        let mut patch = FieldPatch::with_capacity_for(&src);
        patch.capture(&src, b);
        assert_eq!(patch.coeffs.len(), b.count());
        assert_eq!(
            patch.apply_to(&mut dst),
            None,
            "identical field: nothing changed"
        );

        let mut moved = src.clone();
        let idx = moved.index(2, 3, 4);
        moved.coeffs[idx] += 1.0;
        let cap = patch.coeffs.capacity();
        patch.capture(&moved, b);
        assert_eq!(patch.coeffs.capacity(), cap, "no reallocation");
        let changed = patch.apply_to(&mut dst).unwrap();
        assert_eq!(
            changed,
            CoeffBox {
                min: [2, 3, 4],
                max: [2, 3, 4]
            }
        );
        assert_eq!(dst, moved);
    }

    #[test]
    fn copy_into_writes_the_same_field_as_apply_to() {
        let mut moved = lattice(1.0);
        for c in &mut moved.coeffs[40..90] {
            *c = -*c;
        }
        let b = CoeffBox {
            min: [0, 1, 1],
            max: [5, 3, 6],
        };
        let mut patch = FieldPatch::with_capacity_for(&moved);
        patch.capture(&moved, b);
        let mut by_apply = lattice(1.0);
        let mut by_copy = lattice(1.0);
        assert!(patch.apply_to(&mut by_apply).is_some());
        assert!(patch.copy_into(&mut by_copy));
        assert_eq!(by_copy, by_apply);
        assert_ne!(by_copy, lattice(1.0), "the patch changed something");
    }

    #[test]
    fn bad_patches_change_nothing() {
        let src = lattice(0.0);
        let mut dst = lattice(2.0);
        let before = dst.clone();
        let mut patch = FieldPatch::with_capacity_for(&src);
        patch.capture(
            &src,
            CoeffBox {
                min: [0; 3],
                max: [1, 1, 1],
            },
        );
        patch.coeffs.pop();
        assert_eq!(patch.apply_to(&mut dst), None);
        assert!(!patch.copy_into(&mut dst));
        assert_eq!(dst, before);
        patch.capture(
            &src,
            CoeffBox {
                min: [9, 0, 0],
                max: [9, 1, 1],
            },
        );
        assert_eq!(patch.coeff_box, None);
    }
}
