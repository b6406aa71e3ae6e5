//! One model of a device link's health, shared by every driver that streams frames: when the
//! last good frame came, whether the link is dead, and what a read reports after a silence.
//!
//! The states: *live* (a frame within `stale_after`), *silent* (no frame for longer: each
//! read reports [`DeviceError::Timeout`] with how long, and the driver may probe the link),
//! and *dead* (the other side hung up: every call reports [`DeviceError::Disconnected`] until
//! the link is opened again). Time is passed in, never read here, so the machine is tested
//! on an injected clock.

use std::time::{Duration, Instant};

use crate::device::DeviceError;

/// A streaming link's health (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LinkHealth {
    stale_after: Duration,
    last_frame: Instant,
    dead: bool,
}

impl LinkHealth {
    /// A live link opened at `now`, silent after `stale_after` without a frame.
    #[must_use]
    pub fn new(stale_after: Duration, now: Instant) -> Self {
        Self {
            stale_after,
            last_frame: now,
            dead: false,
        }
    }

    /// Starts over as a live link at `now` (the link was opened again, or closed).
    pub fn restart(&mut self, now: Instant) {
        self.last_frame = now;
        self.dead = false;
    }

    /// A good frame arrived at `now`.
    pub fn frame(&mut self, now: Instant) {
        self.last_frame = now;
    }

    /// The other side hung up: the link stays dead until [`LinkHealth::restart`].
    pub fn hung_up(&mut self) {
        self.dead = true;
    }

    /// Notes `error` from the link: a [`DeviceError::Disconnected`] makes it dead. Returns
    /// the error, for `map_err`.
    pub fn note(&mut self, error: DeviceError) -> DeviceError {
        if error == DeviceError::Disconnected {
            self.dead = true;
        }
        error
    }

    /// Whether the other side has hung up.
    #[must_use]
    pub fn is_dead(&self) -> bool {
        self.dead
    }

    /// The error a call reports on a dead link.
    ///
    /// # Errors
    /// [`DeviceError::Disconnected`] once the link is dead.
    pub fn alive(&self) -> Result<(), DeviceError> {
        if self.dead {
            Err(DeviceError::Disconnected)
        } else {
            Ok(())
        }
    }

    /// What a read at `now` reports about the link. After `stale_after` without a frame it
    /// asks `hung_up` whether the other side has gone (a zero-wait probe of the link): then
    /// the link is dead; otherwise the silence is a timeout, and the next frame ends it.
    ///
    /// # Errors
    /// [`DeviceError::Disconnected`] on a dead link, [`DeviceError::Timeout`] (with the time
    /// since the last frame) on a silent one.
    pub fn check(
        &mut self,
        now: Instant,
        hung_up: impl FnOnce() -> bool,
    ) -> Result<(), DeviceError> {
        self.alive()?;
        let silent = now.saturating_duration_since(self.last_frame);
        if silent <= self.stale_after {
            return Ok(());
        }
        if hung_up() {
            self.dead = true;
            return Err(DeviceError::Disconnected);
        }
        Err(DeviceError::Timeout {
            waited_us: silent.as_micros() as u64,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: Duration = Duration::from_millis(1);

    #[test]
    fn a_silence_is_a_timeout_until_the_next_frame() {
        let t0 = Instant::now();
        let mut h = LinkHealth::new(50 * MS, t0);
        assert_eq!(
            h.check(t0 + 50 * MS, || panic!("no probe while live")),
            Ok(())
        );
        assert_eq!(
            h.check(t0 + 80 * MS, || false),
            Err(DeviceError::Timeout { waited_us: 80_000 })
        );
        h.frame(t0 + 81 * MS);
        assert_eq!(h.check(t0 + 90 * MS, || panic!("live again")), Ok(()));
        assert!(!h.is_dead());
    }

    #[test]
    fn a_hang_up_is_dead_until_restart() {
        let t0 = Instant::now();
        let mut h = LinkHealth::new(50 * MS, t0);
        assert_eq!(
            h.check(t0 + 60 * MS, || true),
            Err(DeviceError::Disconnected)
        );
        // Dead: a frame does not revive it, and no probe is made.
        h.frame(t0 + 61 * MS);
        assert_eq!(
            h.check(t0 + 62 * MS, || panic!("no probe when dead")),
            Err(DeviceError::Disconnected)
        );
        assert_eq!(h.alive(), Err(DeviceError::Disconnected));
        h.restart(t0 + 100 * MS);
        assert_eq!(h.check(t0 + 120 * MS, || true), Ok(()));
    }

    #[test]
    fn a_disconnect_from_the_link_kills_it_and_other_errors_do_not() {
        let mut h = LinkHealth::new(50 * MS, Instant::now());
        let e = h.note(DeviceError::Timeout { waited_us: 5 });
        assert_eq!(e, DeviceError::Timeout { waited_us: 5 });
        assert!(!h.is_dead());
        assert_eq!(h.note(DeviceError::Disconnected), DeviceError::Disconnected);
        assert!(h.is_dead());
    }
}
