//! Haptic device layer (no geometry beyond glam vectors).
