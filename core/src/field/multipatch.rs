//! The multi-patch field of Hua & Qin eq. (3): `F(x) = Σ s_i(T_i x)`, a base patch plus finer
//! detail patches over sub-boxes (level of detail), each with its own affine map `T_i` from
//! world space into the patch's space. Value and gradient are summed; the gradient goes through
//! the chain rule, `∇F = Σ J_iᵀ ∇s_i(T_i x)` with `J_i` the linear part of `T_i`.
//!
//! A detail patch's coefficients beyond its lattice count as zero, so it fades out at its own
//! border: fitting it to the residual of the coarser patches (which is what
//! [`MultiPatchField::fit_detail`] does) keeps the sum continuous.

use glam::{Affine3A, Vec3, Vec3A};

use super::budget::MAX_CLAY_BOX_COEFFS;
use super::lattice::BSplineLattice;
use super::refit::{FitError, fit_lattice};

/// Most density patches a clay holds (a base and its details).
pub const MAX_PATCHES: usize = 256;
/// Finest detail level over the base: spacing down to 1/64 of the base's (a brush of 1/256 of
/// a 24-coefficient clay's box still covers three knot spans of it).
pub const MAX_DETAIL_LEVEL: u32 = 6;
/// Most coefficients one detail patch may hold (64 MiB of `f32`).
pub const MAX_DETAIL_COEFFS: usize = 16 << 20;
/// Most coefficients an import may fit, all its patches together (256 MiB of `f32`: the
/// largest import's base, 256³, and three more of its size in detail): a fit holds its
/// lattices dense while it makes them, so an import is bounded by its box.
///
/// A sculpted clay is bounded otherwise: by its dense bricks
/// ([`super::MAX_DENSE_BRICKS`], checked before every write that can make bricks dense) and
/// by the box its brick directories span ([`super::MAX_CLAY_BOX_COEFFS`], checked by a
/// refine, a growth and a session load before anything is allocated).
pub const MAX_CLAY_COEFFS: usize = 64 << 20;

/// Why a detail patch could not be added.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum DetailError {
    /// The clay has no base patch to refine.
    #[error("the clay has no base patch to refine")]
    NoBase,
    /// The level is outside `1..=MAX_DETAIL_LEVEL`.
    #[error(
        "detail level {level} is outside 1..={MAX_DETAIL_LEVEL} (each level halves the knot spacing)"
    )]
    Level {
        /// The level asked for.
        level: u32,
    },
    /// The box is not finite, is empty, or misses the base patch's support.
    #[error("the box {lo:?}..{hi:?} is empty, not finite or outside the clay")]
    Box {
        /// The box's low corner.
        lo: [f32; 3],
        /// The box's high corner.
        hi: [f32; 3],
    },
    /// The clay already holds [`MAX_PATCHES`] patches.
    #[error("the clay already holds {MAX_PATCHES} patches")]
    TooManyPatches,
    /// The patch would hold more than [`MAX_DETAIL_COEFFS`] coefficients.
    #[error(
        "the detail patch would hold {coefficients} coefficients, more than {MAX_DETAIL_COEFFS}; refine a smaller box or a lower level"
    )]
    TooLarge {
        /// Coefficients the patch would hold.
        coefficients: usize,
    },
    /// The clay's lattices would span more than [`MAX_CLAY_BOX_COEFFS`] coefficients of box
    /// with the patch.
    #[error(
        "the clay would span {total} coefficients of box with this patch, more than {MAX_CLAY_BOX_COEFFS}; refine a smaller box or a lower level"
    )]
    ClayTooLarge {
        /// Coefficients of the clay with the patch.
        total: usize,
    },
}

/// The coefficients of a detail patch over `lo ..= hi` at `level` on `base`, with the box
/// clipped to the base's support; checks the level, the box and the patch's size.
fn detail_size(
    base: &Patch,
    lo: Vec3,
    hi: Vec3,
    level: u32,
) -> Result<(usize, Vec3, Vec3), DetailError> {
    if !(1..=MAX_DETAIL_LEVEL).contains(&level) {
        return Err(DetailError::Level { level });
    }
    let (slo, shi) = base.world_support();
    let (clo, chi) = (lo.max(slo), hi.min(shi));
    if !(lo.is_finite() && hi.is_finite()) || clo.cmpge(chi).any() {
        return Err(DetailError::Box {
            lo: lo.to_array(),
            hi: hi.to_array(),
        });
    }
    let spacing = base.lattice.spacing / (1_u32 << level) as f32;
    let coefficients = ((chi - clo) / spacing)
        .to_array()
        .iter()
        .map(|e| e.ceil() as usize + 3)
        .try_fold(1_usize, |acc, n| acc.checked_mul(n.max(4)))
        .unwrap_or(usize::MAX);
    if coefficients > MAX_DETAIL_COEFFS {
        return Err(DetailError::TooLarge { coefficients });
    }
    Ok((coefficients, clo, chi))
}

