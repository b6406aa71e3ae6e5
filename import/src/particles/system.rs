//! The particle system: floaters of Witkin & Heckbert on the clay's iso-surface, with the
//! birth/death rules and the count feedback of Zhang et al. §5.5.
//!
//! Each step is a flat sequence of stages:
//! 1. `index` — sort the particles into the [`Pds`] with the query radius `3 σ_max` (beyond
//!    three standard deviations the Gaussian energy is negligible, §4.1).
//! 2. `repel` — per particle the energy `Eᵢ = Σⱼ α exp(−|rᵢⱼ|² / 2σᵢ²)`, its derivative in
//!    `σᵢ`, and the desired velocity `Dᵢ = σᵢ² Σⱼ rᵢⱼ (Eᵢⱼ/σᵢ² + Eⱼᵢ/σⱼ²)` (WH94 eq. 9–10);
//!    with curvature bias, in the metric of the wanted density and with the energy's
//!    derivative through that metric (stage 4b).
//! 3. `constrain` — the constraint velocity keeps `F = value − iso` at zero:
//!    `ṗᵢ = Dᵢ − (∇F·Dᵢ + φF) ∇F / |∇F|²` (WH94 eq. 6), with `φ = 1/dt`, i.e. each step also
//!    removes the particle's current constraint error to first order.
//! 4. `adapt` — `σᵢ` moves so that `Eᵢ` approaches the target `Ê`:
//!    `d ln σᵢ/dt = −ρ (Eᵢ − Ê) / (σᵢ ∂Eᵢ/∂σᵢ + β)` (WH94 eq. 12, written for `ln σ` so that the
//!    rule is scale free).
//! 5. `population` — fission where a particle's radius had to grow past `S σ̂` to reach `Ê`
//!    (its energy at the desired radius is low: the surface around it is sparse), death where
//!    it shrank below `θ S σ̂` (crowded), and the feedback `S ← S + S² (n − N) t` of §5.5 (eq. 13).
//!
//! `σ̂` is the radius at which `N` particles would tile the current surface (its area estimated
//! from the particles' own radii, each settled particle covering a hexagon of side `2σ/√3`), so
//! `S` only has to correct the estimate, not find the scale. Two departures from the paper,
//! both to hold the count at `N`: fissions are allowed only while `n < N` (plus as many as die
//! in the same step) and deaths only while `n > N` (plus as many as split), which turns the
//! paper's random death test into "most crowded first", "sparsest first" for fission; and a
//! particle whose gradient vanishes (it left the clay's transition band) is removed at once.

use glam::Vec3;

use super::pds::Pds;
use super::surface::ImplicitSurface;

/// Why the particles could not be seeded or stepped.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ParticleError {
    /// The requested particle count was zero.
    #[error("the particle count must be at least 1")]
    ZeroCount,
    /// No point of the clay's surface was found to seed from.
    #[error("no surface found: the clay has no point where its value crosses the iso-level")]
    NoSurface,
    /// The time step was not positive and finite.
    #[error("time step {dt} must be positive and finite")]
    BadTimeStep {
        /// The step given.
        dt: f32,
    },
}

/// How neighbours are found: the PDS, or every pair (the reference the benchmark compares).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum NeighbourSearch {
    /// The particle division structure (`2ᵏ` cubes per axis).
    #[default]
    Pds,
    /// All pairs: `O(n²)` per step.
    AllPairs,
}

/// The constants of the particle system (defaults after Witkin & Heckbert's §6).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParticleParams {
    /// The user's particle count `N`.
    pub target_count: usize,
    /// Energy scale `α` of the Gaussian repulsion.
    pub alpha: f32,
    /// Target energy `Ê` as a fraction of `α` (0.8: about six neighbours at `2σ`).
    pub energy_ratio: f32,
    /// Rate `ρ` at which `σᵢ` approaches the target energy.
    pub rho: f32,
    /// Damping `β` of the radius rule (keeps it finite with no neighbours).
    pub beta: f32,
    /// Death threshold `θ`: a particle dies when `σᵢ < θ S σ̂`.
    pub theta: f32,
    /// Fission threshold: a particle splits when `σᵢ > fission_ratio · S σ̂`.
    pub fission_ratio: f32,
    /// Gain of the feedback `S` (eq. 13 uses `t = count_gain / N`).
    pub count_gain: f32,
    /// Curvature bias (Zhang §7, beyond the paper): the particle density where the surface is
    /// most curved over that where it is flat. 1 samples evenly.
    pub curvature_ratio: f32,
    /// The largest change of `ln σᵢ` in one step.
    pub max_log_sigma_step: f32,
    /// The largest tangential move in one step, as a fraction of `σᵢ`.
    pub max_move_ratio: f32,
}

