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
//!
//! The check costs what a clay of many patches makes it cost only where it must: the
//! residuals come from grid evaluations, the clay at a node sums only the patches that reach
//! the detail patch, and the nodes with the largest residuals go first, so a refused fold
//! (most folds tried, while the detail is there) stops after a few nodes. A caller planning
//! the same patches step after step keeps a [`RefusedFolds`] and plans with
//! [`plan_coarsening_remembering`], which skips the refit of a fold it saw refused with the same
//! inputs while the node that refused it still does. Every variant folds what the plain check
//! of every node, in order, over the whole clay folds (the tests compare them).

use glam::Vec3;

use super::lattice::BSplineLattice;
use super::mass_grid::{CoeffBox, sub_lattice};
use super::multipatch::{MAX_PATCHES, MultiPatchField, sum_value_and_gradient};
use super::refit::{FitError, coeff_box_around, refit_box_edit_rows};

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
    plan_with(field, patch, largest_displacement, None)
}

/// [`plan_coarsening`], remembering in `refused` where each fold it finds refused fails: a
/// later plan whose fold has the same inputs (the detail patch and the coarser patch's
/// window, bit for bit) looks at that node first, and when the surface there still moves past
/// the tolerance the fold is refused without its refit. A patch that a step reaches but does
/// not change is then planned again for the cost of a fingerprint of its coefficients and
/// one evaluation of the clay. The plan is the one [`plan_coarsening`] makes.
///
/// # Errors
/// As [`plan_coarsening`].
pub fn plan_coarsening_remembering(
    field: &MultiPatchField,
    patch: usize,
    refused: &mut RefusedFolds,
) -> Result<Option<CoarsenPlan>, CoarsenError> {
    plan_with(field, patch, largest_displacement, Some(refused))
}

/// Where a fold was found to move the surface past the tolerance.
#[derive(Clone, Copy, Debug, PartialEq)]
struct NodeOverTolerance {
    /// The detail lattice's node (x fastest).
    node: usize,
    /// The residual there.
    residual: f32,
    /// How far the surface moves there, field units.
    moved_fu: f32,
}

/// Folds found refused, each by a fingerprint of its inputs and the node where it failed, for
/// [`plan_coarsening_remembering`]; at most [`RefusedFolds::CAPACITY`], the oldest forgotten
/// first.
#[derive(Clone, Debug, Default)]
pub struct RefusedFolds {
    entries: std::collections::VecDeque<(u64, NodeOverTolerance)>,
}

impl RefusedFolds {
    /// Most refusals remembered: two per patch a clay can hold.
    pub const CAPACITY: usize = 2 * MAX_PATCHES;

    /// How many refusals are remembered.
    #[must_use]
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// Whether none is.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    fn find(&self, inputs: u64) -> Option<NodeOverTolerance> {
        self.entries
            .iter()
            .find(|(key, _)| *key == inputs)
            .map(|&(_, at)| at)
    }

    fn remember(&mut self, inputs: u64, at: NodeOverTolerance) {
        self.entries.retain(|(key, _)| *key != inputs);
        if self.entries.len() >= Self::CAPACITY {
            self.entries.pop_front();
        }
        self.entries.push_back((inputs, at));
    }
}

/// How a fold's displacement is measured: over the detail lattice's nodes, with the coarser
/// patch's window before and after the refit; the largest displacement, or the first node
/// found past the tolerance (see [`largest_displacement`]).
type DisplacementCheck = fn(
    &MultiPatchField,
    &BSplineLattice,
    &BSplineLattice,
    &BSplineLattice,
) -> Result<f32, NodeOverTolerance>;