/// One patch: a lattice and the map from world space into the lattice's space.
#[derive(Clone, Debug, PartialEq)]
pub struct Patch {
    /// The patch's B-spline (its `origin` and `spacing` are in patch space).
    pub lattice: BSplineLattice,
    /// `T_i`: world → patch space.
    pub world_to_patch: Affine3A,
}

impl Patch {
    /// A patch in world coordinates (`T_i` the identity: the lattice's origin and spacing
    /// place it).
    #[must_use]
    pub fn identity(lattice: BSplineLattice) -> Self {
        Self {
            lattice,
            world_to_patch: Affine3A::IDENTITY,
        }
    }

    /// Whether `T_i` is the identity, so the lattice's own world-space fast paths apply.
    #[inline]
    #[must_use]
    pub fn is_identity(&self) -> bool {
        self.world_to_patch == Affine3A::IDENTITY
    }

    /// The world box holding this patch's support (the axis-aligned box around the support's
    /// eight corners mapped back to world space).
    #[must_use]
    pub fn world_support(&self) -> (Vec3, Vec3) {
        let (lo, hi) = self.lattice.support();
        self.world_box_of(lo, hi)
    }

    /// The world box around the patch-space box `lo..=hi`.
    #[must_use]
    pub fn world_box_of(&self, lo: Vec3, hi: Vec3) -> (Vec3, Vec3) {
        if self.is_identity() {
            return (lo, hi);
        }
        let to_world = self.world_to_patch.inverse();
        corners(lo, hi)
            .map(|c| to_world.transform_point3(c))
            .into_iter()
            .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(a, b), c| {
                (a.min(c), b.max(c))
            })
    }

    /// The patch-space box around the world box `lo..=hi`.
    #[must_use]
    pub fn patch_box_of(&self, lo: Vec3, hi: Vec3) -> (Vec3, Vec3) {
        if self.is_identity() {
            return (lo, hi);
        }
        corners(lo, hi)
            .map(|c| self.world_to_patch.transform_point3(c))
            .into_iter()
            .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(a, b), c| {
                (a.min(c), b.max(c))
            })
    }

    /// The world box outside which this patch's term does not change when its coefficients
    /// with indices `first ..= last` (per axis) change: their nodes widened by two knot
    /// spans, the reach of a cubic B-spline, mapped to world space: the region a mesher
    /// meshes again after a stroke.
    #[must_use]
    pub fn coefficient_change_box(&self, first: [usize; 3], last: [usize; 3]) -> (Vec3, Vec3) {
        let l = &self.lattice;
        let reach = Vec3::splat(2.0 * l.spacing);
        let lo = l.node_position(first[0], first[1], first[2]) - reach;
        let hi = l.node_position(last[0], last[1], last[2]) + reach;
        self.world_box_of(lo.min(hi), hi.max(lo))
    }

    /// The knot spacing in world units: the lattice spacing divided by the largest stretch of
    /// `T_i` (so the finest length this patch resolves).
    #[must_use]
    pub fn world_spacing(&self) -> f32 {
        let m = self.world_to_patch.matrix3;
        let stretch = m
            .x_axis
            .length()
            .max(m.y_axis.length())
            .max(m.z_axis.length());
        self.lattice.spacing / stretch
    }

    /// This patch's term at a world point.
    #[inline]
    #[must_use]
    pub fn value(&self, x: Vec3) -> f32 {
        if self.is_identity() {
            return self.lattice.value(x);
        }
        self.lattice.value(self.world_to_patch.transform_point3(x))
    }

    /// Value and world-space gradient of this patch's term at a world point.
    #[inline]
    #[must_use]
    pub fn value_and_gradient(&self, x: Vec3) -> (f32, Vec3) {
        if self.is_identity() {
            return self.lattice.value_and_gradient(x);
        }
        let u = self.world_to_patch.transform_point3(x);
        let (v, g) = self.lattice.value_and_gradient(u);
        let jt = self.world_to_patch.matrix3.transpose();
        (v, Vec3::from(jt * Vec3A::from(g)))
    }
}

