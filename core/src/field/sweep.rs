//! The per-axis sweeps behind `A`, `Aᵀ` and `(AᵀA)⁻¹`: every pass works on blocks of
//! [`LANES`] independent lines at once, so the inner loops are fixed-width lane loops that
//! LLVM turns into SSE2 vectors, and the banded recurrence of the Cholesky solve advances eight
//! lines per step instead of one (a scalar recurrence is latency-bound).
//!
//! Along a strided axis (y, z) a block is `LANES` neighbouring columns of every row, read and
//! written with contiguous loads; along the contiguous x axis a block is `LANES` whole lines,
//! transposed into the block and back. A partial block at the end computes all lanes and
//! writes back only the valid ones, so each output value is produced by the same lane
//! operations whatever the blocking: results do not depend on how the work is split between
//! threads.
//!
//! Each call works on caller-chosen ranges (planes, columns, lines) and writes through an
//! [`Emit`], which is how two threads share one output array. Block buffers live on the stack
//! (axes up to 250 long) and are allocated only for longer axes.
//!
//! Where the CPU has AVX2 the sweeps run a second build of the same code ([`wide_lanes`]): a
//! block row is then one 256-bit register, the projections sweep two blocks side by side (so
//! the Gram solve's recurrence advances two independent chains), and the x passes transpose
//! in 8 × 8 AVX shuffle tiles. Every lane still runs the same operations in the same order, so
//! both builds and every blocking give bit-identical results.

use std::marker::PhantomData;
use std::ops::Range;

use super::band::{Band, SolvePlan, TriLu};

/// Lines swept together by one block.
pub const LANES: usize = 8;

/// One block row: the same position on [`LANES`] lines.
pub(crate) type Lanes = [f32; LANES];

/// Whether this CPU runs the 256-bit (AVX2) builds of the sweeps. A block row of [`LANES`]
/// values is then one register instead of two; the lane operations and their order are the
/// same (no fused multiply-add: Rust never contracts a multiply and an add), so the results are
/// bit-identical to the SSE2 build's. Detected once and cached by the standard library.
#[inline]
#[must_use]
pub(crate) fn wide_lanes() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Declares the `unsafe fn $name` with the docs given (its `# Safety` contract among them),
/// which runs `$portable` or, where [`wide_lanes`] says the CPU has AVX2, `$avx2_body` inside
/// `$avx2`: a twin built with `#[target_feature(enable = "avx2")]`, whose contract is
/// `$name`'s plus AVX2. Both bodies should be `#[inline(always)]`, so each build compiles
/// its own copy of the loops.
macro_rules! avx2_dispatch {
    (
        $(#[$meta:meta])*
        $vis:vis unsafe fn $name:ident($($arg:ident: $ty:ty),* $(,)?);
        portable: $portable:expr;
        $avx2:ident: $avx2_body:expr;
    ) => {
        $(#[$meta])*
        $vis unsafe fn $name($($arg: $ty),*) {
            #[cfg(target_arch = "x86_64")]
            if $crate::field::wide_lanes() {
                // SAFETY: the CPU has AVX2 (checked); the rest is the caller's contract.
                return unsafe { $avx2($($arg),*) };
            }
            // SAFETY: the caller's contract.
            unsafe { $portable($($arg),*) }
        }

        #[doc = concat!("[`", stringify!($name), "`] built for AVX2.")]
        ///
        /// # Safety
        #[doc = concat!("The CPU must have AVX2; otherwise as [`", stringify!($name), "`].")]
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = "avx2")]
        unsafe fn $avx2($($arg: $ty),*) {
            // SAFETY: the caller's contract.
            unsafe { $avx2_body($($arg),*) }
        }
    };
}
pub(crate) use avx2_dispatch;

/// Zero rows kept before and after the solve's rows so its recurrence needs no edge cases.
const PAD: usize = 3;

/// What one axis pass computes.
#[derive(Clone, Copy, Debug)]
pub(crate) enum AxisOp<'a> {
    /// `out = B in` (or `Bᵀ in`, with the transposed band).
    Apply(&'a Band),
    /// `out = (BᵀB)⁻¹ (scale · Bᵀ in)`: `band` is `Bᵀ`.
    Project {
        band: &'a Band,
        solve: &'a SolvePlan,
        scale: f32,
    },
    /// `out = (BᵀB)⁻¹ (scale · in)`.
    Solve { solve: &'a SolvePlan, scale: f32 },
    /// `out = B⁻¹ (scale · in)` for a square `B`: the same as `Project` then.
    Inverse { lu: &'a TriLu, scale: f32 },
}

impl AxisOp<'_> {
    pub(crate) fn rows_in(&self) -> usize {
        match self {
            Self::Apply(b) | Self::Project { band: b, .. } => b.inputs,
            Self::Solve { solve, .. } => solve.len(),
            Self::Inverse { lu, .. } => lu.len(),
        }
    }

    pub(crate) fn rows_out(&self) -> usize {
        match self {
            Self::Apply(b) | Self::Project { band: b, .. } => b.outputs,
            Self::Solve { solve, .. } => solve.len(),
            Self::Inverse { lu, .. } => lu.len(),
        }
    }
}

/// Where a sweep writes its output segments.
pub(crate) trait Emit {
    /// Write `vals` at flat offset `off` of the destination.
    ///
    /// # Safety
    /// No other thread may read or write `off..off + vals.len()` of the destination during
    /// the call.
    unsafe fn emit(&self, off: usize, vals: &[f32]);

    /// [`Emit::emit`] for a whole block row (the common case, worth a fixed-width path).
    ///
    /// # Safety
    /// As [`Emit::emit`].
    #[inline]
    unsafe fn emit_lanes(&self, off: usize, vals: &Lanes) {
        // SAFETY: forwarded contract.
        unsafe { self.emit(off, vals) };
    }
}

/// A mutable slice that several threads write disjoint parts of. It borrows the slice
/// exclusively for its lifetime, so nothing else can touch it meanwhile.
pub(crate) struct SharedOut<'a> {
    ptr: *mut f32,
    len: usize,
    _borrow: PhantomData<&'a mut [f32]>,
}

// SAFETY: a SharedOut is only a pointer to an exclusively borrowed slice; every access goes
// through an `unsafe fn` whose contract makes concurrent accesses disjoint.
unsafe impl Send for SharedOut<'_> {}
// SAFETY: as above.
unsafe impl Sync for SharedOut<'_> {}

impl<'a> SharedOut<'a> {
    /// Share `slice` for the lifetime of the borrow.
    pub(crate) fn new(slice: &'a mut [f32]) -> Self {
        Self {
            ptr: slice.as_mut_ptr(),
            len: slice.len(),
            _borrow: PhantomData,
        }
    }

