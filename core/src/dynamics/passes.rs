//! The data-parallel passes of a step, each split over the threads of a [`Team`]: the
//! six-neighbour springs, the projection `p̈ = (AᵀA)⁻¹ Aᵀ f / μ`, the coefficient bounds, and
//! the Euler update with `ḋ = A ṗ` fused with the density and plastic updates.
//!
//! Every pass splits its work the same way whatever the thread count (whole planes for the x
//! and y sweeps, column ranges for the z sweep), and every value is produced by the same lane
//! operations in either split, so one and two threads give bit-identical results. Threads
//! write disjoint ranges between barriers; no pass allocates.

use std::ops::Range;
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};

use crate::field::{
    KroneckerBasis, LANES, SharedOut, split_range, sweep_strided, sweep_strided_with, sweep_x_with,
    with_blocks,
};

use super::material::Integrator;
use super::springs::{SixInputs, six_forces, six_pads};
use super::team::Team;

/// `(max |v|, all finite)` over `v`, in lane-wise form so it vectorises.
#[must_use]
pub(crate) fn max_abs(v: &[f32]) -> (f32, bool) {
    let mut m = [0.0_f32; LANES];
    // 0 · x is 0 for finite x and NaN for an infinity or a NaN.
    let mut probe = [0.0_f32; LANES];
    let chunks = v.chunks_exact(LANES);
    let tail = chunks.remainder();
    for c in chunks {
        let c: &[f32; LANES] = c.try_into().expect("a chunk");
        for l in 0..LANES {
            let a = f32::from_bits(c[l].to_bits() & 0x7fff_ffff);
            m[l] = if a > m[l] { a } else { m[l] };
            probe[l] += 0.0 * c[l];
        }
    }
    for (l, &x) in tail.iter().enumerate() {
        let a = x.abs();
        m[l] = if a > m[l] { a } else { m[l] };
        probe[l] += 0.0 * x;
    }
    let max = m.iter().fold(0.0_f32, |a, &b| if b > a { b } else { a });
    // A NaN in any lane survives the sum.
    (max, probe.iter().sum::<f32>() == 0.0)
}

/// The common value of `v` when every element is the same (lane-wise, so it vectorises).
#[must_use]
pub(crate) fn uniform_value(v: &[f32]) -> Option<f32> {
    let first = *v.first()?;
    let chunks = v.chunks_exact(LANES);
    let tail = chunks.remainder();
    for c in chunks {
        let mut same = true;
        for &x in c {
            same &= x == first;
        }
        if !same {
            return None;
        }
    }
    tail.iter().all(|&x| x == first).then_some(first)
}

/// Per-part `(max, finite)` results.
struct PartMax {
    bits: [AtomicU32; 2],
    finite: [AtomicBool; 2],
}

impl PartMax {
    fn new() -> Self {
        Self {
            bits: [AtomicU32::new(0), AtomicU32::new(0)],
            finite: [AtomicBool::new(true), AtomicBool::new(true)],
        }
    }

    fn merge(&self, part: usize, (max, finite): (f32, bool)) {
        // Relaxed: `Team::run` orders the parts' writes before the caller's reads.
        let old = f32::from_bits(self.bits[part].load(Ordering::Relaxed));
        self.bits[part].store(old.max(max).to_bits(), Ordering::Relaxed);
        if !finite {
            self.finite[part].store(false, Ordering::Relaxed);
        }
    }

    fn result(&self) -> (f32, bool) {
        let m0 = f32::from_bits(self.bits[0].load(Ordering::Relaxed));
        let m1 = f32::from_bits(self.bits[1].load(Ordering::Relaxed));
        (
            m0.max(m1),
            self.finite[0].load(Ordering::Relaxed) && self.finite[1].load(Ordering::Relaxed),
        )
    }
}

/// The per-point fields the spring pass reads.
pub(crate) struct SpringFields<'a> {
    pub dims: [usize; 3],
    pub d: &'a [f32],
    pub rest: &'a [f32],
    pub stiffness: &'a [f32],
    pub damping: &'a [f32],
    pub d_dot: &'a [f32],
    pub external: &'a [f32],
    pub zeros: &'a [f32],
}

