//! Applying a geometric tool: evaluate the action's rule on the pre-edit clay over the tool's
//! reach, then refit the affected coefficients by local least squares (Hua & Qin §7.1), with
//! every coefficient outside the affected box left bit-identical. Each application reports
//! the box it refitted and Ferley's counts (§3.2): sample points *visited* (in the world-axis
//! box), *computed* (in the tool's local box, so its potential was evaluated) and *dirtied*
//! (whose value changed). Coefficients the freeze mask holds keep their held share of the old
//! value (`tools::mask`).
//!
//! Runs on the simulation or command thread: it allocates (a copy of the local region and the
//! fit's scratch).

use std::cell::Cell;
use std::ops::Range;

use glam::{Affine3A, Vec3};

use super::action::{ActionError, ToolAction};
use super::clay::{Clay, CoeffBox, ColourField, FieldId, sub_lattice};
use super::history::StepRecorder;
use super::mask::hold_before_edit;
use super::report::{ToolError, ToolReport};
use super::shape::{ToolPose, ToolShape, density_from_distance};
use crate::field::{
    BSplineLattice, MultiPatchField, OtherPatches, SampleRow, check_dense_room, coeff_box_around,
    refit_box_edit, refit_box_edit_rows,
};

/// A geometric tool: a shape, what it does, and the width of its potential's falloff band.
#[derive(Clone, Debug, PartialEq)]
pub struct GeometricTool {
    pub shape: ToolShape,
    pub action: ToolAction,
    /// Half-width of the band over which the tool's potential falls from 1 to 0 around its
    /// surface (analytic shapes; about two knot spans suits the fit).
    pub falloff_fu: f32,
}

/// How an application is fitted.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ApplyOptions {
    /// Which density patch the tool edits.
    pub patch: u16,
    /// Target samples per knot span in the local refit (2 is accurate for tool-sized edits).
    pub samples_per_span: usize,
    /// Apply the tool to the patch's own term of eq. (3) as if it were the whole clay,
    /// leaving the other patches out of the rule. For a linear action (a smoothing: the
    /// blur of a sum is the sum of the blurs) applying it so to every patch under the brush
    /// is the action on the whole clay, each level keeping what its own spacing carries.
    pub own_term: bool,
}

impl Default for ApplyOptions {
    fn default() -> Self {
        Self {
            patch: 0,
            samples_per_span: 2,
            own_term: false,
        }
    }
}

impl GeometricTool {
    /// Checks shape, action and falloff.
    ///
    /// # Errors
    /// The first invalid parameter.
    pub fn validate(&self) -> Result<(), ToolError> {
        self.shape.validate().map_err(ToolError::Shape)?;
        self.action.validate().map_err(ToolError::Action)?;
        let freeform = matches!(self.shape, ToolShape::Freeform(_));
        let falloff_ok = self.falloff_fu.is_finite() && self.falloff_fu > 0.0;
        if !freeform && !falloff_ok {
            return Err(ToolError::BadFalloff {
                falloff_fu: self.falloff_fu,
            });
        }
        Ok(())
    }
}

impl GeometricTool {
    /// The falloff band the tool shapes with on a lattice of knot spacing `spacing_fu`: the
    /// user's band for the actions that shape their own, else widened to the lattice's floor.
    #[must_use]
    pub fn band_fu(&self, spacing_fu: f32) -> f32 {
        if self.action.shapes_its_band() {
            self.falloff_fu
        } else {
            effective_falloff_fu(self.falloff_fu, spacing_fu)
        }
    }

    /// The band a stamp's print tends to: the lattice's floor, as the carving actions use
    /// (`StampParams::apply`). Every other action reads one potential, [`Self::band_fu`].
    #[must_use]
    pub fn print_band_fu(&self, spacing_fu: f32) -> f32 {
        if matches!(self.action, ToolAction::Stamp(_)) {
            effective_falloff_fu(self.falloff_fu, spacing_fu)
        } else {
            self.band_fu(spacing_fu)
        }
    }

    /// The world box an application at `pose` reads and writes on a lattice of knot spacing
    /// `spacing_fu`: the shape with its band (a stamp's print band too) and, for smoothing,
    /// one kernel width around it.
    #[must_use]
    pub fn influence_box(&self, pose: &ToolPose, spacing_fu: f32) -> (Vec3, Vec3) {
        let falloff = self.band_fu(spacing_fu);
        let print_falloff = self.print_band_fu(spacing_fu);
        let half = self
            .shape
            .influence_half_extents(falloff.max(print_falloff));
        let (mut lo, mut hi) = pose.world_bounds(half);
        if let ToolAction::Smooth { kernel_fu, .. } = self.action {
            // The average reads one kernel width beyond the tool.
            let reach = kernel_fu.max(spacing_fu);
            lo -= Vec3::splat(reach);
            hi += Vec3::splat(reach);
        }
        (lo, hi)
    }
}

/// Applies `tool` at `pose` for a dwell of `dt_s` seconds, refitting the touched coefficients.
/// When `recorder` is given, the touched region is remembered first so the application can
/// be undone.
///
/// # Errors
/// [`ToolError`] for invalid parameters, a missing patch or a failed fit; the clay is
/// unchanged then.
pub fn apply_tool(
    clay: &mut Clay,
    tool: &GeometricTool,
    pose: &ToolPose,
    dt_s: f32,
    options: &ApplyOptions,
    recorder: Option<&mut StepRecorder>,
) -> Result<ToolReport, ToolError> {
    tool.validate()?;
    let id = FieldId::Density(options.patch);
    if clay.field(id).is_none() {
        return Err(ToolError::NoPatch {
            patch: options.patch,
        });
    }
    if tool.action.paints() {
        return paint(clay, tool, pose, dt_s, options, recorder);
    }
    let lattice = clay.field(id).expect("checked above");
    let falloff = tool.band_fu(lattice.spacing);
    let print_falloff = tool.print_band_fu(lattice.spacing);
    let half = tool
        .shape
        .influence_half_extents(falloff.max(print_falloff));
    let (lo, hi) = tool.influence_box(pose, lattice.spacing);
    let Some(region) = coeff_box_around(lattice, lo, hi, 0) else {
        return Ok(ToolReport::default());
    };
    // Before anything is written: the bricks the box reaches must fit the clay's budget.
    clay.check_dense_room(id, region)?;
    let lattice = clay.field(id).expect("checked above");
    let reach = match tool.action {
        ToolAction::Smooth { kernel_fu, .. } => (kernel_fu / lattice.spacing).ceil() as usize,
        _ => 0,
    };
    // Only smoothing reads the old field away from the samples (its blur); the refit hands
    // every other action the old value at each sample.
    let before = matches!(tool.action, ToolAction::Smooth { .. })
        .then(|| sub_lattice(lattice, &region, 5 + reach));
    let iso = lattice.iso;
    let spacing = lattice.spacing;
    if let Some(r) = recorder {
        r.touch(clay, id, region);
    }
    // What the freeze mask holds there gets its share of the old coefficients back after.
    let held = hold_before_edit(clay, usize::from(options.patch), region)?;
    // `pose.to_local` with the rotation turned into a matrix once, not per sample.
    let to_local =
        glam::Affine3A::from_rotation_translation(pose.rotation, pose.position_fu).inverse();
    // The world-aligned box around the tool's own: samples outside it are left as they were
    // without transforming them (most of a refit box's margin).
    let (world_lo, world_hi) = pose.world_bounds(half);
    let reach = Reach {
        to_local,
        world_lo,
        world_hi,
        half,
        zero_beyond: tool.shape.zero_beyond(falloff.max(print_falloff)),
    };
    let blur_h = match tool.action {
        ToolAction::Smooth { kernel_fu, .. } => Some(kernel_fu.max(spacing)),
        _ => None,
    };
    let (lattice, others) = split_patch(&mut clay.density, usize::from(options.patch));
    let others = if options.own_term {
        OtherPatches::NONE
    } else {
        others
    };
    let rows = ToolRows {
        others: &others,
        reach: &reach,
        before: before.as_ref(),
        blur_h,
        action: tool.action,
        iso,
        dt_s,
    };
    let [visited, computed, dirtied] = match tool.shape {
        // The sphere's potential inlined into the row loop: the expressions of
        // `ToolShape::density` for a sphere, so the values are the same.
        ToolShape::Sphere { radius_fu } => rows.refit(lattice, region, options, |p: Vec3| {
            let d = p.length() - radius_fu;
            let t = density_from_distance(d, falloff);
            (
                t,
                if print_falloff == falloff {
                    t
                } else {
                    density_from_distance(d, print_falloff)
                },
            )
        }),
        ref shape => rows.refit(lattice, region, options, |p: Vec3| {
            if print_falloff == falloff {
                let t = shape.density(p, falloff);
                return (t, t);
            }
            match shape.signed_distance(p) {
                Some(d) => (
                    density_from_distance(d, falloff),
                    density_from_distance(d, print_falloff),
                ),
                None => {
                    let t = shape.density(p, falloff);
                    (t, t)
                }
            }
        }),
    }?;
    if let Some(held) = held {
        held.restore(lattice);
    }
    // The edit settled: bricks it left all one value (carved empty, filled solid) free theirs.
    lattice.coeffs.compact_within(region.min, region.max);
    Ok(ToolReport {
        patch: options.patch,
        coeff_box: Some(region),
        dirty_world: Some(region.world_support(lattice)),
        visited,
        computed,
        dirtied,
    })
}

