//! The coarse springs of a detail patch's region: a two-level material, so a patch's clay
//! resists a shape as large as the base's mass spacing as the base does, and a finer shape as
//! weakly as its own volume-scaled springs.
//!
//! Guarantee: pure passes over borrowed slices; no allocation, no lock, work linear in the
//! region's mass points (three separable sweeps down, one six-neighbour pass on the coarse
//! grid, three sweeps up).
//!
//! Why. A detail patch's mass points hold `1/r³` of a base point's volume (`r` the spacing
//! ratio), and take mass, damping and stiffness scaled by it. The springs are a discrete
//! Laplacian in units of the spacing, `ρ h² ∇²e`, so a dent of a given size in the world is
//! restored `r²` more weakly on the patch than on the base: a stiff painted half springs back
//! like a softer one. Scaling the stiffness by the spacing instead (the springs' energy
//! `½ρ∫|∇e|²`) restores the coarse shapes but smooths the fine ones the patch exists for (a
//! narrow push's groove comes out 30% wider). Here the patch keeps its volume-scaled springs
//! for every shape and adds springs between coarse points one base mass spacing apart (every
//! `r`-th mass point) on the deviation from rest restricted to them, `E = R e` (each coarse
//! point the hat-weighted mean of the fine points within one coarse spacing). Their force,
//! `f = Rᵀ L E`, is the exact gradient of their energy `½ Σ k̄ (E_n − E_j)²`, so the step stays
//! conservative. A shape smooth over a coarse spacing meets `ρ_c H² ∇²e / r³` from them per
//! fine point; with `ρ_c = (r³ − r) ρ` (`ρ` the fine point's volume-scaled stiffness) the two
//! levels together give the base's `ρ_base H² ∇²e / r³` exactly. A shape finer than a coarse
//! spacing is averaged away by `R` and meets (almost) only the fine springs.
//!
//! The coarse springs join coarse points inside the region only (no anchor to the fixed clay
//! around it): the region of a patch holds as many of its own knot spans as a base region, so
//! it is `r` times smaller in the world, and anchoring base-strength springs at its walls held
//! a press there to a third of its depth. The volume-scaled fine springs anchor the region as
//! on the base.

/// Scratch and shape of the coarse springs over one region.
#[derive(Debug, Default)]
pub(crate) struct CoarseScratch {
    /// After the x sweep: coarse in x, fine in y and z.
    x_swept: Vec<f32>,
    /// After the y sweep: coarse in x and y, fine in z.
    xy_swept: Vec<f32>,
    /// The restricted deviation `E` on the coarse grid.
    coarse_e: Vec<f32>,
    /// The coarse springs' force, over each coarse point's total weight.
    coarse_f: Vec<f32>,
    /// The coarse springs' stiffness at each coarse point.
    coarse_k: Vec<f32>,
}

/// Coarse points along an axis of `fine` mass points, one every `stride`: the last one lies at
/// or past the last fine point, so every fine point is within one coarse spacing of two (or of
/// one at the far end).
#[must_use]
pub(crate) fn coarse_count(fine: usize, stride: usize) -> usize {
    if fine == 0 {
        return 0;
    }
    (fine - 1).div_ceil(stride) + 1
}

/// The hat weight of fine index `i` for the coarse point at fine index `c`: `1 − |i − c| / r`
/// within one coarse spacing, 0 beyond.
#[inline]
fn hat(i: usize, c: usize, stride: usize) -> f32 {
    let off = i.abs_diff(c);
    if off >= stride {
        0.0
    } else {
        1.0 - off as f32 / stride as f32
    }
}

/// The one or two coarse points (of `coarse` along the axis) whose hats reach fine index `i`,
/// with their weights there.
fn hats_reaching(i: usize, coarse: usize, stride: usize) -> impl Iterator<Item = (usize, f32)> {
    let below = i / stride;
    [below, below + 1]
        .into_iter()
        .filter(move |&j| j < coarse)
        .map(move |j| (j, hat(i, j * stride, stride)))
        .filter(|&(_, w)| w != 0.0)
}