impl ParticleParams {
    /// Defaults for `target_count` particles.
    #[must_use]
    pub fn new(target_count: usize) -> Self {
        Self {
            target_count,
            alpha: 6.0,
            energy_ratio: 0.8,
            rho: 15.0,
            beta: 10.0,
            theta: 0.5,
            fission_ratio: 1.2,
            count_gain: 0.05,
            curvature_ratio: 1.0,
            max_log_sigma_step: 0.2,
            max_move_ratio: 0.3,
        }
    }
}

/// What one step did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StepReport {
    /// Particles after the step.
    pub count: usize,
    /// Particles that split.
    pub births: usize,
    /// Particles removed for crowding.
    pub deaths: usize,
    /// Particles removed because they left the clay (no gradient).
    pub lost: usize,
}

/// Particles constrained to the iso-surface of a [`BSplineLattice`].
#[derive(Clone, Debug)]
pub struct ParticleSystem {
    params: ParticleParams,
    search: NeighbourSearch,
    positions: Vec<Vec3>,
    sigmas: Vec<f32>,
    /// The feedback `S` of §5.5.
    feedback: f32,
    rng: u64,
    pds: Pds,
    // Scratch, reused every step.
    energy: Vec<f32>,
    denergy: Vec<f32>,
    desired: Vec<Vec3>,
    keep: Vec<bool>,
    candidates: Vec<u32>,
    /// Per-particle scale of the fission and death radii (1 without curvature bias).
    scale: Vec<f32>,
    curvature: Vec<f32>,
    raw_curvature: Vec<f32>,
    sorted: Vec<f32>,
    splitting: Vec<bool>,
    order: Vec<u32>,
    /// `ln sᵢ` of the scale above (with curvature bias).
    ln_scale: Vec<f32>,
    new_index: Vec<u32>,
}

/// With curvature bias, a crowded and a sparse particle swap (one dies, one splits) while
/// their `σ / scale` differ by more than this factor.
pub const SWAP_RATIO: f32 = 1.1;

/// The curvature's finite-difference step, as a fraction of the surface's resolution.
const CURVATURE_STEP_OF_RESOLUTION: f32 = 0.5;

/// The width (standard deviation) of the Gaussian the curvature is smoothed with over the
/// neighbours, as a fraction of the surface's resolution: a fitted lattice's iso-surface
/// ripples at the knot spacing, and its curvature with it.
const CURVATURE_SMOOTHING_OF_RESOLUTION: f32 = 0.5;

/// The largest `σ` allowed, as a fraction of the surface's bounds.
const MAX_SIGMA_OF_EXTENT: f32 = 0.25;

impl ParticleSystem {
    /// An empty system (seed it with [`ParticleSystem::seed_random`] or
    /// [`ParticleSystem::from_positions`]).
    ///
    /// # Errors
    /// [`ParticleError::ZeroCount`] when `params.target_count` is zero.
    pub fn new(params: ParticleParams) -> Result<Self, ParticleError> {
        if params.target_count == 0 {
            return Err(ParticleError::ZeroCount);
        }
        Ok(Self {
            params,
            search: NeighbourSearch::Pds,
            positions: Vec::new(),
            sigmas: Vec::new(),
            feedback: 1.0,
            rng: 0x9E37_79B9_7F4A_7C15,
            pds: Pds::default(),
            energy: Vec::new(),
            denergy: Vec::new(),
            desired: Vec::new(),
            keep: Vec::new(),
            candidates: Vec::new(),
            scale: Vec::new(),
            curvature: Vec::new(),
            raw_curvature: Vec::new(),
            sorted: Vec::new(),
            splitting: Vec::new(),
            order: Vec::new(),
            ln_scale: Vec::new(),
            new_index: Vec::new(),
        })
    }

    /// Choose how neighbours are found (the PDS by default).
    pub fn set_search(&mut self, search: NeighbourSearch) {
        self.search = search;
    }

    /// Change the user's particle count `N`.
    ///
    /// # Errors
    /// [`ParticleError::ZeroCount`] when `count` is zero.
    pub fn set_target_count(&mut self, count: usize) -> Result<(), ParticleError> {
        if count == 0 {
            return Err(ParticleError::ZeroCount);
        }
        self.params.target_count = count;
        Ok(())
    }

