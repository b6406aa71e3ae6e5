//! Hard constraints in the step (Hua & Qin §7.3, eqs. 10–12): the constraint rows of the pins
//! that reach a region, restricted to its coefficients `p_R`, and the stage that keeps them
//! satisfied while the dynamics of eq. (7) run.
//!
//! Rows `C p_R = e` (the part of a row on coefficients outside the region is fixed for the
//! region's life and moves into `e`). Rows that share a coefficient form a *cluster*; clusters
//! are independent, so each is solved on its own support (the ≤ 64 coefficients around each of
//! its pins), and the cost grows with the pins, not with the region.
//!
//! Each cluster takes one of two paths, both giving the acceleration of `p_R` the least
//! (Euclidean) change that satisfies the constraints:
//! - **projection** (few constraints against the coefficients they touch, `k < s/2`, or a
//!   support too large for a dense null-space basis): the unconstrained `p̈` of eq. (7) is
//!   corrected by the minimum-norm step through the rows, `p̈ ← p̈ − Cᵀ (C Cᵀ)⁺ (C p̈ − t)`;
//! - **reduced** (many constraints against their support, `k ≥ s/2` and `s ≤`
//!   [`REDUCED_MAX_SUPPORT`]): eq. (10) on the support, `p_S = N h + h0` with `N` an
//!   orthonormal null-space basis of `C` from an SVD, is stepped in the reduced coordinates
//!   `h`: `ḧ = Nᵀ p̈_S` (eqs. 11–12 with the unit metric of eq. 7's solved form), then
//!   `p̈_S = N ḧ + C⁺ t`.
//!
//! A step runs the stage in two passes: the pure constraint (`t = 0`: `C p̈ = 0` keeps `C p`
//! fixed while `C ṗ = 0`) before the adaptive time step is chosen from the constrained `p̈`,
//! then, with the step known, the drift correction, whose `t` makes the Euler update land
//! exactly on `C p = e` (f32 rounding would otherwise accumulate). The second pass measures
//! `C p̈` again rather than assume the first left it at zero: with large accelerations the
//! first pass's own rounding is worth removing (a pinned curve drifts past 1e-4 otherwise). Redundant rows are handled by the pseudo-inverse (singular
//! values below [`RANK_TOLERANCE`] of the largest are dropped); conflicting rows are met in the
//! least-squares sense and reported ([`ConstraintReport`]). Nothing here produces a NaN from
//! finite input: every division is by a kept singular value.
//!
//! Why nalgebra: its SVD and symmetric eigensolver are all this needs on matrices of at most a
//! few thousand rows; it builds from a handful of small pure-Rust crates (no BLAS, no SIMD
//! kernels generated per target), where faer pulls in a much larger tree for speed this
//! stage does not need.
//!
//! Building a solver allocates (when a region is made or the pins change); a step allocates
//! nothing.

use nalgebra::{DMatrix, SymmetricEigen};

use crate::field::{BSplineLattice, CoeffBox};

use super::constraint_model::ConstraintRow;
use super::material::Integrator;
use super::region::RegionState;

/// Singular values below this fraction of a cluster's largest are treated as zero (rank).
pub const RANK_TOLERANCE: f64 = 1e-6;
/// Largest support (coefficients) a cluster may have for the reduced path (its SVD is dense).
pub const REDUCED_MAX_SUPPORT: usize = 768;

/// Which path the clusters take.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ConstraintPath {
    /// Per cluster: reduced when `k ≥ s/2` and `s ≤ REDUCED_MAX_SUPPORT`, else projection.
    #[default]
    Auto,
    /// Every cluster projects.
    Projection,
    /// Every cluster with `s ≤ REDUCED_MAX_SUPPORT` is reduced (larger ones project).
    Reduced,
}

/// How well the constraints reaching a region can be met.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ConstraintReport {
    /// Rows reaching the region.
    pub rows: usize,
    /// Rank of those rows (fewer than `rows`: some are redundant).
    pub rank: usize,
    /// Rows lying wholly outside the region (held by the fixed coefficients).
    pub outside_rows: usize,
    /// Largest `|C p − e|` of the current state, in row units (unit-length rows: a field
    /// value difference for points, near the iso-value's scale).
    pub violation: f32,
    /// Largest `|C p − e|` left after the minimum-norm correction: above
    /// [`ConstraintReport::CONFLICT`], the rows conflict and are met in the least-squares
    /// sense only (a row wholly outside the region counts with its own violation).
    pub residual: f32,
    /// Clusters on the projection path.
    pub projected_clusters: usize,
    /// Clusters on the reduced path.
    pub reduced_clusters: usize,
}