/// How many items two versions of a list share at each end: the length of the longest
/// common prefix, and of the longest common suffix of what remains after it (so the two never
/// overlap), by `same`. A new patch layout keeps the patches before and after those that
/// came, went or changed.
pub fn shared_ends<T>(old: &[T], new: &[T], same: impl Fn(&T, &T) -> bool) -> (usize, usize) {
    let prefix = old.iter().zip(new).take_while(|(a, b)| same(a, b)).count();
    let room = old.len().min(new.len()) - prefix;
    let suffix = old
        .iter()
        .rev()
        .zip(new.iter().rev())
        .take(room)
        .take_while(|(a, b)| same(a, b))
        .count();
    (prefix, suffix)
}

/// `F(x) = Σ s_i(T_i x)` over a base patch and detail patches: the clay's density, the one
/// model of eq. (3) that evaluation, forces, meshing, tools and sessions act on.
///
/// The solid is where `F` exceeds the base patch's iso-level ([`MultiPatchField::iso`]); the
/// detail patches' own `iso` fields are not used.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MultiPatchField {
    /// Patch 0 is the base; later ones are details.
    pub patches: Vec<Patch>,
}

impl MultiPatchField {
    /// A field of one base patch in world coordinates.
    #[must_use]
    pub fn new(base: BSplineLattice) -> Self {
        Self {
            patches: vec![Patch::identity(base)],
        }
    }

    /// Makes every brick of every patch dense, so that later writes of coefficients never
    /// allocate (a copy written on the haptic thread).
    pub fn densify_all(&mut self) {
        for p in &mut self.patches {
            p.lattice.coeffs.densify_all();
        }
    }

    /// Makes every dense brick of every patch whose values are all equal one value again
    /// (see [`super::BrickedCoeffs::compact`]); returns how many bricks it freed.
    pub fn compact(&mut self) -> usize {
        self.patches
            .iter_mut()
            .map(|p| p.lattice.coeffs.compact())
            .sum()
    }

    /// The iso-level of the surface: the base patch's (0 for a field without patches).
    #[inline]
    #[must_use]
    pub fn iso(&self) -> f32 {
        self.patches.first().map_or(0.0, |p| p.lattice.iso)
    }

    /// The base patch's lattice.
    ///
    /// # Panics
    /// When the field has no patch (a loaded session always has one; see
    /// [`crate::io`]'s decoder).
    #[must_use]
    pub fn base(&self) -> &BSplineLattice {
        &self.patches[0].lattice
    }

    /// The base patch's lattice, mutably.
    ///
    /// # Panics
    /// As [`MultiPatchField::base`].
    pub fn base_mut(&mut self) -> &mut BSplineLattice {
        &mut self.patches[0].lattice
    }

    /// The world box that holds every patch's support (an empty box at the origin for a
    /// field without patches).
    #[must_use]
    pub fn support(&self) -> (Vec3, Vec3) {
        self.patches
            .iter()
            .map(Patch::world_support)
            .reduce(|(alo, ahi), (blo, bhi)| (alo.min(blo), ahi.max(bhi)))
            .unwrap_or((Vec3::ZERO, Vec3::ZERO))
    }

    /// The finest knot spacing of any patch, in world units (the spacing measured along the
    /// patch's axes after its map): the length scale of the finest detail the field holds.
    /// Infinite for a field without patches.
    #[must_use]
    pub fn finest_spacing(&self) -> f32 {
        self.patches
            .iter()
            .map(Patch::world_spacing)
            .fold(f32::INFINITY, f32::min)
    }

    /// Add a patch with its own map; returns its index.
    /// Coefficients of every patch together.
    #[must_use]
    pub fn coefficient_count(&self) -> usize {
        self.patches.iter().map(|p| p.lattice.coeffs.len()).sum()
    }

    /// Dense bricks of every patch together (a count each store keeps: no walk).
    #[must_use]
    pub fn dense_brick_count(&self) -> usize {
        self.patches
            .iter()
            .map(|p| p.lattice.coeffs.dense_brick_count())
            .sum()
    }