/// The total hat weight of the coarse point `j` over `fine` points along an axis.
fn hat_total(j: usize, fine: usize, stride: usize) -> f32 {
    let c = j * stride;
    let lo = c.saturating_sub(stride - 1);
    let hi = (c + stride - 1).min(fine - 1);
    (lo..=hi).map(|i| hat(i, c, stride)).sum()
}

/// The restriction along one axis: `out[.., j, ..] = Σ_i hat(i, j r) src[.., i, ..]`, for an
/// array of `outer × fine × inner` values (the axis in the middle) into `outer × coarse ×
/// inner`.
fn restrict_axis(
    src: &[f32],
    (outer, fine, inner): (usize, usize, usize),
    stride: usize,
    out: &mut [f32],
) {
    let coarse = coarse_count(fine, stride);
    out[..outer * coarse * inner].fill(0.0);
    for o in 0..outer {
        for i in 0..fine {
            let row = &src[(o * fine + i) * inner..(o * fine + i + 1) * inner];
            for (j, w) in hats_reaching(i, coarse, stride) {
                let dst = &mut out[(o * coarse + j) * inner..(o * coarse + j + 1) * inner];
                for (d, &s) in dst.iter_mut().zip(row) {
                    *d += w * s;
                }
            }
        }
    }
}

/// The transpose of [`restrict_axis`]: `out[.., i, ..] = Σ_j hat(i, j r) src[.., j, ..]` (set,
/// or added when `add`).
fn prolong_axis(
    src: &[f32],
    (outer, fine, inner): (usize, usize, usize),
    stride: usize,
    out: &mut [f32],
    add: bool,
) {
    let coarse = coarse_count(fine, stride);
    for o in 0..outer {
        for i in 0..fine {
            let dst = &mut out[(o * fine + i) * inner..(o * fine + i + 1) * inner];
            if !add {
                dst.fill(0.0);
            }
            for (j, w) in hats_reaching(i, coarse, stride) {
                let row = &src[(o * coarse + j) * inner..(o * coarse + j + 1) * inner];
                for (d, &s) in dst.iter_mut().zip(row) {
                    *d += w * s;
                }
            }
        }
    }
}

/// The fine stiffness times this gives the coarse springs' stiffness, for coarse points
/// `stride` mass points apart on a patch of spacing ratio `ratio` to the base (see the
/// module's notes): a smooth shape meets `ρ_c h² ∇²e / S` from the coarse springs and
/// `ρ h² ∇²e` from the fine ones per fine point, and the base's `r³ ρ (r h)² ∇²e / r³`, so
/// `ρ_c = S (r² − 1) ρ`.
#[must_use]
pub(crate) fn coarse_gain(stride: usize, ratio: usize) -> f32 {
    let r = ratio as f32;
    stride as f32 * (r * r - 1.0)
}

