//! A weighted, regularised least-squares fit of a whole lattice to samples on its mass grid:
//! the coefficients `c` minimise
//!
//! `Σₛ wₛ (F(xₛ) − fₛ)² + λ Σ_axes ‖D₂ c‖²`
//!
//! where the samples `xₛ` are the grid of `samples_per_span` points per knot span over the
//! lattice (the grid `field::fit_lattice` samples), `wₛ` each sample's confidence, and `D₂`
//! the second difference of the coefficients along one axis (a discrete bending energy).
//! Where the data is sure (`wₛ` near 1) the fit follows it; where it is not (far from the
//! points, over a hole) the bending energy takes over and the clay stays smooth.
//!
//! The normal equations `(AᵀWA + λL) c = AᵀW f` are solved by conjugate gradients with a
//! Jacobi preconditioner, started from the plain least-squares fit. `A` is the Kronecker
//! product of three banded per-axis basis matrices, so each product with it is three passes
//! of four taps per sample: a few dozen flops per sample and iteration, no matrix stored.
//! Each pass is split over the machine's threads by planes of its output, every entry summed
//! in one fixed order, so the fit is the same bit for bit on any number of threads.

use dynaclay_core::field::{BSplineLattice, BrickedCoeffs};

/// The iterations stop when the residual falls below this fraction of the right-hand side.
pub const TOLERANCE: f64 = 1e-5;

/// The cubic B-spline centred on 0 (support `−2 < d < 2`, knot spacing 1).
fn cubic(d: f64) -> f64 {
    let a = d.abs();
    if a < 1.0 {
        (4.0 - 6.0 * a * a + 3.0 * a * a * a) / 6.0
    } else if a < 2.0 {
        (2.0 - a).powi(3) / 6.0
    } else {
        0.0
    }
}

/// One axis's basis matrix `A` (samples × coefficients), by rows and by columns.
struct AxisBasis {
    samples: usize,
    /// Per sample: the coefficients it reads and their weights (a row of `A`, at most four
    /// entries, zero weights left out).
    rows: Vec<Vec<(usize, f64)>>,
    /// Per coefficient: the samples its basis function reaches and their weights, samples
    /// ascending (a column of `A`: a row of `Aᵀ`).
    columns: Vec<Vec<(usize, f64)>>,
}

impl AxisBasis {
    fn new(coeffs: usize, samples_per_span: usize) -> Self {
        let samples = (coeffs - 1) * samples_per_span + 1;
        let mut columns = vec![Vec::new(); coeffs];
        let rows = (0..samples)
            .map(|s| {
                let u = s as f64 / samples_per_span as f64;
                let first = (u.floor() as i64 - 1).max(0) as usize;
                let mut row = Vec::with_capacity(4);
                for (i, column) in columns.iter_mut().enumerate().skip(first).take(4) {
                    let w = cubic(u - i as f64);
                    if w != 0.0 {
                        row.push((i, w));
                        column.push((s, w));
                    }
                }
                row
            })
            .collect();
        Self {
            samples,
            rows,
            columns,
        }
    }
}

