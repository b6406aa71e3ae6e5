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

use std::marker::PhantomData;
use std::ops::Range;

use super::band::{Band, SolvePlan, TriLu};

/// Lines swept together by one block.
pub const LANES: usize = 8;

/// One block row: the same position on [`LANES`] lines.
pub(crate) type Lanes = [f32; LANES];

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

/// Block buffers for the sweeps of one thread, reused across calls (zeroed once).
pub(crate) struct Blocks<'a> {
    input: &'a mut [Lanes],
    mid: &'a mut [Lanes],
}

impl Blocks<'_> {
    /// Whether the buffers hold an axis of `rows` values.
    fn fits(&self, rows: usize) -> bool {
        self.input.len().min(self.mid.len()) >= rows + 2 * PAD
    }
}

/// Run `f` with block buffers for axes up to `rows` long (on the stack up to 258, else
/// allocated).
pub(crate) fn with_blocks<R>(rows: usize, f: impl FnOnce(&mut Blocks<'_>) -> R) -> R {
    const TINY: usize = 24;
    const SMALL: usize = 72;
    const LARGE: usize = 264;
    let rows = rows + 2 * PAD;
    // Sized tiers: the buffers are zeroed once per call.
    if rows <= TINY {
        let (mut a, mut b) = ([[0.0; LANES]; TINY], [[0.0; LANES]; TINY]);
        f(&mut Blocks {
            input: &mut a,
            mid: &mut b,
        })
    } else if rows <= SMALL {
        let (mut a, mut b) = ([[0.0; LANES]; SMALL], [[0.0; LANES]; SMALL]);
        f(&mut Blocks {
            input: &mut a,
            mid: &mut b,
        })
    } else if rows <= LARGE {
        let (mut a, mut b) = ([[0.0; LANES]; LARGE], [[0.0; LANES]; LARGE]);
        f(&mut Blocks {
            input: &mut a,
            mid: &mut b,
        })
    } else {
        // Axes this long are far beyond interactive sizes; allocating is acceptable there.
        f(&mut Blocks {
            input: &mut vec![[0.0; LANES]; rows],
            mid: &mut vec![[0.0; LANES]; rows],
        })
    }
}

/// `out[o] = Σ_t w[o][t] · input[start[o] + t]` with a compile-time tap count.
#[inline(always)]
fn gather_fixed<const T: usize>(band: &Band, input: &[Lanes], out: &mut [Lanes]) {
    let weights = band.weights.chunks_exact(T);
    for ((dst, &s), w) in out.iter_mut().zip(&band.start).zip(weights) {
        let rows: &[Lanes; T] = input[s..s + T].try_into().expect("window in range");
        let mut acc = [0.0; LANES];
        for t in 0..T {
            for l in 0..LANES {
                acc[l] += w[t] * rows[t][l];
            }
        }
        *dst = acc;
    }
}

fn gather_block(band: &Band, input: &[Lanes], out: &mut [Lanes]) {
    let out = &mut out[..band.outputs];
    match band.taps {
        3 => gather_fixed::<3>(band, input, out),
        4 => gather_fixed::<4>(band, input, out),
        // `Bᵀ` with two mass points per knot span (the engine's regions).
        7 => gather_fixed::<7>(band, input, out),
        taps => {
            for ((dst, &s), w) in out
                .iter_mut()
                .zip(&band.start)
                .zip(band.weights.chunks_exact(taps))
            {
                let mut acc = [0.0; LANES];
                for (wt, row) in w.iter().zip(&input[s..s + taps]) {
                    for l in 0..LANES {
                        acc[l] += wt * row[l];
                    }
                }
                *dst = acc;
            }
        }
    }
}

/// `x[PAD..PAD + n] ← (L Lᵀ)⁻¹ (scale · x[PAD..PAD + n])`; the `PAD` rows on either side must
/// be zero (they stand for the missing neighbours at the ends).
fn solve_block(plan: &SolvePlan, scale: f32, x: &mut [Lanes]) {
    if scale == 1.0 {
        solve_block_scaled::<false>(plan, scale, x);
    } else {
        solve_block_scaled::<true>(plan, scale, x);
    }
}

#[inline(always)]
fn solve_block_scaled<const SCALED: bool>(plan: &SolvePlan, scale: f32, x: &mut [Lanes]) {
    let n = plan.len();
    let x = &mut x[..n + 2 * PAD];
    // The last three rows solved are carried in registers (a store and reload per row would
    // put the store-forwarding latency on the recurrence), and the row just solved enters
    // last, so the critical path is one multiply, one subtract and the scaling.
    let (mut a0, mut a1, mut a2) = (x[0], x[1], x[2]);
    for (o, (l, &inv)) in plan.lower.iter().zip(&plan.inv_diag).enumerate() {
        let b = &mut x[o + PAD];
        let mut v = [0.0; LANES];
        for e in 0..LANES {
            let b = if SCALED { scale * b[e] } else { b[e] };
            v[e] = ((b - l[2] * a0[e]) - l[1] * a1[e] - l[0] * a2[e]) * inv;
        }
        *b = v;
        (a0, a1, a2) = (a1, a2, v);
    }
    let (mut c1, mut c2, mut c3) = (x[n + PAD], x[n + PAD + 1], x[n + PAD + 2]);
    for (o, (u, &inv)) in plan.upper.iter().zip(&plan.inv_diag).enumerate().rev() {
        let w = &mut x[o + PAD];
        let mut v = [0.0; LANES];
        for e in 0..LANES {
            v[e] = ((w[e] - u[2] * c3[e]) - u[1] * c2[e] - u[0] * c1[e]) * inv;
        }
        *w = v;
        (c1, c2, c3) = (v, c1, c2);
    }
}

/// `mid[PAD..PAD + n] = B⁻¹ (scale · input[..n])` by the tridiagonal `L U` sweeps; the row
/// before `PAD` must be zero.
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
fn run_block<'m>(op: &AxisOp<'_>, input: &[Lanes], mid: &'m mut [Lanes]) -> &'m [Lanes] {
    match *op {
        AxisOp::Apply(band) => {
            gather_block(band, input, mid);
            &mid[..band.outputs]
        }
        AxisOp::Project { band, solve, scale } => {
            let n = band.outputs;
            mid[..PAD].fill([0.0; LANES]);
            mid[PAD + n..n + 2 * PAD].fill([0.0; LANES]);
            gather_block(band, input, &mut mid[PAD..]);
            solve_block(solve, scale, mid);
            &mid[PAD..PAD + n]
        }
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
) {
    let (ri, ro) = (op.rows_in(), op.rows_out());
    assert!(blocks.fits(ri.max(ro)), "block buffers too small");
    let (input, mid) = (&mut *blocks.input, &mut *blocks.mid);
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
                                direct_apply_wide::<3>(band, src, inner, c, db, out);
                                c += 2 * LANES;
                                continue;
                            }
                            AxisOp::Inverse { lu, scale } => {
                                direct_inverse_wide(
                                    lu,
                                    scale,
                                    src,
                                    inner,
                                    c,
                                    db,
                                    [mid, input],
                                    out,
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
fn row_at(src: &[f32], off: usize) -> &Lanes {
    src[off..off + LANES].try_into().expect("a block row")
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
        3 => direct_apply_fixed::<3>(band, src, inner, c, db, skip, out),
        4 => direct_apply_fixed::<4>(band, src, inner, c, db, skip, out),
        taps => {
            for (o, (&s, w)) in band
                .start
                .iter()
                .zip(band.weights.chunks_exact(taps))
                .enumerate()
            {
                let mut acc = [0.0; LANES];
                for (t, &wt) in w.iter().enumerate() {
                    let row = row_at(src, (s + t) * inner + c);
                    for l in 0..LANES {
                        acc[l] += wt * row[l];
                    }
                }
                emit_row(out, db + o * inner + c, &acc, skip);
            }
        }
    }
}

#[inline(always)]
fn direct_apply_fixed<const T: usize>(
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
        let mut acc = [0.0; LANES];
        for (t, &wt) in w.iter().enumerate() {
            let row = row_at(src, (s + t) * inner);
            for l in 0..LANES {
                acc[l] += wt * row[l];
            }
        }
        emit_row(out, db + o * inner + c, &acc, skip);
    }
}

/// [`direct_apply_fixed`] on two neighbouring blocks (columns `c..c + 2 · LANES`).
#[inline(always)]
fn direct_apply_wide<const T: usize>(
    band: &Band,
    src: &[f32],
    inner: usize,
    c: usize,
    db: usize,
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
        let (mut a0, mut a1) = ([0.0; LANES], [0.0; LANES]);
        for (t, &wt) in w.iter().enumerate() {
            let off = (s + t) * inner;
            let (r0, r1) = (row_at(src, off), row_at(src, off + LANES));
            for l in 0..LANES {
                a0[l] += wt * r0[l];
                a1[l] += wt * r1[l];
            }
        }
        let off = db + o * inner + c;
        emit_row(out, off, &a0, 0);
        emit_row(out, off + LANES, &a1, 0);
    }
}

/// [`direct_inverse`] on two neighbouring blocks (columns `c..c + 2 · LANES`), with one
/// buffer per block.
#[inline(always)]
#[allow(clippy::too_many_arguments)] // one block pair's coordinates and buffers
fn direct_inverse_wide(
    lu: &TriLu,
    scale: f32,
    src: &[f32],
    inner: usize,
    c: usize,
    db: usize,
    [m0, m1]: [&mut [Lanes]; 2],
    out: &impl Emit,
) {
    let n = lu.len();
    let (m0, m1) = (&mut m0[..n], &mut m1[..n]);
    let (mut p0, mut p1) = ([0.0; LANES], [0.0; LANES]);
    for (o, ((y0, y1), &l)) in m0.iter_mut().zip(m1.iter_mut()).zip(&lu.lower).enumerate() {
        let off = o * inner + c;
        let (b0, b1) = (row_at(src, off), row_at(src, off + LANES));
        for e in 0..LANES {
            p0[e] = scale * b0[e] - l * p0[e];
            p1[e] = scale * b1[e] - l * p1[e];
        }
        *y0 = p0;
        *y1 = p1;
    }
    let (mut q0, mut q1) = ([0.0; LANES], [0.0; LANES]);
    for (o, (((y0, y1), &u), &inv)) in m0
        .iter()
        .zip(m1.iter())
        .zip(&lu.upper)
        .zip(&lu.inv_diag)
        .enumerate()
        .rev()
    {
        for e in 0..LANES {
            q0[e] = (y0[e] - u * q0[e]) * inv;
            q1[e] = (y1[e] - u * q1[e]) * inv;
        }
        let off = db + o * inner + c;
        emit_row(out, off, &q0, 0);
        emit_row(out, off + LANES, &q1, 0);
    }
}

/// `scale · B⁻¹` on columns `c..c + LANES` of one block, read straight from the source rows.
#[inline(always)]
#[allow(clippy::too_many_arguments)] // one block's coordinates and buffers
fn direct_inverse(
    lu: &TriLu,
    scale: f32,
    src: &[f32],
    inner: usize,
    c: usize,
    db: usize,
    skip: usize,
    mid: &mut [Lanes],
    out: &impl Emit,
) {
    let n = lu.len();
    let mut prev = [0.0; LANES];
    for (o, (y, &l)) in mid[..n].iter_mut().zip(&lu.lower).enumerate() {
        let b = row_at(src, o * inner + c);
        for e in 0..LANES {
            prev[e] = scale * b[e] - l * prev[e];
        }
        *y = prev;
    }
    let mut next = [0.0; LANES];
    for (o, ((y, &u), &inv)) in mid[..n]
        .iter()
        .zip(&lu.upper)
        .zip(&lu.inv_diag)
        .enumerate()
        .rev()
    {
        for e in 0..LANES {
            next[e] = (y[e] - u * next[e]) * inv;
        }
        emit_row(out, db + o * inner + c, &next, skip);
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
) {
    let (ri, ro) = (op.rows_in(), op.rows_out());
    assert!(blocks.fits(ri.max(ro)), "block buffers too small");
    let (input, mid) = (&mut *blocks.input, &mut *blocks.mid);
    {
        let mut g = lines.start;
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

/// `block[r][l] = group[l · len + r]` for `LANES` lines of `len` values, in 4 × 4 tiles
/// (which LLVM turns into register shuffles).
#[inline(always)]
fn transpose_in(group: &[f32], len: usize, block: &mut [Lanes]) {
    let lines: [&[f32]; LANES] = std::array::from_fn(|l| &group[l * len..(l + 1) * len]);
    let full = len / 4 * 4;
    for r0 in (0..full).step_by(4) {
        let rows: &mut [Lanes; 4] = (&mut block[r0..r0 + 4]).try_into().expect("four rows");
        for h in 0..LANES / 4 {
            let a: [[f32; 4]; 4] =
                std::array::from_fn(|l| lines[4 * h + l][r0..r0 + 4].try_into().expect("four"));
            for (i, row) in rows.iter_mut().enumerate() {
                row[4 * h..4 * h + 4].copy_from_slice(&[a[0][i], a[1][i], a[2][i], a[3][i]]);
            }
        }
    }
    for (r, row) in block[full..len].iter_mut().enumerate() {
        for l in 0..LANES {
            row[l] = lines[l][full + r];
        }
    }
}

/// `group[l · len + r] = block[r][l]`: the inverse of [`transpose_in`].
#[inline(always)]
fn transpose_out(block: &[Lanes], len: usize, group: &mut [f32]) {
    let mut lines: [&mut [f32]; LANES] = {
        let mut it = group.chunks_exact_mut(len);
        std::array::from_fn(|_| it.next().expect("eight lines"))
    };
    let full = len / 4 * 4;
    for r0 in (0..full).step_by(4) {
        let rows: &[Lanes; 4] = block[r0..r0 + 4].try_into().expect("four rows");
        for h in 0..LANES / 4 {
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
