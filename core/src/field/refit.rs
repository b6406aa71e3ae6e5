//! Least-squares fitting of coefficients to a target function: `p = (AᵀA)⁻¹ Aᵀ d`, over the
//! whole lattice or over a box of coefficients with everything outside held fixed.
//!
//! The target is sampled on the mass grid spanning the box's coefficient nodes with
//! `samples_per_span` points per knot span (see [`MassGrid`]). For a local refit the fixed
//! contribution of the coefficients outside the box is subtracted from the samples first, so
//! the box's coefficients fit the remainder; coefficients outside the box are never written
//! (bit-identical). `(AᵀA)⁻¹` is the Kronecker product of three per-axis banded Cholesky
//! solves, so a fit costs a few dozen flops per sample.
//!
//! Where the fit is exact: any target that is itself a spline on the lattice (a sum of the
//! basis functions, outside ones included) is recovered exactly, up to f32 rounding. A linear
//! target is such a spline where all four coefficients per axis exist — the lattice's
//! [`BSplineLattice::exact_domain`]; so a local refit of a linear function reproduces it
//! exactly when the box lies at least one coefficient inside the lattice and the outside
//! coefficients already carry it. Against the lattice's edge (where coefficients beyond count
//! as zero) a linear target is only approximated.

use glam::Vec3;

use super::kron::KronScratch;
use super::lattice::BSplineLattice;
use super::mass_grid::{CoeffBox, MassGrid};

/// Why a fit could not run.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum FitError {
    /// The coefficient box is empty or reaches beyond the lattice.
    #[error("coefficient box {:?}..={:?} is empty or outside the lattice {dims:?}", .coeffs.min, .coeffs.max)]
    BadBox {
        /// The box asked for.
        coeffs: CoeffBox,
        /// The lattice's dimensions.
        dims: [usize; 3],
    },
    /// `samples_per_span` was zero.
    #[error("samples_per_span must be at least 1")]
    NoSamples,
    /// The target returned a NaN or an infinity at this world point.
    #[error("target is not finite at world point {at:?}")]
    NonFiniteTarget {
        /// Where the target was sampled.
        at: [f32; 3],
    },
}

/// Least-squares refit of the coefficients in `coeff_min ..= coeff_max` (inclusive, lattice
/// indices) to `target`, sampled at `samples_per_span` points per knot span on the box's mass
/// grid. Coefficients outside the box stay bit-identical.
///
/// # Errors
/// [`FitError::BadBox`] when the box is empty or not inside the lattice, [`FitError::NoSamples`]
/// when `samples_per_span` is zero, [`FitError::NonFiniteTarget`] when the target is not finite
/// somewhere (the lattice is left unchanged).
pub fn refit_box(
    lattice: &mut BSplineLattice,
    coeff_min: [usize; 3],
    coeff_max: [usize; 3],
    samples_per_span: usize,
    target: impl Fn(Vec3) -> f32,
) -> Result<(), FitError> {
    refit(
        lattice,
        coeff_min,
        coeff_max,
        samples_per_span,
        false,
        |row: SampleRow<'_>| edit_each(row, &|x, _| target(x)),
    )
}

/// [`refit_box`] for an edit of the field: `edit(x, old)` gets the field's value at `x` before
/// the refit. The old values come from the lattice by the separable operator (the box's
/// coefficients through `A`, three 1-D passes, plus the fixed part of those outside), about
/// a fifth of the work of evaluating each sample's 4×4×4 stencil; an edit that leaves most
/// samples as they were costs little more than the fit itself.
///
/// # Errors
/// As [`refit_box`].
pub fn refit_box_edit(
    lattice: &mut BSplineLattice,
    coeff_min: [usize; 3],
    coeff_max: [usize; 3],
    samples_per_span: usize,
    edit: impl Fn(Vec3, f32) -> f32,
) -> Result<(), FitError> {
    refit(
        lattice,
        coeff_min,
        coeff_max,
        samples_per_span,
        true,
        |row: SampleRow<'_>| edit_each(row, &edit),
    )
}