/// Applies `A` (`forward`: coefficients to samples) or `Aᵀ` along `axis` of the 3-D array
/// `input` with dimensions `dims`, `matrix` being the rows of that matrix (`A`'s rows or its
/// columns, `out_len` of them), into `out` (resized to the result); returns the result's
/// dimensions. Each output entry is the sum over its row of the matrix, in the row's order,
/// computed by one of `threads` threads (each takes a run of whole z-planes of the output),
/// so the result does not depend on the thread count; then multiplied by its entry of
/// `weights`, when given (one per output entry).
///
/// NOTE: the output is cleared plane by plane on the threads that fill it, and weighted there
/// too: cleared and weighted in passes on the calling thread, the half-million samples of a
/// 40³ fit took about 10 ms of each import's serial time (bench/RESULTS.md, "Import wall
/// time"). Along y and z an output line is the weighted sum of whole input lines, added in
/// the matrix row's order (each entry sees the same sums in the same order as a sum per
/// entry, so the result is the same bit for bit), which the compiler vectorises; along x
/// each entry reads its four neighbours in one line. The passes write into buffers the
/// caller keeps, so the fit's twenty steps do not fault in fresh pages for every product
/// (page faults were 7% of an import in `perf record`).
fn along_axis(
    input: &[f64],
    dims: [usize; 3],
    axis: usize,
    matrix: &[Vec<(usize, f64)>],
    weights: Option<&[f32]>,
    out: &mut Vec<f64>,
    threads: usize,
) -> [usize; 3] {
    let mut out_dims = dims;
    out_dims[axis] = matrix.len();
    let [ox, oy, oz] = out_dims;
    let plane = ox * oy;
    let in_plane = dims[0] * dims[1];
    // Kept from the last product of the same size: each plane is cleared where it is filled.
    out.resize(plane * oz, 0.0);
    let fill = |first_plane: usize, slab: &mut [f64]| {
        for (dz, out_plane) in slab.chunks_exact_mut(plane).enumerate() {
            let z = first_plane + dz;
            if axis != 0 {
                out_plane.fill(0.0);
            }
            match axis {
                0 | 1 => plane_along(
                    &input[z * in_plane..(z + 1) * in_plane],
                    [dims[0], dims[1]],
                    axis,
                    matrix,
                    out_plane,
                ),
                _ => {
                    for &(t, w) in &matrix[z] {
                        let from = t * in_plane;
                        for (value, &v) in out_plane.iter_mut().zip(&input[from..from + plane]) {
                            *value += w * v;
                        }
                    }
                }
            }
            if let Some(weights) = weights {
                for (value, &w) in out_plane.iter_mut().zip(&weights[z * plane..]) {
                    *value *= f64::from(w);
                }
            }
        }
    };
    let threads = threads.clamp(1, oz.max(1));
    if threads == 1 || plane == 0 {
        fill(0, out);
    } else {
        let planes_per_thread = oz.div_ceil(threads);
        std::thread::scope(|scope| {
            let mut slabs = out.chunks_mut(planes_per_thread * plane).enumerate();
            // The calling thread fills the first slab itself (one thread fewer to start).
            let own = slabs.next();
            for (t, slab) in slabs {
                let fill = &fill;
                scope.spawn(move || fill(t * planes_per_thread, slab));
            }
            if let Some((t, slab)) = own {
                fill(t * planes_per_thread, slab);
            }
        });
    }
    out_dims
}

/// One z-plane of a pass along x (`axis` 0) or y (1): `input` is the plane, `[nx, ny]` its
/// size, `out` the output plane (every entry set along x; along y, zeros on entry).
fn plane_along(
    input: &[f64],
    [nx, ny]: [usize; 2],
    axis: usize,
    matrix: &[Vec<(usize, f64)>],
    out: &mut [f64],
) {
    if axis == 0 {
        for (line, input_line) in out
            .chunks_exact_mut(matrix.len().max(1))
            .zip(input.chunks_exact(nx.max(1)))
            .take(ny)
        {
            for (value, row) in line.iter_mut().zip(matrix) {
                let mut sum = 0.0;
                for &(t, w) in row {
                    sum += w * input_line[t];
                }
                *value = sum;
            }
        }
    } else {
        for (line, row) in out.chunks_exact_mut(nx.max(1)).zip(matrix) {
            for &(t, w) in row {
                let from = t * nx;
                for (value, &v) in line.iter_mut().zip(&input[from..from + nx]) {
                    *value += w * v;
                }
            }
        }
    }
}

/// The passes along x and then y (`matrices[0]`, then `matrices[1]`) of `input` (`dims`) into
/// `first` and `second`, on `threads` threads: both passes keep each z-plane to itself, so a
/// thread takes a run of whole planes through both, with one wait for the threads instead of
/// two. Returns the dimensions of `second`; its entries are [`along_axis`]'s, bit for bit.
fn along_x_then_y(
    input: &[f64],
    dims: [usize; 3],
    matrices: [&[Vec<(usize, f64)>]; 2],
    first: &mut Vec<f64>,
    second: &mut Vec<f64>,
    threads: usize,
) -> [usize; 3] {
    let first_dims = [matrices[0].len(), dims[1], dims[2]];
    let second_dims = [matrices[0].len(), matrices[1].len(), dims[2]];
    let plane = |d: [usize; 3]| d[0] * d[1];
    let (in_plane, first_plane, second_plane) =
        (plane(dims), plane(first_dims), plane(second_dims));
    // Kept from the last product of the same size: each plane is cleared where it is filled.
    first.resize(first_plane * dims[2], 0.0);
    second.resize(second_plane * dims[2], 0.0);
    if first_plane == 0 || second_plane == 0 {
        return second_dims;
    }
    let fill = |z0: usize, first: &mut [f64], second: &mut [f64]| {
        for (dz, (first, second)) in first
            .chunks_exact_mut(first_plane)
            .zip(second.chunks_exact_mut(second_plane))
            .enumerate()
        {
            let z = z0 + dz;
            let input = &input[z * in_plane..(z + 1) * in_plane];
            plane_along(input, [dims[0], dims[1]], 0, matrices[0], first);
            second.fill(0.0);
            plane_along(
                first,
                [first_dims[0], first_dims[1]],
                1,
                matrices[1],
                second,
            );
        }
    };
    let threads = threads.clamp(1, dims[2].max(1));
    if threads == 1 {
        fill(0, first, second);
    } else {
        let planes_per_thread = dims[2].div_ceil(threads);
        std::thread::scope(|scope| {
            let mut slabs = first
                .chunks_mut(planes_per_thread * first_plane)
                .zip(second.chunks_mut(planes_per_thread * second_plane))
                .enumerate();
            // The calling thread fills the first slab itself (one thread fewer to start).
            let own = slabs.next();
            for (t, (first, second)) in slabs {
                let fill = &fill;
                scope.spawn(move || fill(t * planes_per_thread, first, second));
            }
            if let Some((t, (first, second))) = own {
                fill(t * planes_per_thread, first, second);
            }
        });
    }
    second_dims
}

