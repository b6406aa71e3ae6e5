//! What the mesher samples: any scalar field with an analytic gradient. The B-spline lattice
//! is the product's field; [`FnField`] wraps closures (analytic shapes for tests, benchmarks
//! and previews).
//!
//! Contract shared by every implementation: the value at a grid sample is a pure function of
//! the sample's global index, whichever block it is sampled in, so bricks that share a face
//! agree bit for bit and the mesh has no cracks.

use glam::Vec3;

use super::grid::SampleGrid;
use crate::field::{BSplineLattice, ImplicitField, MultiPatchField, cubic_weights};

/// A field the mesher can sample: point queries ([`ImplicitField`]) and whole blocks of grid
/// samples, with the bit-for-bit contract above.
pub trait ScalarField: ImplicitField {
    /// Values at the grid samples `first + (i, j, k)` for `i < counts[0]` etc., written x
    /// fastest into `out[..counts product]`. `scratch` is working memory the caller keeps.
    ///
    /// Implementations must give each sample the same bits whichever block contains it.
    ///
    /// # Panics
    /// When `out` is shorter than `counts[0] · counts[1] · counts[2]`.
    fn sample_block(
        &self,
        grid: &SampleGrid,
        first: [u32; 3],
        counts: [usize; 3],
        out: &mut [f32],
        scratch: &mut Vec<f32>,
    ) {
        let _ = scratch;
        let mut n = 0;
        for k in 0..counts[2] as u32 {
            for j in 0..counts[1] as u32 {
                for i in 0..counts[0] as u32 {
                    out[n] = self.value(grid.point([first[0] + i, first[1] + j, first[2] + k]));
                    n += 1;
                }
            }
        }
    }

    /// [`ScalarField::sample_block`] into a block with gaps: sample `(i, j, k)` goes to
    /// `out[i + strides[0] · j + strides[1] · k]` (the entries between are left as they
    /// are), each with the same bits as `sample_block` gives it. `dense` is more working
    /// memory the caller keeps: the default samples the block densely there and copies it
    /// row by row; a field that can write each row in place overrides it.
    ///
    /// # Panics
    /// When `out` is too short for the last sample, or the strides let rows overlap.
    #[allow(clippy::too_many_arguments)]
    fn sample_block_strided(
        &self,
        grid: &SampleGrid,
        first: [u32; 3],
        counts: [usize; 3],
        out: &mut [f32],
        strides: [usize; 2],
        scratch: &mut Vec<f32>,
        dense: &mut Vec<f32>,
    ) {
        let [cx, cy, cz] = counts;
        assert_rows_apart(counts, strides);
        if strides == [cx, cx * cy] {
            self.sample_block(grid, first, counts, out, scratch);
            return;
        }
        dense.clear();
        dense.resize(cx * cy * cz, 0.0);
        self.sample_block(grid, first, counts, dense, scratch);
        for k in 0..cz {
            for j in 0..cy {
                let from = cx * (j + cy * k);
                let to = strides[0] * j + strides[1] * k;
                out[to..to + cx].copy_from_slice(&dense[from..from + cx]);
            }
        }
    }

    /// Lower and upper bounds on the value over the box `min..=max`, or `None` when unknown.
    /// Used only to skip boxes that cannot contain the surface; a bound must never be tighter
    /// than the true range.
    fn bounds(&self, min: Vec3, max: Vec3) -> Option<(f32, f32)> {
        let _ = (min, max);
        None
    }
}

/// A field given by closures: the value, its analytic gradient, the iso-level, and
/// optionally a Lipschitz constant (largest gradient length) that lets the mesher skip empty
/// space without sampling it.
#[derive(Clone, Copy, Debug)]
pub struct FnField<V, G> {
    pub value: V,
    pub gradient: G,
    pub iso: f32,
    /// Upper bound on `|∇f|` (per world unit) everywhere, if known.
    pub lipschitz: Option<f32>,
}

impl<V, G> ImplicitField for FnField<V, G>
where
    V: Fn(Vec3) -> f32,
    G: Fn(Vec3) -> Vec3,
{
    #[inline]
    fn iso(&self) -> f32 {
        self.iso
    }

    #[inline]
    fn value(&self, p: Vec3) -> f32 {
        (self.value)(p)
    }

    #[inline]
    fn value_and_gradient(&self, p: Vec3) -> (f32, Vec3) {
        ((self.value)(p), (self.gradient)(p))
    }

    /// Only the gradient closure: the value would be thrown away.
    #[inline]
    fn gradient(&self, p: Vec3) -> Vec3 {
        (self.gradient)(p)
    }
}

