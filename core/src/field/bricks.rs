//! Sparse storage of a lattice's coefficients: a directory of 8×8×8 bricks, each either one
//! value (no heap) or 11×11×11 values on the heap: its own 8³ and an apron, copies of the next
//! three coefficients along +x, +y and +z, which the neighbouring bricks own.
//!
//! The clay's density is clamped to `[0, 1]`: far from the surface whole bricks hold 0 (empty
//! space) or 1 (deep inside), so only the bricks near the surface or inside a simulated region
//! cost memory, and the memory grows with the surface's area rather than the box's volume.
//!
//! The apron puts every 4×4×4 cubic stencil inside the brick that owns its low corner: a
//! stencil is one brick found in the directory and sixteen rows at fixed strides, about as
//! cheap as a dense vector's (`bench/core.rs` `value_and_gradient`). The store keeps one invariant: at each of
//! a brick's 11³ places that lies inside the store, the brick holds the value of the
//! coefficient there, and a brick is uniform only when all of those values are one value. A
//! write therefore updates the owner and the apron copies in up to seven lower neighbours
//! (those whose apron reaches it), making any of them dense if the value changes there.
//!
//! Coefficient `(i, j, k)` of an `nx × ny × nz` store is also addressed by its flat index
//! `i + nx · (j + ny · k)` (x fastest), the order every iteration follows. Reads never
//! allocate. A write of a value the uniform bricks holding it already hold changes nothing;
//! any other write into a uniform brick makes it dense (one allocation of 5 324 bytes), and
//! [`BrickedCoeffs::compact`] makes a dense brick whose values are all equal uniform again.
//!
//! A store written on a thread that must not allocate (the haptic loop's copy) stays sparse:
//! before a box write, [`BrickedCoeffs::densify_for_box`] makes dense exactly the uniform
//! bricks that write would make dense, with storage ([`SpareBrick`]) allocated ahead on
//! another thread, and reports whether the spares sufficed; the write then allocates nothing.
//! Making a brick dense this way changes no value, so a pool that runs dry half-way leaves
//! the store as it was, only partly prepared. [`BrickedCoeffs::densify_all`] remains for a
//! store that is to take any write at all without allocating.
//!
//! The directory has two levels, so that empty space costs per group of bricks, not per brick:
//! the bricks are gathered in groups of 4×4×4, and a group whose bricks inside the store are
//! all uniform with one value is that one value (16 bytes for 32³ coefficients); any other group
//! holds its 64 brick entries on the heap. A stencil read is then two directory reads (the
//! group, the brick) and sixteen rows. Cloning the store, padding it and summing up its dense
//! bricks cost one step per group over the empty space (a clay grown to 930³ coefficients has
//! about 25 000 groups against 1.6 million bricks), which is what the growth step and the
//! readers' copies of a new layout pay. The groups carry an offset in bricks
//! (`group_offset`: brick `b` lies in group `(b + offset) / 4` along each axis) so that padding
//! by whole bricks maps every old group whole onto a new one. A write into a brick of a
//! uniform group gives the group its entries first (one allocation of 1 KiB): on the haptic
//! copy [`BrickedCoeffs::densify_for_box`] takes that storage ([`SpareGroup`]) from the same
//! [`SpareStorage`] as the spare bricks. Only bricks inside the store are ever dense; a
//! group's entries past the store's end stay uniform and are never read.
//!
//! The store counts its dense bricks as they change ([`BrickedCoeffs::dense_brick_count`]
//! walks nothing), and [`BrickedCoeffs::uniform_bricks_holding`] bounds what a write inside a
//! box can make dense: together they let the clay's budget of dense bricks
//! ([`super::MAX_DENSE_BRICKS`]) be checked before every write, at one directory read per brick
//! of the write's box. Building a store from a session file's bricks
//! ([`BrickedCoeffs::try_from_owned_bricks`]) stops before the dense brick past its limit.

use std::fmt;
use std::ops::Index;

use glam::Vec4;

/// Coefficients a brick owns along each axis.
pub const COEFF_BRICK: usize = 8;
/// Coefficients of the next bricks a dense brick copies along each axis (a cubic stencil's
/// reach past its first coefficient).
pub const BRICK_APRON: usize = 3;
/// Coefficients a dense brick holds along each axis: its own and its apron.
pub const BRICK_SPAN: usize = COEFF_BRICK + BRICK_APRON;
/// Coefficients a brick owns.
pub const COEFF_BRICK_VALUES: usize = COEFF_BRICK * COEFF_BRICK * COEFF_BRICK;
/// Values a dense brick holds (its own and its apron).
pub const DENSE_BRICK_VALUES: usize = BRICK_SPAN * BRICK_SPAN * BRICK_SPAN;
/// Heap bytes of one dense brick.
pub const DENSE_BRICK_BYTES: usize = DENSE_BRICK_VALUES * size_of::<f32>();

const SHIFT: usize = 3;
const MASK: usize = COEFF_BRICK - 1;
/// Bricks a group holds along each axis.
const GROUP_SPAN: usize = 4;
const GROUP_SHIFT: usize = 2;
const GROUP_MASK: usize = GROUP_SPAN - 1;
/// Bricks a group holds.
const GROUP_BRICKS: usize = GROUP_SPAN * GROUP_SPAN * GROUP_SPAN;
/// Distance between neighbouring values along y within a dense brick.
const STRIDE_Y: usize = BRICK_SPAN;
/// Distance between neighbouring values along z within a dense brick.
const STRIDE_Z: usize = BRICK_SPAN * BRICK_SPAN;
/// Values from a stencil's first one to past its last within a dense brick.
const STENCIL_REACH: usize = 3 * STRIDE_Z + 3 * STRIDE_Y + 4;

/// One brick: a single value for all of it, or every value it holds (x fastest, `BRICK_SPAN`
/// per row).
#[derive(Clone)]
enum Brick {
    Uniform(f32),
    Dense(Box<[f32; DENSE_BRICK_VALUES]>),
}

/// One group of [`GROUP_BRICKS`] bricks (see the module documentation).
#[derive(Clone)]
enum Group {
    /// Every brick of the group inside the store is uniform with this brick's value (always a
    /// [`Brick::Uniform`], held as a brick so that a read finds a brick in either case).
    Uniform(Brick),
    /// The group's bricks, `(a, b, c)` within the group at `a + 4 · (b + 4 · c)`.
    Bricks(Box<[Brick; GROUP_BRICKS]>),
}

/// The brick at `slot` of group `group`, the group given its own entries first (holding its
/// uniform value) when it had none: one allocation, unless the caller made sure the group has
/// entries already.
#[inline]
fn brick_in_group(group: &mut Group, slot: usize) -> &mut Brick {
    if let Group::Uniform(Brick::Uniform(v)) = *group {
        *group = Group::Bricks(Box::new(std::array::from_fn(|_| Brick::Uniform(v))));
    }
    match group {
        Group::Bricks(bricks) => &mut bricks[slot],
        Group::Uniform(_) => unreachable!("given entries above"),
    }
}

/// Offset of in-brick coordinates `(a, b, c)` (each below [`BRICK_SPAN`]) within a dense
/// brick.
#[inline]
fn offset(a: usize, b: usize, c: usize) -> usize {
    a + STRIDE_Y * b + STRIDE_Z * c
}

/// The offset, within the neighbour `brick + step` that owns it, of in-brick place
/// `(a, b, c)` of a brick's apron (each coordinate past [`COEFF_BRICK`] along the axes `step`
/// moves on).
#[inline]
fn apron_source(step: [usize; 3], a: usize, b: usize, c: usize) -> usize {
    offset(
        a - COEFF_BRICK * step[0],
        b - COEFF_BRICK * step[1],
        c - COEFF_BRICK * step[2],
    )
}

/// The bricks along one axis that hold coordinate `x`, with its place in each: its owner,
/// then the previous brick when `x` lies in that brick's apron. Returns the pairs and how
/// many are used.
#[inline]
fn axis_holders(x: usize) -> ([(usize, usize); 2], usize) {
    let (brick, local) = (x >> SHIFT, x & MASK);
    let in_apron = usize::from(local < BRICK_APRON && brick > 0);
    (
        [(brick, local), (brick.wrapping_sub(1), local + COEFF_BRICK)],
        1 + in_apron,
    )
}

/// Copies a run of at most one brick's row (up to [`BRICK_SPAN`] values) with fixed-size
/// copies the compiler keeps inline: two overlapping copies of 8 or 4 values, or one value
/// at a time below 4. Longer runs go to `copy_from_slice`.
// NOTE: the box reads and writes of a simulation step are a few thousand such runs; a call
// into `memmove` for each cost the step several per cent (`bench/core.rs` `step`).
#[inline(always)]
fn copy_run(dst: &mut [f32], src: &[f32]) {
    fn fixed<const N: usize>(dst: &mut [f32], src: &[f32]) {
        let len = dst.len();
        let (head, tail) = (dst.split_at_mut(N).0, &src[..N]);
        head.copy_from_slice(tail);
        dst[len - N..].copy_from_slice(&src[len - N..]);
    }
    assert_eq!(dst.len(), src.len(), "runs of one length");
    match dst.len() {
        8..=16 => fixed::<8>(dst, src),
        4..=7 => fixed::<4>(dst, src),
        0..=3 => {
            for (d, s) in dst.iter_mut().zip(src) {
                *d = *s;
            }
        }
        _ => dst.copy_from_slice(src),
    }
}

/// The lowest brick along one axis that holds coordinate `x`: the one before its owner when
/// `x` lies in that brick's apron.
#[inline]
fn lowest_holder(x: usize) -> usize {
    let (holders, count) = axis_holders(x);
    holders[count - 1].0
}

/// Widens the box `bounds` (first and last coordinate per axis, inclusive) to hold `at`.
#[inline]
fn widen(bounds: &mut ([usize; 3], [usize; 3]), at: [usize; 3]) {
    for (axis, x) in at.into_iter().enumerate() {
        bounds.0[axis] = bounds.0[axis].min(x);
        bounds.1[axis] = bounds.1[axis].max(x);
    }
}

/// What [`BrickedCoeffs::box_summary`] finds in a box of coefficients.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoxSummary {
    /// The least coefficient (infinite when all are NaN).
    pub min: f32,
    /// The greatest coefficient (minus infinite when all are NaN).
    pub max: f32,
    /// The largest difference between neighbours along an axis both in the box (zero when not
    /// asked for).
    pub max_step: f32,
}

/// `x` where it is greater than `m`, else `m` (so a NaN `x` leaves `m`).
#[inline]
pub(crate) fn larger(m: f32, x: f32) -> f32 {
    if x > m { x } else { m }
}

/// `x` where it is less than `m`, else `m` (so a NaN `x` leaves `m`).
#[inline]
pub(crate) fn smaller(m: f32, x: f32) -> f32 {
    if x < m { x } else { m }
}

/// The largest of `m` and `|b[n] − a[n]|` over the pairs of `a` and `b`.
#[inline]
fn largest_step(m: f32, a: &[f32], b: &[f32]) -> f32 {
    a.iter()
        .zip(b)
        .fold(m, |m, (&p, &q)| larger(m, (q - p).abs()))
}

/// The storage of one dense brick, allocated ahead of time: a store that must not allocate on
/// writes (the haptic loop's copy) takes one from a pool filled on another thread whenever a
/// write would make a uniform brick dense (see [`BrickedCoeffs::densify_for_box`]). Its
/// values are unspecified until it is taken into a store.
pub struct SpareBrick(Box<[f32; DENSE_BRICK_VALUES]>);

impl SpareBrick {
    /// A spare brick: one allocation of [`DENSE_BRICK_BYTES`].
    #[must_use]
    pub fn new() -> Self {
        Self(Box::new([0.0; DENSE_BRICK_VALUES]))
    }
}

impl Default for SpareBrick {
    fn default() -> Self {
        Self::new()
    }
}

impl fmt::Debug for SpareBrick {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("SpareBrick")
    }
}

/// The entries of one group of bricks, allocated ahead of time for a store that must not
/// allocate on writes (see [`SpareBrick`]): a write into a brick of a group whose bricks are
/// all one value needs the group's own entries first.
pub struct SpareGroup(Box<[Brick; GROUP_BRICKS]>);

impl SpareGroup {
    /// A spare group: one allocation of [`SPARE_GROUP_BYTES`].
    #[must_use]
    pub fn new() -> Self {
        Self(Box::new(std::array::from_fn(|_| Brick::Uniform(0.0))))
    }
}

/// Heap bytes of one group's entries ([`SpareGroup`]).
pub const SPARE_GROUP_BYTES: usize = GROUP_BRICKS * size_of::<Brick>();

impl Default for SpareGroup {
    fn default() -> Self {
        Self::new()
    }
}

impl fmt::Debug for SpareGroup {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("SpareGroup")
    }
}

/// Where a store that must not allocate takes the storage a write needs
/// ([`BrickedCoeffs::densify_for_box`]): each answers `None` when its pool is dry.
pub trait SpareStorage {
    /// Storage for one dense brick.
    fn spare_brick(&mut self) -> Option<SpareBrick>;
    /// Entries for one group of bricks.
    fn spare_group(&mut self) -> Option<SpareGroup>;
}

/// Spare storage allocated on demand, for a store that may allocate (a thread off the loops,
/// or shutdown).
#[derive(Clone, Copy, Debug, Default)]
pub struct AllocatingSpares;

impl SpareStorage for AllocatingSpares {
    fn spare_brick(&mut self) -> Option<SpareBrick> {
        Some(SpareBrick::new())
    }
    fn spare_group(&mut self) -> Option<SpareGroup> {
        Some(SpareGroup::new())
    }
}

/// Why [`BrickedCoeffs::try_from_owned_bricks`] made no store.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum OwnedBricksError<E> {
    /// The bricks' values could not be given.
    #[error("{0}")]
    Fill(E),
    /// The store would hold more dense bricks than it may.
    #[error("the bricks would make more than {max_dense} dense bricks")]
    TooManyDense {
        /// The most dense bricks the store could hold.
        max_dense: usize,
    },
}

/// One brick's own coefficients, as a session file stores them (see
/// [`BrickedCoeffs::for_each_owned_brick`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum OwnedBrick<'a> {
    /// Every coefficient the brick owns holds this value.
    Uniform(f32),
    /// The coefficients the brick owns inside the store, x fastest.
    Values(&'a [f32]),
}

/// The coefficients of an `nx × ny × nz` lattice, stored in 8×8×8 bricks with aprons (see
/// the module documentation). Equality compares values, whatever the representation.
#[derive(Clone)]
pub struct BrickedCoeffs {
    dims: [usize; 3],
    /// Bricks per axis: `dims[a]` rounded up to whole bricks.
    bricks_per_axis: [usize; 3],
    /// Per axis, how many bricks before brick 0 its group holds (below [`GROUP_SPAN`]).
    group_offset: [usize; 3],
    /// Groups per axis: the bricks and the offset rounded up to whole groups.
    groups_per_axis: [usize; 3],
    /// Group `(gi, gj, gk)` at `gi + gx · (gj + gy · gk)`.
    groups: Vec<Group>,
    /// How many of `bricks` are dense: kept by every change of representation, so the count
    /// (and the clay's memory budget, [`super::MAX_DENSE_BRICKS`]) costs no walk.
    dense: usize,
}

