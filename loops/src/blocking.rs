//! The rule "a loop tick never blocks", checked on the blocking path itself.
//!
//! A tick (the body that [`spawn_loop`](crate::spawn_loop) and [`run_loop`](crate::run_loop)
//! call at a fixed rate) must never wait for another thread: no blocking channel receive
//! (`recv`, `recv_timeout`), no mutex or read-write lock that another thread may hold, no
//! `join`, no wait on a GPU or an I/O thread. Loops share state only through the triple buffers
//! of [`snapshot_channel`](crate::snapshot_channel) and take commands with `try_recv`. A wait in
//! a tick costs the loop its deadline whenever the other side is slow, which a test on an idle
//! machine rarely shows, so the rule is checked where a wait *could* happen, not where one did:
//!
//! - The runner marks every tick on its thread: [`in_tick`] is true while the body runs (a
//!   thread-local flag, two stores per tick, no allocation, no lock). A driver that runs loop
//!   bodies itself (a lockstep engine) marks them with [`enter_tick`].
//! - Every blocking point of the application calls [`assert_not_in_tick`] just before it may
//!   block. The check fires on the first tick that takes that path, whether or not the wait
//!   would have been long: it depends neither on contention nor on timing.
//! - In debug builds, in this crate's tests and with the `check-blocking` feature (which the
//!   workspace's tests turn on through a dev-dependency), a blocking path in a tick panics,
//!   naming the loop and what would have blocked; the runner reports that as
//!   [`LoopError::Panicked`](crate::LoopError::Panicked). In a release build without the
//!   feature it is counted ([`blocking_in_tick_count`]) and goes on, so the check never
//!   stops a user's loop.
//!
//! Not covered: waits inside third-party code that does not call the check, and fork-join over
//! a loop's own helper threads (a spinning barrier, a scoped join), which wait only for the
//! tick's own work, never for another loop.

use std::cell::Cell;
use std::marker::PhantomData;
use std::sync::atomic::{AtomicU64, Ordering};

/// Whether a blocking path in a tick panics (else it is only counted).
pub const BLOCKING_CHECK_PANICS: bool =
    cfg!(any(debug_assertions, test, feature = "check-blocking"));

thread_local! {
    /// Set while this thread runs a loop's tick. Const-initialised: reading or writing it never
    /// allocates or registers a destructor.
    static IN_TICK: Cell<bool> = const { Cell::new(false) };
}

static BLOCKING_IN_TICK: AtomicU64 = AtomicU64::new(0);

/// Marks the current thread as inside a loop tick until dropped (then restores the previous
/// mark). Not `Send`: it belongs to the thread that made it.
#[must_use = "the tick mark ends when the guard is dropped"]
#[derive(Debug)]
pub struct TickMark {
    previous: bool,
    _thread_bound: PhantomData<*const ()>,
}

/// Marks the current thread as running a loop tick until the returned guard drops. The runner
/// does this around every body call; a driver that runs loop bodies on its own thread (a
/// lockstep engine) calls it around each body so the same rule is checked there.
pub fn enter_tick() -> TickMark {
    let previous = IN_TICK.with(|t| t.replace(true));
    TickMark {
        previous,
        _thread_bound: PhantomData,
    }
}

impl Drop for TickMark {
    fn drop(&mut self) {
        IN_TICK.with(|t| t.set(self.previous));
    }
}

/// Whether the current thread is running a loop tick now.
#[must_use]
pub fn in_tick() -> bool {
    IN_TICK.with(Cell::get)
}

/// Call just before an operation that may block (a blocking receive, a lock another thread may
/// hold, a join, a wait on the GPU), with `what` naming it. Outside a tick it does nothing.
///
/// # Panics
/// Inside a loop tick when [`BLOCKING_CHECK_PANICS`] (debug builds, tests, the
/// `check-blocking` feature), with the loop thread's name, `what` and the caller's location.
/// Otherwise a blocking path in a tick is only counted in [`blocking_in_tick_count`].
#[track_caller]
pub fn assert_not_in_tick(what: &str) {
    if !in_tick() {
        return;
    }
    BLOCKING_IN_TICK.fetch_add(1, Ordering::Relaxed);
    if BLOCKING_CHECK_PANICS {
        let here = std::panic::Location::caller();
        let thread = std::thread::current();
        panic!(
            "a loop tick took a blocking path: {what} at {here} on thread {:?}; loops share \
             state only through triple buffers and try_recv (see dynaclay_loops::blocking)",
            thread.name().unwrap_or("unnamed")
        );
    }
}

/// Blocking paths taken inside ticks since the process started (each also panicked where
/// [`BLOCKING_CHECK_PANICS`]).
#[must_use]
pub fn blocking_in_tick_count() -> u64 {
    BLOCKING_IN_TICK.load(Ordering::Relaxed)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_mark_is_per_thread_nested_and_restored() {
        assert!(!in_tick());
        assert_not_in_tick("outside any tick: nothing happens");
        {
            let _outer = enter_tick();
            assert!(in_tick());
            let other = std::thread::spawn(in_tick).join().expect("join");
            assert!(!other, "another thread is not in this thread's tick");
            {
                let _inner = enter_tick();
                assert!(in_tick());
            }
            assert!(in_tick(), "the outer mark survives the inner one");
        }
        assert!(!in_tick());
    }

    #[test]
    fn a_blocking_path_inside_a_mark_panics_and_the_mark_is_cleared_by_the_unwind() {
        let before = blocking_in_tick_count();
        let caught = std::panic::catch_unwind(|| {
            let _tick = enter_tick();
            assert_not_in_tick("a test receive");
        });
        let message = caught
            .expect_err("the check fires")
            .downcast::<String>()
            .expect("a formatted message");
        assert!(message.contains("a test receive"), "{message}");
        assert!(
            message.contains("blocking.rs"),
            "names the call site: {message}"
        );
        assert!(!in_tick(), "unwinding dropped the mark");
        assert!(blocking_in_tick_count() > before);
    }
}