/// `force = external + six-neighbour springs − damping · ḋ`, split by planes.
pub(crate) fn springs_six(
    team: &mut Team,
    f: &SpringFields<'_>,
    e_pad: &mut [f32],
    k_pad: &mut [f32],
    force: &mut [f32],
) {
    let parts = team.threads();
    let mz = f.dims[2];
    let (ep, kp, out) = (
        SharedOut::new(e_pad),
        SharedOut::new(k_pad),
        SharedOut::new(force),
    );
    // A uniform stiffness (the usual case) needs no padded copy and fewer operations.
    let uniform_k = uniform_value(f.stiffness);
    team.run(&|part, barrier| {
        let planes = split_range(mz, parts, part, 1);
        let k_copy = if uniform_k.is_some() { None } else { Some(&kp) };
        // SAFETY: each part fills only the rows of its own planes.
        unsafe {
            six_pads(
                f.dims,
                f.d,
                f.rest,
                f.stiffness,
                planes.clone(),
                &ep,
                k_copy,
            )
        };
        barrier.wait();
        // SAFETY: after the barrier nobody writes the padded copies.
        let (e_pad, k_pad) = unsafe { (ep.slice(0..ep.len()), kp.slice(0..kp.len())) };
        let inputs = SixInputs {
            dims: f.dims,
            uniform_k,
            e_pad,
            k_pad,
            zeros: f.zeros,
            external: f.external,
            damping: f.damping,
            d_dot: f.d_dot,
        };
        // SAFETY: each part writes only the rows of its own planes.
        unsafe { six_forces(&inputs, planes, &out, 0) };
    });
}

/// Two scratch arrays for the intermediate results of a three-pass chain.
pub(crate) struct ChainScratch<'a> {
    pub t1: &'a mut [f32],
    pub t2: &'a mut [f32],
}

/// `accel = scale · (AᵀA)⁻¹ Aᵀ force`; returns `(max |accel|, all finite)`.
pub(crate) fn project(
    team: &mut Team,
    basis: &KroneckerBasis,
    force: &[f32],
    scale: f32,
    scratch: ChainScratch<'_>,
    accel: &mut [f32],
) -> (f32, bool) {
    let parts = team.threads();
    let ops = [
        basis.op_project(0, 1.0),
        basis.op_project(1, 1.0),
        basis.op_project(2, scale),
    ];
    let [sx, sy, sz] = basis.pass_shapes(&ops);
    let (t1, t2, out) = (
        SharedOut::new(&mut scratch.t1[..sx.out_len]),
        SharedOut::new(&mut scratch.t2[..sy.out_len]),
        SharedOut::new(accel),
    );
    let result = PartMax::new();
    team.run(&|part, barrier| {
        let planes = split_range(sy.outer, parts, part, 1);
        planes_xy(&ops, &[sx, sy], force, planes, &t1, &t2);
        barrier.wait();
        // SAFETY: after the barrier nobody writes t2.
        let t2 = unsafe { t2.slice(0..t2.len()) };
        let cols = split_range(sz.inner, parts, part, LANES);
        // SAFETY: `split_range` gives each part disjoint columns of `out`, written by this
        // part alone; `t2` is a different buffer, read only after the barrier.
        unsafe { sweep_strided(&ops[2], t2, sz.inner, 0..1, cols.clone(), &out) };
        for row in 0..out.len() / sz.inner.max(1) {
            let base = row * sz.inner;
            // SAFETY: these columns were written by this part alone.
            let seg = unsafe { out.slice(base + cols.start..base + cols.end) };
            result.merge(part, max_abs(seg));
        }
    });
    result.result()
}