    /// Length of the shared slice.
    pub(crate) fn len(&self) -> usize {
        self.len
    }

    /// The part `range` of the slice, as a slice of its own (offsets start at 0).
    ///
    /// # Panics
    /// When `range` is out of bounds.
    #[inline]
    pub(crate) fn sub(&self, range: Range<usize>) -> SharedOut<'_> {
        assert!(
            range.start <= range.end && range.end <= self.len,
            "range out of bounds"
        );
        SharedOut {
            // SAFETY: in bounds (checked above).
            ptr: unsafe { self.ptr.add(range.start) },
            len: range.len(),
            _borrow: PhantomData,
        }
    }

    /// Mutable access to `range`.
    ///
    /// # Safety
    /// No other thread may access `range` while the returned slice lives.
    ///
    /// # Panics
    /// When `range` is out of bounds.
    #[inline]
    #[allow(clippy::mut_from_ref)] // the contract above is what makes this sound
    pub(crate) unsafe fn slice_mut(&self, range: Range<usize>) -> &mut [f32] {
        assert!(
            range.start <= range.end && range.end <= self.len,
            "range out of bounds"
        );
        // SAFETY: in bounds (checked); exclusive by the caller's contract.
        unsafe { std::slice::from_raw_parts_mut(self.ptr.add(range.start), range.len()) }
    }

    /// Shared access to `range`.
    ///
    /// # Safety
    /// No other thread may write `range` while the returned slice lives.
    ///
    /// # Panics
    /// When `range` is out of bounds.
    #[inline]
    pub(crate) unsafe fn slice(&self, range: Range<usize>) -> &[f32] {
        assert!(
            range.start <= range.end && range.end <= self.len,
            "range out of bounds"
        );
        // SAFETY: in bounds (checked); no concurrent writer by the caller's contract.
        unsafe { std::slice::from_raw_parts(self.ptr.add(range.start), range.len()) }
    }
}

impl Emit for SharedOut<'_> {
    #[inline]
    unsafe fn emit(&self, off: usize, vals: &[f32]) {
        // SAFETY: forwarded contract.
        let dst = unsafe { self.slice_mut(off..off + vals.len()) };
        for (d, &v) in dst.iter_mut().zip(vals) {
            *d = v;
        }
    }

    #[inline]
    unsafe fn emit_lanes(&self, off: usize, vals: &Lanes) {
        // SAFETY: forwarded contract.
        let dst: &mut Lanes = unsafe { self.slice_mut(off..off + LANES) }
            .try_into()
            .expect("a block row");
        *dst = *vals;
    }
}

/// Lanes of the widest block row a sweep uses: [`WIDE_BLOCKS`] blocks side by side.
const MAX_WIDTH: usize = 2 * LANES;

/// Blocks the AVX2 build of a projection sweeps side by side. One block is one 256-bit
/// register there, and the Gram solve's recurrence (a multiply, a subtract and the scaling per
/// row) would leave the arithmetic units waiting on its latency; two independent blocks per
/// row halve that wait. (The SSE2 build already holds a block in two registers and gains
/// nothing from more: see `bench/RESULTS.md`.)
pub(crate) const WIDE_BLOCKS: usize = 2;

/// Block buffers for the sweeps of one thread, reused across calls (zeroed once): room for
/// block rows up to [`MAX_WIDTH`] lanes, viewed at the width a sweep uses.
pub(crate) struct Blocks<'a> {
    input: &'a mut [f32],
    mid: &'a mut [f32],
}

impl Blocks<'_> {
    /// Whether the buffers hold an axis of `rows` values in block rows of `W` lanes.
    fn fits<const W: usize>(&self, rows: usize) -> bool {
        self.input.len().min(self.mid.len()) / W >= rows + 2 * PAD
    }

    /// The buffers as block rows of `W` lanes.
    fn rows<const W: usize>(&mut self) -> (&mut [[f32; W]], &mut [[f32; W]]) {
        (self.input.as_chunks_mut().0, self.mid.as_chunks_mut().0)
    }
}

/// Run `f` with block buffers for axes up to `rows` long (on the stack up to 258, else
/// allocated).
pub(crate) fn with_blocks<R>(rows: usize, f: impl FnOnce(&mut Blocks<'_>) -> R) -> R {
    const TINY: usize = 24 * MAX_WIDTH;
    const SMALL: usize = 72 * MAX_WIDTH;
    const LARGE: usize = 264 * MAX_WIDTH;
    let len = (rows + 2 * PAD) * MAX_WIDTH;
    // Sized tiers: the buffers are zeroed once per call.
    if len <= TINY {
        let (mut a, mut b) = ([0.0; TINY], [0.0; TINY]);
        f(&mut Blocks {
            input: &mut a,
            mid: &mut b,
        })
    } else if len <= SMALL {
        let (mut a, mut b) = ([0.0; SMALL], [0.0; SMALL]);
        f(&mut Blocks {
            input: &mut a,
            mid: &mut b,
        })
    } else if len <= LARGE {
        let (mut a, mut b) = ([0.0; LARGE], [0.0; LARGE]);
        f(&mut Blocks {
            input: &mut a,
            mid: &mut b,
        })
    } else {
        // Axes this long are far beyond interactive sizes; allocating is acceptable there.
        f(&mut Blocks {
            input: &mut vec![0.0; len],
            mid: &mut vec![0.0; len],
        })
    }
}

/// `out[o] = Σ_t w[o][t] · input[start[o] + t]` with a compile-time tap count.
#[inline(always)]
fn gather_fixed<const T: usize, const W: usize>(
    band: &Band,
    input: &[[f32; W]],
    out: &mut [[f32; W]],
) {
    let weights = band.weights.chunks_exact(T);
    for ((dst, &s), w) in out.iter_mut().zip(&band.start).zip(weights) {
        let rows: &[[f32; W]; T] = input[s..s + T].try_into().expect("window in range");
        let mut acc = [0.0; W];
        for t in 0..T {
            for l in 0..W {
                acc[l] += w[t] * rows[t][l];
            }
        }
        *dst = acc;
    }
}

#[inline(always)]
fn gather_block<const W: usize>(band: &Band, input: &[[f32; W]], out: &mut [[f32; W]]) {
    let out = &mut out[..band.outputs];
    match band.taps {
        3 => gather_fixed::<3, W>(band, input, out),
        4 => gather_fixed::<4, W>(band, input, out),
        // `Bᵀ` with two mass points per knot span (the engine's regions).
        7 => gather_fixed::<7, W>(band, input, out),
        taps => {
            for ((dst, &s), w) in out
                .iter_mut()
                .zip(&band.start)
                .zip(band.weights.chunks_exact(taps))
            {
                let mut acc = [0.0; W];
                for (wt, row) in w.iter().zip(&input[s..s + taps]) {
                    for l in 0..W {
                        acc[l] += wt * row[l];
                    }
                }
                *dst = acc;
            }
        }
    }
}

/// `mid[PAD..PAD + n] = (BᵀB)⁻¹ (scale · Bᵀ input)` for block rows of `W` lanes: the
/// `Project` step of [`run_block`].
#[inline(always)]
fn project_block<'m, const W: usize>(
    band: &Band,
    solve: &SolvePlan,
    scale: f32,
    input: &[[f32; W]],
    mid: &'m mut [[f32; W]],
) -> &'m [[f32; W]] {
    let n = band.outputs;
    mid[..PAD].fill([0.0; W]);
    mid[PAD + n..n + 2 * PAD].fill([0.0; W]);
    gather_block(band, input, &mut mid[PAD..]);
    solve_block(solve, scale, mid);
    &mid[PAD..PAD + n]
}

