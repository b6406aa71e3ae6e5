//! Argument definitions (clap derive).

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand, ValueEnum};

use crate::render::{EnvironmentMode, NamedView, SceneOptions, Shading};

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
    #[command(after_help = RUN_AFTER_HELP)]
    Run(RunArgs),
    /// Run the three loops with a platform probe before and after, print their latency table,
    /// the probe side by side and a readiness verdict for 1 kHz and 4 kHz; or compare two
    /// `latency.json` files.
    Profile(ProfileArgs),
    /// List connected haptic devices (every supported arm and SpaceMouse by USB ID, HID devices
    /// and serial ports) and why each cannot be opened; or run a zero-force read loop on one
    /// (`--doctor SPEC`) and report its rate and jitter.
    #[command(after_help = DEVICES_AFTER_HELP)]
    Devices(DevicesArgs),
    /// Render a session file to a PNG image, offscreen.
    #[command(after_help = RENDER_AFTER_HELP)]
    Render(RenderArgs),
    /// Open the interactive sculpting window (egui on wgpu).
    Gui(PassThrough),
    /// Fit a clay to a point cloud (.xyz, .txt, .pts, .ply) or a volume (.raw, .nrrd) and
    /// write it as a session.
    Import(ImportArgs),
    /// Build a point-set surface (Guo & Qin: a local B-spline field per point, blended) from a
    /// point cloud, optionally pull it with the density-spring dynamics, and write the points
    /// with their normals as PLY.
    Points(PointsArgs),
    /// Sample a session's clay with constrained particles and write the compact RBF that
    /// interpolates them (Zhang et al. §5.3): centres, weights and a linear polynomial.
    Rbf(RbfArgs),
}

/// `dynaclay devices`.
#[derive(Debug, Args, Clone)]
pub struct DevicesArgs {
    /// Open the device SPEC names (a --device spec: sim, falcon:PATH, touch, dhd[:N],
    /// hid[:PROFILE], serial:PATH[:PROFILE], spacemouse), run a zero-force read loop on it and
    /// report the rate achieved and the percentiles of its period.
    #[arg(long, value_name = "SPEC")]
    pub doctor: Option<String>,
    /// How long the doctor's loop runs, seconds.
    #[arg(long, value_name = "N", default_value_t = 2.0, value_parser = parse_doctor_seconds,
          requires = "doctor")]
    pub seconds: f64,
    /// The Novint Falcon firmware file, uploaded when no firmware answers (never guessed;
    /// overrides DYNACLAY_FALCON_FIRMWARE and a profile's `firmware`).
    #[arg(long, value_name = "FILE")]
    pub falcon_firmware: Option<PathBuf>,
    /// Print the udev rules that let this user open every supported device, and exit.
    #[arg(long, conflicts_with = "doctor")]
    pub udev_rules: bool,
}

const DEVICES_AFTER_HELP: &str = "\
Examples:
  dynaclay devices                               what is plugged in, and what stops it opening
  dynaclay devices --udev-rules | sudo tee /etc/udev/rules.d/70-dynaclay.rules
  dynaclay devices --doctor falcon:/dev/ttyUSB0 --falcon-firmware novint.bin
  dynaclay devices --doctor sim --seconds 1";

/// The doctor's duration: 0.05 to 60 seconds.
fn parse_doctor_seconds(s: &str) -> Result<f64, String> {
    let v: f64 = s
        .parse()
        .map_err(|_| format!("`{s}` is not a number of seconds"))?;
    if v.is_finite() && (0.05..=60.0).contains(&v) {
        Ok(v)
    } else {
        Err(format!("{s} is out of range: give 0.05 ≤ N ≤ 60 seconds"))
    }
}