/// One row of the sample grid along x, handed to a row edit: the samples lie at
/// `(xs[i], y, z)` (`xs` ascending), and `values[i]` holds the field's value there before the
/// edit; the edit overwrites the values it changes and leaves the rest.
pub struct SampleRow<'a> {
    /// The samples' x coordinates, ascending.
    pub xs: &'a [f32],
    /// The row's y coordinate.
    pub y: f32,
    /// The row's z coordinate.
    pub z: f32,
    /// The old values on entry, the edited ones on return.
    pub values: &'a mut [f32],
}

/// [`refit_box_edit`] a row at a time: `edit_row` sees every row of the sample grid once, in
/// order (x fastest, then y, then z), and can pass over the part of a row it cannot reach
/// without looking at each sample. The result is the same as [`refit_box_edit`] with the
/// per-sample rule the row edit applies.
///
/// # Errors
/// As [`refit_box`].
pub fn refit_box_edit_rows(
    lattice: &mut BSplineLattice,
    coeff_min: [usize; 3],
    coeff_max: [usize; 3],
    samples_per_span: usize,
    edit_row: impl FnMut(SampleRow<'_>),
) -> Result<(), FitError> {
    refit(
        lattice,
        coeff_min,
        coeff_max,
        samples_per_span,
        true,
        edit_row,
    )
}

/// Applies a per-sample `edit(x, old)` to every sample of a row.
#[inline]
fn edit_each(row: SampleRow<'_>, edit: &impl Fn(Vec3, f32) -> f32) {
    for (&x, v) in row.xs.iter().zip(row.values.iter_mut()) {
        *v = edit(Vec3::new(x, row.y, row.z), *v);
    }
}

/// The refit of [`refit_box`] and [`refit_box_edit`]; `old` (the pre-edit field at each
/// sample) is computed only when `want_old`, else the rows get the fixed part alone.
fn refit(
    lattice: &mut BSplineLattice,
    coeff_min: [usize; 3],
    coeff_max: [usize; 3],
    samples_per_span: usize,
    want_old: bool,
    mut edit_row: impl FnMut(SampleRow<'_>),
) -> Result<(), FitError> {
    let coeffs = CoeffBox {
        min: coeff_min,
        max: coeff_max,
    };
    if !coeffs.fits(lattice.dims) {
        return Err(FitError::BadBox {
            coeffs,
            dims: lattice.dims,
        });
    }
    if samples_per_span == 0 {
        return Err(FitError::NoSamples);
    }
    let grid = MassGrid::with_samples_per_span(coeffs, samples_per_span);
    let basis = grid
        .basis()
        .expect("a grid spanning its own nodes is well posed");
    let [mx, my, mz] = grid.dims;
    let n = coeffs.dims();
    let mut scratch = KronScratch::for_basis(&basis);

    // The fixed contribution of the coefficients outside the box at every sample and, for an
    // edit, the box's own contribution (so `fixed + inside` is the field before the edit).
    let mut fixed = vec![0.0_f32; grid.count()];
    grid.fixed_outside_with(lattice, &mut fixed, Some(scratch.arrays()));
    // The values handed to the rows: the old field, then the edited one.
    let mut values = if want_old {
        let mut p_box = vec![0.0_f32; coeffs.count()];
        for k in 0..n[2] {
            for j in 0..n[1] {
                let row = lattice.index(coeffs.min[0], coeffs.min[1] + j, coeffs.min[2] + k);
                lattice.coeffs.read_row(
                    row,
                    &mut p_box[n[0] * (j + n[1] * k)..n[0] * (j + 1 + n[1] * k)],
                );
            }
        }
        let mut inside = vec![0.0_f32; grid.count()];
        basis.apply(&p_box, &mut inside, &mut scratch);
        for (v, f) in inside.iter_mut().zip(&fixed) {
            *v += f;
        }
        inside
    } else {
        fixed.clone()
    };

    // The sample positions, per axis (the grid is a tensor product): the same values
    // `MassGrid::position` gives.
    let axis_positions = |axis: usize, count: usize| -> Vec<f32> {
        (0..count)
            .map(|t| {
                let mut at = [0; 3];
                at[axis] = t;
                grid.position(lattice, at[0], at[1], at[2])[axis]
            })
            .collect()
    };
    let (xs, ys, zs) = (
        axis_positions(0, mx),
        axis_positions(1, my),
        axis_positions(2, mz),
    );
    for (plane, &z) in values.chunks_exact_mut(mx * my).zip(&zs) {
        for (row, &y) in plane.chunks_exact_mut(mx).zip(&ys) {
            edit_row(SampleRow {
                xs: &xs,
                y,
                z,
                values: row,
            });
        }
    }
    // Samples of the target minus the fixed contribution.
    let mut residual = fixed;
    let mut finite = true;
    for (r, &v) in residual.iter_mut().zip(&values) {
        finite &= v.is_finite();
        *r = v - *r;
    }
    if !finite {
        let at = values
            .iter()
            .position(|v| !v.is_finite())
            .expect("a non-finite value was seen");
        let (i, j, k) = (at % mx, (at / mx) % my, at / (mx * my));
        return Err(FitError::NonFiniteTarget {
            at: [xs[i], ys[j], zs[k]],
        });
    }

    let mut p = vec![0.0_f32; coeffs.count()];
    let mut b = vec![0.0_f32; coeffs.count()];
    basis.apply_transpose(&residual, &mut b, &mut scratch);
    basis.solve_gram_into(&b, &mut p, &mut scratch);

    lattice.coeffs.write_box(coeffs.min, n, &p);
    Ok(())
}

/// Least-squares fit of every coefficient of `lattice` to `target` (a [`refit_box`] over the
/// whole lattice).
///
/// # Errors
/// As [`refit_box`].
pub fn fit_lattice(
    lattice: &mut BSplineLattice,
    samples_per_span: usize,
    target: impl Fn(Vec3) -> f32,
) -> Result<(), FitError> {
    let whole = CoeffBox::whole(lattice.dims);
    refit_box(lattice, whole.min, whole.max, samples_per_span, target)
}

/// The smallest coefficient box (clamped to the lattice) whose coefficients influence the
/// world box `lo ..= hi`, grown by `margin` coefficients on every side. `None` when the world
/// box misses the lattice's support entirely.
#[must_use]
pub fn coeff_box_around(
    lattice: &BSplineLattice,
    lo: Vec3,
    hi: Vec3,
    margin: usize,
) -> Option<CoeffBox> {
    let (ulo, uhi) = (lattice.to_lattice(lo), lattice.to_lattice(hi));
    let mut min = [0; 3];
    let mut max = [0; 3];
    for a in 0..3 {
        // Coefficient c influences lattice coordinates (c − 2, c + 2).
        let first = (ulo[a] - 2.0).floor() as i64 + 1 - margin as i64;
        let last = (uhi[a] + 2.0).ceil() as i64 - 1 + margin as i64;
        let n = lattice.dims[a] as i64;
        if !(ulo[a].is_finite() && uhi[a].is_finite()) || last < 0 || first > n - 1 {
            return None;
        }
        min[a] = first.clamp(0, n - 1) as usize;
        max[a] = last.clamp(0, n - 1) as usize;
    }
    Some(CoeffBox { min, max })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn linear(x: Vec3) -> f32 {
        0.3 * x.x - 0.7 * x.y + 0.2 * x.z + 0.1
    }

    #[test]
    fn local_refit_of_a_linear_function_is_exact() {
        let mut lattice =
            BSplineLattice::zeros([12, 11, 10], 0.5, Vec3::new(-1.0, 0.0, 1.0)).unwrap();
        for k in 0..10 {
            for j in 0..11 {
                for i in 0..12 {
                    let idx = lattice.index(i, j, k);
                    lattice
                        .coeffs
                        .set_flat(idx, linear(lattice.node_position(i, j, k)) + 0.5);
                }
            }
        }
        // Scramble the box, then refit it to the linear function.
        let before = lattice.clone();
        let (lo, hi) = ([3, 2, 4], [8, 7, 6]);
        for k in 4..=6 {
            for j in 2..=7 {
                for i in 3..=8 {
                    let idx = lattice.index(i, j, k);
                    lattice
                        .coeffs
                        .set_flat(idx, ((i * 31 + j * 17 + k) % 7) as f32);
                }
            }
        }
        for r in [1, 2, 3] {
            refit_box(&mut lattice, lo, hi, r, |x| linear(x) + 0.5).unwrap();
            for (a, b) in lattice.coeffs.iter().zip(&before.coeffs) {
                // Exact up to f32 rounding of the sums (a few dozen ulps).
                assert!((a - b).abs() < 5e-5 * (1.0 + b.abs()), "r={r}: {a} vs {b}");
            }
        }
    }

    #[test]
    fn coefficients_outside_the_box_are_bit_identical() {
        let mut lattice = BSplineLattice::zeros([9, 9, 9], 1.0, Vec3::ZERO).unwrap();
        lattice.coeffs.update_each(|n, c| {
            *c = ((n * 7919) % 101) as f32 / 101.0;
        });
        let before = lattice.clone();
        refit_box(&mut lattice, [0, 2, 3], [3, 6, 8], 2, |x| (x.x * 0.5).sin()).unwrap();
        let b = CoeffBox {
            min: [0, 2, 3],
            max: [3, 6, 8],
        };
        let mut changed = 0;
        for k in 0..9 {
            for j in 0..9 {
                for i in 0..9 {
                    let idx = lattice.index(i, j, k);
                    if b.contains(i, j, k) {
                        changed += usize::from(lattice.coeffs[idx] != before.coeffs[idx]);
                    } else {
                        assert_eq!(
                            lattice.coeffs[idx].to_bits(),
                            before.coeffs[idx].to_bits(),
                            "({i},{j},{k}) changed"
                        );
                    }
                }
            }
        }
        assert!(changed > 0);
    }

    #[test]
    fn global_fit_recovers_a_spline_exactly() {
        let mut truth = BSplineLattice::zeros([7, 6, 8], 0.25, Vec3::new(0.1, 0.2, 0.3)).unwrap();
        truth.coeffs.update_each(|n, c| {
            *c = ((n * 31) % 17) as f32 / 17.0;
        });
        let mut fitted = BSplineLattice::zeros(truth.dims, truth.spacing, truth.origin).unwrap();
        fit_lattice(&mut fitted, 1, |x| truth.value(x)).unwrap();
        for (a, b) in fitted.coeffs.iter().zip(&truth.coeffs) {
            assert!((a - b).abs() < 1e-4, "{a} vs {b}");
        }
    }

    #[test]
    fn rejects_bad_input_without_touching_the_lattice() {
        let mut lattice = BSplineLattice::zeros([5, 5, 5], 1.0, Vec3::ZERO).unwrap();
        let before = lattice.clone();
        assert!(matches!(
            refit_box(&mut lattice, [0, 0, 0], [5, 1, 1], 1, |_| 0.0),
            Err(FitError::BadBox { .. })
        ));
        assert!(matches!(
            refit_box(&mut lattice, [2, 0, 0], [1, 1, 1], 1, |_| 0.0),
            Err(FitError::BadBox { .. })
        ));
        assert_eq!(
            refit_box(&mut lattice, [0, 0, 0], [1, 1, 1], 0, |_| 0.0),
            Err(FitError::NoSamples)
        );
        assert!(matches!(
            refit_box(&mut lattice, [0, 0, 0], [1, 1, 1], 1, |_| f32::NAN),
            Err(FitError::NonFiniteTarget { .. })
        ));
        assert_eq!(lattice, before);
    }

    #[test]
    fn coeff_box_around_covers_the_influence() {
        let lattice = BSplineLattice::zeros([20, 20, 20], 1.0, Vec3::ZERO).unwrap();
        let b = coeff_box_around(&lattice, Vec3::splat(5.5), Vec3::splat(7.0), 0).unwrap();
        assert_eq!(b.min, [4; 3]);
        assert_eq!(b.max, [8; 3]);
        assert!(coeff_box_around(&lattice, Vec3::splat(-10.0), Vec3::splat(-5.0), 0).is_none());
    }
}
