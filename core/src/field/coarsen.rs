//! Coarsening: folding a detail patch whose detail has been wiped (smoothed away, cut off with
//! the clay around it, or left as zeros by an undo) back into a coarser patch under it, the
//! inverse of refining. Memory and meshing then follow the detail the clay still holds.
//!
//! A patch `s_p` is folded into a coarser patch `s_c` whose coefficients cover its support:
//! the coefficients of `s_c` over that support are refitted (least squares, everything
//! outside held fixed) to `s_c + s_p`, and the fold is accepted only where what the coarser
//! lattice cannot carry, the residual `r = Δs_c − s_p`, moves the surface by at most
//! [`COARSEN_TOLERANCE_SPANS`] of the detail patch's knot spans: at every node of the detail
//! lattice, `|r| ≤ tol · |∇F|` or `|r| ≤ ½ |F − iso|` (so away from the surface the residual
//! cannot make or cut clay). Candidates are tried coarsest first, so a fold goes as far down
//! as the detail allows.

use super::lattice::BSplineLattice;
use super::mass_grid::{CoeffBox, sub_lattice};
use super::multipatch::MultiPatchField;
use super::refit::{FitError, coeff_box_around, refit_box_edit};

/// How far a fold may move the surface, in knot spans of the detail patch it removes.
pub const COARSEN_TOLERANCE_SPANS: f32 = 0.25;

/// The largest detail patch (in coefficients) whose fold is tried: the check evaluates the
/// clay at each of its nodes, so larger patches (an import's full-size levels) are kept.
pub const COARSEN_MAX_PATCH_COEFFS: usize = 1 << 18;

/// A fold worked out but not yet applied (see [`plan_coarsening`]).
#[derive(Clone, Debug, PartialEq)]
pub struct CoarsenPlan {
    /// The detail patch removed.
    pub patch: usize,
    /// The coarser patch that takes its detail (0 is the base).
    pub into: usize,
    /// The coefficients of `into` rewritten, with their new values (x fastest); `None` when
    /// the detail patch holds only zeros and nothing needs rewriting.
    pub rewrite: Option<(CoeffBox, Vec<f32>)>,
    /// The largest surface displacement the fold causes, in field units (an estimate,
    /// `|r| / |∇F|` at the nodes near the surface).
    pub displacement_fu: f32,
}

/// Why a fold could not be worked out.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum CoarsenError {
    /// The patch index is not a detail patch of the field.
    #[error("patch {patch} is not a detail patch (the field has {patches} patches)")]
    NotADetailPatch {
        /// The index asked for.
        patch: usize,
        /// How many patches the field has.
        patches: usize,
    },
    /// The refit of the coarser patch failed.
    #[error("refitting patch {into}: {source}")]
    Fit {
        /// The coarser patch.
        into: usize,
        /// What the fit reported.
        source: FitError,
    },
}

/// Works out whether detail patch `patch` of `field` can be folded into a coarser patch
/// without moving the surface by more than [`COARSEN_TOLERANCE_SPANS`] of its knot spans, and
/// how. `Ok(None)` when it cannot (its detail is still there, it is mapped, it is too large
/// to check, or no coarser patch covers it).
///
/// # Errors
/// [`CoarsenError`] when `patch` is not a detail patch or a refit fails.
pub fn plan_coarsening(
    field: &MultiPatchField,
    patch: usize,
) -> Result<Option<CoarsenPlan>, CoarsenError> {
    if patch == 0 || patch >= field.patches.len() {
        return Err(CoarsenError::NotADetailPatch {
            patch,
            patches: field.patches.len(),
        });
    }
    let detail = &field.patches[patch];
    if !detail.is_identity() {
        return Ok(None);
    }
    if detail.lattice.coeffs.iter().all(|&c| c == 0.0) {
        return Ok(Some(CoarsenPlan {
            patch,
            into: 0,
            rewrite: None,
            displacement_fu: 0.0,
        }));
    }
    if detail.lattice.coeffs.len() > COARSEN_MAX_PATCH_COEFFS {
        return Ok(None);
    }
    for into in coarser_patches_covering(field, patch) {
        let (rewrite, displacement_fu) = fold(field, patch, into)?;
        if let Some(rewrite) = rewrite {
            return Ok(Some(CoarsenPlan {
                patch,
                into,
                rewrite: Some(rewrite),
                displacement_fu,
            }));
        }
    }
    Ok(None)
}

