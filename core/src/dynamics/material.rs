//! Material constants of the density-spring model and the stepping parameters.

/// Uniform default material of a region (every mass point starts with these values; the
/// per-point fields in [`super::RegionState`] can then be edited).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    /// Mass of each mass point (`μ`).
    pub mass: f32,
    /// Damping of each mass point's density velocity (`γ`), per second times mass.
    pub damping: f32,
    /// Spring stiffness (`ρ`) between neighbouring densities.
    pub stiffness: f32,
    /// Rate (per second) at which rest densities drift toward the current ones past the yield
    /// threshold; 0 is perfectly elastic.
    pub plasticity_per_s: f32,
    /// Density deviation from rest below which no plastic drift happens.
    pub yield_density: f32,
    /// Which grid neighbours the density springs join (6, 18 or 26); the stiffness is
    /// normalised per neighbourhood so that all three resist a smooth deformation alike (see
    /// [`Neighbourhood::weight`]).
    pub neighbourhood: Neighbourhood,
}

impl Material {
    /// This material on mass points holding `volume_ratio` times the volume of the ones it
    /// was set for (a detail patch at half the spacing holds 1/8): mass, damping and stiffness
    /// scale with the volume, so a force spread over a region moves it alike at any spacing
    /// and the step's stability (`√(ρ/μ)`) is unchanged. Plasticity and yield are per density
    /// and stay.
    #[must_use]
    pub fn for_volume_ratio(self, volume_ratio: f32) -> Self {
        Self {
            mass: self.mass * volume_ratio,
            damping: self.damping * volume_ratio,
            stiffness: self.stiffness * volume_ratio,
            ..self
        }
    }

    /// Elastic clay: springs back fully.
    pub const ELASTIC: Self = Self {
        mass: 1.0,
        damping: 40.0,
        stiffness: 1000.0,
        plasticity_per_s: 0.0,
        yield_density: 0.0,
        neighbourhood: Neighbourhood::Six,
    };

    /// Soft clay: dents stay. The yield is low enough that a light stroke already leaves its
    /// mark; the default material, so a new sculpt keeps what the tools do.
    pub const PLASTIC: Self = Self {
        plasticity_per_s: 8.0,
        yield_density: 0.02,
        ..Self::ELASTIC
    };
}

/// A material constant out of range: which, its value, and what it must be.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
#[error("material {name} = {value} must be finite and {need}")]
pub struct MaterialError {
    /// The constant's name (`mass`, `damping`, `stiffness`, `plasticity_per_s`,
    /// `yield_density`).
    pub name: &'static str,
    /// Its value.
    pub value: f32,
    /// What it must be: "positive" or "zero or more".
    pub need: &'static str,
}

impl Material {
    /// Checks that the constants can drive a step: all finite, mass positive, the others zero
    /// or more.
    ///
    /// # Errors
    /// Names the first constant out of range and its value.
    pub fn validate(&self) -> Result<(), MaterialError> {
        let fields = [
            ("mass", self.mass, false),
            ("damping", self.damping, true),
            ("stiffness", self.stiffness, true),
            ("plasticity_per_s", self.plasticity_per_s, true),
            ("yield_density", self.yield_density, true),
        ];
        for (name, v, zero_ok) in fields {
            let ok = v.is_finite() && (v > 0.0 || (zero_ok && v == 0.0));
            if !ok {
                let need = if zero_ok { "zero or more" } else { "positive" };
                return Err(MaterialError {
                    name,
                    value: v,
                    need,
                });
            }
        }
        Ok(())
    }
}

impl Default for Material {
    /// [`Material::PLASTIC`]: work stays where the tools put it (elastic is one click away in
    /// the material panel).
    fn default() -> Self {
        Self::PLASTIC
    }
}

/// Which grid neighbours a density spring joins.
///
/// A spring joins a mass point to a neighbour at offset `o` (each component −1, 0 or 1) at
/// distance `L = √order · h`, where `order` (1, 2 or 3: face, edge or corner) counts the
/// non-zero components and `h` is the mass-point spacing. Its force acts on the density axis
/// only (Hua & Qin §4.1): `k w ((d_j − d_i) − (r_j − r_i))`, with the rest densities `r`
/// holding the spring's rest length along that axis.
///
/// The weight `w` ([`Neighbourhood::weight`]) scales each spring by its rest length and
/// normalises the stencil: a spring measures the density's slope along its own direction,
/// `Δd / L`, and the springs of a point together stand for the energy `½ ρ |∇d|²`, which is
/// the mean of the squared slopes over the stencil's directions (for any of the three cubic
/// stencils the squared slopes sum to `N/3 · |∇d|²` over its `N` directions). That gives
/// `w = (6/N) (h/L)² = 6 / (N · order)`: 1 for the six face springs (today's stencil), and
/// 1/3, 1/6 (faces, edges) for 18 and 3/13, 3/26, 1/13 for 26. So a smooth deformation
/// (long compared to `h`) meets the same restoring force `ρ h² ∇²d` whatever the
/// neighbourhood — one stiffness means the same material — while the larger stencils
/// resolve short, oblique deformations more evenly in every direction (the 18-neighbour
/// stencil is isotropic to fourth order).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Neighbourhood {
    /// Face neighbours.
    #[default]
    Six,
    /// Face and edge neighbours.
    Eighteen,
    /// Face, edge and corner neighbours.
    TwentySix,
}

impl Neighbourhood {
    /// The three neighbourhoods, smallest first.
    pub const ALL: [Self; 3] = [Self::Six, Self::Eighteen, Self::TwentySix];