impl BrickedCoeffs {
    /// A store of `dims` coefficients, all `value`; allocates only the directory.
    ///
    /// # Panics
    /// When the coefficient count overflows `usize`.
    #[must_use]
    pub fn uniform(dims: [usize; 3], value: f32) -> Self {
        Self::uniform_with_offset(dims, [0; 3], value)
    }

    /// [`BrickedCoeffs::uniform`] with the groups offset by `group_offset` bricks per axis
    /// (each below [`GROUP_SPAN`]); allocates one entry per group.
    fn uniform_with_offset(dims: [usize; 3], group_offset: [usize; 3], value: f32) -> Self {
        dims.iter()
            .try_fold(1_usize, |acc, &n| acc.checked_mul(n))
            .expect("coefficient count overflows usize");
        let bricks_per_axis = dims.map(|n| n.div_ceil(COEFF_BRICK));
        let groups_per_axis: [usize; 3] = std::array::from_fn(|a| {
            if bricks_per_axis[a] == 0 {
                0
            } else {
                (bricks_per_axis[a] + group_offset[a]).div_ceil(GROUP_SPAN)
            }
        });
        let count = groups_per_axis.iter().product();
        Self {
            dims,
            bricks_per_axis,
            group_offset,
            groups_per_axis,
            groups: vec![Group::Uniform(Brick::Uniform(value)); count],
            dense: 0,
        }
    }

    /// The group holding brick `brick` and the brick's slot in it.
    #[inline(always)]
    fn locate(&self, brick: [usize; 3]) -> (usize, usize) {
        let [x, y, z]: [usize; 3] = std::array::from_fn(|a| brick[a] + self.group_offset[a]);
        let [gx, gy, _] = self.groups_per_axis;
        let group = (x >> GROUP_SHIFT) + gx * ((y >> GROUP_SHIFT) + gy * (z >> GROUP_SHIFT));
        let slot =
            (x & GROUP_MASK) + GROUP_SPAN * ((y & GROUP_MASK) + GROUP_SPAN * (z & GROUP_MASK));
        (group, slot)
    }

    /// Brick `brick` (per axis, below [`BrickedCoeffs::bricks_per_axis`]).
    #[inline(always)]
    fn brick(&self, brick: [usize; 3]) -> &Brick {
        let (group, slot) = self.locate(brick);
        match &self.groups[group] {
            Group::Uniform(uniform) => uniform,
            Group::Bricks(bricks) => &bricks[slot],
        }
    }

    /// The brick that owns coefficient `(i, j, k)`.
    #[inline(always)]
    fn brick_of(&self, i: usize, j: usize, k: usize) -> &Brick {
        self.brick([i >> SHIFT, j >> SHIFT, k >> SHIFT])
    }

    /// Brick `brick`, its group given entries first when it had none (one allocation).
    #[inline]
    fn brick_mut(&mut self, brick: [usize; 3]) -> &mut Brick {
        let (group, slot) = self.locate(brick);
        brick_in_group(&mut self.groups[group], slot)
    }

    /// Brick `brick` made dense (counted) when it was uniform; allocates its storage, and
    /// its group's entries when the group had none.
    #[inline]
    fn dense_values_mut(&mut self, brick: [usize; 3]) -> &mut [f32; DENSE_BRICK_VALUES] {
        let (group, slot) = self.locate(brick);
        densify(
            brick_in_group(&mut self.groups[group], slot),
            &mut self.dense,
        )
    }

    /// Puts `brick` at `at` (replacing a uniform brick; the caller counts dense ones): a
    /// uniform brick equal to its group's value leaves a uniform group as it is.
    fn put_brick(&mut self, at: [usize; 3], brick: Brick) {
        let (group, slot) = self.locate(at);
        if let (Brick::Uniform(w), Group::Uniform(Brick::Uniform(v))) =
            (&brick, &self.groups[group])
            && w.to_bits() == v.to_bits()
        {
            return;
        }
        *brick_in_group(&mut self.groups[group], slot) = brick;
    }

    /// Writes `values` at `off` of brick `at`; a uniform brick that holds them all already
    /// stays uniform (and its group as it is).
    #[inline]
    fn store_run(&mut self, at: [usize; 3], off: usize, values: &[f32]) {
        if let Brick::Uniform(v) = *self.brick(at)
            && values.iter().all(|h| h.to_bits() == v.to_bits())
        {
            return;
        }
        self.dense_values_mut(at)[off..off + values.len()].copy_from_slice(values);
    }

    /// The bricks of group `group` (per axis) that lie inside the store, per axis.
    fn bricks_of_group(&self, group: [usize; 3]) -> [std::ops::Range<usize>; 3] {
        std::array::from_fn(|a| {
            let first = (group[a] * GROUP_SPAN).saturating_sub(self.group_offset[a]);
            let end =
                ((group[a] + 1) * GROUP_SPAN - self.group_offset[a]).min(self.bricks_per_axis[a]);
            first..end
        })
    }

    /// Group `group` (per axis) and the bricks of it inside the store.
    fn groups_indexed(&self) -> impl Iterator<Item = (usize, [usize; 3])> + use<> {
        let [gx, gy, gz] = self.groups_per_axis;
        (0..gz).flat_map(move |gk| {
            (0..gy)
                .flat_map(move |gj| (0..gx).map(move |gi| (gi + gx * (gj + gy * gk), [gi, gj, gk])))
        })
    }

