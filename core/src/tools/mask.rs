//! The freeze mask: how firmly each coefficient of each density patch is held, `0` (free) to
//! `1` (frozen), painted with a soft brush, inverted and cleared like a sculpting app's mask.
//!
//! The mask lives on the coefficients that tools and dynamics move, so holding it is exact: a
//! tool's refit or a dynamics step computes the free result, and each coefficient keeps
//! `1 − m` of its change (`c = old + (1 − m)(new − old)`), so a fully held coefficient keeps
//! its bits and a half-held one moves half as far. The mask of patch `n` is a lattice over the
//! same nodes as patch `n` (one painted value per coefficient); as a B-spline its value at a
//! point is a smooth blend of the nearby coefficients' painted holds (shown as a tint). The
//! hold `m` applied to a coefficient is the painted mask dilated by the basis support
//! ([`FreezeMask::support_holds`]), so the clay under the tint holds as firmly as it is tinted,
//! soft brush edge included. The mask is addressed as [`FieldId::Mask`] so every edit of it is
//! an undo step like any other.
//!
//! Runs on the simulation or command thread; painting, inverting and clearing allocate only when
//! the mask is first made.

use glam::Vec3;

use super::clay::{Clay, CoeffBox, FieldId};
use super::freeze_mask::{FreezeMask, MaskError};
use super::history::StepRecorder;
use crate::field::{BSplineLattice, check_dense_room};

/// Whether a mask stroke freezes clay or frees it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum MaskMode {
    /// Raise the hold towards 1 (freeze).
    #[default]
    Freeze,
    /// Lower the hold towards 0 (unfreeze: an eraser for the mask).
    Free,
}

/// A soft round mask brush: full `strength` within half its radius, falling smoothly to zero
/// at `radius_fu` (a smoothstep of the distance, so the mask's edge is soft).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MaskBrush {
    /// Radius of the brush, field units.
    pub radius_fu: f32,
    /// How much of the remaining way to the goal one dab moves a coefficient at the centre,
    /// `0..=1` (1: a single dab freezes fully there).
    pub strength: f32,
    /// Freeze or free.
    pub mode: MaskMode,
}

impl MaskBrush {
    /// Checks radius and strength.
    ///
    /// # Errors
    /// The first value out of range.
    pub fn validate(&self) -> Result<(), MaskError> {
        if !(self.radius_fu.is_finite() && self.radius_fu > 0.0) {
            return Err(MaskError::Radius {
                radius_fu: self.radius_fu,
            });
        }
        if !(0.0..=1.0).contains(&self.strength) {
            return Err(MaskError::Strength {
                strength: self.strength,
            });
        }
        Ok(())
    }

    /// The weight of one dab at `distance_fu` from its centre: `strength` over the inner half
    /// of the radius, then a smoothstep down to 0 at the radius (the soft edge).
    #[must_use]
    pub fn weight(&self, distance_fu: f32) -> f32 {
        let x = ((self.radius_fu - distance_fu) / (0.5 * self.radius_fu)).clamp(0.0, 1.0);
        self.strength * x * x * (3.0 - 2.0 * x)
    }
}

/// How a mask edit went: the coefficients whose hold changed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct MaskReport {
    /// Coefficients whose hold changed.
    pub changed: usize,
}

/// Makes sure the clay has a mask fitting its patch layout: made (all free) when absent; a
/// patch the mask does not fit (added by a refinement or a growth since) gets holds sampled
/// from the base patch's mask at its nodes.
///
/// # Errors
/// [`MaskError::Lattice`] when a patch's lattice is refused (never for a valid clay).
pub fn ensure_mask(clay: &mut Clay) -> Result<(), MaskError> {
    let Some(mask) = clay.mask.as_mut() else {
        clay.mask = Some(FreezeMask::matching(&clay.density)?);
        return Ok(());
    };
    let patches = &clay.density.patches;
    mask.patches.truncate(patches.len());
    let base_mask = mask
        .patches
        .first()
        .filter(|m| m.dims == patches[0].lattice.dims)
        .cloned();
    for (n, p) in patches.iter().enumerate() {
        if mask.for_patch(n, &p.lattice).is_some() {
            continue;
        }
        let l = &p.lattice;
        let mut fresh = BSplineLattice::zeros(l.dims, l.spacing, l.origin)
            .map_err(|source| MaskError::Lattice { patch: n, source })?;
        if let Some(base) = base_mask.as_ref().filter(|_| n > 0) {
            let to_world = p.world_to_patch.inverse();
            for k in 0..l.dims[2] {
                for j in 0..l.dims[1] {
                    for i in 0..l.dims[0] {
                        let x = to_world.transform_point3(l.node_position(i, j, k));
                        fresh
                            .coeffs
                            .set_flat(l.index(i, j, k), snapped_hold(base.value(x)));
                    }
                }
            }
        }
        if n < mask.patches.len() {
            mask.patches[n] = fresh;
        } else {
            mask.patches.push(fresh);
        }
    }
    Ok(())
}