/// `dynaclay rbf`.
#[derive(Debug, Args, Clone)]
pub struct RbfArgs {
    /// Session file whose clay is interpolated.
    #[arg(value_name = "SESSION")]
    pub session: PathBuf,
    /// How many particles sample the surface (the RBF has three centres per particle, fewer
    /// when more than --max-centres are needed).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(4..=100_000),
          default_value_t = 400)]
    pub particles: u32,
    /// RBF file to write (`.rbf`, replaced atomically).
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
    /// Particle steps before the fit.
    #[arg(long, value_name = "STEPS", default_value_t = 200,
          value_parser = clap::value_parser!(u32).range(1..=100_000))]
    pub steps: u32,
    /// Offset of the inner and outer constraint points along the normal, field units
    /// (default: half a knot span).
    #[arg(long, value_name = "D", value_parser = parse_positive)]
    pub offset: Option<f32>,
    /// Most centres in one dense solve; above, centres are chosen greedily.
    #[arg(long, value_name = "M", default_value_t = 3000,
          value_parser = clap::value_parser!(u32).range(4..=6000))]
    pub max_centres: u32,
    /// Seed of the particles' random start.
    #[arg(long, value_name = "S", default_value_t = 1)]
    pub seed: u64,
    /// Also import the RBF back as a clay and write it as this session (`.dclay`).
    #[arg(long, value_name = "FILE")]
    pub clay: Option<PathBuf>,
    /// Sculpt the clay as the RBF (Zhang et al. §5.4) with this script's contact tool steps
    /// before writing it: each action resamples and re-interpolates, the centre count stays.
    #[arg(long, value_name = "SCRIPT")]
    pub sculpt: Option<PathBuf>,
}

fn parse_positive(text: &str) -> Result<f32, String> {
    match text.parse::<f32>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!("{text}: expected a positive number")),
    }
}

/// A raw volume's sample type.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum RawSample {
    /// Unsigned 8-bit.
    U8,
    /// Unsigned 16-bit.
    U16,
    /// Signed 16-bit.
    I16,
    /// 32-bit float.
    F32,
}

fn parse_dims(s: &str) -> Result<[usize; 3], String> {
    let v: Vec<usize> = s
        .split(',')
        .map(|t| t.trim().parse::<usize>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("`{s}`: three whole numbers X,Y,Z"))?;
    match v[..] {
        [x, y, z] => Ok([x, y, z]),
        _ => Err(format!("`{s}`: three whole numbers X,Y,Z")),
    }
}

/// `dynaclay import`.
#[derive(Debug, Args, Clone)]
pub struct ImportArgs {
    /// The point cloud: XYZ text (`x y z` or `x y z nx ny nz` per line) or PLY (ASCII or
    /// binary, normals used when present); or a volume: raw samples (`.raw`, with `--dims`)
    /// or NRRD (`.nrrd`, data in the same file, raw encoding).
    #[arg(value_name = "INPUT")]
    pub input: PathBuf,
    /// A volume's iso-value: intensities above it are solid (required for volumes).
    #[arg(long, value_name = "V")]
    pub iso: Option<f32>,
    /// A raw volume's voxels per axis, `X,Y,Z` (x fastest in the file).
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_dims)]
    pub dims: Option<[usize; 3]>,
    /// A raw volume's sample type (little-endian).
    #[arg(long, value_enum, default_value_t = RawSample::U8)]
    pub sample: RawSample,
    /// The session to write (`.dclay`).
    #[arg(long, value_name = "SESSION")]
    pub out: PathBuf,
    /// Coefficients per axis of the fitted clay (12 to 256; the object spans this less
    /// eight). Default: 32 for a mesh or a volume; a point cloud's is chosen from its noise
    /// (estimated, or `--noise`) and point spacing, a knot span of 0.9 (noise × spacing)^(1/3),
    /// within bounds its point count sets (32 up to about 27 000 points; 40 to 44 at 50 000;
    /// at most 48).
    #[arg(long, value_name = "N")]
    pub resolution: Option<usize>,
    /// Holes in a point cloud narrower than twice this, in knot spans, are capped (0.5 to
    /// 3.5): the outside is found by a flood that cannot pass them. Wider holes let the
    /// outside in; narrower concavities are bridged. At the default, a cloud with normals
    /// whose points the outside reaches on both sides is closed again at 3.5 where that
    /// keeps it out (the log says so).
    #[arg(long, default_value_t = crate::fit::cloud::DEFAULT_GAP_SPANS, value_name = "SPANS")]
    pub gap: f32,
    /// The error bound, in percent of the object's size (its box's longest side; a volume's
    /// longest side): an octree node whose points (or voxels near the surface) lie farther
    /// than this from the fitted surface, root mean square, gets a finer detail patch (Hua &
    /// Qin §5).
    #[arg(long, default_value_t = crate::fit::hierarchy::DEFAULT_ERROR * 100.0, value_name = "PERCENT")]
    pub error: f32,
    /// The deepest level of detail patches (0 to 6; 0 fits the base lattice alone). Level
    /// `d` has half the knot spacing of level `d − 1`.
    #[arg(long, default_value_t = crate::fit::hierarchy::DEFAULT_MAX_DEPTH, value_name = "D")]
    pub max_depth: u32,
    /// A point cloud's noise: the scatter of its points across the surface (standard
    /// deviation), in percent of the object's size. Estimated from the cloud when not given;
    /// the fit smooths at this scale and makes no detail patch finer than it.
    #[arg(long, value_name = "PERCENT")]
    pub noise: Option<f32>,
    /// Also write the fitted surface as a mesh (.obj, .ply or .stl) in the input's
    /// coordinates (a volume's in voxels), to lay over the input and check the fit.
    #[arg(long, value_name = "FILE")]
    pub mesh: Option<PathBuf>,
    /// The memory budget, MiB: a mesh or image that would need more is refused before
    /// anything is allocated (exit 2). Default: half of the machine's physical memory.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..))]
    pub memory_budget_mib: Option<u64>,
    /// Print each stage's wall time on stderr at the end (reading, each stage of a point
    /// cloud's fit, meshing, encoding, writing), to see where an import spends its time.
    #[arg(long)]
    pub timings: bool,
}