/// The springs fused into the projection: `accel = scale · (AᵀA)⁻¹ Aᵀ force` with
/// `force = external + six-neighbour springs − damping · ḋ` made one plane at a time, into a
/// plane-sized buffer per thread that the x pass reads at once, instead of a whole force
/// array written by one pass and read back by the next. Returns `(max |accel|, all finite)`.
/// Bit-identical to [`springs_six`] followed by [`project`].
#[allow(clippy::too_many_arguments)] // the spring fields, their scratch and the projection's
pub(crate) fn springs_project(
    team: &mut Team,
    f: &SpringFields<'_>,
    (e_pad, k_pad): (&mut [f32], &mut [f32]),
    plane_buf: &mut [f32],
    basis: &KroneckerBasis,
    scale: f32,
    scratch: ChainScratch<'_>,
    accel: &mut [f32],
) -> (f32, bool) {
    let parts = team.threads();
    let [mx, my, mz] = f.dims;
    let ops = [
        basis.op_project(0, 1.0),
        basis.op_project(1, 1.0),
        basis.op_project(2, scale),
    ];
    let [sx, sy, sz] = basis.pass_shapes(&ops);
    assert_eq!(sy.outer, mz, "the projection's planes are the mass grid's");
    let plane_len = mx * my;
    let (ep, kp) = (SharedOut::new(e_pad), SharedOut::new(k_pad));
    let (t1, t2, out, planes_out) = (
        SharedOut::new(&mut scratch.t1[..sx.out_len]),
        SharedOut::new(&mut scratch.t2[..sy.out_len]),
        SharedOut::new(accel),
        SharedOut::new(&mut plane_buf[..2 * plane_len]),
    );
    let uniform_k = uniform_value(f.stiffness);
    let result = PartMax::new();
    let lines_per_plane = sx.lines / mz.max(1);
    let t1_plane = sx.out_len / mz.max(1);
    let t2_plane = sy.out_len / mz.max(1);
    let rows = [&ops[0], &ops[1]].map(|o| o.rows_in().max(o.rows_out()));
    team.run(&|part, barrier| {
        let planes = split_range(mz, parts, part, 1);
        let k_copy = if uniform_k.is_some() { None } else { Some(&kp) };
        // SAFETY: each part fills only the rows of its own planes.
        unsafe {
            six_pads(
                f.dims,
                f.d,
                f.rest,
                f.stiffness,
                planes.clone(),
                &ep,
                k_copy,
            );
        }
        barrier.wait();
        // SAFETY: after the barrier nobody writes the padded copies.
        let (e_pad, k_pad) = unsafe { (ep.slice(0..ep.len()), kp.slice(0..kp.len())) };
        let inputs = SixInputs {
            dims: f.dims,
            uniform_k,
            e_pad,
            k_pad,
            zeros: f.zeros,
            external: f.external,
            damping: f.damping,
            d_dot: f.d_dot,
        };
        let mine = planes_out.sub(part * plane_len..(part + 1) * plane_len);
        with_blocks(rows[0].max(rows[1]), |blocks| {
            for k in planes {
                // SAFETY: this part's plane buffer is written by this part alone, and row
                // `r` of plane k lands at `r − k · plane_len`, inside it.
                unsafe { six_forces(&inputs, k..k + 1, &mine, k * plane_len) };
                // SAFETY: written just above by this part; nobody else touches it.
                let force = unsafe { mine.slice(0..plane_len) };
                let t1k = t1.sub(k * t1_plane..(k + 1) * t1_plane);
                // SAFETY: plane k is this part's, so t1k is written by this part alone.
                unsafe { sweep_x_with(blocks, &ops[0], force, 0..lines_per_plane, &t1k) };
                // SAFETY: this part wrote this plane of t1 and nobody else touches it.
                let src = unsafe { t1k.slice(0..t1k.len()) };
                // SAFETY: this plane of t2 belongs to this part; `src` lies in t1.
                unsafe {
                    sweep_strided_with(
                        blocks,
                        &ops[1],
                        src,
                        sy.inner,
                        0..1,
                        0..sy.inner,
                        &t2.sub(k * t2_plane..(k + 1) * t2_plane),
                    );
                }
            }
        });
        barrier.wait();
        // SAFETY: after the barrier nobody writes t2.
        let t2 = unsafe { t2.slice(0..t2.len()) };
        let cols = split_range(sz.inner, parts, part, LANES);
        // SAFETY: `split_range` gives each part disjoint columns of `out`, written by this
        // part alone; `t2` is a different buffer, read only after the barrier.
        unsafe { sweep_strided(&ops[2], t2, sz.inner, 0..1, cols.clone(), &out) };
        for row in 0..out.len() / sz.inner.max(1) {
            let base = row * sz.inner;
            // SAFETY: these columns were written by this part alone.
            let seg = unsafe { out.slice(base + cols.start..base + cols.end) };
            result.merge(part, max_abs(seg));
        }
    });
    result.result()
}

