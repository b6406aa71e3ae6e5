//! A snapshot of the simulated region's coefficients: plain data that the simulation thread
//! publishes and the haptic and graphics threads patch into their own full lattice copies.
//!
//! Copying one snapshot into another ([`RegionSnapshot::copy_from`], `clone_from`) reuses the
//! destination's buffer and allocates nothing when its capacity suffices (always, after the
//! first copy of a region of the same size), so it can be used in place inside triple buffers.

use glam::Vec3;

use super::lattice::BSplineLattice;
use super::mass_grid::CoeffBox;

/// Why a snapshot could not be applied.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SnapshotError {
    /// The snapshot's region does not fit in the lattice.
    #[error(
        "snapshot region at {coeff_origin:?} of size {coeff_dims:?} is outside the lattice {lattice_dims:?}"
    )]
    RegionOutside {
        /// First coefficient of the region.
        coeff_origin: [usize; 3],
        /// Region size in coefficients.
        coeff_dims: [usize; 3],
        /// The lattice's dimensions.
        lattice_dims: [usize; 3],
    },
    /// The coefficient buffer does not hold `coeff_dims` values.
    #[error("snapshot holds {got} coefficients, its region needs {expected}")]
    WrongLength {
        /// Coefficients expected from `coeff_dims`.
        expected: usize,
        /// Coefficients present.
        got: usize,
    },
}

/// The coefficients of a box of the lattice at one version, with the world box whose field
/// values may have changed since the previous version.
#[derive(Debug, Default, PartialEq)]
pub struct RegionSnapshot {
    /// Lattice index of the region's first coefficient.
    pub coeff_origin: [usize; 3],
    /// Region size in coefficients per axis.
    pub coeff_dims: [usize; 3],
    /// The region's coefficients, x fastest.
    pub coeffs: Vec<f32>,
    /// Increases with every published step; 0 means never published.
    pub version: u64,
    /// World-space corner (min) of the box where the field may have changed.
    pub dirty_min: Vec3,
    /// World-space corner (max) of the box where the field may have changed.
    pub dirty_max: Vec3,
}

impl Clone for RegionSnapshot {
    fn clone(&self) -> Self {
        let mut s = Self::default();
        s.copy_from(self);
        s
    }

    fn clone_from(&mut self, source: &Self) {
        self.copy_from(source);
    }
}

impl RegionSnapshot {
    /// An empty snapshot with room for `capacity` coefficients.
    #[must_use]
    pub fn with_capacity(capacity: usize) -> Self {
        Self {
            coeffs: Vec::with_capacity(capacity),
            ..Self::default()
        }
    }

    /// Copy `other` into `self`, reusing `self`'s buffer (no allocation when its capacity
    /// suffices).
    pub fn copy_from(&mut self, other: &Self) {
        self.coeff_origin = other.coeff_origin;
        self.coeff_dims = other.coeff_dims;
        self.coeffs.clear();
        self.coeffs.extend_from_slice(&other.coeffs);
        self.version = other.version;
        self.dirty_min = other.dirty_min;
        self.dirty_max = other.dirty_max;
    }

    /// Fill from `values`, the coefficients of `region` (x fastest) just written into
    /// `lattice`, at `version`: as [`RegionSnapshot::capture`] without reading them back out
    /// of the lattice's bricks. Reuses the buffer.
    ///
    /// # Panics
    /// When `region` does not fit in the lattice or `values` does not hold one value per
    /// coefficient of it.
    pub fn capture_written(
        &mut self,
        lattice: &BSplineLattice,
        region: CoeffBox,
        values: &[f32],
        version: u64,
    ) {
        assert!(region.fits(lattice.dims), "region outside the lattice");
        assert_eq!(values.len(), region.count(), "one value per coefficient");
        self.coeff_origin = region.min;
        self.coeff_dims = region.dims();
        self.coeffs.clear();
        self.coeffs.extend_from_slice(values);
        self.version = version;
        let (lo, hi) = region.world_support(lattice);
        self.dirty_min = lo;
        self.dirty_max = hi;
    }

    /// Fill from the coefficients of `region` in `lattice`, at `version`; the dirty box is the
    /// support of the region's coefficients. Reuses the buffer.
    ///
    /// # Panics
    /// When `region` does not fit in the lattice.
    pub fn capture(&mut self, lattice: &BSplineLattice, region: CoeffBox, version: u64) {
        assert!(region.fits(lattice.dims), "region outside the lattice");
        let n = region.dims();
        self.coeff_origin = region.min;
        self.coeff_dims = n;
        self.coeffs.clear();
        self.coeffs.resize(region.count(), 0.0);
        lattice.coeffs.read_box(region.min, n, &mut self.coeffs);
        self.version = version;
        let (lo, hi) = region.world_support(lattice);
        self.dirty_min = lo;
        self.dirty_max = hi;
    }

