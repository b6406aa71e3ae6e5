//! A mouse or pen as a pose-input device: the app turns the pointer into a 3-D tool tip and
//! hands it, time-stamped, to the haptic thread through a [`PointerHandle`]; the
//! [`PointerDevice`] reads it there like any other [`HapticDevice`], so a pointer session goes
//! through the same haptic loop, safety filter, recorder and replay as an arm.
//!
//! Guarantee: the hand-over is a triple buffer (the `triple_buffer` crate) of a fixed window
//! of the last [`WINDOW`] samples: the app's [`PointerHandle::set`] and the haptic thread's
//! [`HapticDevice::read`] are each one atomic swap, bounded wait-free, never block and allocate
//! nothing after construction (the buffer holds three copies of the window, about 2 KiB). The
//! device keeps the samples it has not reached yet in a fixed ring of [`QUEUE`] knots; a read
//! does work bounded by `WINDOW + QUEUE`. No force is output.
//!
//! # The hand's path, not the frames
//!
//! A window may draw two frames a second; the haptic loop reads 1000 times a second. The
//! device does not jump from one frame's tip to the next: it plays the polyline through the
//! samples back on its own clock, each segment over the time between its two samples' stamps
//! (at least [`MIN_SEGMENT_US`], at most [`PointerConfig::max_segment_us`]), starting when the
//! segment's end arrives. So the path is reproduced exactly — every sample is passed through,
//! linearly between them — a fixed delay of one window interval behind the hand (500 ms at
//! 2 frames a second, 16 ms at 60). Extrapolating past the newest sample would cut that delay
//! but overshoot every corner and every stop; a delay keeps the stroke where it was drawn.
//! When samples arrive early (frames bunched), playback runs faster, in proportion to how much
//! more than one interval is queued (at most [`MAX_SPEEDUP`] times), so the delay does not
//! grow; when they are late, the tip waits at the newest sample.
//!
//! Buttons follow the path: a segment presses only when both its ends press, so a press
//! starts where the first pressing sample is reached and ends where the last one was.
//!
//! Time: the app's stamps and the device's reads use one [`PointerClock`]: the wall clock in
//! the window, or a clock stepped a fixed period per read for deterministic runs (lockstep,
//! tests), whose current time [`PointerHandle::set`] stamps with.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use glam::Vec3;
use triple_buffer::{Input, Output, TripleBuffer};

use crate::device::{DeviceError, DeviceInfo, DeviceState, HapticDevice};

/// Bit of [`DeviceState::buttons`] that is set while the pointer presses (a stroke).
pub const PRESS_BUTTON: u32 = 0;

/// Samples the hand-over holds: more than this many handed over between two reads (1 ms) lose
/// the oldest, and the path runs straight past them.
pub const WINDOW: usize = 16;

/// Samples the device holds ahead of its playback; past that, the newest replaces the last
/// queued one (the path runs straight past it).
pub const QUEUE: usize = 64;

/// Shortest time a segment is played over, microseconds (one haptic tick at 1 kHz): two
/// samples stamped alike are still joined by a motion, not a jump.
pub const MIN_SEGMENT_US: u64 = 1_000;

/// Most playback speed-up when samples are queued beyond one window interval.
pub const MAX_SPEEDUP: u64 = 4;

/// How many of the newest segment durations the window interval is taken over (the
/// longest of them), so one short segment (a release in the same frame) does not rush the
/// rest.
const RECENT: usize = 4;

/// What the app hands over each time the pointer moves.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointerSample {
    /// Tool tip, metres in the device frame (the app maps field coordinates there with the
    /// engine's workspace map).
    pub position_m: Vec3,
    /// Whether the pointer presses (left button held, or a pen touching).
    pub pressed: bool,
    /// Count of samples handed over (the first is 1; 0 is the resting sample).
    pub serial: u64,
    /// When the sample was taken, microseconds on the pointer's clock.
    pub time_us: u64,
}

/// The clock the app's stamps and the device's reads share.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PointerClock {
    /// Wall time (a monotonic clock) since the device was made: the window's.
    Wall,
    /// Each device read advances the clock by `period_us` and nothing else does: a
    /// deterministic run's (lockstep, tests). The handle stamps with the time of the last read.
    Stepped {
        /// Time one read advances, microseconds (at least 1).
        period_us: u64,
    },
}

