//! The long fuzz run over sessions, scripts, recordings and point clouds: the mutations and checks of
//! `tests/fuzz/mod.rs`, a million cases or more, outside CI.
//!
//! ```text
//! cargo bench --bench fuzz_inputs                      # 1,000,000 cases in all
//! DYNACLAY_FUZZ_CASES=3000000 cargo bench --bench fuzz_inputs
//! ```
//!
//! The cases are split evenly over the four formats, each format on its own thread. A
//! failing case is shrunk by proptest and printed, and the run exits 1. The summary gives the
//! cases and time per format, for bench/RESULTS.md.

#[path = "../tests/fuzz/mod.rs"]
mod fuzz;

use std::time::Instant;

use proptest::strategy::Strategy;
use proptest::test_runner::{Config, TestCaseError, TestRng, TestRunner};

#[global_allocator]
static HEAP: fuzz::PeakAlloc = fuzz::PeakAlloc;

fn run<S: Strategy>(
    name: &'static str,
    cases: u32,
    seed: u8,
    strategy: &S,
    check: impl Fn(&S::Value) -> Result<(), TestCaseError>,
) -> Result<(u32, f64), String>
where
    S::Value: std::fmt::Debug,
{
    let config = Config {
        cases,
        failure_persistence: None,
        // The checks catch panics themselves through proptest; no forking.
        ..Config::default()
    };
    let rng = TestRng::from_seed(proptest::test_runner::RngAlgorithm::ChaCha, &[seed; 32]);
    let mut runner = TestRunner::new_with_rng(config, rng);
    let started = Instant::now();
    runner
        .run(strategy, |v| check(&v))
        .map_err(|e| format!("{name}: {e}"))?;
    Ok((cases, started.elapsed().as_secs_f64()))
}

fn main() {
    let total: u32 = std::env::var("DYNACLAY_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(1_000_000);
    let per = total.div_ceil(4);
    println!("fuzz_inputs: {per} cases per format ({} in all)", 4 * per);
    let started = Instant::now();
    let sessions = std::thread::spawn(move || {
        run("sessions", per, 1, &fuzz::session_case(), |b| {
            fuzz::check_session(b)
        })
    });
    let scripts = std::thread::spawn(move || {
        run("scripts", per, 2, &fuzz::script_case(), |t| {
            fuzz::check_script(t)
        })
    });
    let recordings = std::thread::spawn(move || {
        run("recordings", per, 3, &fuzz::recording_case(), |b| {
            fuzz::check_recording(b)
        })
    });
    let clouds = std::thread::spawn(move || {
        run("clouds", per, 4, &fuzz::cloud_case(), |(form, b)| {
            fuzz::check_cloud(*form, b)
        })
    });
    let mut failed = false;
    for (format, (name, handle)) in [
        ("sessions", sessions),
        ("scripts", scripts),
        ("recordings", recordings),
        ("clouds", clouds),
    ]
    .into_iter()
    .enumerate()
    {
        match handle.join() {
            Ok(Ok((cases, seconds))) => println!(
                "  {name:<10} {cases:>9} cases  {seconds:>7.1} s  {:>6.1} µs/case  \
                 {:>8} parsed, the rest refused with an error",
                seconds * 1e6 / f64::from(cases),
                fuzz::ACCEPTED[format].load(std::sync::atomic::Ordering::Relaxed)
            ),
            Ok(Err(e)) => {
                failed = true;
                println!("  FAILED {e}");
            }
            Err(_) => {
                failed = true;
                println!("  {name}: the runner thread panicked");
            }
        }
    }
    println!(
        "fuzz_inputs: {} cases in {:.1} s wall",
        4 * per,
        started.elapsed().as_secs_f64()
    );
    if failed {
        std::process::exit(1);
    }
}