/// `x[PAD..PAD + n] ← (L Lᵀ)⁻¹ (scale · x[PAD..PAD + n])`; the `PAD` rows on either side must
/// be zero (they stand for the missing neighbours at the ends).
#[inline(always)]
fn solve_block<const W: usize>(plan: &SolvePlan, scale: f32, x: &mut [[f32; W]]) {
    if scale == 1.0 {
        solve_block_scaled::<false, W>(plan, scale, x);
    } else {
        solve_block_scaled::<true, W>(plan, scale, x);
    }
}

#[inline(always)]
fn solve_block_scaled<const SCALED: bool, const W: usize>(
    plan: &SolvePlan,
    scale: f32,
    x: &mut [[f32; W]],
) {
    let n = plan.len();
    let x = &mut x[..n + 2 * PAD];
    // The last three rows solved are carried in registers (a store and reload per row would
    // put the store-forwarding latency on the recurrence), and the row just solved enters
    // last, so the critical path is one multiply, one subtract and the scaling.
    let (mut a0, mut a1, mut a2) = (x[0], x[1], x[2]);
    for (o, (l, &inv)) in plan.lower.iter().zip(&plan.inv_diag).enumerate() {
        let b = &mut x[o + PAD];
        let mut v = [0.0; W];
        for e in 0..W {
            let b = if SCALED { scale * b[e] } else { b[e] };
            v[e] = ((b - l[2] * a0[e]) - l[1] * a1[e] - l[0] * a2[e]) * inv;
        }
        *b = v;
        (a0, a1, a2) = (a1, a2, v);
    }
    let (mut c1, mut c2, mut c3) = (x[n + PAD], x[n + PAD + 1], x[n + PAD + 2]);
    for (o, (u, &inv)) in plan.upper.iter().zip(&plan.inv_diag).enumerate().rev() {
        let w = &mut x[o + PAD];
        let mut v = [0.0; W];
        for e in 0..W {
            v[e] = ((w[e] - u[2] * c3[e]) - u[1] * c2[e] - u[0] * c1[e]) * inv;
        }
        *w = v;
        (c1, c2, c3) = (v, c1, c2);
    }
}

/// `mid[PAD..PAD + n] = B⁻¹ (scale · input[..n])` by the tridiagonal `L U` sweeps; the row
/// before `PAD` must be zero.
#[inline(always)]
fn inverse_block(lu: &TriLu, scale: f32, input: &[Lanes], mid: &mut [Lanes]) {
    let n = lu.len();
    let mid = &mut mid[PAD - 1..PAD + n + 1];
    for (o, (b, &l)) in input[..n].iter().zip(&lu.lower).enumerate() {
        let w: &mut [Lanes; 2] = (&mut mid[o..o + 2]).try_into().expect("window in range");
        let mut v = [0.0; LANES];
        for e in 0..LANES {
            v[e] = scale * b[e] - l * w[0][e];
        }
        w[1] = v;
    }
    for (o, (&u, &inv)) in lu.upper.iter().zip(&lu.inv_diag).enumerate().rev() {
        let w: &mut [Lanes; 2] = (&mut mid[o + 1..o + 3])
            .try_into()
            .expect("window in range");
        let mut v = [0.0; LANES];
        for e in 0..LANES {
            v[e] = (w[0][e] - u * w[1][e]) * inv;
        }
        w[0] = v;
    }
}

/// Compute one block: `input` holds the op's input rows; returns the output rows (inside
/// `mid`).
#[inline(always)]
fn run_block<'m>(op: &AxisOp<'_>, input: &[Lanes], mid: &'m mut [Lanes]) -> &'m [Lanes] {
    match *op {
        AxisOp::Apply(band) => {
            gather_block(band, input, mid);
            &mid[..band.outputs]
        }
        AxisOp::Project { band, solve, scale } => project_block(band, solve, scale, input, mid),
        AxisOp::Inverse { lu, scale } => {
            let n = lu.len();
            mid[PAD - 1] = [0.0; LANES];
            mid[PAD + n] = [0.0; LANES];
            inverse_block(lu, scale, input, mid);
            &mid[PAD..PAD + n]
        }
        AxisOp::Solve { solve, scale } => {
            let n = solve.len();
            mid[..PAD].fill([0.0; LANES]);
            mid[PAD..PAD + n].copy_from_slice(&input[..n]);
            mid[PAD + n..n + 2 * PAD].fill([0.0; LANES]);
            solve_block(solve, scale, mid);
            &mid[PAD..PAD + n]
        }
    }
}

/// One pass along a strided axis. `src` has shape `[outer][rows_in][inner]` (inner fastest),
/// the output `[outer][rows_out][inner]`; only blocks `outer` and columns `cols` are done.
///
/// # Safety
/// `out` is written at every row of blocks `outer`, columns `cols`: while this runs, no other
/// thread may read or write those elements of `out` (threads splitting one pass must give
/// each a disjoint `outer × cols`), and `src` must not overlap them.
///
/// # Panics
/// When `src` is too short for the ranges.
pub(crate) unsafe fn sweep_strided(
    op: &AxisOp<'_>,
    src: &[f32],
    inner: usize,
    outer: Range<usize>,
    cols: Range<usize>,
    out: &impl Emit,
) {
    with_blocks(op.rows_in().max(op.rows_out()), |blocks| {
        // SAFETY: forwarded contract (the same `out`, `outer` and `cols`).
        unsafe { sweep_strided_with(blocks, op, src, inner, outer, cols, out) };
    });
}

