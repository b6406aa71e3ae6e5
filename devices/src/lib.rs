//! Haptic device layer for dynaclay: one [`HapticDevice`] trait, the safety filter every force
//! passes through, the simulated reference arm, hardware drivers, and record/replay.
//!
//! Knows no geometry beyond glam vectors. Everything called on the haptic path (`read`,
//! `write_force`, the filter) allocates nothing and does bounded work after `open`.

pub mod device;
pub mod record;
pub mod safety;
pub mod sim_arm;

pub use device::{DeviceError, DeviceInfo, DeviceState, HapticDevice};
pub use safety::{SafetyConfig, SafetyCounters, SafetyFilter, soft_start_gain};