    /// Makes uniform again each group in `groups` whose bricks inside the store are all
    /// uniform with one value, freeing its entries; returns how many it made uniform.
    fn collapse_groups(&mut self, groups: impl Iterator<Item = (usize, [usize; 3])>) -> usize {
        let mut collapsed = 0;
        for (at, group) in groups {
            let Group::Bricks(bricks) = &self.groups[at] else {
                continue;
            };
            let [x, y, z] = self.bricks_of_group(group);
            let mut value = None;
            let mut same = true;
            'all: for bk in z {
                for bj in y.clone() {
                    for bi in x.clone() {
                        let slot = self.locate([bi, bj, bk]).1;
                        match (&bricks[slot], value) {
                            (Brick::Uniform(v), None) => value = Some(*v),
                            (Brick::Uniform(v), Some(w)) if v.to_bits() == f32::to_bits(w) => {}
                            _ => {
                                same = false;
                                break 'all;
                            }
                        }
                    }
                }
            }
            if same {
                self.groups[at] = Group::Uniform(Brick::Uniform(value.unwrap_or(0.0)));
                collapsed += 1;
            }
        }
        collapsed
    }

    /// A store of `dims` zero coefficients.
    #[must_use]
    pub fn zeros(dims: [usize; 3]) -> Self {
        Self::uniform(dims, 0.0)
    }

    /// A store holding `values` (x fastest); bricks whose values (apron included) are all
    /// equal stay uniform.
    ///
    /// # Panics
    /// When `values.len()` is not the product of `dims`.
    #[must_use]
    pub fn from_slice(dims: [usize; 3], values: &[f32]) -> Self {
        let mut store = Self::zeros(dims);
        assert_eq!(values.len(), store.len(), "one value per coefficient");
        let [nx, ny, _] = dims;
        let [bx, by, bz] = store.bricks_per_axis;
        // Brick by brick: a brick whose values are all equal is never made dense, so that the
        // peak memory is the values given and the dense bricks kept.
        for bk in 0..bz {
            for bj in 0..by {
                for bi in 0..bx {
                    let extent = store.held_extent([bi, bj, bk]);
                    let [i0, j0, k0] = [bi, bj, bk].map(|b| b * COEFF_BRICK);
                    let row = |b: usize, c: usize| {
                        let start = i0 + nx * (j0 + b + ny * (k0 + c));
                        &values[start..start + extent[0]]
                    };
                    let first = values[i0 + nx * (j0 + ny * k0)];
                    let same = (0..extent[2]).all(|c| {
                        (0..extent[1])
                            .all(|b| row(b, c).iter().all(|v| v.to_bits() == first.to_bits()))
                    });
                    let brick = if same {
                        Brick::Uniform(first)
                    } else {
                        let mut dense = Box::new([0.0; DENSE_BRICK_VALUES]);
                        for c in 0..extent[2] {
                            for b in 0..extent[1] {
                                dense[offset(0, b, c)..][..extent[0]].copy_from_slice(row(b, c));
                            }
                        }
                        store.dense += 1;
                        Brick::Dense(dense)
                    };
                    store.put_brick([bi, bj, bk], brick);
                }
            }
        }
        store.collapse_groups(store.groups_indexed());
        store
    }

    /// [`BrickedCoeffs::from_slice`] of a vector.
    ///
    /// # Panics
    /// As [`BrickedCoeffs::from_slice`].
    #[must_use]
    pub fn from_vec(dims: [usize; 3], values: Vec<f32>) -> Self {
        Self::from_slice(dims, &values)
    }

    /// Every value, x fastest.
    #[must_use]
    pub fn to_vec(&self) -> Vec<f32> {
        let mut out = vec![0.0; self.len()];
        let nx = self.dims[0];
        for k in 0..self.dims[2] {
            for j in 0..self.dims[1] {
                let start = nx * (j + self.dims[1] * k);
                self.read_row_at([0, j, k], &mut out[start..start + nx]);
            }
        }
        out
    }

    /// Coefficients per axis.
    #[inline]
    #[must_use]
    pub fn dims(&self) -> [usize; 3] {
        self.dims
    }

    /// Bricks per axis.
    #[inline]
    #[must_use]
    pub fn bricks_per_axis(&self) -> [usize; 3] {
        self.bricks_per_axis
    }

    /// Number of coefficients.
    #[inline]
    #[must_use]
    pub fn len(&self) -> usize {
        self.dims[0] * self.dims[1] * self.dims[2]
    }

    /// Whether the store holds no coefficient.
    #[inline]
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Number of bricks the store's box holds (uniform or dense).
    #[must_use]
    pub fn brick_count(&self) -> usize {
        self.bricks_per_axis.iter().product()
    }

    /// Number of groups of bricks the directory holds, and how many of them hold their own
    /// brick entries (the rest are one value each): a walk over the groups.
    #[must_use]
    pub fn group_counts(&self) -> (usize, usize) {
        let expanded = self
            .groups
            .iter()
            .filter(|g| matches!(g, Group::Bricks(_)))
            .count();
        (self.groups.len(), expanded)
    }

    /// Number of dense (heap-allocated) bricks: a count kept as bricks change, no walk.
    #[must_use]
    pub fn dense_brick_count(&self) -> usize {
        self.dense
    }

    /// Bytes one brick's directory entry costs where its group holds entries: the most a
    /// store holds per [`COEFF_BRICK_VALUES`] coefficients of its box besides its dense bricks
    /// (a group that is one value costs 1/64 of it per brick, plus its 16-byte share).
    pub const DIRECTORY_BYTES_PER_BRICK: usize = size_of::<Brick>();

    /// The first and last brick (per axis, inclusive) that hold a coefficient of the box
    /// `min..=max` clipped to the store, as owner or in their apron; `None` when the box holds
    /// no coefficient of the store.
    fn bricks_holding(&self, min: [usize; 3], max: [usize; 3]) -> Option<([usize; 3], [usize; 3])> {
        if self.is_empty() || (0..3).any(|a| min[a] > max[a] || min[a] >= self.dims[a]) {
            return None;
        }
        let first = min.map(lowest_holder);
        let last = std::array::from_fn(|a| max[a].min(self.dims[a] - 1) >> SHIFT);
        Some((first, last))
    }

    /// How many uniform bricks hold a coefficient of the box `min..=max` (clipped to the
    /// store), as owner or in their apron: the most bricks a write inside that box can make
    /// dense. Reads one directory entry per brick the box reaches; allocates nothing.
    #[must_use]
    pub fn uniform_bricks_holding(&self, min: [usize; 3], max: [usize; 3]) -> usize {
        let Some((first, last)) = self.bricks_holding(min, max) else {
            return 0;
        };
        let mut uniform = 0;
        for bk in first[2]..=last[2] {
            for bj in first[1]..=last[1] {
                uniform += (first[0]..=last[0])
                    .filter(|&bi| matches!(self.brick([bi, bj, bk]), Brick::Uniform(_)))
                    .count();
            }
        }
        uniform
    }

    /// The dense bricks counted by walking the directory (what `dense` must equal).
    fn walked_dense_count(&self) -> usize {
        self.groups
            .iter()
            .map(|g| match g {
                Group::Uniform(_) => 0,
                Group::Bricks(bricks) => bricks
                    .iter()
                    .filter(|b| matches!(b, Brick::Dense(_)))
                    .count(),
            })
            .sum()
    }

    /// Bytes this store holds on the heap: the groups, the entries of the groups that hold
    /// them, and the dense bricks. Walks the groups.
    #[must_use]
    pub fn heap_bytes(&self) -> usize {
        self.groups.capacity() * size_of::<Group>()
            + self.group_counts().1 * SPARE_GROUP_BYTES
            + self.dense_brick_count() * DENSE_BRICK_BYTES
    }

    /// Coordinates `(i, j, k)` of flat index `n`.
    #[inline]
    #[must_use]
    pub fn coords(&self, n: usize) -> [usize; 3] {
        let [nx, ny, _] = self.dims;
        let i = n % nx;
        let rest = n / nx;
        [i, rest % ny, rest / ny]
    }

    #[inline]
    fn check(&self, i: usize, j: usize, k: usize) {
        assert!(
            i < self.dims[0] && j < self.dims[1] && k < self.dims[2],
            "coefficient ({i}, {j}, {k}) outside {:?}",
            self.dims
        );
    }

    /// A reference to coefficient `(i, j, k)`.
    ///
    /// # Panics
    /// When `(i, j, k)` lies outside the store.
    #[inline]
    #[must_use]
    pub fn at(&self, i: usize, j: usize, k: usize) -> &f32 {
        self.check(i, j, k);
        match self.brick_of(i, j, k) {
            Brick::Uniform(v) => v,
            Brick::Dense(values) => &values[offset(i & MASK, j & MASK, k & MASK)],
        }
    }

    /// Coefficient `(i, j, k)`.
    ///
    /// # Panics
    /// When `(i, j, k)` lies outside the store.
    #[inline]
    #[must_use]
    pub fn get(&self, i: usize, j: usize, k: usize) -> f32 {
        *self.at(i, j, k)
    }

    /// Sets coefficient `(i, j, k)` in its brick and in the aprons that copy it; a uniform
    /// brick that already holds `value` stays uniform.
    ///
    /// # Panics
    /// When `(i, j, k)` lies outside the store.
    #[inline]
    pub fn set(&mut self, i: usize, j: usize, k: usize, value: f32) {
        self.check(i, j, k);
        let (xs, nx) = axis_holders(i);
        let (ys, ny) = axis_holders(j);
        let (zs, nz) = axis_holders(k);
        for &(bk, c) in &zs[..nz] {
            for &(bj, b) in &ys[..ny] {
                for &(bi, a) in &xs[..nx] {
                    self.store_run([bi, bj, bk], offset(a, b, c), &[value]);
                }
            }
        }
    }

    /// Sets the coefficient at flat index `n` (as [`BrickedCoeffs::set`]).
    ///
    /// # Panics
    /// When `n` is not below [`BrickedCoeffs::len`].
    #[inline]
    pub fn set_flat(&mut self, n: usize, value: f32) {
        assert!(
            n < self.len(),
            "index {n} outside {} coefficients",
            self.len()
        );
        let [i, j, k] = self.coords(n);
        self.set(i, j, k, value);
    }

    /// Adds `delta` to the coefficient at flat index `n` (as [`BrickedCoeffs::set_flat`]).
    ///
    /// # Panics
    /// When `n` is not below [`BrickedCoeffs::len`].
    #[inline]
    pub fn add_flat(&mut self, n: usize, delta: f32) {
        let value = self[n] + delta;
        self.set_flat(n, value);
    }

    /// Four consecutive coefficients along x from `(i, j, k)` (the row of a cubic stencil).
    ///
    /// # Panics
    /// When `i + 3`, `j` or `k` lies outside the store.
    #[inline]
    #[must_use]
    pub fn row4(&self, i: usize, j: usize, k: usize) -> Vec4 {
        self.check(i + 3, j, k);
        match self.brick_of(i, j, k) {
            Brick::Uniform(v) => Vec4::splat(*v),
            // The row's last three values are in the owner's apron when they cross.
            Brick::Dense(values) => {
                Vec4::from_slice(&values[offset(i & MASK, j & MASK, k & MASK)..][..4])
            }
        }
    }

    /// The 4×4×4 coefficients from `(i, j, k)` (a cubic stencil) as 16 rows along x, row
    /// `b + 4c` holding `(i..i + 4, j + b, k + c)`: one brick found in the directory (its
    /// group, then the brick), the brick that owns `(i, j, k)` holding the whole stencil in
    /// its own values and apron.
    ///
    /// The caller keeps the stencil inside the store (checked in debug builds; outside it,
    /// the values read past the store's end are not coefficients).
    #[inline(always)]
    #[must_use]
    pub fn stencil_rows(&self, [i, j, k]: [usize; 3]) -> [Vec4; 16] {
        debug_assert!(
            i + 3 < self.dims[0] && j + 3 < self.dims[1] && k + 3 < self.dims[2],
            "stencil at ({i}, {j}, {k}) outside {:?}",
            self.dims
        );
        match self.brick_of(i, j, k) {
            Brick::Uniform(v) => [Vec4::splat(*v); 16],
            Brick::Dense(values) => {
                // NOTE: one slice of the stencil's reach, so the sixteen constant offsets
                // below need no bounds checks of their own.
                let block = &values[offset(i & MASK, j & MASK, k & MASK)..][..STENCIL_REACH];
                std::array::from_fn(|n| {
                    let off = STRIDE_Y * (n & 3) + STRIDE_Z * (n >> 2);
                    Vec4::from_slice(&block[off..off + 4])
                })
            }
        }
    }

    /// Copies `out.len()` coefficients along x from `(i, j, k)` into `out`.
    ///
    /// # Panics
    /// When the run leaves the store.
    pub fn read_row_at(&self, [i, j, k]: [usize; 3], out: &mut [f32]) {
        if out.is_empty() {
            return;
        }
        self.check(i + out.len() - 1, j, k);
        let (b, c) = (j & MASK, k & MASK);
        let mut x = i;
        let mut rest = out;
        while !rest.is_empty() {
            let a = x & MASK;
            let run = (COEFF_BRICK - a).min(rest.len());
            let (here, after) = rest.split_at_mut(run);
            match self.brick_of(x, j, k) {
                Brick::Uniform(v) => here.fill(*v),
                Brick::Dense(values) => {
                    copy_run(here, &values[offset(a, b, c)..][..run]);
                }
            }
            rest = after;
            x += run;
        }
    }

    /// Folds `f` over `len` coefficients along x from `(i, j, k)`, in order, without copying
    /// them out.
    ///
    /// # Panics
    /// When the run leaves the store.
    pub fn fold_row_at<T>(
        &self,
        [i, j, k]: [usize; 3],
        len: usize,
        init: T,
        mut f: impl FnMut(T, f32) -> T,
    ) -> T {
        if len == 0 {
            return init;
        }
        self.check(i + len - 1, j, k);
        let (b, c) = (j & MASK, k & MASK);
        let mut acc = init;
        let mut x = i;
        while x < i + len {
            let a = x & MASK;
            let run = (COEFF_BRICK - a).min(i + len - x);
            match self.brick_of(x, j, k) {
                Brick::Uniform(v) => {
                    for _ in 0..run {
                        acc = f(acc, *v);
                    }
                }
                Brick::Dense(values) => {
                    for &v in &values[offset(a, b, c)..][..run] {
                        acc = f(acc, v);
                    }
                }
            }
            x += run;
        }
        acc
    }

    /// The least and greatest coefficient in the box `first ..= last` (inclusive, per axis)
    /// and, with `steps`, the largest difference between two neighbours along an axis that
    /// both lie in the box. Brick by brick: a uniform brick is one value (its apron holds the
    /// next coefficients, so its steps inside the box are all zero), a dense brick is read in
    /// place, each step to the next coefficient along an axis from its own apron. A NaN
    /// coefficient is passed over. Allocates nothing.
    ///
    /// # Panics
    /// When the box is empty or leaves the store.
    #[must_use]
    pub fn box_summary(&self, first: [usize; 3], last: [usize; 3], steps: bool) -> BoxSummary {
        assert!(
            (0..3).all(|a| first[a] <= last[a]),
            "empty box {first:?} ..= {last:?}"
        );
        self.check(last[0], last[1], last[2]);
        let mut out = BoxSummary {
            min: f32::INFINITY,
            max: f32::NEG_INFINITY,
            max_step: 0.0,
        };
        // A brick's own coordinates in the box along `axis` (in-brick, end exclusive), and
        // whether the coordinate after them is in the box too (then in the brick's apron).
        let own = |axis: usize, brick: usize| {
            let from = first[axis].max(brick << SHIFT);
            let to = last[axis].min((brick << SHIFT) + MASK);
            (from & MASK, (to & MASK) + 1, to < last[axis])
        };
        for bk in first[2] >> SHIFT..=last[2] >> SHIFT {
            let (c0, c_end, z_next) = own(2, bk);
            for bj in first[1] >> SHIFT..=last[1] >> SHIFT {
                let (b0, b_end, y_next) = own(1, bj);
                for bi in first[0] >> SHIFT..=last[0] >> SHIFT {
                    let (a0, a_end, x_next) = own(0, bi);
                    let values = match self.brick([bi, bj, bk]) {
                        Brick::Uniform(v) => {
                            out.min = smaller(out.min, *v);
                            out.max = larger(out.max, *v);
                            continue;
                        }
                        Brick::Dense(values) => values,
                    };
                    // With the next coefficient along x where it is in the box.
                    let row_len = a_end - a0 + usize::from(x_next);
                    for c in c0..c_end {
                        for b in b0..b_end {
                            let at = offset(a0, b, c);
                            let row = &values[at..at + row_len];
                            let mine = &row[..a_end - a0];
                            for &v in mine {
                                out.min = smaller(out.min, v);
                                out.max = larger(out.max, v);
                            }
                            if !steps {
                                continue;
                            }
                            out.max_step = largest_step(out.max_step, row, &row[1..]);
                            if b + 1 < b_end || y_next {
                                let next = offset(a0, b + 1, c);
                                out.max_step = largest_step(
                                    out.max_step,
                                    mine,
                                    &values[next..next + mine.len()],
                                );
                            }
                            if c + 1 < c_end || z_next {
                                let next = offset(a0, b, c + 1);
                                out.max_step = largest_step(
                                    out.max_step,
                                    mine,
                                    &values[next..next + mine.len()],
                                );
                            }
                        }
                    }
                }
            }
        }
        out
    }

    /// The smallest box (first and last coefficient per axis, inclusive) holding every
    /// coefficient whose bits differ between this store and `other`; `None` when they hold the
    /// same values. Brick by brick: two uniform bricks are compared as one value each, so two
    /// copies of a large clay that differ near its surface cost a directory read per brick
    /// and a read of the bricks that are dense in either. Allocates nothing.
    ///
    /// # Panics
    /// When the stores' dimensions differ.
    #[must_use]
    pub fn differing_box(&self, other: &Self) -> Option<([usize; 3], [usize; 3])> {
        assert_eq!(self.dims, other.dims, "stores of one shape");
        let mut bounds = ([usize::MAX; 3], [0_usize; 3]);
        if self.group_offset == other.group_offset {
            // Groups alike: two groups that are one value each are compared as one value.
            for (at, group) in self.groups_indexed() {
                let bricks = self.bricks_of_group(group);
                if let (Group::Uniform(Brick::Uniform(p)), Group::Uniform(Brick::Uniform(q))) =
                    (&self.groups[at], &other.groups[at])
                {
                    if p.to_bits() != q.to_bits() {
                        widen(&mut bounds, bricks.clone().map(|r| r.start * COEFF_BRICK));
                        widen(
                            &mut bounds,
                            std::array::from_fn(|a| {
                                (bricks[a].end * COEFF_BRICK).min(self.dims[a]) - 1
                            }),
                        );
                    }
                    continue;
                }
                self.differing_in_bricks(other, bricks, &mut bounds);
            }
        } else {
            let bricks = self.bricks_per_axis.map(|n| 0..n);
            self.differing_in_bricks(other, bricks, &mut bounds);
        }
        let (first, last) = bounds;
        (first[0] != usize::MAX).then_some((first, last))
    }

    /// [`BrickedCoeffs::differing_box`] over the bricks `bricks` (per axis), widening
    /// `bounds` (first and last coefficient per axis) by every coefficient that differs.
    fn differing_in_bricks(
        &self,
        other: &Self,
        bricks: [std::ops::Range<usize>; 3],
        bounds: &mut ([usize; 3], [usize; 3]),
    ) {
        for bk in bricks[2].clone() {
            for bj in bricks[1].clone() {
                for bi in bricks[0].clone() {
                    let low = [bi << SHIFT, bj << SHIFT, bk << SHIFT];
                    // This brick's own coefficients within the store, per axis (end exclusive).
                    let own: [usize; 3] =
                        std::array::from_fn(|a| COEFF_BRICK.min(self.dims[a] - low[a]));
                    let value = |brick: &Brick, a: usize, b: usize, c: usize| match brick {
                        Brick::Uniform(v) => *v,
                        Brick::Dense(values) => values[offset(a, b, c)],
                    };
                    match (self.brick([bi, bj, bk]), other.brick([bi, bj, bk])) {
                        (Brick::Uniform(p), Brick::Uniform(q)) => {
                            if p.to_bits() != q.to_bits() {
                                widen(bounds, low);
                                widen(bounds, std::array::from_fn(|a| low[a] + own[a] - 1));
                            }
                        }
                        (p, q) => {
                            for c in 0..own[2] {
                                for b in 0..own[1] {
                                    for a in 0..own[0] {
                                        let (u, v) = (value(p, a, b, c), value(q, a, b, c));
                                        if u.to_bits() != v.to_bits() {
                                            widen(bounds, [low[0] + a, low[1] + b, low[2] + c]);
                                        }
                                    }
                                }
                            }
                        }
                    }
                }
            }
        }
    }

    /// [`BrickedCoeffs::read_row_at`] from flat index `start`.
    ///
    /// # Panics
    /// When the run leaves the store or its x row.
    pub fn read_row(&self, start: usize, out: &mut [f32]) {
        self.read_row_at(self.coords(start), out);
    }

    /// Appends `len` coefficients along x from flat index `start` to `out`.
    ///
    /// # Panics
    /// As [`BrickedCoeffs::read_row`].
    pub fn extend_row_into(&self, start: usize, len: usize, out: &mut Vec<f32>) {
        let at = out.len();
        out.resize(at + len, 0.0);
        self.read_row(start, &mut out[at..]);
    }

    /// Writes `values` along x from `(i, j, k)`, into the owners and the aprons that copy
    /// them. A uniform brick whose part of the run already holds its value stays uniform (no
    /// allocation); any other stays or becomes dense.
    ///
    /// # Panics
    /// When the run leaves the store.
    pub fn write_row_at(&mut self, [i, j, k]: [usize; 3], values: &[f32]) {
        if values.is_empty() {
            return;
        }
        self.check(i + values.len() - 1, j, k);
        let (ys, ny) = axis_holders(j);
        let (zs, nz) = axis_holders(k);
        let mut x = i;
        let mut rest = values;
        while !rest.is_empty() {
            let (bi, a) = (x >> SHIFT, x & MASK);
            let run = (COEFF_BRICK - a).min(rest.len());
            let (here, after) = rest.split_at(run);
            for &(bk, c) in &zs[..nz] {
                for &(bj, b) in &ys[..ny] {
                    self.store_run([bi, bj, bk], offset(a, b, c), here);
                    if a < BRICK_APRON && bi > 0 {
                        // The run's first values are also in the apron of the brick before.
                        let copied = &here[..(BRICK_APRON - a).min(run)];
                        let off = offset(a + COEFF_BRICK, b, c);
                        self.store_run([bi - 1, bj, bk], off, copied);
                    }
                }
            }
            rest = after;
            x += run;
        }
    }

    /// Checks a box of `size` coefficients from `min` against the store and against `len`
    /// values given for it; whether it holds any coefficient.
    ///
    /// # Panics
    /// When the box leaves the store or `len` is not its number of coefficients.
    fn check_box(&self, min: [usize; 3], size: [usize; 3], len: usize) -> bool {
        assert_eq!(
            len,
            size.iter().product::<usize>(),
            "one value per coefficient"
        );
        if len == 0 {
            return false;
        }
        self.check(
            min[0] + size[0] - 1,
            min[1] + size[1] - 1,
            min[2] + size[2] - 1,
        );
        true
    }

    /// Writes the box of `size` coefficients whose lowest corner is `min`, `values` holding
    /// them x fastest, into the owners and the aprons that copy them: brick by brick, one
    /// copy per row of the box's part that a brick holds. A uniform brick whose part already
    /// holds its value stays uniform (no allocation); any other stays or becomes dense.
    ///
    /// # Panics
    /// When the box leaves the store or `values` does not hold one value per coefficient of
    /// it.
    pub fn write_box(&mut self, min: [usize; 3], size: [usize; 3], values: &[f32]) {
        if !self.check_box(min, size, values.len()) {
            return;
        }
        let first = min.map(lowest_holder);
        let last: [usize; 3] = std::array::from_fn(|a| (min[a] + size[a] - 1) >> SHIFT);
        for bk in first[2]..=last[2] {
            for bj in first[1]..=last[1] {
                for bi in first[0]..=last[0] {
                    let origin = [bi, bj, bk].map(|b| b * COEFF_BRICK);
                    // The box's part this brick holds, in store coordinates (`lo..hi`).
                    let lo: [usize; 3] = std::array::from_fn(|a| min[a].max(origin[a]));
                    let hi: [usize; 3] =
                        std::array::from_fn(|a| (min[a] + size[a]).min(origin[a] + BRICK_SPAN));
                    if (0..3).any(|a| lo[a] >= hi[a]) {
                        continue;
                    }
                    let len = hi[0] - lo[0];
                    let source = |y: usize, z: usize| {
                        let at = lo[0] - min[0] + size[0] * (y - min[1] + size[1] * (z - min[2]));
                        &values[at..at + len]
                    };
                    if let Brick::Uniform(v) = *self.brick([bi, bj, bk]) {
                        let keeps = (lo[2]..hi[2]).all(|z| {
                            (lo[1]..hi[1])
                                .all(|y| source(y, z).iter().all(|h| h.to_bits() == v.to_bits()))
                        });
                        if keeps {
                            continue;
                        }
                    }
                    let dense = self.dense_values_mut([bi, bj, bk]);
                    for z in lo[2]..hi[2] {
                        for y in lo[1]..hi[1] {
                            let off = offset(lo[0] - origin[0], y - origin[1], z - origin[2]);
                            copy_run(&mut dense[off..off + len], source(y, z));
                        }
                    }
                }
            }
        }
    }

    /// Makes dense, without changing any value, every uniform brick that
    /// [`BrickedCoeffs::write_box`] of the same box and values would make dense, taking the
    /// storage from `spares` instead of allocating: a brick's storage, and first its group's
    /// entries when its group is one value. Returns whether every such brick is dense now:
    /// then that write allocates nothing. When `spares` runs dry first it returns `false`;
    /// the groups given entries and the bricks made dense so far stay so (they hold the
    /// values they held), so a later call with more spares goes on where this one stopped.
    ///
    /// Never allocates, and frees nothing. Reads the directory entry of each brick the box
    /// reaches, and the values that fall in a uniform one (the comparison `write_box` makes
    /// too); a brick already dense costs one lookup.
    ///
    /// # Panics
    /// As [`BrickedCoeffs::write_box`].
    pub fn densify_for_box(
        &mut self,
        min: [usize; 3],
        size: [usize; 3],
        values: &[f32],
        spares: &mut impl SpareStorage,
    ) -> bool {
        if !self.check_box(min, size, values.len()) {
            return true;
        }
        let first = min.map(lowest_holder);
        let last: [usize; 3] = std::array::from_fn(|a| (min[a] + size[a] - 1) >> SHIFT);
        for bk in first[2]..=last[2] {
            for bj in first[1]..=last[1] {
                for bi in first[0]..=last[0] {
                    let Brick::Uniform(v) = *self.brick([bi, bj, bk]) else {
                        continue;
                    };
                    let origin = [bi, bj, bk].map(|b| b * COEFF_BRICK);
                    // The box's part this brick holds, as in `write_box`.
                    let lo: [usize; 3] = std::array::from_fn(|a| min[a].max(origin[a]));
                    let hi: [usize; 3] =
                        std::array::from_fn(|a| (min[a] + size[a]).min(origin[a] + BRICK_SPAN));
                    if (0..3).any(|a| lo[a] >= hi[a]) {
                        continue;
                    }
                    let len = hi[0] - lo[0];
                    let keeps = (lo[2]..hi[2]).all(|z| {
                        (lo[1]..hi[1]).all(|y| {
                            let at =
                                lo[0] - min[0] + size[0] * (y - min[1] + size[1] * (z - min[2]));
                            values[at..at + len]
                                .iter()
                                .all(|h| h.to_bits() == v.to_bits())
                        })
                    });
                    if keeps {
                        continue;
                    }
                    let (group, slot) = self.locate([bi, bj, bk]);
                    let group = &mut self.groups[group];
                    if let Group::Uniform(Brick::Uniform(w)) = *group {
                        let Some(SpareGroup(mut entries)) = spares.spare_group() else {
                            return false;
                        };
                        // The spare's entries are uniform bricks: replacing them frees nothing.
                        for entry in entries.iter_mut() {
                            *entry = Brick::Uniform(w);
                        }
                        *group = Group::Bricks(entries);
                    }
                    let Some(SpareBrick(mut storage)) = spares.spare_brick() else {
                        return false;
                    };
                    storage.fill(v);
                    // The brick was uniform: replacing it frees nothing.
                    *brick_in_group(group, slot) = Brick::Dense(storage);
                    self.dense += 1;
                }
            }
        }
        true
    }

    /// Copies the box of `size` coefficients whose lowest corner is `min` into `out`, x
    /// fastest: brick by brick, one copy per row of the box's part that a brick owns.
    ///
    /// # Panics
    /// When the box leaves the store or `out` does not hold one value per coefficient of it.
    pub fn read_box(&self, min: [usize; 3], size: [usize; 3], out: &mut [f32]) {
        if !self.check_box(min, size, out.len()) {
            return;
        }
        let first = min.map(|m| m >> SHIFT);
        let last: [usize; 3] = std::array::from_fn(|a| (min[a] + size[a] - 1) >> SHIFT);
        for bk in first[2]..=last[2] {
            for bj in first[1]..=last[1] {
                for bi in first[0]..=last[0] {
                    let origin = [bi, bj, bk].map(|b| b * COEFF_BRICK);
                    let lo: [usize; 3] = std::array::from_fn(|a| min[a].max(origin[a]));
                    let hi: [usize; 3] =
                        std::array::from_fn(|a| (min[a] + size[a]).min(origin[a] + COEFF_BRICK));
                    let len = hi[0] - lo[0];
                    let brick = self.brick([bi, bj, bk]);
                    for z in lo[2]..hi[2] {
                        for y in lo[1]..hi[1] {
                            let at =
                                lo[0] - min[0] + size[0] * (y - min[1] + size[1] * (z - min[2]));
                            let here = &mut out[at..at + len];
                            match brick {
                                Brick::Uniform(v) => here.fill(*v),
                                Brick::Dense(values) => {
                                    let off =
                                        offset(lo[0] - origin[0], y - origin[1], z - origin[2]);
                                    copy_run(here, &values[off..off + len]);
                                }
                            }
                        }
                    }
                }
            }
        }
    }

    /// [`BrickedCoeffs::write_row_at`] from flat index `start`.
    ///
    /// # Panics
    /// When the run leaves the store or its x row.
    pub fn write_row(&mut self, start: usize, values: &[f32]) {
        self.write_row_at(self.coords(start), values);
    }

    /// Calls `f` with the run of `len` coefficients along x from flat index `start`, as one
    /// mutable slice (copied out and written back, so bricks the call leaves unchanged stay
    /// uniform). Allocates a scratch row.
    ///
    /// # Panics
    /// As [`BrickedCoeffs::read_row`].
    pub fn with_row_mut<R>(
        &mut self,
        start: usize,
        len: usize,
        f: impl FnOnce(&mut [f32]) -> R,
    ) -> R {
        let mut row = vec![0.0; len];
        self.read_row(start, &mut row);
        let out = f(&mut row);
        self.write_row(start, &row);
        out
    }

    /// Every value in flat order (x fastest).
    #[must_use]
    pub fn iter(&self) -> Values<'_> {
        Values {
            store: self,
            next: [0, 0, 0],
            run: Run::Slice(&[]),
        }
    }

    /// Calls `f(n, value)` for every coefficient in flat order, where `n` is its flat index,
    /// letting it change the value. A uniform brick becomes dense only when `f` changes a
    /// value it holds (to other bits).
    pub fn update_each(&mut self, mut f: impl FnMut(usize, &mut f32)) {
        let [nx, ny, nz] = self.dims;
        let mut run_values = [0.0_f32; COEFF_BRICK];
        for k in 0..nz {
            for j in 0..ny {
                let row = nx * (j + ny * k);
                let mut x = 0;
                while x < nx {
                    let run = (COEFF_BRICK - (x & MASK)).min(nx - x);
                    let values = &mut run_values[..run];
                    self.read_row_at([x, j, k], values);
                    let mut changed = false;
                    for (s, value) in values.iter_mut().enumerate() {
                        let before = value.to_bits();
                        f(row + x + s, value);
                        changed |= value.to_bits() != before;
                    }
                    if changed {
                        self.write_row_at([x, j, k], values);
                    }
                    x += run;
                }
            }
        }
    }

    /// Replaces every coefficient `v` by `f(v)`, brick by brick: a uniform brick stays one
    /// value and a dense one is mapped in place (its apron too, so it stays the copy of its
    /// neighbours'), so nothing is allocated and no brick is made dense. Returns how many
    /// coefficients changed bits.
    pub fn map_values(&mut self, f: impl Fn(f32) -> f32) -> usize {
        let mut changed = 0;
        for (at, group) in self.groups_indexed() {
            let bricks = self.bricks_of_group(group);
            if let Group::Uniform(Brick::Uniform(v)) = &mut self.groups[at] {
                let new = f(*v);
                if new.to_bits() != v.to_bits() {
                    // Every coefficient the group's bricks own inside the store.
                    changed += (0..3)
                        .map(|a| {
                            (bricks[a].end * COEFF_BRICK).min(self.dims[a])
                                - bricks[a].start * COEFF_BRICK
                        })
                        .product::<usize>();
                    *v = new;
                }
                continue;
            }
            for bk in bricks[2].clone() {
                for bj in bricks[1].clone() {
                    for bi in bricks[0].clone() {
                        changed += self.map_brick([bi, bj, bk], &f);
                    }
                }
            }
        }
        changed
    }

    /// [`BrickedCoeffs::map_values`] for brick `brick` of a group that holds entries.
    fn map_brick(&mut self, brick: [usize; 3], f: &impl Fn(f32) -> f32) -> usize {
        let owned = self.owned_extent(brick);
        let held = self.held_extent(brick);
        let (group, slot) = self.locate(brick);
        let mut changed = 0;
        match brick_in_group(&mut self.groups[group], slot) {
            Brick::Uniform(v) => {
                let new = f(*v);
                if new.to_bits() != v.to_bits() {
                    changed += owned.iter().product::<usize>();
                    *v = new;
                }
            }
            Brick::Dense(values) => {
                for c in 0..held[2] {
                    for b in 0..held[1] {
                        let row = &mut values[offset(0, b, c)..][..held[0]];
                        for (a, v) in row.iter_mut().enumerate() {
                            let new = f(*v);
                            let own = a < owned[0] && b < owned[1] && c < owned[2];
                            changed += usize::from(own && new.to_bits() != v.to_bits());
                            *v = new;
                        }
                    }
                }
            }
        }
        changed
    }

    /// Sets every coefficient to `value`; frees every dense brick and every group's entries.
    pub fn fill(&mut self, value: f32) {
        for g in &mut self.groups {
            *g = Group::Uniform(Brick::Uniform(value));
        }
        self.dense = 0;
    }

    /// Makes every dense brick whose values (apron included, within the store) all have the
    /// same bits uniform again, freeing its values; returns how many it freed.
    pub fn compact(&mut self) -> usize {
        if self.is_empty() {
            return 0;
        }
        self.compact_within([0; 3], self.dims.map(|n| n - 1))
    }

    /// [`BrickedCoeffs::compact`] for the bricks that hold a coefficient of the box
    /// `min..=max` (clipped to the store), as owner or in their apron: where an edit settled.
    /// A group of those bricks whose bricks are then all uniform with one value becomes that
    /// value, freeing its entries. Visits the groups the box reaches and the bricks of those
    /// that hold entries.
    pub fn compact_within(&mut self, min: [usize; 3], max: [usize; 3]) -> usize {
        let Some((first, last)) = self.bricks_holding(min, max) else {
            return 0;
        };
        let [gx, gy, _] = self.groups_per_axis;
        let group_of = |b: [usize; 3]| -> [usize; 3] {
            std::array::from_fn(|a| (b[a] + self.group_offset[a]) >> GROUP_SHIFT)
        };
        let (g_first, g_last) = (group_of(first), group_of(last));
        let mut freed = 0;
        for gk in g_first[2]..=g_last[2] {
            for gj in g_first[1]..=g_last[1] {
                for gi in g_first[0]..=g_last[0] {
                    let at = gi + gx * (gj + gy * gk);
                    if matches!(self.groups[at], Group::Uniform(_)) {
                        continue;
                    }
                    let bricks = self.bricks_of_group([gi, gj, gk]);
                    let clip =
                        |a: usize| bricks[a].start.max(first[a])..bricks[a].end.min(last[a] + 1);
                    for bk in clip(2) {
                        for bj in clip(1) {
                            for bi in clip(0) {
                                freed += usize::from(self.compact_brick([bi, bj, bk]));
                            }
                        }
                    }
                    self.collapse_groups(std::iter::once((at, [gi, gj, gk])));
                }
            }
        }
        self.dense -= freed;
        freed
    }

    /// Makes brick `brick` uniform when it is dense and its values (apron included, within
    /// the store) all have the same bits; whether it did. Leaves the dense count to the
    /// caller.
    fn compact_brick(&mut self, brick: [usize; 3]) -> bool {
        let extent = self.held_extent(brick);
        let (group, slot) = self.locate(brick);
        let Group::Bricks(bricks) = &mut self.groups[group] else {
            return false;
        };
        let brick = &mut bricks[slot];
        let Brick::Dense(values) = brick else {
            return false;
        };
        let first = values[0];
        let same = (0..extent[2]).all(|c| {
            (0..extent[1]).all(|b| {
                values[offset(0, b, c)..][..extent[0]]
                    .iter()
                    .all(|v| v.to_bits() == first.to_bits())
            })
        });
        if same {
            *brick = Brick::Uniform(first);
        }
        same
    }

    /// Calls `f` with each brick's own coefficients (never its apron), in directory order
    /// (brick `(bi, bj, bk)` at `bi + bx · (bj + by · bk)`, x fastest): a brick whose own
    /// coefficients inside the store all hold the bits of one value is given as
    /// [`OwnedBrick::Uniform`], any other as [`OwnedBrick::Values`] (the part inside the
    /// store, x fastest). This is the layout a session file stores; see
    /// [`BrickedCoeffs::try_from_owned_bricks`] for the way back.
    pub fn for_each_owned_brick(&self, mut f: impl FnMut(OwnedBrick<'_>)) {
        let mut scratch = [0.0_f32; COEFF_BRICK_VALUES];
        let [bx, by, bz] = self.bricks_per_axis;
        for bk in 0..bz {
            for bj in 0..by {
                for bi in 0..bx {
                    let extent = self.owned_extent([bi, bj, bk]);
                    match self.brick([bi, bj, bk]) {
                        Brick::Uniform(v) => f(OwnedBrick::Uniform(*v)),
                        Brick::Dense(values) => {
                            let first = values[0];
                            let mut same = true;
                            let mut n = 0;
                            for c in 0..extent[2] {
                                for b in 0..extent[1] {
                                    let row = &values[offset(0, b, c)..][..extent[0]];
                                    same &= row.iter().all(|v| v.to_bits() == first.to_bits());
                                    scratch[n..n + extent[0]].copy_from_slice(row);
                                    n += extent[0];
                                }
                            }
                            f(if same {
                                OwnedBrick::Uniform(first)
                            } else {
                                OwnedBrick::Values(&scratch[..n])
                            });
                        }
                    }
                }
            }
        }
    }

    /// A store of `dims` coefficients built brick by brick from each brick's own
    /// coefficients, in directory order (see [`BrickedCoeffs::for_each_owned_brick`]):
    /// `fill(first, extent, out)` is called once per brick with the coordinates of the
    /// brick's first coefficient, how many of its own coefficients lie inside the store per
    /// axis, and `out` of their number; it returns `Ok(Some(v))` when they all equal `v`, or
    /// writes them into `out` (x fastest) and returns `Ok(None)`. The aprons are then copied
    /// from the neighbours that own them; a brick stays uniform when its own values and its
    /// apron all agree (so the store holds no more dense bricks than the one it was saved
    /// from). The directory is allocated first (`dims` bounds it: the caller checks `dims`
    /// against its budget before calling); each dense brick is allocated when `fill` gives
    /// its values, and never more than `max_dense` of them: the store is refused before the
    /// first one past it is allocated. The uniform bricks whose aprons disagree with them are
    /// counted before any of them is made dense, so a store whose aprons would pass
    /// `max_dense` is refused having allocated only the bricks `fill` gave values for (a
    /// hostile file of uniform runs that alternate costs its directory, not the budget).
    ///
    /// # Errors
    /// [`OwnedBricksError::Fill`] with the first error `fill` returns, or
    /// [`OwnedBricksError::TooManyDense`] when the store would hold more than `max_dense`
    /// dense bricks; nothing is kept then.
    ///
    /// # Panics
    /// When the coefficient count overflows `usize`.
    pub fn try_from_owned_bricks<E>(
        dims: [usize; 3],
        max_dense: usize,
        mut fill: impl FnMut([usize; 3], [usize; 3], &mut [f32]) -> Result<Option<f32>, E>,
    ) -> Result<Self, OwnedBricksError<E>> {
        let mut store = Self::zeros(dims);
        if store.is_empty() {
            return Ok(store);
        }
        let mut scratch = [0.0_f32; COEFF_BRICK_VALUES];
        let [bx, by, bz] = store.bricks_per_axis;
        for bk in 0..bz {
            for bj in 0..by {
                for bi in 0..bx {
                    let extent = store.owned_extent([bi, bj, bk]);
                    let count = extent.iter().product::<usize>();
                    let first = [bi, bj, bk].map(|b| b * COEFF_BRICK);
                    let out = &mut scratch[..count];
                    let given = fill(first, extent, out).map_err(OwnedBricksError::Fill)?;
                    let brick = match given {
                        Some(v) => Brick::Uniform(v),
                        None => {
                            if store.dense >= max_dense {
                                return Err(OwnedBricksError::TooManyDense { max_dense });
                            }
                            store.dense += 1;
                            let mut dense = Box::new([0.0; DENSE_BRICK_VALUES]);
                            for (row, values) in out.chunks_exact(extent[0]).enumerate() {
                                let at = offset(0, row % extent[1], row / extent[1]);
                                dense[at..at + extent[0]].copy_from_slice(values);
                            }
                            Brick::Dense(dense)
                        }
                    };
                    store.put_brick([bi, bj, bk], brick);
                }
            }
        }
        // An apron is the neighbours' own values, which the pass below does not change: the
        // bricks it will make dense are known before it allocates any.
        let mut to_densify = 0_usize;
        for bk in 0..bz {
            for bj in 0..by {
                for bi in 0..bx {
                    let brick = [bi, bj, bk];
                    if let Brick::Uniform(v) = *store.brick(brick)
                        && !store.apron_holds_only(brick, v)
                    {
                        to_densify += 1;
                    }
                }
            }
        }
        if store.dense.saturating_add(to_densify) > max_dense {
            return Err(OwnedBricksError::TooManyDense { max_dense });
        }
        for bk in 0..bz {
            for bj in 0..by {
                for bi in 0..bx {
                    let refreshed = store.refresh_apron([bi, bj, bk], true);
                    debug_assert!(refreshed, "allowed to make bricks dense");
                }
            }
        }
        debug_assert!(store.dense <= max_dense, "counted before the pass");
        store.collapse_groups(store.groups_indexed());
        Ok(store)
    }

    /// Makes every brick dense, so that later writes never allocate.
    pub fn densify_all(&mut self) {
        let [bx, by, bz] = self.bricks_per_axis;
        for bk in 0..bz {
            for bj in 0..by {
                for bi in 0..bx {
                    self.dense_values_mut([bi, bj, bk]);
                }
            }
        }
    }

    /// Coefficients of brick `brick`'s own values that lie inside the store, per axis.
    fn owned_extent(&self, brick: [usize; 3]) -> [usize; 3] {
        std::array::from_fn(|a| (self.dims[a] - brick[a] * COEFF_BRICK).min(COEFF_BRICK))
    }

    /// Coefficients of brick `brick`'s own values and apron that lie inside the store, per
    /// axis.
    fn held_extent(&self, brick: [usize; 3]) -> [usize; 3] {
        std::array::from_fn(|a| (self.dims[a] - brick[a] * COEFF_BRICK).min(BRICK_SPAN))
    }

    /// The parts of brick `brick`'s apron inside the store, one per neighbour `brick + step`
    /// that owns one: the neighbour, `step`, and the in-brick ranges (of `brick`'s places) it
    /// owns. None when the brick has no apron inside the store.
    fn apron_parts(
        &self,
        brick: [usize; 3],
    ) -> impl Iterator<Item = ([usize; 3], [usize; 3], [(usize, usize); 3])> + Clone + use<> {
        let owned = self.owned_extent(brick);
        let held = self.held_extent(brick);
        (1..8_usize).filter_map(move |d| {
            let step = [d & 1, (d >> 1) & 1, d >> 2];
            let ranges: [(usize, usize); 3] = std::array::from_fn(|a| {
                if step[a] == 0 {
                    (0, owned[a])
                } else {
                    (COEFF_BRICK, held[a])
                }
            });
            let n: [usize; 3] = std::array::from_fn(|a| brick[a] + step[a]);
            (ranges.iter().all(|(lo, hi)| lo < hi)).then_some((n, step, ranges))
        })
    }

    /// Whether every value of brick `brick`'s apron inside the store (its neighbours' own
    /// values) is `v`, bit for bit: a uniform brick of `v` there needs no dense storage.
    /// Reads only.
    fn apron_holds_only(&self, brick: [usize; 3], v: f32) -> bool {
        let same = |w: &f32| w.to_bits() == v.to_bits();
        self.apron_parts(brick)
            .all(|(n, step, [x, y, z])| match self.brick(n) {
                Brick::Uniform(w) => same(w),
                Brick::Dense(values) => (z.0..z.1).all(|c| {
                    (y.0..y.1).all(|b| {
                        let from = apron_source(step, x.0, b, c);
                        values[from..from + x.1 - x.0].iter().all(same)
                    })
                }),
            })
    }

    /// Brings brick `brick`'s apron to the values its neighbours own: a dense brick copies
    /// them; a uniform one stays uniform when they all equal its value and becomes dense
    /// otherwise. The apron is copied row by row from each of the (up to seven) neighbours
    /// that own a part of it. Returns `false`, changing nothing, when a uniform brick would
    /// have to become dense and `may_densify` is `false`.
    fn refresh_apron(&mut self, brick: [usize; 3], may_densify: bool) -> bool {
        if let Brick::Uniform(v) = *self.brick(brick) {
            if self.apron_holds_only(brick, v) {
                return true;
            }
            if !may_densify {
                return false;
            }
        }
        let parts = self.apron_parts(brick);
        // Taken out of the directory while its neighbours are read.
        let mut target = std::mem::replace(self.brick_mut(brick), Brick::Uniform(0.0));
        let values = densify(&mut target, &mut self.dense);
        for (n, step, [x, y, z]) in parts {
            let len = x.1 - x.0;
            for c in z.0..z.1 {
                for b in y.0..y.1 {
                    let to = offset(x.0, b, c);
                    match self.brick(n) {
                        Brick::Uniform(w) => values[to..to + len].fill(*w),
                        Brick::Dense(from) => {
                            let from_at = apron_source(step, x.0, b, c);
                            copy_run(&mut values[to..to + len], &from[from_at..from_at + len]);
                        }
                    }
                }
            }
        }
        *self.brick_mut(brick) = target;
        true
    }

    /// This store with `low[a]` zero coefficients added before and `high[a]` after it along
    /// each axis `a`. When every `low[a]` is a whole number of bricks the groups and bricks
    /// move into the new directory as they are (the new groups' offset maps each old group
    /// whole onto a new one, so a group that is one value stays one entry, and only the
    /// groups at the old store's border move brick by brick) and the aprons are brought up
    /// to date; otherwise the values are copied row by row. The result is compacted.
    ///
    /// # Panics
    /// When the grown coefficient count overflows `usize`.
    #[must_use]
    pub fn padded(&self, low: [usize; 3], high: [usize; 3]) -> Self {
        let dims: [usize; 3] = std::array::from_fn(|a| self.dims[a] + low[a] + high[a]);
        if self.is_empty() || low.iter().any(|l| l % COEFF_BRICK != 0) {
            let mut grown = Self::zeros(dims);
            let mut row = vec![0.0; self.dims[0]];
            for k in 0..self.dims[2] {
                for j in 0..self.dims[1] {
                    self.read_row_at([0, j, k], &mut row);
                    grown.write_row_at([low[0], j + low[1], k + low[2]], &row);
                }
            }
            grown.compact();
            return grown;
        }
        let shift = low.map(|l| l / COEFF_BRICK);
        // Brick b moves to b + shift; with the offset (offset - shift) mod GROUP_SPAN its group
        // (b + offset) / GROUP_SPAN becomes group (b + offset) / GROUP_SPAN + moved.
        let group_offset: [usize; 3] = std::array::from_fn(|a| {
            (self.group_offset[a] + GROUP_SPAN - shift[a] % GROUP_SPAN) % GROUP_SPAN
        });
        let moved_groups: [usize; 3] = std::array::from_fn(|a| {
            (shift[a] + group_offset[a] - self.group_offset[a]) / GROUP_SPAN
        });
        let mut grown = Self::uniform_with_offset(dims, group_offset, 0.0);
        let [gx, gy, _] = grown.groups_per_axis;
        for (at, group) in self.groups_indexed() {
            let bricks = self.bricks_of_group(group);
            // A group all of whose bricks lie inside the old store and own all their
            // coefficients there moves as it is; its apron copies are refreshed below where
            // they meet the old border.
            let whole = (0..3).all(|a| {
                bricks[a].len() == GROUP_SPAN && bricks[a].end * COEFF_BRICK <= self.dims[a]
            });
            if whole {
                let to: [usize; 3] = std::array::from_fn(|a| group[a] + moved_groups[a]);
                grown.groups[to[0] + gx * (to[1] + gy * to[2])] = self.groups[at].clone();
                continue;
            }
            for bk in bricks[2].clone() {
                for bj in bricks[1].clone() {
                    for bi in bricks[0].clone() {
                        let from = [bi, bj, bk];
                        let to: [usize; 3] = std::array::from_fn(|a| from[a] + shift[a]);
                        let brick = self.brick(from);
                        let moved = if self.owned_extent(from) == grown.owned_extent(to) {
                            brick.clone()
                        } else {
                            // A partial brick at the old high border now owns new (zero)
                            // coefficients: keep only its values inside the old store.
                            let held = self.held_extent(from);
                            let mut kept = Box::new([0.0; DENSE_BRICK_VALUES]);
                            for c in 0..held[2] {
                                for b in 0..held[1] {
                                    let off = offset(0, b, c);
                                    let row = &mut kept[off..off + held[0]];
                                    match brick {
                                        Brick::Uniform(v) => row.fill(*v),
                                        Brick::Dense(values) => {
                                            row.copy_from_slice(&values[off..off + held[0]]);
                                        }
                                    }
                                }
                            }
                            Brick::Dense(kept)
                        };
                        grown.put_brick(to, moved);
                    }
                }
            }
        }
        // Only the aprons of bricks beside the old store's border can have changed: a
        // brick one below its low faces now has moved neighbours, and the last two
        // bricks along an axis now have new (zero) coefficients where their aprons reach
        // past the old store. Deeper inside, every neighbour moved with its brick; farther
        // out, every brick and neighbour is new and zero. On a far growth of a small clay
        // this is a few bricks of a directory of millions.
        let moved = self.bricks_per_axis;
        let reach: [std::ops::Range<usize>; 3] =
            std::array::from_fn(|a| shift[a].saturating_sub(1)..shift[a] + moved[a]);
        let on_border =
            |to: [usize; 3]| (0..3).any(|a| to[a] < shift[a] || to[a] + 2 >= shift[a] + moved[a]);
        for bk in reach[2].clone() {
            for bj in reach[1].clone() {
                for bi in reach[0].clone() {
                    if on_border([bi, bj, bk]) {
                        grown.refresh_apron([bi, bj, bk], true);
                    }
                }
            }
        }
        grown.dense = grown.walked_dense_count();
        grown.compact();
        grown
    }
}

