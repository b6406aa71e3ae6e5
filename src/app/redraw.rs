//! When the window draws, and what its frames cost.
//!
//! The window draws a frame only when something asks for one: input, egui's own animations,
//! the engine's wake-ups (new meshes, an answer for the log, a view that draws differently:
//! see [`super::link::RepaintSignal`] and the bridge), or work in flight whose progress the
//! engine does not announce ([`InFlight`]), which is polled at [`POLL_PERIOD`]. An idle
//! window therefore costs no frames at all.
//!
//! [`FrameStats`] keeps the figures of the status line: the last frame's time as eframe
//! measured it (the app's update and the render, without waiting for the display) and the
//! frames drawn over the last second. It takes the frame instants as arguments, so tests
//! drive it with instants of their own.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

/// How often the window looks again while something is in flight.
pub const POLL_PERIOD: Duration = Duration::from_millis(33);

/// The span over which [`FrameStats::frames_per_s`] counts frames.
const RATE_WINDOW: Duration = Duration::from_secs(1);

/// Frame instants kept at most (a window drawing faster than this per second reports this).
const MAX_FRAMES_KEPT: usize = 1000;

/// Polls without a new particle view before the particles count as settled.
pub const PARTICLE_SETTLE_POLLS: u32 = 30;

/// Work in flight that changes what the window shows without waking it, so the window polls
/// while any is on. Everything else that changes arrives with a wake-up of its own.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct InFlight {
    /// A stroke is held (by the engine's view, the left drag or the Space key).
    pub stroke: bool,
    /// The platform probe runs on its worker (its result comes back without a wake-up).
    pub probe: bool,
    /// A loaded point set still follows the clay (its view is published without a wake-up).
    pub points: bool,
    /// The particles are on and still moving.
    pub particles: bool,
    /// The SpaceMouse drives the camera (read at each frame).
    pub spacemouse: bool,
    /// A native file dialog is open (its answer comes back without a wake-up).
    pub file_dialog: bool,
}

impl InFlight {
    /// Whether anything is in flight.
    #[must_use]
    pub fn any(self) -> bool {
        self.stroke
            || self.probe
            || self.points
            || self.particles
            || self.spacemouse
            || self.file_dialog
    }

    /// When the window should look again without being woken: after [`POLL_PERIOD`] while
    /// anything is in flight, never otherwise.
    #[must_use]
    pub fn poll_after(self) -> Option<Duration> {
        self.any().then_some(POLL_PERIOD)
    }

    /// The names of what is in flight, for the status line.
    #[must_use]
    pub fn names(self) -> Vec<&'static str> {
        [
            (self.stroke, "stroke"),
            (self.probe, "probe"),
            (self.points, "point set"),
            (self.particles, "particles"),
            (self.spacemouse, "SpaceMouse"),
            (self.file_dialog, "file dialog"),
        ]
        .into_iter()
        .filter_map(|(on, name)| on.then_some(name))
        .collect()
    }
}

/// The figures of the status line: the last frame's time and the recent frame rate.
#[derive(Clone, Debug, Default)]
pub struct FrameStats {
    /// The start of each frame within [`RATE_WINDOW`] of the newest, oldest first.
    starts: VecDeque<Instant>,
    /// The last finished frame's time (update and render, no display wait), seconds.
    last_frame_s: Option<f32>,
    /// Frames recorded since the start.
    pub frames: u64,
}

impl FrameStats {
    /// Records a frame that starts at `now`; `last_frame_s` is the previous frame's time as
    /// eframe measured it (`None` on the first frame, and without eframe).
    pub fn record(&mut self, now: Instant, last_frame_s: Option<f32>) {
        self.frames += 1;
        if let Some(s) = last_frame_s.filter(|s| s.is_finite() && *s >= 0.0) {
            self.last_frame_s = Some(s);
        }
        while self
            .starts
            .front()
            .is_some_and(|t| now.saturating_duration_since(*t) >= RATE_WINDOW)
            || self.starts.len() >= MAX_FRAMES_KEPT
        {
            self.starts.pop_front();
        }
        self.starts.push_back(now);
    }

    /// The last finished frame's time, milliseconds.
    #[must_use]
    pub fn last_frame_ms(&self) -> Option<f32> {
        self.last_frame_s.map(|s| s * 1000.0)
    }

    /// Frames started within the second up to the newest one (the newest included).
    #[must_use]
    pub fn frames_per_s(&self) -> usize {
        self.starts.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nothing_in_flight_means_no_poll() {
        assert_eq!(InFlight::default().poll_after(), None);
        assert!(InFlight::default().names().is_empty());
        let probing = InFlight {
            probe: true,
            ..InFlight::default()
        };
        assert_eq!(probing.poll_after(), Some(POLL_PERIOD));
        assert_eq!(probing.names(), vec!["probe"]);
    }

    #[test]
    fn the_rate_counts_the_frames_of_the_last_second_only() {
        let t0 = Instant::now();
        let mut stats = FrameStats::default();
        // Ten frames 50 ms apart, then a pause of two seconds and one frame.
        for i in 0..10 {
            stats.record(t0 + Duration::from_millis(50 * i), Some(0.004));
        }
        assert_eq!(stats.frames_per_s(), 10);
        assert_eq!(stats.last_frame_ms(), Some(4.0));
        stats.record(t0 + Duration::from_millis(2450), None);
        assert_eq!(
            stats.frames_per_s(),
            1,
            "frames before the pause are dropped"
        );
        assert_eq!(
            stats.last_frame_ms(),
            Some(4.0),
            "a missing time keeps the last"
        );
        assert_eq!(stats.frames, 11);
        // Twenty frames in the next second: 1000 ms later the first has left the window.
        let t1 = t0 + Duration::from_millis(2450);
        for i in 1..=20 {
            stats.record(t1 + Duration::from_millis(50 * i), Some(f32::NAN));
        }
        assert_eq!(stats.frames_per_s(), 20);
        assert_eq!(
            stats.last_frame_ms(),
            Some(4.0),
            "a non-finite time is ignored"
        );
    }
}
