//! Density-spring forces on a mass grid: a spring between neighbours `i`, `j` pulls with
//! `k_ij ((d_j − d_i) − (r_j − r_i))` along the density axis only, with `k_ij` the mean of the
//! two points' stiffness times the spring's weight ([`Neighbourhood::weight`]: scaled by its
//! rest length and normalised over the stencil). A neighbour outside the grid is fixed at its
//! rest density, so the spring to it pulls with `w k_i (r_i − d_i)`. Each spring is evaluated from both ends, row by row, so
//! the inner loops are contiguous and vectorise.
//!
//! The six-neighbour springs (the default) have a fused kernel: one pass over the rows that
//! adds every neighbour, the damping and the external force in fixed-width lane loops. It
//! reads `e = d − rest` and the stiffness from copies padded by one value at both ends of
//! every row (`e` zero there, the stiffness repeated), so an anchor at a face of the grid is
//! just a neighbour at rest with the point's own stiffness, and the loops need no edge cases.

use std::ops::Range;

use crate::field::{SharedOut, avx2_dispatch};

use super::material::Neighbourhood;

/// Lanes of the fused kernel.
const W: usize = 8;

/// Offsets of the neighbourhood with their weights ([`Neighbourhood::weight`]).
pub(crate) fn offsets(nb: Neighbourhood) -> impl Iterator<Item = ([i64; 3], f32)> {
    let max_order = i64::from(nb.max_order());
    (-1..=1_i64).flat_map(move |z| {
        (-1..=1_i64).flat_map(move |y| {
            (-1..=1_i64).filter_map(move |x| {
                let order = x.abs() + y.abs() + z.abs();
                (order >= 1 && order <= max_order).then(|| ([x, y, z], nb.weight(order as u32)))
            })
        })
    })
}

/// `force += spring forces` for densities `d`, rest densities `rest` and per-point
/// `stiffness` on a grid of `dims` (x fastest). `e` is scratch of the same length.
pub(crate) fn add_spring_forces(
    dims: [usize; 3],
    d: &[f32],
    rest: &[f32],
    stiffness: &[f32],
    nb: Neighbourhood,
    e: &mut [f32],
    force: &mut [f32],
) {
    let [mx, my, mz] = dims;
    for ((e, &d), &r) in e.iter_mut().zip(d).zip(rest) {
        *e = d - r;
    }
    let e = &*e;
    for (o, w) in offsets(nb) {
        let half_w = 0.5 * w;
        // x range of points whose neighbour is inside along x.
        let lo = (-o[0]).max(0) as usize;
        let hi = (mx as i64 - o[0].max(0)).max(lo as i64) as usize;
        for k in 0..mz {
            for j in 0..my {
                let row = (j + my * k) * mx;
                let (j2, k2) = (j as i64 + o[1], k as i64 + o[2]);
                let f = &mut force[row..row + mx];
                let ee = &e[row..row + mx];
                let kk = &stiffness[row..row + mx];
                if j2 < 0 || j2 >= my as i64 || k2 < 0 || k2 >= mz as i64 {
                    for ((f, &e), &k) in f.iter_mut().zip(ee).zip(kk) {
                        *f -= w * k * e;
                    }
                    continue;
                }
                let nrow = (j2 as usize + my * k2 as usize) * mx;
                let (nlo, nhi) = ((lo as i64 + o[0]) as usize, (hi as i64 + o[0]) as usize);
                let en = &e[nrow + nlo..nrow + nhi];
                let kn = &stiffness[nrow + nlo..nrow + nhi];
                for ((((f, &e), &k), &e2), &k2) in f[lo..hi]
                    .iter_mut()
                    .zip(&ee[lo..hi])
                    .zip(&kk[lo..hi])
                    .zip(en)
                    .zip(kn)
                {
                    *f += half_w * (k + k2) * (e2 - e);
                }
                for i in (0..lo).chain(hi..mx) {
                    f[i] -= w * kk[i] * ee[i];
                }
            }
        }
    }
}

/// Row length of the padded copies for rows of `mx` points.
#[must_use]
pub(crate) fn padded_row(mx: usize) -> usize {
    mx + 2
}

avx2_dispatch! {
    /// Fill the padded copies of `e = d − rest` and the stiffness for the rows of `planes`.
    ///
    /// # Safety
    /// No other thread may access the rows of `planes` in `e_pad` and `k_pad` meanwhile.
    pub(crate) unsafe fn six_pads(
        dims: [usize; 3],
        d: &[f32],
        rest: &[f32],
        stiffness: &[f32],
        planes: Range<usize>,
        e_pad: &SharedOut<'_>,
        k_pad: Option<&SharedOut<'_>>,
    );
    portable: six_pads_body;
    six_pads_avx2: six_pads_body;
}

