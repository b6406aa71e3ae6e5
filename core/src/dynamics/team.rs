//! A persistent helper thread that runs one half of a step's passes beside the caller, with a
//! spinning two-party barrier between passes.
//!
//! Guarantee: [`Team::run`] returns only after both halves have finished, so a job may borrow
//! the caller's data. After construction nothing allocates; a dispatch costs two atomic
//! stores and an unpark, each barrier a fetch-add and a short spin, instead of a thread spawn
//! or a pool wake-up per pass (a step has four dependent phases in three dispatches). Waiting
//! spins briefly, then yields, so an oversubscribed machine degrades instead of livelocking;
//! an idle helper spins a little longer and then parks. A panic in either half is caught,
//! the other half is released from any barrier, and `run` panics on the caller's thread.

use std::cell::UnsafeCell;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::thread::JoinHandle;
use std::time::Duration;

/// One half of a job: called with the part index (0 on the caller, 1 on the helper) and the
/// barrier both halves pass between dependent passes.
pub(crate) type Job<'a> = dyn Fn(usize, &Barrier) + Sync + 'a;

/// A reusable barrier for the two halves of a job.
#[derive(Debug, Default)]
pub(crate) struct Barrier {
    arrivals: AtomicU64,
    poisoned: AtomicBool,
    parties: u64,
}

impl Barrier {
    /// Wait until the other half arrives too (returns at once with one party).
    ///
    /// # Panics
    /// When the other half panicked.
    pub(crate) fn wait(&self) {
        if self.parties < 2 {
            return;
        }
        // Must be AcqRel: it publishes this half's writes and, for the second arrival,
        // acquires the first one's.
        let mine = self.arrivals.fetch_add(1, Ordering::AcqRel);
        let target = mine / 2 * 2 + 2;
        let mut spins = 0_u32;
        // Acquire: the other half's writes before its arrival become visible.
        while self.arrivals.load(Ordering::Acquire) < target {
            assert!(
                !self.poisoned.load(Ordering::Relaxed),
                "the other half of a step panicked"
            );
            backoff(&mut spins);
        }
    }
}

fn backoff(spins: &mut u32) {
    *spins += 1;
    if *spins < 4096 {
        std::hint::spin_loop();
    } else {
        std::thread::yield_now();
    }
}

struct Shared {
    /// The job of the current dispatch; written only while the helper is idle.
    job: UnsafeCell<Option<*const Job<'static>>>,
    /// Dispatches posted.
    posted: AtomicU64,
    /// Dispatches the helper has finished.
    finished: AtomicU64,
    stop: AtomicBool,
    helper_panicked: AtomicBool,
    barrier: Barrier,
}

// SAFETY: `job` is written by the caller only while the helper is idle (posted == finished)
// and read by the helper only between observing a new `posted` (Acquire) and publishing
// `finished` (Release); the pointee is Sync and outlives the dispatch (`Team::run` waits).
unsafe impl Sync for Shared {}
// SAFETY: as above; the raw pointer is only dereferenced under that protocol.
unsafe impl Send for Shared {}

/// The caller plus at most one persistent helper thread.
#[derive(Default)]
pub(crate) struct Team {
    helper: Option<(Arc<Shared>, JoinHandle<()>)>,
    /// Run jobs on the caller alone although a helper exists (a job too small to pay for the
    /// hand-offs); the helper stays alive, so switching back costs nothing.
    solo: bool,
}

impl std::fmt::Debug for Team {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Team")
            .field("threads", &self.threads())
            .finish()
    }
}

impl Team {
    /// Threads that run a job: 1, or 2 with a helper.
    pub(crate) fn threads(&self) -> usize {
        1 + usize::from(self.helper.is_some() && !self.solo)
    }

    /// Whether a helper thread exists (whatever [`Team::set_solo`] says).
    pub(crate) fn has_helper(&self) -> bool {
        self.helper.is_some()
    }