    /// Coefficients a [`MultiPatchField::refine`] of `lo ..= hi` at `level` would add, checked
    /// as the refine checks them (the box, the level and one patch's size), without adding it.
    ///
    /// # Errors
    /// As [`MultiPatchField::refine`], but for the patch count and the clay's total.
    pub fn detail_coefficients(
        &self,
        lo: Vec3,
        hi: Vec3,
        level: u32,
    ) -> Result<usize, DetailError> {
        let base = self.patches.first().ok_or(DetailError::NoBase)?;
        detail_size(base, lo, hi, level).map(|(n, _, _)| n)
    }

    pub fn push(&mut self, lattice: BSplineLattice, world_to_patch: Affine3A) -> usize {
        self.patches.push(Patch {
            lattice,
            world_to_patch,
        });
        self.patches.len() - 1
    }

    /// Add a zero detail patch over the world box `lo ..= hi` with knot spacing
    /// `base spacing / 2^level`, padded by one span so its coefficients cover the box; returns
    /// its index.
    ///
    /// # Errors
    /// When the box is degenerate or not finite.
    pub fn add_detail(&mut self, lo: Vec3, hi: Vec3, level: u32) -> Result<usize, FitError> {
        let spacing = self.patches[0].lattice.spacing / (1_u32 << level.min(16)) as f32;
        let extent = (hi - lo) / spacing;
        if !(extent.is_finite() && extent.min_element() > 0.0) {
            return Err(FitError::NonFiniteTarget { at: lo.to_array() });
        }
        let dims = [0, 1, 2].map(|a| (extent[a].ceil() as usize + 3).max(4));
        let origin = lo - Vec3::splat(spacing);
        let lattice = BSplineLattice::zeros(dims, spacing, origin)
            .map_err(|_| FitError::NonFiniteTarget { at: lo.to_array() })?;
        Ok(self.push(lattice, Affine3A::IDENTITY))
    }

    /// Adds a zero detail patch over the world box `lo ..= hi` clipped to the base patch's
    /// support, at knot spacing `base spacing / 2^level`, in world coordinates; returns its
    /// index. The sum is unchanged (the patch holds zeros) until something edits the patch.
    ///
    /// # Errors
    /// [`DetailError`] when the level, the box or the size is out of bounds; the field is
    /// unchanged then.
    pub fn refine(&mut self, lo: Vec3, hi: Vec3, level: u32) -> Result<usize, DetailError> {
        let Some(base) = self.patches.first() else {
            return Err(DetailError::NoBase);
        };
        if self.patches.len() >= MAX_PATCHES {
            return Err(DetailError::TooManyPatches);
        }
        let (coefficients, clo, chi) = detail_size(base, lo, hi, level)?;
        let total = self.coefficient_count().saturating_add(coefficients);
        if total > MAX_CLAY_BOX_COEFFS {
            return Err(DetailError::ClayTooLarge { total });
        }
        let iso = base.lattice.iso;
        let n = self
            .add_detail(clo, chi, level)
            .map_err(|_| DetailError::Box {
                lo: lo.to_array(),
                hi: hi.to_array(),
            })?;
        self.patches[n].lattice.iso = iso;
        Ok(n)
    }

    /// Least-squares fit of patch `index` to `target − Σ_{other patches}`, so the whole field
    /// approximates `target` over that patch.
    ///
    /// # Errors
    /// As [`fit_lattice`].
    ///
    /// # Panics
    /// When `index` is out of range.
    pub fn fit_detail(
        &mut self,
        index: usize,
        samples_per_span: usize,
        target: impl Fn(Vec3) -> f32,
    ) -> Result<(), FitError> {
        let mut patch = self.patches[index].clone();
        let to_world = patch.world_to_patch.inverse();
        let others = |x: Vec3| -> f32 {
            self.patches
                .iter()
                .enumerate()
                .filter(|(i, _)| *i != index)
                .map(|(_, p)| p.value_and_gradient(x).0)
                .sum()
        };
        fit_lattice(&mut patch.lattice, samples_per_span, |u| {
            let x = to_world.transform_point3(u);
            target(x) - others(x)
        })?;
        self.patches[index] = patch;
        Ok(())
    }

