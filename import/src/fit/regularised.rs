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
//! Jacobi preconditioner, started from the plain least-squares fit ([`fit_regularised`]
//! finds it here: `c₀ = (AᵀA)⁻¹ Aᵀ f`, with `AᵀA` the Kronecker product of the three axes'
//! banded Gram matrices, solved by their Cholesky factors one axis at a time). `A` is the Kronecker
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

/// The Cholesky factor `L` of one axis's Gram matrix `AᵀA` (`LLᵀ = AᵀA`; banded, half-bandwidth
/// at most 3 for the cubic B-spline), dense by rows.
struct GramFactor {
    n: usize,
    /// `L[i][j]` at `i · n + j`, zero above the diagonal and beyond the band.
    lower: Vec<f64>,
}

/// Half-bandwidth of a cubic B-spline Gram matrix: coefficients four or more apart share no
/// sample.
const GRAM_BAND: usize = 3;

impl GramFactor {
    /// The factor of `AᵀA` for `basis` (`None` where it is not positive definite: fewer
    /// samples than coefficients).
    fn of(basis: &AxisBasis) -> Option<Self> {
        let n = basis.columns.len();
        let mut gram = vec![0.0f64; n * n];
        for row in &basis.rows {
            for &(i, wi) in row {
                for &(j, wj) in row {
                    gram[i * n + j] += wi * wj;
                }
            }
        }
        let mut lower = vec![0.0f64; n * n];
        for j in 0..n {
            let first = j.saturating_sub(GRAM_BAND);
            let mut pivot = gram[j * n + j];
            for k in first..j {
                pivot -= lower[j * n + k] * lower[j * n + k];
            }
            // Not positive (or not a number): no factor.
            if pivot.is_nan() || pivot <= 0.0 {
                return None;
            }
            let pivot = pivot.sqrt();
            lower[j * n + j] = pivot;
            for i in j + 1..(j + 1 + GRAM_BAND).min(n) {
                let mut sum = gram[i * n + j];
                for k in i.saturating_sub(GRAM_BAND)..j {
                    sum -= lower[i * n + k] * lower[j * n + k];
                }
                lower[i * n + j] = sum / pivot;
            }
        }
        Some(Self { n, lower })
    }

    /// Solves `AᵀA y = x` along `axis` of the 3-D array `x` (dimensions `dims`, x fastest),
    /// in place: for every line along the axis, forward then back substitution. The lines are
    /// handled `inner` entries at a time (every line through a plane across the axis
    /// together), so the inner loops run over contiguous memory.
    fn solve_along(&self, x: &mut [f64], dims: [usize; 3], axis: usize) {
        let n = self.n;
        debug_assert_eq!(dims[axis], n);
        let inner: usize = dims[..axis].iter().product();
        let outer: usize = dims[axis + 1..].iter().product();
        let l = |i: usize, j: usize| self.lower[i * n + j];
        for block in x.chunks_exact_mut(inner * n).take(outer) {
            // Forward: `y[t] = (x[t] − Σ L[t][k] y[k]) / L[t][t]`.
            for t in 0..n {
                let (done, rest) = block.split_at_mut(t * inner);
                let line = &mut rest[..inner];
                for k in t.saturating_sub(GRAM_BAND)..t {
                    let w = l(t, k);
                    for (v, &y) in line.iter_mut().zip(&done[k * inner..(k + 1) * inner]) {
                        *v -= w * y;
                    }
                }
                let pivot = l(t, t);
                for v in line.iter_mut() {
                    *v /= pivot;
                }
            }
            // Back: `x[t] = (y[t] − Σ L[k][t] x[k]) / L[t][t]`.
            for t in (0..n).rev() {
                let (head, done) = block.split_at_mut((t + 1) * inner);
                let line = &mut head[t * inner..];
                for k in t + 1..(t + 1 + GRAM_BAND).min(n) {
                    let w = l(k, t);
                    let from = (k - t - 1) * inner;
                    for (v, &y) in line.iter_mut().zip(&done[from..from + inner]) {
                        *v -= w * y;
                    }
                }
                let pivot = l(t, t);
                for v in line.iter_mut() {
                    *v /= pivot;
                }
            }
        }
    }
}

/// Applies `A` (`forward`: coefficients to samples) or `Aᵀ` along `axis` of the 3-D array
/// `input` with dimensions `dims`, `matrix` being the rows of that matrix (`A`'s rows or its
/// columns, `out_len` of them), into `out` (resized to the result); returns the result's
/// dimensions. Each output entry is the sum over its row of the matrix, in the row's order,
/// computed by one of `threads` threads (each takes a run of whole z-planes of the output),
/// so the result does not depend on the thread count; then multiplied by its entry of
/// `weights`, when given (one per output entry); then each output z-plane handed to
/// `finish`, when given, with its `z`, on the thread that filled it.
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
#[allow(clippy::too_many_arguments)]
fn along_axis(
    input: &[f64],
    dims: [usize; 3],
    axis: usize,
    matrix: &[Vec<(usize, f64)>],
    weights: Option<&[f32]>,
    finish: Option<&PlaneFinish<'_>>,
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
    let taps = if axis == 0 {
        TapRows::of(matrix, dims[0])
    } else {
        None
    };
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
                    taps.as_ref(),
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
            if let Some(finish) = finish {
                finish(z, out_plane);
            }
        }
    };
    fill_slabs_on_threads(out, plane, oz, threads, fill);
    out_dims
}