/// The x and y passes of a chain over the planes `planes` of its input, plane by plane so
/// the intermediate plane stays in cache (whole planes, so no barrier is needed between them).
fn planes_xy(
    ops: &[crate::field::AxisOp<'_>; 3],
    shapes: &[crate::field::PassShape; 2],
    src: &[f32],
    planes: Range<usize>,
    t1: &SharedOut<'_>,
    t2: &SharedOut<'_>,
) {
    let [sx, sy] = *shapes;
    let planes_total = sy.outer.max(1);
    let lines_per_plane = sx.lines / planes_total;
    let t1_plane = sx.out_len / planes_total;
    let t2_plane = sy.out_len / planes_total;
    let rows = [&ops[0], &ops[1]].map(|o| o.rows_in().max(o.rows_out()));
    with_blocks(rows[0].max(rows[1]), |blocks| {
        for plane in planes {
            // SAFETY: the callers split the planes between parts (`split_range`), so this
            // plane's lines of t1 are written by this part alone; `src` is another buffer.
            // Whole planes hold whole lane groups, so a short tail stays inside the plane.
            unsafe {
                sweep_x_with(
                    blocks,
                    &ops[0],
                    src,
                    plane * lines_per_plane..(plane + 1) * lines_per_plane,
                    t1,
                );
            }
            // SAFETY: this part wrote this plane of t1 and nobody else touches it.
            let mine = unsafe { t1.slice(plane * t1_plane..(plane + 1) * t1_plane) };
            // SAFETY: this plane of t2 (a `sub` of this plane alone) belongs to this part;
            // `mine` lies in t1.
            unsafe {
                sweep_strided_with(
                    blocks,
                    &ops[1],
                    mine,
                    sy.inner,
                    0..1,
                    0..sy.inner,
                    &t2.sub(plane * t2_plane..(plane + 1) * t2_plane),
                );
            }
        }
    });
}

/// `(max |p|, max |ṗ|, all finite)`.
pub(crate) fn coefficient_bounds(team: &mut Team, p: &[f32], p_dot: &[f32]) -> (f32, f32, bool) {
    let parts = team.threads();
    let (pm, vm) = (PartMax::new(), PartMax::new());
    team.run(&|part, _| {
        let r = split_range(p.len(), parts, part, LANES);
        pm.merge(part, max_abs(&p[r.clone()]));
        vm.merge(part, max_abs(&p_dot[r]));
    });
    let ((p_max, p_ok), (v_max, v_ok)) = (pm.result(), vm.result());
    (p_max, v_max, p_ok && v_ok)
}

/// The density-side state a step updates from `ḋ = A ṗ`.
pub(crate) struct Densities<'a> {
    pub d_dot: &'a mut [f32],
    pub d: &'a mut [f32],
    pub rest: &'a mut [f32],
}

/// Plastic drift over one step: `rest += min(rate · dt, 1) · excess` at each mass point, with
/// `excess = dev − clamp(dev, −yield, yield)` and `rate` the mass point's own drift rate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Plastic<'a> {
    /// Drift rate per mass point, per second (indexed like the densities).
    pub rate_per_s: &'a [f32],
    /// The step, seconds.
    pub dt_s: f32,
    pub yield_density: f32,
}

/// The density arrays shared between the parts.
struct DensityOut<'a> {
    d_dot: SharedOut<'a>,
    d: SharedOut<'a>,
    rest: SharedOut<'a>,
}

/// One rest density after the plastic drift toward `d` with the step's drift fraction
/// `share` (written as selects so it vectorises).
#[inline(always)]
fn drifted(d: f32, rest: f32, share: f32, yield_density: f32) -> f32 {
    let y = yield_density;
    let dev = d - rest;
    let upper = if dev > y { y } else { dev };
    let clamped = if upper < -y { -y } else { upper };
    rest + share * (dev - clamped)
}

/// Apply the plastic drift of the rest densities toward `d`; `rate_per_s` holds the drift
/// rates of the same mass points (all three slices are the same points, in order).
pub(crate) fn plastic_drift(d: &[f32], rest: &mut [f32], rate_per_s: &[f32], pl: &Plastic<'_>) {
    for ((r, &d), &rate) in rest.iter_mut().zip(d).zip(rate_per_s) {
        let share = (rate * pl.dt_s).min(1.0);
        *r = drifted(d, *r, share, pl.yield_density);
    }
}