/// `dynaclay points`.
#[derive(Debug, Args, Clone)]
pub struct PointsArgs {
    /// The point cloud: XYZ text (`x y z` or `x y z nx ny nz`), PLY, or a mesh (.obj, .stl)
    /// sampled into points. Normals are estimated and oriented when the file has none.
    #[arg(value_name = "INPUT")]
    pub input: PathBuf,
    /// The PLY file to write: positions, normals and colours.
    #[arg(long, value_name = "OUT.ply")]
    pub out: PathBuf,
    /// Also write the blended surface (eq. 5) as a mesh (.obj, .ply or .stl).
    #[arg(long, value_name = "FILE")]
    pub mesh: Option<PathBuf>,
    /// Pull the surface toward `X,Y,Z` (repeatable; one after another): the nearest surface
    /// point is dragged there by the density-spring dynamics, with points inserted and removed
    /// as the surface stretches.
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_point)]
    pub pull: Vec<[f32; 3]>,
    /// Simulation steps per pull.
    #[arg(long, default_value_t = 2000, value_name = "N",
          value_parser = clap::value_parser!(u32).range(1..=1_000_000))]
    pub steps: u32,
    /// Neighbours per point (`k`) for normals and local fits.
    #[arg(long, default_value_t = 10, value_name = "K",
          value_parser = clap::value_parser!(u32).range(4..=64))]
    pub neighbours: u32,
    /// Emboss this image (PNG or JPEG) onto the surface after the pulls (Guo & Qin §5.1):
    /// each point moves along its normal by the image's brightness times `--depth`, and the
    /// surface is rebuilt from the moved points.
    #[arg(long, value_name = "IMAGE")]
    pub emboss: Option<PathBuf>,
    /// The relief's depth for `--emboss`, field units (default: two point spacings).
    #[arg(long, value_name = "D", value_parser = parse_positive, requires = "emboss")]
    pub depth: Option<f32>,
    /// Engrave (sink the bright parts) instead of raising them.
    #[arg(long, requires = "emboss")]
    pub engrave: bool,
    /// How `--emboss` lays the image on the surface, about the centre of the points' box:
    /// `spherical` (the image's top at +y), `cylindrical` (wrapped around the y axis, the
    /// image's centre facing +z, as tall as the box) or `planar` (projected from +z onto the
    /// faces turned toward it, as wide as the box).
    #[arg(long, value_enum, default_value_t = EmbossProjection::Spherical, requires = "emboss")]
    pub projection: EmbossProjection,
}

/// How `dynaclay points --emboss` lays its image on the surface.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum EmbossProjection {
    /// Longitude and latitude about the centre, the top at +y.
    Spherical,
    /// Around the y axis through the centre.
    Cylindrical,
    /// From +z.
    Planar,
}

