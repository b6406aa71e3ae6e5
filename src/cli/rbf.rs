//! `dynaclay rbf`: sample a session's clay with constrained particles and write the compact
//! RBF that interpolates them (Zhang et al. §5.3); optionally import it back as a clay.

use super::args::RbfArgs;
use crate::field::FitError;
use crate::io::{OutputKind, OutputRefused, OutputRule, load_script};
use crate::io::{Session, SessionError, load_session, save_session};
use crate::particles::ParticleError;
use crate::rbf::{
    ClayRbf, ExportError, ExportOptions, RbfError, RbfFileError, RbfOptions, RbfSculpt,
    RbfSculptError, clay_to_rbf, flatten_clay, write_rbf,
};
use crate::tools::Clay;

/// Why `dynaclay rbf` failed.
#[derive(Debug, thiserror::Error)]
pub enum RbfCommandError {
    /// A bad argument (exit 2).
    #[error("{0}")]
    Usage(String),
    /// The session could not be read (exit 2).
    #[error("cannot read session: {0}")]
    Session(#[source] SessionError),
    /// The particles could not be placed: the clay has no surface (exit 2).
    #[error("particles: {0}")]
    Particles(#[from] ParticleError),
    /// Flattening a multi-patch clay failed (exit 1).
    #[error("flattening the clay: {0}")]
    Flatten(#[from] FitError),
    /// The interpolation failed (exit 1).
    #[error("RBF fit: {0}")]
    Fit(#[from] RbfError),
    /// Writing the RBF file or importing it back failed (exit 1).
    #[error("{0}")]
    File(#[from] RbfFileError),
    /// Sculpting the clay as the RBF failed (exit 1; a refused step exits 2).
    #[error("RBF sculpt: {0}")]
    Sculpt(#[from] RbfSculptError),
    /// Writing the imported clay as a session failed (exit 1).
    #[error("writing the imported clay: {0}")]
    Save(#[source] SessionError),
    /// A step of the `--sculpt` script failed (exit 2 for a step the RBF cannot take, 1
    /// otherwise).
    #[error("{}: {source}", script.display())]
    SculptScript {
        /// The script.
        script: std::path::PathBuf,
        /// What failed.
        source: RbfSculptError,
    },
    /// An output breaks the output rule; refused before any work (exit 2).
    #[error("{0}")]
    OutputRefused(#[from] OutputRefused),
}

impl From<ExportError> for RbfCommandError {
    fn from(e: ExportError) -> Self {
        match e {
            ExportError::NoPatches => Self::Usage(e.to_string()),
            ExportError::Particles(e) => Self::Particles(e),
            ExportError::Flatten(e) => Self::Flatten(e),
            ExportError::Fit(e) => Self::Fit(e),
        }
    }
}

impl RbfCommandError {
    /// The process exit code: 2 for bad input, 1 for a failure.
    #[must_use]
    pub fn exit_code(&self) -> i32 {
        match self {
            Self::Usage(_)
            | Self::Session(_)
            | Self::OutputRefused(_)
            | Self::Particles(_)
            | Self::Sculpt(RbfSculptError::NotContact { .. } | RbfSculptError::BadTool { .. })
            | Self::SculptScript {
                source: RbfSculptError::NotContact { .. } | RbfSculptError::BadTool { .. },
                ..
            } => 2,
            Self::Flatten(_)
            | Self::Fit(_)
            | Self::File(_)
            | Self::Save(_)
            | Self::Sculpt(_)
            | Self::SculptScript { .. } => 1,
        }
    }
}

/// The largest `--offset`, in knot spans of the clay's base patch.
const MAX_OFFSET_SPANS: f32 = 4.0;

/// What `dynaclay rbf` produced.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RbfOutcome {
    /// Particles on the surface after settling.
    pub particles: usize,
    /// Centres in the RBF.
    pub centres: usize,
    /// Largest interpolation residual, world units.
    pub max_residual: f64,
}

/// Runs `dynaclay rbf`.
///
/// # Errors
/// [`RbfCommandError`] naming what failed.
pub fn rbf(args: &RbfArgs) -> Result<RbfOutcome, RbfCommandError> {
    let mut rule = OutputRule::new().input("SESSION", &args.session);
    if let Some(script) = &args.sculpt {
        rule = rule.input("--sculpt", script);
    }
    rule.check("--out", &args.out, OutputKind::Rbf)?;
    if let Some(clay) = &args.clay {
        rule.check("--clay", clay, OutputKind::Session)?;
    }
    let session = load_session(&args.session).map_err(RbfCommandError::Session)?;
    let Some(base) = session.clay.density.patches.first() else {
        return Err(RbfCommandError::Usage(format!(
            "{}: the session holds no density patch",
            args.session.display()
        )));
    };
    // The constraint points sit this far inside and outside the surface: past a few knot
    // spans they leave the clay's features (and, far past, its box) behind.
    let max_offset = MAX_OFFSET_SPANS * base.lattice.spacing;
    if let Some(offset) = args.offset
        && offset > max_offset
    {
        return Err(RbfCommandError::Usage(format!(
            "--offset {offset}: at most {MAX_OFFSET_SPANS} knot spans of the clay ({max_offset})"
        )));
    }
    let options = ExportOptions {
        particles: args.particles as usize,
        steps: args.steps as usize,
        seed: args.seed,
        offset: args.offset.map(f64::from),
        max_centres: args.max_centres as usize,
    };
    let (particles, file, report) = match &args.sculpt {
        None => {
            let ClayRbf {
                particles,
                file,
                report,
                ..
            } = clay_to_rbf(&session.clay, &options)?;
            (particles.len(), file, report)
        }
        Some(path) => {
            let script = load_script(path).map_err(|e| RbfCommandError::Usage(e.to_string()))?;
            let lattice = flatten_clay(&session.clay)?;
            let offset = options.offset.unwrap_or(0.5 * f64::from(lattice.spacing));
            let fit = RbfOptions {
                max_centres: options.max_centres,
                ..RbfOptions::with_offset(offset)
            };
            let mut sculpt = RbfSculpt::from_clay(&lattice, options.particles, options.steps, fit)?;
            let actions = sculpt
                .run_script(&script, &session.tools)
                .map_err(|source| RbfCommandError::SculptScript {
                    script: path.clone(),
                    source,
                })?;
            say!(
                "rbf: {actions} contact actions applied to the clay as the RBF ({} centres)",
                sculpt.rbf().len()
            );
            (sculpt.particles().len(), sculpt.to_file(), *sculpt.report())
        }
    };
    write_rbf(&args.out, &file)?;
    say!(
        "rbf: {} particles, {} centres of {} constraints ({} greedy rounds), largest residual {:.2e}; wrote {}",
        particles,
        report.centres,
        report.constraints,
        report.greedy_rounds,
        report.max_residual,
        args.out.display()
    );
    if let Some(path) = &args.clay {
        let lattice = file.to_clay(2)?;
        let imported = Session {
            clay: Clay::single(lattice),
            ..session
        };
        save_session(path, &imported).map_err(RbfCommandError::Save)?;
        say!("rbf: imported back as a clay; wrote {}", path.display());
    }
    Ok(RbfOutcome {
        particles,
        centres: report.centres,
        max_residual: report.max_residual,
    })
}