avx2_dispatch! {
    /// [`sweep_strided`] with the caller's block buffers.
    ///
    /// # Safety
    /// As [`sweep_strided`].
    ///
    /// # Panics
    /// When `src` is too short for the ranges or the buffers too small for the axis.
    pub(crate) unsafe fn sweep_strided_with(
        blocks: &mut Blocks<'_>,
        op: &AxisOp<'_>,
        src: &[f32],
        inner: usize,
        outer: Range<usize>,
        cols: Range<usize>,
        out: &impl Emit,
    );
    portable: sweep_strided_body::<LANES>;
    sweep_strided_avx2: sweep_strided_body::<{ WIDE_BLOCKS * LANES }>;
}

/// The body of [`sweep_strided_with`], inlined into each build.
///
/// # Safety
/// As [`sweep_strided`].
#[inline(always)]
unsafe fn sweep_strided_body<const WIDE: usize>(
    blocks: &mut Blocks<'_>,
    op: &AxisOp<'_>,
    src: &[f32],
    inner: usize,
    outer: Range<usize>,
    cols: Range<usize>,
    out: &impl Emit,
) {
    let (ri, ro) = (op.rows_in(), op.rows_out());
    assert!(
        blocks.fits::<WIDE>(ri.max(ro)) && blocks.fits::<LANES>(ri.max(ro)),
        "block buffers too small"
    );
    if WIDE > LANES && inner >= WIDE && cols.len() >= WIDE {
        // `WIDE / LANES` blocks side by side (see [`WIDE_BLOCKS`]), read straight from the
        // source rows.
        let shape = (ri, ro, inner);
        match *op {
            AxisOp::Project { band, solve, scale } => {
                let (_, mid) = blocks.rows::<WIDE>();
                column_groups::<WIDE>(src, shape, outer, cols, |src, c, db| {
                    direct_project((band, solve, scale), src, inner, c, db, mid, out);
                });
                return;
            }
            AxisOp::Apply(band) => {
                column_groups::<WIDE>(src, shape, outer, cols, |src, c, db| match band.taps {
                    3 => direct_apply_fixed::<3, WIDE>(band, src, inner, c, db, 0, out),
                    4 => direct_apply_fixed::<4, WIDE>(band, src, inner, c, db, 0, out),
                    _ => {
                        // Other widths keep the narrow blocks.
                        let mut n = c;
                        while n < c + WIDE {
                            direct_apply(band, src, inner, n, db, 0, out);
                            n += LANES;
                        }
                    }
                });
                return;
            }
            _ => {}
        }
    }
    let (input, mid) = blocks.rows::<LANES>();
    {
        for b in outer {
            let (sb, db) = (b * ri * inner, b * ro * inner);
            if inner >= LANES {
                // Fast path: full-width blocks read straight from the source rows.
                let src = &src[sb..sb + ri * inner];
                let mut c = cols.start;
                while c < cols.end {
                    if cols.end - c >= 2 * LANES {
                        // Two blocks side by side: each row read is a whole cache line, which
                        // keeps long strides (the z pass) friendly to the prefetcher.
                        match *op {
                            AxisOp::Apply(band) if band.taps == 3 => {
                                direct_apply_fixed::<3, { 2 * LANES }>(
                                    band, src, inner, c, db, 0, out,
                                );
                                c += 2 * LANES;
                                continue;
                            }
                            AxisOp::Inverse { lu, scale } => {
                                // One buffer of rows twice as wide: the blocks
                                // hold room for them (see [`MAX_WIDTH`]).
                                let mid2 = mid.as_flattened_mut().as_chunks_mut().0;
                                direct_inverse::<{ 2 * LANES }>(
                                    lu, scale, src, inner, c, db, 0, mid2, out,
                                );
                                c += 2 * LANES;
                                continue;
                            }
                            _ => {}
                        }
                    }
                    let (start, skip) = if cols.end - c >= LANES {
                        (c, 0)
                    } else {
                        (cols.end - LANES, c + LANES - cols.end)
                    };
                    let start = start.min(inner - LANES);
                    match *op {
                        AxisOp::Apply(band) => {
                            direct_apply(band, src, inner, start, db, skip, out);
                        }
                        AxisOp::Inverse { lu, scale } => {
                            direct_inverse(lu, scale, src, inner, start, db, skip, mid, out);
                        }
                        _ => strided_block(
                            op,
                            src,
                            inner,
                            (0, db),
                            start,
                            LANES,
                            skip,
                            input,
                            mid,
                            out,
                        ),
                    }
                    c = start + LANES;
                }
                continue;
            }
            let mut c = cols.start;
            while c < cols.end {
                let left = cols.end - c;
                if left >= LANES || cols.len() < LANES {
                    let w = LANES.min(left);
                    strided_block(op, src, inner, (sb, db), c, w, 0, input, mid, out);
                    c += w;
                } else {
                    // A short tail: compute the last full block of the range (the source is
                    // not the destination) and emit only the lanes not emitted yet.
                    let start = cols.end - LANES;
                    strided_block(
                        op,
                        src,
                        inner,
                        (sb, db),
                        start,
                        LANES,
                        c - start,
                        input,
                        mid,
                        out,
                    );
                    c = cols.end;
                }
            }
        }
    }
}

#[inline(always)]
fn emit_row(out: &impl Emit, off: usize, row: &Lanes, skip: usize) {
    // SAFETY: the caller hands each (block, column) range to one thread.
    unsafe {
        if skip == 0 {
            out.emit_lanes(off, row);
        } else {
            out.emit(off + skip, &row[skip..]);
        }
    }
}

/// `f(block_src, c, db)` for each group of `W` columns `c..c + W` in `cols` of each block in
/// `outer`, where `block_src` is the block's source rows and `db` its destination offset
/// (`shape` is `(rows_in, rows_out, inner)`). The last group overlaps the one before it: the
/// source is not the destination, and every lane runs the same operations, so the rewritten
/// columns get the same values.
#[inline(always)]
fn column_groups<const W: usize>(
    src: &[f32],
    (ri, ro, inner): (usize, usize, usize),
    outer: Range<usize>,
    cols: Range<usize>,
    mut f: impl FnMut(&[f32], usize, usize),
) {
    for b in outer {
        let (sb, db) = (b * ri * inner, b * ro * inner);
        let src = &src[sb..sb + ri * inner];
        let mut c = cols.start;
        while c < cols.end {
            c = c.min(cols.end - W);
            f(src, c, db);
            c += W;
        }
    }
}