fn parse_point(s: &str) -> Result<[f32; 3], String> {
    let v: Vec<f32> = s
        .split(',')
        .map(|t| t.trim().parse::<f32>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("`{s}`: three numbers X,Y,Z"))?;
    match v[..] {
        [x, y, z] if x.is_finite() && y.is_finite() && z.is_finite() => Ok([x, y, z]),
        _ => Err(format!("`{s}`: three finite numbers X,Y,Z")),
    }
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
    /// Script: starting clay, strokes, tool steps, undo, saves (TOML; the user guide's "Script
    /// format"). Default: built in.
    #[arg(long, value_name = "FILE")]
    pub script: Option<PathBuf>,
    /// Start from the recovery file that autosave left in DIR (after a crash) instead of the
    /// script's clay.
    #[arg(long)]
    pub recover: bool,
    /// Let the script's `save` steps write outside the script's folder and the output
    /// directory.
    #[arg(long)]
    pub allow_outside: bool,
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
    /// The Novint Falcon firmware file, uploaded when no firmware answers (never guessed;
    /// overrides DYNACLAY_FALCON_FIRMWARE and a profile's `firmware`).
    #[arg(long, value_name = "FILE")]
    pub falcon_firmware: Option<PathBuf>,
    /// Also write DIR/sculpt.ply.
    #[arg(long)]
    pub ply: bool,
    /// Also write DIR/sculpt.stl.
    #[arg(long)]
    pub stl: bool,
    /// Run the loops in lockstep on the device's clock instead of in real time: one device
    /// sample, one simulation step, as fast as the machine goes; the same script always gives
    /// the same sculpt, bit for bit (simulated arm, or a replay: its samples in lockstep
    /// instead of as its recorded schedule says, which a recording without a usable schedule
    /// needs). With touch, phantom or dhd, one servo tick of the arm per step, for
    /// `--seconds` of the arm's clock; with falcon or 2diy, one command and its reply per
    /// step, the samples stamped 1 ms apart by reply count.
    #[arg(long)]
    pub lockstep: bool,
    /// Ask for SCHED_FIFO on the haptic thread (default on; `--no-rt` to skip).
    #[arg(long = "no-rt", action = clap::ArgAction::SetFalse)]
    pub rt: bool,
    /// Also render the final sculpt offscreen to a PNG: FILE, or DIR/sculpt.png when no FILE
    /// is given. Skipped with a message (the run still succeeds) when there is no GPU adapter.
    #[arg(long, value_name = "FILE", num_args = 0..=1)]
    pub png: Option<Option<PathBuf>>,
    /// How the PNG is rendered.
    #[command(flatten, next_help_heading = "Image (with --png)")]
    pub image: ImageArgs,
    /// The memory budget, MiB: the --png image that would need more is refused before
    /// anything is allocated (exit 2). Default: half of the machine's physical memory.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..))]
    pub memory_budget_mib: Option<u64>,
}

/// Exit statuses of `dynaclay render`, shown by `dynaclay render --help`.
pub const RENDER_AFTER_HELP: &str = "\
Exit status:
  0  the PNG was written
  1  rendering or writing the PNG failed
  2  bad argument, the session file cannot be read, or the mesh or image would need more than
     the memory budget (--memory-budget-mib; default half of physical memory)
  4  no GPU adapter on this machine (hardware or software, e.g. Mesa lavapipe): nothing was
     rendered, and the message says which backends were tried";

/// The PNG note of `dynaclay run --help`.
pub const RUN_AFTER_HELP: &str = "\
With --png and no GPU adapter, the run prints \"no GPU adapter: ...; skipped rendering\",
writes every other file and exits 0 (use `dynaclay render` for a status that reports it).
A --png image larger than the memory budget (--memory-budget-mib; default half of physical
memory) is refused with exit 2 before the run starts.";

/// `dynaclay render`.
#[derive(Debug, Args, Clone)]
pub struct RenderArgs {
    /// Session file to render (as written by `dynaclay run` or saved by the app).
    #[arg(value_name = "SESSION")]
    pub session: PathBuf,
    /// PNG file to write (replaced atomically).
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
    /// Marching-cubes cells per knot span (the resolution of the rendered surface).
    #[arg(long, default_value_t = 4, value_name = "N",
          value_parser = clap::value_parser!(u32).range(1..=16))]
    pub cells_per_span: u32,
    /// How the image is rendered.
    #[command(flatten)]
    pub image: ImageArgs,
    /// The memory budget, MiB: a mesh or image that would need more is refused before
    /// anything is allocated (exit 2). Default: half of the machine's physical memory.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..))]
    pub memory_budget_mib: Option<u64>,
}

