//! Sculpting with the clay as an RBF (Zhang et al. §5.4): each contact action gives
//! `h = I + β·g`, the particles resample `h`, and `I` is interpolated again from them, so the
//! function's size stays `3N` centres however many edits are made.
//!
//! The contact rule is the tool module's [`ContactParams::apply`], the same one the B-spline
//! clay uses, applied to the density that `I` stands for: `I` is a signed distance (positive
//! inside), the clay's density near its surface is `iso + I / width` for a transition of
//! `width` (two knot spans, as primitives are built), so a change `Δ` of density is a change
//! `width · Δ` of `I`. Where the action changes nothing `h` is `I` exactly.

use glam::Vec3;

use super::fit::{Rbf, RbfError, RbfFitReport, RbfOptions, fit_surface};
use crate::field::{BSplineLattice, Primitive};
use crate::particles::{ImplicitSurface, ParticleError, ParticleParams, ParticleSystem};
use crate::tools::ContactParams;

/// Why the RBF sculpt could not start or take an action.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum RbfSculptError {
    /// The particles could not be placed.
    #[error("particles: {0}")]
    Particles(#[from] ParticleError),
    /// Interpolation failed.
    #[error("interpolation: {0}")]
    Fit(#[from] RbfError),
    /// The particles did not settle at `N` within the step budget.
    #[error("{count} particles after {steps} steps, not the {target} asked for")]
    Count {
        /// Particles at the end.
        count: usize,
        /// The user's `N`.
        target: usize,
        /// Steps taken.
        steps: usize,
    },
}

/// The function the particles sample: `I`, or `h = I + β·g` during an action.
struct Edited<'a> {
    rbf: &'a Rbf,
    action: Option<(&'a ContactParams, &'a Primitive, f32)>,
    width: f32,
    iso: f32,
    bounds: (Vec3, Vec3),
    resolution: f32,
}

impl Edited<'_> {
    /// `h(x)` and whether the action touches `x`.
    fn value(&self, x: Vec3) -> (f32, bool) {
        let i = self.rbf.value(x.as_dvec3()) as f32;
        let Some((params, tool, dwell_s)) = self.action else {
            return (i, false);
        };
        let density = (self.iso + i / self.width).clamp(0.0, 1.0);
        let t = tool.density(x, self.width);
        let changed = params.apply(density, t, self.iso, dwell_s);
        let delta = changed - density;
        (i + self.width * delta, t > 0.0 && density > 0.0)
    }
}

impl ImplicitSurface for Edited<'_> {
    fn eval(&self, x: Vec3) -> (f32, Vec3) {
        let (h, touched) = self.value(x);
        if !touched {
            return (h, self.rbf.gradient(x.as_dvec3()).as_vec3());
        }
        // Central differences where the action applies (its rule is only piecewise smooth).
        let e = 1e-3 * self.resolution;
        let d = |axis: Vec3| (self.value(x + axis * e).0 - self.value(x - axis * e).0) / (2.0 * e);
        (h, Vec3::new(d(Vec3::X), d(Vec3::Y), d(Vec3::Z)))
    }

    fn bounds(&self) -> (Vec3, Vec3) {
        self.bounds
    }

    fn resolution(&self) -> f32 {
        self.resolution
    }
}

/// The clay held as an RBF of `3N` centres.
#[derive(Clone, Debug)]
pub struct RbfSculpt {
    rbf: Rbf,
    particles: ParticleSystem,
    options: RbfOptions,
    width: f32,
    iso: f32,
    bounds: (Vec3, Vec3),
    resolution: f32,
    /// Particle steps after each action before the count is checked.
    pub steps_per_action: usize,
    /// Further steps allowed for the count to return to `N`.
    pub max_extra_steps: usize,
}

impl RbfSculpt {
    /// Sample `field` with `n` particles (`settle_steps` steps from a seeded random start) and
    /// interpolate them: `I⁰`.
    ///
    /// # Errors
    /// [`RbfSculptError`] when the particles or the interpolation fail.
    pub fn from_clay(
        field: &BSplineLattice,
        n: usize,
        settle_steps: usize,
        options: RbfOptions,
    ) -> Result<Self, RbfSculptError> {
        let mut particles = ParticleSystem::new(ParticleParams::new(n))?;
        particles.seed_random(field, n, 1)?;
        particles.settle(field, settle_steps);
        let (rbf, _) = fit_surface(field, particles.positions(), &options)?;
        let sculpt = Self {
            rbf,
            particles,
            options,
            width: 2.0 * field.spacing,
            iso: field.iso,
            bounds: field.support(),
            resolution: field.spacing,
            steps_per_action: 40,
            max_extra_steps: 200,
        };
        sculpt.check_count(settle_steps)?;
        Ok(sculpt)
    }

    /// The current function `I`.
    #[must_use]
    pub fn rbf(&self) -> &Rbf {
        &self.rbf
    }

    /// The particles sampling it.
    #[must_use]
    pub fn particles(&self) -> &ParticleSystem {
        &self.particles
    }

    fn check_count(&self, steps: usize) -> Result<(), RbfSculptError> {
        let target = self.particles.params().target_count;
        if self.particles.len() == target {
            Ok(())
        } else {
            Err(RbfSculptError::Count {
                count: self.particles.len(),
                target,
                steps,
            })
        }
    }

    /// One contact action (Zhang §3 with §5.4): `h = I + β·g` for the tool `tool` (its
    /// density profile is the tool's potential) held for `dwell_s`; the particles resample
    /// `h` until their count is `N` again, and `I` is interpolated from them.
    ///
    /// # Errors
    /// [`RbfSculptError::Count`] when the count does not return to `N` within the budget
    /// (the function is left as it was), or an interpolation error.
    pub fn contact(
        &mut self,
        params: &ContactParams,
        tool: &Primitive,
        dwell_s: f32,
    ) -> Result<RbfFitReport, RbfSculptError> {
        let h = Edited {
            rbf: &self.rbf,
            action: Some((params, tool, dwell_s)),
            width: self.width,
            iso: self.iso,
            bounds: self.bounds,
            resolution: self.resolution,
        };
        let target = self.particles.params().target_count;
        let mut steps = 0;
        let budget = self.steps_per_action + self.max_extra_steps;
        while steps < budget && (steps < self.steps_per_action || self.particles.len() != target) {
            self.particles
                .step(&h, ParticleSystem::DEFAULT_DT)
                .map_err(RbfSculptError::Particles)?;
            steps += 1;
        }
        self.particles.project(&h, 3);
        self.check_count(steps)?;
        let (rbf, report) = fit_surface(&h, self.particles.positions(), &self.options)?;
        self.rbf = rbf;
        Ok(report)
    }
}