/// [`emit_row`] for a row of `W` lanes (a multiple of [`LANES`]), a block row at a time,
/// emitting lanes `skip..W`.
#[inline(always)]
fn emit_rows<const W: usize>(out: &impl Emit, off: usize, row: &[f32; W], skip: usize) {
    for (h, lanes) in row.as_chunks::<LANES>().0.iter().enumerate() {
        let skip = skip.saturating_sub(h * LANES).min(LANES);
        emit_row(out, off + h * LANES, lanes, skip);
    }
}

/// `Σ_t w[t] · src[(s + t) · inner..][..W]`: one output row of a band, its input rows read
/// at a stride of `inner` (a fixed tap count when `w` comes from an array).
#[inline(always)]
fn tap_sum<const W: usize>(w: &[f32], src: &[f32], s: usize, inner: usize) -> [f32; W] {
    let mut acc = [0.0; W];
    for (t, &wt) in w.iter().enumerate() {
        let row: &[f32; W] = src[(s + t) * inner..][..W].try_into().expect("W");
        for l in 0..W {
            acc[l] += wt * row[l];
        }
    }
    acc
}

/// `B` on columns `c..c + LANES` of one block, read straight from the source rows.
#[inline(always)]
fn direct_apply(
    band: &Band,
    src: &[f32],
    inner: usize,
    c: usize,
    db: usize,
    skip: usize,
    out: &impl Emit,
) {
    match band.taps {
        3 => direct_apply_fixed::<3, LANES>(band, src, inner, c, db, skip, out),
        4 => direct_apply_fixed::<4, LANES>(band, src, inner, c, db, skip, out),
        taps => {
            let src = &src[c..];
            for (o, (&s, w)) in band
                .start
                .iter()
                .zip(band.weights.chunks_exact(taps))
                .enumerate()
            {
                let acc: Lanes = tap_sum(w, src, s, inner);
                emit_row(out, db + o * inner + c, &acc, skip);
            }
        }
    }
}

/// `B` with `T` taps on columns `c..c + W` of one block (`W` a multiple of [`LANES`]), read
/// straight from the source rows, emitting lanes `skip..W` a block row at a time.
#[inline(always)]
#[allow(clippy::too_many_arguments)] // one block's coordinates
fn direct_apply_fixed<const T: usize, const W: usize>(
    band: &Band,
    src: &[f32],
    inner: usize,
    c: usize,
    db: usize,
    skip: usize,
    out: &impl Emit,
) {
    let src = &src[c..];
    for (o, (&s, w)) in band
        .start
        .iter()
        .zip(band.weights.chunks_exact(T))
        .enumerate()
    {
        let w: &[f32; T] = w.try_into().expect("T weights");
        let acc: [f32; W] = tap_sum(w, src, s, inner);
        emit_rows(out, db + o * inner + c, &acc, skip);
    }
}

/// `scale · B⁻¹` on columns `c..c + W` of one block (`W` a multiple of [`LANES`]), read
/// straight from the source rows, emitting lanes `skip..W`.
#[inline(always)]
#[allow(clippy::too_many_arguments)] // one block's coordinates and buffers
fn direct_inverse<const W: usize>(
    lu: &TriLu,
    scale: f32,
    src: &[f32],
    inner: usize,
    c: usize,
    db: usize,
    skip: usize,
    mid: &mut [[f32; W]],
    out: &impl Emit,
) {
    let n = lu.len();
    let mut prev = [0.0; W];
    for (o, (y, &l)) in mid[..n].iter_mut().zip(&lu.lower).enumerate() {
        let b: &[f32; W] = src[o * inner + c..][..W].try_into().expect("W");
        for e in 0..W {
            prev[e] = scale * b[e] - l * prev[e];
        }
        *y = prev;
    }
    let mut next = [0.0; W];
    for (o, ((y, &u), &inv)) in mid[..n]
        .iter()
        .zip(&lu.upper)
        .zip(&lu.inv_diag)
        .enumerate()
        .rev()
    {
        for e in 0..W {
            next[e] = (y[e] - u * next[e]) * inv;
        }
        emit_rows(out, db + o * inner + c, &next, skip);
    }
}

/// `scale · (BᵀB)⁻¹ Bᵀ` on columns `c..c + W` of one block, `Bᵀ` gathered straight from the
/// source rows into `mid` (the same sums in the same order as [`gather_block`]).
#[inline(always)]
#[allow(clippy::too_many_arguments)] // one block's coordinates and buffers
fn direct_project<const W: usize>(
    (band, solve, scale): (&Band, &SolvePlan, f32),
    src: &[f32],
    inner: usize,
    c: usize,
    db: usize,
    mid: &mut [[f32; W]],
    out: &impl Emit,
) {
    let n = band.outputs;
    mid[..PAD].fill([0.0; W]);
    mid[PAD + n..n + 2 * PAD].fill([0.0; W]);
    let src = &src[c..];
    let rows = &mut mid[PAD..PAD + n];
    match band.taps {
        3 => direct_gather_fixed::<3, W>(band, src, inner, rows),
        4 => direct_gather_fixed::<4, W>(band, src, inner, rows),
        7 => direct_gather_fixed::<7, W>(band, src, inner, rows),
        taps => {
            for ((dst, &s), w) in rows
                .iter_mut()
                .zip(&band.start)
                .zip(band.weights.chunks_exact(taps))
            {
                *dst = tap_sum(w, src, s, inner);
            }
        }
    }
    solve_block(solve, scale, mid);
    for (r, row) in mid[PAD..PAD + n].iter().enumerate() {
        emit_rows(out, db + r * inner + c, row, 0);
    }
}

/// [`gather_fixed`] with the input rows read at a stride of `inner` from `src`.
#[inline(always)]
fn direct_gather_fixed<const T: usize, const W: usize>(
    band: &Band,
    src: &[f32],
    inner: usize,
    out: &mut [[f32; W]],
) {
    for ((dst, &s), w) in out
        .iter_mut()
        .zip(&band.start)
        .zip(band.weights.chunks_exact(T))
    {
        let w: &[f32; T] = w.try_into().expect("T weights");
        *dst = tap_sum(w, src, s, inner);
    }
}

