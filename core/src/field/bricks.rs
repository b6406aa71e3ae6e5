//! Sparse storage of a lattice's coefficients: a directory of 8×8×8 bricks, each either one
//! value for the whole brick (no heap) or 512 values on the heap.
//!
//! The clay's density is clamped to `[0, 1]`: far from the surface whole bricks hold 0 (empty
//! space) or 1 (deep inside), so only the bricks near the surface or inside a simulated region
//! cost memory, and the memory grows with the surface's area rather than the box's volume.
//!
//! Coefficient `(i, j, k)` of an `nx × ny × nz` store is also addressed by its flat index
//! `i + nx · (j + ny · k)` (x fastest), the order every iteration follows. Reads never
//! allocate. A write of a value a uniform brick already holds changes nothing; any other write
//! into a uniform brick makes it dense (one 2 KiB allocation), and [`BrickedCoeffs::compact`]
//! makes a dense brick whose values are all equal uniform again. A store made dense with
//! [`BrickedCoeffs::densify_all`] never allocates on writes (the haptic loop's copy).

use std::fmt;
use std::ops::{Index, IndexMut};

use glam::Vec4;

/// Coefficients per brick along each axis.
pub const COEFF_BRICK: usize = 8;
/// Coefficients in one brick.
pub const COEFF_BRICK_VALUES: usize = COEFF_BRICK * COEFF_BRICK * COEFF_BRICK;
/// Heap bytes of one dense brick.
pub const DENSE_BRICK_BYTES: usize = COEFF_BRICK_VALUES * size_of::<f32>();

const SHIFT: usize = 3;
const MASK: usize = COEFF_BRICK - 1;

/// One 8×8×8 brick: a single value for all of it, or every value (x fastest within the brick).
#[derive(Clone)]
enum Brick {
    Uniform(f32),
    Dense(Box<[f32; COEFF_BRICK_VALUES]>),
}

/// Offset of in-brick coordinates `(a, b, c)` (each below 8) within a dense brick.
#[inline]
fn offset(a: usize, b: usize, c: usize) -> usize {
    a | (b << SHIFT) | (c << (2 * SHIFT))
}

/// The coefficients of an `nx × ny × nz` lattice, stored in 8×8×8 bricks (see the module
/// documentation). Equality compares values, whatever the representation.
#[derive(Clone)]
pub struct BrickedCoeffs {
    dims: [usize; 3],
    /// Bricks per axis: `dims[a]` rounded up to whole bricks.
    bricks_per_axis: [usize; 3],
    /// Brick `(bi, bj, bk)` at `bi + bx · (bj + by · bk)`.
    bricks: Vec<Brick>,
}

impl BrickedCoeffs {
    /// A store of `dims` coefficients, all `value`; allocates only the directory.
    ///
    /// # Panics
    /// When the coefficient count overflows `usize`.
    #[must_use]
    pub fn uniform(dims: [usize; 3], value: f32) -> Self {
        dims.iter()
            .try_fold(1_usize, |acc, &n| acc.checked_mul(n))
            .expect("coefficient count overflows usize");
        let bricks_per_axis = dims.map(|n| n.div_ceil(COEFF_BRICK));
        let count = bricks_per_axis.iter().product();
        Self {
            dims,
            bricks_per_axis,
            bricks: vec![Brick::Uniform(value); count],
        }
    }

    /// A store of `dims` zero coefficients.
    #[must_use]
    pub fn zeros(dims: [usize; 3]) -> Self {
        Self::uniform(dims, 0.0)
    }