/// Narrowest band of a tool's potential, in knot spans of the patch it edits.
///
/// The starting clays are fitted with a density ramp two knot spans wide, slope `1 / (2h)` at
/// their surface; the tool's C¹ ramp ([`density_from_distance`]) has slope `3 / (4w)` at its
/// surface, equal at `w = 1.5 h`. A steeper wall is more than the cubic lattice holds: its
/// least-squares fit rings and shrinks small dents (measured on the default block, a remove
/// sphere of one knot span's radius carved 17% shallow with a half-span band and 0.3% with
/// this floor; `tests/geometric_size.rs`). The surface (potential one half) stays where the
/// shape puts it whatever the band.
pub const MIN_FALLOFF_SPANS: f32 = 1.5;

/// The band a tool's potential falls over on a patch of knot spacing `spacing`: the tool's own
/// `falloff_fu`, at least [`MIN_FALLOFF_SPANS`] knot spans.
#[must_use]
pub fn effective_falloff_fu(falloff_fu: f32, spacing: f32) -> f32 {
    falloff_fu.max(MIN_FALLOFF_SPANS * spacing)
}

/// [`blur`] of the other patches' summed density.
fn blur_others(others: &OtherPatches<'_>, x: Vec3, h: f32) -> f32 {
    if others.is_empty() {
        return 0.0;
    }
    binomial_average(|p| others.value(p), x, h)
}

/// Patch `n`'s lattice, mutably, beside the other patches.
///
/// # Panics
/// When `n` is not a patch of `density` (callers check it first).
fn split_patch(density: &mut MultiPatchField, n: usize) -> (&mut BSplineLattice, OtherPatches<'_>) {
    density
        .split_patch_mut(n)
        .expect("the caller checked the patch")
}

/// What a geometric tool's row edit needs besides the shape's potential.
struct ToolRows<'a> {
    /// The clay's other patches (their sum offsets the rule).
    others: &'a OtherPatches<'a>,
    reach: &'a Reach,
    /// The clay before the edit, for smoothing's blur.
    before: Option<&'a BSplineLattice>,
    /// Smoothing's blur step.
    blur_h: Option<f32>,
    action: ToolAction,
    iso: f32,
    dt_s: f32,
}

impl ToolRows<'_> {
    /// Refits `region` to the tool's rule with the potential `density` (local point to
    /// `[0, 1]`), row by row; returns Ferley's visited, computed and dirtied counts.
    fn refit<D: Fn(Vec3) -> (f32, f32)>(
        &self,
        lattice: &mut BSplineLattice,
        region: CoeffBox,
        options: &ApplyOptions,
        density: D,
    ) -> Result<[usize; 3], ToolError> {
        let (mut visited, mut computed, mut dirtied) = (0_usize, 0_usize, 0_usize);
        let reach = self.reach;
        let (to_local, half) = (reach.to_local, reach.half);
        // The rule at one sample with potential `t` (zero outside the tool's box).
        let rule = |x: Vec3, (t, print): (f32, f32), old: f32| -> f32 {
            if t == 0.0 && print == 0.0 {
                return old;
            }
            if self.others.is_empty() {
                let blurred = match (self.blur_h, self.before) {
                    (Some(h), Some(before)) => blur(before, x, h),
                    _ => 0.0,
                };
                return self
                    .action
                    .density_with_print(old, t, print, blurred, self.iso, self.dt_s);
            }
            let offset = self.others.value(x);
            let blurred = match (self.blur_h, self.before) {
                (Some(h), Some(before)) => blur(before, x, h) + blur_others(self.others, x, h),
                _ => 0.0,
            };
            self.action
                .density_with_print(old + offset, t, print, blurred, self.iso, self.dt_s)
                - offset
        };
        let edit_row = |row: SampleRow<'_>| {
            let SampleRow { xs, y, z, values } = row;
            visited += xs.len();
            let (boxed, live) = reach.spans(xs, y, z);
            // The samples in the tool's local box form one run of the row: each local
            // coordinate is a rounded affine function of x, monotone, so each slab of the
            // box holds an interval of the row. Its ends are found by testing inwards from the
            // analytic span's; every sample between them passes the per-sample test.
            let inside = |i: usize| {
                to_local
                    .transform_point3(Vec3::new(xs[i], y, z))
                    .abs()
                    .cmple(half)
                    .all()
            };
            let mut first = boxed.start;
            while first < boxed.end && !inside(first) {
                first += 1;
            }
            let mut end = boxed.end;
            while end > first && !inside(end - 1) {
                end -= 1;
            }
            computed += end - first;
            // Beyond the shape's zero radius the potential is exactly zero: the old value.
            for i in live.start.max(first)..live.end.min(end) {
                let x = Vec3::new(xs[i], y, z);
                let local = to_local.transform_point3(x);
                let old = values[i];
                let new = rule(x, density(local), old);
                dirtied += usize::from(new != old);
                values[i] = new;
            }
        };
        refit_box_edit_rows(
            lattice,
            region.min,
            region.max,
            options.samples_per_span,
            edit_row,
        )?;
        Ok([visited, computed, dirtied])
    }
}

