//! The haptic tick allocates nothing: a counting global allocator in this test binary counts
//! allocations made on the ticking thread while a tick runs, through contact, new field
//! patches, the safety filter, a force-limit change and a whole-field republication after a
//! session load.

mod common;

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use dynaclay::engine::{Command, HeadlessSink, build};
use dynaclay::io::Session;
use dynaclay::tools::Clay;

struct Counting;

static ALLOCS_IN_TICK: AtomicU64 = AtomicU64::new(0);

thread_local! {
    static IN_TICK: Cell<bool> = const { Cell::new(false) };
}

// SAFETY: forwards every call to the system allocator unchanged; only counts.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if IN_TICK.with(Cell::get) {
            ALLOCS_IN_TICK.fetch_add(1, Ordering::Relaxed);
        }
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: same contract as the caller's.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if IN_TICK.with(Cell::get) {
            ALLOCS_IN_TICK.fetch_add(1, Ordering::Relaxed);
        }
        // SAFETY: same contract as the caller's.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn haptic_tick_allocates_nothing() {
    let s = common::setup(common::PUSH_SCRIPT, vec![]);
    let mut stages = build(
        &s.config,
        s.field,
        common::boxed(s.arm),
        Box::new(HeadlessSink::default()),
        true,
    )
    .expect("stages build");
    // The guard itself works: an allocation inside it is counted.
    IN_TICK.with(|f| f.set(true));
    let probe = std::hint::black_box(vec![1u8; 16]);
    IN_TICK.with(|f| f.set(false));
    drop(probe);
    assert_eq!(ALLOCS_IN_TICK.swap(0, Ordering::Relaxed), 1);

    let limit = stages.haptic.force_limit();
    let mut status = stages.sim.take_status_reader().expect("status reader");
    let mut loaded = stages.sim.lattice().clone();
    for c in &mut loaded.coeffs {
        *c *= 0.999;
    }
    let mut contact_ticks = 0;
    let mut patched_ticks = 0;
    for i in 0..1400 {
        if i == 300 {
            limit.request(0.1).unwrap();
        }
        if i == 700 {
            let session = Session {
                clay: Clay::single(loaded.clone()),
                ..Session::default()
            };
            stages
                .commands
                .send(Command::Load {
                    session: Box::new(session),
                    source: "same-lattice.dclay".into(),
                    reply: None,
                })
                .unwrap();
        }
        IN_TICK.with(|f| f.set(true));
        let out = stages.haptic.tick(Instant::now());
        IN_TICK.with(|f| f.set(false));
        if out.sample.in_contact {
            contact_ticks += 1;
        }
        // The simulation and graphics run outside the guard (they may allocate).
        stages.sim.apply_commands();
        let sample = stages.samples.latest().value;
        if stages.sim.step(&sample).stepped {
            patched_ticks += 1;
        }
        if i % 50 == 0 {
            stages.graphics.tick();
        }
    }
    assert!(
        contact_ticks > 200,
        "the tick was exercised in contact ({contact_ticks})"
    );
    assert!(
        patched_ticks > 200,
        "with fresh field patches ({patched_ticks})"
    );
    assert_eq!(
        limit.applied_n(),
        0.1,
        "the limit change was applied in a tick"
    );
    assert_eq!(
        (
            status.latest().value.sessions_loaded,
            stages.counters.snapshot().command_errors
        ),
        (1, 0),
        "the load was applied"
    );
    assert_eq!(
        ALLOCS_IN_TICK.load(Ordering::Relaxed),
        0,
        "haptic tick allocated"
    );
}
