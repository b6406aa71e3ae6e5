//! Fitting the RBF: constraints from surface particles, the dense `(k+4) × (k+4)` solve, and
//! greedy centre reduction above the dense limit.
//!
//! `I` models the signed distance, positive inside (where the clay's value exceeds its
//! iso-level): each surface particle `p` with outward normal `n` gives three constraints,
//! `I(p) = 0`, `I(p − δn) = δ` and `I(p + δn) = −δ` (§5.3: "one interior and one exterior
//! particle"). The system of eq. 11,
//!
//! ```text
//! [ Φ   P ] [λ]   [v]      Φᵢⱼ = |cᵢ − cⱼ|³,  Pᵢ = (1, xᵢ, yᵢ, zᵢ)
//! [ Pᵀ  0 ] [a] = [0]
//! ```
//!
//! is symmetric but indefinite (the polynomial block is a saddle point), so it is solved by LU
//! with partial pivoting (nalgebra, f64). Coordinates are centred and scaled to unit size
//! first, which keeps the matrix's entries within a few orders of magnitude of one another.
//! The dense solve costs `⅔ (k+4)³` flops and `8 (k+4)²` bytes; above
//! [`RbfOptions::max_centres`] the centres are chosen greedily (Carr et al.'s scheme): start
//! from an even subset, solve, evaluate the residual at every constraint, add the worst-fit
//! ones, and repeat until every residual is below the tolerance or the limit is reached.

use glam::{DVec3, Vec3};
use nalgebra::{DMatrix, DVector};

use crate::particles::ImplicitSurface;

/// Why an RBF could not be fitted.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum RbfError {
    /// No surface points were given.
    #[error("no surface points to interpolate")]
    NoPoints,
    /// The normal offset was not positive and finite.
    #[error("normal offset {offset} must be positive and finite")]
    BadOffset {
        /// The offset given.
        offset: f64,
    },
    /// A point or a value was not finite.
    #[error("constraint {index} is not finite")]
    NonFinite {
        /// Which constraint.
        index: usize,
    },
    /// The clay has no gradient at a surface point, so it has no normal there.
    #[error("no normal at surface point {index} (the clay's gradient vanishes there)")]
    NoNormal {
        /// Which point.
        index: usize,
    },
    /// The linear system is singular (coincident centres, or all centres on a plane).
    #[error("the interpolation system with {centres} centres is singular")]
    Singular {
        /// Centres in the system.
        centres: usize,
    },
    /// A limit below 4 centres leaves the polynomial undetermined.
    #[error("max_centres {max} is too small (at least 4)")]
    TooFewCentres {
        /// The limit given.
        max: usize,
    },
}

/// How to fit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RbfOptions {
    /// Offset of the inner and outer points along the normal, world units.
    pub offset: f64,
    /// Most centres in one dense solve; above it centres are reduced greedily.
    pub max_centres: usize,
    /// Greedy reduction stops when every constraint's residual is below this, world units.
    pub tolerance: f64,
}

impl RbfOptions {
    /// The dense limit by default: 3000 centres is a 72 MB matrix and about 2·10¹⁰ flops.
    pub const DEFAULT_MAX_CENTRES: usize = 3000;

    /// Defaults for a normal offset of `offset` world units: tolerance a hundredth of it.
    #[must_use]
    pub fn with_offset(offset: f64) -> Self {
        Self {
            offset,
            max_centres: Self::DEFAULT_MAX_CENTRES,
            tolerance: 0.01 * offset,
        }
    }
}

/// `I(x) = Σ λᵢ |x − cᵢ|³ + a + b x + c y + d z`.
#[derive(Clone, Debug, PartialEq)]
pub struct Rbf {
    /// Centres `cᵢ`, world units.
    pub centres: Vec<DVec3>,
    /// Weights `λᵢ`.
    pub weights: Vec<f64>,
    /// `(a, b, c, d)` of the linear polynomial, world units.
    pub poly: [f64; 4],
}

/// What a fit did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RbfFitReport {
    /// Constraints offered (three per surface point).
    pub constraints: usize,
    /// Centres kept.
    pub centres: usize,
    /// Largest `|I(xᵢ) − vᵢ|` over all constraints, world units.
    pub max_residual: f64,
    /// Greedy rounds (0 when the dense solve took every constraint).
    pub greedy_rounds: usize,
}