/// Calls `fill(first_plane, slab)` over `out` cut into slabs of whole planes of `plane_len`
/// values each (`planes` planes in all), one slab per thread on up to `threads` threads; the
/// calling thread fills the first slab itself (one thread fewer to start).
fn fill_slabs_on_threads(
    out: &mut [f64],
    plane_len: usize,
    planes: usize,
    threads: usize,
    fill: impl Fn(usize, &mut [f64]) + Sync,
) {
    let threads = threads.clamp(1, planes.max(1));
    if threads == 1 || plane_len == 0 {
        fill(0, out);
        return;
    }
    let planes_per_thread = planes.div_ceil(threads);
    std::thread::scope(|scope| {
        let mut slabs = out.chunks_mut(planes_per_thread * plane_len).enumerate();
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

/// One z-plane of a pass along x (`axis` 0) or y (1): `input` is the plane, `[nx, ny]` its
/// size, `out` the output plane (every entry set along x; along y, zeros on entry); along x,
/// `taps` is `matrix` as [`TapRows`] where it can be.
fn plane_along(
    input: &[f64],
    [nx, ny]: [usize; 2],
    axis: usize,
    matrix: &[Vec<(usize, f64)>],
    taps: Option<&TapRows>,
    out: &mut [f64],
) {
    if axis == 0 {
        let lines = out
            .chunks_exact_mut(matrix.len().max(1))
            .zip(input.chunks_exact(nx.max(1)))
            .take(ny);
        match taps {
            Some(taps) => {
                for (line, input_line) in lines {
                    taps.line(input_line, line);
                }
            }
            None => {
                for (line, input_line) in lines {
                    for (value, row) in line.iter_mut().zip(matrix) {
                        let mut sum = 0.0;
                        for &(t, w) in row {
                            sum += w * input_line[t];
                        }
                        *value = sum;
                    }
                }
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

/// A matrix's rows, each a run of consecutive columns, as windows of a fixed width (4, 8, 12
/// or 16 columns) with their weights, zero outside the run: each entry of a product is the sum
/// of its window's products in the columns' order, the same value bit for bit as the sum over
/// the run alone (a zero weight times a finite value adds a zero, which leaves a sum as it
/// was), with no branch per column.
///
/// NOTE: the pass along x summed each entry over its row's list of columns, a loop of three to
/// seven steps with the list read through a pointer: about 70% of the passes along x and y in
/// `perf annotate`, and the passes 4–6% of an import's CPU time (bench/RESULTS.md, "Import
/// time toward a fifth of PoissonRecon's").
struct TapRows {
    width: usize,
    /// Per row: its window's first column.
    first: Vec<usize>,
    /// Per row: `width` weights.
    weights: Vec<f64>,
}

impl TapRows {
    /// `matrix` (rows of `(column, weight)`, over `columns` columns) as windows, or `None`
    /// where a row's columns are not consecutive and ascending, or are more than 16, or the
    /// window does not fit in the columns.
    fn of(matrix: &[Vec<(usize, f64)>], columns: usize) -> Option<Self> {
        let longest = matrix.iter().map(Vec::len).max()?;
        let width = longest.max(1).div_ceil(4) * 4;
        if width > 16 || width > columns {
            return None;
        }
        let mut first = Vec::with_capacity(matrix.len());
        let mut weights = vec![0.0; matrix.len() * width];
        for (row, window) in matrix.iter().zip(weights.chunks_exact_mut(width)) {
            let start = row.first().map_or(0, |&(t, _)| t);
            let consecutive = row.iter().enumerate().all(|(k, &(t, _))| t == start + k);
            if !consecutive || start + row.len() > columns {
                return None;
            }
            // The window ends within the columns: it starts at the run, or earlier where
            // the run is near the end.
            let at = start.min(columns - width);
            for &(t, w) in row {
                window[t - at] = w;
            }
            first.push(at);
        }
        Some(Self {
            width,
            first,
            weights,
        })
    }

    /// One line of the product: `out[o] = Σ_k weights[o][k] · input[first[o] + k]`.
    fn line(&self, input: &[f64], out: &mut [f64]) {
        match self.width {
            4 => self.line_of::<4>(input, out),
            8 => self.line_of::<8>(input, out),
            12 => self.line_of::<12>(input, out),
            _ => self.line_of::<16>(input, out),
        }
    }

    #[inline(always)]
    fn line_of<const WIDTH: usize>(&self, input: &[f64], out: &mut [f64]) {
        for ((value, &at), weights) in out
            .iter_mut()
            .zip(&self.first)
            .zip(self.weights.chunks_exact(WIDTH))
        {
            let window = &input[at..at + WIDTH];
            let mut sum = 0.0;
            for k in 0..WIDTH {
                sum += weights[k] * window[k];
            }
            *value = sum;
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
    // Kept from the last product, at least as long: each plane is cleared where it is
    // filled, so only the entries a product needs are read (`second`'s first
    // `second_dims`' product), and a buffer grows, never shrinks.
    //
    // NOTE: resized to each product's length, the buffers of a regularised fit's step shrank
    // for one product and grew back for the other (a forward product's first pass is
    // `samples × coefficients²` entries, a transposed one's `coefficients × samples²`), and
    // every growth cleared the new tail on the calling thread: 22 of 305 main-thread samples
    // of the base fit in `perf record` (bench/RESULTS.md, "Import time: the idle core").
    let first = grown(first, first_plane * dims[2]);
    let second = grown(second, second_plane * dims[2]);
    if first_plane == 0 || second_plane == 0 {
        return second_dims;
    }
    let taps = TapRows::of(matrices[0], dims[0]);
    let fill = |z0: usize, first: &mut [f64], second: &mut [f64]| {
        for (dz, (first, second)) in first
            .chunks_exact_mut(first_plane)
            .zip(second.chunks_exact_mut(second_plane))
            .enumerate()
        {
            let z = z0 + dz;
            let input = &input[z * in_plane..(z + 1) * in_plane];
            plane_along(
                input,
                [dims[0], dims[1]],
                0,
                matrices[0],
                taps.as_ref(),
                first,
            );
            second.fill(0.0);
            plane_along(
                first,
                [first_dims[0], first_dims[1]],
                1,
                matrices[1],
                None,
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

/// `buffer`'s first `len` entries, the buffer grown with zeros where it is shorter (never
/// shrunk: a longer buffer keeps its tail for the next, longer product).
fn grown(buffer: &mut Vec<f64>, len: usize) -> &mut [f64] {
    if buffer.len() < len {
        buffer.resize(len, 0.0);
    }
    &mut buffer[..len]
}

/// The buffers of [`apply`]'s passes, kept across the fit's steps (each as long as the
/// longest product that used it).
#[derive(Default)]
struct Passes {
    first: Vec<f64>,
    second: Vec<f64>,
    /// [`weighted_normal_product`]'s planes after the transposed passes along x and y.
    third: Vec<f64>,
}

/// What [`along_axis`] does to each output z-plane once it is filled: called with the
/// plane's `z` and its entries, on the thread that filled it.
type PlaneFinish<'a> = dyn Fn(usize, &mut [f64]) + Sync + 'a;

/// `A x` over the three axes (or `Aᵀ x`; with `squared`, the entrywise squares of `A`) into
/// `out`, each entry then multiplied by its entry of `weights` when given, and each output
/// z-plane then handed to `finish` when given, on `threads` threads.
#[allow(clippy::too_many_arguments)]
fn apply(
    x: &[f64],
    dims: [usize; 3],
    bases: &[AxisBasis; 3],
    forward: bool,
    squared: bool,
    weights: Option<&[f32]>,
    finish: Option<&PlaneFinish<'_>>,
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
    let Passes { first, second, .. } = passes;
    let d = along_x_then_y(x, dims, [&matrix(0), &matrix(1)], first, second, threads);
    let second = &second[..d.iter().product::<usize>()];
    along_axis(second, d, 2, &matrix(2), weights, finish, out, threads);
}

/// `Aᵀ W A x` (the weights `W` one per sample of the mass grid) into `out`, each output
/// z-plane then handed to `finish` when given, on `threads` threads: the same values bit for
/// bit as [`apply`] forward with the weights and then [`apply`] transposed.
///
/// The forward pass along z, the weights and the transposed passes along x and y each keep
/// a z-plane of the samples to itself, so they run plane by plane on one thread, with the
/// plane in that thread's cache: the samples (`samples_per_span³` times the coefficients)
/// are never stored, and the threads are waited for three times per product instead of four.
///
/// NOTE: by two [`apply`]s, each step of a 44³ base fit wrote and read back the 658 000
/// weighted samples (5 MB) and the transposed pass along x's 333 000 entries, and waited for
/// the threads once more (bench/RESULTS.md, "Import time: the idle core").
#[allow(clippy::too_many_arguments)]
fn weighted_normal_product(
    x: &[f64],
    dims: [usize; 3],
    bases: &[AxisBasis; 3],
    weights: &[f32],
    finish: Option<&PlaneFinish<'_>>,
    threads: usize,
    passes: &mut Passes,
    out: &mut Vec<f64>,
) {
    let Passes {
        first,
        second,
        third,
    } = passes;
    let [sx, sy, cz] = along_x_then_y(
        x,
        dims,
        [&bases[0].rows, &bases[1].rows],
        first,
        second,
        threads,
    );
    let sz = bases[2].samples;
    let (cx, cy) = (bases[0].columns.len(), bases[1].columns.len());
    let second = &second[..sx * sy * cz];
    let (sample_plane, across_plane, out_plane) = (sx * sy, cx * sy, cx * cy);
    let third = grown(third, out_plane * sz);
    if sample_plane == 0 || out_plane == 0 {
        // No samples, or no coefficients in a plane: the transposed passes sum nothing.
        third.fill(0.0);
        along_axis(
            third,
            [cx, cy, sz],
            2,
            &bases[2].columns,
            None,
            finish,
            out,
            threads,
        );
        return;
    }
    let taps = TapRows::of(&bases[0].columns, sx);
    let fill = |z0: usize, slab: &mut [f64]| {
        let mut samples = vec![0.0; sample_plane];
        let mut across = vec![0.0; across_plane];
        for (dz, plane) in slab.chunks_exact_mut(out_plane).enumerate() {
            let z = z0 + dz;
            // `A` along z ([`along_axis`]'s sum per entry, in the row's order), then `W`.
            samples.fill(0.0);
            for &(t, w) in &bases[2].rows[z] {
                let from = t * sample_plane;
                for (value, &v) in samples.iter_mut().zip(&second[from..from + sample_plane]) {
                    *value += w * v;
                }
            }
            for (value, &w) in samples.iter_mut().zip(&weights[z * sample_plane..]) {
                *value *= f64::from(w);
            }
            // `Aᵀ` along x, then along y ([`along_x_then_y`]'s plane).
            plane_along(
                &samples,
                [sx, sy],
                0,
                &bases[0].columns,
                taps.as_ref(),
                &mut across,
            );
            plane.fill(0.0);
            plane_along(&across, [cx, sy], 1, &bases[1].columns, None, plane);
        }
    };
    fill_slabs_on_threads(third, out_plane, sz, threads, fill);
    along_axis(
        third,
        [cx, cy, sz],
        2,
        &bases[2].columns,
        None,
        finish,
        out,
        threads,
    );
}

/// `L x = Σ_axes D₂ᵀ Λ D₂ x` on the coefficient grid, added to `out`, by a scatter over the
/// grid: each row of `D₂` (the second difference centred on a coefficient) weighs `lambda`
/// times that coefficient's entry of `scale` (1 where `scale` is `None`); the reference
/// [`add_bending_plane`] is tested against.
#[cfg(test)]
fn add_bending(x: &[f64], dims: [usize; 3], lambda: f64, scale: Option<&[f64]>, out: &mut [f64]) {
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
                    let weight = scale.map_or(lambda, |s| lambda * s[at + st]);
                    let d = x[at] - 2.0 * x[at + st] + x[at + 2 * st];
                    out[at] += weight * d;
                    out[at + st] -= 2.0 * weight * d;
                    out[at + 2 * st] += weight * d;
                }
            }
        }
    }
}

/// [`add_bending`]'s sums for the z-plane `z` of `out` alone (`plane`, `nx · ny` entries):
/// the same scatter restricted to the plane's entries, axis by axis and along an axis row
/// by row in ascending order, so each entry receives the same terms in the same order and
/// is the same bit for bit, and the planes can be summed on the threads that fill them.
/// Along z a row's three entries lie in three planes: the plane takes its term from each
/// of the (at most three) rows that reach it.
///
/// NOTE: added by the scatter over the whole grid on the calling thread after each product
/// by `AᵀWA`, the bending took 25 of the 305 main-thread samples of a 44³ base fit in
/// `perf record`, with the other core idle; a gather per entry (each entry reading the
/// nine second differences it takes) was the same bits at 2.7 times the CPU
/// (bench/RESULTS.md, "Import time: the idle core").
fn add_bending_plane(
    x: &[f64],
    dims: [usize; 3],
    lambda: f64,
    scale: Option<&[f64]>,
    z: usize,
    plane: &mut [f64],
) {
    let [nx, ny, nz] = dims;
    let area = nx * ny;
    let plane = &mut plane[..area];
    let own = &x[z * area..(z + 1) * area];
    // The weight of the row centred on coefficient `at` (a plane's entry `k` is `z·area + k`).
    let weight = |at: usize| scale.map_or(lambda, |s| lambda * s[at]);
    if nx >= 3 {
        for (j, (line, out)) in own
            .chunks_exact(nx)
            .zip(plane.chunks_exact_mut(nx))
            .enumerate()
        {
            let row_start = z * area + j * nx;
            for i in 0..nx - 2 {
                let w = weight(row_start + i + 1);
                let d = line[i] - 2.0 * line[i + 1] + line[i + 2];
                out[i] += w * d;
                out[i + 1] -= 2.0 * w * d;
                out[i + 2] += w * d;
            }
        }
    }
    if ny >= 3 {
        for j in 0..ny - 2 {
            let rows = &own[j * nx..(j + 3) * nx];
            let (low, rest) = plane[j * nx..(j + 3) * nx].split_at_mut(nx);
            let (mid, high) = rest.split_at_mut(nx);
            let centre_start = z * area + (j + 1) * nx;
            for i in 0..nx {
                let w = weight(centre_start + i);
                let d = rows[i] - 2.0 * rows[nx + i] + rows[2 * nx + i];
                low[i] += w * d;
                mid[i] -= 2.0 * w * d;
                high[i] += w * d;
            }
        }
    }
    if nz >= 3 {
        // Row `r` along z starts in plane `r`, is centred on plane `r + 1` and reaches plane
        // `r + 2`.
        let row = |r: usize| {
            (
                &x[r * area..(r + 1) * area],
                &x[(r + 1) * area..(r + 2) * area],
                &x[(r + 2) * area..(r + 3) * area],
            )
        };
        if z >= 2 {
            let (a, b, c) = row(z - 2);
            let centre = (z - 1) * area;
            for (k, value) in plane.iter_mut().enumerate() {
                *value += weight(centre + k) * (a[k] - 2.0 * b[k] + c[k]);
            }
        }
        if z >= 1 && z + 1 < nz {
            let (a, b, c) = row(z - 1);
            let centre = z * area;
            for (k, value) in plane.iter_mut().enumerate() {
                *value -= 2.0 * weight(centre + k) * (a[k] - 2.0 * b[k] + c[k]);
            }
        }
        if z + 2 < nz {
            let (a, b, c) = row(z);
            let centre = (z + 1) * area;
            for (k, value) in plane.iter_mut().enumerate() {
                *value += weight(centre + k) * (a[k] - 2.0 * b[k] + c[k]);
            }
        }
    }
}

/// The diagonal of `L` (see [`add_bending`]; `scale` as there).
fn bending_diagonal(dims: [usize; 3], scale: Option<&[f64]>) -> Vec<f64> {
    let mut e = vec![0.0; dims.iter().product()];
    let [nx, ny, _] = dims;
    let strides = [1i64, nx as i64, (nx * ny) as i64];
    for (at, v) in e.iter_mut().enumerate() {
        let c = [at % nx, (at / nx) % ny, at / (nx * ny)];
        for axis in 0..3 {
            let n = dims[axis] as i64;
            if n < 3 {
                continue;
            }
            // Rows r = c−2 ..= c of D₂ touch coefficient c with weights 1, −2, 1; row r is
            // centred on r + 1.
            for (offset, w) in [(2i64, 1.0), (1, 4.0), (0, 1.0)] {
                let r = c[axis] as i64 - offset;
                if r >= 0 && r + 2 < n {
                    let centre = at as i64 + (1 - offset) * strides[axis];
                    *v += w * scale.map_or(1.0, |s| s[centre as usize]);
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

/// [`refit_regularised`] from the plain least-squares fit of `targets` (every weight 1, no
/// bending) rather than from the lattice's coefficients, which are replaced: the plain fit's
/// `Aᵀ f` is three passes on every thread and its solve three banded substitutions per line,
/// where a plain fit by the lattice's own sampled target (`field::fit_lattice`) ran on one
/// thread. Returns the conjugate-gradient steps run.
///
/// NOTE: the base of a 50 000-point import took its plain fit from `field::fit_lattice`,
/// 14–40 ms on the calling thread (bench/RESULTS.md, "Import time toward a fifth of
/// PoissonRecon's").
///
/// # Panics
/// When `targets` or `weights` do not hold one value per sample.
pub fn fit_regularised(
    lattice: &mut BSplineLattice,
    samples_per_span: usize,
    targets: &[f32],
    weights: &[f32],
    lambda: f32,
    max_iterations: usize,
) -> usize {
    fit_regularised_scaled(
        lattice,
        samples_per_span,
        targets,
        weights,
        lambda,
        None,
        max_iterations,
    )
}

/// [`fit_regularised`] with the bending weighed per coefficient: the second differences
/// centred on coefficient `c` (x fastest) weigh `lambda · bending_scale[c]` (`lambda` alone
/// where `bending_scale` is `None`), so the clay can be held smoother in one region than in
/// another.
///
/// # Panics
/// When `targets` or `weights` do not hold one value per sample, or `bending_scale` one per
/// coefficient.
pub fn fit_regularised_scaled(
    lattice: &mut BSplineLattice,
    samples_per_span: usize,
    targets: &[f32],
    weights: &[f32],
    lambda: f32,
    bending_scale: Option<&[f32]>,
    max_iterations: usize,
) -> usize {
    let threads = std::thread::available_parallelism().map_or(1, std::num::NonZeroUsize::get);
    let start = plain_fit(lattice.dims, samples_per_span, targets, threads);
    let start = start.unwrap_or_else(|| lattice.coeffs.iter().map(|&c| f64::from(c)).collect());
    let scale: Option<Vec<f64>> = bending_scale.map(|s| {
        assert_eq!(s.len(), start.len(), "one bending scale per coefficient");
        s.iter().map(|&v| f64::from(v)).collect()
    });
    regularised_from(
        lattice,
        samples_per_span,
        targets,
        weights,
        lambda,
        scale.as_deref(),
        max_iterations,
        threads,
        start,
    )
}

/// The values of `lattice` at its samples (`samples_per_span` per span over the lattice, x
/// fastest: the grid the fits here are fitted on), `A c`.
#[must_use]
pub fn values_at_samples(lattice: &BSplineLattice, samples_per_span: usize) -> Vec<f32> {
    let threads = std::thread::available_parallelism().map_or(1, std::num::NonZeroUsize::get);
    let bases = lattice.dims.map(|n| AxisBasis::new(n, samples_per_span));
    let coeffs: Vec<f64> = lattice.coeffs.iter().map(|&c| f64::from(c)).collect();
    let mut values = Vec::new();
    apply(
        &coeffs,
        lattice.dims,
        &bases,
        true,
        false,
        None,
        None,
        threads,
        &mut Passes::default(),
        &mut values,
    );
    values.iter().map(|&v| v as f32).collect()
}

/// The plain least-squares fit of the coefficients (`dims`) to `targets` at the samples
/// (`samples_per_span` per span, x fastest): `(AᵀA)⁻¹ Aᵀ f`; `None` where an axis's Gram
/// matrix has no Cholesky factor.
///
/// # Panics
/// When `targets` does not hold one value per sample.
fn plain_fit(
    dims: [usize; 3],
    samples_per_span: usize,
    targets: &[f32],
    threads: usize,
) -> Option<Vec<f64>> {
    let bases = dims.map(|n| AxisBasis::new(n, samples_per_span));
    let factors = [
        GramFactor::of(&bases[0])?,
        GramFactor::of(&bases[1])?,
        GramFactor::of(&bases[2])?,
    ];
    let sample_dims = [bases[0].samples, bases[1].samples, bases[2].samples];
    assert_eq!(
        targets.len(),
        sample_dims.iter().product::<usize>(),
        "one target per sample"
    );
    let f: Vec<f64> = targets.iter().map(|&v| f64::from(v)).collect();
    let mut c = Vec::new();
    apply(
        &f,
        sample_dims,
        &bases,
        false,
        false,
        None,
        None,
        threads,
        &mut Passes::default(),
        &mut c,
    );
    for (axis, factor) in factors.iter().enumerate() {
        factor.solve_along(&mut c, dims, axis);
    }
    Some(c)
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
    let start = lattice.coeffs.iter().map(|&c| f64::from(c)).collect();
    regularised_from(
        lattice,
        samples_per_span,
        targets,
        weights,
        lambda,
        None,
        max_iterations,
        threads,
        start,
    )
}

/// The conjugate-gradient steps of [`refit_regularised_on`] from the coefficients `start`
/// (one per coefficient of `lattice`, x fastest); the result is written into `lattice`.
#[allow(clippy::too_many_arguments)]
fn regularised_from(
    lattice: &mut BSplineLattice,
    samples_per_span: usize,
    targets: &[f32],
    weights: &[f32],
    lambda: f32,
    bending_scale: Option<&[f64]>,
    max_iterations: usize,
    threads: usize,
    start: Vec<f64>,
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
        None,
        threads,
        &mut passes,
        &mut diagonal,
    );
    // The weights as `f64` are not kept through the steps: the products convert them as
    // they weight the samples (the same values), 4 MB fewer for a 40³ fit.
    drop(w);
    for (d, l) in diagonal
        .iter_mut()
        .zip(bending_diagonal(dims, bending_scale))
    {
        *d = (*d + lambda * l).max(1e-12);
    }
    let mut operator = |x: &[f64], out: &mut Vec<f64>| {
        weighted_normal_product(
            x,
            dims,
            &bases,
            weights,
            Some(&|z, plane: &mut [f64]| {
                add_bending_plane(x, dims, lambda, bending_scale, z, plane)
            }),
            threads,
            &mut passes,
            out,
        );
    };
    let mut x = start;
    assert_eq!(
        x.len(),
        dims.iter().product::<usize>(),
        "one start per coefficient"
    );
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

    /// `count` targets in [0, 1), spread unevenly over the samples.
    fn uneven_targets(count: usize) -> Vec<f32> {
        (0..count)
            .map(|s| ((s * 7919) % 101) as f32 / 101.0)
            .collect()
    }

    /// A 9 × 7 × 11 lattice's fit at two samples per span with uneven targets and weights:
    /// the lattice's dimensions, the samples per span, the samples per axis, the targets and
    /// the weights (in [0.1, 1.1)).
    fn uneven_problem() -> ([usize; 3], usize, [usize; 3], Vec<f32>, Vec<f32>) {
        let dims = [9, 7, 11];
        let sps = 2;
        let m = dims.map(|n| (n - 1) * sps + 1);
        let count = m.iter().product::<usize>();
        let weights = (0..count)
            .map(|s| 0.1 + ((s * 31) % 17) as f32 / 17.0)
            .collect();
        (dims, sps, m, uneven_targets(count), weights)
    }

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

    #[test]
    fn the_plain_fit_is_the_lattices_own_least_squares_fit_and_recovers_a_spline() {
        // Uneven targets on a lattice with an odd and an even side: the plain fit found here
        // (Aᵀ f by the passes, then the banded Cholesky solves per axis) is the least-squares
        // fit the lattice's own Kronecker machinery finds (`field::fit_lattice`).
        let dims = [9, 7, 12];
        let (sps, spacing) = (2, 0.5);
        let m = dims.map(|n| (n - 1) * sps + 1);
        let count = m.iter().product::<usize>();
        let targets = uneven_targets(count);
        let plain = plain_fit(dims, sps, &targets, 3).expect("the Gram matrices factor");
        let mut reference = BSplineLattice::zeros(dims, spacing, Vec3::ZERO).unwrap();
        dynaclay_core::field::fit_lattice(&mut reference, sps, |x| {
            let u = x / (spacing / sps as f32);
            let [i, j, k] = [u.x, u.y, u.z].map(|v| v.round() as usize);
            targets[i + m[0] * (j + m[1] * k)]
        })
        .unwrap();
        let worst = plain
            .iter()
            .zip(reference.coeffs.iter())
            .map(|(&a, &b)| (a - f64::from(b)).abs())
            .fold(0.0f64, f64::max);
        assert!(worst < 1e-4, "the plain fits differ by {worst}");
        assert!(plain.iter().any(|&c| c.abs() > 0.1));
        // A spline's own samples give back its coefficients; and the same on one thread.
        let coeffs: Vec<f32> = (0..dims.iter().product::<usize>())
            .map(|i| ((i * 7919) % 23) as f32 / 23.0)
            .collect();
        let truth = BSplineLattice::from_coeffs(dims, spacing, Vec3::ZERO, coeffs.clone()).unwrap();
        let mut samples = Vec::with_capacity(count);
        for k in 0..m[2] {
            for j in 0..m[1] {
                for i in 0..m[0] {
                    let x = Vec3::new(i as f32, j as f32, k as f32) * spacing / sps as f32;
                    samples.push(truth.value(x));
                }
            }
        }
        let recovered = plain_fit(dims, sps, &samples, 1).unwrap();
        for (at, (&got, &want)) in recovered.iter().zip(&coeffs).enumerate() {
            assert!(
                (got - f64::from(want)).abs() < 1e-4,
                "coefficient {at}: {got} against {want}"
            );
        }
        assert_eq!(plain_fit(dims, sps, &samples, 4).unwrap(), recovered);
    }

    #[test]
    fn the_regularised_fit_from_the_plain_fit_is_the_refit_from_the_lattices_plain_fit() {
        // With uneven weights and a bending energy, run to the tolerance: starting from the
        // plain fit found here or from the lattice's own, the fits agree within the
        // tolerance's reach.
        let (dims, sps, m, targets, weights) = uneven_problem();
        let mut here = BSplineLattice::zeros(dims, 0.5, Vec3::ZERO).unwrap();
        fit_regularised(&mut here, sps, &targets, &weights, 0.01, 400);
        let mut there = BSplineLattice::zeros(dims, 0.5, Vec3::ZERO).unwrap();
        dynaclay_core::field::fit_lattice(&mut there, sps, |x| {
            let u = x / (0.5 / sps as f32);
            let [i, j, k] = [u.x, u.y, u.z].map(|v| v.round() as usize);
            targets[i + m[0] * (j + m[1] * k)]
        })
        .unwrap();
        refit_regularised(&mut there, sps, &targets, &weights, 0.01, 400);
        let worst = here
            .coeffs
            .iter()
            .zip(there.coeffs.iter())
            .map(|(a, b)| (a - b).abs())
            .fold(0.0f32, f32::max);
        assert!(worst < 1e-3, "the fits differ by {worst}");
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
    fn the_bases_of_a_fit_are_read_as_windows_along_x_and_a_scattered_row_is_not() {
        // Every basis at one to four samples per span, both ways: each row a run of
        // consecutive columns within its window (the pass along x takes the windows; the
        // bit-for-bit test below checks their sums).
        for sps in 1..=4 {
            for n in [4, 12, 40] {
                let basis = AxisBasis::new(n, sps);
                for (matrix, columns) in [(&basis.rows, n), (&basis.columns, basis.samples)] {
                    let taps = TapRows::of(matrix, columns);
                    let Some(taps) = taps else {
                        assert!(columns < 16, "{n} coefficients, {sps} samples per span");
                        continue;
                    };
                    for (o, row) in matrix.iter().enumerate() {
                        let window = &taps.weights[o * taps.width..(o + 1) * taps.width];
                        let total: f64 = row.iter().map(|&(_, w)| w).sum();
                        assert_eq!(window.iter().sum::<f64>(), total, "row {o}");
                        for &(t, w) in row {
                            assert_eq!(window[t - taps.first[o]], w);
                        }
                    }
                }
            }
        }
        let scattered = vec![vec![(0, 1.0), (2, 0.5)]];
        assert!(TapRows::of(&scattered, 8).is_none());
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
                    along_axis(&input, dims, axis, matrix, None, None, &mut out, threads);
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
            let d = along_axis(&input, dims, 0, &m0, None, None, &mut one, 1);
            let mut two = Vec::new();
            let want_dims = along_axis(&one, d, 1, &m1, None, None, &mut two, 1);
            // Buffers shorter than the passes need, and longer (kept from a larger product).
            for (threads, kept) in [(1, 2), (2, 5), (3, 5000)] {
                let (mut first, mut second) = (vec![9.0; kept], vec![4.0; kept]);
                let got_dims =
                    along_x_then_y(&input, dims, [&m0, &m1], &mut first, &mut second, threads);
                assert_eq!(got_dims, want_dims);
                assert!(
                    second[..two.len()]
                        .iter()
                        .map(|v| v.to_bits())
                        .eq(two.iter().map(|v| v.to_bits())),
                    "forward {forward}, {threads} threads"
                );
            }
        }
    }

    #[test]
    fn the_bending_by_planes_is_the_scatter_bit_for_bit() {
        // A grid with an axis too short to bend (2) and one just long enough (3), and a
        // larger one; uneven coefficients and a non-zero `out` to add to.
        for dims in [[7, 6, 9], [2, 5, 4], [3, 3, 8], [6, 1, 3]] {
            let count: usize = dims.iter().product();
            let x: Vec<f64> = (0..count)
                .map(|i| ((i * 7919) % 103) as f64 / 103.0 - 0.41)
                .collect();
            let start: Vec<f64> = (0..count)
                .map(|i| ((i * 104_729) % 97) as f64 / 9.7 - 5.0)
                .collect();
            // The whole weight everywhere, and a weight per coefficient (uneven, some zero).
            let scale: Vec<f64> = (0..count).map(|i| ((i * 31) % 5) as f64 / 4.0).collect();
            for scale in [None, Some(scale.as_slice())] {
                let mut scattered = start.clone();
                add_bending(&x, dims, 0.37, scale, &mut scattered);
                let mut by_planes = start.clone();
                let plane = dims[0] * dims[1];
                for (z, out) in by_planes.chunks_exact_mut(plane).enumerate() {
                    add_bending_plane(&x, dims, 0.37, scale, z, out);
                }
                assert!(
                    by_planes
                        .iter()
                        .map(|v| v.to_bits())
                        .eq(scattered.iter().map(|v| v.to_bits())),
                    "{dims:?}, scaled {}",
                    scale.is_some()
                );
                assert_ne!(scattered, start, "{dims:?}: the bending added nothing");
            }
        }
    }

    #[test]
    fn products_with_kept_buffers_are_those_with_fresh_buffers_bit_for_bit() {
        // A fit's step alternates forward and transposed products, whose passes need buffers
        // of different lengths: kept from one product to the next, they must give what
        // fresh buffers give, on one thread and several, with and without a plane finisher.
        let (dims, sps, sample_dims, _, weights) = uneven_problem();
        let bases = dims.map(|n| AxisBasis::new(n, sps));
        let coefficients: Vec<f64> = (0..dims.iter().product::<usize>())
            .map(|i| ((i * 7919) % 101) as f64 / 101.0 - 0.37)
            .collect();
        let finish = |z: usize, plane: &mut [f64]| {
            add_bending_plane(&coefficients, dims, 0.2, None, z, plane)
        };
        for threads in [1, 2, 3] {
            let mut kept = Passes::default();
            let mut x = coefficients.clone();
            for round in 0..3 {
                let (mut samples, mut fresh_samples) = (Vec::new(), Vec::new());
                apply(
                    &x,
                    dims,
                    &bases,
                    true,
                    false,
                    Some(&weights),
                    None,
                    threads,
                    &mut kept,
                    &mut samples,
                );
                apply(
                    &x,
                    dims,
                    &bases,
                    true,
                    false,
                    Some(&weights),
                    None,
                    threads,
                    &mut Passes::default(),
                    &mut fresh_samples,
                );
                assert_eq!(samples.len(), sample_dims.iter().product::<usize>());
                assert!(
                    samples
                        .iter()
                        .map(|v| v.to_bits())
                        .eq(fresh_samples.iter().map(|v| v.to_bits())),
                    "forward, round {round}, {threads} threads"
                );
                let (mut back, mut fresh_back) = (Vec::new(), Vec::new());
                apply(
                    &samples,
                    sample_dims,
                    &bases,
                    false,
                    false,
                    None,
                    Some(&finish),
                    threads,
                    &mut kept,
                    &mut back,
                );
                apply(
                    &samples,
                    sample_dims,
                    &bases,
                    false,
                    false,
                    None,
                    Some(&finish),
                    threads,
                    &mut Passes::default(),
                    &mut fresh_back,
                );
                assert!(
                    back.iter()
                        .map(|v| v.to_bits())
                        .eq(fresh_back.iter().map(|v| v.to_bits())),
                    "transposed, round {round}, {threads} threads"
                );
                // The finisher ran on every plane: the bending is in the product.
                let mut plain_back = Vec::new();
                apply(
                    &samples,
                    sample_dims,
                    &bases,
                    false,
                    false,
                    None,
                    None,
                    threads,
                    &mut Passes::default(),
                    &mut plain_back,
                );
                add_bending(&coefficients, dims, 0.2, None, &mut plain_back);
                assert!(
                    back.iter()
                        .map(|v| v.to_bits())
                        .eq(plain_back.iter().map(|v| v.to_bits())),
                    "finished, round {round}, {threads} threads"
                );
                x = back.iter().map(|v| v * 0.5).collect();
            }
        }
    }

    #[test]
    fn the_weighted_normal_product_is_the_two_products_bit_for_bit() {
        // `AᵀWA x` plane by plane against `A x` weighted, then `Aᵀ` of that, each by
        // `apply`: with kept and fresh buffers, on one thread and several, with the bending
        // as the finisher and without.
        let (dims, sps, sample_dims, _, weights) = uneven_problem();
        let bases = dims.map(|n| AxisBasis::new(n, sps));
        let x: Vec<f64> = (0..dims.iter().product::<usize>())
            .map(|i| ((i * 104_729) % 89) as f64 / 89.0 - 0.52)
            .collect();
        let bending =
            |z: usize, plane: &mut [f64]| add_bending_plane(&x, dims, 0.3, None, z, plane);
        let finishes: [Option<&PlaneFinish<'_>>; 2] = [None, Some(&bending)];
        for finish in finishes {
            let mut samples = Vec::new();
            let mut passes = Passes::default();
            apply(
                &x,
                dims,
                &bases,
                true,
                false,
                Some(&weights),
                None,
                1,
                &mut passes,
                &mut samples,
            );
            let mut want = Vec::new();
            apply(
                &samples,
                sample_dims,
                &bases,
                false,
                false,
                None,
                finish,
                1,
                &mut passes,
                &mut want,
            );
            for threads in [1, 2, 3, 8] {
                let mut kept = Passes::default();
                for round in 0..2 {
                    let mut got = vec![7.0; 3];
                    weighted_normal_product(
                        &x, dims, &bases, &weights, finish, threads, &mut kept, &mut got,
                    );
                    assert!(
                        got.iter()
                            .map(|v| v.to_bits())
                            .eq(want.iter().map(|v| v.to_bits())),
                        "{threads} threads, round {round}, finished {}",
                        finish.is_some()
                    );
                }
            }
        }
    }

    #[test]
    fn the_refit_is_the_same_on_one_thread_and_on_several() {
        // Uneven weights and a bending energy, a few steps from zero: every coefficient must
        // come out bit for bit the same whatever the thread count.
        let (dims, sps, _, targets, weights) = uneven_problem();
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
