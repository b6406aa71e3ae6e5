//! Engine settings and the starting clay.

use std::time::Duration;

use dynaclay_devices::{DeviceInfo, SafetyConfig};
use glam::Vec3;

use super::simulation::SimConfig;
use super::workspace::{WorkspaceMap, reach_box};
use dynaclay_core::field::{
    BSplineLattice, FitError, MultiPatchField, Primitive, band_limited_lattice,
};
use dynaclay_core::haptics::{HapticConfig, calibrated_force_scale};
use dynaclay_core::io::{ClayShape, ClaySpec};

/// Newtons per unit of reaction when the clay cannot be calibrated (about what the
/// calibration gives for the default block on the simulated arm).
pub const DEFAULT_FORCE_N_PER_UNIT: f32 = 300.0;

pub use dynaclay_core::field::CLAY_SPACING;

/// Everything the engine needs besides the device and the starting field.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EngineConfig {
    /// Haptic loop rate, hertz.
    pub haptic_rate_hz: f64,
    /// Simulation loop rate, hertz (one step per tick).
    pub sim_rate_hz: f64,
    /// Graphics loop rate, hertz: it ticks at least this often (paint, idle frames).
    pub graphics_rate_hz: f64,
    /// The most graphics ticks a second that the simulation's publications may start: a
    /// publication that changed the clay wakes the graphics loop at once, but never sooner
    /// after its previous tick than one over this rate (so re-meshing never runs faster).
    pub graphics_max_rate_hz: f64,
    /// SCHED_FIFO priority asked for the haptic thread (`None`: normal priority).
    pub haptic_rt_priority: Option<i32>,
    /// Field snapshots younger than this give full force.
    pub stale_fresh: Duration,
    /// Field snapshots this old give zero force (the fade runs in between).
    pub stale_limit: Duration,
    /// Device metres ↔ field coordinates, and force scale.
    pub map: WorkspaceMap,
    /// How the clay feels: touch, sculpting reaction, shaping, passivity.
    pub haptics: HapticConfig,
    /// Simulation settings.
    pub sim: SimConfig,
    /// Marching-cubes cells per knot span.
    pub cells_per_span: u32,
    /// Simulation steps per haptic sample in lockstep mode.
    pub lockstep_steps_per_sample: u32,
    /// The safety filter's settings (force cap, slew limit, soft start).
    pub safety: SafetyConfig,
}

impl EngineConfig {
    /// Defaults for `field` driven by a device with `info`: 1 kHz haptic, 1 kHz simulation,
    /// 60 Hz graphics woken by publications up to 120 Hz, SCHED_FIFO 80 asked for, staleness fade from 50 to 100 ms, the device
    /// workspace mapped around the lattice and room past it ([`reach_box`],
    /// [`WorkspaceMap::fitting`]), touch as stiff as
    /// the device allows, and the sculpting force calibrated on `field` so that pressing 5 mm
    /// into its top feels 2 N at haptic gain 1 ([`calibrated_force_scale`];
    /// [`DEFAULT_FORCE_N_PER_UNIT`] when the field has no top to press).
    #[must_use]
    pub fn for_field(field: &BSplineLattice, info: &DeviceInfo) -> Self {
        Self::for_clay(&MultiPatchField::new(field.clone()), info)
    }

    /// [`EngineConfig::for_field`] for a clay of several patches: the workspace is mapped
    /// around the base patch's lattice ([`reach_box`]) and the force is calibrated on the whole density.
    #[must_use]
    pub fn for_clay(density: &MultiPatchField, info: &DeviceInfo) -> Self {
        let (lo, hi) = reach_box(density.base());
        let mut map = WorkspaceMap::fitting(
            info.workspace_min_m,
            info.workspace_max_m,
            lo,
            hi,
            DEFAULT_FORCE_N_PER_UNIT,
        );
        if let Some(scale) = calibrated_force_scale(density, map.field_per_m) {
            map.force_n_per_reaction = scale;
        }
        Self {
            haptic_rate_hz: 1000.0,
            sim_rate_hz: 1000.0,
            graphics_rate_hz: 60.0,
            graphics_max_rate_hz: 120.0,
            haptic_rt_priority: Some(dynaclay_loops::DEFAULT_RT_PRIORITY),
            stale_fresh: Duration::from_millis(50),
            stale_limit: Duration::from_millis(100),
            map,
            haptics: HapticConfig::for_device(
                info.max_stiffness_n_per_m,
                info.max_damping_n_s_per_m,
            ),
            sim: SimConfig::default(),
            cells_per_span: 4,
            lockstep_steps_per_sample: 1,
            safety: SafetyConfig::default(),
        }
    }
}

/// The starting clay of `spec`: a lattice of `resolution³` coefficients at [`CLAY_SPACING`],
/// holding a block (the middle half of the lattice, its edges and corners rounded over about
/// 1.7 knot spans) or a sphere (radius a quarter of the lattice), with the smooth density step
/// of [`band_limited_lattice`] (ramp width two spans): flat faces, no ridges, no ringing.
///
/// # Errors
/// When the fit fails (it does not for valid specs).
pub fn build_clay(spec: &ClaySpec) -> Result<BSplineLattice, FitError> {
    build_clay_sized(spec.shape, spec.resolution, DEFAULT_CLAY_SIZE)
}

/// The block's half side and the sphere's radius of the starting clay, as a fraction of the
/// lattice's side ([`build_clay`]'s size).
pub const DEFAULT_CLAY_SIZE: f32 = 0.25;

/// The starting clays a window may ask for: their half side (or radius) as a fraction of
/// the lattice's side. Below a tenth the shape is a few knot spans across at low
/// resolutions; above 0.45 it touches the lattice's border band.
pub const CLAY_SIZE_RANGE: std::ops::RangeInclusive<f32> = 0.1..=0.45;

/// Like [`build_clay`], with the block's half side or the sphere's radius `size` times the
/// lattice's side (`size` is clamped to [`CLAY_SIZE_RANGE`]); the "New clay" of the window.
///
/// # Errors
/// When the fit fails (it does not for a resolution of 8 to 96).
pub fn build_clay_sized(
    shape: ClayShape,
    resolution: usize,
    size: f32,
) -> Result<BSplineLattice, FitError> {
    let n = resolution;
    let extent = n.saturating_sub(1) as f32 * CLAY_SPACING;
    let centre = Vec3::splat(extent * 0.5);
    let size = if size.is_finite() {
        size.clamp(*CLAY_SIZE_RANGE.start(), *CLAY_SIZE_RANGE.end())
    } else {
        DEFAULT_CLAY_SIZE
    };
    let primitive = match shape {
        ClayShape::Block => Primitive::Box {
            centre,
            half_extents: Vec3::splat(extent * size),
        },
        ClayShape::Sphere => Primitive::Sphere {
            centre,
            radius: extent * size,
        },
    };
    band_limited_lattice(
        [n; 3],
        CLAY_SPACING,
        Vec3::ZERO,
        &primitive,
        2.0 * CLAY_SPACING,
        2,
    )
}
