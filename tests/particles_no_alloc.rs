//! A settled particle follower's update allocates nothing: a counting global allocator in this
//! test binary counts the allocations made on the test's thread while updates run (steps,
//! projection, and the publication of positions, normals and radii), with and without
//! curvature bias. The first updates (seeding, and the buffers growing to their size) are
//! outside the count.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

use dynaclay::engine::HeadlessSink;
use dynaclay::field::{MultiPatchField, Primitive, lattice_from_primitive};
use dynaclay::particles::{ParticleFollower, ParticleParams, ParticleSystem};
use glam::Vec3;

struct Counting;

thread_local! {
    /// Whether this thread is inside a guarded update.
    static GUARDED: Cell<bool> = const { Cell::new(false) };
    /// Allocations this thread made inside guarded updates.
    static ALLOCS: Cell<u64> = const { Cell::new(0) };
}

// SAFETY: forwards every call to the system allocator unchanged; only counts.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if GUARDED.with(Cell::get) {
            ALLOCS.with(|n| n.set(n.get() + 1));
        }
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: same contract as the caller's.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if GUARDED.with(Cell::get) {
            ALLOCS.with(|n| n.set(n.get() + 1));
        }
        // SAFETY: same contract as the caller's.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// Allocations `f` makes on this thread.
fn allocations(f: impl FnOnce()) -> u64 {
    let before = ALLOCS.with(Cell::get);
    GUARDED.with(|g| g.set(true));
    f();
    GUARDED.with(|g| g.set(false));
    ALLOCS.with(Cell::get) - before
}

fn sphere() -> MultiPatchField {
    let lattice = lattice_from_primitive(
        [25; 3],
        0.1,
        Vec3::ZERO,
        &Primitive::Sphere {
            centre: Vec3::splat(1.2),
            radius: 0.7,
        },
        0.2,
        2,
    )
    .expect("clay fits");
    MultiPatchField::new(lattice)
}

#[test]
fn a_settled_follower_update_allocates_nothing() {
    let clay = sphere();
    let (mut follower, _view) = ParticleFollower::new(HeadlessSink::default(), 400, 2).unwrap();
    for _ in 0..40 {
        follower.follow(&clay);
    }
    let n = allocations(|| {
        for _ in 0..10 {
            follower.follow(&clay);
        }
    });
    assert_eq!(n, 0, "allocations in 10 settled follower updates");
}

#[test]
fn a_settled_biased_step_allocates_nothing() {
    let clay = sphere();
    let mut params = ParticleParams::new(400);
    params.curvature_ratio = 4.0;
    let mut system = ParticleSystem::new(params).unwrap();
    system.seed_random(&clay, 400, 3).unwrap();
    system.settle(&clay, 100);
    let n = allocations(|| {
        for _ in 0..10 {
            system.step(&clay, ParticleSystem::DEFAULT_DT).unwrap();
        }
    });
    assert_eq!(n, 0, "allocations in 10 settled biased steps");
}