/// The buffers of [`apply`]'s passes, kept across the fit's steps.
#[derive(Default)]
struct Passes {
    first: Vec<f64>,
    second: Vec<f64>,
}

/// `A x` over the three axes (or `Aᵀ x`; with `squared`, the entrywise squares of `A`) into
/// `out`, each entry then multiplied by its entry of `weights` when given, on `threads`
/// threads.
#[allow(clippy::too_many_arguments)]
fn apply(
    x: &[f64],
    dims: [usize; 3],
    bases: &[AxisBasis; 3],
    forward: bool,
    squared: bool,
    weights: Option<&[f32]>,
    threads: usize,
    passes: &mut Passes,
    out: &mut Vec<f64>,
) {
    let matrix = |axis: usize| {
        let rows = if forward {
            &bases[axis].rows
        } else {
            &bases[axis].columns
        };
        if squared {
            std::borrow::Cow::Owned(
                rows.iter()
                    .map(|row| row.iter().map(|&(t, w)| (t, w * w)).collect())
                    .collect(),
            )
        } else {
            std::borrow::Cow::Borrowed(rows)
        }
    };
    let Passes { first, second } = passes;
    let d = along_x_then_y(x, dims, [&matrix(0), &matrix(1)], first, second, threads);
    along_axis(second, d, 2, &matrix(2), weights, out, threads);
}

/// `L x = Σ_axes D₂ᵀ D₂ x` on the coefficient grid, added to `out` times `lambda`.
fn add_bending(x: &[f64], dims: [usize; 3], lambda: f64, out: &mut [f64]) {
    let [nx, ny, nz] = dims;
    let strides = [1, nx, nx * ny];
    for axis in 0..3 {
        let n = dims[axis];
        if n < 3 {
            continue;
        }
        let st = strides[axis];
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    let c = [i, j, k];
                    if c[axis] + 2 >= n {
                        continue;
                    }
                    let at = i + nx * (j + ny * k);
                    let d = x[at] - 2.0 * x[at + st] + x[at + 2 * st];
                    out[at] += lambda * d;
                    out[at + st] -= 2.0 * lambda * d;
                    out[at + 2 * st] += lambda * d;
                }
            }
        }
    }
}

/// The diagonal of `L`.
fn bending_diagonal(dims: [usize; 3]) -> Vec<f64> {
    let mut e = vec![0.0; dims.iter().product()];
    let [nx, ny, _] = dims;
    for (at, v) in e.iter_mut().enumerate() {
        let c = [at % nx, (at / nx) % ny, at / (nx * ny)];
        for axis in 0..3 {
            let n = dims[axis] as i64;
            if n < 3 {
                continue;
            }
            // Rows r = c−2 ..= c of D₂ touch coefficient c with weights 1, −2, 1.
            for (offset, w) in [(2i64, 1.0), (1, 4.0), (0, 1.0)] {
                let r = c[axis] as i64 - offset;
                if r >= 0 && r + 2 < n {
                    *v += w;
                }
            }
        }
    }
    e
}

