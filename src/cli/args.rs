//! Argument definitions (clap derive).

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand};

/// Haptic volumetric sculpting: dynamic B-spline clay under a force-feedback arm.
#[derive(Debug, Parser)]
#[command(name = "dynaclay", version, about)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Commands,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Commands {
    /// Run a headless sculpting session (simulated arm and built-in script by default).
    Run(RunArgs),
    /// Run the three loops and print their latency table.
    Profile(ProfileArgs),
    /// List connected haptic devices (HID and serial) and permission problems.
    Devices,
    /// Render a session to a PNG (not available in this build yet).
    Render(PassThrough),
    /// Open the interactive sculpting window (not available in this build yet).
    Gui(PassThrough),
}

/// Arguments kept for subcommands that other builds provide.
#[derive(Debug, Args)]
pub struct PassThrough {
    /// Arguments for the subcommand.
    #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
    pub rest: Vec<String>,
}

/// `dynaclay run`.
#[derive(Debug, Args, Clone)]
pub struct RunArgs {
    /// Script: starting clay, strokes, tool steps, undo, saves (TOML; the README's "Script
    /// format"). Default: built in.
    #[arg(long, value_name = "FILE")]
    pub script: Option<PathBuf>,
    /// Start from the recovery file that autosave left in DIR (after a crash) instead of the
    /// script's clay.
    #[arg(long)]
    pub recover: bool,
    /// Device: sim, hid[:PROFILE], serial:PATH[:PROFILE], falcon:PATH, spacemouse, replay:FILE.
    #[arg(long, default_value = "sim", value_name = "SPEC")]
    pub device: String,
    /// Session length in seconds (default: the script's `seconds`, else 3).
    #[arg(long, value_name = "N", value_parser = parse_seconds)]
    pub seconds: Option<f64>,
    /// Output directory.
    #[arg(long, default_value = "out", value_name = "DIR")]
    pub out: PathBuf,
    /// Record the device session (every read and force) to FILE, for `--device replay:FILE`.
    #[arg(long, value_name = "FILE")]
    pub record: Option<PathBuf>,
    /// Also write DIR/sculpt.ply.
    #[arg(long)]
    pub ply: bool,
    /// Also write DIR/sculpt.stl.
    #[arg(long)]
    pub stl: bool,
    /// Ask for SCHED_FIFO on the haptic thread (default on; `--no-rt` to skip).
    #[arg(long = "no-rt", action = clap::ArgAction::SetFalse)]
    pub rt: bool,
}

/// `dynaclay profile`.
#[derive(Debug, Args, Clone)]
pub struct ProfileArgs {
    /// How long to run, seconds.
    #[arg(long, default_value = "5", value_name = "N", value_parser = parse_seconds)]
    pub seconds: f64,
    /// Run a CPU hog thread on each other core meanwhile.
    #[arg(long)]
    pub load: bool,
    /// Ask for SCHED_FIFO on the haptic thread (default on; `--no-rt` to skip).
    #[arg(long = "no-rt", action = clap::ArgAction::SetFalse)]
    pub rt: bool,
}

fn parse_seconds(s: &str) -> Result<f64, String> {
    let v: f64 = s
        .parse()
        .map_err(|_| format!("`{s}` is not a number of seconds"))?;
    if v.is_finite() && v > 0.0 && v <= 3600.0 {
        Ok(v)
    } else {
        Err(format!("{s} is out of range: give 0 < N ≤ 3600 seconds"))
    }
}