/// Where along a row of samples a tool can act: its world-aligned box, its local box and the
/// sphere beyond which its potential is exactly zero.
struct Reach {
    to_local: glam::Affine3A,
    world_lo: Vec3,
    world_hi: Vec3,
    half: Vec3,
    zero_beyond: Option<f32>,
}

impl Reach {
    /// For the row `(xs[i], y, z)`: the index range outside which no sample lies in the
    /// tool's local box, and the one outside which the tool's potential is exactly zero. Both
    /// are computed analytically and widened by a sample on each side: they only spare the
    /// samples that cannot count, and the caller still finds the box's run within the first
    /// with the per-sample test.
    fn spans(&self, xs: &[f32], y: f32, z: f32) -> (Range<usize>, Range<usize>) {
        let empty = (0..0, 0..0);
        let (lo, hi) = (self.world_lo, self.world_hi);
        if xs.is_empty() || y < lo.y || y > hi.y || z < lo.z || z > hi.z {
            return empty;
        }
        // The world box's x extent, exactly as a per-sample comparison would find it.
        let first = xs.partition_point(|&x| x < lo.x);
        let last = xs.partition_point(|&x| x <= hi.x);
        if first >= last {
            return empty;
        }
        // The row in local coordinates: `base + dir · x`.
        let dir = Vec3::from(self.to_local.matrix3.x_axis);
        let base = self.to_local.transform_point3(Vec3::new(0.0, y, z));
        let step = if xs.len() > 1 {
            (xs[1] - xs[0]).abs()
        } else {
            0.0
        };
        let (mut t0, mut t1) = (f32::NEG_INFINITY, f32::INFINITY);
        for a in 0..3 {
            let (d, b, h) = (dir[a], base[a], self.half[a]);
            if d.abs() < 1e-6 {
                // Parallel to this slab: all in or all out (with a rounding margin).
                if b.abs() > h + 1e-4 * (h + b.abs()) + step {
                    return empty;
                }
            } else {
                let (u, v) = ((-h - b) / d, (h - b) / d);
                t0 = t0.max(u.min(v));
                t1 = t1.min(u.max(v));
            }
        }
        let boxed = index_span(xs, t0 - step, t1 + step, first..last);
        let live = match self.zero_beyond {
            None => boxed.clone(),
            Some(r) => {
                // |base + dir·x|² ≤ R² with R widened well beyond rounding.
                let r = r * (1.0 + 1e-3) + step;
                let (dd, db, bb) = (dir.dot(dir), dir.dot(base), base.dot(base));
                let disc = db * db - dd * (bb - r * r);
                if disc < 0.0 || dd <= 0.0 {
                    0..0
                } else {
                    let s = disc.sqrt();
                    let (u, v) = ((-db - s) / dd, (-db + s) / dd);
                    index_span(xs, u - step, v + step, boxed.clone())
                }
            }
        };
        (boxed, live)
    }
}

/// The indices within `within` of the ascending `xs` that lie in `[t0, t1]`.
fn index_span(xs: &[f32], t0: f32, t1: f32, within: Range<usize>) -> Range<usize> {
    if t0.is_nan() || t1.is_nan() || t0 > t1 {
        return within.start..within.start;
    }
    let a = xs.partition_point(|&x| x < t0).max(within.start);
    let b = xs.partition_point(|&x| x <= t1).min(within.end);
    a..b.max(a)
}

/// Applies `tool` at each pose of a path in turn, splitting `duration_s` evenly (toothpaste
/// deposits at its rate along the path); one recorder covers the whole stroke.
///
/// # Errors
/// As [`apply_tool`]; applications before the failing one stay applied (and recorded).
pub fn apply_stroke(
    clay: &mut Clay,
    tool: &GeometricTool,
    poses: &[ToolPose],
    duration_s: f32,
    options: &ApplyOptions,
    mut recorder: Option<&mut StepRecorder>,
) -> Result<ToolReport, ToolError> {
    let dt_s = duration_s / poses.len().max(1) as f32;
    let mut report = ToolReport {
        patch: options.patch,
        ..ToolReport::default()
    };
    for pose in poses {
        let r = apply_tool(clay, tool, pose, dt_s, options, recorder.as_deref_mut())?;
        report.merge(&r);
    }
    Ok(report)
}

/// CSG between the clay's patch and another sculpt (Guo & Qin Table 1): `action` must be
/// [`ToolAction::Union`], [`ToolAction::Intersection`] or [`ToolAction::Difference`]; the other
/// clay's summed density plays the tool's part. Union and difference refit only where the
/// other clay's patches reach; intersection refits the whole patch.
///
/// # Errors
/// [`ToolError::Action`] for a non-CSG action, [`ToolError::NoPatch`], or a failed fit.
pub fn apply_csg(
    clay: &mut Clay,
    other: &Clay,
    action: ToolAction,
    options: &ApplyOptions,
    recorder: Option<&mut StepRecorder>,
) -> Result<ToolReport, ToolError> {
    if !matches!(
        action,
        ToolAction::Union | ToolAction::Intersection | ToolAction::Difference
    ) {
        return Err(ToolError::Action(ActionError(format!(
            "{} is not a CSG operation",
            action.name()
        ))));
    }
    let id = FieldId::Density(options.patch);
    let Some(lattice) = clay.field(id) else {
        return Err(ToolError::NoPatch {
            patch: options.patch,
        });
    };
    // Intersection clears the clay wherever the other clay is not: the whole patch.
    let region = if action == ToolAction::Intersection {
        Some(CoeffBox::whole(lattice.dims))
    } else {
        other
            .density
            .patches
            .iter()
            .filter_map(|p| {
                let (lo, hi) = p.world_support();
                coeff_box_around(lattice, lo, hi, 0)
            })
            .reduce(|a, b| a.union(&b))
    };
    let Some(region) = region else {
        return Ok(ToolReport::default());
    };
    clay.check_dense_room(id, region)?;
    let iso = clay.field(id).expect("checked above").iso;
    if let Some(r) = recorder {
        r.touch(clay, id, region);
    }
    let patch = usize::from(options.patch);
    let held = hold_before_edit(clay, patch, region)?;
    let counts = Counts::default();
    let (lattice, others) = split_patch(&mut clay.density, patch);
    let target = |x: Vec3, old: f32| {
        counts.visited.set(counts.visited.get() + 1);
        counts.computed.set(counts.computed.get() + 1);
        let offset = if others.is_empty() {
            0.0
        } else {
            others.value(x)
        };
        let tool = other.density.value(x).clamp(0.0, 1.0);
        let new = action.density(old + offset, tool, 0.0, iso, 0.0) - offset;
        if new != old {
            counts.dirtied.set(counts.dirtied.get() + 1);
        }
        new
    };
    refit_box_edit(
        lattice,
        region.min,
        region.max,
        options.samples_per_span,
        target,
    )?;
    if let Some(held) = held {
        held.restore(lattice);
    }
    // The edit settled: bricks it left all one value (carved empty, filled solid) free theirs.
    lattice.coeffs.compact_within(region.min, region.max);
    Ok(ToolReport {
        patch: options.patch,
        coeff_box: Some(region),
        dirty_world: Some(region.world_support(lattice)),
        visited: counts.visited.get(),
        computed: counts.computed.get(),
        dirtied: counts.dirtied.get(),
    })
}