/// The body of [`six_pads`], inlined into each build.
///
/// # Safety
/// As [`six_pads`].
#[inline(always)]
unsafe fn six_pads_body(
    dims: [usize; 3],
    d: &[f32],
    rest: &[f32],
    stiffness: &[f32],
    planes: Range<usize>,
    e_pad: &SharedOut<'_>,
    k_pad: Option<&SharedOut<'_>>,
) {
    let [mx, my, _] = dims;
    let s = padded_row(mx);
    for row in planes.start * my..planes.end * my {
        let src = row * mx..(row + 1) * mx;
        // SAFETY: this row is ours by the caller's contract.
        let ep = unsafe { e_pad.slice_mut(row * s..(row + 1) * s) };
        for ((e, &d), &r) in ep[1..=mx]
            .iter_mut()
            .zip(&d[src.clone()])
            .zip(&rest[src.clone()])
        {
            *e = d - r;
        }
        ep[0] = 0.0;
        ep[mx + 1] = 0.0;
        if let Some(k_pad) = k_pad {
            // SAFETY: as above.
            let kp = unsafe { k_pad.slice_mut(row * s..(row + 1) * s) };
            let k = &stiffness[src];
            kp[1..=mx].copy_from_slice(k);
            kp[0] = k[0];
            kp[mx + 1] = k[mx - 1];
        }
    }
}

/// Fixed inputs of the fused six-neighbour kernel.
pub(crate) struct SixInputs<'a> {
    pub dims: [usize; 3],
    /// The stiffness when it is the same at every point; `k_pad` is not read then.
    pub uniform_k: Option<f32>,
    pub e_pad: &'a [f32],
    pub k_pad: &'a [f32],
    /// At least `dims[0]` zeros: the `e` of an anchor row.
    pub zeros: &'a [f32],
    pub external: &'a [f32],
    pub damping: &'a [f32],
    pub d_dot: &'a [f32],
}

/// The neighbour rows of one row: `(e, stiffness)` for y−, y+, z−, z+ (an anchor is a row of
/// zeros with the row's own stiffness), each `mx` long.
type NeighbourRows<'a> = [(&'a [f32], &'a [f32]); 4];

/// `s[i..i + W]`, bounds-checked (one check per lane group, which the loops around it hoist
/// or fold: see `cargo bench --bench core -- step` in `bench/RESULTS.md`).
///
/// # Panics
/// When `i + W > s.len()`.
#[inline(always)]
fn lanes(s: &[f32], i: usize) -> [f32; W] {
    let chunk: &[f32; W] = s[i..i + W]
        .try_into()
        .unwrap_or_else(|_| unreachable!("a slice of W is W long"));
    *chunk
}

/// The fused kernel on `W` points starting at `i` (full width).
///
/// # Panics
/// Unless `i + W <= mx`, where `ec` and `kc` hold `mx + 2` values and every other slice `mx`.
#[inline(always)]
#[allow(clippy::too_many_arguments)] // the streams of one row
fn six_chunk(
    i: usize,
    ec: &[f32],
    kc: &[f32],
    rows: &NeighbourRows<'_>,
    ext: &[f32],
    g: &[f32],
    v: &[f32],
    out: &mut [f32],
) {
    // The padded rows are two longer: centre at i + 1, x− at i, x+ at i + 2.
    let [(e0, k0), (exm, kxm), (exp, kxp)] =
        [1, 0, 2].map(|o| (lanes(ec, i + o), lanes(kc, i + o)));
    let mut acc = [0.0; W];
    for l in 0..W {
        acc[l] = (k0[l] + kxm[l]) * (exm[l] - e0[l]) + (k0[l] + kxp[l]) * (exp[l] - e0[l]);
    }
    for &(en, kn) in rows {
        let (en, kn) = (lanes(en, i), lanes(kn, i));
        for l in 0..W {
            acc[l] += (k0[l] + kn[l]) * (en[l] - e0[l]);
        }
    }
    let (x, gg, vv) = (lanes(ext, i), lanes(g, i), lanes(v, i));
    let mut f = [0.0; W];
    for l in 0..W {
        f[l] = x[l] + 0.5 * acc[l] - gg[l] * vv[l];
    }
    out[i..i + W].copy_from_slice(&f);
}

