//! What the hand feels: touch through a surface proxy or the held tool's shape, the sculpting reaction of every force
//! tool (Hua & Qin §7.2.2), smooth saturation and cross-fades, a passivity observer with its
//! damper, and one shaping stage with a stated rate limit before the device's safety filter.
//!
//! Everything here runs on the haptic thread: no allocation after construction, no lock,
//! bounded work, device time only. The engine's haptic stage owns a [`ForceRenderer`] and
//! calls it once per tick.

mod passivity;
mod proxy;
mod renderer;
mod sculpt;
mod shaping;
mod shell;
#[cfg(test)]
mod test_clay;

pub use passivity::{MAX_SENSOR_DELAY_TICKS, PassivityConfig, PassivityController};
pub use proxy::{MAX_PROXY_PROBES, ProxyConfig, SurfaceProxy, Touch};
pub use renderer::{
    CALIBRATION_DEPTH_M, CALIBRATION_FORCE_N, Felt, FeltInput, ForceRenderer, HapticConfig,
    ToolPressConfig, calibrated_force_scale, saturate, spring_energy_j,
};
pub use sculpt::{
    FELT_TARGETS, FeltTool, MAX_FELT_VECTORS, MAX_STROKE_POINTS, MAX_TOOL_VECTORS, SculptForce,
    SculptReaction, StrokeGeometry,
};
pub use shaping::{Blend, FadeOut, ForceShaper, ShapingConfig};
pub use shell::{MAX_SHAPE_PROBES, SHELL_POINTS, ShapeProxy, ToolShell, press_fraction};
