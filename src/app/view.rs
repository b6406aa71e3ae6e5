//! What the engine publishes for the app to show: one [`EngineView`] value, replaced whole
//! through a triple buffer, so the app reads a consistent picture without ever blocking the
//! publisher.
//!
//! The view is plain data apart from the device name, which the publisher overwrites in place
//! (`clone_from`), so publishing allocates only when the name grows.

use glam::Vec3;

use dynaclay_loops::LatencyStats;

use crate::dynamics::Material;

/// The three loops, in the order of [`EngineView::loops`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum LoopId {
    Haptic,
    Simulation,
    Graphics,
}

impl LoopId {
    /// Every loop, in display order.
    pub const ALL: [LoopId; 3] = [Self::Haptic, Self::Simulation, Self::Graphics];

    /// The loop's name, as in latency reports.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Haptic => "haptic",
            Self::Simulation => "simulation",
            Self::Graphics => "graphics",
        }
    }

    /// Index into [`EngineView::loops`].
    #[must_use]
    pub fn index(self) -> usize {
        match self {
            Self::Haptic => 0,
            Self::Simulation => 1,
            Self::Graphics => 2,
        }
    }
}

/// Where the haptic device stands.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum DeviceLinkState {
    #[default]
    Disconnected,
    Connecting,
    Connected,
    /// The device reported an error or went away; force is zero until it is reconnected.
    Faulted,
}

impl DeviceLinkState {
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Disconnected => "disconnected",
            Self::Connecting => "connecting",
            Self::Connected => "connected",
            Self::Faulted => "faulted",
        }
    }
}

/// The device as the engine sees it.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DeviceStatus {
    pub state: DeviceLinkState,
    /// Model name from the driver's `DeviceInfo` (empty when disconnected).
    pub name: String,
    /// Force limit applied by the safety filter, newtons.
    pub max_force_n: f32,
    /// The device's own force maximum, newtons (the limit never exceeds it).
    pub device_max_force_n: f32,
    /// Whether the device outputs force at all (a SpaceMouse does not).
    pub has_force: bool,
    /// Largest force sent to the device since it was connected, newtons.
    pub peak_force_n: f32,
    /// The spec of the device in use (as `--device` takes it), `None` before the engine says.
    /// The one source for the device the panels show as in use.
    pub spec: Option<dynaclay_devices::spec::DeviceSpec>,
}

/// An axis-aligned box in world units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WorldBox {
    pub min: Vec3,
    pub max: Vec3,
}

/// Everything the app shows besides the meshes.
#[derive(Clone, Debug, PartialEq)]
pub struct EngineView {
    /// Tool centre in world units.
    pub tool_position: Vec3,
    /// Radius of the tool's bounding sphere, world units (0: draw no tool).
    pub tool_radius: f32,
    /// Force the user feels, newtons, in world axes.
    pub force_n: Vec3,
    /// Whether a stroke is being applied.
    pub stroke_active: bool,
    /// The material in effect.
    pub material: Material,
    /// Steps that undo and redo can take.
    pub undo_steps: usize,
    pub redo_steps: usize,
    pub device: DeviceStatus,
    /// Latency figures of each loop, indexed by [`LoopId::index`].
    pub loops: [LatencyStats; 3],
    /// The sculpting workspace.
    pub workspace: Option<WorldBox>,
    /// The locally simulated region (Hua & Qin §7.3).
    pub region: Option<WorldBox>,
    /// Simulated time, seconds.
    pub sim_time_s: f64,
    /// Sessions loaded into the running engine so far (the app re-reads the material when
    /// this changes).
    pub sessions_loaded: u64,
    /// The clay's pins, one line each, in the order `EngineCommand::Unpin` counts them.
    pub pins: Vec<String>,
    /// Where each pin is, field coordinates: one point for a point or normal pin, the
    /// polyline of a curve pin (drawn over the view).
    pub pin_marks: Vec<Vec<Vec3>>,
    /// Times the engine restarted on a loaded clay of another layout (the app frames the
    /// new clay and re-maps its pointer when this changes).
    pub restarts: u64,
    /// The base lattice's box since the last restart (`None` before one).
    pub clay_box: Option<WorldBox>,
    /// The field → device map since the last restart (`None` before one).
    pub workspace_map: Option<crate::engine::WorkspaceMap>,
    /// The compact RBF clay: on or off, centres, the last re-interpolation's time.
    pub compact: crate::engine::CompactStatus,
    /// A step held until the user says it may remove more than half the clay.
    pub removal_question: Option<crate::engine::RemovalQuestion>,
}

impl EngineView {
    /// Whether `self` and `other` draw the same window: equal in everything but the loops'
    /// latency figures and the simulated time, which change on every step even when nothing
    /// on the screen would. The bridge wakes the app only when this is false.
    #[must_use]
    pub fn same_picture(&self, other: &Self) -> bool {
        let Self {
            tool_position,
            tool_radius,
            force_n,
            stroke_active,
            material,
            undo_steps,
            redo_steps,
            device,
            loops: _,
            workspace,
            region,
            sim_time_s: _,
            sessions_loaded,
            pins,
            pin_marks,
            restarts,
            clay_box,
            workspace_map,
            compact,
            removal_question,
        } = self;
        *tool_position == other.tool_position
            && *tool_radius == other.tool_radius
            && *force_n == other.force_n
            && *stroke_active == other.stroke_active
            && *material == other.material
            && *undo_steps == other.undo_steps
            && *redo_steps == other.redo_steps
            && *device == other.device
            && *workspace == other.workspace
            && *region == other.region
            && *sessions_loaded == other.sessions_loaded
            && *pins == other.pins
            && *pin_marks == other.pin_marks
            && *restarts == other.restarts
            && *clay_box == other.clay_box
            && *workspace_map == other.workspace_map
            && *compact == other.compact
            && *removal_question == other.removal_question
    }
}

impl Default for EngineView {
    fn default() -> Self {
        Self {
            tool_position: Vec3::ZERO,
            tool_radius: 0.0,
            force_n: Vec3::ZERO,
            stroke_active: false,
            material: Material::default(),
            undo_steps: 0,
            redo_steps: 0,
            device: DeviceStatus::default(),
            loops: [LatencyStats::default(); 3],
            workspace: None,
            region: None,
            sim_time_s: 0.0,
            sessions_loaded: 0,
            pins: Vec::new(),
            pin_marks: Vec::new(),
            restarts: 0,
            clay_box: None,
            workspace_map: None,
            compact: crate::engine::CompactStatus::default(),
            removal_question: None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn loop_figures_and_simulated_time_alone_do_not_change_the_picture() {
        let shown = EngineView::default();
        let mut next = shown.clone();
        next.loops[LoopId::Haptic.index()].ticks = 1000;
        next.loops[LoopId::Simulation.index()].achieved_rate_hz = 997.0;
        next.sim_time_s = 12.5;
        assert!(next.same_picture(&shown), "nothing on screen would change");
        assert_ne!(next, shown, "though the views differ");

        for changed in [
            EngineView {
                undo_steps: 1,
                ..next.clone()
            },
            EngineView {
                tool_position: Vec3::X,
                ..next.clone()
            },
            EngineView {
                pins: vec!["#0: point".into()],
                ..next.clone()
            },
            EngineView {
                device: DeviceStatus {
                    spec: Some(dynaclay_devices::spec::DeviceSpec::Sim),
                    ..DeviceStatus::default()
                },
                ..next.clone()
            },
        ] {
            assert!(!changed.same_picture(&shown), "{changed:?}");
        }
    }
}
