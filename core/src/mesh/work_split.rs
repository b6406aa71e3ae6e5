//! Handing out a sequence of work units to several threads, so that each thread works along
//! one contiguous stretch of the sequence for as long as it can and none sits idle while
//! work is left.
//!
//! Each thread starts with an equal contiguous share of the units and takes them from its
//! front, in order. A thread whose share is empty takes the back half of the largest share
//! left (a steal) and goes on from the front of that half. So a thread's next unit follows
//! its last one in the sequence except right after a steal: a worker that carries state
//! from one unit to the next (a brick build takes the faces below each brick from the
//! bricks it built before) loses that state only at the few steals, while the threads
//! still finish within about one unit of each other, whatever the units cost and however
//! the operating system schedules the threads.
//!
//! Lock-free: each share is one `AtomicU64` (its front and its end), changed only by
//! compare-and-swap; its owner moves the front, a thief moves the end. Allocates once, on
//! construction (one atomic per thread); never blocks.

use std::sync::atomic::{AtomicU64, Ordering};

/// Units `front .. end` of the sequence, as one word (front in the high half).
#[inline]
fn pack(front: u32, end: u32) -> u64 {
    (u64::from(front) << 32) | u64::from(end)
}

#[inline]
fn unpack(share: u64) -> (u32, u32) {
    ((share >> 32) as u32, share as u32)
}

/// The shares of a sequence of units among threads (see the module docs): every unit is
/// handed out exactly once, to one thread, by [`WorkSplit::next`].
#[derive(Debug)]
pub(crate) struct WorkSplit {
    /// Per thread, the units it has still to take.
    shares: Vec<AtomicU64>,
}

impl WorkSplit {
    /// Units `0 .. units` over `threads` threads (at least one): thread `t` starts with
    /// units `units · t / threads .. units · (t + 1) / threads`.
    ///
    /// # Panics
    /// If `units` does not fit in a `u32` (a caller's units are a few per thread).
    pub(crate) fn new(units: usize, threads: usize) -> Self {
        let units = u32::try_from(units).expect("at most u32::MAX work units");
        let threads = threads.max(1) as u64;
        let bound = |t: u64| (u64::from(units) * t / threads) as u32;
        Self {
            shares: (0..threads)
                .map(|t| AtomicU64::new(pack(bound(t), bound(t + 1))))
                .collect(),
        }
    }

    /// The next unit for thread `thread` (below the count given to [`WorkSplit::new`]):
    /// the front of its share, or, once its share is empty, the front of the half it takes
    /// from the largest share left. `None` when every unit has been handed out.
    pub(crate) fn next(&self, thread: usize) -> Option<usize> {
        loop {
            if let Some(unit) = self.take_front(thread) {
                return Some(unit);
            }
            if !self.steal_into(thread) {
                return None;
            }
        }
    }

    /// Takes the front unit of `thread`'s own share, if it has one.
    fn take_front(&self, thread: usize) -> Option<usize> {
        let share = &self.shares[thread];
        // NOTE: Relaxed throughout this type. A unit is claimed by one read-modify-write of
        // one word, whose atomicity alone makes the claim unique; the work a unit stands for
        // reaches the threads through their spawn and comes back through their join, not
        // through these words.
        let mut now = share.load(Ordering::Relaxed);
        loop {
            let (front, end) = unpack(now);
            if front >= end {
                return None;
            }
            match share.compare_exchange_weak(
                now,
                pack(front + 1, end),
                Ordering::Relaxed,
                Ordering::Relaxed,
            ) {
                Ok(_) => return Some(front as usize),
                Err(seen) => now = seen,
            }
        }
    }

