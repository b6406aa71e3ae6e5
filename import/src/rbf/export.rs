//! A session's clay to an RBF file, the way `dynaclay rbf` and the script's `particles` and
//! `rbf` steps do it: flatten the clay to one lattice, settle `N` particles on its surface
//! from a seeded random start, and interpolate them.

use std::fmt::Write as _;
use std::path::Path;

use dynaclay_files::{WriteError, write_atomic};
use glam::Vec3;

use super::file::RbfFile;
use super::fit::{RbfError, RbfFitReport, RbfOptions, fit_surface};
use crate::particles::{ImplicitSurface, ParticleError, ParticleParams, ParticleSystem};
use dynaclay_core::field::{BSplineLattice, FitError, fit_lattice};
use dynaclay_core::tools::Clay;

/// How a clay is sampled and interpolated.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExportOptions {
    /// The particle count `N`.
    pub particles: usize,
    /// Particle steps from the random start.
    pub steps: usize,
    /// Seed of the random start.
    pub seed: u64,
    /// Normal offset of the inner and outer points, field units (default: half a knot span).
    pub offset: Option<f64>,
    /// Most centres in one dense solve; above, centres are chosen greedily.
    pub max_centres: usize,
}

impl Default for ExportOptions {
    fn default() -> Self {
        Self {
            particles: 400,
            steps: 200,
            seed: 1,
            offset: None,
            max_centres: RbfOptions::DEFAULT_MAX_CENTRES,
        }
    }
}

/// Why a clay could not be sampled or interpolated.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ExportError {
    /// The clay has no patch.
    #[error("the session's clay has no patches")]
    NoPatches,
    /// The particles could not be placed (no surface, or a zero count).
    #[error("particles: {0}")]
    Particles(#[from] ParticleError),
    /// Flattening a multi-patch clay failed.
    #[error("flattening the clay: {0}")]
    Flatten(#[from] FitError),
    /// The interpolation failed.
    #[error("RBF fit: {0}")]
    Fit(#[from] RbfError),
}

/// The clay as one lattice: the first patch, or (several patches) a lattice of the first
/// patch's geometry least-squares fitted to their clamped sum.
///
/// # Errors
/// [`ExportError::NoPatches`], [`ExportError::Flatten`].
pub fn flatten_clay(clay: &Clay) -> Result<BSplineLattice, ExportError> {
    let first = &clay
        .density
        .patches
        .first()
        .ok_or(ExportError::NoPatches)?
        .lattice;
    if clay.density.patches.len() == 1 && clay.density.patches[0].is_identity() {
        return Ok(first.clone());
    }
    let mut lattice = first.clone();
    fit_lattice(&mut lattice, 2, |x| clay.density.value(x).clamp(0.0, 1.0))?;
    Ok(lattice)
}

/// `options.particles` particles settled on `lattice`'s surface.
///
/// # Errors
/// [`ParticleError`] when the count is zero or the clay has no surface.
pub fn settle_particles(
    lattice: &BSplineLattice,
    options: &ExportOptions,
) -> Result<ParticleSystem, ParticleError> {
    let mut particles = ParticleSystem::new(ParticleParams::new(options.particles))?;
    particles.seed_random(lattice, options.particles, options.seed)?;
    particles.settle(lattice, options.steps);
    Ok(particles)
}

/// A clay sampled and interpolated.
#[derive(Clone, Debug)]
pub struct ClayRbf {
    /// The lattice the clay was flattened to.
    pub lattice: BSplineLattice,
    /// The settled particles.
    pub particles: ParticleSystem,
    /// The RBF with the lattice's geometry, ready to write.
    pub file: RbfFile,
    /// What the fit did.
    pub report: RbfFitReport,
}

/// Samples `clay` with particles and interpolates them (Zhang et al. §5.3).
///
/// # Errors
/// [`ExportError`] naming what failed.
pub fn clay_to_rbf(clay: &Clay, options: &ExportOptions) -> Result<ClayRbf, ExportError> {
    let lattice = flatten_clay(clay)?;
    let particles = settle_particles(&lattice, options)?;
    let offset = options.offset.unwrap_or(0.5 * f64::from(lattice.spacing));
    let fit = RbfOptions {
        max_centres: options.max_centres,
        ..RbfOptions::with_offset(offset)
    };
    let (rbf, report) = fit_surface(&lattice, particles.positions(), &fit)?;
    let file = RbfFile {
        rbf,
        dims: lattice.dims,
        spacing: lattice.spacing,
        origin: lattice.origin,
        iso: lattice.iso,
    };
    Ok(ClayRbf {
        lattice,
        particles,
        file,
        report,
    })
}

/// Writes particles as an ASCII point cloud, one `x y z nx ny nz` line per particle (the
/// outward unit normal from `field`'s gradient), replacing `path` atomically.
///
/// # Errors
/// [`WriteError`] when the file cannot be written.
pub fn write_particles(
    path: &Path,
    field: &(impl ImplicitSurface + ?Sized),
    positions: &[Vec3],
) -> Result<(), WriteError> {
    let mut text = String::with_capacity(64 * positions.len());
    for &p in positions {
        let n = -field.eval(p).1.normalize_or_zero();
        let _ = writeln!(text, "{} {} {} {} {} {}", p.x, p.y, p.z, n.x, n.y, n.z);
    }
    write_atomic(path, text.as_bytes())
}
