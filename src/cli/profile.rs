//! `dynaclay profile`: runs the engine with the simulated arm and prints the latency table,
//! optionally with a CPU hog thread on every other core.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use dynaclay_devices::{SimArmConfig, SimulatedArm};
use dynaclay_loops::{LoopSummary, markdown_table};

use super::args::ProfileArgs;
use super::run::CliError;
use crate::engine::{Engine, EngineConfig, HeadlessSink, ScriptPlan, build_clay};

/// Runs the loops for `args.seconds` and prints their latency table.
///
/// # Errors
/// When the engine cannot start or a loop fails.
pub fn profile(args: &ProfileArgs) -> Result<(), CliError> {
    let plan = ScriptPlan::builtin();
    let field =
        build_clay(&plan.clay).map_err(|e| CliError::Output(format!("clay fit failed: {e}")))?;
    let arm_config = SimArmConfig::default();
    let mut config = EngineConfig::for_field(&field, &arm_config.info);
    if !args.rt {
        config.haptic_rt_priority = None;
    }
    let trajectory = plan.trajectory(&config.map).map_err(CliError::Script)?;
    let device = Box::new(SimulatedArm::new(arm_config, trajectory));

    let stop = Arc::new(AtomicBool::new(false));
    let mut hogs = Vec::new();
    if args.load {
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        for i in 0..cores.saturating_sub(1).max(1) {
            let stop = stop.clone();
            hogs.push(
                std::thread::Builder::new()
                    .name(format!("cpu-hog-{i}"))
                    .spawn(move || {
                        let mut x = 0u64;
                        // NOTE: Relaxed: the flag only ends the loop eventually.
                        while !stop.load(Ordering::Relaxed) {
                            x = std::hint::black_box(
                                x.wrapping_mul(6364136223846793005).wrapping_add(1),
                            );
                        }
                    })
                    .map_err(|e| CliError::Output(format!("cannot start a CPU hog: {e}")))?,
            );
        }
    }
    let engine = Engine::start(&config, field, device, Box::new(HeadlessSink::default()))
        .map_err(CliError::Engine);
    let engine = match engine {
        Ok(e) => e,
        Err(e) => {
            stop.store(true, Ordering::Relaxed);
            return Err(e);
        }
    };
    println!(
        "profiling {:.1} s{}; haptic priority: {}",
        args.seconds,
        if args.load { " with CPU hogs" } else { "" },
        engine.haptic_rt()
    );
    let started = Instant::now();
    while started.elapsed() < Duration::from_secs_f64(args.seconds) && engine.is_alive() {
        std::thread::sleep(Duration::from_millis(50));
    }
    let report = engine.stop();
    stop.store(true, Ordering::Relaxed);
    for h in hogs {
        let _ = h.join();
    }
    let report = report.map_err(CliError::Engine)?;
    let summaries: Vec<LoopSummary> = report.loops.iter().map(|r| r.summary()).collect();
    print!("{}", markdown_table(&summaries));
    let c = report.counters;
    println!(
        "haptic ticks {}, simulation steps {}, graphics updates {}, stale ticks {}, device faults {}",
        c.haptic_ticks,
        c.sim_steps,
        c.graphics_updates,
        c.stale_ticks,
        c.device_read_faults + c.device_write_faults
    );
    Ok(())
}