/// [`plan_coarsening`] with the displacement measured by `check`, remembering refusals in
/// `refused` when given.
fn plan_with(
    field: &MultiPatchField,
    patch: usize,
    check: DisplacementCheck,
    mut refused: Option<&mut RefusedFolds>,
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
        let (rewrite, displacement_fu) = fold(field, patch, into, check, refused.as_deref_mut())?;
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
/// cannot carry with `check`. Returns the rewritten box and values when the surface moves by
/// at most the tolerance, with the largest displacement measured. With `refused`, a fold
/// whose inputs it remembers is first checked at the node where it failed, and a refusal is
/// remembered.
#[allow(clippy::type_complexity)] // a box with its values, and the figure that accepted it
fn fold(
    field: &MultiPatchField,
    patch: usize,
    into: usize,
    check: DisplacementCheck,
    refused: Option<&mut RefusedFolds>,
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
    // The refit and the residuals follow from these alone.
    let inputs = refused
        .as_ref()
        .map(|_| fold_inputs(detail, &before, inner_min, inner_max));
    let remembered = inputs
        .zip(refused.as_ref())
        .and_then(|(key, r)| r.find(key));
    if let Some(at) = remembered {
        let x = node_at(detail, at.node);
        let near = field.patches_reaching(x, x);
        let clay = sum_value_and_gradient(near.iter().copied(), x);
        let tolerance_fu = COARSEN_TOLERANCE_SPANS * detail.spacing;
        let moved_fu = surface_moved(at.residual, clay, field.iso());
        if let Some(moved_fu) = moved_fu.filter(|&m| m > tolerance_fu) {
            return Ok((None, moved_fu));
        }
    }
    let mut after = before.clone();
    // About one sample per detail span, at least four per coarse span.
    let ratio = (coarse.spacing / detail.spacing).round() as usize;
    let samples_per_span = ratio.clamp(4, 8);
    refit_adding(&mut after, inner_min, inner_max, samples_per_span, detail)
        .map_err(|source| CoarsenError::Fit { into, source })?;

    match check(field, detail, &before, &after) {
        Ok(displacement_fu) => {
            let values = window_values(&after, inner_min, inner_max);
            Ok((Some((region, values)), displacement_fu))
        }
        Err(at) => {
            if let (Some(inputs), Some(refused)) = (inputs, refused) {
                refused.remember(inputs, at);
            }
            Ok((None, at.moved_fu))
        }
    }
}

/// [`refit_box_edit`](super::refit::refit_box_edit) of `window`'s coefficients
/// `inner_min ..= inner_max` to the field plus `detail`'s term, each row of samples gaining
/// the term on the row's grid (bit for bit its value sample by sample, at a fraction of the
/// cost).
fn refit_adding(
    window: &mut BSplineLattice,
    inner_min: [usize; 3],
    inner_max: [usize; 3],
    samples_per_span: usize,
    detail: &BSplineLattice,
) -> Result<(), FitError> {
    let mut term = Vec::new();
    refit_box_edit_rows(window, inner_min, inner_max, samples_per_span, |row| {
        term.resize(row.xs.len(), 0.0);
        detail.values_on_grid(row.xs, &[row.y], &[row.z], &mut term);
        for (v, t) in row.values.iter_mut().zip(&term) {
            *v += t;
        }
    })
}

/// A fingerprint of what a fold's refit and residuals are worked out from: the detail
/// lattice and the coarser patch's window (their shapes, places and coefficients, bit for
/// bit) and the window's refitted box.
fn fold_inputs(
    detail: &BSplineLattice,
    window: &BSplineLattice,
    inner_min: [usize; 3],
    inner_max: [usize; 3],
) -> u64 {
    use std::hash::{Hash, Hasher};
    let mut hasher = std::collections::hash_map::DefaultHasher::new();
    for lattice in [detail, window] {
        lattice.dims.hash(&mut hasher);
        lattice.spacing.to_bits().hash(&mut hasher);
        lattice
            .origin
            .to_array()
            .map(f32::to_bits)
            .hash(&mut hasher);
        for c in lattice.coeffs.iter() {
            hasher.write_u32(c.to_bits());
        }
    }
    inner_min.hash(&mut hasher);
    inner_max.hash(&mut hasher);
    hasher.finish()
}

/// The world position of node `node` (x fastest) of `lattice`, as
/// [`largest_displacement`] places it.
fn node_at(lattice: &BSplineLattice, node: usize) -> Vec3 {
    let [nx, ny, _] = lattice.dims;
    let ijk = [node % nx, node / nx % ny, node / (nx * ny)];
    Vec3::from_array(std::array::from_fn(|a| {
        lattice.origin[a] + lattice.spacing * ijk[a] as f32
    }))
}

/// How far a residual `residual` at a point where the clay has value and gradient `clay`
/// moves the surface (field units), or `None` where it is at most half the clay's distance
/// from `iso` (the clay keeps its side of the surface there).
#[inline]
fn surface_moved(residual: f32, (f, gradient): (f32, Vec3), iso: f32) -> Option<f32> {
    if residual.abs() <= 0.5 * (f - iso).abs() {
        return None;
    }
    Some(residual.abs() / gradient.length().max(f32::MIN_POSITIVE))
}

/// The largest surface displacement, in field units, of replacing `detail`'s term of `field`
/// by the change from `before` to `after` (windows of the coarser patch), measured at every
/// node of `detail`: a node moves the surface by `|r| / |∇F|`, where the residual
/// `r = after − before − detail`, unless `|r| ≤ ½ |F − iso|` (the clay keeps its side of the
/// surface there). `Err` with a node found past the tolerance.
///
/// The nodes with the largest residuals are checked first, so a fold that fails mostly finds
/// out at once; one that passes checks every node, and the largest displacement does not
/// depend on the order. The clay at the nodes sums only the patches that reach them, and a
/// node whose residual is zero moves nothing.
fn largest_displacement(
    field: &MultiPatchField,
    detail: &BSplineLattice,
    before: &BSplineLattice,
    after: &BSplineLattice,
) -> Result<f32, NodeOverTolerance> {
    /// Nodes checked in order of their residuals before the rest, in any order.
    const LARGEST_FIRST: usize = 256;
    let tolerance_fu = COARSEN_TOLERANCE_SPANS * detail.spacing;
    let iso = field.iso();
    // The residual at every node (the windows' and the detail's values on the node grid, bit
    // for bit their values node by node).
    let nodes: [Vec<f32>; 3] = std::array::from_fn(|a| {
        (0..detail.dims[a])
            .map(|i| detail.origin[a] + detail.spacing * i as f32)
            .collect()
    });
    let on_nodes = |lattice: &BSplineLattice| {
        let mut values = vec![0.0; detail.coeffs.len()];
        lattice.values_on_grid(&nodes[0], &nodes[1], &nodes[2], &mut values);
        values
    };
    let mut residuals = on_nodes(after);
    for ((r, b), d) in residuals
        .iter_mut()
        .zip(on_nodes(before))
        .zip(on_nodes(detail))
    {
        *r = *r - b - d;
    }
    let near = field.patches_reaching(
        detail.node_position(0, 0, 0),
        detail.node_position(detail.dims[0] - 1, detail.dims[1] - 1, detail.dims[2] - 1),
    );
    let mut order: Vec<u32> = (0..residuals.len() as u32).collect();
    let larger = |a: &u32, b: &u32| {
        let (ra, rb) = (residuals[*a as usize].abs(), residuals[*b as usize].abs());
        rb.total_cmp(&ra).then(a.cmp(b))
    };
    let first = LARGEST_FIRST.min(order.len());
    if first < order.len() {
        order.select_nth_unstable_by(first, larger);
    }
    order[..first].sort_unstable_by(larger);
    let mut displacement_fu = 0.0_f32;
    for node in order {
        let node = node as usize;
        let residual = residuals[node];
        if residual == 0.0 {
            continue;
        }
        let x = node_at(detail, node);
        let clay = sum_value_and_gradient(near.iter().copied(), x);
        let Some(moved_fu) = surface_moved(residual, clay, iso) else {
            continue; // the clay keeps its side of the surface here
        };
        if moved_fu > tolerance_fu {
            return Err(NodeOverTolerance {
                node,
                residual,
                moved_fu,
            });
        }
        displacement_fu = displacement_fu.max(moved_fu);
    }
    Ok(displacement_fu)
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

    /// The displacement as first planned: the residual and the whole field evaluated node by
    /// node over the detail lattice, in index order, stopping at the first node past the
    /// tolerance.
    fn largest_displacement_node_by_node(
        field: &MultiPatchField,
        detail: &BSplineLattice,
        before: &BSplineLattice,
        after: &BSplineLattice,
    ) -> Result<f32, NodeOverTolerance> {
        let tolerance_fu = COARSEN_TOLERANCE_SPANS * detail.spacing;
        let iso = field.iso();
        let mut displacement_fu = 0.0_f32;
        for k in 0..detail.dims[2] {
            for j in 0..detail.dims[1] {
                for i in 0..detail.dims[0] {
                    let x = detail.node_position(i, j, k);
                    let residual = after.value(x) - before.value(x) - detail.value(x);
                    let (f, gradient) = field.value_and_gradient(x);
                    if residual.abs() <= 0.5 * (f - iso).abs() {
                        continue;
                    }
                    let moved = residual.abs() / gradient.length().max(f32::MIN_POSITIVE);
                    if moved > tolerance_fu {
                        return Err(NodeOverTolerance {
                            node: detail.index(i, j, k),
                            residual,
                            moved_fu: moved,
                        });
                    }
                    displacement_fu = displacement_fu.max(moved);
                }
            }
        }
        Ok(displacement_fu)
    }

    #[test]
    fn the_planning_folds_exactly_what_a_check_of_every_node_over_the_whole_field_folds() {
        // Overlapping patches at levels 2 and 3 around the top and one on the side, each a
        // groove along x whose depth halves at every step, with a new patch every step:
        // folds are refused, then accepted as the grooves fade, among patches that reach
        // each other's nodes and patches that do not.
        let mut field = sphere_field();
        let places = [
            (top(), 3),
            (top() + Vec3::new(0.12, -0.02, 0.0), 2),
            (top() + Vec3::new(-0.05, 0.0, 0.08), 3),
            (Vec3::new(0.5, 0.0, 0.0), 2),
            (top() + Vec3::new(0.0, 0.0, -0.1), 2),
            (top() + Vec3::new(0.08, 0.0, 0.05), 3),
        ];
        let mut centres = Vec::new();
        let mut refusals = RefusedFolds::default();
        let (mut accepted, mut refused) = (0, 0);
        for (step, &(centre, level)) in places.iter().enumerate() {
            let n = field
                .refine(
                    centre - Vec3::splat(0.15),
                    centre + Vec3::splat(0.15),
                    level,
                )
                .unwrap();
            assert_eq!(n, centres.len() + 1);
            centres.push(centre);
            let depth = 0.04 * 0.5_f32.powi(step as i32);
            // Every other patch keeps its detail from the last step, so its fold has the
            // same inputs as then.
            for (n, &centre) in centres.iter().enumerate() {
                if (n + step) % 2 == 1 && n + 1 != centres.len() {
                    continue;
                }
                let groove = move |x: Vec3| {
                    let d = Vec3::new(0.0, x.y - centre.y, x.z - centre.z).length();
                    let along = (x - centre).length();
                    0.5 - x.length() - depth * (-(d * d) / 0.0004 - along * along / 0.01).exp()
                };
                field.fit_detail(n + 1, 2, groove).unwrap();
            }
            for n in (1..field.patches.len()).rev() {
                let plan = plan_coarsening(&field, n);
                let plain = plan_with(&field, n, largest_displacement_node_by_node, None);
                assert_eq!(plan, plain, "step {step}, patch {n}");
                let remembering = plan_coarsening_remembering(&field, n, &mut refusals);
                assert_eq!(remembering, plain, "step {step}, patch {n}, remembering");
                if let Ok(Some(plan)) = plan {
                    apply_coarsening(&mut field, &plan);
                    centres.remove(n - 1);
                    accepted += 1;
                } else {
                    refused += 1;
                }
            }
        }
        assert!(
            accepted >= 2 && refused >= 2,
            "{accepted} folds, {refused} kept"
        );
        assert!(!refusals.is_empty());
    }

    #[test]
    fn the_refit_adding_the_detail_by_rows_is_the_refit_adding_it_sample_by_sample() {
        let swell = |x: Vec3| 0.5 - x.length() + 0.03 * (-(x.x * x.x) / 0.01).exp();
        let (field, n) = with_detail(swell);
        let detail = &field.patches[n].lattice;
        let base = &field.patches[0].lattice;
        let (lo, hi) = detail.support();
        let region = coeff_box_around(base, lo, hi, 0).unwrap();
        let window = sub_lattice(base, &region, 3);
        let start: [usize; 3] = std::array::from_fn(|a| region_start(base, &window, a));
        let inner_min: [usize; 3] = std::array::from_fn(|a| region.min[a] - start[a]);
        let inner_max: [usize; 3] = std::array::from_fn(|a| region.max[a] - start[a]);
        for samples_per_span in [4, 8] {
            let mut by_rows = window.clone();
            refit_adding(&mut by_rows, inner_min, inner_max, samples_per_span, detail).unwrap();
            let mut by_samples = window.clone();
            super::super::refit::refit_box_edit(
                &mut by_samples,
                inner_min,
                inner_max,
                samples_per_span,
                |x, old| old + detail.value(x),
            )
            .unwrap();
            let bits =
                |l: &BSplineLattice| l.coeffs.iter().map(|c| c.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&by_rows), bits(&by_samples));
            assert_ne!(bits(&by_rows), bits(&window), "the refit took the detail");
        }
    }

    #[test]
    fn refusals_are_remembered_once_per_fold_and_the_oldest_forgotten_first() {
        let at = |node: usize| NodeOverTolerance {
            node,
            residual: 1.0,
            moved_fu: 1.0,
        };
        let mut refusals = RefusedFolds::default();
        refusals.remember(7, at(1));
        refusals.remember(7, at(2));
        assert_eq!((refusals.len(), refusals.find(7)), (1, Some(at(2))));
        for key in 0..RefusedFolds::CAPACITY as u64 {
            refusals.remember(100 + key, at(3));
        }
        assert_eq!(refusals.len(), RefusedFolds::CAPACITY);
        assert_eq!(refusals.find(7), None, "the oldest went first");
        assert_eq!(refusals.find(100), Some(at(3)));
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
