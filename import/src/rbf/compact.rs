//! The clay held as a compact RBF in the live engine (Zhang et al. §5.4): after each contact
//! stroke the engine's lattice already holds `h = I + β·g`; the particles (a fixed `N`,
//! warm-started from where the previous stroke left them) resample `h`, `I` is interpolated
//! again from them with the same `3N` centres, and `I` is fitted back onto the lattice. The
//! function's size never grows, however many strokes are made.
//!
//! This is the computation only, for a worker thread: it allocates and takes from a tenth of
//! a second to seconds. The engine's side (the worker, the undo step) is in
//! `engine::compact_rbf`.

use glam::Vec3;

use super::file::{RbfFile, RbfFileError};
use super::fit::{RbfFitReport, RbfOptions, fit_surface};
use super::sculpt::RbfSculptError;
use crate::particles::{ParticleParams, ParticleSystem};
use dynaclay_core::field::BSplineLattice;

/// How the clay is held as an RBF.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CompactSettings {
    /// The particle count `N` (the RBF has `3N` centres).
    pub particles: usize,
    /// Particle steps from the seeded random start of the first interpolation.
    pub settle_steps: usize,
    /// Particle steps after each stroke before the count is checked (warm start).
    pub steps_per_stroke: usize,
    /// Further steps allowed for the count to return to `N`.
    pub max_extra_steps: usize,
    /// Samples per knot span of the least-squares fit of `I` onto the lattice.
    pub samples_per_span: usize,
}

// The script's bound on particles keeps `3N` centres within one dense solve.
const _: () = assert!(3 * CompactSettings::MAX_PARTICLES <= RbfOptions::DEFAULT_MAX_CENTRES);

impl CompactSettings {
    /// The default `N`: the fewest particles with which four contact strokes on a sphere stay
    /// within 1% of the same strokes on the plain clay (`tests/compact_rbf_live.rs`; 400 end
    /// at 1.09%).
    pub const DEFAULT_PARTICLES: usize = 600;
    /// The most particles: `3N` centres must fit one dense solve
    /// ([`RbfOptions::DEFAULT_MAX_CENTRES`]), or the centre count would not stay fixed.
    pub const MAX_PARTICLES: usize = dynaclay_core::io::MAX_COMPACT_PARTICLES;
    /// The fewest particles.
    pub const MIN_PARTICLES: usize = dynaclay_core::io::MIN_COMPACT_PARTICLES;

    /// Defaults for `particles` particles.
    #[must_use]
    pub fn new(particles: usize) -> Self {
        Self {
            particles,
            settle_steps: 200,
            steps_per_stroke: 40,
            max_extra_steps: 200,
            samples_per_span: 2,
        }
    }

    /// Checks the particle count.
    ///
    /// # Errors
    /// [`CompactError::Particles`] when it is outside
    /// [`Self::MIN_PARTICLES`]`..=`[`Self::MAX_PARTICLES`].
    pub fn validate(&self) -> Result<(), CompactError> {
        if (Self::MIN_PARTICLES..=Self::MAX_PARTICLES).contains(&self.particles) {
            Ok(())
        } else {
            Err(CompactError::Particles {
                particles: self.particles,
            })
        }
    }
}

impl Default for CompactSettings {
    fn default() -> Self {
        Self::new(Self::DEFAULT_PARTICLES)
    }
}

/// Why a re-interpolation failed (the clay is left as it was).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum CompactError {
    /// The particle count is out of range.
    #[error(
        "{particles} particles: the compact RBF clay takes {} to {} (3N centres in one solve)",
        CompactSettings::MIN_PARTICLES,
        CompactSettings::MAX_PARTICLES
    )]
    Particles {
        /// The count asked for.
        particles: usize,
    },
    /// Sampling or interpolating failed.
    #[error(transparent)]
    Sculpt(#[from] RbfSculptError),
    /// The centre count changed (it is fixed at the first interpolation's).
    #[error("the interpolation has {found} centres, not the {fixed} of the first")]
    Centres {
        /// The first interpolation's count.
        fixed: usize,
        /// This one's.
        found: usize,
    },
    /// Fitting `I` onto the lattice failed.
    #[error("fitting the RBF onto the lattice: {0}")]
    Lattice(String),
}

impl From<RbfFileError> for CompactError {
    fn from(e: RbfFileError) -> Self {
        Self::Lattice(e.to_string())
    }
}

/// One re-interpolation's outcome.
#[derive(Clone, Debug)]
pub struct Reinterpolation {
    /// The RBF `I` with the lattice's geometry.
    pub file: RbfFile,
    /// `I` fitted onto the lattice (the same geometry as the lattice sampled).
    pub lattice: BSplineLattice,
    /// What the interpolation did.
    pub report: RbfFitReport,
    /// Particle steps taken.
    pub particle_steps: usize,
}

/// The particles and the fixed centre count, kept from one stroke to the next.
#[derive(Clone, Debug)]
pub struct CompactClay {
    settings: CompactSettings,
    particles: Option<ParticleSystem>,
    centres: Option<usize>,
}

impl CompactClay {
    /// A compact clay with no particles yet (the first [`Self::reinterpolate`] seeds them).
    ///
    /// # Errors
    /// [`CompactError::Particles`] for a count out of range.
    pub fn new(settings: CompactSettings) -> Result<Self, CompactError> {
        settings.validate()?;
        Ok(Self {
            settings,
            particles: None,
            centres: None,
        })
    }

    /// The settings.
    #[must_use]
    pub fn settings(&self) -> &CompactSettings {
        &self.settings
    }

    /// The centre count, fixed by the first interpolation.
    #[must_use]
    pub fn centres(&self) -> Option<usize> {
        self.centres
    }