impl CoarseScratch {
    /// Adds the coarse springs' force on the deviation `d − rest` of a region of `dims` mass
    /// points (x fastest) to `force`, with coarse points every `stride` mass points on a
    /// patch of spacing ratio `ratio` to the base; the coarse stiffness at a coarse point is
    /// the fine `stiffness` there times [`coarse_gain`]. Nothing for a stride or a ratio
    /// below 2. Allocates only when the region is larger
    /// than any before.
    ///
    /// # Panics
    /// When a slice is shorter than `dims`' count.
    #[allow(clippy::too_many_arguments)] // the fields of one region
    pub(crate) fn add_forces(
        &mut self,
        dims: [usize; 3],
        (stride, ratio): (usize, usize),
        d: &[f32],
        rest: &[f32],
        stiffness: &[f32],
        e: &mut [f32],
        force: &mut [f32],
    ) {
        if stride < 2 || ratio < 2 {
            return;
        }
        let [mx, my, mz] = dims;
        let n = mx * my * mz;
        if n == 0 {
            return;
        }
        let c = [mx, my, mz].map(|m| coarse_count(m, stride));
        let nc = c[0] * c[1] * c[2];
        fit(&mut self.x_swept, c[0] * my * mz);
        fit(&mut self.xy_swept, c[0] * c[1] * mz);
        fit(&mut self.coarse_e, nc);
        fit(&mut self.coarse_f, nc);
        fit(&mut self.coarse_k, nc);

        for ((e, &d), &r) in e[..n].iter_mut().zip(&d[..n]).zip(&rest[..n]) {
            *e = d - r;
        }
        // Down: x (fastest, so `inner` 1), then y, then z.
        restrict_axis(&e[..n], (my * mz, mx, 1), stride, &mut self.x_swept);
        restrict_axis(&self.x_swept, (mz, my, c[0]), stride, &mut self.xy_swept);
        restrict_axis(
            &self.xy_swept,
            (1, mz, c[0] * c[1]),
            stride,
            &mut self.coarse_e,
        );
        let gain = coarse_gain(stride, ratio);
        for kc in 0..c[2] {
            let wz = hat_total(kc, mz, stride);
            let fz = (kc * stride).min(mz - 1);
            for jc in 0..c[1] {
                let wy = hat_total(jc, my, stride);
                let fy = (jc * stride).min(my - 1);
                for ic in 0..c[0] {
                    let wx = hat_total(ic, mx, stride);
                    let fx = (ic * stride).min(mx - 1);
                    let at = ic + c[0] * (jc + c[1] * kc);
                    // Weight totals are positive: every coarse point's hat holds its own fine
                    // point or the last fine point within one spacing.
                    self.coarse_e[at] /= wx * wy * wz;
                    self.coarse_k[at] = gain * stiffness[fx + mx * (fy + my * fz)];
                }
            }
        }
        // The coarse six-neighbour springs, between coarse points of the grid only.
        let (ce, ck) = (&self.coarse_e, &self.coarse_k);
        for kc in 0..c[2] {
            let wz = hat_total(kc, mz, stride);
            for jc in 0..c[1] {
                let wy = hat_total(jc, my, stride);
                for ic in 0..c[0] {
                    let wx = hat_total(ic, mx, stride);
                    let at = ic + c[0] * (jc + c[1] * kc);
                    let (e0, k0) = (ce[at], ck[at]);
                    let mut acc = 0.0;
                    let mut spring = |other: usize| {
                        acc += 0.5 * (k0 + ck[other]) * (ce[other] - e0);
                    };
                    if ic > 0 {
                        spring(at - 1);
                    }
                    if ic + 1 < c[0] {
                        spring(at + 1);
                    }
                    if jc > 0 {
                        spring(at - c[0]);
                    }
                    if jc + 1 < c[1] {
                        spring(at + c[0]);
                    }
                    if kc > 0 {
                        spring(at - c[0] * c[1]);
                    }
                    if kc + 1 < c[2] {
                        spring(at + c[0] * c[1]);
                    }
                    // `Rᵀ`: the row of R for this coarse point is its hat over its total.
                    self.coarse_f[at] = acc / (wx * wy * wz);
                }
            }
        }
        // Up: z, then y, then x, added onto the force.
        prolong_axis(
            &self.coarse_f,
            (1, mz, c[0] * c[1]),
            stride,
            &mut self.xy_swept,
            false,
        );
        prolong_axis(
            &self.xy_swept,
            (mz, my, c[0]),
            stride,
            &mut self.x_swept,
            false,
        );
        prolong_axis(
            &self.x_swept,
            (my * mz, mx, 1),
            stride,
            &mut force[..n],
            true,
        );
    }
}