impl<V, G> ScalarField for FnField<V, G>
where
    V: Fn(Vec3) -> f32,
    G: Fn(Vec3) -> Vec3,
{
    /// The closure at each sample, with each axis's coordinates worked out once per block
    /// (the same expression as [`SampleGrid::point`], so the same bits).
    fn sample_block(
        &self,
        grid: &SampleGrid,
        first: [u32; 3],
        counts: [usize; 3],
        out: &mut [f32],
        scratch: &mut Vec<f32>,
    ) {
        let [cx, cy, _] = counts;
        self.sample_rows(grid, first, counts, out, [cx, cx * cy], scratch);
    }

    /// Each row written in place, with the same coordinates and closure calls as
    /// [`FnField::sample_block`] (so the same bits), without a dense block to copy from.
    fn sample_block_strided(
        &self,
        grid: &SampleGrid,
        first: [u32; 3],
        counts: [usize; 3],
        out: &mut [f32],
        strides: [usize; 2],
        scratch: &mut Vec<f32>,
        _dense: &mut Vec<f32>,
    ) {
        assert_rows_apart(counts, strides);
        self.sample_rows(grid, first, counts, out, strides, scratch);
    }

    fn bounds(&self, min: Vec3, max: Vec3) -> Option<(f32, f32)> {
        let l = self.lipschitz?;
        let centre = (min + max) * 0.5;
        let v = (self.value)(centre);
        let reach = l * (max - min).length() * 0.5;
        Some((v - reach, v + reach))
    }
}

impl<V, G> FnField<V, G>
where
    V: Fn(Vec3) -> f32,
{
    /// The closure at the samples `first + (i, j, k)`, sample `(i, j, k)` written to
    /// `out[i + strides[0] · j + strides[1] · k]`, each row in place; each axis's
    /// coordinates are worked out once per block, in `scratch`.
    fn sample_rows(
        &self,
        grid: &SampleGrid,
        first: [u32; 3],
        counts: [usize; 3],
        out: &mut [f32],
        strides: [usize; 2],
        scratch: &mut Vec<f32>,
    ) {
        let [cx, cy, cz] = counts;
        if cx == 0 || cy == 0 || cz == 0 {
            return;
        }
        scratch.clear();
        scratch.extend((0..cx).map(|i| grid.coordinate(0, first[0] + i as u32)));
        scratch.extend((0..cy).map(|j| grid.coordinate(1, first[1] + j as u32)));
        scratch.extend((0..cz).map(|k| grid.coordinate(2, first[2] + k as u32)));
        let (xs, rest) = scratch.split_at(cx);
        let (ys, zs) = rest.split_at(cy);
        for (k, &z) in zs.iter().enumerate() {
            for (j, &y) in ys.iter().enumerate() {
                let at = strides[0] * j + strides[1] * k;
                let row = &mut out[at..at + cx];
                for (o, &x) in row.iter_mut().zip(xs) {
                    *o = (self.value)(Vec3::new(x, y, z));
                }
            }
        }
    }
}

/// Panics unless the rows of a block of `counts` samples laid out with `strides` (see
/// [`ScalarField::sample_block_strided`]) stay apart.
fn assert_rows_apart(counts: [usize; 3], strides: [usize; 2]) {
    assert!(
        strides[0] >= counts[0] && strides[1] >= strides[0] * counts[1],
        "rows of a strided block must not overlap"
    );
}