/// A hold sampled from a mask's B-spline, within `[0, 1]`, with the rounding of a sum of
/// weights (`0.99999994` where every coefficient around is held) snapped to 0 or 1, so held
/// clay stays exactly held on a new patch.
fn snapped_hold(h: f32) -> f32 {
    const ROUNDING: f32 = 1e-5;
    if h >= 1.0 - ROUNDING {
        1.0
    } else if h <= ROUNDING {
        0.0
    } else {
        h
    }
}

/// One dab of `brush` at `centre_fu` (world): on every patch, each coefficient whose node lies
/// within the brush moves its hold towards 1 (freeze) or 0 (free) by the brush's weight there.
/// Recorded in `recorder` first when given.
///
/// # Errors
/// [`MaskError`] for a bad brush or centre; the clay is unchanged then.
pub fn paint_mask(
    clay: &mut Clay,
    brush: &MaskBrush,
    centre_fu: Vec3,
    mut recorder: Option<&mut StepRecorder>,
) -> Result<MaskReport, MaskError> {
    brush.validate()?;
    if !centre_fu.is_finite() {
        return Err(MaskError::Centre {
            centre_fu: centre_fu.to_array(),
        });
    }
    ensure_mask(clay)?;
    let mut report = MaskReport::default();
    let (lo, hi) = (
        centre_fu - Vec3::splat(brush.radius_fu),
        centre_fu + Vec3::splat(brush.radius_fu),
    );
    // Before anything is written: the mask's bricks under the brush, on every patch, must
    // fit the clay's budget.
    let mut more = 0;
    let mut reached = None;
    for (n, patch) in clay.density.patches.iter().enumerate() {
        let (plo, phi) = patch.patch_box_of(lo, hi);
        let mask = clay.mask.as_ref().and_then(|m| m.patches.get(n));
        if let (Some(region), Some(mask)) = (node_box(&patch.lattice, plo, phi), mask) {
            more += mask.coeffs.uniform_bricks_holding(region.min, region.max);
            reached = Some(region);
        }
    }
    check_dense_room(clay.dense_brick_count(), more, reached)?;
    for n in 0..clay.density.patches.len() {
        let patch = &clay.density.patches[n];
        let (plo, phi) = patch.patch_box_of(lo, hi);
        let l = &patch.lattice;
        let Some(region) = node_box(l, plo, phi) else {
            continue;
        };
        let id = FieldId::Mask(u16::try_from(n).unwrap_or(u16::MAX));
        if let Some(r) = recorder.as_deref_mut() {
            r.touch(clay, id, region);
        }
        let patch = &clay.density.patches[n];
        let to_world = patch.world_to_patch.inverse();
        let identity = patch.is_identity();
        let l = &patch.lattice;
        let Some(mask) = clay.mask.as_mut().and_then(|m| m.patches.get_mut(n)) else {
            continue;
        };
        for k in region.min[2]..=region.max[2] {
            for j in region.min[1]..=region.max[1] {
                for i in region.min[0]..=region.max[0] {
                    let node = l.node_position(i, j, k);
                    let x = if identity {
                        node
                    } else {
                        to_world.transform_point3(node)
                    };
                    let w = brush.weight(x.distance(centre_fu));
                    if w <= 0.0 {
                        continue;
                    }
                    let h = mask.coeffs.get(i, j, k);
                    // A full-weight dab sets the goal exactly (no rounding short of it).
                    let new = match brush.mode {
                        MaskMode::Freeze if w >= 1.0 => 1.0,
                        MaskMode::Free if w >= 1.0 => 0.0,
                        MaskMode::Freeze => h + w * (1.0 - h),
                        MaskMode::Free => h * (1.0 - w),
                    }
                    .clamp(0.0, 1.0);
                    report.changed += usize::from(new != h);
                    mask.coeffs.set(i, j, k, new);
                }
            }
        }
    }
    Ok(report)
}