impl ConstraintReport {
    /// Residual above which constraints are reported as conflicting.
    pub const CONFLICT: f32 = 1e-4;

    /// Whether some rows cannot all be met.
    #[must_use]
    pub fn conflicting(&self) -> bool {
        self.residual > Self::CONFLICT
    }

    /// Whether some rows repeat others.
    #[must_use]
    pub fn redundant(&self) -> bool {
        self.rank < self.rows
    }
}

#[derive(Clone, Debug)]
enum ClusterPath {
    /// `(C Cᵀ)⁺`, `k × k`, row-major.
    Projection { gram_pinv: Vec<f64> },
    /// Null-space basis `N` (`s × m`, column-major) and `C⁺` (`s × k`, column-major) on the
    /// cluster's support.
    Reduced {
        support: Vec<u32>,
        null_basis: Vec<f64>,
        nullity: usize,
        pinv: Vec<f64>,
    },
}

#[derive(Clone, Debug)]
struct Cluster {
    rows: std::ops::Range<usize>,
    path: ClusterPath,
}

/// The constraint stage of one region (see the module docs).
#[derive(Clone, Debug, Default)]
pub struct ConstraintSolver {
    /// CSR rows on the region's coefficients, grouped by cluster.
    row_start: Vec<usize>,
    cols: Vec<u32>,
    weights: Vec<f32>,
    targets: Vec<f32>,
    clusters: Vec<Cluster>,
    report: ConstraintReport,
    /// Per-row scratch: residuals, then multipliers.
    r: Vec<f64>,
    y: Vec<f64>,
    /// Per-row scratch: the targets `t` of the drift correction.
    t: Vec<f64>,
    /// Per-support scratch of the reduced path.
    a_s: Vec<f64>,
    h: Vec<f64>,
}

struct UnionFind(Vec<usize>);

impl UnionFind {
    fn find(&mut self, mut i: usize) -> usize {
        while self.0[i] != i {
            self.0[i] = self.0[self.0[i]];
            i = self.0[i];
        }
        i
    }
    fn union(&mut self, a: usize, b: usize) {
        let (ra, rb) = (self.find(a), self.find(b));
        if ra != rb {
            self.0[ra.max(rb)] = ra.min(rb);
        }
    }
}

impl ConstraintSolver {
    /// The stage for `rows` (on `lattice`'s coefficients) on `region`, with the clusters'
    /// paths chosen by `path`.
    #[must_use]
    pub fn new(
        rows: &[ConstraintRow],
        lattice: &BSplineLattice,
        region: &RegionState,
        path: ConstraintPath,
    ) -> Self {
        Self::on_box(rows, lattice, region.coeff_box(), &region.p, path)
    }