impl Rbf {
    /// `I(x)`: positive inside, about the signed distance near the surface.
    #[must_use]
    pub fn value(&self, x: DVec3) -> f64 {
        let mut sum = self.poly[0] + self.poly[1] * x.x + self.poly[2] * x.y + self.poly[3] * x.z;
        for (c, w) in self.centres.iter().zip(&self.weights) {
            let r = (x - *c).length();
            sum += w * r * r * r;
        }
        sum
    }

    /// `∇I(x)` (`∇|r|³ = 3 |r| r`).
    #[must_use]
    pub fn gradient(&self, x: DVec3) -> DVec3 {
        let mut g = DVec3::new(self.poly[1], self.poly[2], self.poly[3]);
        for (c, w) in self.centres.iter().zip(&self.weights) {
            let d = x - *c;
            g += d * (3.0 * w * d.length());
        }
        g
    }

    /// Number of centres.
    #[must_use]
    pub fn len(&self) -> usize {
        self.centres.len()
    }

    /// True when there are no centres.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.centres.is_empty()
    }
}

/// Interpolate `values` at `points` exactly (the dense eq. 11 over every point).
///
/// # Errors
/// [`RbfError::NoPoints`], [`RbfError::NonFinite`], [`RbfError::Singular`].
pub fn solve_rbf(points: &[DVec3], values: &[f64]) -> Result<Rbf, RbfError> {
    if points.is_empty() {
        return Err(RbfError::NoPoints);
    }
    for (i, (p, v)) in points.iter().zip(values).enumerate() {
        if !(p.is_finite() && v.is_finite()) {
            return Err(RbfError::NonFinite { index: i });
        }
    }
    // Centre and scale to unit size: |r|³ then stays O(1).
    let (mut lo, mut hi) = (DVec3::splat(f64::MAX), DVec3::splat(f64::MIN));
    for &p in points {
        lo = lo.min(p);
        hi = hi.max(p);
    }
    let centre = 0.5 * (lo + hi);
    let scale = 0.5 * (hi - lo).max_element().max(f64::MIN_POSITIVE);
    let k = points.len();
    let local: Vec<DVec3> = points.iter().map(|p| (*p - centre) / scale).collect();
    let size = k + 4;
    let mut a = DMatrix::<f64>::zeros(size, size);
    for j in 0..k {
        for i in j..k {
            let r = (local[i] - local[j]).length();
            let phi = r * r * r;
            a[(i, j)] = phi;
            a[(j, i)] = phi;
        }
        let p = local[j];
        for (m, q) in [1.0, p.x, p.y, p.z].into_iter().enumerate() {
            a[(j, k + m)] = q;
            a[(k + m, j)] = q;
        }
    }
    let mut b = DVector::<f64>::zeros(size);
    for (i, v) in values.iter().enumerate() {
        b[i] = *v;
    }
    let x = a
        .lu()
        .solve(&b)
        .filter(|x| x.iter().all(|v| v.is_finite()))
        .ok_or(RbfError::Singular { centres: k })?;
    // Back to world units: |x − c|³ = s³ |x' − c'|³ and P(x') with x' = (x − centre)/s.
    let s3 = scale * scale * scale;
    let weights = (0..k).map(|i| x[i] / s3).collect();
    let (a0, bx, by, bz) = (x[k], x[k + 1], x[k + 2], x[k + 3]);
    let poly = [
        a0 - (bx * centre.x + by * centre.y + bz * centre.z) / scale,
        bx / scale,
        by / scale,
        bz / scale,
    ];
    Ok(Rbf {
        centres: points.to_vec(),
        weights,
        poly,
    })
}