    /// The particles, once seeded.
    #[must_use]
    pub fn particles(&self) -> Option<&ParticleSystem> {
        self.particles.as_ref()
    }

    /// Resamples `lattice` (the clay after a stroke, `h`) with the `N` particles — seeded and
    /// settled the first time, warm-started from their last places after — interpolates `I`
    /// with `3N` centres and fits it onto a lattice of `lattice`'s geometry. On failure the
    /// particles keep their last good places.
    ///
    /// # Errors
    /// [`CompactError`] naming what failed.
    pub fn reinterpolate(
        &mut self,
        lattice: &BSplineLattice,
    ) -> Result<Reinterpolation, CompactError> {
        let s = self.settings;
        let n = s.particles;
        let mut particles = match &self.particles {
            Some(p) => p.clone(),
            None => {
                let mut p =
                    ParticleSystem::new(ParticleParams::new(n)).map_err(RbfSculptError::from)?;
                p.seed_random(lattice, n, 1).map_err(RbfSculptError::from)?;
                p.settle(lattice, s.settle_steps);
                p
            }
        };
        let warm = self.particles.is_some();
        let mut steps = 0;
        if warm {
            let budget = s.steps_per_stroke + s.max_extra_steps;
            while steps < budget && (steps < s.steps_per_stroke || particles.len() != n) {
                particles
                    .step(lattice, ParticleSystem::DEFAULT_DT)
                    .map_err(RbfSculptError::from)?;
                steps += 1;
            }
            particles.project(lattice, 3);
        } else {
            steps = s.settle_steps;
        }
        if particles.len() != n && particles.len() >= n / 2 {
            // NOTE: the population control settles near N but may hover a few particles off
            // it after a large change; the centre count must stay 3N, so the count is made N
            // here and the particles projected again (the next stroke's steps even them out).
            set_count(&mut particles, n);
            particles.project(lattice, 3);
        }
        if particles.len() != n {
            return Err(RbfSculptError::Count {
                count: particles.len(),
                target: n,
                steps,
            }
            .into());
        }
        let options = RbfOptions::with_offset(0.5 * f64::from(lattice.spacing));
        let (rbf, report) =
            fit_surface(lattice, particles.positions(), &options).map_err(RbfSculptError::from)?;
        if let Some(fixed) = self.centres
            && fixed != report.centres
        {
            return Err(CompactError::Centres {
                fixed,
                found: report.centres,
            });
        }
        let file = RbfFile {
            rbf,
            dims: lattice.dims,
            spacing: lattice.spacing,
            origin: lattice.origin,
            iso: lattice.iso,
        };
        let fitted = file.to_clay(s.samples_per_span)?;
        self.particles = Some(particles);
        self.centres = Some(report.centres);
        Ok(Reinterpolation {
            file,
            lattice: fitted,
            report,
            particle_steps: steps,
        })
    }
}

/// Makes `particles` hold exactly `n` (placed on no surface yet): the most crowded particle
/// (closest to its nearest neighbour) is removed while there are too many, and a particle is
/// added halfway between the loneliest one and its nearest neighbour while there are too few.
/// Radii become the mean radius. Quadratic in the count; called only for a few particles.
fn set_count(particles: &mut ParticleSystem, n: usize) {
    let mut points = particles.positions().to_vec();
    let sigmas = particles.sigmas();
    let sigma = sigmas.iter().sum::<f32>() / sigmas.len().max(1) as f32;
    let nearest = |points: &[Vec3], i: usize| -> (usize, f32) {
        let mut best = (i, f32::INFINITY);
        for (j, q) in points.iter().enumerate() {
            let d = points[i].distance_squared(*q);
            if j != i && d < best.1 {
                best = (j, d);
            }
        }
        best
    };
    while points.len() > n {
        let crowded = (0..points.len())
            .min_by(|&a, &b| nearest(&points, a).1.total_cmp(&nearest(&points, b).1))
            .unwrap_or(0);
        points.swap_remove(crowded);
    }
    while points.len() < n && points.len() >= 2 {
        let lonely = (0..points.len())
            .max_by(|&a, &b| nearest(&points, a).1.total_cmp(&nearest(&points, b).1))
            .unwrap_or(0);
        let (j, _) = nearest(&points, lonely);
        points.push(0.5 * (points[lonely] + points[j]));
    }
    particles.from_positions(&points, sigma);
}

#[cfg(test)]
mod tests {
    use super::*;
    use dynaclay_core::field::{Primitive, lattice_from_primitive};

    #[test]
    fn counts_out_of_range_are_refused() {
        for n in [0, 7, CompactSettings::MAX_PARTICLES + 1] {
            let e = CompactClay::new(CompactSettings::new(n)).unwrap_err();
            assert!(e.to_string().contains(&format!("{n} particles")), "{e}");
        }
    }

    #[test]
    fn the_centre_count_stays_and_the_lattice_is_the_fit_of_the_rbf() {
        let sphere = Primitive::Sphere {
            centre: Vec3::splat(0.8),
            radius: 0.45,
        };
        let lattice = lattice_from_primitive([16; 3], 0.1, Vec3::ZERO, &sphere, 0.2, 2).unwrap();
        let mut clay = CompactClay::new(CompactSettings::new(80)).unwrap();
        let first = clay.reinterpolate(&lattice).unwrap();
        assert_eq!(first.report.centres, 240);
        assert_eq!(clay.centres(), Some(240));
        let again = clay.reinterpolate(&first.lattice).unwrap();
        assert_eq!(again.report.centres, 240);
        assert_eq!(again.lattice.dims, lattice.dims);
        let refit = again.file.to_clay(2).unwrap();
        assert_eq!(refit.coeffs, again.lattice.coeffs);
    }
}