    /// The region as a coefficient box, or `None` when it is empty.
    #[must_use]
    pub fn region(&self) -> Option<CoeffBox> {
        if self.coeff_dims.contains(&0) {
            return None;
        }
        Some(CoeffBox {
            min: self.coeff_origin,
            max: [
                self.coeff_origin[0] + self.coeff_dims[0] - 1,
                self.coeff_origin[1] + self.coeff_dims[1] - 1,
                self.coeff_origin[2] + self.coeff_dims[2] - 1,
            ],
        })
    }

    /// Write the region's coefficients into `lattice` (a full copy kept by a reader thread).
    /// An empty snapshot changes nothing. Allocates nothing.
    ///
    /// # Errors
    /// When the region does not fit the lattice or the buffer has the wrong length; the lattice
    /// is then unchanged.
    pub fn apply_to(&self, lattice: &mut BSplineLattice) -> Result<(), SnapshotError> {
        let expected = self.coeff_dims.iter().product::<usize>();
        if self.coeffs.len() != expected {
            return Err(SnapshotError::WrongLength {
                expected,
                got: self.coeffs.len(),
            });
        }
        let Some(region) = self.region() else {
            return Ok(());
        };
        if !region.fits(lattice.dims) {
            return Err(SnapshotError::RegionOutside {
                coeff_origin: self.coeff_origin,
                coeff_dims: self.coeff_dims,
                lattice_dims: lattice.dims,
            });
        }
        lattice
            .coeffs
            .write_box(region.min, self.coeff_dims, &self.coeffs);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lattice() -> BSplineLattice {
        let mut l = BSplineLattice::zeros([8, 7, 6], 0.5, Vec3::ONE).unwrap();
        l.coeffs.update_each(|n, c| {
            *c = n as f32;
        });
        l
    }

    #[test]
    fn capture_then_apply_round_trips_only_the_region() {
        let src = lattice();
        let region = CoeffBox {
            min: [2, 1, 3],
            max: [5, 4, 5],
        };
        let mut snap = RegionSnapshot::default();
        snap.capture(&src, region, 7);
        assert_eq!(snap.coeffs.len(), 4 * 4 * 3);
        // The values written into a lattice, captured as written, equal those read back.
        let mut written = RegionSnapshot::default();
        written.capture_written(&src, region, &snap.coeffs, 7);
        assert_eq!(written, snap);
        let mut dst = BSplineLattice::zeros(src.dims, src.spacing, src.origin).unwrap();
        snap.apply_to(&mut dst).unwrap();
        for k in 0..6 {
            for j in 0..7 {
                for i in 0..8 {
                    let idx = src.index(i, j, k);
                    let want = if region.contains(i, j, k) {
                        src.coeffs[idx]
                    } else {
                        0.0
                    };
                    assert_eq!(dst.coeffs[idx], want);
                }
            }
        }
        assert_eq!(snap.version, 7);
        assert_eq!(snap.dirty_min, Vec3::ONE + 0.5 * Vec3::new(0.0, -1.0, 1.0));
    }

    #[test]
    fn copy_from_reuses_capacity() {
        let src = lattice();
        let region = CoeffBox {
            min: [0, 0, 0],
            max: [3, 3, 3],
        };
        let mut a = RegionSnapshot::default();
        a.capture(&src, region, 1);
        let mut b = RegionSnapshot::with_capacity(64);
        let ptr = b.coeffs.as_ptr();
        b.clone_from(&a);
        assert_eq!(b, a);
        assert_eq!(b.coeffs.as_ptr(), ptr, "buffer was reallocated");
    }

    #[test]
    fn apply_rejects_mismatches_without_writing() {
        let mut dst = lattice();
        let before = dst.clone();
        let mut snap = RegionSnapshot {
            coeff_origin: [6, 0, 0],
            coeff_dims: [4, 1, 1],
            coeffs: vec![0.0; 4],
            ..RegionSnapshot::default()
        };
        assert!(matches!(
            snap.apply_to(&mut dst),
            Err(SnapshotError::RegionOutside { .. })
        ));
        snap.coeffs.pop();
        assert!(matches!(
            snap.apply_to(&mut dst),
            Err(SnapshotError::WrongLength { .. })
        ));
        assert_eq!(dst, before);
    }
}