    /// The stage for `rows` on the coefficients `b` of `lattice`, whose current values are
    /// `p` (x fastest over the box). With the whole lattice as the box and its coefficients
    /// as `p`, [`ConstraintSolver::report`] says whether a set of pins can be held at all.
    ///
    /// # Panics
    /// When `p` is shorter than the box.
    #[must_use]
    pub fn on_box(
        rows: &[ConstraintRow],
        lattice: &BSplineLattice,
        b: CoeffBox,
        p: &[f32],
        path: ConstraintPath,
    ) -> Self {
        assert!(p.len() >= b.count(), "coefficients for the whole box");
        let n = b.dims();
        let [dx, dy, _] = lattice.dims;
        let mut report = ConstraintReport::default();
        // Restrict every row to the region; the fixed part moves into the target.
        let mut local: Vec<(Vec<(u32, f32)>, f32)> = Vec::with_capacity(rows.len());
        for row in rows {
            let mut terms = Vec::with_capacity(row.terms.len());
            let mut target = f64::from(row.target);
            for &(idx, w) in &row.terms {
                let (i, j, k) = (idx % dx, (idx / dx) % dy, idx / (dx * dy));
                if b.contains(i, j, k) {
                    let l = (i - b.min[0]) + n[0] * ((j - b.min[1]) + n[1] * (k - b.min[2]));
                    terms.push((l as u32, w));
                } else {
                    target -= f64::from(w) * f64::from(lattice.coeffs[idx]);
                }
            }
            if terms.is_empty() {
                let off = row.residual(lattice).abs();
                report.outside_rows += 1;
                report.violation = report.violation.max(off);
                report.residual = report.residual.max(off);
                continue;
            }
            local.push((terms, target as f32));
        }

        // Clusters: rows sharing a coefficient.
        let mut uf = UnionFind((0..local.len()).collect());
        let mut owner = std::collections::HashMap::<u32, usize>::new();
        for (r, (terms, _)) in local.iter().enumerate() {
            for &(c, _) in terms {
                match owner.get(&c) {
                    Some(&o) => uf.union(o, r),
                    None => {
                        owner.insert(c, r);
                    }
                }
            }
        }
        let mut order: Vec<usize> = (0..local.len()).collect();
        let roots: Vec<usize> = (0..local.len()).map(|r| uf.find(r)).collect();
        order.sort_by_key(|&r| (roots[r], r));

        let mut solver = Self::default();
        solver.row_start.push(0);
        let mut start = 0;
        while start < order.len() {
            let root = roots[order[start]];
            let end = start
                + order[start..]
                    .iter()
                    .take_while(|&&r| roots[r] == root)
                    .count();
            let first_row = solver.targets.len();
            for &r in &order[start..end] {
                let (terms, target) = &local[r];
                for &(c, w) in terms {
                    solver.cols.push(c);
                    solver.weights.push(w);
                }
                solver.targets.push(*target);
                solver.row_start.push(solver.cols.len());
            }
            let rows = first_row..solver.targets.len();
            let cluster = solver.build_cluster(rows, p, path, &mut report);
            solver.clusters.push(cluster);
            start = end;
        }
        report.rows += solver.targets.len() + report.outside_rows;
        solver.r = vec![0.0; solver.targets.len()];
        solver.y = vec![0.0; solver.targets.len()];
        solver.t = vec![0.0; solver.targets.len()];
        let widest = solver
            .clusters
            .iter()
            .map(|c| match &c.path {
                ClusterPath::Reduced { support, .. } => support.len(),
                ClusterPath::Projection { .. } => 0,
            })
            .max()
            .unwrap_or(0);
        solver.a_s = vec![0.0; widest];
        solver.h = vec![0.0; widest];
        solver.report = report;
        solver
    }

    /// The stage with no constraints (a step through it changes nothing).
    #[must_use]
    pub fn empty() -> Self {
        Self::default()
    }