/// Settings of a pointer device.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointerConfig {
    /// Lower corner of the workspace the app maps the clay into, metres.
    pub workspace_min_m: Vec3,
    /// Upper corner of that workspace, metres.
    pub workspace_max_m: Vec3,
    /// The clock of stamps and reads.
    pub clock: PointerClock,
    /// Longest time one segment is played over, microseconds: after the pointer rested
    /// without frames (a window redraws only when something changes), the next move is
    /// played over this at most, not over the whole rest. At 1 s, a window down to one
    /// frame a second keeps its strokes moving without pause.
    pub max_segment_us: u64,
}

impl Default for PointerConfig {
    /// A 20 cm cube around the origin, like a desktop arm's, on the wall clock.
    fn default() -> Self {
        Self {
            workspace_min_m: Vec3::splat(-0.1),
            workspace_max_m: Vec3::splat(0.1),
            clock: PointerClock::Wall,
            max_segment_us: 1_000_000,
        }
    }
}

impl PointerConfig {
    /// The default settings on a clock stepped `period_us` per read (deterministic runs).
    #[must_use]
    pub fn stepped(period_us: u64) -> Self {
        Self {
            clock: PointerClock::Stepped { period_us },
            ..Self::default()
        }
    }

    /// The device description the engine maps its workspace from.
    #[must_use]
    pub fn info(&self) -> DeviceInfo {
        DeviceInfo {
            name: "pointer".into(),
            dof: 3,
            // Nothing is output: these bound the contact forces the engine computes for the
            // clay, at a desktop arm's figures, so a pointer stroke sculpts like an arm's.
            max_force_n: 8.0,
            max_stiffness_n_per_m: 3000.0,
            max_damping_n_s_per_m: 20.0,
            workspace_min_m: self.workspace_min_m,
            workspace_max_m: self.workspace_max_m,
            has_orientation: false,
            has_force: false,
            button_count: 1,
            sample_rate_hz: 0.0,
        }
    }
}

/// The shared clock (see [`PointerClock`]).
#[derive(Clone, Debug)]
enum Clock {
    Wall(Instant),
    Stepped {
        period_us: u64,
        now_us: Arc<AtomicU64>,
    },
}

impl Clock {
    fn new(kind: PointerClock) -> Self {
        match kind {
            PointerClock::Wall => Self::Wall(Instant::now()),
            PointerClock::Stepped { period_us } => Self::Stepped {
                period_us: period_us.max(1),
                now_us: Arc::new(AtomicU64::new(0)),
            },
        }
    }

    /// The time now, for a stamp.
    fn now_us(&self) -> u64 {
        match self {
            Self::Wall(epoch) => epoch.elapsed().as_micros() as u64,
            // NOTE: Relaxed: the value is the whole message; nothing else is published with it.
            Self::Stepped { now_us, .. } => now_us.load(Ordering::Relaxed),
        }
    }

    /// The time of a read (a stepped clock advances first).
    fn read_us(&self) -> u64 {
        match self {
            Self::Wall(_) => self.now_us(),
            // NOTE: Relaxed, as above; only the device's thread advances it.
            Self::Stepped { period_us, now_us } => {
                now_us.fetch_add(*period_us, Ordering::Relaxed) + period_us
            }
        }
    }
}

/// The last [`WINDOW`] samples, the newest at `newest.serial % WINDOW` (plain data, copied
/// through the triple buffer).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Window {
    samples: [PointerSample; WINDOW],
    newest: u64,
}

impl Window {
    fn push(&mut self, sample: PointerSample) {
        self.samples[(sample.serial % WINDOW as u64) as usize] = sample;
        self.newest = sample.serial;
    }
}

/// The app's end: hands time-stamped tool tips to the device.
pub struct PointerHandle {
    input: Input<Window>,
    window: Window,
    last: PointerSample,
    clock: Clock,
    min_m: Vec3,
    max_m: Vec3,
}

impl PointerHandle {
    /// Publishes a new tip stamped now on the pointer's clock (clamped to the workspace; a
    /// non-finite position keeps the previous one) and whether the pointer presses.
    /// Wait-free.
    pub fn set(&mut self, position_m: Vec3, pressed: bool) {
        let now = self.clock.now_us();
        self.set_at(position_m, pressed, now);
    }