/// Inverts the mask (`m → 1 − m` on every coefficient): held clay becomes free and free clay
/// held. A clay without a mask becomes fully held. Recorded in `recorder` first when given.
///
/// # Errors
/// [`MaskError::Lattice`] when a mask cannot be made (never for a valid clay).
pub fn invert_mask(
    clay: &mut Clay,
    recorder: Option<&mut StepRecorder>,
) -> Result<MaskReport, MaskError> {
    ensure_mask(clay)?;
    set_every_hold(clay, recorder, |h| 1.0 - h)
}

/// Clears the mask: every coefficient free. Recorded in `recorder` first when given.
///
/// # Errors
/// [`MaskError::Lattice`] when a mask cannot be made (never for a valid clay).
pub fn clear_mask(
    clay: &mut Clay,
    recorder: Option<&mut StepRecorder>,
) -> Result<MaskReport, MaskError> {
    if clay.mask.is_none() {
        return Ok(MaskReport::default());
    }
    ensure_mask(clay)?;
    set_every_hold(clay, recorder, |_| 0.0)
}

/// Applies `f` to every hold of every patch, recording each patch's whole lattice first.
fn set_every_hold(
    clay: &mut Clay,
    mut recorder: Option<&mut StepRecorder>,
    f: impl Fn(f32) -> f32,
) -> Result<MaskReport, MaskError> {
    let mut report = MaskReport::default();
    for n in 0..clay.density.patches.len() {
        let dims = clay.density.patches[n].lattice.dims;
        let id = FieldId::Mask(u16::try_from(n).unwrap_or(u16::MAX));
        if let Some(r) = recorder.as_deref_mut() {
            r.touch(clay, id, CoeffBox::whole(dims));
        }
        if let Some(mask) = clay.mask.as_mut().and_then(|m| m.patches.get_mut(n)) {
            // Brick by brick: a uniform brick stays one value (no brick is made dense).
            report.changed += mask.coeffs.map_values(|h| f(h).clamp(0.0, 1.0));
            mask.coeffs.compact();
        }
    }
    Ok(report)
}

/// The coefficients whose nodes lie in the patch-space box `lo..=hi`, clipped to the lattice.
fn node_box(l: &BSplineLattice, lo: Vec3, hi: Vec3) -> Option<CoeffBox> {
    let a = ((lo - l.origin) / l.spacing).ceil();
    let b = ((hi - l.origin) / l.spacing).floor();
    let mut min = [0_usize; 3];
    let mut max = [0_usize; 3];
    for axis in 0..3 {
        let top = l.dims[axis] as f32 - 1.0;
        if !(a[axis].is_finite() && b[axis].is_finite()) || b[axis] < 0.0 || a[axis] > top {
            return None;
        }
        min[axis] = a[axis].max(0.0) as usize;
        max[axis] = b[axis].min(top) as usize;
        if min[axis] > max[axis] {
            return None;
        }
    }
    Some(CoeffBox { min, max })
}

/// The coefficients of one patch's region as they were before an edit, to give back the held
/// share of each after it ([`HeldRegion::restore`]).
#[derive(Clone, Debug)]
pub struct HeldRegion {
    region: CoeffBox,
    /// The holds over the region, x fastest.
    holds: Vec<f32>,
    /// The coefficients over the region before the edit, x fastest.
    before: Vec<f32>,
}

impl HeldRegion {
    /// Remembers `region` of patch `patch` before an edit when the clay's mask holds any of it
    /// (the holds of [`FreezeMask::support_holds`]); `None` when nothing there is held (the
    /// edit then needs no restoring).
    #[must_use]
    pub fn capture(clay: &Clay, patch: usize, region: CoeffBox) -> Option<Self> {
        let lattice = &clay.density.patches.get(patch)?.lattice;
        let region = region.clipped(lattice.dims)?;
        let mut holds = Vec::new();
        clay.mask
            .as_ref()?
            .support_holds(patch, lattice, region, &mut holds);
        if holds.is_empty() {
            return None;
        }
        let mut before = Vec::with_capacity(region.count());
        for_each_row(lattice, &region, |row| {
            lattice
                .coeffs
                .extend_row_into(row.start, row.len(), &mut before);
        });
        Some(Self {
            region,
            holds,
            before,
        })
    }