/// Refits every coefficient of `lattice` (its current coefficients the starting guess) to
/// `targets` with confidences `weights`, both given at the samples of the mass grid
/// (`samples_per_span` per span, x fastest), with bending weight `lambda` (see the module
/// docs), in at most `max_iterations` conjugate-gradient steps. Returns the steps run.
///
/// # Panics
/// When `targets` or `weights` do not hold one value per sample.
pub fn refit_regularised(
    lattice: &mut BSplineLattice,
    samples_per_span: usize,
    targets: &[f32],
    weights: &[f32],
    lambda: f32,
    max_iterations: usize,
) -> usize {
    let threads = std::thread::available_parallelism().map_or(1, std::num::NonZeroUsize::get);
    refit_regularised_on(
        lattice,
        samples_per_span,
        targets,
        weights,
        lambda,
        max_iterations,
        threads,
    )
}

/// [`refit_regularised`] with the products by `A` and `Aᵀ` split over `threads` threads; the
/// result is the same for any count.
fn refit_regularised_on(
    lattice: &mut BSplineLattice,
    samples_per_span: usize,
    targets: &[f32],
    weights: &[f32],
    lambda: f32,
    max_iterations: usize,
    threads: usize,
) -> usize {
    let dims = lattice.dims;
    let bases = dims.map(|n| AxisBasis::new(n, samples_per_span));
    let sample_dims = [bases[0].samples, bases[1].samples, bases[2].samples];
    let count: usize = sample_dims.iter().product();
    assert_eq!(targets.len(), count, "one target per sample");
    assert_eq!(weights.len(), count, "one weight per sample");
    let lambda = f64::from(lambda);
    let w: Vec<f64> = weights.iter().map(|&v| f64::from(v)).collect();
    let mut passes = Passes::default();
    let mut b = Vec::new();
    {
        let wf: Vec<f64> = targets
            .iter()
            .zip(&w)
            .map(|(&f, &w)| f64::from(f) * w)
            .collect();
        apply(
            &wf,
            sample_dims,
            &bases,
            false,
            false,
            None,
            threads,
            &mut passes,
            &mut b,
        );
    }
    let mut diagonal = Vec::new();
    apply(
        &w,
        sample_dims,
        &bases,
        false,
        true,
        None,
        threads,
        &mut passes,
        &mut diagonal,
    );
    // The weights as `f64` are not kept through the steps: the products convert them as
    // they weight the samples (the same values), 4 MB fewer for a 40³ fit.
    drop(w);
    for (d, l) in diagonal.iter_mut().zip(bending_diagonal(dims)) {
        *d = (*d + lambda * l).max(1e-12);
    }
    let mut at_samples = Vec::new();
    let mut operator = |x: &[f64], out: &mut Vec<f64>| {
        apply(
            x,
            dims,
            &bases,
            true,
            false,
            Some(weights),
            threads,
            &mut passes,
            &mut at_samples,
        );
        apply(
            &at_samples,
            sample_dims,
            &bases,
            false,
            false,
            None,
            threads,
            &mut passes,
            out,
        );
        add_bending(x, dims, lambda, out);
    };
    let mut x: Vec<f64> = lattice.coeffs.iter().map(|&c| f64::from(c)).collect();
    let mut ap = Vec::new();
    operator(&x, &mut ap);
    let mut r: Vec<f64> = b.iter().zip(&ap).map(|(b, a)| b - a).collect();
    let norm_b = b.iter().map(|v| v * v).sum::<f64>().sqrt().max(1e-30);
    let mut z: Vec<f64> = r.iter().zip(&diagonal).map(|(r, d)| r / d).collect();
    let mut p = z.clone();
    let mut rz: f64 = r.iter().zip(&z).map(|(a, b)| a * b).sum();
    let mut iterations = 0;
    while iterations < max_iterations {
        let norm_r = r.iter().map(|v| v * v).sum::<f64>().sqrt();
        if norm_r <= TOLERANCE * norm_b {
            break;
        }
        iterations += 1;
        operator(&p, &mut ap);
        let pap: f64 = p.iter().zip(&ap).map(|(a, b)| a * b).sum();
        if pap <= 0.0 {
            break;
        }
        let alpha = rz / pap;
        for ((x, r), (p, ap)) in x.iter_mut().zip(r.iter_mut()).zip(p.iter().zip(&ap)) {
            *x += alpha * p;
            *r -= alpha * ap;
        }
        for ((z, r), d) in z.iter_mut().zip(&r).zip(&diagonal) {
            *z = r / d;
        }
        let next: f64 = r.iter().zip(&z).map(|(a, b)| a * b).sum();
        let beta = next / rz;
        rz = next;
        for (p, z) in p.iter_mut().zip(&z) {
            *p = z + beta * *p;
        }
    }
    let dims = lattice.dims;
    let values: Vec<f32> = x.iter().map(|&v| v as f32).collect();
    lattice.coeffs = BrickedCoeffs::from_vec(dims, values);
    iterations
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn the_basis_matches_the_lattice_and_unit_weights_without_bending_recover_a_spline() {
        // A random-ish spline: its samples are fitted back exactly (the plain least squares
        // solution), starting from a guess off by up to 0.05 per coefficient.
        let dims = [7, 6, 8];
        let coeffs: Vec<f32> = (0..dims.iter().product::<usize>())
            .map(|i| ((i * 7919) % 23) as f32 / 23.0)
            .collect();
        let truth = BSplineLattice::from_coeffs(dims, 0.5, Vec3::ZERO, coeffs.clone()).unwrap();
        let sps = 2;
        let m = dims.map(|n| (n - 1) * sps + 1);
        let mut targets = Vec::new();
        for k in 0..m[2] {
            for j in 0..m[1] {
                for i in 0..m[0] {
                    let x = Vec3::new(i as f32, j as f32, k as f32) * 0.5 / sps as f32;
                    targets.push(truth.value(x));
                }
            }
        }
        let weights = vec![1.0; targets.len()];
        let guess = coeffs
            .iter()
            .enumerate()
            .map(|(i, c)| c + ((i * 31) % 11) as f32 / 11.0 * 0.1 - 0.05)
            .collect();
        let mut fitted = BSplineLattice::from_coeffs(dims, 0.5, Vec3::ZERO, guess).unwrap();
        let iterations = refit_regularised(&mut fitted, sps, &targets, &weights, 0.0, 400);
        assert!(iterations > 0);
        let mut at = 0;
        for k in 0..m[2] {
            for j in 0..m[1] {
                for i in 0..m[0] {
                    let x = Vec3::new(i as f32, j as f32, k as f32) * 0.5 / sps as f32;
                    let (got, want) = (fitted.value(x), targets[at]);
                    assert!((got - want).abs() < 1e-3, "at {x}: {got} vs {want}");
                    at += 1;
                }
            }
        }
    }

    /// The product along one axis as a plain sum per output entry (the definition).
    fn along_axis_plain(
        input: &[f64],
        dims: [usize; 3],
        axis: usize,
        matrix: &[Vec<(usize, f64)>],
    ) -> Vec<f64> {
        let mut out_dims = dims;
        out_dims[axis] = matrix.len();
        let strides = [1, dims[0], dims[0] * dims[1]];
        let mut out = Vec::new();
        for z in 0..out_dims[2] {
            for y in 0..out_dims[1] {
                for x in 0..out_dims[0] {
                    let at = [x, y, z];
                    let base: usize = (0..3)
                        .filter(|&a| a != axis)
                        .map(|a| at[a] * strides[a])
                        .sum();
                    let mut sum = 0.0;
                    for &(t, w) in &matrix[at[axis]] {
                        sum += w * input[base + t * strides[axis]];
                    }
                    out.push(sum);
                }
            }
        }
        out
    }

    #[test]
    fn each_pass_is_the_plain_sum_per_entry_bit_for_bit() {
        let basis = [
            AxisBasis::new(6, 2),
            AxisBasis::new(5, 3),
            AxisBasis::new(7, 2),
        ];
        for axis in 0..3 {
            for forward in [true, false] {
                let mut dims = [9, 8, 10];
                dims[axis] = if forward {
                    basis[axis].columns.len()
                } else {
                    basis[axis].samples
                };
                let input: Vec<f64> = (0..dims.iter().product::<usize>())
                    .map(|i| ((i * 7919) % 101) as f64 / 101.0 - 0.37)
                    .collect();
                let matrix = if forward {
                    &basis[axis].rows
                } else {
                    &basis[axis].columns
                };
                let plain = along_axis_plain(&input, dims, axis, matrix);
                for threads in [1, 3] {
                    let mut out = vec![5.0; 3];
                    along_axis(&input, dims, axis, matrix, None, &mut out, threads);
                    assert!(
                        out.iter()
                            .map(|v| v.to_bits())
                            .eq(plain.iter().map(|v| v.to_bits())),
                        "axis {axis}, forward {forward}, {threads} threads"
                    );
                }
            }
        }
    }

    #[test]
    fn the_passes_along_x_then_y_are_the_two_single_passes_bit_for_bit() {
        let basis = [AxisBasis::new(6, 2), AxisBasis::new(5, 3)];
        for forward in [true, false] {
            let pick = |b: &AxisBasis| if forward { b.columns.len() } else { b.samples };
            let dims = [pick(&basis[0]), pick(&basis[1]), 7];
            let input: Vec<f64> = (0..dims.iter().product::<usize>())
                .map(|i| ((i * 7919) % 101) as f64 / 101.0 - 0.37)
                .collect();
            let matrix = |b: &AxisBasis| {
                if forward {
                    b.rows.clone()
                } else {
                    b.columns.clone()
                }
            };
            let (m0, m1) = (matrix(&basis[0]), matrix(&basis[1]));
            let mut one = Vec::new();
            let d = along_axis(&input, dims, 0, &m0, None, &mut one, 1);
            let mut two = Vec::new();
            let want_dims = along_axis(&one, d, 1, &m1, None, &mut two, 1);
            for threads in [1, 2, 3] {
                let (mut first, mut second) = (vec![9.0; 2], vec![4.0; 5]);
                let got_dims =
                    along_x_then_y(&input, dims, [&m0, &m1], &mut first, &mut second, threads);
                assert_eq!(got_dims, want_dims);
                assert!(
                    second
                        .iter()
                        .map(|v| v.to_bits())
                        .eq(two.iter().map(|v| v.to_bits())),
                    "forward {forward}, {threads} threads"
                );
            }
        }
    }

    #[test]
    fn the_refit_is_the_same_on_one_thread_and_on_several() {
        // Uneven weights and a bending energy, a few steps from zero: every coefficient must
        // come out bit for bit the same whatever the thread count.
        let dims = [9, 7, 11];
        let sps = 2;
        let m = dims.map(|n| (n - 1) * sps + 1);
        let count = m.iter().product::<usize>();
        let targets: Vec<f32> = (0..count)
            .map(|s| ((s * 7919) % 101) as f32 / 101.0)
            .collect();
        let weights: Vec<f32> = (0..count)
            .map(|s| 0.1 + ((s * 31) % 17) as f32 / 17.0)
            .collect();
        let fit = |threads: usize| {
            let mut lattice = BSplineLattice::zeros(dims, 0.5, Vec3::ZERO).unwrap();
            let steps =
                refit_regularised_on(&mut lattice, sps, &targets, &weights, 0.01, 12, threads);
            (steps, lattice.coeffs)
        };
        let (steps, one) = fit(1);
        assert_eq!(steps, 12, "the tolerance is not reached in a dozen steps");
        assert!(one.iter().any(|&c| c != 0.0));
        for threads in [2, 3, 8] {
            assert_eq!(fit(threads), (steps, one.clone()), "{threads} threads");
        }
    }

    #[test]
    fn bending_smooths_what_the_data_does_not_hold() {
        // Samples only on the x = low half (weight 1), none on the rest (weight 0): with the
        // bending energy the unheld half continues the held one's linear ramp.
        let dims = [12, 5, 5];
        let sps = 2;
        let m = dims.map(|n| (n - 1) * sps + 1);
        let (mut targets, mut weights) = (Vec::new(), Vec::new());
        for _k in 0..m[2] {
            for _j in 0..m[1] {
                for i in 0..m[0] {
                    let u = i as f32 / sps as f32;
                    targets.push(if u < 5.0 { 0.1 * u } else { 0.0 });
                    weights.push(if u < 5.0 { 1.0 } else { 0.0 });
                }
            }
        }
        let mut lattice = BSplineLattice::zeros(dims, 1.0, Vec3::ZERO).unwrap();
        refit_regularised(&mut lattice, sps, &targets, &weights, 0.05, 400);
        let at = |u: f32| lattice.value(Vec3::new(u, 2.0, 2.0));
        // (Against the lattice's low edge a ramp is only approximated.)
        assert!((at(3.0) - 0.3).abs() < 0.02, "held: {}", at(3.0));
        // Bent as little as it can be, the unheld half carries the ramp on (the distortion
        // at the low edge tilts it a little) instead of dropping to the unheld targets.
        assert!((at(8.0) - 0.8).abs() < 0.1, "continued: {}", at(8.0));
        assert!(at(6.0) > at(5.0) && at(8.0) > at(6.0) && at(10.0) > at(8.0));
    }
}