    /// As [`Self::set`], stamped `time_us` on the pointer's clock (see [`Self::now_us`]); a
    /// stamp before the previous one counts as the same time. Wait-free.
    pub fn set_at(&mut self, position_m: Vec3, pressed: bool, time_us: u64) {
        let position_m = if position_m.is_finite() {
            position_m.clamp(self.min_m, self.max_m)
        } else {
            self.last.position_m
        };
        self.last = PointerSample {
            position_m,
            pressed,
            serial: self.last.serial + 1,
            time_us: time_us.max(self.last.time_us),
        };
        self.window.push(self.last);
        *self.input.input_buffer_mut() = self.window;
        self.input.publish();
    }

    /// The time now on the pointer's clock, microseconds.
    #[must_use]
    pub fn now_us(&self) -> u64 {
        self.clock.now_us()
    }

    /// The last sample handed over.
    #[must_use]
    pub fn last(&self) -> PointerSample {
        self.last
    }
}

/// One queued sample: where the path goes next, and over how long.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Knot {
    position_m: Vec3,
    pressed: bool,
    /// Time the segment from the previous knot to this one is played over, microseconds.
    duration_us: u64,
}

impl Knot {
    const REST: Self = Self {
        position_m: Vec3::ZERO,
        pressed: false,
        duration_us: 0,
    };
}

/// The haptic thread's end: a [`HapticDevice`] whose pose is the app's pointer, played back
/// along its path (see the module's docs).
pub struct PointerDevice {
    config: PointerConfig,
    output: Output<Window>,
    clock: Clock,
    /// Clock time at `open`.
    opened_at_us: Option<u64>,
    /// Clock time of the previous read.
    last_read_us: u64,
    /// Serial and stamp of the newest sample taken from the window.
    last_serial: u64,
    last_stamp_us: Option<u64>,
    /// The knot playback has reached (the start of the current segment).
    from: Knot,
    /// Knots not reached yet, the first at `head`.
    queue: [Knot; QUEUE],
    head: usize,
    len: usize,
    /// Time played into the first queued segment, microseconds.
    progress_us: u64,
    /// Durations of the newest segments (ring), for the window interval.
    recent_us: [u64; RECENT],
    recent_next: usize,
    state: DeviceState,
}

/// A connected device and handle; the device rests at the workspace centre until the first
/// [`PointerHandle::set`].
#[must_use]
pub fn pointer_device(config: PointerConfig) -> (PointerDevice, PointerHandle) {
    let centre = (config.workspace_min_m + config.workspace_max_m) * 0.5;
    let first = PointerSample {
        position_m: centre,
        pressed: false,
        serial: 0,
        time_us: 0,
    };
    let window = Window {
        samples: [first; WINDOW],
        newest: 0,
    };
    let clock = Clock::new(config.clock);
    let (input, output) = TripleBuffer::new(&window).split();
    let handle = PointerHandle {
        input,
        window,
        last: first,
        clock: clock.clone(),
        min_m: config.workspace_min_m.min(config.workspace_max_m),
        max_m: config.workspace_min_m.max(config.workspace_max_m),
    };
    let device = PointerDevice {
        config,
        output,
        clock,
        opened_at_us: None,
        last_read_us: 0,
        last_serial: 0,
        last_stamp_us: None,
        from: Knot {
            position_m: centre,
            ..Knot::REST
        },
        queue: [Knot::REST; QUEUE],
        head: 0,
        len: 0,
        progress_us: 0,
        recent_us: [0; RECENT],
        recent_next: 0,
        state: DeviceState {
            position_m: centre,
            ..DeviceState::ZERO
        },
    };
    (device, handle)
}

impl PointerDevice {
    /// Takes the samples handed over since the last read into the queue.
    fn take_samples(&mut self) {
        let window = *self.output.read();
        if window.newest <= self.last_serial {
            return;
        }
        let oldest_held = window.newest.saturating_sub(WINDOW as u64 - 1).max(1);
        for serial in (self.last_serial + 1).max(oldest_held)..=window.newest {
            let sample = window.samples[(serial % WINDOW as u64) as usize];
            self.enqueue(sample);
        }
        self.last_serial = window.newest;
    }