/// [`six_chunk`] with one stiffness `k` everywhere: `k Σ (e_n − e)`.
///
/// # Panics
/// As [`six_chunk`].
#[inline(always)]
#[allow(clippy::too_many_arguments)] // the streams of one row
fn six_chunk_uniform(
    i: usize,
    k: f32,
    ec: &[f32],
    rows: &NeighbourRows<'_>,
    ext: &[f32],
    g: &[f32],
    v: &[f32],
    out: &mut [f32],
) {
    // The padded row is two longer: centre at i + 1, x− at i, x+ at i + 2.
    let [e0, exm, exp] = [1, 0, 2].map(|o| lanes(ec, i + o));
    let mut acc = [0.0; W];
    for l in 0..W {
        acc[l] = (exm[l] - e0[l]) + (exp[l] - e0[l]);
    }
    for &(en, _) in rows {
        let en = lanes(en, i);
        for l in 0..W {
            acc[l] += en[l] - e0[l];
        }
    }
    let (x, gg, vv) = (lanes(ext, i), lanes(g, i), lanes(v, i));
    let mut f = [0.0; W];
    for l in 0..W {
        f[l] = x[l] + k * acc[l] - gg[l] * vv[l];
    }
    out[i..i + W].copy_from_slice(&f);
}

/// The same sum for one point (rows shorter than `W`); `uniform` replaces every stiffness.
#[allow(clippy::too_many_arguments)] // the streams of one row
fn six_point(
    i: usize,
    uniform: Option<f32>,
    ec: &[f32],
    kc: &[f32],
    rows: &NeighbourRows<'_>,
    ext: &[f32],
    g: &[f32],
    v: &[f32],
    out: &mut [f32],
) {
    let k = |s: &[f32], j: usize| uniform.unwrap_or_else(|| s[j]);
    let (e0, k0) = (ec[i + 1], k(kc, i + 1));
    let mut acc = (k0 + k(kc, i)) * (ec[i] - e0) + (k0 + k(kc, i + 2)) * (ec[i + 2] - e0);
    for &(en, kn) in rows {
        acc += (k0 + k(kn, i)) * (en[i] - e0);
    }
    out[i] = ext[i] + 0.5 * acc - g[i] * v[i];
}

avx2_dispatch! {
    /// `force = external + springs − damping · ḋ` for the rows of `planes`. The point at flat
    /// index `i` is written at `i − base` of `force` (a buffer that holds only some planes).
    ///
    /// # Safety
    /// No other thread may access the rows of `planes` in `force` meanwhile.
    pub(crate) unsafe fn six_forces(
        inp: &SixInputs<'_>,
        planes: Range<usize>,
        force: &SharedOut<'_>,
        base: usize,
    );
    portable: six_forces_body;
    six_forces_avx2: six_forces_body;
}