    /// Whether there is nothing to enforce.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.targets.is_empty()
    }

    /// Rank, residual and the paths taken.
    #[must_use]
    pub fn report(&self) -> ConstraintReport {
        self.report
    }

    fn row(&self, r: usize) -> (&[u32], &[f32]) {
        let s = self.row_start[r]..self.row_start[r + 1];
        (&self.cols[s.clone()], &self.weights[s])
    }

    /// Row `r` against two vectors in one pass over its terms.
    fn dot_row_pair(&self, r: usize, a: &[f32], b: &[f32]) -> (f64, f64) {
        let (c, w) = self.row(r);
        c.iter().zip(w).fold((0.0, 0.0), |(sa, sb), (&c, &w)| {
            let w = f64::from(w);
            (
                sa + w * f64::from(a[c as usize]),
                sb + w * f64::from(b[c as usize]),
            )
        })
    }

    fn dot_row(&self, r: usize, v: &[f32]) -> f64 {
        let (c, w) = self.row(r);
        c.iter()
            .zip(w)
            .map(|(&c, &w)| f64::from(w) * f64::from(v[c as usize]))
            .sum()
    }

    /// The dense rows of a cluster on its support (sorted local columns).
    fn dense(&self, rows: &std::ops::Range<usize>) -> (Vec<u32>, DMatrix<f64>) {
        let mut support: Vec<u32> =
            self.cols[self.row_start[rows.start]..self.row_start[rows.end]].to_vec();
        support.sort_unstable();
        support.dedup();
        let mut m = DMatrix::zeros(rows.len(), support.len());
        for (i, r) in rows.clone().enumerate() {
            let (c, w) = self.row(r);
            for (&c, &w) in c.iter().zip(w) {
                let j = support.binary_search(&c).expect("column in the support");
                m[(i, j)] += f64::from(w);
            }
        }
        (support, m)
    }

    fn build_cluster(
        &self,
        rows: std::ops::Range<usize>,
        p: &[f32],
        path: ConstraintPath,
        report: &mut ConstraintReport,
    ) -> Cluster {
        let (support, c) = self.dense(&rows);
        let (k, s) = (rows.len(), support.len());
        let residual0: Vec<f64> = rows
            .clone()
            .map(|r| self.dot_row(r, p) - f64::from(self.targets[r]))
            .collect();
        let reduce = s <= REDUCED_MAX_SUPPORT
            && match path {
                ConstraintPath::Auto => 2 * k >= s,
                ConstraintPath::Reduced => true,
                ConstraintPath::Projection => false,
            };
        let (cluster_path, rank, correction) = if reduce {
            // Full V from the SVD of C padded with zero rows to at least s × s.
            let rows_padded = k.max(s);
            let mut padded = DMatrix::<f64>::zeros(rows_padded, s);
            padded.view_mut((0, 0), (k, s)).copy_from(&c);
            let svd = padded.svd(true, true);
            let (u, v_t) = (svd.u.expect("u asked for"), svd.v_t.expect("v asked for"));
            let sigma_max = svd.singular_values.max();
            let keep: Vec<bool> = svd
                .singular_values
                .iter()
                .map(|&sv| sigma_max > 0.0 && sv > RANK_TOLERANCE * sigma_max)
                .collect();
            let rank = keep.iter().filter(|&&x| x).count();
            let nullity = s - rank;
            let mut null_basis = Vec::with_capacity(s * nullity);
            let mut pinv = vec![0.0; s * k];
            for (i, &kept) in keep.iter().enumerate() {
                let v = v_t.row(i);
                if kept {
                    let sv = svd.singular_values[i];
                    for col in 0..k {
                        let uc = u[(col, i)] / sv;
                        for j in 0..s {
                            pinv[col * s + j] += v[j] * uc;
                        }
                    }
                } else {
                    null_basis.extend(v.iter().copied());
                }
            }
            // The min-norm correction's effect on the current residual: C (C⁺ r).
            let mut z = vec![0.0; s];
            for (col, &rc) in residual0.iter().enumerate() {
                for (zj, q) in z.iter_mut().zip(&pinv[col * s..(col + 1) * s]) {
                    *zj += q * rc;
                }
            }
            let correction: Vec<f64> = (0..k)
                .map(|i| (0..s).map(|j| c[(i, j)] * z[j]).sum())
                .collect();
            (
                ClusterPath::Reduced {
                    support,
                    null_basis,
                    nullity,
                    pinv,
                },
                rank,
                correction,
            )
        } else {
            let gram = &c * c.transpose();
            let eig = SymmetricEigen::new(gram.clone());
            let lambda_max = eig.eigenvalues.iter().fold(0.0_f64, |a, &b| a.max(b));
            let floor = (RANK_TOLERANCE * RANK_TOLERANCE) * lambda_max;
            let mut pinv = vec![0.0; k * k];
            let mut rank = 0;
            for (i, &lambda) in eig.eigenvalues.iter().enumerate() {
                if lambda_max > 0.0 && lambda > floor {
                    rank += 1;
                    let q = eig.eigenvectors.column(i);
                    for a in 0..k {
                        for b in 0..k {
                            pinv[a * k + b] += q[a] * q[b] / lambda;
                        }
                    }
                }
            }
            // The min-norm correction's effect on the current residual: (C Cᵀ)(C Cᵀ)⁺ r.
            let y: Vec<f64> = (0..k)
                .map(|i| (0..k).map(|j| pinv[i * k + j] * residual0[j]).sum())
                .collect();
            let correction: Vec<f64> = (0..k)
                .map(|i| (0..k).map(|j| gram[(i, j)] * y[j]).sum())
                .collect();
            (
                ClusterPath::Projection { gram_pinv: pinv },
                rank,
                correction,
            )
        };
        report.rank += rank;
        for (r0, cr) in residual0.iter().zip(&correction) {
            report.violation = report.violation.max(r0.abs() as f32);
            report.residual = report.residual.max((r0 - cr).abs() as f32);
        }
        match cluster_path {
            ClusterPath::Projection { .. } => report.projected_clusters += 1,
            ClusterPath::Reduced { .. } => report.reduced_clusters += 1,
        }
        Cluster {
            rows,
            path: cluster_path,
        }
    }

    /// Makes `accel` satisfy `C p̈ = 0` (the constraints stay as they are while `C ṗ = 0`):
    /// the part of the stage that runs before the time step is chosen.
    pub fn project_accel(&mut self, accel: &mut [f32]) {
        self.enforce(accel, None);
    }

    /// Makes `accel` satisfy `C p̈ = t` with `t` chosen so that one `integrator` step of
    /// `dt_s` from `(p, p_dot)` lands on `C p = e` exactly (and leaves `C ṗ` at the drift
    /// rate): it removes whatever f32 rounding or a changed fixed part left behind.
    pub fn enforce_with_drift(
        &mut self,
        p: &[f32],
        p_dot: &[f32],
        accel: &mut [f32],
        dt_s: f32,
        integrator: Integrator,
    ) {
        if self.is_empty() || dt_s.is_nan() || dt_s <= 0.0 {
            return;
        }
        let dt = f64::from(dt_s);
        let velocity_weight = match integrator {
            Integrator::SemiImplicit => 1.0,
            Integrator::Explicit => 2.0,
        };
        // Targets first (they only read p and ṗ); taking the buffer out allocates nothing.
        let mut t = std::mem::take(&mut self.t);
        for (r, tr) in t.iter_mut().enumerate() {
            let (cx, cv) = self.dot_row_pair(r, p, p_dot);
            let cx = cx - f64::from(self.targets[r]);
            *tr = -cx / (dt * dt) - velocity_weight * cv / dt;
        }
        self.enforce(accel, Some(&t));
        self.t = t;
    }

    /// `accel ← accel − C⁺ (C accel − t)`, cluster by cluster, on either path.
    fn enforce(&mut self, accel: &mut [f32], targets: Option<&[f64]>) {
        let target = |r: usize| targets.map_or(0.0, |t| t[r]);
        let clusters = std::mem::take(&mut self.clusters);
        for cluster in &clusters {
            let rows = cluster.rows.clone();
            let k = rows.len();
            match &cluster.path {
                ClusterPath::Projection { gram_pinv } => {
                    for r in rows.clone() {
                        self.r[r] = self.dot_row(r, accel) - target(r);
                    }
                    for (i, r) in rows.clone().enumerate() {
                        let line = &gram_pinv[i * k..(i + 1) * k];
                        self.y[r] = line
                            .iter()
                            .zip(&self.r[rows.clone()])
                            .map(|(g, x)| g * x)
                            .sum();
                    }
                    for r in rows {
                        let y = self.y[r];
                        let s = self.row_start[r]..self.row_start[r + 1];
                        for (&c, &w) in self.cols[s.clone()].iter().zip(&self.weights[s]) {
                            accel[c as usize] -= (f64::from(w) * y) as f32;
                        }
                    }
                }
                ClusterPath::Reduced {
                    support,
                    null_basis,
                    nullity,
                    pinv,
                } => {
                    let s = support.len();
                    for (a, &c) in self.a_s.iter_mut().zip(support) {
                        *a = f64::from(accel[c as usize]);
                    }
                    // ḧ = Nᵀ p̈_S (eq. 12 in the reduced coordinates).
                    for (m, h) in self.h[..*nullity].iter_mut().enumerate() {
                        let col = &null_basis[m * s..(m + 1) * s];
                        *h = col.iter().zip(&self.a_s[..s]).map(|(n, a)| n * a).sum();
                    }
                    // p̈_S = N ḧ + C⁺ t.
                    self.a_s[..s].fill(0.0);
                    for (m, &h) in self.h[..*nullity].iter().enumerate() {
                        let col = &null_basis[m * s..(m + 1) * s];
                        for (a, n) in self.a_s[..s].iter_mut().zip(col) {
                            *a += n * h;
                        }
                    }
                    for (i, r) in rows.enumerate() {
                        let t = target(r);
                        if t != 0.0 {
                            let col = &pinv[i * s..(i + 1) * s];
                            for (a, q) in self.a_s[..s].iter_mut().zip(col) {
                                *a += q * t;
                            }
                        }
                    }
                    for (&c, &a) in support.iter().zip(&self.a_s[..s]) {
                        accel[c as usize] = a as f32;
                    }
                }
            }
        }
        self.clusters = clusters;
    }

    /// Largest `|C p − e|` over the rows on the region's coefficients.
    #[must_use]
    pub fn max_violation(&self, p: &[f32]) -> f32 {
        (0..self.targets.len())
            .map(|r| (self.dot_row(r, p) - f64::from(self.targets[r])).abs() as f32)
            .fold(0.0, f32::max)
    }
}