    /// The parameters in use.
    #[must_use]
    pub fn params(&self) -> &ParticleParams {
        &self.params
    }

    /// Particle positions.
    #[must_use]
    pub fn positions(&self) -> &[Vec3] {
        &self.positions
    }

    /// Repulsion radii `σᵢ`.
    #[must_use]
    pub fn sigmas(&self) -> &[f32] {
        &self.sigmas
    }

    /// Each particle's wanted density relative to the flattest parts: 1 without curvature
    /// bias, up to `curvature_ratio` where the surface is most curved (as of the last step).
    /// Allocates nothing (the follower calls it for every published view).
    #[must_use]
    pub fn wanted_density(&self) -> impl ExactSizeIterator<Item = f32> + '_ {
        let fresh = self.scale.len() == self.positions.len();
        (0..self.positions.len()).map(move |i| {
            if fresh {
                let s = self.scale[i];
                (s * s).recip()
            } else {
                1.0
            }
        })
    }

    /// Number of particles.
    #[must_use]
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// True when there are no particles.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// The feedback `S` of §5.5.
    #[must_use]
    pub fn feedback(&self) -> f32 {
        self.feedback
    }

    /// The PDS level `k` of the last step.
    #[must_use]
    pub fn pds_level(&self) -> u32 {
        self.pds.level()
    }

    fn next_unit(&mut self) -> f32 {
        // splitmix64: a fixed seed makes every run of the system identical.
        self.rng = self.rng.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.rng;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 40) as f32 / (1u64 << 24) as f32
    }

    /// Replace the particles by `positions` (projected onto the surface by the next steps),
    /// each with radius `sigma`.
    pub fn from_positions(&mut self, positions: &[Vec3], sigma: f32) {
        self.positions.clear();
        self.positions.extend_from_slice(positions);
        self.sigmas.clear();
        self.sigmas
            .resize(positions.len(), sigma.max(f32::MIN_POSITIVE));
        self.scale.clear();
    }

    /// Replace the particles by `count` points scattered at random (seeded) on the surface:
    /// points drawn uniformly in its bounds (the clay's support), kept where they lie within
    /// [`ImplicitSurface::resolution`] of it (first order), and projected onto the surface by Newton steps. Each gets
    /// the radius at which `count` particles would tile the surface.
    ///
    /// # Errors
    /// [`ParticleError::ZeroCount`] for `count == 0`; [`ParticleError::NoSurface`] when a
    /// bounded number of draws (`2000 · count + 100000`) finds too few surface points.
    pub fn seed_random(
        &mut self,
        field: &(impl ImplicitSurface + ?Sized),
        count: usize,
        seed: u64,
    ) -> Result<(), ParticleError> {
        if count == 0 {
            return Err(ParticleError::ZeroCount);
        }
        self.rng = seed ^ 0xD1B5_4A32_D192_ED03;
        let (lo, hi) = field.bounds();
        let extent = hi - lo;
        let band = field.resolution();
        let mut points = Vec::with_capacity(count);
        let max_draws = 2000 * count + 100_000;
        let mut draws = 0;
        while points.len() < count && draws < max_draws {
            draws += 1;
            let x = lo + extent * Vec3::new(self.next_unit(), self.next_unit(), self.next_unit());
            let (f, g) = field.eval(x);
            let g2 = g.length_squared();
            if g2 <= f32::EPSILON || (f.abs() / g2.sqrt()) > band {
                continue;
            }
            if let Some(p) = project_point(field, x, 8) {
                points.push(p);
            }
        }
        if points.is_empty() {
            return Err(ParticleError::NoSurface);
        }
        // Area from the draws: the band of half-width `band` around the surface holds
        // `hits / draws` of the box's volume.
        let area =
            points.len() as f32 / draws as f32 * extent.x * extent.y * extent.z / (2.0 * band);
        let sigma = sigma_for(area, count);
        self.from_positions(&points, sigma);
        Ok(())
    }

    /// Move every particle onto the surface by `iterations` Newton steps along the gradient
    /// (`p ← p − F ∇F / |∇F|²`); particles where the gradient vanishes are removed.
    pub fn project(&mut self, field: &(impl ImplicitSurface + ?Sized), iterations: usize) {
        let mut w = 0;
        for r in 0..self.positions.len() {
            if let Some(p) = project_point(field, self.positions[r], iterations) {
                self.positions[w] = p;
                self.sigmas[w] = self.sigmas[r];
                if let Some(&k) = self.scale.get(r) {
                    self.scale[w] = k;
                }
                w += 1;
            }
        }
        self.positions.truncate(w);
        self.sigmas.truncate(w);
        self.scale.truncate(w);
    }

    /// Run `steps` steps of size `dt = 0.1` and then project the particles onto the surface
    /// (two Newton steps). Returns the report of the last step.
    pub fn settle(&mut self, field: &(impl ImplicitSurface + ?Sized), steps: usize) -> StepReport {
        let mut report = StepReport {
            count: self.len(),
            ..StepReport::default()
        };
        for _ in 0..steps {
            // NOTE: `step` refuses only a bad `dt`, and DEFAULT_DT is positive and finite.
            if let Ok(r) = self.step(field, Self::DEFAULT_DT) {
                report = r;
            }
        }
        self.project(field, 2);
        report.count = self.len();
        report
    }

    /// The step [`ParticleSystem::settle`] uses. Velocities scale with `σ`, so the step is
    /// dimensionless: a particle moves at most `max_move_ratio · σᵢ` per step.
    pub const DEFAULT_DT: f32 = 0.1;

    /// One step of the particle system (see the module docs for its stages).
    ///
    /// # Errors
    /// [`ParticleError::BadTimeStep`] when `dt` is not positive and finite (nothing changes).
    pub fn step(
        &mut self,
        field: &(impl ImplicitSurface + ?Sized),
        dt: f32,
    ) -> Result<StepReport, ParticleError> {
        if !(dt.is_finite() && dt > 0.0) {
            return Err(ParticleError::BadTimeStep { dt });
        }
        let mut report = StepReport::default();
        if self.positions.is_empty() {
            return Ok(report);
        }
        self.index(field);
        self.repel();
        report.lost = self.constrain(field, dt);
        self.adapt(field, dt);
        self.bias(field);
        let (births, deaths) = self.population(field);
        report.births = births;
        report.deaths = deaths;
        report.count = self.positions.len();
        Ok(report)
    }

    /// Stage 1: the PDS over the surface's bounds, query radius `3 σ_max s_max` (the
    /// largest radius in world units).
    fn index(&mut self, field: &(impl ImplicitSurface + ?Sized)) {
        let (lo, hi) = field.bounds();
        if self.scale.len() != self.positions.len() {
            self.scale.clear();
            self.scale.resize(self.positions.len(), 1.0);
        }
        self.ln_scale.clear();
        let ratio = self.params.curvature_ratio;
        if ratio.is_finite() && ratio > 1.0 {
            // Read by `repel` for the gradient of the metric (only with bias).
            self.ln_scale.extend(self.scale.iter().map(|s| s.ln()));
        }
        let reach = 3.0 * self.query_radius();
        self.pds.build(&self.positions, lo, hi, reach);
    }

    /// `σ_max · s_max`: no pair farther apart than three times this interacts.
    fn query_radius(&self) -> f32 {
        let sigma_max = self.sigmas.iter().copied().fold(0.0f32, f32::max);
        let scale_max = self.scale.iter().copied().fold(1.0f32, f32::max);
        sigma_max * scale_max
    }

    /// Stage 2: energies, their `σ` derivatives, and the desired (repulsion) velocities.
    ///
    /// With curvature bias the pair energy is `α exp(−r²/(2σᵢ² sᵢ sⱼ))`, and the velocity is
    /// its whole negative gradient in `pᵢ`: the repulsion `Σⱼ cᵢⱼ (pᵢ − pⱼ)/(sᵢ sⱼ)`, with
    /// `cᵢⱼ = Eᵢⱼ/σᵢ² + Eⱼᵢ/σⱼ²`, and the pull through `sᵢ(pᵢ)`, `−½ Σⱼ cᵢⱼ r²ᵢⱼ ∇ ln sᵢ` (`rᵢⱼ`
    /// in the metric), with `∇ ln sᵢ` fitted by least squares to the neighbours' `ln sⱼ`.
    /// Leaving the pull out settles at about 80% of the density ratio asked.
    fn repel(&mut self) {
        let n = self.positions.len();
        self.energy.clear();
        self.energy.resize(n, 0.0);
        self.denergy.clear();
        self.denergy.resize(n, 0.0);
        self.desired.clear();
        self.desired.resize(n, Vec3::ZERO);
        let alpha = self.params.alpha;
        let reach = 3.0 * self.query_radius();
        let ratio = self.params.curvature_ratio;
        let biased = ratio.is_finite() && ratio > 1.0;
        for i in 0..n {
            let p = self.positions[i];
            let si = self.sigmas[i];
            let ki = self.scale[i];
            let inv_si2 = 1.0 / (si * si);
            let (mut e, mut de, mut d) = (0.0f32, 0.0f32, Vec3::ZERO);
            // With bias: the regression sums of `ln s` over the neighbours, and the sum that
            // multiplies `∇ ln sᵢ` in the pull along the wanted density's gradient.
            let (mut slope, mut spread, mut pull) = (Vec3::ZERO, 0.0f32, 0.0f32);
            let (sigmas, scale, ln_scale) = (&self.sigmas, &self.scale, &self.ln_scale);
            let mut pair = |j: usize, q: Vec3, r2: f32| {
                if j == i {
                    return;
                }
                let sj = sigmas[j];
                // Distances in the metric of the wanted density (none without curvature bias).
                let (r2_world, (r2, along)) = if biased {
                    let metric = ki * scale[j];
                    (r2, (r2 / metric, metric.recip()))
                } else {
                    (r2, (r2, 1.0))
                };
                let cut = 3.0 * si.max(sj);
                if r2 > cut * cut {
                    return;
                }
                let inv_sj2 = 1.0 / (sj * sj);
                let eij = alpha * (-0.5 * r2 * inv_si2).exp();
                let eji = alpha * (-0.5 * r2 * inv_sj2).exp();
                e += eij;
                de += r2 * inv_si2 * eij;
                let c = eij * inv_si2 + eji * inv_sj2;
                d += (p - q) * (c * along);
                if biased {
                    slope += (q - p) * (eij * (ln_scale[j] - ln_scale[i]));
                    spread += eij * r2_world;
                    pull += c * r2;
                }
            };
            match self.search {
                NeighbourSearch::Pds => self.pds.for_each_within(p, reach, &mut pair),
                NeighbourSearch::AllPairs => {
                    for (j, &q) in self.positions.iter().enumerate() {
                        pair(j, q, (q - p).length_squared());
                    }
                }
            }
            if biased && spread > 0.0 {
                // `∇ ln sᵢ` by least squares over the neighbours in the tangent plane (for an
                // even neighbourhood `Σ w d dᵀ = ½ Σ w |d|² P`), and the energy's derivative
                // through `sᵢ`: `−½ Σⱼ cᵢⱼ r²ᵢⱼ ∇ ln sᵢ` (in the same units as the repulsion).
                let grad = slope * (2.0 / spread);
                d -= grad * (0.5 * pull);
            }
            self.energy[i] = e;
            // σ ∂E/∂σ (dimensionless).
            self.denergy[i] = de;
            self.desired[i] = d * (si * si * ki);
        }
    }

    /// Stage 3: constrained motion. Returns how many particles were removed for having no
    /// gradient (they left the clay's transition band).
    fn constrain(&mut self, field: &(impl ImplicitSurface + ?Sized), dt: f32) -> usize {
        let max_move = self.params.max_move_ratio;
        self.keep.clear();
        let mut lost = 0;
        for i in 0..self.positions.len() {
            let p = self.positions[i];
            let (f, g) = field.eval(p);
            let g2 = g.length_squared();
            if g2.is_nan() || g2 <= 1e-12 || !f.is_finite() {
                self.keep.push(false);
                lost += 1;
                continue;
            }
            let d = self.desired[i];
            // Tangential part of the repulsion, limited to a fraction of σ per step.
            let mut tangent = (d - g * (g.dot(d) / g2)) * dt;
            let limit = max_move * self.sigmas[i] * self.scale[i];
            let len = tangent.length();
            if len > limit {
                tangent *= limit / len;
            }
            // Feedback φ = 1/dt: the constraint error is removed to first order this step.
            let correction = g * (f / g2);
            self.positions[i] = p + tangent - correction;
            self.keep.push(true);
        }
        lost
    }

    /// Stage 4: radii toward the target energy.
    fn adapt(&mut self, field: &(impl ImplicitSurface + ?Sized), dt: f32) {
        let p = self.params;
        let target = p.energy_ratio * p.alpha;
        let (lo, hi) = field.bounds();
        let sigma_cap = MAX_SIGMA_OF_EXTENT * (hi - lo).max_element();
        let sigma_floor = 1e-4 * field.resolution();
        for i in 0..self.sigmas.len() {
            let rate = -p.rho * (self.energy[i] - target) / (self.denergy[i] + p.beta);
            let step = (rate * dt).clamp(-p.max_log_sigma_step, p.max_log_sigma_step);
            self.sigmas[i] = (self.sigmas[i] * step.exp()).clamp(sigma_floor, sigma_cap);
        }
    }

    /// Stage 4b (beyond the paper, its §7): curvature bias. Each particle gets the length
    /// scale `sᵢ = ρᵢ^(−1/2)` of the wanted density `ρᵢ = 1 + (ratio − 1) · min(κᵢ / κ₉₀, 1)`,
    /// `κᵢ = √(k₁² + k₂²)` the norm of the shape operator at the particle (central differences
    /// of the gradient at half the resolution, then a Gaussian average over the neighbours of
    /// width half the resolution: a fitted lattice's surface ripples at its knot spacing) and
    /// `κ₉₀` the 90th percentile over the particles. The particles live in the metric this
    /// defines: a pair's squared distance is measured in units of `sᵢ sⱼ` (repulsion, energy
    /// and the radii `σᵢ`, which are therefore in those units, world radius `σᵢ sᵢ`), and
    /// they follow the energy's whole gradient, including its part through `sᵢ`, which pulls
    /// each particle up the wanted density (after Meyer et al.'s adaptive repulsion; see
    /// `repel`). The settled state, even in the metric, then has `ρᵢ` times the density where
    /// the surface is curved (`tests/particles.rs`: within 10% of the ratio asked on a rounded
    /// box). Fission, death and the count feedback work on the metric's radii unchanged.
    /// Without bias `sᵢ = 1` and every step is exactly the unbiased one.
    fn bias(&mut self, field: &(impl ImplicitSurface + ?Sized)) {
        let n = self.positions.len();
        let ratio = self.params.curvature_ratio;
        let biased = ratio.is_finite() && ratio > 1.0;
        if !biased || n == 0 {
            self.scale.clear();
            self.scale.resize(n, 1.0);
            return;
        }
        let resolution = field.resolution();
        let h = CURVATURE_STEP_OF_RESOLUTION * resolution;
        self.raw_curvature.clear();
        for &p in &self.positions {
            self.raw_curvature.push(shape_operator_norm(field, p, h));
        }
        // Smoothed over the neighbours within the PDS's reach (built this step with the
        // previous scales; positions have moved by at most `max_move_ratio σ` since).
        let width = CURVATURE_SMOOTHING_OF_RESOLUTION * resolution;
        let reach = (3.0 * self.query_radius()).min(2.5 * width);
        let inv = 1.0 / (2.0 * width * width);
        self.curvature.clear();
        for i in 0..n {
            let p = self.positions[i];
            let (mut weights, mut sum) = (0.0f32, 0.0f32);
            let (positions, raw) = (&self.positions, &self.raw_curvature);
            self.pds.for_each_within(p, reach, |j, _, _| {
                let w = (-(positions[j] - p).length_squared() * inv).exp();
                weights += w;
                sum += w * raw[j];
            });
            // NOTE: the particle itself is within reach unless it moved out of its cubes'
            // neighbourhood since the build; then its own estimate stands.
            self.curvature
                .push(if weights > 0.0 { sum / weights } else { raw[i] });
        }
        self.sorted.clear();
        self.sorted.extend_from_slice(&self.curvature);
        let k = (9 * n / 10).min(n - 1);
        let (_, &mut reference, _) = self.sorted.select_nth_unstable_by(k, f32::total_cmp);
        self.scale.clear();
        self.scale.resize(n, 1.0);
        if reference.is_nan() || reference <= 0.0 {
            return;
        }
        for (s, c) in self.scale.iter_mut().zip(&self.curvature) {
            let density = 1.0 + (ratio - 1.0) * (c / reference).clamp(0.0, 1.0);
            *s = density.sqrt().recip();
        }
    }

    /// With curvature bias, the fission and death thresholds alone would leave an evenly
    /// seeded population as it is (a particle between them neither splits nor dies, and the
    /// count is already `N`), and the repulsion alone moves particles only locally. So,
    /// count-neutral swaps: the particle most crowded in the metric (smallest `σᵢ`, the
    /// metric's radius) dies and the sparsest splits, while the two differ by
    /// more than [`SWAP_RATIO`], at most `n/100 + 1` pairs a step. Returns the swaps, whose
    /// parents are appended to `candidates`.
    fn redistribute(&mut self, n: usize) -> usize {
        let ratio = self.params.curvature_ratio;
        if !(ratio.is_finite() && ratio > 1.0) {
            return 0;
        }
        self.splitting.clear();
        self.splitting.resize(n, false);
        for &c in &self.candidates {
            self.splitting[c as usize] = true;
        }
        let sigmas = &self.sigmas;
        let key = |i: u32| sigmas[i as usize];
        let (keep, splitting) = (&self.keep, &self.splitting);
        self.order.clear();
        self.order
            .extend((0..n as u32).filter(|&i| keep[i as usize] && !splitting[i as usize]));
        self.order
            .sort_unstable_by(|&a, &b| key(a).total_cmp(&key(b)));
        let order = &self.order;
        let max_swaps = n / 100 + 1;
        let mut swaps = 0;
        while swaps < max_swaps && 2 * swaps + 1 < order.len() {
            let (lo, hi) = (order[swaps], order[order.len() - 1 - swaps]);
            if key(hi) <= SWAP_RATIO * key(lo) {
                break;
            }
            self.keep[lo as usize] = false;
            self.candidates.push(hi);
            swaps += 1;
        }
        swaps
    }

    /// Stage 5: fission, death and the count feedback. Returns (births, deaths).
    fn population(&mut self, field: &(impl ImplicitSurface + ?Sized)) -> (usize, usize) {
        let n = self.positions.len();
        let big_n = self.params.target_count;
        // σ̂: the radius at which N particles tile the surface whose area the live particles'
        // radii estimate.
        let area: f32 = self
            .sigmas
            .iter()
            .zip(&self.keep)
            .filter(|(_, k)| **k)
            .map(|(s, _)| area_of(*s))
            .sum();
        let sigma_hat = sigma_for(area, big_n);
        let high = self.params.fission_ratio * self.feedback * sigma_hat;
        let low = self.params.theta * self.feedback * sigma_hat;

        // Death candidates, most crowded first.
        self.candidates.clear();
        for i in 0..n {
            if self.keep[i] && self.sigmas[i] < low {
                self.candidates.push(i as u32);
            }
        }
        let live = self.keep.iter().filter(|k| **k).count();
        let death_candidates = self.candidates.len();
        let fission_candidates = (0..n)
            .filter(|&i| self.keep[i] && self.sigmas[i] > high)
            .count();
        let swaps = death_candidates.min(fission_candidates);
        let deaths = death_candidates.min(live.saturating_sub(big_n) + swaps);
        {
            let sigmas = &self.sigmas;
            let key = |i: u32| sigmas[i as usize];
            self.candidates
                .sort_unstable_by(|&a, &b| key(a).total_cmp(&key(b)));
        }
        for &i in &self.candidates[..deaths] {
            self.keep[i as usize] = false;
        }
        let after_deaths = live - deaths;
        // Fission candidates, sparsest first, at most half the population per step.
        let births = fission_candidates
            .min(big_n.saturating_sub(after_deaths))
            .min(after_deaths / 2 + 1);
        self.candidates.clear();
        for i in 0..n {
            if self.keep[i] && self.sigmas[i] > high {
                self.candidates.push(i as u32);
            }
        }
        {
            let sigmas = &self.sigmas;
            let key = |i: u32| sigmas[i as usize];
            self.candidates
                .sort_unstable_by(|&a, &b| key(b).total_cmp(&key(a)));
        }
        self.candidates.truncate(births);
        let swaps = self.redistribute(n);
        let (births, deaths) = (births + swaps, deaths + swaps);
        // Compact the survivors (remembering where each went), then append the children.
        self.new_index.clear();
        let mut w = 0;
        for r in 0..n {
            if self.keep[r] {
                self.positions[w] = self.positions[r];
                self.sigmas[w] = self.sigmas[r];
                self.scale[w] = self.scale[r];
                self.new_index.push(w as u32);
                w += 1;
            } else {
                self.new_index.push(u32::MAX);
            }
        }
        self.positions.truncate(w);
        self.sigmas.truncate(w);
        self.scale.truncate(w);
        for c in 0..self.candidates.len() {
            let parent = self.new_index[self.candidates[c] as usize] as usize;
            let (p, s, k) = (
                self.positions[parent],
                self.sigmas[parent],
                self.scale[parent],
            );
            let g = field.eval(p).1;
            let t = random_tangent(g, self.next_unit(), self.next_unit());
            let child_sigma = s * std::f32::consts::FRAC_1_SQRT_2;
            let half = 0.5 * s * k;
            self.positions[parent] = p - t * half;
            self.sigmas[parent] = child_sigma;
            self.positions.push(p + t * half);
            self.sigmas.push(child_sigma);
            self.scale.push(k);
        }
        // Eq. 13 with t = count_gain / N.
        let error = self.positions.len() as f32 - big_n as f32;
        let gain = self.params.count_gain / big_n as f32;
        self.feedback =
            (self.feedback + self.feedback * self.feedback * error * gain).clamp(0.1, 10.0);
        (births, deaths)
    }
}