    /// Gives each coefficient of the region back its held share of the change:
    /// `old + (1 − m)(new − old)`; a fully held coefficient gets its old bits back.
    pub fn restore(&self, lattice: &mut BSplineLattice) {
        let mut at = 0;
        let (holds, before) = (&self.holds, &self.before);
        for_each_row_mut(lattice, &self.region, |row| {
            for c in row {
                let (m, old) = (holds[at], before[at]);
                *c = if m >= 1.0 {
                    old
                } else if m > 0.0 {
                    old + (1.0 - m) * (*c - old)
                } else {
                    *c
                };
                at += 1;
            }
        });
    }
}

/// Calls `f` with the index range of each x-row of `region` in `lattice`.
fn for_each_row(
    lattice: &BSplineLattice,
    region: &CoeffBox,
    mut f: impl FnMut(std::ops::Range<usize>),
) {
    for k in region.min[2]..=region.max[2] {
        for j in region.min[1]..=region.max[1] {
            let start = lattice.index(region.min[0], j, k);
            f(start..start + region.max[0] - region.min[0] + 1);
        }
    }
}

/// Calls `f` with each x-row of `region` in `lattice`, mutably.
fn for_each_row_mut(
    lattice: &mut BSplineLattice,
    region: &CoeffBox,
    mut f: impl FnMut(&mut [f32]),
) {
    let dims = lattice.dims;
    for k in region.min[2]..=region.max[2] {
        for j in region.min[1]..=region.max[1] {
            let start = region.min[0] + dims[0] * (j + dims[1] * k);
            let len = region.max[0] - region.min[0] + 1;
            lattice.coeffs.with_row_mut(start, len, &mut f);
        }
    }
}

/// The holds of the region `region` of patch `patch` in the region's own order (x fastest),
/// as [`FreezeMask::support_holds`] gives them, written into `out` (cleared first; left empty
/// when nothing there is held). For a dynamics region ([`crate::dynamics::RegionState::held`]).
pub fn region_holds(clay: &Clay, patch: usize, region: CoeffBox, out: &mut Vec<f32>) {
    out.clear();
    let Some(lattice) = clay.density.patches.get(patch).map(|p| &p.lattice) else {
        return;
    };
    if let Some(mask) = clay.mask.as_ref() {
        mask.support_holds(patch, lattice, region, out);
    }
}

/// Before an edit of `region` on patch `patch`: fits the mask to the patch layout (when the
/// clay has one) and remembers what the mask holds there, for [`HeldRegion::restore`] after
/// the edit.
///
/// # Errors
/// As [`ensure_mask`].
pub fn hold_before_edit(
    clay: &mut Clay,
    patch: usize,
    region: CoeffBox,
) -> Result<Option<HeldRegion>, MaskError> {
    if clay.mask.is_none() {
        return Ok(None);
    }
    ensure_mask(clay)?;
    Ok(HeldRegion::capture(clay, patch, region))
}

/// One edit of the mask, as a command or a script step carries it.
#[derive(Clone, Debug, PartialEq)]
pub enum MaskEdit {
    /// Dabs of `brush` at each centre in turn (field units): one stroke.
    Paint {
        /// The brush.
        brush: MaskBrush,
        /// Where each dab lands, world field units.
        centres_fu: Vec<Vec3>,
    },
    /// Every hold `m` becomes `1 − m`.
    Invert,
    /// Every hold becomes 0.
    Clear,
}

impl MaskEdit {
    /// Short name for menus and undo labels.
    #[must_use]
    pub fn name(&self) -> &'static str {
        match self {
            Self::Paint {
                brush:
                    MaskBrush {
                        mode: MaskMode::Freeze,
                        ..
                    },
                ..
            } => "mask",
            Self::Paint { .. } => "unmask",
            Self::Invert => "invert mask",
            Self::Clear => "clear mask",
        }
    }

    /// Applies the edit to `clay`, recorded in `recorder` when given.
    ///
    /// # Errors
    /// [`MaskError`] for a bad brush or centre (checked before any dab lands).
    pub fn apply(
        &self,
        clay: &mut Clay,
        mut recorder: Option<&mut StepRecorder>,
    ) -> Result<MaskReport, MaskError> {
        match self {
            Self::Paint { brush, centres_fu } => {
                brush.validate()?;
                if let Some(c) = centres_fu.iter().find(|c| !c.is_finite()) {
                    return Err(MaskError::Centre {
                        centre_fu: c.to_array(),
                    });
                }
                let mut report = MaskReport::default();
                for &c in centres_fu {
                    report.changed += paint_mask(clay, brush, c, recorder.as_deref_mut())?.changed;
                }
                Ok(report)
            }
            Self::Invert => invert_mask(clay, recorder),
            Self::Clear => clear_mask(clay, recorder),
        }
    }
}
