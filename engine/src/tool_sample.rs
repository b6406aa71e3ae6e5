//! What the haptic loop tells the simulation each tick: where the tool is and which force
//! vector it is applying.

use glam::{Quat, Vec3};

use super::motion_to_photon::FeltChange;

/// The latest tool state, published by the haptic loop through a triple buffer (plain data).
///
/// Positions are in field coordinates. While `in_contact` with the push tool, the tool applies
/// the force vector from `force_from_fu` (the touch proxy, on the clay's surface) to `force_to_fu`
/// (the tool tip); the simulation maps it onto the mass points with Hua & Qin's eq. (6)
/// evaluated on its own, newest field. With a force tool the pair is the first vector the
/// haptic loop felt (for display); the simulation makes the tool's vectors itself.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ToolSample {
    /// Tool tip, field coordinates.
    #[serde(alias = "tip")]
    pub tip_fu: Vec3,
    /// Start of the force vector (the surface point the push started from), field coordinates.
    #[serde(alias = "force_from")]
    pub force_from_fu: Vec3,
    /// End of the force vector (the tip), field coordinates.
    #[serde(alias = "force_to")]
    pub force_to_fu: Vec3,
    /// Whether the user holds the stroke (button 0, or a stroke armed by command).
    pub stroke_active: bool,
    /// Whether the held tool is acting on the clay this tick (a stroke is active and the push
    /// tool's tip is inside the clay, or a force tool has taken hold).
    pub in_contact: bool,
    /// Whether the tip is inside the clay with the touch proxy on its surface.
    #[serde(default)]
    pub touching: bool,
    /// The force sent to the device after the safety filter, newtons.
    pub device_force_n: Vec3,
    /// The device sample's timestamp, microseconds of device time.
    pub device_time_us: u64,
    /// Whether the device failed this tick (force is zero then).
    pub device_fault: bool,
    /// The haptic tick that produced this sample.
    pub tick: u64,
    /// The tool's orientation in field coordinates (the device's, for one that senses it).
    #[serde(default = "identity")]
    pub rotation: Quat,
    /// With tool-shaped contact (a device that renders force), the geometric tool's centre
    /// where it rests on the clay, field coordinates; the tool acts from there toward the tip
    /// as the hand presses. `None`: the tool acts at the tip (by its press), or it touches
    /// nothing.
    #[serde(default)]
    pub resting_at: Option<Vec3>,
    /// How hard the hand presses the resting tool: 0 (it rests, or touches nothing: the tool
    /// does nothing) to 1 (firmly: its full rate); 1 without tool-shaped contact.
    #[serde(default = "full_press")]
    pub press: f32,
    /// The force integral (field units) below which the push and the force tools do not move
    /// the clay: the clay's yield under the hand's press on a device that renders force
    /// (`haptics::ToolPressConfig::yield_n`); 0 otherwise.
    pub force_yield: f32,
    /// When the haptic tick read the device, nanoseconds of the engine's clock (the hand's
    /// time on the path to the screen, see [`super::motion_to_photon`]).
    #[serde(default)]
    pub read_ns: u64,
    /// What the haptic loop has felt of the newest stroke's first change.
    #[serde(default)]
    pub felt: FeltChange,
}

fn identity() -> Quat {
    Quat::IDENTITY
}

fn full_press() -> f32 {
    1.0
}

impl ToolSample {
    /// No tool, no stroke, time zero.
    pub const IDLE: Self = Self {
        tip_fu: Vec3::ZERO,
        force_from_fu: Vec3::ZERO,
        force_to_fu: Vec3::ZERO,
        stroke_active: false,
        in_contact: false,
        touching: false,
        device_force_n: Vec3::ZERO,
        device_time_us: 0,
        device_fault: false,
        tick: 0,
        rotation: Quat::IDENTITY,
        resting_at: None,
        press: 1.0,
        force_yield: 0.0,
        read_ns: 0,
        felt: FeltChange {
            stroke: 0,
            ticks: 0,
        },
    };
}

impl Default for ToolSample {
    fn default() -> Self {
        Self::IDLE
    }
}