    /// Moves the back half (rounded up) of the largest other share into `thief`'s own share,
    /// which is empty. False when every other share is empty.
    ///
    /// No other thread changes the thief's share meanwhile: a thief changes only a share it
    /// saw non-empty, and a share never holds the same non-empty value twice (its front
    /// only grows until it is empty, and a share taken in a steal starts at a unit not yet
    /// handed out, which no earlier front of it named), so a thief that saw the empty
    /// share's old value fails its compare-and-swap.
    fn steal_into(&self, thief: usize) -> bool {
        loop {
            let largest = self
                .shares
                .iter()
                .enumerate()
                .filter(|&(t, _)| t != thief)
                .map(|(t, share)| (t, share.load(Ordering::Relaxed)))
                .max_by_key(|&(_, share)| {
                    let (front, end) = unpack(share);
                    end.saturating_sub(front)
                });
            let Some((victim, seen)) = largest else {
                return false;
            };
            let (front, end) = unpack(seen);
            if front >= end {
                return false;
            }
            let middle = front + (end - front) / 2;
            if self.shares[victim]
                .compare_exchange(
                    seen,
                    pack(front, middle),
                    Ordering::Relaxed,
                    Ordering::Relaxed,
                )
                .is_ok()
            {
                self.shares[thief].store(pack(middle, end), Ordering::Relaxed);
                return true;
            }
            // The victim took a unit or another thief came first: look again.
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_thread_starts_on_its_own_stretch_in_order() {
        let split = WorkSplit::new(10, 3);
        // Shares 0..3, 3..6, 6..10, each taken from its front.
        assert_eq!(split.next(1), Some(3));
        assert_eq!(split.next(0), Some(0));
        assert_eq!(split.next(2), Some(6));
        assert_eq!(split.next(1), Some(4));
        assert_eq!(split.next(1), Some(5));
        // Thread 1's share is empty: it takes the back half of the largest share left
        // (thread 2's 7..10: 8..10) and goes on from its front.
        assert_eq!(split.next(1), Some(8));
        assert_eq!(split.next(2), Some(7));
        // Thread 2 is left with nothing of its own; the largest share is thread 0's 1..3.
        assert_eq!(split.next(2), Some(2));
        assert_eq!(split.next(1), Some(9));
        assert_eq!(split.next(0), Some(1));
        for t in 0..3 {
            assert_eq!(split.next(t), None);
        }
    }

    #[test]
    fn one_thread_takes_every_unit_of_the_others_in_few_steals() {
        // Threads 1..4 never run: thread 0 takes all 1000 units, each once, and after its
        // own share it moves to another unit out of order only at a steal.
        let split = WorkSplit::new(1000, 4);
        let mut taken = Vec::new();
        while let Some(unit) = split.next(0) {
            taken.push(unit);
        }
        let mut sorted = taken.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, (0..1000).collect::<Vec<_>>());
        let jumps = taken.windows(2).filter(|w| w[1] != w[0] + 1).count();
        assert!(jumps < 40, "{jumps} jumps");
        assert_eq!(&taken[..250], &(0..250).collect::<Vec<_>>()[..]);
    }

    #[test]
    fn threads_racing_hand_out_every_unit_exactly_once() {
        let units = if cfg!(miri) { 200 } else { 100_000 };
        for threads in [2, 3, 8] {
            let split = WorkSplit::new(units, threads);
            let taken: Vec<Vec<usize>> = std::thread::scope(|scope| {
                let split = &split;
                let workers: Vec<_> = (0..threads)
                    .map(|t| scope.spawn(move || std::iter::from_fn(|| split.next(t)).collect()))
                    .collect();
                workers.into_iter().map(|w| w.join().unwrap()).collect()
            });
            let mut all: Vec<usize> = taken.concat();
            all.sort_unstable();
            assert_eq!(all, (0..units).collect::<Vec<_>>(), "{threads} threads");
        }
    }

    #[test]
    fn fewer_units_than_threads_and_no_units() {
        let split = WorkSplit::new(2, 5);
        let mut taken: Vec<usize> = (0..5).filter_map(|t| split.next(t)).collect();
        taken.sort_unstable();
        assert_eq!(taken, [0, 1]);
        assert!((0..5).all(|t| split.next(t).is_none()));
        let none = WorkSplit::new(0, 3);
        assert!((0..3).all(|t| none.next(t).is_none()));
    }
}