/// One block of a strided pass: columns `c..c + w` of block `(sb, db)` (source and
/// destination offsets), emitting lanes `skip..w`.
#[inline(always)]
#[allow(clippy::too_many_arguments)] // one block's coordinates and buffers
fn strided_block(
    op: &AxisOp<'_>,
    src: &[f32],
    inner: usize,
    (sb, db): (usize, usize),
    c: usize,
    w: usize,
    skip: usize,
    input: &mut [Lanes],
    mid: &mut [Lanes],
    out: &impl Emit,
) {
    let ri = op.rows_in();
    if w == LANES {
        for (r, row) in input[..ri].iter_mut().enumerate() {
            let s = sb + r * inner + c;
            *row = src[s..s + LANES].try_into().expect("a block row");
        }
    } else {
        for (r, row) in input[..ri].iter_mut().enumerate() {
            let s = sb + r * inner + c;
            for (d, &v) in row.iter_mut().zip(&src[s..s + w]) {
                *d = v;
            }
        }
    }
    let res = run_block(op, input, mid);
    for (r, row) in res.iter().enumerate() {
        let off = db + r * inner + c;
        // SAFETY: the caller hands each (block, column) range to one thread.
        unsafe {
            if w == LANES && skip == 0 {
                out.emit_lanes(off, row);
            } else {
                out.emit(off + skip, &row[skip..w]);
            }
        }
    }
}

/// One pass along the contiguous x axis: `src` holds lines of `rows_in` values, the output
/// lines of `rows_out`; only `lines` are done.
///
/// # Safety
/// `out` is written at lines `lines` (and, for a range shorter than a lane group at its end,
/// at most `LANES − 1` lines before it, rewritten with the same values): while this runs, no
/// other thread may read or write those lines of `out`, and `src` must not overlap them.
///
/// # Panics
/// When `src` is too short for the range.
pub(crate) unsafe fn sweep_x(
    op: &AxisOp<'_>,
    src: &[f32],
    lines: Range<usize>,
    out: &SharedOut<'_>,
) {
    with_blocks(op.rows_in().max(op.rows_out()), |blocks| {
        // SAFETY: forwarded contract (the same `out` and `lines`).
        unsafe { sweep_x_with(blocks, op, src, lines, out) };
    });
}

avx2_dispatch! {
    /// [`sweep_x`] with the caller's block buffers.
    ///
    /// # Safety
    /// As [`sweep_x`].
    ///
    /// # Panics
    /// When `src` is too short for the range or the buffers too small for the axis.
    pub(crate) unsafe fn sweep_x_with(
        blocks: &mut Blocks<'_>,
        op: &AxisOp<'_>,
        src: &[f32],
        lines: Range<usize>,
        out: &SharedOut<'_>,
    );
    portable: sweep_x_body::<LANES>;
    sweep_x_avx2: sweep_x_body::<{ WIDE_BLOCKS * LANES }>;
}

/// The body of [`sweep_x_with`], inlined into each build.
///
/// # Safety
/// As [`sweep_x`].
#[inline(always)]
unsafe fn sweep_x_body<const WIDE: usize>(
    blocks: &mut Blocks<'_>,
    op: &AxisOp<'_>,
    src: &[f32],
    lines: Range<usize>,
    out: &SharedOut<'_>,
) {
    let (ri, ro) = (op.rows_in(), op.rows_out());
    assert!(
        blocks.fits::<WIDE>(ri.max(ro)) && blocks.fits::<LANES>(ri.max(ro)),
        "block buffers too small"
    );
    let mut g = lines.start;
    if WIDE > LANES
        && lines.len() >= WIDE
        && matches!(op, AxisOp::Project { .. } | AxisOp::Apply(_))
    {
        // `WIDE / LANES` blocks side by side (see [`WIDE_BLOCKS`]), transposed with AVX
        // shuffles: only the AVX2 build sweeps wide blocks.
        assert!(wide_lanes(), "wide blocks need AVX2");
        let (input, mid) = blocks.rows::<WIDE>();
        while g < lines.end {
            // The last group overlaps the one before it: the source is not the destination,
            // and every lane runs the same operations, so the rewritten lines get the same
            // values.
            g = g.min(lines.end - WIDE);
            // SAFETY: the CPU has AVX2 (asserted above).
            unsafe { transpose_in_avx(&src[g * ri..(g + WIDE) * ri], ri, &mut input[..ri]) };
            let res: &[[f32; WIDE]] = match *op {
                AxisOp::Project { band, solve, scale } => {
                    project_block(band, solve, scale, input, mid)
                }
                AxisOp::Apply(band) => {
                    gather_block(band, input, mid);
                    &mid[..ro]
                }
                _ => unreachable!("matched above"),
            };
            // SAFETY: these lines are in `lines`, which the caller's contract gives to this
            // call alone.
            let dst = unsafe { out.slice_mut(g * ro..(g + WIDE) * ro) };
            // SAFETY: as above.
            unsafe { transpose_out_avx(res, ro, dst) };
            g += WIDE;
        }
        return;
    }
    let (input, mid) = blocks.rows::<LANES>();
    {
        while g < lines.end {
            if lines.end - g < LANES && lines.len() >= LANES {
                // A short tail: redo the last full group instead (the source is not the
                // destination, so rewriting lines with the same values is harmless).
                g = lines.end - LANES;
            }
            let count = LANES.min(lines.end - g);
            let group = &src[g * ri..(g + count) * ri];
            if count == LANES {
                transpose_in(group, ri, &mut input[..ri]);
            } else {
                for (l, s) in group.chunks_exact(ri).enumerate() {
                    for (row, &v) in input.iter_mut().zip(s) {
                        row[l] = v;
                    }
                }
            }
            let res = run_block(op, input, mid);
            // SAFETY: these lines are in (or, for a short tail, just before) `lines`, which the
            // caller's contract gives to this call alone.
            let dst = unsafe { out.slice_mut(g * ro..(g + count) * ro) };
            if count == LANES {
                transpose_out(res, ro, dst);
            } else {
                for (l, d) in dst.chunks_exact_mut(ro).enumerate() {
                    for (v, row) in d.iter_mut().zip(res) {
                        *v = row[l];
                    }
                }
            }
            g += count;
        }
    }
}

/// `block[r][l] = group[l · len + r]` for `W` lines (a multiple of 4) of `len` values, in 4 × 4 tiles
/// (which LLVM turns into register shuffles).
#[inline(always)]
fn transpose_in<const W: usize>(group: &[f32], len: usize, block: &mut [[f32; W]]) {
    let lines: [&[f32]; W] = std::array::from_fn(|l| &group[l * len..(l + 1) * len]);
    let full = len / 4 * 4;
    for r0 in (0..full).step_by(4) {
        let rows: &mut [[f32; W]; 4] = (&mut block[r0..r0 + 4]).try_into().expect("four rows");
        for h in 0..W / 4 {
            let a: [[f32; 4]; 4] =
                std::array::from_fn(|l| lines[4 * h + l][r0..r0 + 4].try_into().expect("four"));
            for (i, row) in rows.iter_mut().enumerate() {
                row[4 * h..4 * h + 4].copy_from_slice(&[a[0][i], a[1][i], a[2][i], a[3][i]]);
            }
        }
    }
    for (r, row) in block[full..len].iter_mut().enumerate() {
        for l in 0..W {
            row[l] = lines[l][full + r];
        }
    }
}

