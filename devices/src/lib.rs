//! Haptic device layer for dynaclay: one [`HapticDevice`] trait, the safety filter every force
//! passes through, the simulated reference arm, hardware drivers, and record/replay.
//!
//! Knows no geometry beyond glam vectors. Everything called on the haptic path (`read`,
//! `write_force`, the filter) allocates nothing and does bounded work after `open`.

#![deny(unsafe_op_in_unsafe_fn)]
#![warn(clippy::undocumented_unsafe_blocks)]
#![warn(missing_docs)]

pub mod device;
pub mod record;
pub mod safety;
pub mod sim_arm;

pub use device::{DeviceError, DeviceInfo, DeviceState, HapticDevice};
pub use record::{
    RecordError, RecorderConfig, Recording, RecordingDevice, ReplayDevice, ReplayDivergence,
};
pub use safety::{SafetyConfig, SafetyCounters, SafetyFilter, soft_start_gain};
pub use sim_arm::{
    Fault, FaultKind, HandSample, Interpolation, SimArmConfig, SimArmCounters, SimRng,
    SimulatedArm, Trajectory, TrajectoryError, Waypoint,
};

// Hardware drivers, their protocol codecs, kinematics, profiles, enumeration and device specs.
pub mod arm_link;
pub mod codec;
pub mod delta;
pub mod dhd_arm;
pub mod doctor;
pub mod enumerate;
pub mod falcon;
pub mod ftdi_latency;
pub mod hid_arm;
pub mod hid_link;
pub mod inverse3;
pub mod kinematics;
mod kinematics_error;
pub mod link_health;
mod node_access;
pub mod node_holders;
pub mod open;
pub mod openhaptics_arm;
pub mod pantograph;
pub mod pointer;
pub mod pose_input;
pub mod profile;
pub mod serial_arm;
pub mod serial_link;
pub mod spacemouse;
pub mod spec;
pub mod two_diy;
pub mod usb_ids;
pub mod velocity;
pub mod vendor_lib;