/// The values of `brick`, made dense first if it was uniform (counted in `dense`).
#[inline]
fn densify<'a>(brick: &'a mut Brick, dense: &mut usize) -> &'a mut [f32; DENSE_BRICK_VALUES] {
    if let Brick::Uniform(v) = *brick {
        *brick = Brick::Dense(Box::new([v; DENSE_BRICK_VALUES]));
        *dense += 1;
    }
    match brick {
        Brick::Dense(values) => values,
        Brick::Uniform(_) => unreachable!("made dense above"),
    }
}

impl Index<usize> for BrickedCoeffs {
    type Output = f32;

    /// The coefficient at flat index `n`.
    #[inline]
    fn index(&self, n: usize) -> &f32 {
        assert!(
            n < self.len(),
            "index {n} outside {} coefficients",
            self.len()
        );
        let [i, j, k] = self.coords(n);
        self.at(i, j, k)
    }
}

impl PartialEq for BrickedCoeffs {
    /// Same dimensions and equal values (as `f32`s: a NaN equals nothing), whatever the
    /// bricks' representation.
    fn eq(&self, other: &Self) -> bool {
        self.dims == other.dims && self.iter().eq(other.iter())
    }
}

impl fmt::Debug for BrickedCoeffs {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("BrickedCoeffs")
            .field("dims", &self.dims)
            .field("dense_bricks", &self.dense_brick_count())
            .field("bricks", &self.brick_count())
            .field("groups", &self.group_counts())
            .field("values", &ShortList(self))
            .finish()
    }
}