/// `group[l · len + r] = block[r][l]`: the inverse of [`transpose_in`].
#[inline(always)]
fn transpose_out<const W: usize>(block: &[[f32; W]], len: usize, group: &mut [f32]) {
    let mut lines: [&mut [f32]; W] = {
        let mut it = group.chunks_exact_mut(len);
        std::array::from_fn(|_| it.next().expect("W lines"))
    };
    let full = len / 4 * 4;
    for r0 in (0..full).step_by(4) {
        let rows: &[[f32; W]; 4] = block[r0..r0 + 4].try_into().expect("four rows");
        for h in 0..W / 4 {
            for i in 0..4 {
                let l = 4 * h + i;
                lines[l][r0..r0 + 4]
                    .copy_from_slice(&[rows[0][l], rows[1][l], rows[2][l], rows[3][l]]);
            }
        }
    }
    for (r, row) in block[full..len].iter().enumerate() {
        for (l, line) in lines.iter_mut().enumerate() {
            line[full + r] = row[l];
        }
    }
}

/// `block[r][l] = group[l · len + r]` for `W` lines (a multiple of 8) of `len` values, in
/// 8 × 8 tiles of AVX shuffles (rows short of a whole tile at the end are redone by a tile
/// that overlaps the one before it; below 8 rows, one value at a time).
///
/// # Safety
/// The CPU must have AVX.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn transpose_in_avx<const W: usize>(group: &[f32], len: usize, block: &mut [[f32; W]]) {
    assert!(W.is_multiple_of(8) && group.len() >= W * len && block.len() >= len);
    if len < 8 {
        for (r, row) in block[..len].iter_mut().enumerate() {
            for (l, v) in row.iter_mut().enumerate() {
                *v = group[l * len + r];
            }
        }
        return;
    }
    for h in 0..W / 8 {
        let mut r0 = 0;
        while r0 < len {
            let r = r0.min(len - 8);
            // SAFETY: line `8h + i` holds `len` values from `(8h + i) · len`, and `r + 8 <=
            // len`; block rows `r..r + 8` exist (`len <= block.len()`), lanes `8h..8h + 8`
            // inside `W`; the CPU has AVX by the caller's contract.
            unsafe {
                let p = group.as_ptr().add(8 * h * len + r);
                let rows = std::array::from_fn(|i| p.add(i * len));
                let t = transpose8(rows);
                for (i, v) in t.into_iter().enumerate() {
                    std::arch::x86_64::_mm256_storeu_ps(block[r + i].as_mut_ptr().add(8 * h), v);
                }
            }
            r0 += 8;
        }
    }
}

/// `group[l · len + r] = block[r][l]`: the inverse of [`transpose_in_avx`].
///
/// # Safety
/// The CPU must have AVX.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn transpose_out_avx<const W: usize>(block: &[[f32; W]], len: usize, group: &mut [f32]) {
    assert!(W.is_multiple_of(8) && group.len() >= W * len && block.len() >= len);
    if len < 8 {
        for (r, row) in block[..len].iter().enumerate() {
            for (l, &v) in row.iter().enumerate() {
                group[l * len + r] = v;
            }
        }
        return;
    }
    for h in 0..W / 8 {
        let mut r0 = 0;
        while r0 < len {
            let r = r0.min(len - 8);
            // SAFETY: as in `transpose_in_avx`, with the roles of the two sides swapped.
            unsafe {
                let rows = std::array::from_fn(|i| block[r + i].as_ptr().add(8 * h));
                let t = transpose8(rows);
                let p = group.as_mut_ptr().add(8 * h * len + r);
                for (i, v) in t.into_iter().enumerate() {
                    std::arch::x86_64::_mm256_storeu_ps(p.add(i * len), v);
                }
            }
            r0 += 8;
        }
    }
}

/// The 8 × 8 transpose of the eight rows of 8 values at `rows`.
///
/// # Safety
/// Each pointer must be valid for 8 reads; the CPU must have AVX.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn transpose8(rows: [*const f32; 8]) -> [std::arch::x86_64::__m256; 8] {
    use std::arch::x86_64::{
        _mm256_loadu_ps, _mm256_permute2f128_ps, _mm256_shuffle_ps, _mm256_unpackhi_ps,
        _mm256_unpacklo_ps,
    };
    // SAFETY: the caller's contract.
    unsafe {
        let r = rows.map(|p| _mm256_loadu_ps(p));
        let t0 = _mm256_unpacklo_ps(r[0], r[1]);
        let t1 = _mm256_unpackhi_ps(r[0], r[1]);
        let t2 = _mm256_unpacklo_ps(r[2], r[3]);
        let t3 = _mm256_unpackhi_ps(r[2], r[3]);
        let t4 = _mm256_unpacklo_ps(r[4], r[5]);
        let t5 = _mm256_unpackhi_ps(r[4], r[5]);
        let t6 = _mm256_unpacklo_ps(r[6], r[7]);
        let t7 = _mm256_unpackhi_ps(r[6], r[7]);
        let u0 = _mm256_shuffle_ps::<0x44>(t0, t2);
        let u1 = _mm256_shuffle_ps::<0xEE>(t0, t2);
        let u2 = _mm256_shuffle_ps::<0x44>(t1, t3);
        let u3 = _mm256_shuffle_ps::<0xEE>(t1, t3);
        let u4 = _mm256_shuffle_ps::<0x44>(t4, t6);
        let u5 = _mm256_shuffle_ps::<0xEE>(t4, t6);
        let u6 = _mm256_shuffle_ps::<0x44>(t5, t7);
        let u7 = _mm256_shuffle_ps::<0xEE>(t5, t7);
        [
            _mm256_permute2f128_ps::<0x20>(u0, u4),
            _mm256_permute2f128_ps::<0x20>(u1, u5),
            _mm256_permute2f128_ps::<0x20>(u2, u6),
            _mm256_permute2f128_ps::<0x20>(u3, u7),
            _mm256_permute2f128_ps::<0x31>(u0, u4),
            _mm256_permute2f128_ps::<0x31>(u1, u5),
            _mm256_permute2f128_ps::<0x31>(u2, u6),
            _mm256_permute2f128_ps::<0x31>(u3, u7),
        ]
    }
}