/// Fit the RBF to surface points of `field` (the settled particles; the clay, or any
/// [`ImplicitSurface`] whose gradient gives the normal): each gives a surface,
/// an inner and an outer constraint (§5.3). Above `options.max_centres` constraints the
/// centres are reduced greedily.
///
/// # Errors
/// [`RbfError::NoPoints`], [`RbfError::BadOffset`], [`RbfError::NoNormal`],
/// [`RbfError::TooFewCentres`], [`RbfError::Singular`], [`RbfError::NonFinite`].
pub fn fit_surface(
    field: &(impl ImplicitSurface + ?Sized),
    surface: &[Vec3],
    options: &RbfOptions,
) -> Result<(Rbf, RbfFitReport), RbfError> {
    if surface.is_empty() {
        return Err(RbfError::NoPoints);
    }
    if !(options.offset.is_finite() && options.offset > 0.0) {
        return Err(RbfError::BadOffset {
            offset: options.offset,
        });
    }
    if options.max_centres < 4 {
        return Err(RbfError::TooFewCentres {
            max: options.max_centres,
        });
    }
    let delta = options.offset;
    let mut points = Vec::with_capacity(3 * surface.len());
    let mut values = Vec::with_capacity(3 * surface.len());
    for (i, &p) in surface.iter().enumerate() {
        let g = field.eval(p).1.as_dvec3();
        let len = g.length();
        if len.is_nan() || len <= 1e-12 {
            return Err(RbfError::NoNormal { index: i });
        }
        // The value rises inward, so the outward normal is −∇f/|∇f|.
        let n = -g / len;
        let p = p.as_dvec3();
        points.extend([p, p - n * delta, p + n * delta]);
        values.extend([0.0, delta, -delta]);
    }
    let total = points.len();
    if total <= options.max_centres {
        let rbf = solve_rbf(&points, &values)?;
        let max_residual = max_residual(&rbf, &points, &values).0;
        return Ok((
            rbf,
            RbfFitReport {
                constraints: total,
                centres: total,
                max_residual,
                greedy_rounds: 0,
            },
        ));
    }
    greedy(&points, &values, options)
}

/// Largest residual and the residuals themselves.
fn max_residual(rbf: &Rbf, points: &[DVec3], values: &[f64]) -> (f64, Vec<f64>) {
    let residuals: Vec<f64> = points
        .iter()
        .zip(values)
        .map(|(p, v)| (rbf.value(*p) - v).abs())
        .collect();
    (residuals.iter().copied().fold(0.0, f64::max), residuals)
}

/// Greedy centre selection: an even quarter of the limit (whole surface/inner/outer triples),
/// then the worst-fit constraints, a quarter of the current count at a time.
fn greedy(
    points: &[DVec3],
    values: &[f64],
    options: &RbfOptions,
) -> Result<(Rbf, RbfFitReport), RbfError> {
    let total = points.len();
    let triples = total / 3;
    let start = (options.max_centres / 4 / 3).max(2).min(triples);
    let mut chosen = vec![false; total];
    for t in 0..start {
        let i = t * triples / start;
        for m in 0..3 {
            chosen[3 * i + m] = true;
        }
    }
    let mut rounds = 0;
    loop {
        let idx: Vec<usize> = (0..total).filter(|&i| chosen[i]).collect();
        let sub_p: Vec<DVec3> = idx.iter().map(|&i| points[i]).collect();
        let sub_v: Vec<f64> = idx.iter().map(|&i| values[i]).collect();
        let rbf = solve_rbf(&sub_p, &sub_v)?;
        rounds += 1;
        let (worst, residuals) = max_residual(&rbf, points, values);
        let room = options.max_centres - idx.len();
        let candidates = residuals
            .iter()
            .enumerate()
            .any(|(i, r)| !chosen[i] && *r > options.tolerance);
        if worst <= options.tolerance || room == 0 || !candidates {
            return Ok((
                rbf,
                RbfFitReport {
                    constraints: total,
                    centres: idx.len(),
                    max_residual: worst,
                    greedy_rounds: rounds,
                },
            ));
        }
        let mut order: Vec<usize> = (0..total)
            .filter(|&i| !chosen[i] && residuals[i] > options.tolerance)
            .collect();
        order.sort_unstable_by(|&a, &b| residuals[b].total_cmp(&residuals[a]));
        let add = order.len().min(room).min((idx.len() / 4).max(16));
        for &i in &order[..add] {
            chosen[i] = true;
        }
    }
}
