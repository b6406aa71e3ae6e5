//! Triple-buffer stress: a fast writer and a fast reader on two threads. The reader must only
//! ever see whole snapshots (every element of the payload equals the snapshot's version) with
//! strictly increasing versions, and must end on the writer's last version.
//!
//! The default run is short; the long run is ignored by default and meant for release CI:
//! `cargo test --release -p dynaclay-loops --test stress -- --ignored --test-threads=1`.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Barrier};

use dynaclay_loops::snapshot_channel;

const WORDS: usize = 64;

/// Runs `publishes` publications against a spinning reader; returns how many distinct versions
/// the reader saw.
fn stress_array(publishes: u64) -> u64 {
    let (mut tx, mut rx) = snapshot_channel(&[0u64; WORDS]);
    let done = Arc::new(AtomicBool::new(false));
    let start = Arc::new(Barrier::new(2));

    let writer = {
        let done = Arc::clone(&done);
        let start = Arc::clone(&start);
        std::thread::spawn(move || {
            start.wait();
            for _ in 0..publishes {
                let next = tx.version() + 1;
                tx.back_mut().fill(next);
                assert_eq!(tx.publish(), next);
            }
            // Release: the reader's Acquire load below then sees every publication made before.
            done.store(true, Ordering::Release);
            tx.version()
        })
    };

    start.wait();
    let mut last = 0u64;
    let mut seen = 0u64;
    loop {
        // Acquire pairs with the writer's Release store, so after it the final publish is visible.
        let finished = done.load(Ordering::Acquire);
        if let Some(snap) = rx.try_fresh() {
            assert!(
                snap.version > last,
                "version went from {last} to {}",
                snap.version
            );
            assert!(
                snap.value.iter().all(|&w| w == snap.version),
                "torn snapshot at version {}: {:?}",
                snap.version,
                &snap.value[..4]
            );
            last = snap.version;
            seen += 1;
        } else if finished {
            break;
        }
    }
    let final_version = writer.join().expect("writer thread");
    assert_eq!(
        last, final_version,
        "reader must end on the last publication"
    );
    seen
}

/// The same with a heap payload refilled in place (no reallocation is needed: the length never
/// changes), checking that whole vectors travel together with their version.
fn stress_vec(publishes: u64) {
    let (mut tx, mut rx) = snapshot_channel(&vec![0u32; 257]);
    let writer = std::thread::spawn(move || {
        for _ in 0..publishes {
            let next = (tx.version() + 1) as u32;
            tx.back_mut().iter_mut().for_each(|w| *w = next);
            tx.publish();
        }
    });
    let mut last = 0u64;
    while !writer.is_finished() {
        let snap = rx.latest();
        assert!(snap.version >= last);
        assert!(snap.value.iter().all(|&w| u64::from(w) == snap.version));
        assert_eq!(snap.value.len(), 257);
        last = snap.version;
    }
    writer.join().expect("writer thread");
    assert_eq!(rx.latest().version, publishes);
}

fn short_count() -> u64 {
    if cfg!(miri) { 200 } else { 200_000 }
}

#[test]
fn array_snapshots_are_whole_and_monotonic() {
    let seen = stress_array(short_count());
    assert!(seen >= 1);
}

#[test]
fn vec_snapshots_are_whole_and_monotonic() {
    stress_vec(short_count() / 4);
}

#[test]
#[ignore = "long stress run; use --release --ignored --test-threads=1"]
fn array_snapshots_long_run() {
    let seen = stress_array(50_000_000);
    eprintln!("reader saw {seen} of 50000000 versions");
}

#[test]
#[ignore = "long stress run; use --release --ignored --test-threads=1"]
fn vec_snapshots_long_run() {
    stress_vec(5_000_000);
}