    fn enqueue(&mut self, sample: PointerSample) {
        let knot = |duration_us| Knot {
            position_m: sample.position_m,
            pressed: sample.pressed,
            duration_us,
        };
        let Some(previous_us) = self.last_stamp_us else {
            // The first sample: the tip is there (nothing to come from).
            self.last_stamp_us = Some(sample.time_us);
            self.from = knot(0);
            self.len = 0;
            self.progress_us = 0;
            return;
        };
        let duration_us = sample.time_us.saturating_sub(previous_us).clamp(
            MIN_SEGMENT_US,
            self.config.max_segment_us.max(MIN_SEGMENT_US),
        );
        self.last_stamp_us = Some(sample.time_us.max(previous_us));
        self.recent_us[self.recent_next] = duration_us;
        self.recent_next = (self.recent_next + 1) % RECENT;
        if self.len == QUEUE {
            // Full: the newest replaces the last queued knot, over both their times.
            let last = &mut self.queue[(self.head + QUEUE - 1) % QUEUE];
            *last = knot(last.duration_us + duration_us);
            return;
        }
        self.queue[(self.head + self.len) % QUEUE] = knot(duration_us);
        self.len += 1;
    }

    /// Plays the path on by `dt_us` of device time.
    fn advance(&mut self, dt_us: u64) {
        if self.len == 0 {
            return;
        }
        let queued_us = (0..self.len)
            .map(|i| self.queue[(self.head + i) % QUEUE].duration_us)
            .sum::<u64>()
            .saturating_sub(self.progress_us);
        let interval_us = self.recent_us.iter().copied().max().unwrap_or(0).max(1);
        // Speed 1 with one interval queued; faster in proportion beyond that.
        let mut budget_us = if queued_us > interval_us {
            (u128::from(dt_us) * u128::from(queued_us) / u128::from(interval_us))
                .min(u128::from(dt_us.saturating_mul(MAX_SPEEDUP))) as u64
        } else {
            dt_us
        };
        while self.len > 0 && budget_us > 0 {
            let head = self.queue[self.head];
            let left_us = head.duration_us - self.progress_us;
            if budget_us >= left_us {
                budget_us -= left_us;
                self.from = head;
                self.head = (self.head + 1) % QUEUE;
                self.len -= 1;
                self.progress_us = 0;
            } else {
                self.progress_us += budget_us;
                budget_us = 0;
            }
        }
    }

    /// The tip and whether it presses, where playback is.
    fn playback(&self) -> (Vec3, bool) {
        if self.len == 0 {
            return (self.from.position_m, self.from.pressed);
        }
        let to = self.queue[self.head];
        let s = self.progress_us as f32 / to.duration_us as f32;
        // NOTE: `from + (to − from)·s`, not a weighted sum: a coordinate the segment keeps
        // stays bit-exact, and s = 0 is exactly the knot reached.
        (
            self.from.position_m + (to.position_m - self.from.position_m) * s,
            self.from.pressed && to.pressed,
        )
    }
}

impl HapticDevice for PointerDevice {
    fn info(&self) -> DeviceInfo {
        self.config.info()
    }

    fn open(&mut self) -> Result<(), DeviceError> {
        if self.opened_at_us.is_none() {
            let now = self.clock.now_us();
            self.opened_at_us = Some(now);
            self.last_read_us = now;
        }
        Ok(())
    }

    fn close(&mut self) -> Result<(), DeviceError> {
        self.opened_at_us = None;
        Ok(())
    }

    fn is_open(&self) -> bool {
        self.opened_at_us.is_some()
    }

    fn read(&mut self) -> Result<DeviceState, DeviceError> {
        let Some(opened_at_us) = self.opened_at_us else {
            return Err(DeviceError::NotOpen);
        };
        let now_us = self.clock.read_us();
        let dt_us = now_us.saturating_sub(self.last_read_us);
        self.last_read_us = now_us;
        self.take_samples();
        self.advance(dt_us);
        let (position_m, pressed) = self.playback();
        let buttons = u32::from(pressed) << PRESS_BUTTON;
        let timestamp_us = now_us.saturating_sub(opened_at_us);
        let dt_s = timestamp_us.saturating_sub(self.state.timestamp_us) as f32 * 1e-6;
        let velocity_m_per_s = if self.state.sequence > 0 && dt_s > 0.0 {
            (position_m - self.state.position_m) / dt_s
        } else {
            Vec3::ZERO
        };
        let resting = position_m == self.state.position_m
            && buttons == self.state.buttons
            && self.state.velocity_m_per_s == Vec3::ZERO;
        if resting {
            // Nothing new: the same sample again.
            return Ok(self.state);
        }
        self.state = DeviceState {
            position_m,
            orientation: None,
            velocity_m_per_s,
            buttons,
            timestamp_us,
            sequence: self.state.sequence + 1,
        };
        Ok(self.state)
    }