    /// The world box outside which the patches this field shares with `before` hold the same
    /// coefficients (`None` where they all do). Shared patches are those before the first
    /// patch whose lattice shape or map differs, and those after the last (as a new layout
    /// keeps them: a refine appends a patch, a fold takes one out); their coefficients are
    /// compared bit for bit, and the box is the support of those that differ. The patches
    /// between (that came, went or changed shape) are not in it.
    #[must_use]
    pub fn shared_patches_change_box(&self, before: &Self) -> Option<(Vec3, Vec3)> {
        let same_shape = |a: &Patch, b: &Patch| {
            a.lattice.dims == b.lattice.dims
                && a.lattice.origin == b.lattice.origin
                && a.lattice.spacing == b.lattice.spacing
                && a.world_to_patch == b.world_to_patch
        };
        let (old, new) = (&before.patches, &self.patches);
        let (prefix, suffix) = shared_ends(old, new, same_shape);
        let shared = (0..prefix)
            .map(|i| (i, i))
            .chain((0..suffix).map(|k| (old.len() - suffix + k, new.len() - suffix + k)));
        let mut change: Option<(Vec3, Vec3)> = None;
        for (i, j) in shared {
            let (a, b) = (&old[i].lattice, &new[j].lattice);
            let Some((first, last)) = a.coeffs.differing_box(&b.coeffs) else {
                continue;
            };
            let (lo, hi) = new[j].coefficient_change_box(first, last);
            change = Some(change.map_or((lo, hi), |(l, h)| (l.min(lo), h.max(hi))));
        }
        change
    }

    /// `F(x)`.
    #[inline]
    #[must_use]
    pub fn value(&self, x: Vec3) -> f32 {
        self.patches.iter().map(|p| p.value(x)).sum()
    }

    /// `F` at every point of the grid `xs × ys × zs` (world coordinates along each axis),
    /// written into `out` with x fastest: `out[i + xs.len() * (j + ys.len() * k)]` is, bit for
    /// bit, [`MultiPatchField::value`] at `(xs[i], ys[j], zs[k])`. Each patch in world
    /// coordinates is evaluated by [`BSplineLattice::values_on_grid`] (its weights once per
    /// coordinate of each axis); a patch with a map point by point.
    ///
    /// # Panics
    /// When `out.len() != xs.len() * ys.len() * zs.len()`.
    pub fn values_on_grid(&self, xs: &[f32], ys: &[f32], zs: &[f32], out: &mut [f32]) {
        self.values_on_grid_with(xs, ys, zs, out, &mut Vec::new());
    }

    /// [`MultiPatchField::values_on_grid`] with `term` as its buffer for one patch's terms
    /// (resized as needed), so that a caller sampling grid after grid allocates it once.
    ///
    /// # Panics
    /// When `out.len() != xs.len() * ys.len() * zs.len()`.
    pub fn values_on_grid_with(
        &self,
        xs: &[f32],
        ys: &[f32],
        zs: &[f32],
        out: &mut [f32],
        term: &mut Vec<f32>,
    ) {
        assert_eq!(
            out.len(),
            xs.len() * ys.len() * zs.len(),
            "one output per grid point"
        );
        // The patches' terms are added in order onto the neutral element of `f32`'s `Sum`, as
        // `value` adds them.
        out.fill(std::iter::empty::<f32>().sum());
        term.resize(out.len(), 0.0);
        for patch in &self.patches {
            if patch.is_identity() {
                patch.lattice.values_on_grid(xs, ys, zs, term);
            } else {
                let mut at = 0;
                for &z in zs {
                    for &y in ys {
                        for &x in xs {
                            term[at] = patch.value(Vec3::new(x, y, z));
                            at += 1;
                        }
                    }
                }
            }
            for (v, t) in out.iter_mut().zip(term.iter()) {
                *v += t;
            }
        }
    }

    /// `F(x)` and its world-space gradient.
    #[inline]
    #[must_use]
    pub fn value_and_gradient(&self, x: Vec3) -> (f32, Vec3) {
        sum_value_and_gradient(self.patches.iter(), x)
    }

    /// The patches whose terms can be nonzero somewhere in the world box `lo ..= hi`, in their
    /// order: every other patch is in world coordinates and its support (where its term can be
    /// nonzero) ends more than two of its knot spans from the box, so its term is exactly zero
    /// there, and
    /// [`sum_value_and_gradient`] over these patches is [`MultiPatchField::value_and_gradient`]
    /// anywhere in the box (up to the sign of a zero). A check that evaluates the clay at many
    /// points of a small box sums a few patches instead of all of them.
    #[must_use]
    pub fn patches_reaching(&self, lo: Vec3, hi: Vec3) -> Vec<&Patch> {
        self.patches
            .iter()
            .filter(|p| {
                if !p.is_identity() {
                    return true;
                }
                let (plo, phi) = p.lattice.support();
                let margin = Vec3::splat(2.0 * p.lattice.spacing);
                (plo - margin).cmple(hi).all() && (phi + margin).cmpge(lo).all()
            })
            .collect()
    }