/// Without x86-64 no build sweeps wide blocks; this keeps the generic body compiling.
#[cfg(not(target_arch = "x86_64"))]
unsafe fn transpose_in_avx<const W: usize>(group: &[f32], len: usize, block: &mut [[f32; W]]) {
    transpose_in(group, len, block);
}

/// See [`transpose_in_avx`].
#[cfg(not(target_arch = "x86_64"))]
unsafe fn transpose_out_avx<const W: usize>(block: &[[f32; W]], len: usize, group: &mut [f32]) {
    transpose_out(block, len, group);
}

/// Split `0..len` into `parts` near-equal ranges (the `i`-th of them), cut on multiples of
/// `align` where possible.
#[must_use]
pub(crate) fn split_range(len: usize, parts: usize, i: usize, align: usize) -> Range<usize> {
    let parts = parts.max(1);
    let cut = |k: usize| {
        if k >= parts {
            return len;
        }
        let raw = len * k / parts;
        let aligned = (raw + align / 2) / align.max(1) * align.max(1);
        aligned.min(len)
    };
    cut(i)..cut(i + 1)
}

#[cfg(test)]
mod tests {
    use super::super::axis::AxisBasis;
    use super::super::kron::KroneckerBasis;
    use super::*;

    fn basis(n: usize, m: usize) -> KroneckerBasis {
        let du = (n - 1) as f64 / (m - 1) as f64;
        let axis = || AxisBasis::uniform(0.0, n, 0.0, du, m);
        KroneckerBasis::new([axis(), axis(), axis()]).unwrap()
    }

    fn pseudo(len: usize, seed: u32) -> Vec<f32> {
        (0..len)
            .map(|i| (((i as u32).wrapping_mul(2654435761) ^ seed) % 1000) as f32 / 500.0 - 1.0)
            .collect()
    }

    fn bits(v: &[f32]) -> Vec<u32> {
        v.iter().map(|x| x.to_bits()).collect()
    }

    /// The x pass over `lines` by the narrow body and by the dispatched build (the wide blocks
    /// and, where the CPU has it, AVX2), and by the wide body without AVX2.
    fn x_pass_all_ways(op: &AxisOp<'_>, src: &[f32], lines: Range<usize>, len: usize) {
        let rows = op.rows_in().max(op.rows_out());
        let mut outs = [vec![0.0; len], vec![0.0; len], vec![0.0; len]];
        with_blocks(rows, |b| {
            let [o0, o1, o2] = &mut outs;
            // SAFETY: one thread; the source is another buffer.
            unsafe {
                sweep_x_body::<LANES>(b, op, src, lines.clone(), &SharedOut::new(o0));
                sweep_x_with(b, op, src, lines.clone(), &SharedOut::new(o1));
                if wide_lanes() {
                    sweep_x_body::<{ 2 * LANES }>(b, op, src, lines.clone(), &SharedOut::new(o2));
                } else {
                    sweep_x_body::<LANES>(b, op, src, lines.clone(), &SharedOut::new(o2));
                }
            }
        });
        assert_eq!(bits(&outs[0]), bits(&outs[1]), "x pass, lines {lines:?}");
        assert_eq!(bits(&outs[0]), bits(&outs[2]), "x pass, lines {lines:?}");
    }

    /// The same for a strided pass over `cols` of every block.
    fn strided_all_ways(
        op: &AxisOp<'_>,
        src: &[f32],
        inner: usize,
        outer: usize,
        cols: Range<usize>,
    ) {
        let rows = op.rows_in().max(op.rows_out());
        let len = outer * op.rows_out() * inner;
        let mut outs = [vec![0.0; len], vec![0.0; len], vec![0.0; len]];
        with_blocks(rows, |b| {
            let [o0, o1, o2] = &mut outs;
            let c = cols.clone();
            // SAFETY: one thread; the source is another buffer.
            unsafe {
                sweep_strided_body::<LANES>(
                    b,
                    op,
                    src,
                    inner,
                    0..outer,
                    c.clone(),
                    &SharedOut::new(o0),
                );
                sweep_strided_with(b, op, src, inner, 0..outer, c.clone(), &SharedOut::new(o1));
                sweep_strided_body::<{ 2 * LANES }>(
                    b,
                    op,
                    src,
                    inner,
                    0..outer,
                    c,
                    &SharedOut::new(o2),
                );
            }
        });
        assert_eq!(
            bits(&outs[0]),
            bits(&outs[1]),
            "strided pass, inner {inner}, cols {cols:?}"
        );
        assert_eq!(
            bits(&outs[0]),
            bits(&outs[2]),
            "strided pass, inner {inner}, cols {cols:?}"
        );
    }

    #[test]
    fn wide_blocks_and_the_avx2_build_give_bit_identical_sweeps() {
        for (n, m) in [(16, 31), (11, 21), (5, 9), (8, 8), (20, 39)] {
            let k = basis(n, m);
            for op in [k.op_project(0, 1.0), k.op_project(2, 0.37), k.op_apply(0)] {
                let (ri, ro) = (op.rows_in(), op.rows_out());
                for count in [1, 7, 16, 31, 40, 97] {
                    let src = pseudo(count * ri, count as u32);
                    for lines in [0..count, count / 3..count, 0..count - count / 4] {
                        x_pass_all_ways(&op, &src, lines, count * ro);
                    }
                }
                for inner in [3, 8, 11, 16, 31, 47, 256] {
                    let outer = 2;
                    let src = pseudo(outer * ri * inner, inner as u32);
                    for cols in [0..inner, inner / 3..inner, 0..inner - inner / 4] {
                        if !cols.is_empty() {
                            strided_all_ways(&op, &src, inner, outer, cols);
                        }
                    }
                }
            }
        }
    }

    /// The sweeps' raw-pointer output (`SharedOut`) on sizes small enough for Miri
    /// (`cargo +nightly miri test -p dynaclay-core --lib miri_`): every body, narrow and
    /// wide, agrees on a few line counts and strides, with no access outside its buffer.
    #[test]
    fn miri_tiny_sweeps_agree_every_way() {
        let k = basis(5, 9);
        for op in [k.op_project(0, 1.0), k.op_apply(0)] {
            let (ri, ro) = (op.rows_in(), op.rows_out());
            for count in [1, 7] {
                let src = pseudo(count * ri, count as u32);
                x_pass_all_ways(&op, &src, 0..count, count * ro);
                x_pass_all_ways(&op, &src, count / 3..count, count * ro);
            }
            for inner in [3, 11] {
                let src = pseudo(2 * ri * inner, inner as u32);
                strided_all_ways(&op, &src, inner, 2, 0..inner);
                strided_all_ways(&op, &src, inner, 2, inner / 3..inner);
            }
        }
    }
}