#[derive(Default)]
struct Counts {
    visited: Cell<usize>,
    computed: Cell<usize>,
    dirtied: Cell<usize>,
}

/// Refits `region` of the lattice `id` (which must exist) to `target(x, old)` (`old`: the
/// field at `x` before the edit) and reports it with the
/// counts `target` kept (Ferley's visited, computed and dirtied corners).
fn refit_region(
    clay: &mut Clay,
    id: FieldId,
    region: CoeffBox,
    options: &ApplyOptions,
    counts: &Counts,
    target: impl Fn(Vec3, f32) -> f32,
) -> Result<ToolReport, ToolError> {
    let lattice = clay
        .field_mut(id)
        .expect("the caller checked the lattice exists");
    refit_box_edit(
        lattice,
        region.min,
        region.max,
        options.samples_per_span,
        target,
    )?;
    Ok(ToolReport {
        patch: 0,
        coeff_box: Some(region),
        dirty_world: Some(region.world_support(lattice)),
        visited: counts.visited.get(),
        computed: counts.computed.get(),
        dirtied: counts.dirtied.get(),
    })
}

/// Separable binomial (1, 2, 1)/4 average over the 27 points `h` apart: a local low-pass of
/// the clay with a standard deviation of `h/√2` per axis.
fn blur(lattice: &BSplineLattice, x: Vec3, h: f32) -> f32 {
    binomial_average(|p| lattice.value(p), x, h)
}

/// The separable binomial (1, 2, 1)/4 average of `f` over the 27 points `h` apart around `x`.
fn binomial_average(f: impl Fn(Vec3) -> f32, x: Vec3, h: f32) -> f32 {
    const W: [f32; 3] = [0.25, 0.5, 0.25];
    let mut sum = 0.0;
    for (c, wz) in W.iter().enumerate() {
        for (b, wy) in W.iter().enumerate() {
            for (a, wx) in W.iter().enumerate() {
                let o = Vec3::new(a as f32 - 1.0, b as f32 - 1.0, c as f32 - 1.0) * h;
                sum += wx * wy * wz * f(x + o);
            }
        }
    }
    sum
}

/// Painting: blends each colour channel towards the tool's colour (coverage towards 1) with
/// the action's weight, refitting the colour lattices; the density is untouched.
fn paint(
    clay: &mut Clay,
    tool: &GeometricTool,
    pose: &ToolPose,
    dt_s: f32,
    options: &ApplyOptions,
    mut recorder: Option<&mut StepRecorder>,
) -> Result<ToolReport, ToolError> {
    let patch = clay.base();
    let half = tool.shape.influence_half_extents(tool.falloff_fu);
    let (lo, hi) = pose.world_bounds(half);
    // The clay's density near the tool, for the soft painter's presence weight: the sum of
    // every patch there (a detail patch adds clay the base does not hold), each copied over
    // the tool's box with its map.
    let density: Vec<(BSplineLattice, Affine3A)> = clay
        .density
        .patches
        .iter()
        .filter_map(|p| {
            let (plo, phi) = p.patch_box_of(lo, hi);
            coeff_box_around(&p.lattice, plo, phi, 0)
                .map(|b| (sub_lattice(&p.lattice, &b, 5), p.world_to_patch))
        })
        .collect();
    let iso = patch.iso;
    // Before anything is written: the four channels' bricks in the tool's box must fit the
    // clay's budget (a colour field made here is all uniform).
    let made_colour = clay.colour.is_none();
    if made_colour {
        let colour = ColourField::matching(patch).map_err(ToolError::Colour)?;
        clay.colour = Some(colour);
    }
    let mut more = 0;
    let mut reached = None;
    for channel in 0..4_u8 {
        let lattice = clay.field(FieldId::Colour(channel)).expect("colour exists");
        if let Some(region) = coeff_box_around(lattice, lo, hi, 0) {
            more += lattice
                .coeffs
                .uniform_bricks_holding(region.min, region.max);
            reached = Some(region);
        }
    }
    if let Err(refused) = check_dense_room(clay.dense_brick_count(), more, reached) {
        if made_colour {
            clay.colour = None;
        }
        return Err(refused.into());
    }
    let rgb = tool.action.rgb().unwrap_or([0.0; 3]);
    let mut report = ToolReport::default();
    for channel in 0..4_u8 {
        let id = FieldId::Colour(channel);
        let lattice = clay.field(id).expect("colour exists");
        let Some(region) = coeff_box_around(lattice, lo, hi, 0) else {
            return Ok(report);
        };
        let goal = if channel < 3 {
            rgb[usize::from(channel)]
        } else {
            1.0
        };
        if let Some(r) = recorder.as_deref_mut() {
            r.touch(clay, id, region);
        }
        let counts = Counts::default();
        let target = |x: Vec3, old: f32| {
            counts.visited.set(counts.visited.get() + 1);
            let local = pose.to_local(x);
            if !local.abs().cmple(half).all() {
                return old;
            }
            counts.computed.set(counts.computed.get() + 1);
            let t = tool.shape.density(local, tool.falloff_fu);
            let clay_here: f32 = density
                .iter()
                .map(|(d, to_patch)| d.value(to_patch.transform_point3(x)))
                .sum();
            let w = tool.action.paint_weight(clay_here, t, iso, dt_s);
            if w == 0.0 {
                return old;
            }
            counts.dirtied.set(counts.dirtied.get() + 1);
            old + w * (goal - old)
        };
        let channel_report = refit_region(clay, id, region, options, &counts, target)?;
        if channel == 0 {
            report = channel_report;
        }
    }
    Ok(report)
}

#[cfg(test)]
mod tests {
    use std::f32::consts::PI;

    use super::*;
    use crate::field::{Primitive, lattice_from_primitive};
    use crate::tools::{ContactParams, FreeformTool, StampParams, StepRecorder};

    const N: usize = 36;
    const H: f32 = 1.0 / 16.0;

    /// Over `samples` quasi-random points of the lattice's interior, away from both surfaces
    /// (sharp CSG edges round off over the fit's width), counts the points checked and those
    /// `l` classifies differently from the analytic CSG `action` of `a` and `b` (signed
    /// distances, negative inside).
    fn csg_misclassified(
        l: &BSplineLattice,
        action: ToolAction,
        samples: usize,
        a: impl Fn(Vec3) -> f32,
        b: impl Fn(Vec3) -> f32,
    ) -> (usize, usize) {
        let (mut checked, mut wrong) = (0, 0);
        for s in 0..samples {
            let f = Vec3::new(
                (s * 37 % 101) as f32 / 101.0,
                (s * 53 % 103) as f32 / 103.0,
                (s * 71 % 107) as f32 / 107.0,
            );
            let x = Vec3::splat(0.2) + f * (N as f32 * H - 0.4);
            let (da, db) = (a(x), b(x));
            if da.abs() < 1.5 * H || db.abs() < 1.5 * H {
                continue;
            }
            let expected = match action {
                ToolAction::Union => da < 0.0 || db < 0.0,
                ToolAction::Intersection => da < 0.0 && db < 0.0,
                _ => da < 0.0 && db >= 0.0,
            };
            checked += 1;
            wrong += usize::from(l.is_inside(x) != expected);
        }
        (checked, wrong)
    }

