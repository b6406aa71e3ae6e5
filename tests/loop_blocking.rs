//! The "a loop tick never blocks" rule, checked: every loop tick is marked on its thread and
//! every blocking point of the engine calls `dynaclay_loops::assert_not_in_tick`, which the
//! test build arms (the `check-blocking` feature). A blocking path in any tick panics there,
//! and a panicked loop makes `Engine::stop` fail; so these runs of the threaded and the
//! lockstep engine pass only if no tick took one. The last test puts an engine wait inside a
//! tick on purpose and expects the check to fire. Nothing here depends on timing: the check
//! fires on the path, whether or not the wait would have been long.

mod common;

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::time::{Duration, Instant};

use dynaclay::engine::{Engine, HeadlessSink, Lockstep};

// Tests build dynaclay-loops with the check-blocking feature (or in debug): the check panics.
const _: () = assert!(dynaclay_loops::BLOCKING_CHECK_PANICS);

#[test]
fn lockstep_ticks_of_a_push_and_a_save_take_no_blocking_path() {
    let s = common::setup(common::PUSH_SCRIPT, vec![]);
    let mut engine = Lockstep::new(
        &s.config,
        s.field,
        common::boxed(s.arm),
        Box::new(HeadlessSink::default()),
        16,
    )
    .expect("engine starts");
    let dir = tempfile::tempdir().expect("temp dir");
    for i in 0..600 {
        if i == 300 {
            engine
                .commands()
                .send(dynaclay::engine::Command::Save {
                    path: dir.path().join("mid.dclay"),
                    as_session: false,
                    reply: None,
                })
                .expect("the simulation takes commands");
        }
        engine.step();
    }
    engine.finish().expect("engine stops");
}

/// Waits (off any loop) until `done` holds; a generous bound turns a hang into a failure.
fn wait_until(mut done: impl FnMut() -> bool) {
    let give_up = Instant::now() + Duration::from_secs(120);
    while !done() {
        assert!(Instant::now() < give_up, "the engine made no progress");
        std::thread::sleep(Duration::from_millis(2));
    }
}

#[test]
fn the_threaded_engines_loops_take_no_blocking_path() {
    let s = common::setup(common::PUSH_SCRIPT, vec![]);
    let engine = Engine::start(
        &s.config,
        s.field,
        common::boxed(s.arm),
        Box::new(HeadlessSink::default()),
    )
    .expect("engine starts");
    wait_until(|| engine.haptic_ticks() >= 300 || !engine.is_alive());
    let dir = tempfile::tempdir().expect("temp dir");
    // A save goes through the simulation loop to the I/O thread and back.
    engine
        .save(&dir.path().join("mid.dclay"), Duration::from_secs(120))
        .expect("saved");
    let ticks = engine.haptic_ticks();
    wait_until(|| engine.haptic_ticks() >= ticks + 300 || !engine.is_alive());
    assert!(engine.is_alive(), "no loop stopped");
    // A loop whose tick took a blocking path panicked there, and stop reports it.
    engine.stop().expect("every loop ran to the stop");
}

#[test]
fn an_engine_wait_inside_a_tick_is_caught() {
    let s = common::setup(common::PUSH_SCRIPT, vec![]);
    let engine = Engine::start(
        &s.config,
        s.field,
        common::boxed(s.arm),
        Box::new(HeadlessSink::default()),
    )
    .expect("engine starts");
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("from_a_tick.dclay");
    // As if a loop body waited for a save: the check fires before the receive.
    let caught = catch_unwind(AssertUnwindSafe(|| {
        let _tick = dynaclay_loops::enter_tick();
        let _ = engine.save(&path, Duration::from_secs(120));
    }));
    let message = *caught
        .expect_err("the blocking check fires")
        .downcast::<String>()
        .expect("a formatted message");
    assert!(
        message.contains("Engine::save waiting for the I/O thread"),
        "{message}"
    );
    assert!(!dynaclay_loops::in_tick(), "the unwind ended the mark");
    engine.stop().expect("the engine itself is unharmed");
}
