//! `dynaclay render`: a session file to a PNG image, rendered offscreen.

use super::args::RenderArgs;
use super::budget::MemoryBudget;
use super::error::CliError;
use super::sculpt::{describe_outcome, mesh_clay, render_sculpt};
use crate::io::{OutputKind, OutputRule, load_session};
use crate::render::RenderOutcome;

/// Loads the session, meshes its clay and writes the PNG.
///
/// # Errors
/// [`CliError::Session`] when the session cannot be read (exit 2); [`CliError::OverBudget`]
/// when the image or the mesh would not fit the memory budget (exit 2, checked before either is
/// allocated); [`CliError::Render`] when
/// rendering fails (exit 1) or there is no GPU adapter (exit
/// [`CliError::NO_ADAPTER_EXIT`]); [`CliError::Output`] when the clay cannot be meshed.
pub fn render(args: &RenderArgs) -> Result<RenderOutcome, CliError> {
    OutputRule::new()
        .input("SESSION", &args.session)
        .check("--out", &args.out, OutputKind::Image)
        .map_err(CliError::OutputRefused)?;
    let budget = MemoryBudget::from_flag(args.memory_budget_mib);
    budget
        .check_image(args.image.width, args.image.height)
        .map_err(CliError::OverBudget)?;
    // The file is read whole, then decoded into as many bytes again.
    budget
        .check_input(&args.session, 2)
        .map_err(CliError::OverBudget)?;
    let session = load_session(&args.session).map_err(CliError::Session)?;
    if session.clay.density.patches.is_empty() {
        return Err(CliError::Usage(format!(
            "{}: the session holds no density patch; there is nothing to render",
            args.session.display()
        )));
    }
    let octree = mesh_clay(&session.clay, args.cells_per_span, &budget).map_err(|e| match e {
        CliError::Output(m) => CliError::Output(format!("{}: {m}", args.session.display())),
        CliError::OutputFailed { context, source } => CliError::OutputFailed {
            context: format!("{}: {context}", args.session.display()),
            source,
        },
        CliError::OverBudget(mut o) => {
            o.what = format!("{}: {}", args.session.display(), o.what);
            CliError::OverBudget(o)
        }
        other => other,
    })?;
    let outcome = render_sculpt(
        &octree,
        session.clay.colour.as_ref(),
        &args.image,
        &args.out,
    )
    .map_err(|e| CliError::Render(e, args.out.clone()))?;
    println!("{}", describe_outcome(&outcome));
    Ok(outcome)
}
