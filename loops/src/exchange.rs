//! Versioned, time-stamped triple-buffer exchange between one writer thread and one reader thread.
//!
//! Guarantee: after construction, [`SnapshotWriter::publish`] and [`SnapshotReader::latest`] are
//! bounded wait-free (one atomic swap each, from the `triple_buffer` crate), never block, never
//! allocate, and never run user `Drop` code. The reader always sees a whole snapshot: the payload,
//! its version and its time stamp were written together into one buffer before that buffer was
//! published, so they cannot tear. Versions are strictly increasing (1, 2, 3, … ; the initial
//! value carries version 0); a slow reader skips versions, never goes back.
//!
//! Cost: three copies of `Stamped<T>` live for as long as either end does (the last end dropped
//! frees them, on whichever thread drops it). A payload that owns heap memory (a `Vec`) keeps it:
//! writers fill the back buffer in place, so after the first round through all three buffers no
//! publish needs to allocate.

use std::time::{Duration, Instant};

use triple_buffer::{Input, Output, TripleBuffer};

/// A payload with the version and the time at which it was published.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Stamped<T> {
    /// 0 for the initial value, then 1, 2, 3, … in publication order.
    pub version: u64,
    /// When the writer published this value (for the initial value: when the channel was made).
    pub published_at: Instant,
    /// The data.
    pub value: T,
}

impl<T> Stamped<T> {
    /// Age of this snapshot at `now`; zero if `now` is earlier than the publication time.
    #[must_use]
    pub fn age_at(&self, now: Instant) -> Duration {
        now.saturating_duration_since(self.published_at)
    }

    /// Age of this snapshot now (reads the clock).
    #[must_use]
    pub fn age(&self) -> Duration {
        self.age_at(Instant::now())
    }

    /// True for the channel's initial value, which no writer has published.
    #[must_use]
    pub fn is_initial(&self) -> bool {
        self.version == 0
    }
}

/// Creates a snapshot channel whose three buffers all start as clones of `initial` (version 0).
///
/// Clone `initial` with its final capacity (for example a `Vec` already sized to the largest
/// region) so that later in-place writes never grow it.
///
/// # Examples
/// ```
/// let (mut tx, mut rx) = dynaclay_loops::snapshot_channel(&[0.0f32; 4]);
/// tx.back_mut().fill(1.5);
/// let version = tx.publish();
/// let snap = rx.latest();
/// assert_eq!((snap.version, snap.value), (version, [1.5; 4]));
/// ```
#[must_use]
pub fn snapshot_channel<T: Clone + Send>(initial: &T) -> (SnapshotWriter<T>, SnapshotReader<T>) {
    let now = Instant::now();
    let stamped = Stamped {
        version: 0,
        published_at: now,
        value: initial.clone(),
    };
    let (input, output) = TripleBuffer::new(&stamped).split();
    (
        SnapshotWriter {
            input,
            last_version: 0,
            overwritten_unread: 0,
        },
        SnapshotReader {
            output,
            last_seen_version: 0,
        },
    )
}

/// The writing end: fill the back buffer in place, then publish it.
pub struct SnapshotWriter<T: Send> {
    input: Input<Stamped<T>>,
    last_version: u64,
    overwritten_unread: u64,
}

impl<T: Send> SnapshotWriter<T> {
    /// The back buffer, to be filled in place before [`publish`](Self::publish).
    ///
    /// Its contents are NOT the last published value: it holds whatever snapshot the triple
    /// buffer recycled (an older version, or the initial value). Overwrite every field the reader
    /// relies on, or use [`publish_clone_of`](Self::publish_clone_of) for a full copy.
    pub fn back_mut(&mut self) -> &mut T {
        &mut self.input.input_buffer_mut().value
    }

    /// Publishes the back buffer with the next version and the current time; returns that
    /// version. Wait-free, allocation-free.
    pub fn publish(&mut self) -> u64 {
        self.publish_at(Instant::now())
    }

    /// As [`publish`](Self::publish), with a caller-supplied time stamp (a loop that already
    /// read the clock this tick saves a clock read).
    pub fn publish_at(&mut self, now: Instant) -> u64 {
        self.last_version += 1;
        let back = self.input.input_buffer_mut();
        back.version = self.last_version;
        back.published_at = now;
        if self.input.publish() {
            self.overwritten_unread += 1;
        }
        self.last_version
    }

    /// Fills the back buffer with `fill` and publishes it; returns the new version.
    pub fn write_with(&mut self, fill: impl FnOnce(&mut T)) -> u64 {
        fill(self.back_mut());
        self.publish()
    }

    /// Version of the last publication (0 before the first).
    #[must_use]
    pub fn version(&self) -> u64 {
        self.last_version
    }