fn fit(v: &mut Vec<f32>, len: usize) {
    if v.len() != len {
        v.resize(len, 0.0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dynamics::Neighbourhood;
    use crate::dynamics::springs::add_spring_forces;

    fn coarse_force(dims: [usize; 3], stride: usize, e: &[f32], k: &[f32]) -> Vec<f32> {
        let n = e.len();
        let rest = vec![0.0; n];
        let mut scratch = CoarseScratch::default();
        let mut tmp = vec![0.0; n];
        let mut f = vec![0.0; n];
        scratch.add_forces(dims, (stride, stride), e, &rest, k, &mut tmp, &mut f);
        f
    }

    /// The energy `½ Σ k̄ (E_n − E_j)²` of the coarse springs, computed directly.
    fn coarse_energy(dims: [usize; 3], stride: usize, e: &[f32], k: &[f32]) -> f64 {
        let c = dims.map(|m| coarse_count(m, stride));
        let mut big_e = vec![0.0_f64; c[0] * c[1] * c[2]];
        let mut big_k = vec![0.0_f64; big_e.len()];
        for kc in 0..c[2] {
            for jc in 0..c[1] {
                for ic in 0..c[0] {
                    let (mut sum, mut total) = (0.0_f64, 0.0_f64);
                    for z in 0..dims[2] {
                        for y in 0..dims[1] {
                            for x in 0..dims[0] {
                                let w = f64::from(hat(x, ic * stride, stride))
                                    * f64::from(hat(y, jc * stride, stride))
                                    * f64::from(hat(z, kc * stride, stride));
                                sum += w * f64::from(e[x + dims[0] * (y + dims[1] * z)]);
                                total += w;
                            }
                        }
                    }
                    let at = ic + c[0] * (jc + c[1] * kc);
                    big_e[at] = sum / total;
                    let f = [ic, jc, kc].map(|j| j * stride);
                    let f = [0, 1, 2].map(|a| f[a].min(dims[a] - 1));
                    big_k[at] = f64::from(coarse_gain(stride, stride))
                        * f64::from(k[f[0] + dims[0] * (f[1] + dims[1] * f[2])]);
                }
            }
        }
        let mut u = 0.0;
        for kc in 0..c[2] {
            for jc in 0..c[1] {
                for ic in 0..c[0] {
                    let at = ic + c[0] * (jc + c[1] * kc);
                    let mut one = |other: usize| {
                        let kk = 0.5 * (big_k[at] + big_k[other]);
                        u += 0.5 * kk * (big_e[other] - big_e[at]).powi(2);
                    };
                    if ic + 1 < c[0] {
                        one(at + 1);
                    }
                    if jc + 1 < c[1] {
                        one(at + c[0]);
                    }
                    if kc + 1 < c[2] {
                        one(at + c[0] * c[1]);
                    }
                }
            }
        }
        u
    }

    #[test]
    fn coarse_counts_cover_every_fine_point() {
        assert_eq!(coarse_count(9, 2), 5);
        assert_eq!(coarse_count(10, 2), 6);
        assert_eq!(coarse_count(17, 4), 5);
        assert_eq!(coarse_count(18, 4), 6);
        assert_eq!(coarse_count(1, 4), 1);
        for (fine, stride) in [(9, 2), (10, 2), (17, 4), (19, 8)] {
            for i in 0..fine {
                let covered: f32 = (0..coarse_count(fine, stride))
                    .map(|j| hat(i, j * stride, stride))
                    .sum();
                assert!(
                    (covered - 1.0).abs() < 1e-6,
                    "{fine} {stride} {i}: {covered}"
                );
            }
        }
    }

    /// The force is minus the gradient of the coarse springs' energy (checked by central
    /// differences on an uneven deviation and stiffness): the coarse springs conserve energy
    /// as the fine ones do.
    #[test]
    fn the_coarse_force_is_the_gradient_of_the_coarse_energy() {
        for (dims, stride) in [([9, 7, 6], 2), ([13, 9, 10], 4)] {
            let n: usize = dims.iter().product();
            let e: Vec<f32> = (0..n).map(|i| ((i * 7) % 11) as f32 * 0.01).collect();
            let k: Vec<f32> = (0..n).map(|i| 1.0 + (i % 5) as f32 * 0.2).collect();
            let f = coarse_force(dims, stride, &e, &k);
            for probe in [0, n / 3, n / 2, n - 1] {
                let h = 1e-2_f32;
                let (mut up, mut down) = (e.clone(), e.clone());
                up[probe] += h;
                down[probe] -= h;
                let grad = (coarse_energy(dims, stride, &up, &k)
                    - coarse_energy(dims, stride, &down, &k))
                    / (2.0 * f64::from(h));
                assert!(
                    (f64::from(f[probe]) + grad).abs() < 1e-3 * (1.0 + grad.abs()),
                    "{dims:?}/{stride} point {probe}: force {} against −∇U {}",
                    f[probe],
                    -grad
                );
            }
        }
    }

    /// A uniform or linear deviation meets no coarse force inside the region (the coarse
    /// springs do not anchor); a quadratic one meets, with the fine springs, the base's force
    /// per volume: `(r³ − r) ρ H² ∇²e / r³` plus `ρ h² ∇²e` is `r³ ρ H² ∇²e / r³` with
    /// `H = r h`.
    #[test]
    fn two_levels_restore_a_smooth_shape_as_the_base_does() {
        let stride = 4;
        let dims = [33, 33, 33];
        let n: usize = dims.iter().product();
        let rho = 2.0_f32;
        let k = vec![rho; n];
        let at = |x: usize, y: usize, z: usize| x + dims[0] * (y + dims[1] * z);
        // Uniform and linear: no coarse force (the ends of a linear ramp aside: the hat is
        // cut there, so test away from them).
        for lin in [[0.0, 0.0, 0.0], [0.01, -0.02, 0.005]] {
            let mut e = vec![0.0; n];
            for z in 0..dims[2] {
                for y in 0..dims[1] {
                    for x in 0..dims[0] {
                        e[at(x, y, z)] =
                            0.3 + lin[0] * x as f32 + lin[1] * y as f32 + lin[2] * z as f32;
                    }
                }
            }
            let f = coarse_force(dims, stride, &e, &k);
            for z in 8..25 {
                for y in 8..25 {
                    for x in 8..25 {
                        assert!(f[at(x, y, z)].abs() < 1e-4, "{lin:?} at {x},{y},{z}");
                    }
                }
            }
        }
        // Quadratic along x: e = c x² (fine units), ∇²e = 2c per fine spacing squared.
        let c = 1e-3_f32;
        let mut e = vec![0.0; n];
        for z in 0..dims[2] {
            for y in 0..dims[1] {
                for x in 0..dims[0] {
                    e[at(x, y, z)] = c * (x as f32 - 16.0).powi(2);
                }
            }
        }
        let coarse = coarse_force(dims, stride, &e, &k);
        let mut fine = vec![0.0; n];
        let mut tmp = vec![0.0; n];
        add_spring_forces(
            dims,
            &e,
            &vec![0.0; n],
            &k,
            Neighbourhood::Six,
            &mut tmp,
            &mut fine,
        );
        // The base: stiffness r³ ρ on points r apart: r³ ρ (r² · 2c) per base point, over r³
        // fine points.
        let r = stride as f32;
        let base_per_fine = rho * r * r * 2.0 * c;
        for x in [12, 14, 16, 18, 20] {
            let p = at(x, 16, 16);
            let total = coarse[p] + fine[p];
            assert!(
                (total - base_per_fine).abs() < 0.02 * base_per_fine,
                "x {x}: coarse {} + fine {} against the base's {base_per_fine}",
                coarse[p],
                fine[p]
            );
        }
    }

    /// A shape finer than a coarse spacing (a one-point spike) meets a coarse force far
    /// smaller than a coarse-sized dent of the same depth: the fine detail is left to the
    /// volume-scaled springs.
    #[test]
    fn a_fine_spike_meets_little_of_the_coarse_springs() {
        let stride = 4;
        let dims = [25, 25, 25];
        let n: usize = dims.iter().product();
        let k = vec![1.0; n];
        let at = |x: usize, y: usize, z: usize| x + dims[0] * (y + dims[1] * z);
        let mut spike = vec![0.0; n];
        spike[at(13, 13, 13)] = -0.1;
        let mut dent = vec![0.0; n];
        for z in 0..dims[2] {
            for y in 0..dims[1] {
                for x in 0..dims[0] {
                    let r2 = [x, y, z]
                        .iter()
                        .map(|&v| (v as f32 - 12.0).powi(2))
                        .sum::<f32>();
                    dent[at(x, y, z)] = -0.1 * (-r2 / (2.0 * 16.0)).exp();
                }
            }
        }
        let on_spike = coarse_force(dims, stride, &spike, &k)[at(13, 13, 13)];
        let on_dent = coarse_force(dims, stride, &dent, &k)[at(12, 12, 12)];
        assert!(on_spike > 0.0 && on_dent > 0.0, "{on_spike} {on_dent}");
        assert!(
            on_spike < 0.05 * on_dent,
            "spike {on_spike}, dent {on_dent}"
        );
    }
}