    fn empty() -> Clay {
        Clay::single(BSplineLattice::zeros([N; 3], H, Vec3::ZERO).unwrap())
    }

    fn clay_of(p: Primitive) -> Clay {
        Clay::single(lattice_from_primitive([N; 3], H, Vec3::ZERO, &p, 2.0 * H, 2).unwrap())
    }

    fn centre() -> Vec3 {
        Vec3::splat(H * (N as f32 - 1.0) / 2.0)
    }

    fn tool(shape: ToolShape, action: ToolAction) -> GeometricTool {
        GeometricTool {
            shape,
            action,
            falloff_fu: 2.0 * H,
        }
    }

    /// Volume of the solid by counting inside samples on a grid of step `H / 2`.
    fn volume(l: &BSplineLattice) -> f32 {
        let step = H / 2.0;
        let n = (N as f32 * H / step) as usize;
        let mut inside = 0;
        for k in 0..n {
            for j in 0..n {
                for i in 0..n {
                    let x = (Vec3::new(i as f32, j as f32, k as f32) + 0.5) * step;
                    inside += usize::from(l.is_inside(x));
                }
            }
        }
        inside as f32 * step * step * step
    }

    fn add_once(clay: &mut Clay, shape: ToolShape, at: Vec3) -> ToolReport {
        let t = tool(
            shape,
            ToolAction::Add {
                deposit_rate_per_s: 1.0,
            },
        );
        apply_tool(
            clay,
            &t,
            &ToolPose::at(at),
            1.0,
            &ApplyOptions::default(),
            None,
        )
        .unwrap()
    }

    /// On a clay of two patches the tool's rule acts on the sum (eq. (3)): a union on the
    /// detail patch raises the sum to the tool's potential where that exceeds the base, not
    /// base plus potential, and the base patch is left alone.
    #[test]
    fn a_tool_on_a_detail_patch_makes_the_sum_follow_its_rule() {
        let mut clay = empty();
        clay.base_mut().coeffs.fill(0.3);
        let c = centre();
        let detail = clay
            .density
            .refine(c - Vec3::splat(0.8), c + Vec3::splat(0.8), 1)
            .unwrap();
        assert_eq!(detail, 1);
        let base = clay.base().clone();
        let r = 0.35;
        let t = tool(ToolShape::Sphere { radius_fu: r }, ToolAction::Union);
        let options = ApplyOptions {
            patch: 1,
            ..ApplyOptions::default()
        };
        let report = apply_tool(&mut clay, &t, &ToolPose::at(c), 1.0, &options, None).unwrap();
        assert_eq!(report.patch, 1);
        assert_eq!(clay.base(), &base, "the base patch is untouched");
        // A stroke of several poses names the patch it edited too (its box indexes that
        // patch's lattice, and the engine publishes it there).
        let poses = [ToolPose::at(c), ToolPose::at(c + Vec3::new(0.1, 0.0, 0.0))];
        let mut stroked = clay.clone();
        let report = apply_stroke(&mut stroked, &t, &poses, 1.0, &options, None).unwrap();
        assert_eq!(report.patch, 1);
        assert!(report.coeff_box.is_some());
        // Inside the tool its potential (1 at the centre) wins: the sum is 1, not 1.3.
        let at_centre = clay.density.value(c);
        assert!(
            (at_centre - 1.0).abs() < 0.05,
            "sum at the centre {at_centre}"
        );
        // Far outside the tool the sum is the base's 0.3.
        let away = c + Vec3::new(0.7, 0.0, 0.0);
        assert!((clay.density.value(away) - 0.3).abs() < 0.02);
        assert!(clay.density.is_inside(c) && !clay.density.is_inside(away));
    }

