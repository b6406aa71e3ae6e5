//! The regular grid on which the field is sampled: sample `(i, j, k)` sits at
//! `origin + cell_size · (i, j, k)`, for `0 ≤ i ≤ cells[0]` and likewise per axis.
//!
//! Every sample position is computed from its global integer index by the same expression, so
//! two bricks that share a sample compute bit-identical positions (and hence values).

use glam::Vec3;

use super::error::GridError;
use crate::field::{BSplineLattice, MultiPatchField};

/// A regular sampling grid (virtual resolution `cells`, stored sparsely by the octree).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SampleGrid {
    /// World position of sample (0, 0, 0).
    pub origin: Vec3,
    /// Edge length of one cubic cell, in world units.
    pub cell_size: f32,
    /// Cells per axis; samples per axis are one more.
    pub cells: [u32; 3],
}

impl SampleGrid {
    /// Most cells per axis (edge ids pack each sample coordinate in 20 bits).
    pub const MAX_CELLS: u32 = (1 << 20) - 2;

    /// A grid with the given origin, cell size and cell counts.
    ///
    /// # Errors
    /// When the cell size is not positive and finite, the origin is not finite, or an axis has
    /// zero or more than [`SampleGrid::MAX_CELLS`] cells.
    pub fn new(origin: Vec3, cell_size: f32, cells: [u32; 3]) -> Result<Self, GridError> {
        if !(cell_size.is_finite() && cell_size > 0.0) {
            return Err(GridError::BadCellSize { cell_size });
        }
        if !origin.is_finite() {
            return Err(GridError::BadOrigin { origin });
        }
        if cells.iter().any(|&n| n == 0 || n > Self::MAX_CELLS) {
            return Err(GridError::BadCellCount { cells });
        }
        Ok(Self {
            origin,
            cell_size,
            cells,
        })
    }

    /// The smallest grid with this cell size whose samples span the box `min..=max`.
    ///
    /// # Errors
    /// When the box is inverted or not finite, or as [`SampleGrid::new`].
    pub fn covering(min: Vec3, max: Vec3, cell_size: f32) -> Result<Self, GridError> {
        if !(min.is_finite() && max.is_finite()) || min.cmpgt(max).any() {
            return Err(GridError::BadBox { min, max });
        }
        if !(cell_size.is_finite() && cell_size > 0.0) {
            return Err(GridError::BadCellSize { cell_size });
        }
        let extent = ((max - min) / cell_size).ceil().max(Vec3::ONE);
        let cells = [extent.x, extent.y, extent.z].map(|e| {
            if e > Self::MAX_CELLS as f32 {
                u32::MAX
            } else {
                e as u32
            }
        });
        Self::new(min, cell_size, cells)
    }

    /// A grid over the whole support of a lattice (where the field can be non-zero), with
    /// `cells_per_span` cells per knot span: cell size = lattice spacing / `cells_per_span`.
    ///
    /// The field is zero — outside — on this grid's boundary, so the extracted surface is
    /// closed.
    ///
    /// # Errors
    /// When `cells_per_span` is zero or the grid would exceed [`SampleGrid::MAX_CELLS`].
    pub fn for_lattice(lattice: &BSplineLattice, cells_per_span: u32) -> Result<Self, GridError> {
        if cells_per_span == 0 {
            return Err(GridError::BadCellCount { cells: [0; 3] });
        }
        let (min, _) = lattice.support();
        let cells = lattice.dims.map(|n| {
            // The support spans n + 3 knot spans.
            u64::try_from(n + 3)
                .unwrap_or(u64::MAX)
                .saturating_mul(u64::from(cells_per_span))
                .min(u64::from(u32::MAX)) as u32
        });
        Self::new(min, lattice.spacing / cells_per_span as f32, cells)
    }

    /// Most halvings of the base's knot spacing a uniform grid over a whole multi-patch field
    /// follows (see [`SampleGrid::for_field`]).
    pub const UNIFORM_LEVELS: u32 = 2;

    /// The knot spacing a uniform grid over `field` follows: its finest, but no finer than
    /// [`SampleGrid::UNIFORM_LEVELS`] halvings of the base patch's (infinite without patches).
    #[must_use]
    pub fn uniform_spacing(field: &MultiPatchField) -> f32 {
        let floor = field.patches.first().map_or(0.0, |base| {
            base.world_spacing() / (1 << Self::UNIFORM_LEVELS) as f32
        });
        field.finest_spacing().max(floor)
    }

    /// A grid over the support of every patch of a multi-patch field at its finest spacing,
    /// with `cells_per_span` cells per finest knot span, but no finer than
    /// [`SampleGrid::UNIFORM_LEVELS`] halvings of the base's spacing: one grid over the whole
    /// clay at a deep level's spacing would cost the whole surface at that level
    /// ([`super::mesh_adaptive`] meshes each level at its own spacing). A field of one patch in
    /// world coordinates gets exactly [`SampleGrid::for_lattice`]'s grid.
    ///
    /// # Errors
    /// When the field has no patch, `cells_per_span` is zero, or the grid would exceed
    /// [`SampleGrid::MAX_CELLS`] per axis.
    pub fn for_field(field: &MultiPatchField, cells_per_span: u32) -> Result<Self, GridError> {
        match field.patches.as_slice() {
            [] => Err(GridError::BadCellCount { cells: [0; 3] }),
            [only] if only.is_identity() => Self::for_lattice(&only.lattice, cells_per_span),
            _ => {
                if cells_per_span == 0 {
                    return Err(GridError::BadCellCount { cells: [0; 3] });
                }
                let (min, max) = field.support();
                Self::covering(
                    min,
                    max,
                    Self::uniform_spacing(field) / cells_per_span as f32,
                )
            }
        }
    }

