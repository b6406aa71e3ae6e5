//! The window's pointer (a mouse, or a pen with its pressure) as a 3-DoF tool with no force
//! output: the application places the tip, this device hands it to the haptic loop.
//!
//! Guarantee: [`PointerFeed::set`] (the window's thread) and [`PointerDevice::read`] (the
//! haptic thread) are wait-free and allocate nothing. The pose travels through a sequence lock
//! made of atomics only: the writer bumps the sequence to odd, stores the fields, bumps it to
//! even; the reader copies the fields between two loads of an even, unchanged sequence, and
//! after a bounded number of torn attempts keeps the pose it read last. So a reader never
//! waits for the writer, and never sees a half-written pose.
//!
//! The device enters the engine the way an arm does (haptic loop, safety filter, recorder,
//! replay), so a mouse session records and replays bit for bit: the recording holds the
//! poses and device times the haptic loop read.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, Ordering};
use std::time::Instant;

use glam::Vec3;

use crate::device::{DeviceError, DeviceInfo, DeviceState, HapticDevice};

/// How many torn reads [`PointerDevice::read`] retries before keeping the previous pose.
const READ_ATTEMPTS: u32 = 4;

/// One pose of the pointer tool, in device metres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointerPose {
    /// Tip position, device metres.
    pub position_m: Vec3,
    /// Buttons: bit 0 while a stroke is held.
    pub buttons: u32,
}

/// The shared slot between the window and the pointer device (cheap to clone: an `Arc`).
#[derive(Clone, Debug, Default)]
pub struct PointerFeed {
    cells: Arc<Cells>,
}

#[derive(Debug, Default)]
struct Cells {
    /// Even: stable; odd: a write is in progress. Counts writes × 2.
    sequence: AtomicU64,
    x: AtomicU32,
    y: AtomicU32,
    z: AtomicU32,
    buttons: AtomicU32,
    /// Set by the device while it is open (the window shows whether anything listens).
    listening: AtomicBool,
}

impl PointerFeed {
    /// A feed at the origin, no button.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// Publishes a pose (one writer: the window's thread). Wait-free.
    pub fn set(&self, pose: PointerPose) {
        let c = &self.cells;
        let s = c.sequence.load(Ordering::Relaxed);
        // NOTE: Release on the odd store would not order the field stores after it; the
        // fence below does (the seqlock pattern: odd, fence, fields, even with Release).
        c.sequence.store(s.wrapping_add(1), Ordering::Relaxed);
        std::sync::atomic::fence(Ordering::Release);
        c.x.store(pose.position_m.x.to_bits(), Ordering::Relaxed);
        c.y.store(pose.position_m.y.to_bits(), Ordering::Relaxed);
        c.z.store(pose.position_m.z.to_bits(), Ordering::Relaxed);
        c.buttons.store(pose.buttons, Ordering::Relaxed);
        // NOTE: Release, so a reader that sees this even sequence (Acquire) sees the fields.
        c.sequence.store(s.wrapping_add(2), Ordering::Release);
    }

    /// The latest pose and the number of poses published so far, or `None` when a write was
    /// in progress on every attempt. Wait-free: at most [`READ_ATTEMPTS`] tries.
    #[must_use]
    pub fn get(&self) -> Option<(PointerPose, u64)> {
        let c = &self.cells;
        for _ in 0..READ_ATTEMPTS {
            // NOTE: Acquire pairs with the writer's final Release store.
            let before = c.sequence.load(Ordering::Acquire);
            if before % 2 == 1 {
                std::hint::spin_loop();
                continue;
            }
            let pose = PointerPose {
                position_m: Vec3::new(
                    f32::from_bits(c.x.load(Ordering::Relaxed)),
                    f32::from_bits(c.y.load(Ordering::Relaxed)),
                    f32::from_bits(c.z.load(Ordering::Relaxed)),
                ),
                buttons: c.buttons.load(Ordering::Relaxed),
            };
            // NOTE: the Acquire fence keeps the field loads above before the second sequence
            // load, so an unchanged sequence proves they were not torn.
            std::sync::atomic::fence(Ordering::Acquire);
            if c.sequence.load(Ordering::Relaxed) == before {
                return Some((pose, before / 2));
            }
        }
        None
    }

    /// Whether an open pointer device reads this feed.
    #[must_use]
    pub fn is_listening(&self) -> bool {
        self.cells.listening.load(Ordering::Relaxed)
    }
}

/// The pointer as a [`HapticDevice`]: 3-DoF, one button, no force output (forces written to
/// it are accepted and dropped).
#[derive(Debug)]
pub struct PointerDevice {
    feed: PointerFeed,
    info: DeviceInfo,
    opened_at: Option<Instant>,
    last: PointerPose,
}

