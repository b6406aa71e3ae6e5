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

use super::file::RbfFile;
use super::fit::{Rbf, RbfError, RbfFitReport, RbfOptions, fit_surface};
use crate::particles::{ImplicitSurface, ParticleError, ParticleParams, ParticleSystem};
use dynaclay_core::field::{BSplineLattice, Primitive};
use dynaclay_core::io::{Script, ToolPreset};
use dynaclay_core::tools::{ContactParams, GeometricTool, ToolAction, ToolPose};

/// Why the RBF sculpt could not start or take an action.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum RbfSculptError {
    /// The particles could not be placed.
    #[error("particles: {0}")]
    Particles(#[from] ParticleError),
    /// Interpolation failed.
    #[error("interpolation: {0}")]
    Fit(#[from] RbfError),
    /// The clay held as an RBF takes only contact actions (Zhang's `h = I + β·g`).
    #[error("step {step}: the RBF clay takes contact tools only, not {what}")]
    NotContact {
        /// The 1-based script step (0 for a tool applied directly).
        step: usize,
        /// What was asked for.
        what: String,
    },
    /// The tool's parameters were refused.
    #[error("step {step}: {message}")]
    BadTool {
        /// The 1-based script step (0 for a tool applied directly).
        step: usize,
        /// Why.
        message: String,
    },
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

/// A tool's potential (density in `[0, 1]`) at world points.
type Potential<'a> = &'a dyn Fn(Vec3) -> f32;

/// One contact action: the rule, the tool's potential and the dwell.
type Action<'a> = (&'a ContactParams, Potential<'a>, f32);

/// The function the particles sample: `I`, or `h = I + β·g` during an action.
struct Edited<'a> {
    rbf: &'a Rbf,
    action: Option<Action<'a>>,
    width: f32,
    iso: f32,
    bounds: (Vec3, Vec3),
    resolution: f32,
}

impl Edited<'_> {
    /// `h(x)` and whether the action touches `x`.
    fn value(&self, x: Vec3) -> (f32, bool) {
        let i = self.rbf.value(x.as_dvec3()) as f32;
        let Some((params, potential, dwell_s)) = self.action else {
            return (i, false);
        };
        let density = (self.iso + i / self.width).clamp(0.0, 1.0);
        let t = potential(x);
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
    /// The latest fit's report.
    report: RbfFitReport,
    particles: ParticleSystem,
    options: RbfOptions,
    width: f32,
    iso: f32,
    bounds: (Vec3, Vec3),
    resolution: f32,
    /// The clay's lattice geometry, for the file and the way back to a clay.
    dims: [usize; 3],
    origin: Vec3,
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
        let (rbf, report) = fit_surface(field, particles.positions(), &options)?;
        let sculpt = Self {
            rbf,
            report,
            particles,
            options,
            width: 2.0 * field.spacing,
            iso: field.iso,
            bounds: field.support(),
            resolution: field.spacing,
            dims: field.dims,
            origin: field.origin,
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

    /// The function with the clay's lattice geometry: what `.rbf` files hold, and what
    /// [`RbfFile::to_clay`] turns back into a clay.
    #[must_use]
    pub fn to_file(&self) -> RbfFile {
        RbfFile {
            rbf: self.rbf.clone(),
            dims: self.dims,
            spacing: self.resolution,
            origin: self.origin,
            iso: self.iso,
        }
    }

    /// What the latest interpolation did.
    #[must_use]
    pub fn report(&self) -> &RbfFitReport {
        &self.report
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
        let width = self.width;
        self.contact_with(params, &|x| tool.density(x, width), dwell_s)
    }

    /// [`RbfSculpt::contact`] with the tool given by its potential (density in `[0, 1]`, one
    /// half on the tool's surface) at world points.
    ///
    /// # Errors
    /// As [`RbfSculpt::contact`].
    pub fn contact_with(
        &mut self,
        params: &ContactParams,
        potential: &dyn Fn(Vec3) -> f32,
        dwell_s: f32,
    ) -> Result<RbfFitReport, RbfSculptError> {
        let h = Edited {
            rbf: &self.rbf,
            action: Some((params, potential, dwell_s)),
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
        self.report = report;
        Ok(report)
    }
}

impl RbfSculpt {
    /// A geometric tool step, as the B-spline clay takes it ([`dynaclay_core::tools::apply_stroke`]):
    /// one contact action per pose, the duration split evenly. Only
    /// [`ToolAction::Contact`] applies to the RBF clay. Returns the last fit's report.
    ///
    /// # Errors
    /// [`RbfSculptError::NotContact`] for any other action, [`RbfSculptError::BadTool`] for
    /// invalid parameters, and the errors of [`RbfSculpt::contact`].
    pub fn apply_tool(
        &mut self,
        tool: &GeometricTool,
        poses: &[ToolPose],
        duration_s: f32,
    ) -> Result<Option<RbfFitReport>, RbfSculptError> {
        self.apply_step(0, tool, poses, duration_s)
    }

    fn apply_step(
        &mut self,
        step: usize,
        tool: &GeometricTool,
        poses: &[ToolPose],
        duration_s: f32,
    ) -> Result<Option<RbfFitReport>, RbfSculptError> {
        let ToolAction::Contact(params) = tool.action else {
            return Err(RbfSculptError::NotContact {
                step,
                what: format!("the {} action", tool.action.name()),
            });
        };
        tool.validate().map_err(|e| RbfSculptError::BadTool {
            step,
            message: e.to_string(),
        })?;
        let dt_s = duration_s / poses.len().max(1) as f32;
        let mut last = None;
        for pose in poses {
            let potential = |x: Vec3| tool.shape.density(pose.to_local(x), tool.falloff_fu);
            last = Some(self.contact_with(&params, &potential, dt_s)?);
        }
        Ok(last)
    }

    /// The session mode of Zhang et al. §5.4: a script's edits applied to the clay held as
    /// this RBF. `tool` and `preset` steps with the contact action are taken in order (presets
    /// from `library`); any other step is refused, naming it. Returns how many contact actions
    /// were applied (one per pose).
    ///
    /// # Errors
    /// [`RbfSculptError`] naming the step that could not be applied; the steps before it stay
    /// applied.
    pub fn run_script(
        &mut self,
        script: &Script,
        library: &[ToolPreset],
    ) -> Result<usize, RbfSculptError> {
        let mut actions = 0;
        for (n, step) in script.steps.iter().enumerate() {
            let at = n + 1;
            let bad = |message: String| RbfSculptError::BadTool { step: at, message };
            let Some(tool_step) = step.tool_step() else {
                return Err(RbfSculptError::NotContact {
                    step: at,
                    what: format!("do = {:?}", step.name()),
                });
            };
            let tool = tool_step
                .geometric_tool(|name| library.iter().find(|t| t.name == name))
                .map_err(|e| bad(e.to_string()))?;
            let (poses, duration_s) = (tool_step.poses, tool_step.duration_s);
            self.apply_step(at, &tool, &poses, duration_s)?;
            actions += poses.len();
        }
        Ok(actions)
    }
}