    /// A store holding `values` (x fastest); bricks whose values are all equal stay uniform.
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
                    let extent = store.brick_extent([bi, bj, bk]);
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
                    let at = bi + bx * (bj + by * bk);
                    store.bricks[at] = if same {
                        Brick::Uniform(first)
                    } else {
                        let mut dense = Box::new([0.0; COEFF_BRICK_VALUES]);
                        for c in 0..extent[2] {
                            for b in 0..extent[1] {
                                dense[offset(0, b, c)..][..extent[0]].copy_from_slice(row(b, c));
                            }
                        }
                        Brick::Dense(dense)
                    };
                }
            }
        }
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

    /// Number of bricks in the directory.
    #[must_use]
    pub fn brick_count(&self) -> usize {
        self.bricks.len()
    }

    /// Number of dense (heap-allocated) bricks.
    #[must_use]
    pub fn dense_brick_count(&self) -> usize {
        self.bricks
            .iter()
            .filter(|b| matches!(b, Brick::Dense(_)))
            .count()
    }

    /// Bytes this store holds on the heap: the directory and the dense bricks.
    #[must_use]
    pub fn heap_bytes(&self) -> usize {
        self.bricks.capacity() * size_of::<Brick>() + self.dense_brick_count() * DENSE_BRICK_BYTES
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
    fn brick_index(&self, i: usize, j: usize, k: usize) -> usize {
        let [bx, by, _] = self.bricks_per_axis;
        (i >> SHIFT) + bx * ((j >> SHIFT) + by * (k >> SHIFT))
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
        match &self.bricks[self.brick_index(i, j, k)] {
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

    /// A mutable reference to coefficient `(i, j, k)`; makes its brick dense if it was
    /// uniform.
    ///
    /// # Panics
    /// When `(i, j, k)` lies outside the store.
    #[inline]
    pub fn at_mut(&mut self, i: usize, j: usize, k: usize) -> &mut f32 {
        self.check(i, j, k);
        let b = self.brick_index(i, j, k);
        &mut densify(&mut self.bricks[b])[offset(i & MASK, j & MASK, k & MASK)]
    }

    /// Sets coefficient `(i, j, k)`; a uniform brick that already holds `value` stays uniform.
    ///
    /// # Panics
    /// When `(i, j, k)` lies outside the store.
    #[inline]
    pub fn set(&mut self, i: usize, j: usize, k: usize, value: f32) {
        self.check(i, j, k);
        let b = self.brick_index(i, j, k);
        match &mut self.bricks[b] {
            Brick::Uniform(v) if v.to_bits() == value.to_bits() => {}
            brick => densify(brick)[offset(i & MASK, j & MASK, k & MASK)] = value,
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

    /// Four consecutive coefficients along x from `(i, j, k)` (the row of a cubic stencil).
    ///
    /// # Panics
    /// When `i + 3`, `j` or `k` lies outside the store.
    #[inline]
    #[must_use]
    pub fn row4(&self, i: usize, j: usize, k: usize) -> Vec4 {
        self.check(i + 3, j, k);
        self.row4_inside(i, j, k)
    }

    /// Four consecutive coefficients along x from `(i, j, k)`; the caller checked the range.
    #[inline]
    fn row4_inside(&self, i: usize, j: usize, k: usize) -> Vec4 {
        let a = i & MASK;
        match &self.bricks[self.brick_index(i, j, k)] {
            Brick::Dense(values) if a <= COEFF_BRICK - 4 => {
                Vec4::from_slice(&values[offset(a, j & MASK, k & MASK)..][..4])
            }
            Brick::Uniform(v) if a <= COEFF_BRICK - 4 => Vec4::splat(*v),
            _ => {
                // The row crosses into the next brick along x.
                let next = &self.bricks[self.brick_index(i + COEFF_BRICK - a, j, k)];
                let (b, c) = (j & MASK, k & MASK);
                let here = &self.bricks[self.brick_index(i, j, k)];
                let mut row = [0.0; 4];
                for (t, r) in row.iter_mut().enumerate() {
                    let (brick, x) = if a + t < COEFF_BRICK {
                        (here, a + t)
                    } else {
                        (next, a + t - COEFF_BRICK)
                    };
                    *r = match brick {
                        Brick::Uniform(v) => *v,
                        Brick::Dense(values) => values[offset(x, b, c)],
                    };
                }
                Vec4::from_array(row)
            }
        }
    }

    /// The 4×4×4 coefficients from `(i, j, k)` (a cubic stencil) as 16 rows along x, row
    /// `b + 4c` holding `(i..i + 4, j + b, k + c)`. A stencil inside one brick is read
    /// straight from it.
    ///
    /// The caller keeps the stencil inside the store (checked in debug builds; outside it,
    /// the values read are wrong or a directory read panics).
    #[inline(always)]
    #[must_use]
    pub fn stencil_rows(&self, [i, j, k]: [usize; 3]) -> [Vec4; 16] {
        debug_assert!(
            i + 3 < self.dims[0] && j + 3 < self.dims[1] && k + 3 < self.dims[2],
            "stencil at ({i}, {j}, {k}) outside {:?}",
            self.dims
        );
        let (a, b, c) = (i & MASK, j & MASK, k & MASK);
        let [bx, by, _] = self.bricks_per_axis;
        let first = (i >> SHIFT) + bx * ((j >> SHIFT) + by * (k >> SHIFT));
        let reach = [a, b, c].map(|o| usize::from(o > COEFF_BRICK - 4));
        if reach == [0; 3] {
            // The whole stencil in one brick: one directory read.
            return match &self.bricks[first] {
                Brick::Uniform(v) => [Vec4::splat(*v); 16],
                Brick::Dense(values) => std::array::from_fn(|n| {
                    let off = a | ((b + (n & 3)) << SHIFT) | ((c + (n >> 2)) << (2 * SHIFT));
                    Vec4::from_slice(&values[off..off + 4])
                }),
            };
        }
        // NOTE: the directory is read once per brick the stencil meets (at most 2×2×2), not
        // once per row: each brick becomes a source, its dense values (offsets kept) or four
        // copies of its one value (offsets masked to 0), so a row is one masked 4-wide load
        // whatever the brick holds (`bench/core.rs` `value_and_gradient`).
        let mut splats = [[0.0_f32; 4]; 8];
        let mut dense: [Option<&[f32; COEFF_BRICK_VALUES]>; 8] = [None; 8];
        let mut masks = [0_usize; 8];
        for n in 0..8 {
            // A neighbour the stencil does not reach is read as the first brick again (no
            // branch on where the stencil lies).
            let (dx, dy, dz) = (n & reach[0], (n >> 1) & reach[1], (n >> 2) & reach[2]);
            match &self.bricks[first + dx + bx * (dy + by * dz)] {
                Brick::Uniform(v) => splats[n] = [*v; 4],
                Brick::Dense(values) => {
                    dense[n] = Some(values);
                    masks[n] = usize::MAX;
                }
            }
        }
        let sources: [&[f32]; 8] =
            std::array::from_fn(|n| dense[n].map_or(&splats[n][..], |values| &values[..]));
        let mut rows = [Vec4::ZERO; 16];
        for (n, row) in rows.iter_mut().enumerate() {
            let (y, z) = (b + (n & 3), c + (n >> 2));
            let brick_yz = 2 * (y >> SHIFT) + 4 * (z >> SHIFT);
            let off = ((y & MASK) << SHIFT) | ((z & MASK) << (2 * SHIFT));
            *row = if reach[0] == 0 {
                let m = masks[brick_yz];
                Vec4::from_slice(&sources[brick_yz][(a + off) & m..][..4])
            } else {
                Vec4::from_array(std::array::from_fn(|t| {
                    let x = a + t;
                    let src = brick_yz + (x >> SHIFT);
                    sources[src][((x & MASK) + off) & masks[src]]
                }))
            };
        }
        rows
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
            match &self.bricks[self.brick_index(x, j, k)] {
                Brick::Uniform(v) => here.fill(*v),
                Brick::Dense(values) => {
                    here.copy_from_slice(&values[offset(a, b, c)..][..run]);
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
            match &self.bricks[self.brick_index(x, j, k)] {
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

    /// Writes `values` along x from `(i, j, k)`. A uniform brick whose part of the run already
    /// holds its value stays uniform (no allocation); any other stays or becomes dense.
    ///
    /// # Panics
    /// When the run leaves the store.
    pub fn write_row_at(&mut self, [i, j, k]: [usize; 3], values: &[f32]) {
        if values.is_empty() {
            return;
        }
        self.check(i + values.len() - 1, j, k);
        let (b, c) = (j & MASK, k & MASK);
        let mut x = i;
        let mut rest = values;
        while !rest.is_empty() {
            let a = x & MASK;
            let run = (COEFF_BRICK - a).min(rest.len());
            let (here, after) = rest.split_at(run);
            let at = self.brick_index(x, j, k);
            let brick = &mut self.bricks[at];
            let keeps = match brick {
                Brick::Uniform(v) => here.iter().all(|h| h.to_bits() == v.to_bits()),
                Brick::Dense(_) => false,
            };
            if !keeps {
                densify(brick)[offset(a, b, c)..][..run].copy_from_slice(here);
            }
            rest = after;
            x += run;
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
    /// letting it change the value. A uniform brick becomes dense only when `f` changes one of
    /// its values (to other bits).
    pub fn update_each(&mut self, mut f: impl FnMut(usize, &mut f32)) {
        let [nx, ny, nz] = self.dims;
        for k in 0..nz {
            for j in 0..ny {
                let row = nx * (j + ny * k);
                let mut x = 0;
                while x < nx {
                    let a = x & MASK;
                    let run = (COEFF_BRICK - a).min(nx - x);
                    let at = self.brick_index(x, j, k);
                    let brick = &mut self.bricks[at];
                    let off = offset(a, j & MASK, k & MASK);
                    if let Brick::Uniform(v) = *brick {
                        // Visit copies until one changes; then go dense from there.
                        let mut changed_at = None;
                        for s in 0..run {
                            let mut value = v;
                            f(row + x + s, &mut value);
                            if value.to_bits() != v.to_bits() {
                                changed_at = Some((s, value));
                                break;
                            }
                        }
                        if let Some((s, value)) = changed_at {
                            let values = densify(brick);
                            values[off + s] = value;
                            for t in s + 1..run {
                                f(row + x + t, &mut values[off + t]);
                            }
                        }
                    } else if let Brick::Dense(values) = brick {
                        for (s, value) in values[off..off + run].iter_mut().enumerate() {
                            f(row + x + s, value);
                        }
                    }
                    x += run;
                }
            }
        }
    }

    /// Sets every coefficient to `value`; frees every dense brick.
    pub fn fill(&mut self, value: f32) {
        for b in &mut self.bricks {
            *b = Brick::Uniform(value);
        }
    }

    /// Makes every dense brick whose coefficients (within the store) all have the same bits
    /// uniform again, freeing its values; returns how many it freed.
    pub fn compact(&mut self) -> usize {
        if self.is_empty() {
            return 0;
        }
        self.compact_within([0; 3], self.dims.map(|n| n - 1))
    }

    /// [`BrickedCoeffs::compact`] for the bricks that hold a coefficient of the box
    /// `min..=max` (clipped to the store): where an edit settled.
    pub fn compact_within(&mut self, min: [usize; 3], max: [usize; 3]) -> usize {
        if self.is_empty() || (0..3).any(|a| min[a] > max[a] || min[a] >= self.dims[a]) {
            return 0;
        }
        let first = min.map(|m| m >> SHIFT);
        let last: [usize; 3] = std::array::from_fn(|a| max[a].min(self.dims[a] - 1) >> SHIFT);
        let [bx, by, _] = self.bricks_per_axis;
        let mut freed = 0;
        for bk in first[2]..=last[2] {
            for bj in first[1]..=last[1] {
                for bi in first[0]..=last[0] {
                    let extent = self.brick_extent([bi, bj, bk]);
                    let brick = &mut self.bricks[bi + bx * (bj + by * bk)];
                    let Brick::Dense(values) = brick else {
                        continue;
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
                        freed += 1;
                    }
                }
            }
        }
        freed
    }

    /// Makes every brick dense, so that later writes never allocate.
    pub fn densify_all(&mut self) {
        for b in &mut self.bricks {
            densify(b);
        }
    }

    /// Coefficients of brick `(bi, bj, bk)` that lie inside the store, per axis.
    fn brick_extent(&self, brick: [usize; 3]) -> [usize; 3] {
        std::array::from_fn(|a| (self.dims[a] - brick[a] * COEFF_BRICK).min(COEFF_BRICK))
    }

    /// This store with `low[a]` zero coefficients added before and `high[a]` after it along
    /// each axis `a`. When every `low[a]` is a whole number of bricks the bricks move into the
    /// new directory as they are (a uniform brick stays one value); otherwise the values are
    /// copied brick by brick, and the result is compacted.
    ///
    /// # Panics
    /// When the grown coefficient count overflows `usize`.
    #[must_use]
    pub fn padded(&self, low: [usize; 3], high: [usize; 3]) -> Self {
        let dims: [usize; 3] = std::array::from_fn(|a| self.dims[a] + low[a] + high[a]);
        let mut grown = Self::zeros(dims);
        if low.iter().all(|l| l % COEFF_BRICK == 0) {
            let shift = low.map(|l| l / COEFF_BRICK);
            let [bx, by, bz] = self.bricks_per_axis;
            for bk in 0..bz {
                for bj in 0..by {
                    for bi in 0..bx {
                        let from = [bi, bj, bk];
                        let extent = self.brick_extent(from);
                        let to = [bi + shift[0], bj + shift[1], bk + shift[2]];
                        let at = grown.brick_index(
                            to[0] * COEFF_BRICK,
                            to[1] * COEFF_BRICK,
                            to[2] * COEFF_BRICK,
                        );
                        let brick = &self.bricks[bi + bx * (bj + by * bk)];
                        if extent == grown.brick_extent(to) {
                            grown.bricks[at] = brick.clone();
                        } else {
                            // A partial brick at the old high border now has room for new
                            // (zero) coefficients: copy only its values.
                            let mut values = Box::new([0.0; COEFF_BRICK_VALUES]);
                            for c in 0..extent[2] {
                                for b in 0..extent[1] {
                                    for a in 0..extent[0] {
                                        values[offset(a, b, c)] = match brick {
                                            Brick::Uniform(v) => *v,
                                            Brick::Dense(d) => d[offset(a, b, c)],
                                        };
                                    }
                                }
                            }
                            grown.bricks[at] = Brick::Dense(values);
                        }
                    }
                }
            }
        } else {
            let mut row = vec![0.0; self.dims[0]];
            for k in 0..self.dims[2] {
                for j in 0..self.dims[1] {
                    self.read_row_at([0, j, k], &mut row);
                    grown.write_row_at([low[0], j + low[1], k + low[2]], &row);
                }
            }
        }
        grown.compact();
        grown
    }
}

/// The values of `brick`, made dense first if it was uniform.
#[inline]
fn densify(brick: &mut Brick) -> &mut [f32; COEFF_BRICK_VALUES] {
    if let Brick::Uniform(v) = *brick {
        *brick = Brick::Dense(Box::new([v; COEFF_BRICK_VALUES]));
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

impl IndexMut<usize> for BrickedCoeffs {
    /// The coefficient at flat index `n`; makes its brick dense if it was uniform.
    #[inline]
    fn index_mut(&mut self, n: usize) -> &mut f32 {
        assert!(
            n < self.len(),
            "index {n} outside {} coefficients",
            self.len()
        );
        let [i, j, k] = self.coords(n);
        self.at_mut(i, j, k)
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
            .field("bricks", &self.bricks.len())
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
        self.run = match &store.bricks[store.brick_index(i, j, k)] {
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
    }

    fn assert_matches(store: &BrickedCoeffs, model: &[f32]) {
        assert_eq!(store.len(), model.len());
        assert_eq!(store.to_vec(), model);
        assert!(store.iter().copied().eq(model.iter().copied()));
        assert_eq!(store.iter().len(), model.len());
        for (n, &m) in model.iter().enumerate() {
            assert_eq!(store[n].to_bits(), m.to_bits(), "at {n}");
        }
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
                    0 => store[n] = v,
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
    fn compacting_frees_bricks_whose_values_are_all_equal_and_keeps_the_values() {
        let dims = [20, 16, 9];
        let mut store = BrickedCoeffs::zeros(dims);
        assert_eq!(store.brick_count(), 3 * 2 * 2);
        assert_eq!(store.dense_brick_count(), 0);
        // Setting a value a uniform brick holds costs nothing; another value densifies.
        store.set(1, 1, 1, 0.0);
        assert_eq!(store.dense_brick_count(), 0);
        store.set(1, 1, 1, 1.0);
        store[19 + 20 * (15 + 16 * 8)] = 2.0;
        assert_eq!(store.dense_brick_count(), 2);
        let before = store.to_vec();
        assert_eq!(store.compact(), 0);
        assert_eq!(store.to_vec(), before);
        // Back to zero: the first brick compacts; the partial corner brick holds 2 still.
        store.set(1, 1, 1, 0.0);
        assert_eq!(store.compact_within([8, 8, 0], [19, 15, 8]), 0, "elsewhere");
        assert_eq!(store.compact_within([0, 0, 0], [3, 3, 3]), 1);
        assert_eq!(store.dense_brick_count(), 1);
        // A partial brick whose values inside the store agree compacts too (its unused
        // room does not count).
        for k in 8..9 {
            for j in 8..16 {
                store.write_row_at([16, j, k], &[2.0; 4]);
            }
        }
        assert_eq!(store.compact(), 1);
        assert_eq!(store.dense_brick_count(), 0);
        assert_eq!(store.get(19, 15, 8), 2.0);
        assert_eq!(store.get(0, 0, 0), 0.0);
        assert_eq!(store.heap_bytes(), store.brick_count() * size_of::<Brick>());
    }

    #[test]
    fn equality_is_by_value_whatever_the_representation() {
        let dims = [9, 10, 11];
        let uniform = BrickedCoeffs::uniform(dims, 0.5);
        let mut dense = uniform.clone();
        dense.densify_all();
        assert_eq!(dense.dense_brick_count(), dense.brick_count());
        assert_eq!(uniform, dense);
        dense[100] = 0.25;
        assert_ne!(uniform, dense);
        dense[100] = 0.5;
        assert_eq!(uniform, dense);
        assert_ne!(uniform, BrickedCoeffs::uniform([9, 11, 10], 0.5));
        let mut nan = uniform.clone();
        nan[3] = f32::NAN;
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
    fn stencils_read_the_same_rows_inside_one_brick_and_across_bricks() {
        let dims = [19, 18, 17];
        let values: Vec<f32> = (0..dims.iter().product::<usize>())
            .map(|n| ((n * 7919) % 61) as f32)
            .collect();
        let mut store = BrickedCoeffs::from_slice(dims, &values);
        // One brick uniform, so uniform and dense bricks meet in some stencils.
        for k in 8..16 {
            for j in 0..8 {
                store.write_row_at([8, j, k], &[3.0; 8]);
            }
        }
        store.compact();
        assert!(store.dense_brick_count() < store.brick_count());
        for k in 0..=dims[2] - 4 {
            for j in 0..=dims[1] - 4 {
                for i in 0..=dims[0] - 4 {
                    let rows = store.stencil_rows([i, j, k]);
                    for (n, row) in rows.iter().enumerate() {
                        let (b, c) = (n & 3, n >> 2);
                        let want = Vec4::from_array(std::array::from_fn(|t| {
                            store.get(i + t, j + b, k + c)
                        }));
                        assert_eq!(*row, want, "stencil at {:?} row {n}", [i, j, k]);
                    }
                }
            }
        }
    }

    #[test]
    fn the_visit_densifies_only_the_bricks_it_changes() {
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
        assert_eq!(store.dense_brick_count(), 1);
        assert_eq!(store[13], 0.5);
        assert_eq!(store[14], 0.5);
        assert_eq!(store[12], 1.0);
        assert_eq!(store[15], 1.0);
        // A visit that writes the same value back changes nothing.
        store.update_each(|_, v| *v *= 1.0);
        assert_eq!(store.dense_brick_count(), 1);
    }

    #[test]
    fn padding_moves_whole_bricks_and_copies_unaligned_ones() {
        let dims = [10, 9, 12];
        let mut rng = Rng(7);
        let mut store = BrickedCoeffs::uniform(dims, 1.0);
        for _ in 0..50 {
            let n = rng.below(store.len());
            store[n] = rng.value();
        }
        for (low, high) in [([8, 0, 16], [8, 3, 0]), ([3, 1, 0], [0, 2, 5])] {
            let grown = store.padded(low, high);
            let gd = grown.dims();
            assert_eq!(gd, std::array::from_fn(|a| dims[a] + low[a] + high[a]));
            for k in 0..gd[2] {
                for j in 0..gd[1] {
                    for i in 0..gd[0] {
                        let src = [i, j, k];
                        let inside = (0..3).all(|a| src[a] >= low[a] && src[a] - low[a] < dims[a]);
                        let want = if inside {
                            store.get(i - low[0], j - low[1], k - low[2])
                        } else {
                            0.0
                        };
                        assert_eq!(grown.get(i, j, k), want, "at {src:?} padded {low:?}");
                    }
                }
            }
            // Whole uniform bricks of ones survive as uniform; the new room costs nothing.
            assert!(grown.dense_brick_count() <= store.brick_count());
        }
    }

    #[test]
    #[should_panic(expected = "outside")]
    fn reading_past_the_end_panics() {
        let store = BrickedCoeffs::zeros([4, 4, 4]);
        let _ = store[64];
    }
}