impl ScalarField for BSplineLattice {
    /// Tensor-product evaluation: one pass per axis over the block's coefficients, about 6×
    /// fewer operations than evaluating each sample's 4×4×4 stencil.
    fn sample_block(
        &self,
        grid: &SampleGrid,
        first: [u32; 3],
        counts: [usize; 3],
        out: &mut [f32],
        scratch: &mut Vec<f32>,
    ) {
        let [cx, cy, cz] = counts;
        if cx == 0 || cy == 0 || cz == 0 {
            return;
        }
        if let Some(axis) = (0..3).find(|&a| counts[a] > MAX_BLOCK) {
            // Too long for one pass: split; each sample's bits do not depend on its block.
            let mut head = counts;
            head[axis] = MAX_BLOCK;
            let mut tail = counts;
            tail[axis] -= MAX_BLOCK;
            let mut tail_first = first;
            tail_first[axis] += MAX_BLOCK as u32;
            let mut part = vec![0.0; head[0] * head[1] * head[2]];
            for (sub_first, sub) in [(first, head), (tail_first, tail)] {
                part.resize(sub[0] * sub[1] * sub[2], 0.0);
                self.sample_block(grid, sub_first, sub, &mut part, scratch);
                let shift = (sub_first[axis] - first[axis]) as usize;
                for k in 0..sub[2] {
                    for j in 0..sub[1] {
                        for i in 0..sub[0] {
                            let mut at = [i, j, k];
                            at[axis] += shift;
                            out[at[0] + cx * (at[1] + cy * at[2])] =
                                part[i + sub[0] * (j + sub[1] * k)];
                        }
                    }
                }
            }
            return;
        }
        // Per axis: first coefficient index and the four weights of each sample.
        let mut taps = [[(0i64, [0.0f32; 4]); MAX_BLOCK]; 3];
        let mut coeff_lo = [0i64; 3];
        let mut coeff_n = [0usize; 3];
        for axis in 0..3 {
            for (s, tap) in taps[axis][..counts[axis]].iter_mut().enumerate() {
                let x = grid.coordinate(axis, first[axis] + s as u32);
                let u = (x - self.origin[axis]) / self.spacing;
                let base = u.floor();
                *tap = (base as i64 - 1, cubic_weights(u - base));
            }
            coeff_lo[axis] = taps[axis][0].0;
            coeff_n[axis] = (taps[axis][counts[axis] - 1].0 - coeff_lo[axis]) as usize + 4;
        }
        let [nx, ny, nz] = coeff_n;
        // Layout of scratch: coefficients (nx·ny·nz), then after the x pass (cx·ny·nz), then
        // after the y pass (cx·cy·nz).
        let (a_len, b_len, c_len) = (nx * ny * nz, cx * ny * nz, cx * cy * nz);
        scratch.clear();
        scratch.resize(a_len + b_len + c_len, 0.0);
        let (coeffs, rest) = scratch.split_at_mut(a_len);
        let (pass_x, pass_y) = rest.split_at_mut(b_len);

        // Gather, with zeros beyond the lattice.
        let dims = self.dims.map(|d| d as i64);
        for k in 0..nz {
            let gk = coeff_lo[2] + k as i64;
            if gk < 0 || gk >= dims[2] {
                continue;
            }
            for j in 0..ny {
                let gj = coeff_lo[1] + j as i64;
                if gj < 0 || gj >= dims[1] {
                    continue;
                }
                // The part of the row inside the lattice, copied out of the bricks at once.
                let (lo, hi) = (coeff_lo[0].max(0), (coeff_lo[0] + nx as i64).min(dims[0]));
                if lo < hi {
                    let at = (lo - coeff_lo[0]) as usize + nx * (j + ny * k);
                    self.coeffs.read_row_at(
                        [lo as usize, gj as usize, gk as usize],
                        &mut coeffs[at..at + (hi - lo) as usize],
                    );
                }
            }
        }
        // x pass.
        for jk in 0..ny * nz {
            let line = &coeffs[jk * nx..(jk + 1) * nx];
            for (s, (c0, w)) in taps[0][..cx].iter().enumerate() {
                let o = (c0 - coeff_lo[0]) as usize;
                pass_x[s + cx * jk] =
                    w[0] * line[o] + w[1] * line[o + 1] + w[2] * line[o + 2] + w[3] * line[o + 3];
            }
        }
        // y pass.
        for k in 0..nz {
            for (t, (c0, w)) in taps[1][..cy].iter().enumerate() {
                let o = (c0 - coeff_lo[1]) as usize;
                for s in 0..cx {
                    let at = |j: usize| pass_x[s + cx * (o + j + ny * k)];
                    pass_y[s + cx * (t + cy * k)] =
                        w[0] * at(0) + w[1] * at(1) + w[2] * at(2) + w[3] * at(3);
                }
            }
        }
        // z pass.
        for (r, (c0, w)) in taps[2][..cz].iter().enumerate() {
            let o = (c0 - coeff_lo[2]) as usize;
            for t in 0..cy {
                for s in 0..cx {
                    let at = |k: usize| pass_y[s + cx * (t + cy * (o + k))];
                    out[s + cx * (t + cy * r)] =
                        w[0] * at(0) + w[1] * at(1) + w[2] * at(2) + w[3] * at(3);
                }
            }
        }
    }