    #[test]
    fn adding_a_sphere_grows_the_volume_by_the_sphere_and_touches_only_its_box() {
        let mut clay = empty();
        let before = clay.clone();
        let r = 0.5;
        let report = add_once(&mut clay, ToolShape::Sphere { radius_fu: r }, centre());
        let v = volume(&clay.density.patches[0].lattice);
        let expected = 4.0 / 3.0 * PI * r * r * r;
        assert!((v - expected).abs() < 0.03 * expected, "{v} vs {expected}");
        // Ferley's counts are nested and non-trivial.
        assert!(report.visited > report.computed && report.computed > report.dirtied);
        assert!(report.dirtied > 0);
        // Every coefficient outside the refitted box is bit-identical.
        let b = report.coeff_box.unwrap();
        let l = &clay.density.patches[0].lattice;
        for k in 0..N {
            for j in 0..N {
                for i in 0..N {
                    if !b.contains(i, j, k) {
                        let idx = l.index(i, j, k);
                        assert_eq!(
                            l.coeffs[idx].to_bits(),
                            before.density.patches[0].lattice.coeffs[idx].to_bits()
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn every_analytic_shape_adds_about_its_own_volume() {
        let shapes = [
            ToolShape::Ellipsoid {
                radii_fu: Vec3::new(0.6, 0.4, 0.3),
            },
            ToolShape::Box {
                half_extents_fu: Vec3::new(0.5, 0.3, 0.4),
            },
            ToolShape::Cylinder {
                radius_fu: 0.35,
                half_height_fu: 0.5,
            },
            ToolShape::Capsule {
                radius_fu: 0.3,
                half_height_fu: 0.4,
            },
        ];
        for shape in shapes {
            let mut clay = empty();
            add_once(&mut clay, shape.clone(), centre());
            let v = volume(&clay.density.patches[0].lattice);
            let expected = shape.volume_m3().unwrap();
            // Box and cylinder edges round off by the fit's smoothness.
            assert!(
                (v - expected).abs() < 0.06 * expected,
                "{shape:?}: {v} vs {expected}"
            );
        }
    }

    #[test]
    fn toothpaste_deposits_progressively_at_its_rate() {
        let mut clay = empty();
        let t = tool(
            ToolShape::Sphere { radius_fu: 0.4 },
            ToolAction::Add {
                deposit_rate_per_s: 1.0,
            },
        );
        let pose = ToolPose::at(centre());
        // 0.3 s at 1/s deposits 0.3 < iso: no solid yet.
        apply_tool(&mut clay, &t, &pose, 0.3, &ApplyOptions::default(), None).unwrap();
        assert_eq!(volume(&clay.density.patches[0].lattice), 0.0);
        apply_tool(&mut clay, &t, &pose, 0.3, &ApplyOptions::default(), None).unwrap();
        assert!(volume(&clay.density.patches[0].lattice) > 0.0);
        // A stroke along a path lays a sausage longer than the tool.
        let mut clay = empty();
        let path: Vec<ToolPose> = (0..8)
            .map(|s| ToolPose::at(centre() + Vec3::X * (s as f32 * 0.1 - 0.35)))
            .collect();
        let small = tool(
            ToolShape::Sphere { radius_fu: 0.15 },
            ToolAction::Add {
                deposit_rate_per_s: 8.0,
            },
        );
        apply_stroke(
            &mut clay,
            &small,
            &path,
            1.0,
            &ApplyOptions::default(),
            None,
        )
        .unwrap();
        let l = &clay.density.patches[0].lattice;
        assert!(l.is_inside(centre() - Vec3::X * 0.4) && l.is_inside(centre() + Vec3::X * 0.4));
        assert!(!l.is_inside(centre() + Vec3::Y * 0.3));
    }

    #[test]
    fn removing_makes_a_hole_of_the_right_size() {
        let block = Primitive::Box {
            centre: centre(),
            half_extents: Vec3::splat(0.8),
        };
        let mut clay = clay_of(block);
        let v0 = volume(&clay.density.patches[0].lattice);
        let r = 0.4;
        let t = tool(ToolShape::Sphere { radius_fu: r }, ToolAction::Remove);
        apply_tool(
            &mut clay,
            &t,
            &ToolPose::at(centre()),
            0.0,
            &ApplyOptions::default(),
            None,
        )
        .unwrap();
        let hole = v0 - volume(&clay.density.patches[0].lattice);
        let expected = 4.0 / 3.0 * PI * r * r * r;
        assert!(
            (hole - expected).abs() < 0.05 * expected,
            "{hole} vs {expected}"
        );
        let l = &clay.density.patches[0].lattice;
        assert!(!l.is_inside(centre()));
        assert!(!l.is_inside(centre() + Vec3::Y * (r - 1.5 * H)));
        assert!(l.is_inside(centre() + Vec3::Y * (r + 1.5 * H)));
    }

    #[test]
    fn soft_remove_erodes_progressively() {
        let mut clay = clay_of(Primitive::Box {
            centre: centre(),
            half_extents: Vec3::splat(0.8),
        });
        let v0 = volume(&clay.density.patches[0].lattice);
        let t = tool(
            ToolShape::Sphere { radius_fu: 0.4 },
            ToolAction::SoftRemove { rate_per_s: 1.0 },
        );
        let pose = ToolPose::at(centre() + Vec3::Z * 0.8);
        apply_tool(&mut clay, &t, &pose, 0.2, &ApplyOptions::default(), None).unwrap();
        let v1 = volume(&clay.density.patches[0].lattice);
        apply_tool(&mut clay, &t, &pose, 0.6, &ApplyOptions::default(), None).unwrap();
        let v2 = volume(&clay.density.patches[0].lattice);
        assert!(v0 > v1 && v1 > v2, "{v0} {v1} {v2}");
    }

    #[test]
    fn union_and_difference_with_a_shape_match_the_analytic_classification() {
        let sphere = Primitive::Sphere {
            centre: centre(),
            radius: 0.6,
        };
        let half = Vec3::new(0.7, 0.3, 0.3);
        let offset = Vec3::new(0.5, 0.0, 0.0);
        let in_sphere = |x: Vec3| sphere.signed_distance(x);
        let in_box = |x: Vec3| {
            let q = (x - centre() - offset).abs() - half;
            q.max(Vec3::ZERO).length() + q.max_element().min(0.0)
        };
        // Intersection is CSG with another clay only: as a brush it is refused, the clay
        // untouched.
        let mut clay = clay_of(sphere);
        let brush = tool(
            ToolShape::Box {
                half_extents_fu: half,
            },
            ToolAction::Intersection,
        );
        let refused = apply_tool(
            &mut clay,
            &brush,
            &ToolPose::at(centre() + offset),
            0.0,
            &ApplyOptions::default(),
            None,
        );
        assert!(matches!(refused, Err(ToolError::Action(_))), "{refused:?}");
        assert_eq!(clay, clay_of(sphere));
        for action in [ToolAction::Union, ToolAction::Difference] {
            let mut clay = clay_of(sphere);
            let t = tool(
                ToolShape::Box {
                    half_extents_fu: half,
                },
                action,
            );
            apply_tool(
                &mut clay,
                &t,
                &ToolPose::at(centre() + offset),
                0.0,
                &ApplyOptions::default(),
                None,
            )
            .unwrap();
            let l = &clay.density.patches[0].lattice;
            let (checked, wrong) = csg_misclassified(l, action, 4000, in_sphere, in_box);
            assert!(checked > 2000);
            assert!(
                wrong * 200 < checked,
                "{action:?}: {wrong} of {checked} misclassified"
            );
        }
    }

    /// Mean |mean curvature| of the surface over points near `around`, by central differences
    /// of the normalised gradient.
    fn mean_curvature_near(l: &BSplineLattice, around: Vec3, radius: f32) -> f32 {
        let e = H / 4.0;
        let normal = |x: Vec3| l.gradient(x).normalize_or_zero();
        let (mut sum, mut count) = (0.0, 0);
        for s in 0..600 {
            let f = Vec3::new(
                (s * 37 % 101) as f32 / 101.0,
                (s * 53 % 103) as f32 / 103.0,
                (s * 71 % 107) as f32 / 107.0,
            ) * 2.0
                - 1.0;
            let mut x = around + f * radius;
            // Project onto the surface with a few Newton steps.
            for _ in 0..8 {
                let (v, g) = l.value_and_gradient(x);
                if g.length_squared() < 1e-8 {
                    break;
                }
                x -= (v - l.iso) * g / g.length_squared();
            }
            if (l.value(x) - l.iso).abs() > 1e-3 || (x - around).length() > radius {
                continue;
            }
            let div = (normal(x + Vec3::X * e).x - normal(x - Vec3::X * e).x
                + normal(x + Vec3::Y * e).y
                - normal(x - Vec3::Y * e).y
                + normal(x + Vec3::Z * e).z
                - normal(x - Vec3::Z * e).z)
                / (2.0 * e);
            sum += div.abs();
            count += 1;
        }
        assert!(count > 50, "only {count} surface points");
        sum / count as f32
    }

    #[test]
    fn smoothing_lowers_curvature() {
        // A box's edges and corners are the most curved part of its surface.
        let mut clay = clay_of(Primitive::Box {
            centre: centre(),
            half_extents: Vec3::splat(0.6),
        });
        let corner = centre() + Vec3::splat(0.6);
        let k0 = mean_curvature_near(&clay.density.patches[0].lattice, corner, 0.25);
        let t = tool(
            ToolShape::Sphere { radius_fu: 0.4 },
            ToolAction::Smooth {
                rate_per_s: 1.0,
                kernel_fu: 2.0 * H,
            },
        );
        for _ in 0..3 {
            apply_tool(
                &mut clay,
                &t,
                &ToolPose::at(corner),
                1.0,
                &ApplyOptions::default(),
                None,
            )
            .unwrap();
        }
        let k1 = mean_curvature_near(&clay.density.patches[0].lattice, corner, 0.25);
        assert!(k1 < 0.8 * k0, "curvature {k0} -> {k1}");
    }

    #[test]
    fn a_stamp_leaves_the_tools_print_with_a_rim() {
        // A slab whose top face is at z = top.
        let top = centre().z + 0.3;
        let slab = Primitive::Box {
            centre: centre() - Vec3::Z * 0.3,
            half_extents: Vec3::new(0.9, 0.9, 0.6),
        };
        let mut clay = clay_of(slab);
        let r = 0.3;
        let at = Vec3::new(centre().x, centre().y, top);
        // A wide falloff band: the bulge lives in it, and must span a few knots to be fitted.
        let t = GeometricTool {
            shape: ToolShape::Sphere { radius_fu: r },
            action: ToolAction::Stamp(StampParams::default()),
            falloff_fu: 4.0 * H,
        };
        // Three whole prints: the rim grows from the surface outward (a rise is weighted by
        // the clay's presence), a little more with each.
        for _ in 0..3 {
            apply_tool(
                &mut clay,
                &t,
                &ToolPose::at(at),
                0.01,
                &ApplyOptions::default(),
                None,
            )
            .unwrap();
        }
        let l = &clay.density.patches[0].lattice;
        // The print: the tool's hemisphere is hollowed out of the slab.
        for depth in [0.1, 0.2, r - 2.0 * H] {
            assert!(
                !l.is_inside(at - Vec3::Z * depth),
                "depth {depth} still filled"
            );
        }
        assert!(!l.is_inside(at + Vec3::new(r * 0.6, 0.0, -0.1)));
        // Beneath the print the slab stays.
        assert!(l.is_inside(at - Vec3::Z * (r + 3.0 * H)));
        // The rim: material pushed up just outside the tool, above the old top face.
        let rim = (0..40)
            .map(|s| at + Vec3::new(r + s as f32 * H / 8.0, 0.0, 0.5 * H))
            .any(|x| l.is_inside(x));
        assert!(rim, "no rim above the old surface");
        // Far away the slab is untouched.
        assert!(l.is_inside(at + Vec3::new(0.7, 0.0, -2.0 * H)));
        assert!(!l.is_inside(at + Vec3::new(0.7, 0.0, 2.0 * H)));
    }

    #[test]
    fn contact_deformation_dents_with_negative_alpha_and_bulges_with_positive() {
        let sphere = Primitive::Sphere {
            centre: centre(),
            radius: 0.6,
        };
        let surface = centre() + Vec3::X * 0.6;
        let probe = centre() + Vec3::X * (0.6 - 2.0 * H);
        let small = ToolShape::Sphere { radius_fu: 0.2 };

        let mut dent = clay_of(sphere);
        let t = tool(
            small.clone(),
            ToolAction::Contact(ContactParams::with_alpha(-3.0)),
        );
        apply_tool(
            &mut dent,
            &t,
            &ToolPose::at(surface),
            0.01,
            &ApplyOptions::default(),
            None,
        )
        .unwrap();
        assert!(!dent.density.patches[0].lattice.is_inside(probe), "dent");
        assert!(
            dent.density.patches[0].lattice.is_inside(centre()),
            "core untouched"
        );

        // A bulge grows from the surface outward, a little with each whole application: ten
        // take it a knot span out.
        let mut bulge = clay_of(sphere);
        let t = tool(small, ToolAction::Contact(ContactParams::with_alpha(3.0)));
        for _ in 0..10 {
            apply_tool(
                &mut bulge,
                &t,
                &ToolPose::at(surface),
                0.01,
                &ApplyOptions::default(),
                None,
            )
            .unwrap();
        }
        assert!(
            bulge.density.patches[0]
                .lattice
                .is_inside(surface + Vec3::X * H),
            "bulge"
        );
    }

    #[test]
    fn painting_colours_the_surface_under_the_tool_only() {
        let mut clay = clay_of(Primitive::Sphere {
            centre: centre(),
            radius: 0.6,
        });
        let t = tool(
            ToolShape::Sphere { radius_fu: 0.25 },
            ToolAction::Paint {
                rgb: [1.0, 0.2, 0.0],
            },
        );
        let at = centre() + Vec3::Y * 0.6;
        let density = clay.density.patches[0].lattice.clone();
        let mut rec = StepRecorder::new("paint");
        apply_tool(
            &mut clay,
            &t,
            &ToolPose::at(at),
            0.0,
            &ApplyOptions::default(),
            Some(&mut rec),
        )
        .unwrap();
        assert_eq!(
            clay.density.patches[0].lattice, density,
            "painting leaves the density alone"
        );
        let c = clay.colour.as_ref().unwrap();
        let here = c.rgba(at);
        assert!(
            (here.x - 1.0).abs() < 0.05 && (here.y - 0.2).abs() < 0.05 && here.w > 0.95,
            "{here}"
        );
        assert!(c.rgba(centre() - Vec3::Y * 0.6).w < 0.01);
        assert!(rec.touched_box(FieldId::Colour(0)).is_some());
        // The soft painter takes paint only where there is clay.
        let soft = tool(
            ToolShape::Sphere { radius_fu: 0.25 },
            ToolAction::SoftPaint {
                rgb: [0.0, 0.0, 1.0],
                rate_per_s: 1.0,
            },
        );
        let air = centre() + Vec3::new(0.0, 0.0, 1.0);
        apply_tool(
            &mut clay,
            &soft,
            &ToolPose::at(air),
            1.0,
            &ApplyOptions::default(),
            None,
        )
        .unwrap();
        assert!(clay.colour.as_ref().unwrap().rgba(air).w < 0.01);
    }

    #[test]
    fn the_soft_painter_finds_the_clay_a_detail_patch_holds() {
        // The base is empty; a detail patch alone holds clay around the centre.
        let mut clay = empty();
        let at = centre();
        let n = clay
            .density
            .refine(at - Vec3::splat(0.5), at + Vec3::splat(0.5), 1)
            .unwrap();
        clay.density.patches[n].lattice.coeffs.fill(1.0);
        assert!(clay.density.patches[0].lattice.value(at) < 1e-6);
        assert!(clay.density.value(at) > clay.density.iso());
        let soft = tool(
            ToolShape::Sphere { radius_fu: 0.25 },
            ToolAction::SoftPaint {
                rgb: [0.0, 0.0, 1.0],
                rate_per_s: 1.0,
            },
        );
        apply_tool(
            &mut clay,
            &soft,
            &ToolPose::at(at),
            1.0,
            &ApplyOptions::default(),
            None,
        )
        .unwrap();
        let here = clay.colour.as_ref().unwrap().rgba(at);
        assert!(here.w > 0.9 && here.z > 0.9, "{here}");
    }

    #[test]
    fn a_freeform_tool_from_a_sculpt_adds_its_shape() {
        let r = 0.3;
        let sculpt = lattice_from_primitive(
            [16; 3],
            H,
            Vec3::ZERO,
            &Primitive::Sphere {
                centre: Vec3::splat(7.5 * H),
                radius: r,
            },
            2.0 * H,
            2,
        )
        .unwrap();
        let freeform = ToolShape::Freeform(FreeformTool {
            lattice: sculpt,
            scale: Vec3::new(2.0, 1.0, 1.0),
        });
        let mut clay = empty();
        add_once(&mut clay, freeform, centre());
        let v = volume(&clay.density.patches[0].lattice);
        // Scaled by two along x: an ellipsoid of radii (2r, r, r).
        let expected = 4.0 / 3.0 * PI * 2.0 * r * r * r;
        assert!((v - expected).abs() < 0.08 * expected, "{v} vs {expected}");
        assert!(
            clay.density.patches[0]
                .lattice
                .is_inside(centre() + Vec3::X * (2.0 * r - 2.0 * H))
        );
    }

    #[test]
    fn csg_between_two_sculpts_matches_the_classification() {
        let a = Primitive::Sphere {
            centre: centre() - Vec3::X * 0.25,
            radius: 0.5,
        };
        let b = Primitive::Sphere {
            centre: centre() + Vec3::X * 0.25,
            radius: 0.5,
        };
        let other = clay_of(b);
        for action in [
            ToolAction::Union,
            ToolAction::Intersection,
            ToolAction::Difference,
        ] {
            let mut clay = clay_of(a);
            apply_csg(&mut clay, &other, action, &ApplyOptions::default(), None).unwrap();
            let l = &clay.density.patches[0].lattice;
            let (checked, wrong) = csg_misclassified(
                l,
                action,
                3000,
                |x| a.signed_distance(x),
                |x| b.signed_distance(x),
            );
            assert!(wrong * 200 < checked, "{action:?}: {wrong} of {checked}");
        }
        let mut clay = clay_of(a);
        assert!(
            apply_csg(
                &mut clay,
                &other,
                ToolAction::Remove,
                &ApplyOptions::default(),
                None
            )
            .is_err()
        );
    }

    #[test]
    fn bad_parameters_are_rejected_without_changing_the_clay() {
        let mut clay = empty();
        let before = clay.clone();
        let mut t = tool(ToolShape::Sphere { radius_fu: 0.3 }, ToolAction::Remove);
        t.falloff_fu = 0.0;
        let pose = ToolPose::at(centre());
        assert!(matches!(
            apply_tool(&mut clay, &t, &pose, 1.0, &ApplyOptions::default(), None),
            Err(ToolError::BadFalloff { .. })
        ));
        let options = ApplyOptions {
            patch: 3,
            ..ApplyOptions::default()
        };
        let t = tool(ToolShape::Sphere { radius_fu: 0.3 }, ToolAction::Remove);
        assert!(matches!(
            apply_tool(&mut clay, &t, &pose, 1.0, &options, None),
            Err(ToolError::NoPatch { patch: 3 })
        ));
        assert_eq!(clay, before);
        // A tool far outside the lattice is a no-op, not an error.
        let far = ToolPose::at(Vec3::splat(100.0));
        let report = apply_tool(&mut clay, &t, &far, 1.0, &ApplyOptions::default(), None).unwrap();
        assert!(report.coeff_box.is_none());
    }

    #[test]
    fn an_edit_whose_box_could_pass_the_dense_budget_is_refused_and_changes_nothing() {
        use crate::field::{DenseBudgetError, MAX_DENSE_BRICKS};
        // A thin clay of empty space spanning more bricks than the budget: 2048 × 1024 × 40
        // coefficients, 256 × 128 × 5 = 163 840 uniform bricks (a 2.5 MiB directory).
        let mut clay =
            Clay::single(BSplineLattice::zeros([2048, 1024, 40], H, Vec3::ZERO).unwrap());
        assert!(clay.base().coeffs.brick_count() > MAX_DENSE_BRICKS);
        // Smoothing everything: its box reaches every brick, more than the budget holds.
        let smooth = tool(
            ToolShape::Box {
                half_extents_fu: Vec3::new(2048.0, 1024.0, 40.0) * H,
            },
            ToolAction::Smooth {
                kernel_fu: 2.0 * H,
                rate_per_s: 1.0,
            },
        );
        let before = clay.clone();
        let everywhere = ToolPose::at(Vec3::new(1024.0, 512.0, 20.0) * H);
        let refused = apply_tool(
            &mut clay,
            &smooth,
            &everywhere,
            1.0,
            &ApplyOptions::default(),
            None,
        );
        match refused {
            Err(ToolError::DenseBudget(DenseBudgetError { dense: 0, more, at })) => {
                assert!(more > MAX_DENSE_BRICKS, "{more}");
                assert!(at.is_some());
            }
            other => panic!("{other:?}"),
        }
        assert_eq!(clay.dense_brick_count(), 0);
        assert!(clay == before, "the clay is unchanged");
        // A small lump in the same clay fits.
        let lump = tool(
            ToolShape::Sphere { radius_fu: 4.0 * H },
            ToolAction::Add {
                deposit_rate_per_s: 4.0,
            },
        );
        apply_tool(
            &mut clay,
            &lump,
            &everywhere,
            1.0,
            &ApplyOptions::default(),
            None,
        )
        .unwrap();
        assert!((1..100).contains(&clay.dense_brick_count()));
    }

    /// The field change of `action` held for `dwell_s` at the centre of a clay whose density
    /// ramps gently through the iso-level (0.3 to 0.7, so no density meets the range's ends and
    /// only the tool's own effect shows), applied `times` times (coefficient deltas).
    fn held(action: ToolAction, dwell_s: f32, times: u32) -> Vec<f32> {
        let mut lattice = BSplineLattice::zeros([N; 3], H, Vec3::ZERO).unwrap();
        lattice.iso = 0.5;
        for k in 0..N {
            for j in 0..N {
                for i in 0..N {
                    let idx = lattice.index(i, j, k);
                    lattice
                        .coeffs
                        .set_flat(idx, 0.7 - 0.4 * k as f32 / (N - 1) as f32);
                }
            }
        }
        let mut clay = Clay::single(lattice);
        let before = clay.density.patches[0].lattice.coeffs.clone();
        let t = GeometricTool {
            shape: ToolShape::Sphere { radius_fu: 0.3 },
            action,
            falloff_fu: 4.0 * H,
        };
        for _ in 0..times {
            apply_tool(
                &mut clay,
                &t,
                &ToolPose::at(centre()),
                dwell_s,
                &ApplyOptions::default(),
                None,
            )
            .unwrap();
        }
        clay.density.patches[0]
            .lattice
            .coeffs
            .iter()
            .zip(&before)
            .map(|(a, b)| a - b)
            .collect()
    }

    #[test]
    fn stamp_and_contact_scale_with_dwell_time() {
        let stamp = |rate_per_s| {
            ToolAction::Stamp(StampParams {
                rate_per_s,
                ..StampParams::default()
            })
        };
        let contact = |rate_per_s| {
            ToolAction::Contact(ContactParams {
                alpha: -0.5,
                rate_per_s,
            })
        };
        // A tenth of a whole application: no density leaves the range.
        for (name, make) in [
            ("stamp", &stamp as &dyn Fn(f32) -> ToolAction),
            ("contact", &contact),
        ] {
            let long = held(make(10.0), 0.01, 1);
            let twice = held(make(5.0), 0.01, 2);
            let peak = long.iter().fold(0.0_f32, |m, d| m.max(d.abs()));
            assert!(peak > 1e-3, "{name}: the tool did something");
            let worst = long
                .iter()
                .zip(&twice)
                .fold(0.0_f32, |m, (a, b)| m.max((a - b).abs()));
            // Within 3% of the peak: a rise is weighted by the clay's presence and a fall
            // outside the tool by its exposure, which the first half already changed (a
            // second-order difference).
            assert!(
                worst <= 0.03 * peak,
                "{name}: twice as long differs from two halves by {worst} (peak {peak})"
            );
            // And the change grows with the dwell.
            let short = held(make(10.0), 0.005, 1);
            let short_peak = short.iter().fold(0.0_f32, |m, d| m.max(d.abs()));
            assert!(
                (short_peak / peak - 0.5).abs() < 0.01,
                "{name}: {short_peak} vs {peak}"
            );
        }
    }
}