/// The first values of a store, for debug output.
struct ShortList<'a>(&'a BrickedCoeffs);

impl fmt::Debug for ShortList<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        const SHOWN: usize = 32;
        let mut list = f.debug_list();
        list.entries(self.0.iter().take(SHOWN));
        if self.0.len() > SHOWN {
            list.entry(&format_args!("… {} more", self.0.len() - SHOWN));
        }
        list.finish()
    }
}

/// The part of a row the iterator is walking: values of a dense brick, or one value repeated.
enum Run<'a> {
    Slice(&'a [f32]),
    Repeat(&'a f32, usize),
}

/// Iterator over a store's values in flat order (see [`BrickedCoeffs::iter`]).
pub struct Values<'a> {
    store: &'a BrickedCoeffs,
    /// Coordinates of the first value after the current run.
    next: [usize; 3],
    run: Run<'a>,
}

impl<'a> Iterator for Values<'a> {
    type Item = &'a f32;

    #[inline]
    fn next(&mut self) -> Option<&'a f32> {
        loop {
            match &mut self.run {
                Run::Slice(values) => {
                    if let Some((first, rest)) = values.split_first() {
                        *values = rest;
                        return Some(first);
                    }
                }
                Run::Repeat(value, left) => {
                    if *left > 0 {
                        *left -= 1;
                        return Some(value);
                    }
                }
            }
            self.start_next_run()?;
        }
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        let [nx, ny, _] = self.store.dims;
        let [i, j, k] = self.next;
        let after = self.store.len().saturating_sub(i + nx * (j + ny * k));
        let here = match self.run {
            Run::Slice(values) => values.len(),
            Run::Repeat(_, left) => left,
        };
        (after + here, Some(after + here))
    }
}