    /// Convex-hull bound: the value is a convex combination of the coefficients whose support
    /// meets the box (coefficients beyond the lattice count as zero).
    fn bounds(&self, min: Vec3, max: Vec3) -> Option<(f32, f32)> {
        let lo = self.to_lattice(min);
        let hi = self.to_lattice(max);
        if !(lo.is_finite() && hi.is_finite()) {
            return None;
        }
        let mut range = [(0i64, 0i64); 3];
        let mut beyond = false;
        for axis in 0..3 {
            let n = self.dims[axis] as i64;
            let a = lo[axis].floor() as i64 - 1;
            let b = hi[axis].floor() as i64 + 2;
            if a < 0 || b >= n {
                beyond = true;
            }
            let (a, b) = (a.max(0), b.min(n - 1));
            if a > b {
                return Some((0.0, 0.0));
            }
            range[axis] = (a, b);
        }
        // Brick by brick: a uniform brick (empty space, solid inside) is one value, so a node
        // over a large clay's empty box costs a directory read per brick, not per coefficient.
        let first = range.map(|(a, _)| a as usize);
        let last = range.map(|(_, b)| b as usize);
        let inside = self.coeffs.box_summary(first, last, false);
        Some(if beyond {
            (inside.min.min(0.0), inside.max.max(0.0))
        } else {
            (inside.min, inside.max)
        })
    }
}

/// Most samples per axis in one tensor-product pass on a lattice (larger blocks are split).
pub const MAX_BLOCK: usize = 64;

impl ScalarField for MultiPatchField {
    /// Each patch's block in a fixed order, summed: a patch in world coordinates uses the
    /// lattice's tensor-product pass, a mapped one its per-sample value. Either gives a sample
    /// the same bits in any block, and so does the sum.
    fn sample_block(
        &self,
        grid: &SampleGrid,
        first: [u32; 3],
        counts: [usize; 3],
        out: &mut [f32],
        scratch: &mut Vec<f32>,
    ) {
        let n: usize = counts.iter().product();
        let out = &mut out[..n];
        match self.patches.as_slice() {
            [] => out.fill(0.0),
            [only] if only.is_identity() => {
                ScalarField::sample_block(&only.lattice, grid, first, counts, out, scratch);
            }
            patches => {
                out.fill(0.0);
                let mut part = vec![0.0; n];
                for patch in patches {
                    if patch.is_identity() {
                        ScalarField::sample_block(
                            &patch.lattice,
                            grid,
                            first,
                            counts,
                            &mut part,
                            scratch,
                        );
                    } else {
                        let mut at = 0;
                        for k in 0..counts[2] as u32 {
                            for j in 0..counts[1] as u32 {
                                for i in 0..counts[0] as u32 {
                                    let x = grid.point([first[0] + i, first[1] + j, first[2] + k]);
                                    part[at] = patch.value(x);
                                    at += 1;
                                }
                            }
                        }
                    }
                    for (o, v) in out.iter_mut().zip(&part) {
                        *o += v;
                    }
                }
            }
        }
    }