/// Image settings shared by `dynaclay render` and `dynaclay run --png`.
#[derive(Debug, Args, Clone)]
pub struct ImageArgs {
    /// Viewpoint: front, back, left, right, top, bottom or iso.
    #[arg(long, default_value = "iso", value_name = "VIEW", value_parser = parse_view)]
    pub view: NamedView,
    /// Image width in pixels.
    #[arg(long, default_value_t = 1024, value_name = "PX",
          value_parser = clap::value_parser!(u32).range(1..=16384))]
    pub width: u32,
    /// Image height in pixels.
    #[arg(long, default_value_t = 768, value_name = "PX",
          value_parser = clap::value_parser!(u32).range(1..=16384))]
    pub height: u32,
    /// Surface shading (Ferley et al. §5).
    #[arg(long, value_enum, default_value_t = ShadingMode::Phong, value_name = "MODE")]
    pub shading: ShadingMode,
    /// Opacity of the environment layer for `transparent`, and at normal incidence for
    /// `clearcoat`, in [0, 1].
    #[arg(long, default_value_t = 0.35, value_name = "A", value_parser = parse_opacity)]
    pub opacity: f32,
}

/// The `--shading` choices.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ShadingMode {
    /// Blinn-Phong lighting of the clay colour and paint.
    Phong,
    /// The studio environment (matcap) replaces the surface colour: a metallic look.
    Matcap,
    /// The environment blended over the lit clay with constant opacity (`--opacity`).
    Transparent,
    /// An angle-dependent clear coat: the environment's opacity rises from `--opacity` facing
    /// the viewer to 1 at grazing angles.
    Clearcoat,
}

impl ShadingMode {
    /// The renderer's environment mode for this choice.
    #[must_use]
    pub fn environment(self) -> EnvironmentMode {
        match self {
            Self::Phong => EnvironmentMode::Off,
            Self::Matcap => EnvironmentMode::Opaque,
            Self::Transparent => EnvironmentMode::Transparent,
            Self::Clearcoat => EnvironmentMode::ClearCoat,
        }
    }
}

impl ImageArgs {
    /// The scene options these settings ask for: default lights and clay colour, the chosen
    /// environment mode, no overlays.
    #[must_use]
    pub fn scene_options(&self) -> SceneOptions {
        SceneOptions {
            shading: Shading {
                environment: self.shading.environment(),
                environment_opacity: self.opacity,
                ..Shading::default()
            },
            ..SceneOptions::default()
        }
    }
}

fn parse_view(s: &str) -> Result<NamedView, String> {
    s.parse()
        .map_err(|e: crate::render::UnknownView| e.to_string())
}

fn parse_opacity(s: &str) -> Result<f32, String> {
    let v: f32 = s.parse().map_err(|_| format!("`{s}` is not a number"))?;
    if (0.0..=1.0).contains(&v) {
        Ok(v)
    } else {
        Err(format!("{s} is out of range: give an opacity in [0, 1]"))
    }
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
    /// The haptic loop's rate (1000 or 4000 Hz; the probe wakes at the same rate).
    #[arg(long, default_value = "1000", value_name = "HZ", value_parser = parse_profile_rate)]
    pub rate_hz: f64,
    /// Also write latency.json, latency.md and latency.svg into this directory.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Print per-figure ratios B ÷ A of two latency.json files instead of profiling.
    #[arg(long, num_args = 2, value_names = ["A.json", "B.json"])]
    pub compare: Option<Vec<PathBuf>>,
    /// Run the loops in lockstep on the device's clock instead of in real time: one device
    /// sample, one simulation step, as fast as the machine goes; the same script always gives
    /// the same sculpt, bit for bit (simulated arm, or a replay: its samples in lockstep
    /// instead of as its recorded schedule says, which a recording without a usable schedule
    /// needs).
    #[arg(long)]
    pub lockstep: bool,
    /// Ask for SCHED_FIFO on the haptic thread (default on; `--no-rt` to skip).
    #[arg(long = "no-rt", action = clap::ArgAction::SetFalse)]
    pub rt: bool,
}

fn parse_profile_rate(s: &str) -> Result<f64, String> {
    match s.parse::<u32>() {
        Ok(hz @ (1000 | 4000)) => Ok(f64::from(hz)),
        _ => Err(format!("`{s}` is not a profiled rate: give 1000 or 4000")),
    }
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