    /// Number of springs at an interior mass point: 6, 18 or 26.
    #[must_use]
    pub const fn count(self) -> u32 {
        match self {
            Self::Six => 6,
            Self::Eighteen => 18,
            Self::TwentySix => 26,
        }
    }

    /// The neighbourhood with `count` springs, if it is 6, 18 or 26.
    #[must_use]
    pub const fn from_count(count: u32) -> Option<Self> {
        match count {
            6 => Some(Self::Six),
            18 => Some(Self::Eighteen),
            26 => Some(Self::TwentySix),
            _ => None,
        }
    }

    /// Highest order of neighbour joined: 1 (faces), 2 (edges) or 3 (corners).
    #[must_use]
    pub const fn max_order(self) -> u32 {
        match self {
            Self::Six => 1,
            Self::Eighteen => 2,
            Self::TwentySix => 3,
        }
    }

    /// Weight of a spring to a neighbour of `order` (1 face, 2 edge, 3 corner): `6 / (N ·
    /// order)` (see the type's docs); exactly 1 for the six-neighbour face springs.
    #[must_use]
    pub fn weight(self, order: u32) -> f32 {
        6.0 / (self.count() as f32 * order as f32)
    }
}

/// How `(AᵀMA)⁻¹` is applied.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum AccelSolver {
    /// Kronecker inverse when the mass is uniform, preconditioned CG otherwise.
    #[default]
    Auto,
    /// Always conjugate gradients preconditioned by the Kronecker inverse.
    ConjugateGradient,
}

/// Which forward Euler variant advances the coefficients.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Integrator {
    /// Velocity first, then position with the new velocity (symplectic Euler). Stable for
    /// undamped springs at `Δt < 2/ω`; the default.
    #[default]
    SemiImplicit,
    /// Eq. (8) exactly as printed: position with the old velocity. Gains energy on undamped
    /// springs; needs `Δt < γ/ω²`.
    Explicit,
}

/// Parameters of a step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepParams {
    /// Largest (and initial) time step, seconds.
    pub dt_max_s: f32,
    /// Smallest time step, seconds: halving stops here.
    pub dt_min_s: f32,
    /// The step halves while `max|p̈| · Δt` exceeds this (largest change of a coefficient
    /// velocity in one step; on a two-level detail region, see
    /// [`crate::dynamics::RegionState::set_coarse_springs`], this times its spacing ratio).
    pub max_velocity_change: f32,
    /// Consecutive calm steps (under a quarter of the threshold) before the step grows.
    pub calm_steps_to_grow: u32,
    /// Growth factor of the step after a calm run.
    pub growth: f32,
    /// A step that would make any coefficient larger than this in magnitude is refused.
    pub max_abs_coeff: f32,
    /// Acceleration solver.
    pub solver: AccelSolver,
    /// Euler variant.
    pub integrator: Integrator,
    /// Conjugate-gradient relative residual target.
    pub cg_tolerance: f32,
    /// Conjugate-gradient iteration cap.
    pub cg_max_iterations: u32,
    /// Densities are recomputed from the coefficients (instead of updated incrementally)
    /// every this many steps, to bound f32 drift.
    pub resync_every: u32,
    /// Largest travel of the coast surface (where the clay would come to rest, see
    /// `dynamics::coast`) that one step's tool forces may cause, knot spans of the simulated
    /// patch (of the base on a two-level detail region, see
    /// [`crate::dynamics::RegionState::set_coarse_springs`]): each force
    /// vector's share on its most loaded mass point is capped so. It bounds how far a huge
    /// gain can carry the surface past a target in one step (the closed loop brings it back
    /// from there) and keeps the step from halving to nothing under such a gain; at the
    /// default 1/25 span per 1 ms step the surface may still travel 40 knot spans a second.
    /// `f32::INFINITY` turns the cap off.
    pub max_coast_step_spans: f32,
    /// Threads a step's passes may be split over: 1, or 2 (one persistent helper thread;
    /// larger values count as 2). With 2, a region runs on two threads only where that is
    /// faster: never below 40 000 mass points, and above that as timing a few steps of each
    /// says (re-checked every few thousand steps, so a busy machine falls back to one). The
    /// result is bit-identical either way.
    pub threads: usize,
}

impl Default for StepParams {
    fn default() -> Self {
        Self {
            dt_max_s: 1e-3,
            dt_min_s: 1e-6,
            max_velocity_change: 50.0,
            calm_steps_to_grow: 20,
            growth: 1.25,
            max_abs_coeff: 1e6,
            solver: AccelSolver::Auto,
            integrator: Integrator::SemiImplicit,
            cg_tolerance: 1e-5,
            cg_max_iterations: 60,
            resync_every: 256,
            max_coast_step_spans: 0.04,
            threads: 1,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn validate_accepts_the_presets_and_names_a_bad_constant() {
        assert_eq!(Material::ELASTIC.validate(), Ok(()));
        assert_eq!(Material::PLASTIC.validate(), Ok(()));
        let no_mass = Material {
            mass: 0.0,
            ..Material::ELASTIC
        };
        assert!(
            no_mass
                .validate()
                .unwrap_err()
                .to_string()
                .contains("mass = 0")
        );
        let nan_damping = Material {
            damping: f32::NAN,
            ..Material::ELASTIC
        };
        assert!(
            nan_damping
                .validate()
                .unwrap_err()
                .to_string()
                .contains("damping")
        );
        let negative = Material {
            yield_density: -0.1,
            ..Material::PLASTIC
        };
        assert!(
            negative
                .validate()
                .unwrap_err()
                .to_string()
                .contains("yield_density")
        );
    }
}