    /// Run the next jobs on the caller alone (`true`) or split with the helper (`false`,
    /// when there is one). Every pass splits its work so that the results are bit-identical
    /// either way.
    pub(crate) fn set_solo(&mut self, solo: bool) {
        self.solo = solo;
    }

    /// Have `threads.clamp(1, 2)` threads run jobs from now on, starting or stopping the
    /// helper. Falls back to one thread when the helper cannot be spawned.
    pub(crate) fn resize(&mut self, threads: usize) {
        let want = threads.clamp(1, 2);
        if want == 1 + usize::from(self.helper.is_some()) {
            return;
        }
        if want == 1 {
            self.stop();
            return;
        }
        let shared = Arc::new(Shared {
            job: UnsafeCell::new(None),
            posted: AtomicU64::new(0),
            finished: AtomicU64::new(0),
            stop: AtomicBool::new(false),
            helper_panicked: AtomicBool::new(false),
            barrier: Barrier {
                parties: 2,
                ..Barrier::default()
            },
        });
        let theirs = Arc::clone(&shared);
        let spawned = std::thread::Builder::new()
            .name("dynaclay-step-helper".into())
            .spawn(move || helper_loop(&theirs));
        if let Ok(handle) = spawned {
            self.helper = Some((shared, handle));
        }
    }

    /// Run `job(0)` here and `job(1)` on the helper (or only `job(0)` with one thread), and
    /// return when both are done. Takes `&mut self`: one dispatch at a time is what makes the
    /// helper's job slot safe to write (see the SAFETY note inside), and the borrow checker
    /// now enforces it instead of a comment.
    ///
    /// # Panics
    /// When either half panicked.
    pub(crate) fn run(&mut self, job: &Job<'_>) {
        let Some((shared, handle)) = self.helper.as_ref().filter(|_| !self.solo) else {
            job(0, &Barrier::default());
            return;
        };
        let ticket = shared.posted.load(Ordering::Relaxed) + 1;
        // SAFETY: `&mut self` rules out a concurrent `run`, and the helper is idle (every
        // earlier dispatch finished before `run` returned), so nobody reads `job` now. The lifetime is erased only for the duration of this
        // dispatch: `Wait` below blocks until the helper has finished with it, even when our
        // half panics.
        unsafe {
            let erased: *const Job<'static> = std::mem::transmute::<*const Job<'_>, _>(job);
            *shared.job.get() = Some(erased);
        }
        // Must be Release: the helper's Acquire load of `posted` then sees the job pointer.
        shared.posted.store(ticket, Ordering::Release);
        handle.thread().unpark();

        struct Wait<'s>(&'s Shared, u64);
        impl Drop for Wait<'_> {
            fn drop(&mut self) {
                let mut spins = 0;
                // Acquire: the helper's writes become visible to the caller.
                while self.0.finished.load(Ordering::Acquire) < self.1 {
                    backoff(&mut spins);
                }
            }
        }
        let wait = Wait(shared, ticket);
        let mine = catch_unwind(AssertUnwindSafe(|| job(0, &shared.barrier)));
        if mine.is_err() {
            shared.barrier.poisoned.store(true, Ordering::Relaxed);
        }
        drop(wait);
        let helper_failed = shared.helper_panicked.swap(false, Ordering::Relaxed);
        if mine.is_err() || helper_failed {
            // Reset for the next dispatch: both halves are out of the job now.
            shared.barrier.poisoned.store(false, Ordering::Relaxed);
            let arrivals = shared.barrier.arrivals.load(Ordering::Relaxed);
            shared
                .barrier
                .arrivals
                .store(arrivals.next_multiple_of(2), Ordering::Relaxed);
            panic!("a step pass panicked");
        }
    }

    fn stop(&mut self) {
        if let Some((shared, handle)) = self.helper.take() {
            shared.stop.store(true, Ordering::Release);
            handle.thread().unpark();
            let _ = handle.join();
        }
    }
}

impl Drop for Team {
    fn drop(&mut self) {
        self.stop();
    }
}

