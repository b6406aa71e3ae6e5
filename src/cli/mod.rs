//! The `dynaclay` command line: argument definitions and one module per subcommand.

/// `println!` for progress lines that tolerates a closed stdout (`dynaclay run | head -1`): a
/// broken pipe must not stop a run before its outputs are written, so the error is dropped.
macro_rules! say {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout().lock(), $($arg)*);
    }};
}

/// `print!` with the same tolerance as [`say!`].
macro_rules! say_raw {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = write!(std::io::stdout().lock(), $($arg)*);
    }};
}

mod args;
pub mod budget;
mod devices;
mod error;
mod import;
mod outputs;
mod platform;
mod points;
mod profile;
mod rbf;
mod render;
mod run;
mod sculpt;

pub use args::{
    Cli, Commands, DevicesArgs, ImageArgs, PointsArgs, ProfileArgs, RbfArgs, RenderArgs, RunArgs,
    ShadingMode,
};
pub use error::CliError;
pub use outputs::{ExtraOutputs, RunOutputs, write_lockstep_outputs, write_outputs};
pub use platform::{PlatformJudged, PlatformWatch};
pub use points::{PointsOutcome, points};
pub use profile::profile;
pub use rbf::{RbfCommandError, RbfOutcome, rbf};
pub use render::render;
pub use run::run;
pub use sculpt::{describe_outcome, mesh_clay, render_sculpt};

/// Runs the parsed command line; returns the process exit code.
#[must_use]
pub fn dispatch(cli: Cli) -> i32 {
    let result = match cli.command {
        Commands::Run(a) => run(&a).map(|_| ()),
        Commands::Profile(a) => profile(&a),
        Commands::Devices(a) => devices::devices(&a),
        Commands::Gui(a) => crate::app::gui_main(&a.rest).map_err(|e| match e {
            crate::app::LaunchError::Usage(_) => CliError::bad_input("gui", e),
            crate::app::LaunchError::Device(_) | crate::app::LaunchError::Start { .. } => {
                CliError::device("gui", e)
            }
            crate::app::LaunchError::Failed(_) => CliError::output("gui", e),
            crate::app::LaunchError::Session(s) => CliError::Session(s),
        }),
        Commands::Render(a) => render(&a).map(|_| ()),
        Commands::Import(a) => import::import(&a),
        Commands::Points(a) => points::points(&a).map(|_| ()),
        Commands::Rbf(a) => rbf(&a).map(|_| ()).map_err(CliError::Rbf),
    };
    match result {
        Ok(()) => 0,
        Err(e) => {
            eprintln!("dynaclay: {e}");
            e.exit_code()
        }
    }
}