    /// Whether `x` is inside the solid.
    #[inline]
    #[must_use]
    pub fn is_inside(&self, x: Vec3) -> bool {
        self.value(x) > self.iso()
    }
}

/// The sum of `patches`' terms at `x` and of their world-space gradients, added in order (as
/// [`MultiPatchField::value_and_gradient`] adds all of a field's).
#[inline]
#[must_use]
pub fn sum_value_and_gradient<'a>(
    patches: impl IntoIterator<Item = &'a Patch>,
    x: Vec3,
) -> (f32, Vec3) {
    patches.into_iter().fold((0.0, Vec3::ZERO), |(v, g), p| {
        let (pv, pg) = p.value_and_gradient(x);
        (v + pv, g + pg)
    })
}

impl From<BSplineLattice> for MultiPatchField {
    /// A field of one base patch in world coordinates.
    fn from(base: BSplineLattice) -> Self {
        Self::new(base)
    }
}

/// Every term of eq. (3) but one patch's, beside that patch's lattice borrowed mutably (see
/// [`MultiPatchField::split_patch_mut`]): what an edit of one patch adds its change to.
#[derive(Clone, Copy, Debug, Default)]
pub struct OtherPatches<'a> {
    /// The patches before the edited one.
    pub before: &'a [Patch],
    /// The patches after it.
    pub after: &'a [Patch],
}

impl OtherPatches<'_> {
    /// No other patch.
    pub const NONE: OtherPatches<'static> = OtherPatches {
        before: &[],
        after: &[],
    };

    /// Whether there is no other patch.
    #[inline]
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.before.is_empty() && self.after.is_empty()
    }

    /// The other patches' summed density at world point `x`.
    #[inline]
    #[must_use]
    pub fn value(&self, x: Vec3) -> f32 {
        self.before
            .iter()
            .chain(self.after)
            .map(|p| p.value(x))
            .sum()
    }

    /// The other patches' summed density and world-space gradient at `x`.
    #[inline]
    #[must_use]
    pub fn value_and_gradient(&self, x: Vec3) -> (f32, Vec3) {
        self.before
            .iter()
            .chain(self.after)
            .fold((0.0, Vec3::ZERO), |(v, g), p| {
                let (pv, pg) = p.value_and_gradient(x);
                (v + pv, g + pg)
            })
    }
}

impl MultiPatchField {
    /// Patch `n`'s lattice, mutably, beside the other patches (`None` when `n` is not a
    /// patch).
    pub fn split_patch_mut(&mut self, n: usize) -> Option<(&mut BSplineLattice, OtherPatches<'_>)> {
        if n >= self.patches.len() {
            return None;
        }
        let (before, rest) = self.patches.split_at_mut(n);
        let (edited, after) = rest.split_first_mut()?;
        Some((&mut edited.lattice, OtherPatches { before, after }))
    }
}

/// The eight corners of the box `lo..=hi`.
fn corners(lo: Vec3, hi: Vec3) -> [Vec3; 8] {
    std::array::from_fn(|n| {
        Vec3::new(
            if n & 1 == 0 { lo.x } else { hi.x },
            if n & 2 == 0 { lo.y } else { hi.y },
            if n & 4 == 0 { lo.z } else { hi.z },
        )
    })
}

#[cfg(test)]
mod tests {
    use glam::Quat;

    use super::*;

    fn wavy(dims: [usize; 3], spacing: f32) -> BSplineLattice {
        let mut l = BSplineLattice::zeros(dims, spacing, Vec3::ZERO).unwrap();
        l.coeffs.update_each(|n, c| {
            *c = ((n * 7919) % 53) as f32 / 53.0;
        });
        l
    }