impl ExactSizeIterator for Values<'_> {}

impl Values<'_> {
    /// Moves to the next run of values (the rest of a row within one brick); `None` at the end.
    #[inline]
    fn start_next_run(&mut self) -> Option<()> {
        let store = self.store;
        let [nx, ny, nz] = store.dims;
        let [i, j, k] = self.next;
        if k >= nz || nx == 0 || ny == 0 {
            return None;
        }
        let a = i & MASK;
        let run = (COEFF_BRICK - a).min(nx - i);
        self.run = match store.brick_of(i, j, k) {
            Brick::Uniform(v) => Run::Repeat(v, run),
            Brick::Dense(values) => Run::Slice(&values[offset(a, j & MASK, k & MASK)..][..run]),
        };
        self.next = if i + run < nx {
            [i + run, j, k]
        } else if j + 1 < ny {
            [0, j + 1, k]
        } else {
            [0, 0, k + 1]
        };
        Some(())
    }
}

impl<'a> IntoIterator for &'a BrickedCoeffs {
    type Item = &'a f32;
    type IntoIter = Values<'a>;

    fn into_iter(self) -> Values<'a> {
        self.iter()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small deterministic generator (xorshift), so the tests need no crate.
    struct Rng(u64);

    impl Rng {
        fn next(&mut self) -> u64 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            self.0
        }
        fn below(&mut self, n: usize) -> usize {
            (self.next() % n as u64) as usize
        }
        /// A value from a small set, so uniform runs and repeats happen.
        fn value(&mut self) -> f32 {
            [0.0, 1.0, 0.5, 0.25][self.below(4)]
        }
        /// A coordinate below `n`, most often within three of a brick's border.
        fn near_border(&mut self, n: usize) -> usize {
            if self.below(4) == 0 {
                return self.below(n);
            }
            let border = COEFF_BRICK * self.below(n.div_ceil(COEFF_BRICK) + 1);
            (border + self.below(2 * BRICK_APRON + 1))
                .saturating_sub(BRICK_APRON)
                .min(n - 1)
        }
    }

    /// A pool of spare storage that runs dry after a given number of each.
    struct Pool {
        bricks_left: usize,
        groups_left: usize,
        bricks_taken: usize,
        groups_taken: usize,
    }

    impl Pool {
        fn new(bricks: usize, groups: usize) -> Self {
            Self {
                bricks_left: bricks,
                groups_left: groups,
                bricks_taken: 0,
                groups_taken: 0,
            }
        }
    }

    impl SpareStorage for Pool {
        fn spare_brick(&mut self) -> Option<SpareBrick> {
            (self.bricks_left > 0).then(|| {
                self.bricks_left -= 1;
                self.bricks_taken += 1;
                SpareBrick::new()
            })
        }
        fn spare_group(&mut self) -> Option<SpareGroup> {
            (self.groups_left > 0).then(|| {
                self.groups_left -= 1;
                self.groups_taken += 1;
                SpareGroup::new()
            })
        }
    }

    /// The directory's own promises: the dense count is the dense bricks, no group that is
    /// one value holds a dense brick, and no brick past the store's end is dense.
    fn assert_directory_sound(store: &BrickedCoeffs) {
        assert_eq!(store.dense, store.walked_dense_count(), "dense count");
        let in_store: usize = store
            .groups_indexed()
            .map(|(at, group)| {
                let bricks = store.bricks_of_group(group);
                match &store.groups[at] {
                    Group::Uniform(brick) => {
                        assert!(
                            matches!(brick, Brick::Uniform(_)),
                            "a uniform group's brick"
                        );
                        0
                    }
                    Group::Bricks(_) => {
                        let mut dense = 0;
                        for bk in bricks[2].clone() {
                            for bj in bricks[1].clone() {
                                for bi in bricks[0].clone() {
                                    dense += usize::from(matches!(
                                        store.brick([bi, bj, bk]),
                                        Brick::Dense(_)
                                    ));
                                }
                            }
                        }
                        dense
                    }
                }
            })
            .sum();
        assert_eq!(
            in_store, store.dense,
            "every dense brick lies inside the store"
        );
        let groups: usize = store.groups_per_axis.iter().product();
        assert_eq!(store.groups.len(), groups);
        for a in 0..3 {
            assert!(store.group_offset[a] < GROUP_SPAN);
            let span = store.bricks_per_axis[a] + store.group_offset[a];
            assert!(
                store.bricks_per_axis[a] == 0
                    || store.groups_per_axis[a] == span.div_ceil(GROUP_SPAN)
            );
        }
    }

    fn assert_matches(store: &BrickedCoeffs, model: &[f32]) {
        assert_directory_sound(store);
        assert_eq!(store.len(), model.len());
        assert_eq!(store.to_vec(), model);
        assert!(store.iter().copied().eq(model.iter().copied()));
        assert_eq!(store.iter().len(), model.len());
        for (n, &m) in model.iter().enumerate() {
            assert_eq!(store[n].to_bits(), m.to_bits(), "at {n}");
        }
        assert_aprons_agree(store, model);
    }

    /// Every value every brick holds inside the store (own and apron) equals the model's
    /// value of that coefficient, and a uniform brick is uniform over all of them.
    fn assert_aprons_agree(store: &BrickedCoeffs, model: &[f32]) {
        let [nx, ny, _] = store.dims;
        let [bx, by, bz] = store.bricks_per_axis;
        for bk in 0..bz {
            for bj in 0..by {
                for bi in 0..bx {
                    let held = store.held_extent([bi, bj, bk]);
                    let brick = store.brick([bi, bj, bk]);
                    for c in 0..held[2] {
                        for b in 0..held[1] {
                            for a in 0..held[0] {
                                let [i, j, k] = [bi * 8 + a, bj * 8 + b, bk * 8 + c];
                                let want = model[i + nx * (j + ny * k)];
                                let got = match brick {
                                    Brick::Uniform(v) => *v,
                                    Brick::Dense(values) => values[offset(a, b, c)],
                                };
                                assert_eq!(
                                    got.to_bits(),
                                    want.to_bits(),
                                    "brick {:?} holds {got} at ({i}, {j}, {k}), owner {want}",
                                    [bi, bj, bk]
                                );
                            }
                        }
                    }
                }
            }
        }
    }

    /// Every stencil inside the store read through the bricks equals the model's.
    fn assert_stencils_match(store: &BrickedCoeffs, model: &[f32]) {
        let [nx, ny, nz] = store.dims;
        for k in 0..=nz - 4 {
            for j in 0..=ny - 4 {
                for i in 0..=nx - 4 {
                    let rows = store.stencil_rows([i, j, k]);
                    for (n, row) in rows.iter().enumerate() {
                        let (b, c) = (n & 3, n >> 2);
                        let start = i + nx * (j + b + ny * (k + c));
                        let want = Vec4::from_slice(&model[start..start + 4]);
                        assert_eq!(*row, want, "stencil at {:?} row {n}", [i, j, k]);
                        assert_eq!(store.row4(i, j + b, k + c), want);
                    }
                }
            }
        }
    }

    #[test]
    fn owned_bricks_rebuild_the_store_with_its_aprons_and_no_more_dense_bricks() {
        // Partial bricks at every high border, uniform regions of 0 and 1, a brick whose own
        // values are uniform but whose apron is not, and scattered values.
        let dims = [21, 12, 19];
        let mut rng = Rng(0x2545_f491_4f6c_dd1d);
        let mut model = vec![0.0_f32; dims.iter().product()];
        for (n, v) in model.iter_mut().enumerate() {
            let [i, _, k] = [n % 21, (n / 21) % 12, n / (21 * 12)];
            if k >= 8 && i < 16 {
                *v = 1.0;
            }
            if rng.below(40) == 0 {
                *v = rng.value();
            }
        }
        let mut store = BrickedCoeffs::from_slice(dims, &model);
        // A dense brick whose values are all equal again (an edit undone, not compacted).
        store.set(1, 1, 1, 0.75);
        store.set(1, 1, 1, model[1 + 21 * (1 + 12)]);
        let mut records = Vec::new();
        store.for_each_owned_brick(|b| {
            records.push(match b {
                OwnedBrick::Uniform(v) => Err(v),
                OwnedBrick::Values(values) => Ok(values.to_vec()),
            });
        });
        assert_eq!(records.len(), store.brick_count());
        assert!(records.iter().any(Result::is_ok) && records.iter().any(Result::is_err));
        let rebuild = |max_dense: usize| {
            let mut next = records.iter();
            BrickedCoeffs::try_from_owned_bricks(dims, max_dense, |first, extent, out| {
                assert_eq!(out.len(), extent.iter().product::<usize>());
                assert!((0..3).all(|a| first[a] % COEFF_BRICK == 0 && first[a] < dims[a]));
                match next.next().expect("one record per brick") {
                    Err(v) => Ok::<_, ()>(Some(*v)),
                    Ok(values) => {
                        out.copy_from_slice(values);
                        Ok(None)
                    }
                }
            })
        };
        let back = rebuild(usize::MAX).unwrap();
        assert_matches(&back, &model);
        assert_stencils_match(&back, &model);
        assert!(back.dense_brick_count() <= store.dense_brick_count());
        assert_eq!(back.dense_brick_count(), back.walked_dense_count());
        let mut compacted = store.clone();
        compacted.compact();
        assert_eq!(back.dense_brick_count(), compacted.dense_brick_count());
        // Exactly as many dense bricks as it needs are allowed; one fewer is refused.
        let needed = back.dense_brick_count();
        assert_eq!(rebuild(needed).unwrap(), back);
        assert_eq!(
            rebuild(needed - 1).unwrap_err(),
            OwnedBricksError::TooManyDense {
                max_dense: needed - 1
            }
        );
        // An error from the fill stops the build.
        let failed = BrickedCoeffs::try_from_owned_bricks(dims, usize::MAX, |first, _, _| {
            if first == [8, 0, 0] {
                Err("bad brick")
            } else {
                Ok(Some(0.0))
            }
        });
        assert_eq!(failed.unwrap_err(), OwnedBricksError::Fill("bad brick"));
    }

    #[test]
    fn uniform_bricks_that_differ_from_their_neighbours_count_against_the_dense_limit() {
        // Every brick uniform in the file, alternating values: each brick's apron reaches a
        // neighbour of the other value, so every brick that has one must become dense.
        let dims = [32, 8, 8];
        let build = |max_dense: usize| {
            BrickedCoeffs::try_from_owned_bricks(dims, max_dense, |first, _, _| {
                Ok::<_, ()>(Some(if first[0] % 16 == 0 { 0.0 } else { 1.0 }))
            })
        };
        let all = build(usize::MAX).unwrap();
        assert_eq!(all.dense_brick_count(), 3, "the last brick has no apron");
        assert_eq!(all.walked_dense_count(), 3);
        assert_eq!(
            build(2).unwrap_err(),
            OwnedBricksError::TooManyDense { max_dense: 2 }
        );
    }

    #[test]
    fn the_dense_count_follows_every_change_and_the_uniform_bound_holds() {
        let dims = [21, 17, 19];
        let mut rng = Rng(0x2545_f491_4f6c_dd1d);
        let mut store = BrickedCoeffs::zeros(dims);
        for _ in 0..40 {
            let min: [usize; 3] = std::array::from_fn(|a| rng.below(dims[a]));
            let size: [usize; 3] = std::array::from_fn(|a| 1 + rng.below(dims[a] - min[a]));
            let max: [usize; 3] = std::array::from_fn(|a| min[a] + size[a] - 1);
            let bound = store.uniform_bricks_holding(min, max);
            let dense_before = store.dense_brick_count();
            let value = if rng.below(3) == 0 { 0.0 } else { rng.value() };
            let values = vec![value; size.iter().product()];
            match rng.below(4) {
                0 => store.write_box(min, size, &values),
                1 => store.write_row_at(min, &values[..size[0]]),
                2 => store.set(min[0], min[1], min[2], value),
                _ => {
                    store.compact_within(min, max);
                }
            }
            assert_eq!(store.dense_brick_count(), store.walked_dense_count());
            assert!(
                store.dense_brick_count() <= dense_before + bound,
                "a write in {min:?}..={max:?} made more than {bound} bricks dense"
            );
        }
        assert!(store.dense_brick_count() > 0);
        let grown = store.padded([8, 0, 8], [3, 5, 0]);
        assert_eq!(grown.dense_brick_count(), grown.walked_dense_count());
        let shifted = store.padded([1, 2, 3], [0, 0, 0]);
        assert_eq!(shifted.dense_brick_count(), shifted.walked_dense_count());
        let mut all = store.clone();
        all.densify_all();
        assert_eq!(all.dense_brick_count(), all.brick_count());
        assert_eq!(all.uniform_bricks_holding([0; 3], dims.map(|n| n - 1)), 0);
        all.fill(0.5);
        assert_eq!(all.dense_brick_count(), 0);
        assert_eq!(
            all.uniform_bricks_holding([0; 3], dims.map(|n| n - 1)),
            all.brick_count()
        );
        // A box of one coefficient is held by its owner and the bricks whose aprons copy it.
        assert_eq!(all.uniform_bricks_holding([9, 9, 9], [9, 9, 9]), 8);
        assert_eq!(all.uniform_bricks_holding([12, 12, 12], [12, 12, 12]), 1);
        assert_eq!(all.uniform_bricks_holding([30, 0, 0], [31, 1, 1]), 0);
    }

    #[test]
    fn random_edits_read_back_as_a_plain_vector_does() {
        let dims = [13, 9, 17];
        let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
        let mut store = BrickedCoeffs::zeros(dims);
        let mut model = vec![0.0_f32; dims.iter().product()];
        for round in 0..20 {
            for _ in 0..200 {
                let n = rng.below(model.len());
                let v = rng.value();
                match rng.below(3) {
                    0 => store.add_flat(n, v - store[n]),
                    1 => store.set_flat(n, v),
                    _ => {
                        let [i, j, k] = store.coords(n);
                        store.set(i, j, k, v);
                    }
                }
                model[n] = v;
            }
            // A row written across bricks, and read back at another offset.
            let [i, j, k] = [rng.below(5), rng.below(dims[1]), rng.below(dims[2])];
            let len = 1 + rng.below(dims[0] - i);
            let row: Vec<f32> = (0..len).map(|_| rng.value()).collect();
            store.write_row_at([i, j, k], &row);
            let start = i + dims[0] * (j + dims[1] * k);
            model[start..start + len].copy_from_slice(&row);
            let mut back = vec![f32::NAN; len];
            store.read_row(start, &mut back);
            assert_eq!(back, row);
            if round % 3 == 0 {
                store.compact();
            }
            assert_matches(&store, &model);
        }
        store.update_each(|n, v| *v += n as f32);
        for (n, m) in model.iter_mut().enumerate() {
            *m += n as f32;
        }
        assert_matches(&store, &model);
        store.fill(0.75);
        assert_eq!(store.dense_brick_count(), 0);
        assert!(store.iter().all(|&v| v == 0.75));
    }

    #[test]
    fn writes_near_brick_borders_keep_every_apron_copy_equal_to_its_owner() {
        let dims = [21, 19, 18];
        let mut rng = Rng(0x2545_f491_4f6c_dd1d);
        let mut store = BrickedCoeffs::uniform(dims, 1.0);
        let mut model = vec![1.0_f32; dims.iter().product()];
        for round in 0..12 {
            for _ in 0..150 {
                let at = [0, 1, 2].map(|a| rng.near_border(dims[a]));
                let v = rng.value();
                store.set(at[0], at[1], at[2], v);
                model[at[0] + dims[0] * (at[1] + dims[1] * at[2])] = v;
            }
            // A row starting near a border, crossing one or more bricks.
            let [i, j, k] = [0, 1, 2].map(|a| rng.near_border(dims[a]));
            let len = 1 + rng.below(dims[0] - i);
            let row: Vec<f32> = (0..len).map(|_| rng.value()).collect();
            store.write_row_at([i, j, k], &row);
            let start = i + dims[0] * (j + dims[1] * k);
            model[start..start + len].copy_from_slice(&row);
            // A visit that changes values on some border layers only.
            let pick = rng.below(COEFF_BRICK);
            store.update_each(|n, v| {
                if n % COEFF_BRICK == pick && (n / 7) % 3 == 0 {
                    *v = 0.5 - *v;
                }
            });
            for (n, m) in model.iter_mut().enumerate() {
                if n % COEFF_BRICK == pick && (n / 7) % 3 == 0 {
                    *m = 0.5 - *m;
                }
            }
            if round % 2 == 1 {
                let box_min = [0, 1, 2].map(|a| rng.near_border(dims[a]));
                store.compact_within(box_min, box_min.map(|m| m + 9));
            }
            assert_matches(&store, &model);
        }
        assert_stencils_match(&store, &model);
    }

    /// Preparing a box write with spares makes dense exactly the bricks the write would, and
    /// changes no value; a pool that runs dry stops it, and a later call goes on from there.
    #[test]
    fn a_box_write_prepared_with_spares_makes_no_further_brick_dense() {
        let dims = [23, 18, 20];
        let mut rng = Rng(0x2545_f491_4f6c_dd1d);
        let mut store = BrickedCoeffs::uniform(dims, 1.0);
        for round in 0..30 {
            let min = [0, 1, 2].map(|a| rng.near_border(dims[a]));
            let size: [usize; 3] = std::array::from_fn(|a| 1 + rng.below(dims[a] - min[a]));
            // Some boxes repeat the value uniform bricks hold (no brick need change).
            let one = (round % 3 == 0).then_some(1.0);
            let values: Vec<f32> = (0..size.iter().product::<usize>())
                .map(|_| one.unwrap_or_else(|| rng.value()))
                .collect();
            let mut written_plainly = store.clone();
            written_plainly.write_box(min, size, &values);

            let before = store.clone();
            let mut taken = 0;
            // At most two spare bricks per call (and groups enough): the calls go on until
            // the box is ready.
            let mut calls = 0;
            loop {
                let mut pool = Pool::new(2, usize::MAX);
                let ready = store.densify_for_box(min, size, &values, &mut pool);
                taken += pool.bricks_taken;
                assert_eq!(store, before, "making bricks dense changes no value");
                calls += 1;
                if ready {
                    break;
                }
                assert_eq!(
                    pool.bricks_left, 0,
                    "a call stops only when the spares ran out"
                );
            }
            assert!(
                calls <= 1 + taken / 2,
                "every call but the last used its spares"
            );
            let dense_before_write = store.dense_brick_count();
            store.write_box(min, size, &values);
            assert_eq!(store, written_plainly);
            assert_eq!(
                store.dense_brick_count(),
                dense_before_write,
                "the prepared write made no brick dense"
            );
            assert_eq!(
                dense_before_write,
                written_plainly.dense_brick_count(),
                "the spares went exactly where a plain write allocates"
            );
            assert_eq!(taken, dense_before_write - before.dense_brick_count());
            if round % 4 == 3 {
                store.compact();
            }
        }
    }

    #[test]
    fn boxes_written_and_read_brick_by_brick_match_the_model() {
        let dims = [23, 18, 20];
        let mut rng = Rng(0x5851_f42d_4c95_7f2d);
        let mut store = BrickedCoeffs::uniform(dims, 0.0);
        let mut model = vec![0.0_f32; dims.iter().product()];
        for round in 0..40 {
            let min = [0, 1, 2].map(|a| rng.near_border(dims[a]));
            let size: [usize; 3] = std::array::from_fn(|a| 1 + rng.below(dims[a] - min[a]));
            // Some boxes of one value (uniform bricks keep it), most of mixed values.
            let one = (round % 4 == 0).then(|| rng.value());
            let values: Vec<f32> = (0..size.iter().product::<usize>())
                .map(|_| one.unwrap_or_else(|| rng.value()))
                .collect();
            store.write_box(min, size, &values);
            for (n, &v) in values.iter().enumerate() {
                let [x, y, z] = [
                    n % size[0],
                    (n / size[0]) % size[1],
                    n / (size[0] * size[1]),
                ];
                model[min[0] + x + dims[0] * (min[1] + y + dims[1] * (min[2] + z))] = v;
            }
            let mut back = vec![f32::NAN; values.len()];
            store.read_box(min, size, &mut back);
            assert_eq!(back, values);
            if round % 5 == 4 {
                store.compact();
            }
            assert_matches(&store, &model);
        }
        assert_stencils_match(&store, &model);
        // A box of the value a uniform store holds allocates nothing.
        let mut ones = BrickedCoeffs::uniform(dims, 1.0);
        ones.write_box([3, 4, 5], [10, 9, 8], &[1.0; 720]);
        assert_eq!(ones.dense_brick_count(), 0);
    }

    #[test]
    fn a_stencil_at_every_base_of_a_random_lattice_equals_the_dense_vectors() {
        for (seed, dims) in [(3_u64, [19, 18, 17]), (11, [12, 20, 9]), (29, [4, 4, 4])] {
            let mut rng = Rng(seed);
            // Mostly zeros and ones with a band of other values, as the clay holds.
            let model: Vec<f32> = (0..dims.iter().product::<usize>())
                .map(|n| {
                    let [i, j, k] = [
                        n % dims[0],
                        (n / dims[0]) % dims[1],
                        n / (dims[0] * dims[1]),
                    ];
                    let d = (i + j + k) as f32 - 16.0;
                    if d.abs() < 3.0 {
                        rng.next() as f32 / u64::MAX as f32
                    } else if d < 0.0 {
                        1.0
                    } else {
                        0.0
                    }
                })
                .collect();
            let store = BrickedCoeffs::from_slice(dims, &model);
            assert!(store.dense_brick_count() < store.brick_count() || dims == [4, 4, 4]);
            assert_matches(&store, &model);
            assert_stencils_match(&store, &model);
            // The same values written one by one into a uniform store.
            let mut written = BrickedCoeffs::uniform(dims, 1.0);
            for (n, &v) in model.iter().enumerate() {
                written.set_flat(n, v);
            }
            assert_eq!(written, store);
            assert_aprons_agree(&written, &model);
            assert_stencils_match(&written, &model);
        }
    }

    #[test]
    fn compacting_frees_bricks_whose_values_are_all_equal_and_keeps_the_values() {
        let dims = [20, 16, 9];
        let mut store = BrickedCoeffs::zeros(dims);
        assert_eq!(store.brick_count(), 3 * 2 * 2);
        assert_eq!(store.dense_brick_count(), 0);
        // Setting a value a uniform brick holds costs nothing; another value densifies.
        store.set(1, 1, 1, 0.0);
        assert_eq!(store.dense_brick_count(), 0);
        store.set(1, 1, 1, 1.0);
        assert_eq!(store.dense_brick_count(), 1, "no brick before the first");
        // (19, 15, 8) is owned by brick (2, 1, 1) and in the apron of brick (2, 1, 0) below.
        store.set(19, 15, 8, 2.0);
        assert_eq!(store.dense_brick_count(), 3);
        let before = store.to_vec();
        assert_eq!(store.compact(), 0);
        assert_eq!(store.to_vec(), before);
        // Back to zero: the first brick compacts; the bricks holding 2 stay.
        store.set(1, 1, 1, 0.0);
        assert_eq!(
            store.compact_within([11, 11, 3], [19, 15, 8]),
            0,
            "elsewhere"
        );
        assert_eq!(store.compact_within([0, 0, 0], [3, 3, 3]), 1);
        assert_eq!(store.dense_brick_count(), 2);
        // A brick whose values inside the store agree compacts, its unused room not
        // counting: the corner brick's 4×8×1 coefficients all 2.
        for j in 8..16 {
            store.write_row_at([16, j, 8], &[2.0; 4]);
        }
        store.compact();
        assert!(matches!(store.brick([2, 1, 1]), Brick::Uniform(v) if *v == 2.0));
        // Its copies in the aprons below keep those bricks dense until they agree too.
        assert!(matches!(store.brick([2, 1, 0]), Brick::Dense(_)));
        store.fill(2.0);
        store.set(0, 0, 0, 0.0);
        store.set(0, 0, 0, 2.0);
        assert_eq!(store.compact(), 1);
        assert_eq!(store.dense_brick_count(), 0);
        assert_eq!(store.get(19, 15, 8), 2.0);
        assert_eq!(
            store.heap_bytes(),
            size_of::<Group>(),
            "one group, one value"
        );
    }

    #[test]
    fn equality_is_by_value_whatever_the_representation() {
        let dims = [9, 10, 11];
        let uniform = BrickedCoeffs::uniform(dims, 0.5);
        let mut dense = uniform.clone();
        dense.densify_all();
        assert_eq!(dense.dense_brick_count(), dense.brick_count());
        assert_eq!(uniform, dense);
        dense.set_flat(100, 0.25);
        assert_ne!(uniform, dense);
        dense.set_flat(100, 0.5);
        assert_eq!(uniform, dense);
        assert_ne!(uniform, BrickedCoeffs::uniform([9, 11, 10], 0.5));
        let mut nan = uniform.clone();
        nan.set_flat(3, f32::NAN);
        assert_ne!(nan, nan.clone(), "a NaN equals nothing, as in a Vec<f32>");
    }

    #[test]
    fn iteration_and_rows_follow_the_flat_order() {
        let dims = [11, 5, 10];
        let values: Vec<f32> = (0..dims.iter().product::<usize>())
            .map(|n| n as f32)
            .collect();
        let store = BrickedCoeffs::from_slice(dims, &values);
        assert_matches(&store, &values);
        assert_eq!(store.get(3, 2, 7), values[3 + 11 * (2 + 5 * 7)]);
        for i in 0..=dims[0] - 4 {
            let row = store.row4(i, 4, 9);
            let start = i + 11 * (4 + 5 * 9);
            assert_eq!(row, Vec4::from_slice(&values[start..start + 4]));
        }
        let mut out = vec![1.0];
        store.extend_row_into(11 * 3 + 2, 6, &mut out);
        assert_eq!(out[1..], values[35..41]);
        // A uniform store's values come from its uniform bricks.
        let halves = BrickedCoeffs::uniform(dims, 0.5);
        assert_eq!(halves.row4(6, 0, 0), Vec4::splat(0.5));
        assert_eq!(halves.iter().filter(|&&v| v == 0.5).count(), halves.len());
    }

    #[test]
    fn the_visit_densifies_only_the_bricks_that_hold_what_it_changes() {
        let dims = [24, 8, 8];
        let mut store = BrickedCoeffs::uniform(dims, 1.0);
        let mut seen = Vec::new();
        store.update_each(|n, v| {
            seen.push(n);
            if n == 13 || n == 14 {
                *v = 0.5;
            }
        });
        assert_eq!(seen, (0..store.len()).collect::<Vec<_>>());
        assert_eq!(store.dense_brick_count(), 1, "13 and 14 lie in no apron");
        assert_eq!(store[13], 0.5);
        assert_eq!(store[14], 0.5);
        assert_eq!(store[12], 1.0);
        assert_eq!(store[15], 1.0);
        // A visit that writes the same value back changes nothing.
        store.update_each(|_, v| *v *= 1.0);
        assert_eq!(store.dense_brick_count(), 1);
        // A change in the first layers of a brick reaches the apron of the brick before.
        store.update_each(|n, v| {
            if n == 17 {
                *v = 0.25;
            }
        });
        assert_eq!(store.dense_brick_count(), 2);
        assert_eq!(store.row4(14, 0, 0), Vec4::new(0.5, 1.0, 1.0, 0.25));
    }

    #[test]
    fn padding_moves_whole_bricks_and_copies_unaligned_ones() {
        // Stores whose last brick along an axis owns fewer coefficients than an apron holds
        // (9, 17, 25: one), so the brick before it has an apron reaching past the store.
        for (dims, seed) in [([10, 9, 12], 7), ([17, 25, 11], 8)] {
            padding_keeps_values_and_stencils(dims, seed);
        }
    }

    fn padding_keeps_values_and_stencils(dims: [usize; 3], seed: u64) {
        let mut rng = Rng(seed);
        let mut store = BrickedCoeffs::uniform(dims, 1.0);
        for _ in 0..50 {
            let n = rng.below(store.len());
            store.set_flat(n, rng.value());
        }
        for (low, high) in [
            ([8, 0, 16], [8, 3, 0]),
            ([3, 1, 0], [0, 2, 5]),
            ([0; 3], [6; 3]),
            ([24, 16, 8], [30, 17, 1]),
            ([0, 8, 0], [2, 0, 9]),
        ] {
            let grown = store.padded(low, high);
            let gd = grown.dims();
            assert_eq!(gd, std::array::from_fn(|a| dims[a] + low[a] + high[a]));
            let mut model = vec![0.0; grown.len()];
            for k in 0..gd[2] {
                for j in 0..gd[1] {
                    for i in 0..gd[0] {
                        let src = [i, j, k];
                        let inside = (0..3).all(|a| src[a] >= low[a] && src[a] - low[a] < dims[a]);
                        if inside {
                            model[i + gd[0] * (j + gd[1] * k)] =
                                store.get(i - low[0], j - low[1], k - low[2]);
                        }
                    }
                }
            }
            assert_matches(&grown, &model);
            assert_stencils_match(&grown, &model);
            // Only bricks whose own values or apron meet the old values are dense: the new
            // room beyond that costs nothing.
            let meets = |b: usize, a: usize| {
                let first = b * COEFF_BRICK;
                first < low[a] + dims[a] && first + BRICK_SPAN > low[a]
            };
            let [bx, by, bz] = grown.bricks_per_axis();
            let meeting = (0..bx).filter(|&b| meets(b, 0)).count()
                * (0..by).filter(|&b| meets(b, 1)).count()
                * (0..bz).filter(|&b| meets(b, 2)).count();
            assert!(grown.dense_brick_count() <= meeting);
        }
    }

    #[test]
    #[should_panic(expected = "outside")]
    fn reading_past_the_end_panics() {
        let store = BrickedCoeffs::zeros([4, 4, 4]);
        let _ = store[64];
    }

    #[test]
    fn the_differing_box_brick_by_brick_is_the_plain_one() {
        let mut rng = Rng(0xd1ff_b0c5);
        for round in 0..40 {
            // Up to three groups per axis; every third store padded by whole bricks on the
            // low side, so that its groups are offset.
            let mut dims = [1 + rng.below(70), 1 + rng.below(70), 1 + rng.below(70)];
            let mut a = BrickedCoeffs::uniform(dims, rng.value());
            if round % 3 == 0 {
                a.set(0, 0, 0, 0.5);
                a = a.padded([8, 16, 24], [0; 3]);
                dims = a.dims();
            }
            for _ in 0..rng.below(100) {
                let at: [usize; 3] = std::array::from_fn(|n| rng.near_border(dims[n]));
                a.set(
                    at[0],
                    at[1],
                    at[2],
                    rng.value() + 0.001 * rng.below(1000) as f32,
                );
            }
            // The copy differs at a few places, some on a brick of its own (uniform against
            // uniform, dense against uniform), some where both are dense; every fifth not at
            // all; one round a whole uniform brick's value.
            let mut b = a.clone();
            if round % 5 != 0 {
                for _ in 0..1 + rng.below(4) {
                    let at: [usize; 3] = std::array::from_fn(|n| rng.below(dims[n]));
                    let v = b.get(at[0], at[1], at[2]) + 0.5;
                    b.set(at[0], at[1], at[2], v);
                }
            }
            if round == 7 {
                b.fill(0.25);
            }
            let mut want: Option<([usize; 3], [usize; 3])> = None;
            for k in 0..dims[2] {
                for j in 0..dims[1] {
                    for i in 0..dims[0] {
                        if a.get(i, j, k).to_bits() != b.get(i, j, k).to_bits() {
                            let at = [i, j, k];
                            want = Some(want.map_or((at, at), |(lo, hi)| {
                                (
                                    std::array::from_fn(|n| lo[n].min(at[n])),
                                    std::array::from_fn(|n| hi[n].max(at[n])),
                                )
                            }));
                        }
                    }
                }
            }
            assert_eq!(a.differing_box(&b), want, "round {round}: {dims:?}");
            assert_eq!(b.differing_box(&a), want, "round {round}: {dims:?}");
            assert_eq!(a.differing_box(&a), None);
            // The same values with the groups not offset: compared brick by brick.
            let unshifted = BrickedCoeffs::from_slice(dims, &b.to_vec());
            assert_eq!(a.differing_box(&unshifted), want, "round {round}: {dims:?}");
            assert_eq!(unshifted.differing_box(&b), None);
        }
    }

    /// [`BrickedCoeffs::box_summary`] the plain way, coefficient by coefficient.
    fn plain_box_summary(store: &BrickedCoeffs, first: [usize; 3], last: [usize; 3]) -> BoxSummary {
        let mut out = BoxSummary {
            min: f32::INFINITY,
            max: f32::NEG_INFINITY,
            max_step: 0.0,
        };
        for k in first[2]..=last[2] {
            for j in first[1]..=last[1] {
                for i in first[0]..=last[0] {
                    let v = store.get(i, j, k);
                    out.min = smaller(out.min, v);
                    out.max = larger(out.max, v);
                    for (axis, next) in [[i + 1, j, k], [i, j + 1, k], [i, j, k + 1]]
                        .into_iter()
                        .enumerate()
                    {
                        if next[axis] <= last[axis] {
                            let w = store.get(next[0], next[1], next[2]);
                            out.max_step = larger(out.max_step, (w - v).abs());
                        }
                    }
                }
            }
        }
        out
    }

    #[test]
    fn a_box_summary_brick_by_brick_is_the_plain_one() {
        let mut rng = Rng(0x5eed_b0c5);
        for _ in 0..40 {
            let dims = [1 + rng.below(30), 1 + rng.below(30), 1 + rng.below(30)];
            let mut store = BrickedCoeffs::uniform(dims, rng.value());
            // A few writes near brick borders, some of them of fractional values, so uniform
            // and dense bricks mix and steps cross the borders.
            for _ in 0..rng.below(200) {
                let at = [
                    rng.near_border(dims[0]),
                    rng.near_border(dims[1]),
                    rng.near_border(dims[2]),
                ];
                let v = rng.value() + 0.001 * rng.below(1000) as f32;
                store.set(at[0], at[1], at[2], v);
            }
            for _ in 0..20 {
                let a: [usize; 3] = std::array::from_fn(|n| rng.below(dims[n]));
                let b: [usize; 3] = std::array::from_fn(|n| rng.below(dims[n]));
                let first = std::array::from_fn(|n| a[n].min(b[n]));
                let last = std::array::from_fn(|n| a[n].max(b[n]));
                let want = plain_box_summary(&store, first, last);
                assert_eq!(
                    store.box_summary(first, last, true),
                    want,
                    "{first:?} ..= {last:?}"
                );
                let extremes = store.box_summary(first, last, false);
                assert_eq!(
                    (extremes.min, extremes.max, extremes.max_step),
                    (want.min, want.max, 0.0)
                );
            }
        }
    }

    /// A store over several groups, written at random (single values, rows, boxes, maps),
    /// compacted and padded now and then (whole bricks, so the groups' offset changes, and
    /// unaligned), against a plain vector: every value, apron and stencil the same, and the
    /// groups sound.
    #[test]
    fn a_grouped_store_under_random_writes_padding_and_compaction_is_the_flat_one() {
        let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
        let mut dims = [45, 38, 41];
        let mut store = BrickedCoeffs::uniform(dims, 1.0);
        let mut model = vec![1.0_f32; dims.iter().product()];
        for round in 0..24 {
            for _ in 0..40 {
                let at = [0, 1, 2].map(|a| rng.near_border(dims[a]));
                let v = rng.value();
                store.set(at[0], at[1], at[2], v);
                model[at[0] + dims[0] * (at[1] + dims[1] * at[2])] = v;
            }
            let min = [0, 1, 2].map(|a| rng.near_border(dims[a]));
            let size: [usize; 3] =
                std::array::from_fn(|a| 1 + rng.below((dims[a] - min[a]).min(20)));
            let fill = rng.value();
            let values: Vec<f32> = (0..size.iter().product::<usize>())
                .map(|_| if rng.below(3) == 0 { rng.value() } else { fill })
                .collect();
            store.write_box(min, size, &values);
            let mut n = 0;
            for k in min[2]..min[2] + size[2] {
                for j in min[1]..min[1] + size[1] {
                    for i in min[0]..min[0] + size[0] {
                        model[i + dims[0] * (j + dims[1] * k)] = values[n];
                        n += 1;
                    }
                }
            }
            let mut out = vec![0.0; values.len()];
            store.read_box(min, size, &mut out);
            assert_eq!(out, values);
            match round % 6 {
                1 => {
                    store.compact();
                }
                2 => {
                    let lo = [0, 1, 2].map(|a| rng.below(dims[a]));
                    store.compact_within(lo, lo.map(|l| l + 17));
                }
                3 => {
                    let changed = store.map_values(|v| if v == 0.5 { 0.75 } else { v });
                    let mut want = 0;
                    for m in &mut model {
                        if *m == 0.5 {
                            *m = 0.75;
                            want += 1;
                        }
                    }
                    assert_eq!(changed, want);
                }
                4 | 5 if dims.iter().product::<usize>() < 300_000 => {
                    // Whole bricks on the low side (0 to 3: every offset change), any number
                    // on the high side; an unaligned padding now and then.
                    let low: [usize; 3] = if round % 12 == 11 {
                        [3, 0, 5]
                    } else {
                        std::array::from_fn(|_| COEFF_BRICK * rng.below(4))
                    };
                    let high: [usize; 3] = std::array::from_fn(|_| rng.below(6));
                    let grown = store.padded(low, high);
                    let gd = grown.dims();
                    let mut grown_model = vec![0.0; grown.len()];
                    for k in 0..dims[2] {
                        for j in 0..dims[1] {
                            for i in 0..dims[0] {
                                grown_model
                                    [i + low[0] + gd[0] * (j + low[1] + gd[1] * (k + low[2]))] =
                                    model[i + dims[0] * (j + dims[1] * k)];
                            }
                        }
                    }
                    let mut compacted = grown.clone();
                    assert_eq!(compacted.compact(), 0, "a padded store comes compacted");
                    store = grown;
                    model = grown_model;
                    dims = gd;
                }
                _ => {}
            }
            assert_matches(&store, &model);
        }
        assert!(
            store.groups_per_axis.iter().product::<usize>() > 8,
            "the store spans several groups: {:?}",
            store.groups_per_axis
        );
        assert_stencils_match(&store, &model);
        // A clone is the same store, groups and all.
        let copy = store.clone();
        assert_matches(&copy, &model);
        assert_eq!(copy.group_counts(), store.group_counts());
        assert_eq!(copy.heap_bytes(), store.heap_bytes());
    }

    /// Padding by whole bricks moves the groups as they are: a far growth of a small clay
    /// holds entries only for the groups its old bricks fall in, and costs one entry per
    /// group of the new empty space.
    #[test]
    fn a_far_padding_costs_per_group_not_per_brick() {
        let dims = [40, 40, 40];
        let mut store = BrickedCoeffs::zeros(dims);
        for k in 10..30 {
            for j in 10..30 {
                store.write_row_at([10, j, k], &[1.0; 20]);
            }
        }
        // The block's inner brick holds only 1s: a padded store comes compacted, so compare
        // with the compacted one.
        assert_eq!(store.compact(), 1);
        let before = store.to_vec();
        let (_, expanded_before) = store.group_counts();
        // Three paddings of 3, 5 and 7 bricks per side: offsets 1, 0 and 1 in turn.
        let mut grown = store.clone();
        for bricks in [3, 5, 7] {
            let pad = [bricks * COEFF_BRICK; 3];
            grown = grown.padded(pad, pad);
            assert_directory_sound(&grown);
        }
        let shift = (3 + 5 + 7) * COEFF_BRICK;
        let gd = grown.dims();
        assert_eq!(gd, [40 + 2 * shift; 3]);
        for k in 0..dims[2] {
            for j in 0..dims[1] {
                let mut row = vec![0.0; dims[0]];
                grown.read_row_at([shift, j + shift, k + shift], &mut row);
                assert_eq!(row[..], before[dims[0] * (j + dims[1] * k)..][..dims[0]]);
            }
        }
        assert_eq!(grown.dense_brick_count(), store.dense_brick_count());
        let (groups, expanded) = grown.group_counts();
        assert_eq!(
            groups,
            (gd[0].div_ceil(COEFF_BRICK) + 1)
                .div_ceil(GROUP_SPAN)
                .pow(3)
        );
        // The old store's bricks span two groups per axis wherever they land.
        assert!(
            expanded <= expanded_before.max(1) * 8,
            "{expanded} groups with entries"
        );
        assert_eq!(
            grown.heap_bytes(),
            groups * size_of::<Group>()
                + expanded * SPARE_GROUP_BYTES
                + grown.dense_brick_count() * DENSE_BRICK_BYTES
        );
        // The grown store's directory is a small part of a flat one's.
        let directory = grown.heap_bytes() - grown.dense_brick_count() * DENSE_BRICK_BYTES;
        assert!(
            directory < grown.brick_count() * size_of::<Brick>() / 4,
            "{directory} bytes"
        );
    }

    /// A box write prepared from a pool whose groups run dry stops before the first brick
    /// in a uniform group, changes no value, and goes on once the pool holds groups again;
    /// the prepared write then gives no group entries and makes no brick dense.
    #[test]
    fn preparing_a_write_takes_group_entries_from_the_pool_and_waits_when_it_runs_dry() {
        let dims = [70, 40, 40];
        let store0 = BrickedCoeffs::zeros(dims);
        // A box across four groups of uniform zero bricks.
        let (min, size) = ([28, 28, 5], [10, 8, 3]);
        let values = vec![0.5; size.iter().product()];
        let mut plain = store0.clone();
        plain.write_box(min, size, &values);
        let mut store = store0.clone();
        let mut dry = Pool::new(usize::MAX, 0);
        assert!(!store.densify_for_box(min, size, &values, &mut dry));
        assert_eq!((dry.bricks_taken, dry.groups_taken), (0, 0));
        assert_eq!(store.group_counts(), store0.group_counts());
        let mut one_group = Pool::new(usize::MAX, 1);
        assert!(!store.densify_for_box(min, size, &values, &mut one_group));
        assert_eq!(one_group.groups_taken, 1);
        assert!(one_group.bricks_taken > 0);
        assert_eq!(store, store0, "no value changed");
        assert_directory_sound(&store);
        let mut no_bricks = Pool::new(0, usize::MAX);
        assert!(!store.densify_for_box(min, size, &values, &mut no_bricks));
        assert!(
            no_bricks.groups_taken >= 1,
            "a group is given entries before its brick"
        );
        let mut plenty = Pool::new(usize::MAX, usize::MAX);
        assert!(store.densify_for_box(min, size, &values, &mut plenty));
        assert_eq!(store, store0);
        let groups_before = store.group_counts();
        let dense_before = store.dense_brick_count();
        assert_eq!(dense_before, plain.dense_brick_count());
        assert_eq!(groups_before.1, plain.group_counts().1);
        assert_eq!(
            one_group.groups_taken + no_bricks.groups_taken + plenty.groups_taken,
            groups_before.1
        );
        store.write_box(min, size, &values);
        assert_eq!(store, plain);
        assert_eq!(
            store.group_counts(),
            groups_before,
            "no group given entries by the write"
        );
        assert_eq!(
            store.dense_brick_count(),
            dense_before,
            "no brick made dense by it"
        );
        assert_directory_sound(&store);
        // Compaction after the edit is undone frees the bricks and the groups' entries.
        store.write_box(min, size, &vec![0.0; values.len()]);
        store.compact();
        assert_eq!(store.group_counts(), store0.group_counts());
        assert_eq!(store.heap_bytes(), store0.heap_bytes());
    }
}