/// Area one settled particle of radius `σ` covers: a hexagon whose inscribed circle has
/// radius `σ` (neighbours at `2σ`, where the energy is `0.8 α` for six of them).
#[inline]
fn area_of(sigma: f32) -> f32 {
    2.0 * 3.0f32.sqrt() * sigma * sigma
}

/// The radius at which `count` settled particles tile `area`.
#[inline]
fn sigma_for(area: f32, count: usize) -> f32 {
    (area / (2.0 * 3.0f32.sqrt() * count.max(1) as f32)).sqrt()
}

/// A unit vector perpendicular to `normal`, at the angle given by `u ∈ [0, 1)` (and `v`
/// to pick a helper axis deterministically).
fn random_tangent(normal: Vec3, u: f32, _v: f32) -> Vec3 {
    let n = normal.normalize_or(Vec3::Z);
    let helper = if n.x.abs() < 0.9 { Vec3::X } else { Vec3::Y };
    let a = n.cross(helper).normalize();
    let b = n.cross(a);
    let angle = std::f32::consts::TAU * u;
    a * angle.cos() + b * angle.sin()
}

/// Newton steps `p ← p − F ∇F / |∇F|²` from `x`; `None` where the gradient vanishes or the
/// result is not finite.
fn project_point(
    field: &(impl ImplicitSurface + ?Sized),
    x: Vec3,
    iterations: usize,
) -> Option<Vec3> {
    let mut p = x;
    for _ in 0..iterations {
        let (f, g) = field.eval(p);
        let g2 = g.length_squared();
        if g2.is_nan() || g2 <= 1e-12 {
            return None;
        }
        p -= g * (f / g2);
    }
    p.is_finite().then_some(p)
}