    /// World position of sample `(i, j, k)`.
    #[inline]
    #[must_use]
    pub fn point(&self, index: [u32; 3]) -> Vec3 {
        Vec3::new(
            self.origin.x + self.cell_size * index[0] as f32,
            self.origin.y + self.cell_size * index[1] as f32,
            self.origin.z + self.cell_size * index[2] as f32,
        )
    }

    /// World coordinate of sample `index` along one axis (the same expression as `point`).
    #[inline]
    #[must_use]
    pub fn coordinate(&self, axis: usize, index: u32) -> f32 {
        self.origin[axis] + self.cell_size * index as f32
    }

    /// The far corner of the grid (position of the last sample).
    #[must_use]
    pub fn max_corner(&self) -> Vec3 {
        self.point(self.cells)
    }

    /// Range of sample indices (inclusive) strictly inside the box `min..max`, per axis, or
    /// `None` when no sample is. Samples within 1e-4 cell of a face count as on the face,
    /// i.e. outside: a field whose change is confined to the box (a B-spline edit, whose
    /// change and its gradient vanish on the support's boundary) has not changed there.
    #[must_use]
    pub fn interior_sample_range(&self, min: Vec3, max: Vec3) -> Option<([u32; 3], [u32; 3])> {
        const ON_FACE: f32 = 1e-4;
        let mut lo = [0u32; 3];
        let mut hi = [0u32; 3];
        for axis in 0..3 {
            let a = (min[axis] - self.origin[axis]) / self.cell_size;
            let b = (max[axis] - self.origin[axis]) / self.cell_size;
            if !(a.is_finite() && b.is_finite()) {
                return None;
            }
            let first = ((a + ON_FACE).floor() + 1.0).max(0.0);
            let last = ((b - ON_FACE).ceil() - 1.0).min(self.cells[axis] as f32);
            if first > last {
                return None;
            }
            lo[axis] = first as u32;
            hi[axis] = last as u32;
        }
        Some((lo, hi))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rejects_bad_parameters() {
        assert!(SampleGrid::new(Vec3::ZERO, 0.0, [4; 3]).is_err());
        assert!(SampleGrid::new(Vec3::NAN, 1.0, [4; 3]).is_err());
        assert!(SampleGrid::new(Vec3::ZERO, 1.0, [4, 0, 4]).is_err());
        assert!(SampleGrid::covering(Vec3::ONE, Vec3::ZERO, 0.1).is_err());
        assert!(SampleGrid::covering(Vec3::ZERO, Vec3::ONE, 1e-9).is_err());
    }

    #[test]
    fn covering_grid_spans_the_box() {
        let g = SampleGrid::covering(Vec3::new(-1.0, 0.0, 2.0), Vec3::new(1.0, 0.5, 2.1), 0.25)
            .unwrap();
        assert_eq!(g.cells, [8, 2, 1]);
        assert!(g.max_corner().cmpge(Vec3::new(1.0, 0.5, 2.1) - 1e-6).all());
    }

    #[test]
    fn lattice_grid_covers_the_support() {
        let lattice = BSplineLattice::zeros([6, 5, 4], 0.5, Vec3::ZERO).unwrap();
        let g = SampleGrid::for_lattice(&lattice, 4).unwrap();
        let (lo, hi) = lattice.support();
        assert_eq!(g.origin, lo);
        assert_eq!(g.cells, [36, 32, 28]);
        assert!((g.max_corner() - hi).abs().max_element() < 1e-5);
    }

    #[test]
    fn interior_sample_range_excludes_faces_and_clamps() {
        let g = SampleGrid::new(Vec3::ZERO, 1.0, [10; 3]).unwrap();
        let r = g.interior_sample_range(Vec3::splat(2.5), Vec3::splat(4.5));
        assert_eq!(r, Some(([3; 3], [4; 3])));
        // Samples on the faces (2 and 6) are not inside.
        let r = g.interior_sample_range(Vec3::splat(2.0), Vec3::splat(6.0));
        assert_eq!(r, Some(([3; 3], [5; 3])));
        let r = g.interior_sample_range(Vec3::splat(2.0 - 1e-6), Vec3::splat(6.0 + 1e-6));
        assert_eq!(r, Some(([3; 3], [5; 3])));
        let r = g.interior_sample_range(Vec3::splat(-5.0), Vec3::splat(50.0));
        assert_eq!(r, Some(([0; 3], [10; 3])));
        assert!(
            g.interior_sample_range(Vec3::splat(20.0), Vec3::splat(30.0))
                .is_none()
        );
        assert!(
            g.interior_sample_range(Vec3::splat(3.0), Vec3::splat(4.0))
                .is_none()
        );
        assert!(
            g.interior_sample_range(Vec3::splat(3.2), Vec3::splat(3.1))
                .is_none()
        );
    }
}
