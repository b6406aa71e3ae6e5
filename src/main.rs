//! The `dynaclay` command-line entry point: parses the arguments and runs the subcommand.

use clap::Parser;

fn main() {
    let cli = dynaclay::cli::Cli::parse();
    std::process::exit(dynaclay::cli::dispatch(cli));
}