    fn write_force(&mut self, _force_n: Vec3) -> Result<(), DeviceError> {
        if self.opened_at_us.is_none() {
            return Err(DeviceError::NotOpen);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A device and handle on a 1 ms stepped clock, opened.
    fn stepped() -> (PointerDevice, PointerHandle) {
        let (mut dev, handle) = pointer_device(PointerConfig::stepped(1_000));
        dev.open().unwrap();
        (dev, handle)
    }

    #[test]
    fn the_device_reads_what_the_handle_set_and_repeats_it_until_the_next() {
        let (mut dev, mut handle) = pointer_device(PointerConfig::stepped(1_000));
        assert_eq!(dev.read(), Err(DeviceError::NotOpen));
        dev.open().unwrap();
        let rest = dev.read().unwrap();
        assert_eq!(rest.position_m, Vec3::ZERO);
        assert_eq!(rest.sequence, 0);
        // The first sample is where the tip is.
        handle.set(Vec3::new(0.01, 0.02, 0.03), true);
        let s = dev.read().unwrap();
        assert_eq!(s.position_m, Vec3::new(0.01, 0.02, 0.03));
        assert!(s.button(PRESS_BUTTON));
        assert_eq!(s.sequence, 1);
        let again = dev.read().unwrap();
        assert_eq!(again, s, "no new sample: the same state, same sequence");
        // A NaN keeps the tip (the sample is played as a rest there).
        handle.set(Vec3::new(5.0, 0.0, f32::NAN), true);
        for _ in 0..3 {
            assert_eq!(dev.read().unwrap().position_m, Vec3::new(0.01, 0.02, 0.03));
        }
        // Clamped to the workspace, reached after its segment's time.
        handle.set(Vec3::new(5.0, 0.0, 0.0), false);
        let mut s = dev.read().unwrap();
        for _ in 0..20 {
            s = dev.read().unwrap();
        }
        assert_eq!(s.position_m, Vec3::new(0.1, 0.0, 0.0), "clamped");
        assert!(!s.button(PRESS_BUTTON));
        assert!(dev.write_force(Vec3::X).is_ok());
        assert!(!dev.info().has_force);
        dev.close().unwrap();
        assert_eq!(dev.write_force(Vec3::X), Err(DeviceError::NotOpen));
    }

    /// Samples 500 ms apart (2 frames a second) along a line: at 1 kHz the device moves by
    /// the same small step every read, passes through every sample exactly, one interval
    /// behind, and presses from the first pressing sample to the last.
    #[test]
    fn samples_at_two_hertz_are_played_as_a_steady_motion_one_interval_behind() {
        let (mut dev, mut handle) = stepped();
        let at = |k: u64| Vec3::new(-0.08 + 0.02 * k as f32, 0.01, 0.0);
        let mut reads = Vec::new();
        for tick in 0..5_600u64 {
            if tick % 500 == 0 && tick <= 4_500 {
                let k = tick / 500;
                // Hover over the first point, press from the second sample to the eighth.
                handle.set(at(k), (1..=7).contains(&k));
            }
            reads.push(dev.read().unwrap());
        }
        // Every read while moving moves 0.02 / 500 along x, nothing across.
        let step = 0.02 / 500.0;
        for w in reads[1000..4500].windows(2) {
            let dx = w[1].position_m.x - w[0].position_m.x;
            assert!((dx - step).abs() < 1e-6, "step {dx} at {:?}", w[1]);
            assert_eq!(w[1].position_m.y, 0.01);
            assert_eq!(w[1].sequence, w[0].sequence + 1);
            assert!((w[1].velocity_m_per_s.x - 0.04).abs() < 1e-3);
        }
        // Sample k (stamped at 500k ms) is reached at 500(k + 1) ms, exactly.
        for k in 1..9u64 {
            let read = reads[(500 * (k + 1)) as usize - 1];
            assert!(
                (read.position_m - at(k)).length() < 1e-6,
                "sample {k}: {} vs {}",
                read.position_m,
                at(k)
            );
        }
        // Pressed on the segments between pressing samples 1..=7: from 1 s to 4 s.
        let pressed: Vec<bool> = reads.iter().map(|r| r.button(PRESS_BUTTON)).collect();
        assert!(!pressed[998] && pressed[999], "press starts at sample 1");
        assert!(pressed[3998] && !pressed[4000], "press ends at sample 7");
        // At rest after the last sample (reached at 5 s): once more with no velocity, then
        // the same state again.
        assert!((reads[4999].position_m - at(9)).length() < 1e-6);
        assert_eq!(reads[5000].velocity_m_per_s, Vec3::ZERO);
        assert_eq!(reads[5000].sequence, reads[4999].sequence + 1);
        assert_eq!(reads[5001], reads[5000]);
    }

    /// Bunched samples speed playback up so the delay stays about one interval, and a long
    /// rest without samples is played over `max_segment_us` at most.
    #[test]
    fn bunched_and_late_samples_keep_the_delay_bounded_and_the_path_continuous() {
        let (mut dev, mut handle) = stepped();
        handle.set(Vec3::ZERO, false);
        dev.read().unwrap();
        // Ten samples stamped 100 ms apart, all handed over at once (a stalled app).
        for k in 1..=10u64 {
            handle.set_at(Vec3::new(0.005 * k as f32, 0.0, 0.0), false, 100_000 * k);
        }
        let mut ticks = 0;
        let mut last = dev.read().unwrap().position_m;
        while last.x < 0.05 - 1e-6 {
            let p = dev.read().unwrap().position_m;
            assert!((p - last).length() <= 0.005 * 4.0 / 100.0 + 1e-6, "a jump");
            last = p;
            ticks += 1;
            assert!(ticks < 1_000, "playback did not catch up");
        }
        // 1 s of path played faster than real time (at most 4×).
        assert!((250..1_000).contains(&ticks), "{ticks} ticks");
        // A 30 s rest, then one move: played over 1 s, not 30.
        let rest = handle.last().time_us;
        handle.set_at(Vec3::new(0.05, 0.05, 0.0), false, rest + 30_000_000);
        let mut reads = 0;
        while dev.read().unwrap().position_m.y < 0.05 - 1e-6 {
            reads += 1;
        }
        assert!((990..=1_001).contains(&reads), "{reads} reads");
    }

    /// More samples than the window holds between two reads: the oldest are lost and the
    /// path runs straight on from where it was to the oldest one kept, without a jump.
    #[test]
    fn a_flood_of_samples_between_two_reads_keeps_the_path_continuous() {
        let (mut dev, mut handle) = stepped();
        handle.set(Vec3::ZERO, false);
        dev.read().unwrap();
        for k in 1..=40u64 {
            handle.set_at(Vec3::new(0.0, -0.001 * k as f32, 0.0), false, 10_000 * k);
        }
        let mut last = dev.read().unwrap().position_m;
        for _ in 0..600 {
            let p = dev.read().unwrap().position_m;
            assert!((p - last).length() < 0.0005, "a jump: {last} → {p}");
            assert_eq!(p.x, 0.0, "off the line");
            last = p;
        }
        assert!((last.y + 0.04).abs() < 1e-6, "ends at the newest sample");
    }

    /// The wall clock: stamps and reads on one monotonic clock, nothing else changes.
    #[test]
    fn on_the_wall_clock_the_newest_sample_is_reached() {
        let (mut dev, mut handle) = pointer_device(PointerConfig::default());
        dev.open().unwrap();
        handle.set(Vec3::ZERO, false);
        handle.set(Vec3::new(0.01, 0.0, 0.0), true);
        let start = Instant::now();
        loop {
            let s = dev.read().unwrap();
            if s.position_m == Vec3::new(0.01, 0.0, 0.0) {
                assert!(s.button(PRESS_BUTTON));
                break;
            }
            assert!(
                start.elapsed().as_secs() < 10,
                "never reached: {}",
                s.position_m
            );
            std::thread::sleep(std::time::Duration::from_micros(200));
        }
    }
}
