//! Haptic device layer (no geometry beyond glam vectors).
pub mod codec;
pub mod delta;
pub mod kinematics;
pub mod profile;