    /// How many publications replaced a snapshot the reader never fetched (diagnostics only).
    #[must_use]
    pub fn overwritten_unread(&self) -> u64 {
        self.overwritten_unread
    }
}

impl<T: Clone + Send> SnapshotWriter<T> {
    /// Copies `value` into the back buffer with `clone_from` (which reuses the buffer's heap
    /// memory for `Vec` and similar types) and publishes it; returns the new version.
    pub fn publish_clone_of(&mut self, value: &T) -> u64 {
        self.back_mut().clone_from(value);
        self.publish()
    }
}

/// The reading end: always has a snapshot, fetches the newest one without waiting.
pub struct SnapshotReader<T: Send> {
    output: Output<Stamped<T>>,
    last_seen_version: u64,
}

impl<T: Send> SnapshotReader<T> {
    /// The newest published snapshot (or the initial value if none was published). Wait-free.
    pub fn latest(&mut self) -> &Stamped<T> {
        let snap = self.output.read();
        self.last_seen_version = snap.version;
        snap
    }

    /// The newest snapshot if one was published since the last `latest`/`try_fresh`, else
    /// `None`. Wait-free; never returns the same version twice.
    pub fn try_fresh(&mut self) -> Option<&Stamped<T>> {
        let before = self.last_seen_version;
        let snap = self.output.read();
        if snap.version == before {
            return None;
        }
        self.last_seen_version = snap.version;
        Some(snap)
    }

    /// The snapshot fetched last, without looking for a newer one.
    #[must_use]
    pub fn current(&self) -> &Stamped<T> {
        self.output.output_buffer()
    }

    /// Version of the snapshot fetched last (0: the initial value).
    #[must_use]
    pub fn version(&self) -> u64 {
        self.last_seen_version
    }

    /// Age at `now` of the snapshot fetched last.
    #[must_use]
    pub fn age_at(&self, now: Instant) -> Duration {
        self.current().age_at(now)
    }

    /// True if the writer published something this reader has not fetched yet (diagnostics
    /// only: fetch with [`latest`](Self::latest) rather than polling this).
    #[must_use]
    pub fn has_fresh(&self) -> bool {
        self.output.updated()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn initial_value_has_version_zero() {
        let (_tx, mut rx) = snapshot_channel(&7u32);
        let snap = rx.latest();
        assert_eq!(snap.version, 0);
        assert!(snap.is_initial());
        assert_eq!(snap.value, 7);
    }

    #[test]
    fn reader_sees_latest_and_versions_increase() {
        let (mut tx, mut rx) = snapshot_channel(&0u64);
        for i in 1..=5u64 {
            *tx.back_mut() = i * 10;
            assert_eq!(tx.publish(), i);
        }
        let snap = rx.latest();
        assert_eq!((snap.version, snap.value), (5, 50));
        assert_eq!(tx.version(), 5);
        // Four of the five publications replaced an unread snapshot.
        assert_eq!(tx.overwritten_unread(), 4);
    }

    #[test]
    fn try_fresh_returns_each_version_once() {
        let (mut tx, mut rx) = snapshot_channel(&0i32);
        assert!(rx.try_fresh().is_none());
        tx.write_with(|v| *v = 3);
        assert!(rx.has_fresh());
        assert_eq!(rx.try_fresh().map(|s| s.value), Some(3));
        assert!(rx.try_fresh().is_none());
        assert!(!rx.has_fresh());
        assert_eq!(rx.current().value, 3);
        assert_eq!(rx.version(), 1);
    }

    #[test]
    fn back_buffer_is_recycled_not_the_last_published() {
        let (mut tx, mut rx) = snapshot_channel(&0u8);
        tx.write_with(|v| *v = 1);
        let _ = rx.latest();
        // The back buffer now holds an older snapshot, not 1: writers must overwrite it.
        assert_ne!(*tx.back_mut(), 1);
    }

    #[test]
    fn publish_clone_of_reuses_capacity() {
        let (mut tx, mut rx) = snapshot_channel(&Vec::<f32>::with_capacity(16));
        let data: Vec<f32> = (0..16).map(|i| i as f32).collect();
        tx.publish_clone_of(&data);
        assert_eq!(rx.latest().value, data);
    }

    #[test]
    fn age_uses_the_publication_stamp() {
        let (mut tx, mut rx) = snapshot_channel(&());
        let t0 = Instant::now();
        tx.publish_at(t0);
        let snap = rx.latest();
        assert_eq!(snap.published_at, t0);
        assert_eq!(
            snap.age_at(t0 + Duration::from_millis(3)),
            Duration::from_millis(3)
        );
        // A clock read earlier than the stamp saturates to zero instead of panicking.
        assert_eq!(
            rx.age_at(t0.checked_sub(Duration::from_millis(1)).unwrap_or(t0)),
            Duration::ZERO
        );
    }
}