    /// The sum of each patch's convex-hull bound over the patch-space box around `min..=max`.
    fn bounds(&self, min: Vec3, max: Vec3) -> Option<(f32, f32)> {
        self.patches.iter().try_fold((0.0, 0.0), |(lo, hi), p| {
            let (a, b) = p.patch_box_of(min, max);
            let (plo, phi) = ScalarField::bounds(&p.lattice, a, b)?;
            Some((lo + plo, hi + phi))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bumpy_lattice() -> BSplineLattice {
        let mut l = BSplineLattice::zeros([7, 6, 8], 0.5, Vec3::new(-0.3, 0.2, 0.1)).unwrap();
        l.coeffs.update_each(|n, c| {
            *c = ((n * 7919) % 101) as f32 / 101.0;
        });
        l
    }

    #[test]
    fn lattice_block_sampling_matches_pointwise_values() {
        let l = bumpy_lattice();
        let grid = SampleGrid::for_lattice(&l, 3).unwrap();
        let counts = [9, 7, 11];
        let first = [2, 0, 13];
        let mut out = vec![0.0; 9 * 7 * 11];
        let mut scratch = Vec::new();
        l.sample_block(&grid, first, counts, &mut out, &mut scratch);
        let mut n = 0;
        for k in 0..counts[2] as u32 {
            for j in 0..counts[1] as u32 {
                for i in 0..counts[0] as u32 {
                    let p = grid.point([first[0] + i, first[1] + j, first[2] + k]);
                    let v = BSplineLattice::value(&l, p);
                    assert!((out[n] - v).abs() < 1e-5, "{} vs {v} at {p}", out[n]);
                    n += 1;
                }
            }
        }
    }

    #[test]
    fn large_blocks_are_split_without_changing_bits() {
        let l = bumpy_lattice();
        let grid = SampleGrid::for_lattice(&l, 12).unwrap();
        let counts = [MAX_BLOCK + 30, 3, 2];
        let mut big = vec![0.0; counts[0] * 6];
        let mut scratch = Vec::new();
        l.sample_block(&grid, [5, 7, 9], counts, &mut big, &mut scratch);
        let mut small = vec![0.0; 9 * 6];
        l.sample_block(&grid, [5 + 60, 7, 9], [9, 3, 2], &mut small, &mut scratch);
        for k in 0..2 {
            for j in 0..3 {
                for i in 0..9 {
                    let a = big[60 + i + counts[0] * (j + 3 * k)];
                    assert_eq!(a.to_bits(), small[i + 9 * (j + 3 * k)].to_bits());
                }
            }
        }
    }

    #[test]
    fn shared_samples_are_bit_identical_across_blocks() {
        let l = bumpy_lattice();
        let grid = SampleGrid::for_lattice(&l, 4).unwrap();
        let mut scratch = Vec::new();
        let mut a = vec![0.0; 9 * 9 * 9];
        let mut b = vec![0.0; 9 * 9 * 9];
        l.sample_block(&grid, [8, 8, 8], [9, 9, 9], &mut a, &mut scratch);
        l.sample_block(&grid, [16, 8, 8], [9, 9, 9], &mut b, &mut scratch);
        for k in 0..9 {
            for j in 0..9 {
                // a's x = 8 face is b's x = 0 face.
                assert_eq!(
                    a[8 + 9 * (j + 9 * k)].to_bits(),
                    b[9 * (j + 9 * k)].to_bits()
                );
            }
        }
    }

    #[test]
    fn lattice_bounds_contain_sampled_values() {
        let l = bumpy_lattice();
        for s in 0..40 {
            let min = Vec3::new(-1.5, -1.0, -1.2) + Vec3::splat(0.11 * s as f32);
            let max = min + Vec3::new(0.7, 0.4, 1.1);
            let (lo, hi) = l.bounds(min, max).unwrap();
            for t in 0..64 {
                let f = Vec3::new((t % 4) as f32, ((t / 4) % 4) as f32, (t / 16) as f32) / 3.0;
                let v = BSplineLattice::value(&l, min + (max - min) * f);
                assert!(v >= lo - 1e-6 && v <= hi + 1e-6, "{v} outside [{lo}, {hi}]");
            }
        }
        // Far outside the support the bound is exactly zero.
        assert_eq!(
            l.bounds(Vec3::splat(50.0), Vec3::splat(51.0)),
            Some((0.0, 0.0))
        );
    }

    #[test]
    fn strided_blocks_hold_the_dense_blocks_bits_and_leave_the_gaps() {
        let f = FnField {
            value: |p: Vec3| (3.1 * p.x).sin() * (2.3 * p.y).cos() + p.z * p.z,
            gradient: |_| Vec3::ZERO,
            iso: 0.0,
            lipschitz: None,
        };
        let l = bumpy_lattice();
        let grid = SampleGrid::new(Vec3::new(-0.4, 0.1, 0.3), 0.07, [20, 20, 20]).unwrap();
        let (first, counts, strides) = ([3, 1, 4], [5, 3, 4], [7, 29]);
        let len = strides[1] * counts[2];
        let mut scratch = Vec::new();
        let mut dense_scratch = Vec::new();
        let fields: [&dyn ScalarField; 2] = [&f, &l];
        for field in fields {
            let mut dense = vec![0.0; counts.iter().product()];
            field.sample_block(&grid, first, counts, &mut dense, &mut scratch);
            let mut out = vec![-7.0f32; len];
            field.sample_block_strided(
                &grid,
                first,
                counts,
                &mut out,
                strides,
                &mut scratch,
                &mut dense_scratch,
            );
            let mut written = vec![false; len];
            for k in 0..counts[2] {
                for j in 0..counts[1] {
                    for i in 0..counts[0] {
                        let at = i + strides[0] * j + strides[1] * k;
                        let d = dense[i + counts[0] * (j + counts[1] * k)];
                        assert_eq!(out[at].to_bits(), d.to_bits(), "sample {i} {j} {k}");
                        written[at] = true;
                    }
                }
            }
            for (v, w) in out.iter().zip(&written) {
                assert!(*w || *v == -7.0, "an entry between the rows was written");
            }
        }
    }

    #[test]
    fn lipschitz_bounds_contain_values() {
        let f = FnField {
            value: |p: Vec3| p.length(),
            gradient: |p: Vec3| p.normalize_or_zero(),
            iso: 1.0,
            lipschitz: Some(1.0),
        };
        let (lo, hi) = f.bounds(Vec3::splat(-0.5), Vec3::splat(0.5)).unwrap();
        assert!(lo <= 0.0 && hi >= 3f32.sqrt() / 2.0);
        let g = FnField {
            lipschitz: None,
            ..f
        };
        assert_eq!(g.bounds(Vec3::ZERO, Vec3::ONE), None);
    }
}