/// The body of [`six_forces`], inlined into each build.
///
/// # Safety
/// As [`six_forces`].
#[inline(always)]
unsafe fn six_forces_body(
    inp: &SixInputs<'_>,
    planes: Range<usize>,
    force: &SharedOut<'_>,
    base: usize,
) {
    let [mx, my, mz] = inp.dims;
    let s = padded_row(mx);
    let plane = s * my;
    for row in planes.start * my..planes.end * my {
        let (j, k) = (row % my, row / my);
        let pad = row * s;
        let ec = &inp.e_pad[pad..pad + s];
        let kc = &inp.k_pad[pad..pad + s];
        let centre_k = &kc[1..=mx];
        let neighbour = |present: bool, at: usize| {
            if present {
                (&inp.e_pad[at + 1..=at + mx], &inp.k_pad[at + 1..=at + mx])
            } else {
                (&inp.zeros[..mx], centre_k)
            }
        };
        let rows = [
            neighbour(j > 0, pad.wrapping_sub(s)),
            neighbour(j + 1 < my, pad + s),
            neighbour(k > 0, pad.wrapping_sub(plane)),
            neighbour(k + 1 < mz, pad + plane),
        ];
        let flat = row * mx..(row + 1) * mx;
        let (ext, g, v) = (
            &inp.external[flat.clone()],
            &inp.damping[flat.clone()],
            &inp.d_dot[flat.clone()],
        );
        // SAFETY: this row is ours by the caller's contract.
        let out = unsafe { force.slice_mut(flat.start - base..flat.end - base) };
        assert!(
            rows.iter().all(|(e, k)| e.len() >= mx && k.len() >= mx)
                && ec.len() >= mx + 2
                && kc.len() >= mx + 2
                && ext.len() >= mx
                && g.len() >= mx
                && v.len() >= mx,
            "row lengths"
        );
        if mx < W {
            for i in 0..mx {
                six_point(i, inp.uniform_k, ec, kc, &rows, ext, g, v, out);
            }
            continue;
        }
        // Chunks of W; the last one overlaps the previous (outputs depend only on inputs).
        let mut i = 0;
        loop {
            // The last chunk overlaps the previous one.
            let at = i.min(mx - W);
            // at + W <= mx, and the lengths were checked above.
            match inp.uniform_k {
                Some(k) => six_chunk_uniform(at, k, ec, &rows, ext, g, v, out),
                None => six_chunk(at, ec, kc, &rows, ext, g, v, out),
            }
            i += W;
            if i >= mx {
                break;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn neighbourhoods_have_the_right_sizes() {
        assert_eq!(offsets(Neighbourhood::Six).count(), 6);
        assert_eq!(offsets(Neighbourhood::Eighteen).count(), 18);
        assert_eq!(offsets(Neighbourhood::TwentySix).count(), 26);
        for nb in Neighbourhood::ALL {
            assert_eq!(offsets(nb).count(), nb.count() as usize);
            assert_eq!(Neighbourhood::from_count(nb.count()), Some(nb));
        }
        assert_eq!(Neighbourhood::from_count(12), None);
        // The face springs of the six-neighbour stencil keep weight 1 exactly (the fused
        // kernel and every stored result assume it).
        assert!(offsets(Neighbourhood::Six).all(|(_, w)| w == 1.0));
    }

    /// The normalisation: every stencil has the same second moment `Σ w o oᵀ = 2 I`, so a
    /// smooth deformation `e` meets the same spring force `Σ w (e(x + o) − e(x)) = ∇²e` (in
    /// units of `h²`); a linear `e` meets none; and the 18-neighbour stencil is isotropic to
    /// fourth order (`Σ w (o·u)⁴` the same along an axis and a diagonal).
    #[test]
    fn every_stencil_resists_a_smooth_deformation_alike() {
        for nb in Neighbourhood::ALL {
            let mut m2 = [[0.0_f64; 3]; 3];
            let mut first = [0.0_f64; 3];
            for (o, w) in offsets(nb) {
                for a in 0..3 {
                    first[a] += f64::from(w) * o[a] as f64;
                    for b in 0..3 {
                        m2[a][b] += f64::from(w) * (o[a] * o[b]) as f64;
                    }
                }
            }
            for (a, row) in m2.iter().enumerate() {
                assert!(first[a].abs() < 1e-6, "{nb:?}");
                for (b, &moment) in row.iter().enumerate() {
                    let want = if a == b { 2.0 } else { 0.0 };
                    assert!((moment - want).abs() < 1e-6, "{nb:?} {a}{b}: {moment}");
                }
            }
        }
        let fourth = |nb: Neighbourhood, u: [f64; 3]| -> f64 {
            offsets(nb)
                .map(|(o, w)| {
                    let d: f64 = (0..3).map(|a| o[a] as f64 * u[a]).sum();
                    f64::from(w) * d.powi(4)
                })
                .sum()
        };
        let s = std::f64::consts::FRAC_1_SQRT_2;
        let ratio = |nb| fourth(nb, [s, s, 0.0]) / fourth(nb, [1.0, 0.0, 0.0]);
        assert!((ratio(Neighbourhood::Eighteen) - 1.0).abs() < 1e-6);
        // The six-neighbour stencil is half as stiff along a diagonal at fourth order; the
        // 26-neighbour one is closer to even.
        assert!((ratio(Neighbourhood::Six) - 0.5).abs() < 1e-6);
        let r26 = ratio(Neighbourhood::TwentySix);
        assert!(
            (r26 - 1.0).abs() < (ratio(Neighbourhood::Six) - 1.0).abs(),
            "{r26}"
        );
    }

    #[test]
    fn springs_match_a_direct_sum_and_vanish_at_rest() {
        let dims = [5, 4, 3];
        let n: usize = dims.iter().product();
        let d: Vec<f32> = (0..n).map(|i| ((i * 7) % 5) as f32 * 0.1).collect();
        let rest: Vec<f32> = (0..n).map(|i| ((i * 3) % 4) as f32 * 0.05).collect();
        let stiff: Vec<f32> = (0..n).map(|i| 1.0 + (i % 3) as f32).collect();
        for nb in Neighbourhood::ALL {
            let mut e = vec![0.0; n];
            let mut f = vec![0.0; n];
            add_spring_forces(dims, &d, &rest, &stiff, nb, &mut e, &mut f);
            for idx in 0..n {
                let c = [idx % 5, (idx / 5) % 4, idx / 20];
                let mut want = 0.0;
                for (o, w) in offsets(nb) {
                    let q = [c[0] as i64 + o[0], c[1] as i64 + o[1], c[2] as i64 + o[2]];
                    let ei = d[idx] - rest[idx];
                    if (0..3).all(|a| q[a] >= 0 && q[a] < dims[a] as i64) {
                        let qi = q[0] as usize + 5 * (q[1] as usize + 4 * q[2] as usize);
                        want += w * 0.5 * (stiff[idx] + stiff[qi]) * ((d[qi] - rest[qi]) - ei);
                    } else {
                        want -= w * stiff[idx] * ei;
                    }
                }
                assert!((f[idx] - want).abs() < 1e-5, "{nb:?} point {idx}");
            }
            let mut f0 = vec![0.0; n];
            add_spring_forces(dims, &d, &d, &stiff, nb, &mut e, &mut f0);
            assert!(f0.iter().all(|&v| v == 0.0));
        }
    }

    #[test]
    fn fused_six_kernel_matches_the_generic_springs() {
        for (dims, uniform) in [
            ([5, 4, 3], false),
            ([9, 3, 4], false),
            ([17, 5, 2], false),
            ([8, 8, 8], false),
            ([1, 2, 3], false),
            ([9, 3, 4], true),
            ([5, 4, 3], true),
        ] {
            let n: usize = dims.iter().product();
            let d: Vec<f32> = (0..n).map(|i| ((i * 7) % 5) as f32 * 0.1).collect();
            let rest: Vec<f32> = (0..n).map(|i| ((i * 3) % 4) as f32 * 0.05).collect();
            let stiff: Vec<f32> = (0..n)
                .map(|i| if uniform { 2.5 } else { 1.0 + (i % 3) as f32 })
                .collect();
            let ext: Vec<f32> = (0..n).map(|i| (i % 4) as f32).collect();
            let damping: Vec<f32> = (0..n).map(|i| 0.5 + (i % 2) as f32).collect();
            let d_dot: Vec<f32> = (0..n).map(|i| ((i * 5) % 3) as f32 - 1.0).collect();
            let mut want = ext.clone();
            let mut e = vec![0.0; n];
            add_spring_forces(
                dims,
                &d,
                &rest,
                &stiff,
                Neighbourhood::Six,
                &mut e,
                &mut want,
            );
            for ((f, &g), &v) in want.iter_mut().zip(&damping).zip(&d_dot) {
                *f -= g * v;
            }
            let padded = padded_row(dims[0]) * dims[1] * dims[2];
            let (mut e_pad, mut k_pad) = (vec![f32::NAN; padded], vec![f32::NAN; padded]);
            let mut got = vec![f32::NAN; n];
            let zeros = vec![0.0; dims[0]];
            // SAFETY: one thread.
            unsafe {
                six_pads(
                    dims,
                    &d,
                    &rest,
                    &stiff,
                    0..dims[2],
                    &SharedOut::new(&mut e_pad),
                    (!uniform).then_some(&SharedOut::new(&mut k_pad)),
                );
            }
            let inputs = SixInputs {
                dims,
                uniform_k: uniform.then_some(2.5),
                e_pad: &e_pad,
                k_pad: &k_pad,
                zeros: &zeros,
                external: &ext,
                damping: &damping,
                d_dot: &d_dot,
            };
            // SAFETY: one thread.
            unsafe { six_forces(&inputs, 0..dims[2], &SharedOut::new(&mut got), 0) };
            for (i, (g, w)) in got.iter().zip(&want).enumerate() {
                assert!((g - w).abs() < 1e-5, "{dims:?} point {i}: {g} vs {w}");
            }
            // The portable build gives the same bits as the one chosen for this CPU.
            let mut portable = vec![f32::NAN; n];
            // SAFETY: one thread.
            unsafe { six_forces_body(&inputs, 0..dims[2], &SharedOut::new(&mut portable), 0) };
            let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&portable), bits(&got), "{dims:?}");
        }
    }
}