/// Applies `plan` to `field`: rewrites the coarser patch's coefficients and removes the
/// detail patch (later patches move down one index). Returns the removed patch.
///
/// # Panics
/// When `plan` was not worked out on this field (an index or box out of range).
pub fn apply_coarsening(field: &mut MultiPatchField, plan: &CoarsenPlan) -> super::Patch {
    if let Some((region, values)) = &plan.rewrite {
        let lattice = &mut field.patches[plan.into].lattice;
        let n = region.dims();
        let mut rows = values.chunks_exact(n[0]);
        for k in region.min[2]..=region.max[2] {
            for j in region.min[1]..=region.max[1] {
                let at = lattice.index(region.min[0], j, k);
                let row = rows.next().expect("one row of values per row of the box");
                lattice.coeffs.write_row(at, row);
            }
        }
    }
    field.patches.remove(plan.patch)
}

/// The patches coarser than `patch` in world coordinates whose coefficients cover its whole
/// support, coarsest first.
fn coarser_patches_covering(field: &MultiPatchField, patch: usize) -> Vec<usize> {
    let detail = &field.patches[patch].lattice;
    let (lo, hi) = detail.support();
    let mut found: Vec<usize> = field
        .patches
        .iter()
        .enumerate()
        .filter(|&(n, p)| {
            n != patch && p.is_identity() && p.lattice.spacing > 1.001 * detail.spacing && {
                let (plo, phi) = p.lattice.support();
                lo.cmpge(plo).all() && hi.cmple(phi).all()
            }
        })
        .map(|(n, _)| n)
        .collect();
    found.sort_by(|&a, &b| {
        let spacing = |n: usize| field.patches[n].lattice.spacing;
        spacing(b).total_cmp(&spacing(a))
    });
    found
}

/// Refits patch `into` over `patch`'s support to carry `patch`'s term, and measures what it
/// cannot carry. Returns the rewritten box and values when the surface moves by at most the
/// tolerance, with the largest displacement measured.
#[allow(clippy::type_complexity)] // a box with its values, and the figure that accepted it
fn fold(
    field: &MultiPatchField,
    patch: usize,
    into: usize,
) -> Result<(Option<(CoeffBox, Vec<f32>)>, f32), CoarsenError> {
    let detail = &field.patches[patch].lattice;
    let coarse = &field.patches[into].lattice;
    let (lo, hi) = detail.support();
    let Some(region) = coeff_box_around(coarse, lo, hi, 0) else {
        return Ok((None, f32::INFINITY));
    };
    // A window with three coefficients of margin evaluates like the whole lattice over the
    // region, so the refit sees the fixed coefficients around it.
    const MARGIN: usize = 3;
    let before = sub_lattice(coarse, &region, MARGIN);
    let offset: [usize; 3] =
        std::array::from_fn(|a| region.min[a] - region_start(coarse, &before, a));
    let inner_min = offset;
    let inner_max: [usize; 3] = std::array::from_fn(|a| offset[a] + region.dims()[a] - 1);
    let mut after = before.clone();
    // About one sample per detail span, at least four per coarse span.
    let ratio = (coarse.spacing / detail.spacing).round() as usize;
    let samples_per_span = ratio.clamp(4, 8);
    refit_box_edit(
        &mut after,
        inner_min,
        inner_max,
        samples_per_span,
        |x, old| old + detail.value(x),
    )
    .map_err(|source| CoarsenError::Fit { into, source })?;

    let tolerance_fu = COARSEN_TOLERANCE_SPANS * detail.spacing;
    let iso = field.iso();
    let mut displacement_fu = 0.0_f32;
    for k in 0..detail.dims[2] {
        for j in 0..detail.dims[1] {
            for i in 0..detail.dims[0] {
                let x = detail.node_position(i, j, k);
                let residual = after.value(x) - before.value(x) - detail.value(x);
                let (f, gradient) = field.value_and_gradient(x);
                let beside = (f - iso).abs();
                if residual.abs() <= 0.5 * beside {
                    continue; // the clay keeps its side of the surface here
                }
                let moved = residual.abs() / gradient.length().max(f32::MIN_POSITIVE);
                if moved > tolerance_fu {
                    return Ok((None, moved));
                }
                displacement_fu = displacement_fu.max(moved);
            }
        }
    }
    let values = window_values(&after, inner_min, inner_max);
    Ok((Some((region, values)), displacement_fu))
}

/// Where the window `window` cut from `lattice` starts along `axis`, in `lattice`'s indices.
fn region_start(lattice: &BSplineLattice, window: &BSplineLattice, axis: usize) -> usize {
    ((window.origin[axis] - lattice.origin[axis]) / lattice.spacing).round() as usize
}