    #[test]
    fn shared_ends_count_what_a_new_layout_keeps_at_each_end_without_counting_twice() {
        let eq = |a: &u8, b: &u8| a == b;
        // A patch added in the middle, one taken out, one replaced, one appended.
        assert_eq!(shared_ends(&[1, 2, 3, 4], &[1, 2, 9, 3, 4], eq), (2, 2));
        assert_eq!(shared_ends(&[1, 2, 3, 4], &[1, 3, 4], eq), (1, 2));
        assert_eq!(shared_ends(&[1, 2, 3], &[1, 7, 3], eq), (1, 1));
        assert_eq!(shared_ends(&[1, 2], &[1, 2, 5], eq), (2, 0));
        // Equal items everywhere: the suffix takes only what the prefix left.
        assert_eq!(shared_ends(&[1, 1], &[1, 1, 1], eq), (2, 0));
        assert_eq!(shared_ends::<u8>(&[], &[4], eq), (0, 0));
    }

    #[test]
    fn shared_patches_change_box_holds_the_changed_coefficients_of_kept_patches() {
        let mut before = MultiPatchField::new(wavy([12, 12, 12], 0.25));
        before
            .refine(Vec3::splat(0.5), Vec3::splat(1.5), 1)
            .unwrap();
        assert_eq!(before.shared_patches_change_box(&before), None);
        // A refine appends a patch: the kept ones are unchanged.
        let mut after = before.clone();
        let added = after.refine(Vec3::splat(1.8), Vec3::splat(2.4), 2).unwrap();
        assert_eq!(after.shared_patches_change_box(&before), None);
        // Two base coefficients and one of the new patch's change: the box is the base ones'.
        let base = &mut after.patches[0].lattice;
        let (a, b) = (base.index(3, 4, 5), base.index(6, 4, 7));
        base.coeffs.add_flat(a, 0.5);
        base.coeffs.set_flat(b, -base.coeffs[b]);
        after.patches[added].lattice.coeffs.set_flat(0, 1.0);
        let expected = after.patches[0].coefficient_change_box([3, 4, 5], [6, 4, 7]);
        assert_eq!(after.shared_patches_change_box(&before), Some(expected));
        // A patch taken out of the middle: the patches after it are matched from the end.
        let mut fewer = after.clone();
        fewer.patches.remove(1);
        fewer
            .patches
            .last_mut()
            .unwrap()
            .lattice
            .coeffs
            .set_flat(5, 2.0);
        let last = fewer.patches.last().unwrap();
        let at = [5 % last.lattice.dims[0], 0, 0];
        assert_eq!(
            fewer.shared_patches_change_box(&after),
            Some(last.coefficient_change_box(at, at))
        );
    }

    #[test]
    fn the_patches_reaching_a_box_sum_to_the_field_in_it_and_leave_out_the_far_ones() {
        let mut field = MultiPatchField::new(wavy([16, 16, 16], 0.25));
        let near = field.refine(Vec3::splat(0.9), Vec3::splat(1.6), 2).unwrap();
        let far = field.refine(Vec3::splat(2.8), Vec3::splat(3.4), 1).unwrap();
        let touching = field.refine(Vec3::splat(1.5), Vec3::splat(2.0), 3).unwrap();
        for n in [near, far, touching] {
            let dims = field.patches[n].lattice.dims;
            let values: Vec<f32> = (0..dims[0] * dims[1] * dims[2])
                .map(|i| ((i * 37 % 101) as f32 / 101.0 - 0.5) * 0.2)
                .collect();
            field.patches[n].lattice = BSplineLattice::from_coeffs(
                dims,
                field.patches[n].lattice.spacing,
                field.patches[n].lattice.origin,
                values,
            )
            .unwrap();
        }
        let (lo, hi) = (Vec3::splat(1.0), Vec3::splat(1.4));
        let reaching = field.patches_reaching(lo, hi);
        let kept: Vec<usize> = reaching
            .iter()
            .map(|p| {
                field
                    .patches
                    .iter()
                    .position(|q| std::ptr::eq(q, *p))
                    .unwrap()
            })
            .collect();
        assert_eq!(kept, vec![0, near, touching]);
        for s in 0..=20 {
            for t in 0..=20 {
                let f = Vec3::new(s as f32, t as f32, ((s * 7 + t * 3) % 21) as f32) / 20.0;
                let x = lo + (hi - lo) * f;
                let (v, g) = sum_value_and_gradient(reaching.iter().copied(), x);
                assert_eq!((v, g), field.value_and_gradient(x), "at {x}");
            }
        }
    }

