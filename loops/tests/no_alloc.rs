//! The real-time operations allocate nothing after construction: a counting global allocator
//! (per thread, so parallel tests do not disturb each other) brackets each of them.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::ops::ControlFlow;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use dynaclay_loops::{
    Heartbeat, LatencyRecorder, LoopConfig, Staleness, StopFlag, TickTiming, Watchdog,
    snapshot_channel, spawn_loop,
};

struct Counting;

thread_local! {
    static ALLOCS: Cell<u64> = const { Cell::new(0) };
}

fn bump() {
    // try_with: the slot may already be gone while a thread is being torn down.
    let _ = ALLOCS.try_with(|c| c.set(c.get() + 1));
}

// SAFETY: every method forwards to the system allocator with the caller's arguments unchanged;
// counting touches only a const-initialised thread-local `Cell`, which never allocates.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        bump();
        // SAFETY: the caller upholds `alloc`'s contract; we pass it through.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: `ptr` came from `System` through this allocator with this layout.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        bump();
        // SAFETY: the caller upholds `alloc_zeroed`'s contract; we pass it through.
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        bump();
        // SAFETY: the caller upholds `realloc`'s contract; we pass it through.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

fn allocs() -> u64 {
    ALLOCS.with(Cell::get)
}

/// Allocations made on this thread while running `f`.
fn count_allocs(f: impl FnOnce()) -> u64 {
    let before = allocs();
    f();
    allocs() - before
}

#[test]
fn counter_sees_an_allocation() {
    // The guard itself must be able to fail.
    assert!(count_allocs(|| drop(std::hint::black_box(vec![1u8; 32]))) >= 1);
}

#[test]
fn recorder_record_stats_and_reset_do_not_allocate() {
    let period = Duration::from_millis(1);
    let mut rec = LatencyRecorder::new(period);
    let t0 = Instant::now();
    let n = count_allocs(|| {
        for i in 0..10_000u32 {
            rec.record_tick(&TickTiming {
                scheduled: t0 + period * i,
                woke: t0 + period * i + Duration::from_nanos(u64::from(i) * 977 % 50_000),
                compute: Duration::from_nanos(u64::from(i) * 131 % 30_000),
                skipped_before: u64::from(i % 100 == 0),
            });
        }
        // Far beyond the histogram range: saturates instead of resizing.
        rec.record_tick(&TickTiming {
            scheduled: t0,
            woke: t0 + Duration::from_secs(3600),
            compute: Duration::from_secs(3600),
            skipped_before: 0,
        });
        std::hint::black_box(rec.stats());
        rec.reset();
    });
    assert_eq!(n, 0, "recorder allocated {n} times");
}

#[test]
fn publish_and_read_do_not_allocate() {
    let (mut tx, mut rx) = snapshot_channel(&[0.0f64; 128]);
    let (mut vtx, mut vrx) = snapshot_channel(&vec![0.0f32; 1024]);
    let source = vec![1.0f32; 1024];
    let n = count_allocs(|| {
        for i in 0..1000u32 {
            tx.back_mut().fill(f64::from(i));
            tx.publish();
            std::hint::black_box(rx.latest().version);
            std::hint::black_box(rx.try_fresh().is_some());
            vtx.publish_clone_of(&source);
            vtx.write_with(|v| v.iter_mut().for_each(|x| *x += 1.0));
            std::hint::black_box(vrx.latest().value[0]);
        }
    });
    assert_eq!(n, 0, "exchange allocated {n} times");
}

#[test]
fn heartbeat_watchdog_staleness_and_stop_flag_do_not_allocate() {
    let hb = Heartbeat::new();
    let mut dog = Watchdog::new(hb.clone(), Duration::from_millis(5));
    let stop = StopFlag::new();
    let fade = Staleness::with_limit(Duration::from_millis(20));
    let n = count_allocs(|| {
        for i in 0..1000u64 {
            hb.beat();
            std::hint::black_box(dog.check());
            std::hint::black_box(fade.factor(Duration::from_micros(i * 30)));
            std::hint::black_box(stop.is_stopped());
        }
    });
    assert_eq!(n, 0);
}

#[test]
fn runner_tick_path_does_not_allocate() {
    // Read this thread-local counter from inside the loop thread at two ticks; every tick in
    // between (sleep, closure, recording, heartbeat, periodic stats publication every 10 ticks)
    // must leave it unchanged.
    let at_10 = Arc::new(AtomicU64::new(u64::MAX));
    let at_end = Arc::new(AtomicU64::new(u64::MAX));
    let (a, b) = (Arc::clone(&at_10), Arc::clone(&at_end));
    let handle = spawn_loop(
        LoopConfig::new("alloc-check")
            .with_rate_hz(4000.0)
            .with_stats_every_ticks(10),
        move |t| match t.index {
            10 => {
                a.store(allocs(), Ordering::Relaxed);
                ControlFlow::Continue(())
            }
            300 => {
                b.store(allocs(), Ordering::Relaxed);
                ControlFlow::Break(())
            }
            _ => ControlFlow::Continue(()),
        },
    )
    .expect("spawn");
    handle.join().expect("join");
    let (start, end) = (
        at_10.load(Ordering::Relaxed),
        at_end.load(Ordering::Relaxed),
    );
    assert_ne!(start, u64::MAX);
    assert_eq!(
        end,
        start,
        "the loop thread allocated {} times in 290 ticks",
        end - start
    );
}