/// The coefficients of `lattice` in `min ..= max`, x fastest.
fn window_values(lattice: &BSplineLattice, min: [usize; 3], max: [usize; 3]) -> Vec<f32> {
    let mut values = Vec::with_capacity((0..3).map(|a| max[a] + 1 - min[a]).product());
    for k in min[2]..=max[2] {
        for j in min[1]..=max[1] {
            let at = lattice.index(min[0], j, k);
            lattice
                .coeffs
                .extend_row_into(at, max[0] + 1 - min[0], &mut values);
        }
    }
    values
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;

    /// A sphere of radius 0.5 at the centre of a 24³ base of spacing 0.1, as a signed
    /// distance (positive inside) fitted on the base.
    fn sphere_field() -> MultiPatchField {
        let mut base = BSplineLattice::zeros([24; 3], 0.1, Vec3::splat(-1.15)).unwrap();
        super::super::refit::fit_lattice(&mut base, 2, |x| 0.5 - x.length()).unwrap();
        base.iso = 0.0;
        MultiPatchField::new(base)
    }

    fn top() -> Vec3 {
        Vec3::new(0.0, 0.5, 0.0)
    }

    /// Adds a level-3 detail patch around the sphere's top and fits it to `target` there.
    fn with_detail(target: impl Fn(Vec3) -> f32) -> (MultiPatchField, usize) {
        let mut field = sphere_field();
        let n = field
            .refine(top() - Vec3::splat(0.25), top() + Vec3::splat(0.25), 3)
            .unwrap();
        field.fit_detail(n, 2, target).unwrap();
        (field, n)
    }

    /// The radius of the solid along the ray from the centre through `dir`.
    fn radius_along(field: &MultiPatchField, dir: Vec3) -> f32 {
        let dir = dir.normalize();
        let (mut inside, mut outside) = (0.2_f32, 0.9_f32);
        for _ in 0..40 {
            let mid = 0.5 * (inside + outside);
            if field.is_inside(dir * mid) {
                inside = mid;
            } else {
                outside = mid;
            }
        }
        0.5 * (inside + outside)
    }

    #[test]
    fn a_patch_of_zeros_is_removed_without_rewriting_anything() {
        let mut field = sphere_field();
        let n = field
            .refine(top() - Vec3::splat(0.1), top() + Vec3::splat(0.1), 2)
            .unwrap();
        let plan = plan_coarsening(&field, n).unwrap().expect("zeros fold");
        assert_eq!((plan.into, plan.rewrite.is_none()), (0, true));
        let base = field.patches[0].clone();
        apply_coarsening(&mut field, &plan);
        assert_eq!(field.patches.len(), 1);
        assert_eq!(field.patches[0], base);
    }

    #[test]
    fn a_groove_finer_than_the_base_is_kept() {
        // A groove 0.03 wide and deep across the top: the base (spacing 0.1) cannot carry it.
        let groove = |x: Vec3| {
            let d = Vec3::new(0.0, x.y - 0.5, x.z).length() - 0.015;
            (0.5 - x.length()).min(d)
        };
        let (field, n) = with_detail(groove);
        assert!(
            !field.is_inside(top() - Vec3::Y * 0.01),
            "the groove is cut"
        );
        assert_eq!(plan_coarsening(&field, n).unwrap(), None);
    }

    #[test]
    fn a_smooth_swelling_folds_into_the_base_and_the_surface_stays_within_the_tolerance() {
        // A broad, low swelling (0.02 high, about 0.4 wide) that the base's spacing resolves.
        let swell = |x: Vec3| {
            let r2 = x.x * x.x + x.z * x.z;
            0.5 - x.length() + 0.02 * (-r2 / (0.12 * 0.12)).exp()
        };
        let (mut field, n) = with_detail(swell);
        let dirs = [
            Vec3::Y,
            Vec3::new(0.05, 1.0, 0.0),
            Vec3::new(0.1, 1.0, 0.05),
            Vec3::new(-0.15, 1.0, 0.1),
        ];
        let before: Vec<f32> = dirs.iter().map(|&d| radius_along(&field, d)).collect();
        assert!(before[0] > 0.515, "the swelling is there: {}", before[0]);
        let plan = plan_coarsening(&field, n)
            .unwrap()
            .expect("a smooth swelling folds");
        assert_eq!(plan.into, 0);
        let detail_spacing = field.patches[n].lattice.spacing;
        apply_coarsening(&mut field, &plan);
        assert_eq!(field.patches.len(), 1);
        for (d, b) in dirs.iter().zip(&before) {
            let after = radius_along(&field, *d);
            assert!(
                (after - b).abs() <= COARSEN_TOLERANCE_SPANS * detail_spacing,
                "along {d}: {b} became {after}"
            );
        }
    }

    #[test]
    fn the_base_is_not_a_detail_patch() {
        let field = sphere_field();
        assert!(matches!(
            plan_coarsening(&field, 0),
            Err(CoarsenError::NotADetailPatch { patch: 0, .. })
        ));
    }
}