/// Distance from each point to its nearest other point (all pairs through a [`Pds`] at the
/// given query radius; points with no other within `radius` get `f32::INFINITY`).
#[must_use]
pub fn nearest_neighbour_distances(points: &[Vec3], radius: f32) -> Vec<f32> {
    let (mut lo, mut hi) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN));
    for &p in points {
        lo = lo.min(p);
        hi = hi.max(p);
    }
    let mut pds = Pds::default();
    pds.build(points, lo, hi, radius);
    points
        .iter()
        .enumerate()
        .map(|(i, &p)| {
            let mut best = f32::INFINITY;
            pds.for_each_within(p, radius, |j, _, d2| {
                if j != i {
                    best = best.min(d2);
                }
            });
            best.sqrt()
        })
        .collect()
}

/// `√(k₁² + k₂²)`: the Frobenius norm of the shape operator `P H P / |∇F|` at `p`, with the
/// Hessian `H` from central differences of the gradient at step `h` and `P` the projection
/// onto the tangent plane.
fn shape_operator_norm(field: &(impl ImplicitSurface + ?Sized), p: Vec3, h: f32) -> f32 {
    let g = field.eval(p).1;
    let len = g.length();
    if len.is_nan() || len <= 1e-12 {
        return 0.0;
    }
    let col = |axis: Vec3| (field.eval(p + axis * h).1 - field.eval(p - axis * h).1) / (2.0 * h);
    let hess = glam::Mat3::from_cols(col(Vec3::X), col(Vec3::Y), col(Vec3::Z));
    let hess = (hess + hess.transpose()) * 0.5;
    let n = g / len;
    let proj = glam::Mat3::IDENTITY - glam::Mat3::from_cols(n * n.x, n * n.y, n * n.z);
    let shape = proj * hess * proj;
    let norm2 = shape.x_axis.length_squared()
        + shape.y_axis.length_squared()
        + shape.z_axis.length_squared();
    norm2.sqrt() / len
}