fn helper_loop(shared: &Shared) {
    let mut seen = 0_u64;
    loop {
        let mut spins = 0_u32;
        loop {
            if shared.stop.load(Ordering::Acquire) {
                return;
            }
            // Acquire: pairs with the Release store in `run`, so the job pointer is visible.
            if shared.posted.load(Ordering::Acquire) > seen {
                break;
            }
            spins += 1;
            if spins < 20_000 {
                std::hint::spin_loop();
            } else {
                // Idle between steps: sleep until the next dispatch unparks us.
                std::thread::park_timeout(Duration::from_millis(5));
            }
        }
        seen += 1;
        // SAFETY: posted > finished, so the caller has published the job and waits in `run`
        // until we store `finished`; the pointee is alive and Sync.
        let job = unsafe { (*shared.job.get()).expect("a posted job") };
        // SAFETY: as above.
        let ran = catch_unwind(AssertUnwindSafe(|| unsafe { (*job)(1, &shared.barrier) }));
        if ran.is_err() {
            shared.barrier.poisoned.store(true, Ordering::Relaxed);
            shared.helper_panicked.store(true, Ordering::Relaxed);
        }
        // Must be Release: publishes this half's writes to the caller.
        shared.finished.store(seen, Ordering::Release);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::AtomicUsize;

    #[test]
    fn both_halves_run_and_the_barrier_orders_their_writes() {
        let mut team = Team::default();
        team.resize(2);
        assert_eq!(team.threads(), 2);
        let cells: Vec<AtomicUsize> = (0..2).map(|_| AtomicUsize::new(0)).collect();
        for round in 1..200 {
            team.run(&|part, barrier| {
                cells[part].store(round, Ordering::Relaxed);
                barrier.wait();
                assert_eq!(cells[1 - part].load(Ordering::Relaxed), round);
                barrier.wait();
            });
        }
        team.set_solo(true);
        assert_eq!(team.threads(), 1);
        let parts = AtomicUsize::new(0);
        team.run(&|part, barrier| {
            barrier.wait();
            parts.fetch_add(part + 1, Ordering::Relaxed);
        });
        assert_eq!(parts.load(Ordering::Relaxed), 1, "only the caller ran");
        team.set_solo(false);
        assert_eq!(team.threads(), 2);
        team.resize(1);
        assert_eq!(team.threads(), 1);
    }

    #[test]
    fn a_panicking_half_is_reported_and_the_team_stays_usable() {
        let mut team = Team::default();
        team.resize(2);
        let r = catch_unwind(AssertUnwindSafe(|| {
            team.run(&|part, barrier| {
                assert!(part == 0, "helper half fails");
                barrier.wait();
            });
        }));
        assert!(r.is_err());
        let count = AtomicUsize::new(0);
        team.run(&|_, barrier| {
            barrier.wait();
            count.fetch_add(1, Ordering::Relaxed);
        });
        assert_eq!(count.load(Ordering::Relaxed), 2);
    }

    /// The team's hand-over (the job pointer, the spinning barrier) under Miri
    /// (`cargo +nightly miri test -p dynaclay-core --lib miri_`): a few rounds, each half
    /// seeing the other's write after the barrier, then a panicking half.
    #[test]
    fn miri_two_halves_hand_over_through_the_barrier() {
        let mut team = Team::default();
        team.resize(2);
        let cells: Vec<AtomicUsize> = (0..2).map(|_| AtomicUsize::new(0)).collect();
        for round in 1..4 {
            team.run(&|part, barrier| {
                cells[part].store(round, Ordering::Relaxed);
                barrier.wait();
                assert_eq!(cells[1 - part].load(Ordering::Relaxed), round);
                barrier.wait();
            });
        }
        let r = catch_unwind(AssertUnwindSafe(|| {
            team.run(&|part, barrier| {
                assert!(part == 0, "helper half fails");
                barrier.wait();
            });
        }));
        assert!(r.is_err());
        team.resize(1);
        assert_eq!(team.threads(), 1);
    }
}