/// Forward Euler on `(p, ṗ)` with `p̈ = accel`, then `ḋ = A ṗ` with `d` advanced and the
/// plastic drift applied as each value of `ḋ` comes out.
#[allow(clippy::too_many_arguments)] // one pass over the whole state
pub(crate) fn integrate(
    team: &mut Team,
    basis: &KroneckerBasis,
    dt: f32,
    integrator: Integrator,
    plastic: Option<Plastic<'_>>,
    (p, p_dot, accel): (&mut [f32], &mut [f32], &[f32]),
    scratch: ChainScratch<'_>,
    dens: Densities<'_>,
) {
    let parts = team.threads();
    let ops = [basis.op_apply(0), basis.op_apply(1), basis.op_apply(2)];
    let [sx, sy, sz] = basis.pass_shapes(&ops);
    let (po, vo) = (SharedOut::new(p), SharedOut::new(p_dot));
    let (t1, t2) = (
        SharedOut::new(&mut scratch.t1[..sx.out_len]),
        SharedOut::new(&mut scratch.t2[..sy.out_len]),
    );
    let out = DensityOut {
        d_dot: SharedOut::new(dens.d_dot),
        d: SharedOut::new(dens.d),
        rest: SharedOut::new(dens.rest),
    };
    let plane = po.len() / sy.outer.max(1);
    let lines_per_plane = sx.lines / sy.outer.max(1);
    let t1_plane = sx.out_len / sy.outer.max(1);
    let t2_plane = sy.out_len / sy.outer.max(1);
    let rows = [&ops[0], &ops[1]].map(|o| o.rows_in().max(o.rows_out()));
    team.run(&|part, barrier| {
        let planes = split_range(sy.outer, parts, part, 1);
        // Plane by plane: Euler on the plane's coefficients, then its x and y passes, while
        // the plane is in cache.
        with_blocks(rows[0].max(rows[1]), |blocks| {
            for k in planes {
                let range = k * plane..(k + 1) * plane;
                // SAFETY: each part updates only the coefficients of its own planes.
                let (x, v) = unsafe { (po.slice_mut(range.clone()), vo.slice_mut(range.clone())) };
                let a = &accel[range];
                match integrator {
                    Integrator::SemiImplicit => {
                        for ((x, v), &a) in x.iter_mut().zip(v.iter_mut()).zip(a) {
                            *v += dt * a;
                            *x += dt * *v;
                        }
                    }
                    Integrator::Explicit => {
                        for ((x, v), &a) in x.iter_mut().zip(v.iter_mut()).zip(a) {
                            *x += dt * *v;
                            *v += dt * a;
                        }
                    }
                }
                let v: &[f32] = v;
                let t1k = t1.sub(k * t1_plane..(k + 1) * t1_plane);
                // SAFETY: plane k is this part's (split by `split_range`), so t1k (this
                // plane of t1 alone) is written by this part only; `v` lies in the velocity.
                unsafe { sweep_x_with(blocks, &ops[0], v, 0..lines_per_plane, &t1k) };
                // SAFETY: this part wrote this plane of t1 and nobody else touches it.
                let mine = unsafe { t1k.slice(0..t1k.len()) };
                // SAFETY: this plane of t2 belongs to this part; `mine` lies in t1.
                unsafe {
                    sweep_strided_with(
                        blocks,
                        &ops[1],
                        mine,
                        sy.inner,
                        0..1,
                        0..sy.inner,
                        &t2.sub(k * t2_plane..(k + 1) * t2_plane),
                    );
                }
            }
        });
        barrier.wait();
        // SAFETY: after the barrier nobody writes t2.
        let t2 = unsafe { t2.slice(0..t2.len()) };
        let cols = split_range(sz.inner, parts, part, LANES);
        // The density updates run over this part's columns row by row (contiguous, so they
        // vectorise), around the z pass that writes ḋ.
        let rows = out.d_dot.len() / sz.inner.max(1);
        let segments = || (0..rows).map(|r| r * sz.inner + cols.start..r * sz.inner + cols.end);
        if integrator == Integrator::Explicit {
            for seg in segments() {
                // SAFETY: these columns belong to this part alone.
                let (d, dd) = unsafe { (out.d.slice_mut(seg.clone()), out.d_dot.slice(seg)) };
                for (d, &v) in d.iter_mut().zip(dd) {
                    *d += dt * v;
                }
            }
        }
        // SAFETY: `split_range` gives each part disjoint columns of ḋ; t2 is another buffer,
        // read only after the barrier.
        unsafe { sweep_strided(&ops[2], t2, sz.inner, 0..1, cols.clone(), &out.d_dot) };
        for seg in segments() {
            let seg_start = seg.start;
            // SAFETY: these columns belong to this part alone.
            let (dd, d, rest) = unsafe {
                (
                    out.d_dot.slice(seg.clone()),
                    out.d.slice_mut(seg.clone()),
                    out.rest.slice_mut(seg),
                )
            };
            if integrator == Integrator::SemiImplicit {
                for (d, &v) in d.iter_mut().zip(dd) {
                    *d += dt * v;
                }
            }
            if let Some(pl) = &plastic {
                plastic_drift(d, rest, &pl.rate_per_s[seg_start..seg_start + d.len()], pl);
            }
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn max_abs_finds_the_largest_magnitude_and_flags_non_finite_values() {
        let mut v: Vec<f32> = (0..37).map(|i| (i as f32 * 0.37).sin()).collect();
        v[29] = -3.5;
        assert_eq!(max_abs(&v), (3.5, true));
        v[35] = f32::INFINITY;
        assert!(!max_abs(&v).1);
        v[35] = f32::NAN;
        assert!(!max_abs(&v).1);
        v[35] = 0.0;
        v[3] = f32::NAN;
        assert!(!max_abs(&v).1);
        assert_eq!(max_abs(&[]), (0.0, true));
    }
}