    #[test]
    fn value_is_the_sum_and_gradient_follows_the_chain_rule() {
        let mut field = MultiPatchField::new(wavy([8, 8, 8], 0.25));
        let t = Affine3A::from_scale_rotation_translation(
            Vec3::new(2.0, 1.5, 3.0),
            Quat::from_rotation_y(0.4) * Quat::from_rotation_x(-0.3),
            Vec3::new(0.2, -0.1, 0.3),
        );
        field.push(wavy([6, 7, 5], 0.5), t);
        let h = 1e-3_f32;
        for s in 0..40 {
            let x = Vec3::new(
                0.4 + 0.03 * s as f32,
                0.5 + 0.021 * s as f32,
                0.6 + 0.017 * s as f32,
            );
            let (v, g) = field.value_and_gradient(x);
            let sum = field.patches[0].lattice.value(x)
                + field.patches[1].lattice.value(t.transform_point3(x));
            assert!((v - sum).abs() < 1e-6);
            let fd = Vec3::new(
                field.value(x + Vec3::X * h) - field.value(x - Vec3::X * h),
                field.value(x + Vec3::Y * h) - field.value(x - Vec3::Y * h),
                field.value(x + Vec3::Z * h) - field.value(x - Vec3::Z * h),
            ) / (2.0 * h);
            assert!(
                (g - fd).length() < 2e-3 * (1.0 + g.length()),
                "{g} vs {fd} at {x}"
            );
        }
    }

    #[test]
    fn values_on_a_grid_are_the_values_point_by_point_bit_for_bit() {
        // A base, a mapped patch (evaluated point by point) and a level-2 detail patch; the
        // grid runs from beyond the base's support, across its borders, through its inside.
        let mut field = MultiPatchField::new(wavy([8, 8, 8], 0.25));
        let t = Affine3A::from_scale_rotation_translation(
            Vec3::new(2.0, 1.5, 3.0),
            Quat::from_rotation_y(0.4),
            Vec3::new(0.2, -0.1, 0.3),
        );
        field.push(wavy([6, 7, 5], 0.5), t);
        let d = field
            .refine(Vec3::splat(0.7), Vec3::new(1.1, 1.0, 1.2), 2)
            .unwrap();
        field.patches[d].lattice.coeffs.update_each(|n, c| {
            *c = ((n * 31) % 17) as f32 / 170.0 - 0.05;
        });
        let axis = |start: f32, step: f32, n: usize| -> Vec<f32> {
            (0..n).map(|i| start + step * i as f32).collect()
        };
        let (xs, ys, zs) = (
            axis(-0.83, 0.0625, 45),
            axis(-0.6, 0.07, 37),
            axis(0.61, 0.031, 23),
        );
        let mut out = vec![f32::NAN; xs.len() * ys.len() * zs.len()];
        field.values_on_grid(&xs, &ys, &zs, &mut out);
        let mut at = 0;
        let mut nonzero = 0;
        for &z in &zs {
            for &y in &ys {
                for &x in &xs {
                    let one = field.value(Vec3::new(x, y, z));
                    assert_eq!(out[at].to_bits(), one.to_bits(), "at ({x}, {y}, {z})");
                    nonzero += usize::from(one != 0.0);
                    at += 1;
                }
            }
        }
        assert!(nonzero > out.len() / 2, "{nonzero} of {}", out.len());
    }

    #[test]
    fn a_detail_patch_fitted_to_the_residual_reduces_the_error() {
        let target = |x: Vec3| (6.0 * x.x).sin() * (5.0 * x.y).cos() * 0.3 + 0.5 * x.z;
        let mut base = BSplineLattice::zeros([8, 8, 8], 0.25, Vec3::splat(-0.25)).unwrap();
        fit_lattice(&mut base, 2, target).unwrap();
        let mut field = MultiPatchField::new(base);
        let (lo, hi) = (Vec3::splat(0.6), Vec3::splat(1.0));
        let err = |f: &MultiPatchField| {
            let mut e = 0.0_f32;
            for s in 0..100 {
                let t = Vec3::new((s % 5) as f32, ((s / 5) % 5) as f32, (s / 25) as f32) / 4.0;
                let x = lo + (hi - lo) * t;
                e = e.max((f.value(x) - target(x)).abs());
            }
            e
        };
        let before = err(&field);
        let d = field.add_detail(lo, hi, 2).unwrap();
        field.fit_detail(d, 2, target).unwrap();
        let after = err(&field);
        assert!(after < 0.25 * before, "{before} -> {after}");
    }
}