impl PointerDevice {
    /// A pointer tool reading `feed`, whose poses lie in the workspace box `min_m`..`max_m`.
    #[must_use]
    pub fn new(feed: PointerFeed, min_m: Vec3, max_m: Vec3) -> Self {
        Self {
            feed,
            info: DeviceInfo {
                name: "pointer".to_owned(),
                dof: 3,
                max_force_n: 0.0,
                max_stiffness_n_per_m: 0.0,
                max_damping_n_s_per_m: 0.0,
                workspace_min_m: min_m,
                workspace_max_m: max_m,
                has_orientation: false,
                has_force: false,
                button_count: 1,
                sample_rate_hz: 1000.0,
            },
            opened_at: None,
            last: PointerPose {
                position_m: (min_m + max_m) * 0.5,
                buttons: 0,
            },
        }
    }
}

impl HapticDevice for PointerDevice {
    fn info(&self) -> DeviceInfo {
        self.info.clone()
    }

    fn open(&mut self) -> Result<(), DeviceError> {
        self.opened_at = Some(Instant::now());
        self.feed.cells.listening.store(true, Ordering::Relaxed);
        Ok(())
    }

    fn close(&mut self) -> Result<(), DeviceError> {
        self.opened_at = None;
        self.feed.cells.listening.store(false, Ordering::Relaxed);
        Ok(())
    }

    fn is_open(&self) -> bool {
        self.opened_at.is_some()
    }

    fn read(&mut self) -> Result<DeviceState, DeviceError> {
        let Some(opened) = self.opened_at else {
            return Err(DeviceError::NotOpen);
        };
        let (pose, sequence) = match self.feed.get() {
            Some((pose, n)) if pose.position_m.is_finite() => (pose, n),
            // Torn on every attempt, or a non-finite pose: keep the last good one.
            _ => (self.last, 0),
        };
        self.last = pose;
        let timestamp_us = u64::try_from(opened.elapsed().as_micros()).unwrap_or(u64::MAX);
        Ok(DeviceState {
            position_m: pose.position_m,
            orientation: None,
            velocity_m_per_s: Vec3::ZERO,
            buttons: pose.buttons,
            timestamp_us,
            sequence,
        })
    }

    fn write_force(&mut self, _force_n: Vec3) -> Result<(), DeviceError> {
        if self.opened_at.is_none() {
            return Err(DeviceError::NotOpen);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_device_reads_what_the_window_set() {
        let feed = PointerFeed::new();
        let mut d = PointerDevice::new(feed.clone(), Vec3::splat(-0.1), Vec3::splat(0.1));
        assert!(matches!(d.read(), Err(DeviceError::NotOpen)));
        d.open().unwrap();
        assert!(feed.is_listening());
        let first = d.read().unwrap();
        assert_eq!(
            first.position_m,
            Vec3::ZERO,
            "starts at the workspace centre"
        );
        let pose = PointerPose {
            position_m: Vec3::new(0.01, 0.02, -0.03),
            buttons: 1,
        };
        feed.set(pose);
        let s = d.read().unwrap();
        assert_eq!(
            (s.position_m, s.buttons, s.sequence),
            (pose.position_m, 1, 1)
        );
        // Non-finite poses are not passed on.
        feed.set(PointerPose {
            position_m: Vec3::NAN,
            buttons: 0,
        });
        assert_eq!(d.read().unwrap().position_m, pose.position_m);
        d.write_force(Vec3::X).unwrap();
        d.close().unwrap();
        assert!(!feed.is_listening());
    }

    #[test]
    fn a_reader_never_sees_a_torn_pose() {
        let feed = PointerFeed::new();
        let writer = feed.clone();
        let stop = Arc::new(AtomicBool::new(false));
        let done = Arc::clone(&stop);
        let t = std::thread::spawn(move || {
            let mut i = 0u32;
            while !done.load(Ordering::Relaxed) {
                let v = (i % 1000) as f32;
                // Every field carries the same value: a torn read would mix two.
                writer.set(PointerPose {
                    position_m: Vec3::splat(v),
                    buttons: i % 1000,
                });
                i = i.wrapping_add(1);
                std::thread::yield_now();
            }
        });
        let mut reads = 0;
        for _ in 0..200_000 {
            if let Some((p, _)) = feed.get() {
                let v = p.position_m.x;
                assert!(p.position_m.y == v && p.position_m.z == v && p.buttons as f32 == v);
                reads += 1;
            }
        }
        stop.store(true, Ordering::Relaxed);
        t.join().unwrap();
        assert!(reads > 0);
    }
}
