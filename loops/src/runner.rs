//! Fixed-rate loop runner: calls a tick closure at a set rate on absolute deadlines, measuring
//! every tick.
//!
//! Guarantee: after set-up (thread spawn, priority request, core pinning, recorder allocation —
//! all before the first tick) the loop itself allocates nothing and takes no lock; per tick it
//! reads the clock, sleeps until the next deadline (native sleep, then a spin for the last
//! `spin_margin_us`), runs the closure, records the timing, beats the heartbeat and checks a
//! relaxed stop flag. Every `stats_every_ticks` ticks it also computes [`LatencyStats`] into the
//! back buffer of a triple buffer (bounded work, see [`LatencyRecorder::stats`]) — all of this
//! after the closure, inside the slack before the next deadline.
//!
//! Deadlines are absolute (`start + k·period`, from `spin_sleep_util::Interval`), so the loop
//! does not drift. When a tick starts late, [`OverrunPolicy`] decides what happens to the ticks
//! that were due meanwhile.

use std::ops::ControlFlow;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use spin_sleep::{SpinSleeper, SpinStrategy};
use spin_sleep_util::MissedTickBehavior;

use crate::exchange::{SnapshotReader, SnapshotWriter, Stamped, snapshot_channel};
use crate::priority::{PinOutcome, RtOutcome, pin_current_thread, request_realtime};
use crate::recorder::{LatencyRecorder, LatencyStats, TickTiming};
use crate::summary::LoopSummary;
use crate::wake::{WakeBell, WakeSchedule, WakeWaiter};
use crate::watchdog::{Heartbeat, Watchdog};

/// Highest rate a loop may be configured for.
pub const MAX_RATE_HZ: f64 = 100_000.0;

/// What to do with ticks that fell due while the loop was late.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum OverrunPolicy {
    /// Drop the missed ticks and resume on the original grid of deadlines (`start + k·period`).
    /// The next tick is never closer than the remainder of the current period. Right for the
    /// haptic loop: a burst of catch-up ticks would render stale device reads back to back.
    #[default]
    Skip,
    /// Run every missed tick back to back until the loop is on schedule again. Right for a loop
    /// that integrates time in fixed steps and must run exactly `rate × elapsed` steps.
    CatchUp,
}

impl OverrunPolicy {
    fn missed_tick_behavior(self) -> MissedTickBehavior {
        match self {
            Self::Skip => MissedTickBehavior::Skip,
            Self::CatchUp => MissedTickBehavior::Burst,
        }
    }
}

/// How to run one loop.
#[derive(Clone, Debug, PartialEq)]
pub struct LoopConfig {
    /// Thread name (also the loop's name in reports). Non-empty, no NUL byte.
    pub name: String,
    /// Ticks per second; finite, in (0, [`MAX_RATE_HZ`]].
    pub rate_hz: f64,
    /// What happens to ticks missed while late.
    pub overrun: OverrunPolicy,
    /// SCHED_FIFO priority to ask for; `None` keeps normal priority.
    pub rt_priority: Option<i32>,
    /// Core (index among the cores this process may use) to pin the loop thread to.
    pub core: Option<usize>,
    /// The native sleep ends this early and the thread spins the rest of the way to the deadline.
    /// Larger is more precise and burns more CPU.
    pub spin_margin_us: u32,
    /// Publish [`LatencyStats`] every this many ticks (0: only when the loop ends).
    pub stats_every_ticks: u32,
}

impl LoopConfig {
    /// Defaults: 1 kHz, skip missed ticks, normal priority, not pinned, 125 µs spin margin (the
    /// spin_sleep default on Linux), stats published every 1000 ticks.
    #[must_use]
    pub fn new(name: impl Into<String>) -> Self {
        Self {
            name: name.into(),
            rate_hz: 1000.0,
            overrun: OverrunPolicy::Skip,
            rt_priority: None,
            core: None,
            spin_margin_us: 125,
            stats_every_ticks: 1000,
        }
    }

    /// Sets the rate.
    #[must_use]
    pub fn with_rate_hz(mut self, rate_hz: f64) -> Self {
        self.rate_hz = rate_hz;
        self
    }

    /// Sets the overrun policy.
    #[must_use]
    pub fn with_overrun(mut self, overrun: OverrunPolicy) -> Self {
        self.overrun = overrun;
        self
    }

    /// Asks for SCHED_FIFO at `priority` (see [`crate::DEFAULT_RT_PRIORITY`]).
    #[must_use]
    pub fn with_rt_priority(mut self, priority: i32) -> Self {
        self.rt_priority = Some(priority);
        self
    }

    /// Pins the loop thread to `core`.
    #[must_use]
    pub fn with_core(mut self, core: usize) -> Self {
        self.core = Some(core);
        self
    }

    /// Sets how often statistics are published.
    #[must_use]
    pub fn with_stats_every_ticks(mut self, ticks: u32) -> Self {
        self.stats_every_ticks = ticks;
        self
    }

    /// The nominal period, `1 / rate_hz`.
    ///
    /// # Errors
    /// [`LoopError::InvalidConfig`] if the rate is not finite or outside (0, [`MAX_RATE_HZ`]].
    pub fn try_period(&self) -> Result<Duration, LoopError> {
        if !(self.rate_hz.is_finite() && self.rate_hz > 0.0 && self.rate_hz <= MAX_RATE_HZ) {
            return Err(self.invalid(
                "rate_hz",
                format!(
                    "must be finite and in (0, {MAX_RATE_HZ}], got {}",
                    self.rate_hz
                ),
            ));
        }
        Ok(Duration::from_secs_f64(1.0 / self.rate_hz))
    }

    /// Checks every field.
    ///
    /// # Errors
    /// [`LoopError::InvalidConfig`] naming the first bad field.
    pub fn validate(&self) -> Result<(), LoopError> {
        if self.name.is_empty() || self.name.contains('\0') {
            return Err(self.invalid("name", "must be non-empty and contain no NUL byte".into()));
        }
        self.try_period()?;
        if u64::from(self.spin_margin_us) * 1000 >= 1_000_000_000 {
            return Err(self.invalid("spin_margin_us", "must be under one second".into()));
        }
        Ok(())
    }

    fn invalid(&self, field: &'static str, message: String) -> LoopError {
        LoopError::InvalidConfig {
            loop_name: self.name.clone(),
            field,
            message,
        }
    }
}

/// Errors from setting up or joining a loop.
#[derive(Debug, thiserror::Error)]
pub enum LoopError {
    /// A configuration field is out of range.
    #[error("loop '{loop_name}': invalid `{field}`: {message}")]
    InvalidConfig {
        /// The loop's name.
        loop_name: String,
        /// The offending field of [`LoopConfig`].
        field: &'static str,
        /// What is wrong with it.
        message: String,
    },
    /// The OS could not start the thread.
    #[error("loop '{loop_name}': could not start thread: {source}")]
    Spawn {
        /// The loop's name.
        loop_name: String,
        /// The OS error.
        source: std::io::Error,
    },
    /// The loop thread panicked (in the tick closure or during set-up).
    #[error("loop '{loop_name}' panicked: {message}")]
    Panicked {
        /// The loop's name.
        loop_name: String,
        /// The panic message, if it was a string.
        message: String,
    },
}

/// What the tick closure is told about the current tick.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TickInfo {
    /// 0 for the first tick, then 1, 2, … (ticks actually run; skipped ones are not counted).
    pub index: u64,
    /// When this tick was due.
    pub scheduled: Instant,
    /// When the loop thread started it (`woke − scheduled` is the lateness).
    pub woke: Instant,
    /// Time since the previous tick started (the nominal period for the first tick).
    pub dt: Duration,
    /// Ticks dropped just before this one by [`OverrunPolicy::Skip`].
    pub skipped_before: u64,
    /// The nominal period.
    pub nominal_period: Duration,
}

impl TickInfo {
    /// How late this tick started.
    #[must_use]
    pub fn lateness(&self) -> Duration {
        self.woke.saturating_duration_since(self.scheduled)
    }
}

/// A flag that asks a loop to stop after its current tick. Cloneable; any clone can set it.
#[derive(Clone, Debug, Default)]
pub struct StopFlag {
    flag: Arc<AtomicBool>,
}

impl StopFlag {
    /// A flag that is not set.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// Asks the loop to stop. Wait-free.
    pub fn stop(&self) {
        // NOTE: Relaxed is enough: the flag publishes no data, and the loop only needs to see it
        // eventually (the next tick); the final state is handed back through the thread join,
        // which synchronises on its own.
        self.flag.store(true, Ordering::Relaxed);
    }

    /// True once [`stop`](Self::stop) was called. Wait-free.
    #[must_use]
    pub fn is_stopped(&self) -> bool {
        self.flag.load(Ordering::Relaxed)
    }
}

/// Why a loop ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StopReason {
    /// Its [`StopFlag`] was set.
    StopRequested,
    /// The tick closure returned `ControlFlow::Break`.
    BodyFinished,
}

/// The loop side of the control plumbing: what [`run_loop`] needs besides the closure.
pub struct LoopControl {
    stop: StopFlag,
    heartbeat: Heartbeat,
    stats: SnapshotWriter<LatencyStats>,
}

/// The observer side: stop the loop, watch its heartbeat, read its latest statistics. Lives on
/// any one thread other than the loop's.
pub struct LoopMonitor {
    stop: StopFlag,
    heartbeat: Heartbeat,
    stats: SnapshotReader<LatencyStats>,
    /// A woken loop's bell, rung on stop so a loop asleep towards a long period ends at once.
    wake: Option<WakeBell>,
}

/// Makes a connected [`LoopControl`] / [`LoopMonitor`] pair (allocates; call at set-up).
#[must_use]
pub fn loop_control() -> (LoopControl, LoopMonitor) {
    let stop = StopFlag::new();
    let heartbeat = Heartbeat::new();
    let (tx, rx) = snapshot_channel(&LatencyStats::default());
    (
        LoopControl {
            stop: stop.clone(),
            heartbeat: heartbeat.clone(),
            stats: tx,
        },
        LoopMonitor {
            stop,
            heartbeat,
            stats: rx,
            wake: None,
        },
    )
}

impl LoopMonitor {
    /// Asks the loop to stop after its current tick (a woken loop asleep is woken to stop).
    pub fn stop(&self) {
        self.stop.stop();
        if let Some(bell) = &self.wake {
            bell.ring();
        }
    }

    /// A clone of the loop's stop flag.
    #[must_use]
    pub fn stop_flag(&self) -> StopFlag {
        self.stop.clone()
    }

    /// A clone of the loop's heartbeat (beaten once per tick).
    #[must_use]
    pub fn heartbeat(&self) -> Heartbeat {
        self.heartbeat.clone()
    }

    /// A watchdog that reports a stall after `limit` without a tick.
    #[must_use]
    pub fn watchdog(&self, limit: Duration) -> Watchdog {
        Watchdog::new(self.heartbeat.clone(), limit)
    }

    /// Ticks run so far (from the heartbeat; exact, unlike the periodic statistics).
    #[must_use]
    pub fn ticks(&self) -> u64 {
        self.heartbeat.count()
    }

    /// The latest statistics the loop published (version 0 and zeros before the first).
    /// Wait-free.
    pub fn latest_stats(&mut self) -> &Stamped<LatencyStats> {
        self.stats.latest()
    }
}

/// Everything a finished loop hands back: its recorder (full histograms), how it ran, why it
/// stopped.
#[derive(Clone, Debug)]
pub struct LoopReport {
    /// The configuration it ran with.
    pub config: LoopConfig,
    /// What the OS granted for the real-time request.
    pub rt: RtOutcome,
    /// What happened to the pinning request.
    pub pin: PinOutcome,
    /// Why it ended.
    pub stop_reason: StopReason,
    /// Every tick's timing.
    pub recorder: LatencyRecorder,
}

impl LoopReport {
    /// The serialisable summary of this run.
    #[must_use]
    pub fn summary(&self) -> LoopSummary {
        LoopSummary {
            name: self.config.name.clone(),
            rt_priority: self.rt,
            pinning: self.pin,
            stats: self.recorder.stats(),
        }
    }
}

/// Runs a loop on the calling thread until the stop flag is set or `body` breaks.
///
/// The calling thread is raised to `config.rt_priority` and pinned to `config.core` first, and
/// stays so after the return. Use [`spawn_loop`] to give the loop its own named thread.
///
/// # Errors
/// [`LoopError::InvalidConfig`] if `config` does not validate (nothing is run then).
pub fn run_loop<F>(
    config: &LoopConfig,
    control: LoopControl,
    body: F,
) -> Result<LoopReport, LoopError>
where
    F: FnMut(&TickInfo) -> ControlFlow<()>,
{
    config.validate()?;
    let (rt, pin) = prepare_thread(config);
    Ok(run_prepared(config.clone(), rt, pin, control, body, None))
}

fn prepare_thread(config: &LoopConfig) -> (RtOutcome, PinOutcome) {
    let pin = config
        .core
        .map_or(PinOutcome::NotRequested, pin_current_thread);
    let rt = config
        .rt_priority
        .map_or(RtOutcome::NotRequested, request_realtime);
    (rt, pin)
}

/// The tick loop proper; `config` is validated. With `wake`, ticks also start when its bell
/// rings (see [`crate::wake`]) instead of only on the deadline grid.
fn run_prepared<F>(
    config: LoopConfig,
    rt: RtOutcome,
    pin: PinOutcome,
    mut control: LoopControl,
    mut body: F,
    wake: Option<WakeWaiter>,
) -> LoopReport
where
    F: FnMut(&TickInfo) -> ControlFlow<()>,
{
    let period = config
        .try_period()
        .unwrap_or_else(|e| unreachable!("validated config: {e}"));
    let period_ns = period.as_nanos().max(1);
    let mut recorder = LatencyRecorder::new(period);
    let sleeper = SpinSleeper::new(config.spin_margin_us.saturating_mul(1000))
        .with_spin_strategy(SpinStrategy::SpinLoopHint);
    // NOTE: SpinLoopHint, not the Linux default YieldThread: under normal priority a yield can
    // hand the core to a CPU hog for a whole time slice (milliseconds) right before the deadline.
    let mut interval = spin_sleep_util::interval(period)
        .with_missed_tick_behavior(config.overrun.missed_tick_behavior())
        .with_spin_sleeper(sleeper);
    let stats_every = u64::from(config.stats_every_ticks);
    let mut woken = wake.map(|w| {
        w.register_current_thread();
        let schedule = WakeSchedule::new(period, w.min_interval());
        (w, schedule)
    });

    let mut index = 0u64;
    let mut prev: Option<(Instant, Instant)> = None; // (scheduled, woke) of the previous tick
    let stop_reason = loop {
        if control.stop.is_stopped() {
            break StopReason::StopRequested;
        }
        let scheduled = match woken.as_ref() {
            Some((waiter, schedule)) => {
                match waiter.wait_for_tick(schedule, || control.stop.is_stopped()) {
                    Some(scheduled) => scheduled,
                    None => break StopReason::StopRequested,
                }
            }
            None => interval.tick(),
        };
        let woke = Instant::now();
        if let Some((_, schedule)) = woken.as_mut() {
            schedule.ticked(woke);
        }
        let (dt, skipped_before) = match prev {
            // A woken loop has no grid and skips nothing.
            Some((_, prev_woke)) if woken.is_some() => {
                (woke.saturating_duration_since(prev_woke), 0)
            }
            Some((prev_scheduled, prev_woke)) => {
                // Deadlines sit on the grid start + k·period, so the gap in whole periods minus
                // one is the number of ticks the skip policy dropped (0 under catch-up).
                let gap = scheduled
                    .saturating_duration_since(prev_scheduled)
                    .as_nanos();
                let periods = (gap + period_ns / 2) / period_ns;
                (
                    woke.saturating_duration_since(prev_woke),
                    u64::try_from(periods.saturating_sub(1)).unwrap_or(u64::MAX),
                )
            }
            None => (period, 0),
        };
        let info = TickInfo {
            index,
            scheduled,
            woke,
            dt,
            skipped_before,
            nominal_period: period,
        };
        let flow = {
            // Marks the tick on this thread: a blocking path inside it trips
            // `assert_not_in_tick` (see `crate::blocking`).
            let _tick = crate::blocking::enter_tick();
            body(&info)
        };
        let compute = woke.elapsed();
        recorder.record_tick(&TickTiming {
            scheduled,
            woke,
            compute,
            skipped_before,
        });
        control.heartbeat.beat();
        prev = Some((scheduled, woke));
        index += 1;
        if stats_every > 0 && index.is_multiple_of(stats_every) {
            let stats = recorder.stats();
            control.stats.write_with(|slot| *slot = stats);
        }
        if flow.is_break() {
            break StopReason::BodyFinished;
        }
    };
    let stats = recorder.stats();
    control.stats.write_with(|slot| *slot = stats);
    LoopReport {
        config,
        rt,
        pin,
        stop_reason,
        recorder,
    }
}

/// A loop running on its own named thread.
pub struct LoopHandle {
    name: String,
    rt: RtOutcome,
    pin: PinOutcome,
    monitor: LoopMonitor,
    /// Always `Some` until [`LoopHandle::join`] takes it (a type with `Drop` cannot move a
    /// field out).
    thread: Option<JoinHandle<LoopReport>>,
}

/// Starts `body` in a loop on a new thread named `config.name`, after raising its priority and
/// pinning it as configured. Returns once the thread is set up, so [`LoopHandle::rt_outcome`] is
/// already known.
///
/// # Errors
/// [`LoopError::InvalidConfig`] for a bad configuration, [`LoopError::Spawn`] if the OS cannot
/// start the thread, [`LoopError::Panicked`] if the thread died during set-up.
pub fn spawn_loop<F>(config: LoopConfig, body: F) -> Result<LoopHandle, LoopError>
where
    F: FnMut(&TickInfo) -> ControlFlow<()> + Send + 'static,
{
    spawn_loop_with(config, move || body)
}

/// As [`spawn_loop`], but builds the tick closure on the loop thread (after priority and
/// pinning), for state that must be created there or is not `Send`.
///
/// # Errors
/// As [`spawn_loop`].
pub fn spawn_loop_with<M, F>(config: LoopConfig, make_body: M) -> Result<LoopHandle, LoopError>
where
    M: FnOnce() -> F + Send + 'static,
    F: FnMut(&TickInfo) -> ControlFlow<()>,
{
    spawn_prepared(config, None, make_body)
}

/// As [`spawn_loop`], for a loop that also ticks when `wake`'s bell rings: a ring starts a
/// tick at once, but never sooner after the previous tick than the waiter's rate cap; without
/// a ring a tick is due one period after the previous one (see [`crate::wake`]).
///
/// # Errors
/// As [`spawn_loop`].
pub fn spawn_woken_loop<F>(
    config: LoopConfig,
    wake: WakeWaiter,
    body: F,
) -> Result<LoopHandle, LoopError>
where
    F: FnMut(&TickInfo) -> ControlFlow<()> + Send + 'static,
{
    spawn_prepared(config, Some(wake), move || body)
}

fn spawn_prepared<M, F>(
    config: LoopConfig,
    wake: Option<WakeWaiter>,
    make_body: M,
) -> Result<LoopHandle, LoopError>
where
    M: FnOnce() -> F + Send + 'static,
    F: FnMut(&TickInfo) -> ControlFlow<()>,
{
    config.validate()?;
    let (control, mut monitor) = loop_control();
    monitor.wake = wake.as_ref().map(WakeWaiter::bell);
    let (ready_tx, ready_rx) = mpsc::sync_channel::<(RtOutcome, PinOutcome)>(1);
    let name = config.name.clone();
    let thread = std::thread::Builder::new()
        .name(name.clone())
        .spawn(move || {
            let (rt, pin) = prepare_thread(&config);
            // The receiver only disappears if spawn_loop_with itself is gone; nothing to tell.
            let _ = ready_tx.send((rt, pin));
            let body = make_body();
            run_prepared(config, rt, pin, control, body, wake)
        })
        .map_err(|source| LoopError::Spawn {
            loop_name: name.clone(),
            source,
        })?;
    match ready_rx.recv() {
        Ok((rt, pin)) => Ok(LoopHandle {
            name,
            rt,
            pin,
            monitor,
            thread: Some(thread),
        }),
        Err(_) => Err(LoopError::Panicked {
            message: panic_message(thread.join().err()),
            loop_name: name,
        }),
    }
}

fn panic_message(payload: Option<Box<dyn std::any::Any + Send>>) -> String {
    match payload {
        Some(p) => p
            .downcast_ref::<&str>()
            .map(|s| (*s).to_owned())
            .or_else(|| p.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "non-string panic payload".to_owned()),
        None => "thread ended before reporting its set-up".to_owned(),
    }
}

impl LoopHandle {
    /// The loop's name.
    #[must_use]
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Whether the loop thread got real-time priority.
    #[must_use]
    pub fn rt_outcome(&self) -> RtOutcome {
        self.rt
    }

    /// Whether the loop thread was pinned.
    #[must_use]
    pub fn pin_outcome(&self) -> PinOutcome {
        self.pin
    }

    /// Stop flag, heartbeat and published statistics.
    pub fn monitor(&mut self) -> &mut LoopMonitor {
        &mut self.monitor
    }

    /// Asks the loop to stop after its current tick (does not wait).
    pub fn stop(&self) {
        self.monitor.stop();
    }

    /// True once the loop thread has ended (stopped, broke out or panicked).
    #[must_use]
    pub fn is_finished(&self) -> bool {
        self.thread.as_ref().is_none_or(JoinHandle::is_finished)
    }

    /// A summary from the latest published statistics, without stopping the loop. Wait-free
    /// on the loop's side; allocates here (the name).
    pub fn latest_summary(&mut self) -> LoopSummary {
        LoopSummary {
            name: self.name.clone(),
            rt_priority: self.rt,
            pinning: self.pin,
            stats: self.monitor.latest_stats().value,
        }
    }

    /// Waits for the loop to end (it ends when stopped or when its closure breaks) and returns
    /// its report. Does not stop it: call [`stop`](Self::stop) first, or use
    /// [`stop_and_join`](Self::stop_and_join).
    ///
    /// # Errors
    /// [`LoopError::Panicked`] if the tick closure panicked.
    pub fn join(mut self) -> Result<LoopReport, LoopError> {
        let thread = self
            .thread
            .take()
            .unwrap_or_else(|| unreachable!("only join takes the thread, and it consumes"));
        thread.join().map_err(|p| LoopError::Panicked {
            loop_name: std::mem::take(&mut self.name),
            message: panic_message(Some(p)),
        })
    }

    /// Stops the loop and waits for its report.
    ///
    /// # Errors
    /// [`LoopError::Panicked`] if the tick closure panicked.
    pub fn stop_and_join(self) -> Result<LoopReport, LoopError> {
        self.stop();
        self.join()
    }
}

/// A handle dropped without [`LoopHandle::join`] stops its loop and waits for the thread to
/// end, so no loop outlives its owner (a loop's state, a device among it, is dropped on its
/// own thread when that ends). The loop's report, or its panic, is discarded. A handle
/// dropped on a loop thread (inside a tick) would wait there, which the blocking check
/// flags.
impl Drop for LoopHandle {
    fn drop(&mut self) {
        if let Some(thread) = self.thread.take() {
            self.monitor.stop();
            crate::blocking::assert_not_in_tick("dropping a LoopHandle joins its thread");
            let _ = thread.join();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rejects_bad_configs() {
        for (config, field) in [
            (LoopConfig::new("x").with_rate_hz(0.0), "rate_hz"),
            (LoopConfig::new("x").with_rate_hz(f64::NAN), "rate_hz"),
            (LoopConfig::new("x").with_rate_hz(1e9), "rate_hz"),
            (LoopConfig::new(""), "name"),
            (LoopConfig::new("a\0b"), "name"),
        ] {
            match spawn_loop(config, |_| ControlFlow::Break(())) {
                Err(LoopError::InvalidConfig { field: f, .. }) => assert_eq!(f, field),
                Err(e) => panic!("wrong error {e}"),
                Ok(_) => panic!("accepted a bad config for {field}"),
            }
        }
    }

    #[test]
    fn error_messages_name_loop_and_field() {
        let err = LoopConfig::new("haptic").with_rate_hz(-1.0).validate();
        let text = err.map_err(|e| e.to_string()).expect_err("invalid");
        assert!(
            text.contains("haptic") && text.contains("rate_hz"),
            "{text}"
        );
    }

    #[test]
    fn body_break_ends_the_loop_after_exact_tick_count() {
        let handle = spawn_loop(LoopConfig::new("t-break").with_rate_hz(4000.0), |t| {
            if t.index == 49 {
                ControlFlow::Break(())
            } else {
                ControlFlow::Continue(())
            }
        })
        .expect("spawn");
        let report = handle.join().expect("join");
        assert_eq!(report.stop_reason, StopReason::BodyFinished);
        assert_eq!(report.recorder.ticks(), 50);
        assert_eq!(report.summary().stats.ticks, 50);
    }

    /// A handle dropped without join stops its loop and waits for the thread: the loop's
    /// state (here a flag set when the closure is dropped, at the thread's end) is gone by the
    /// time the drop returns.
    #[test]
    fn dropping_a_handle_stops_and_joins_its_loop() {
        struct SetOnDrop(std::sync::Arc<std::sync::atomic::AtomicBool>);
        impl Drop for SetOnDrop {
            fn drop(&mut self) {
                self.0.store(true, std::sync::atomic::Ordering::SeqCst);
            }
        }
        let ended = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
        let guard = SetOnDrop(ended.clone());
        let (tick_tx, tick_rx) = mpsc::channel();
        let handle = spawn_loop(LoopConfig::new("t-drop"), move |_| {
            let _ = &guard;
            let _ = tick_tx.send(());
            ControlFlow::Continue(())
        })
        .expect("spawn");
        tick_rx.recv().expect("a first tick");
        assert!(!ended.load(std::sync::atomic::Ordering::SeqCst));
        drop(handle);
        assert!(
            ended.load(std::sync::atomic::Ordering::SeqCst),
            "the loop's state outlived its handle"
        );
    }

    #[test]
    fn stop_flag_stops_a_running_loop_and_names_the_thread() {
        let (name_tx, name_rx) = mpsc::channel();
        let mut handle = spawn_loop(LoopConfig::new("t-stop"), move |t| {
            if t.index == 0 {
                let _ = name_tx.send(std::thread::current().name().map(str::to_owned));
            }
            ControlFlow::Continue(())
        })
        .expect("spawn");
        assert_eq!(
            name_rx.recv().expect("first tick"),
            Some("t-stop".to_owned())
        );
        let mut dog = handle.monitor().watchdog(Duration::from_secs(5));
        std::thread::sleep(Duration::from_millis(20));
        assert!(dog.check().is_alive());
        assert!(!handle.is_finished());
        let report = handle.stop_and_join().expect("join");
        assert_eq!(report.stop_reason, StopReason::StopRequested);
        assert!(report.recorder.ticks() > 0);
        assert_eq!(report.rt, RtOutcome::NotRequested);
    }

    #[test]
    fn tick_indices_count_up_and_dt_is_positive() {
        let mut seen = Vec::with_capacity(20);
        let (control, _monitor) = loop_control();
        let report = run_loop(
            &LoopConfig::new("t-info").with_rate_hz(2000.0),
            control,
            |t| {
                seen.push((t.index, t.dt, t.nominal_period));
                if seen.len() == 20 {
                    ControlFlow::Break(())
                } else {
                    ControlFlow::Continue(())
                }
            },
        )
        .expect("run");
        assert_eq!(report.recorder.ticks(), 20);
        for (i, (index, dt, nominal)) in seen.iter().enumerate() {
            assert_eq!(*index, i as u64);
            assert_eq!(*nominal, Duration::from_micros(500));
            assert!(*dt > Duration::ZERO);
        }
    }

    #[test]
    fn skip_policy_drops_ticks_after_a_long_one_and_catch_up_does_not() {
        for (policy, expect_skips) in [(OverrunPolicy::Skip, true), (OverrunPolicy::CatchUp, false)]
        {
            let (control, _monitor) = loop_control();
            let mut skipped = 0;
            let report = run_loop(
                &LoopConfig::new("t-overrun")
                    .with_rate_hz(1000.0)
                    .with_overrun(policy),
                control,
                |t| {
                    skipped += t.skipped_before;
                    if t.index == 2 {
                        // Overrun by several periods.
                        std::thread::sleep(Duration::from_millis(5));
                    }
                    if t.index == 12 {
                        ControlFlow::Break(())
                    } else {
                        ControlFlow::Continue(())
                    }
                },
            )
            .expect("run");
            let stats = report.recorder.stats();
            assert!(stats.deadline_misses >= 1, "{policy:?}");
            assert_eq!(stats.skipped_ticks, skipped, "{policy:?}");
            if expect_skips {
                assert!(skipped >= 3, "skip policy dropped only {skipped}");
            } else {
                assert_eq!(skipped, 0, "catch-up must run every tick");
            }
        }
    }

    #[test]
    fn never_runs_ahead_of_its_deadline_grid_at_1khz_and_4khz() {
        // Whatever the machine's load: never more ticks than were due, and the rate it reports
        // never above the nominal one. How far behind a loaded machine falls belongs in bench/.
        for rate_hz in [1000.0, 4000.0] {
            // Before the spawn: the loop's deadline grid starts on its own thread, possibly
            // before spawn_loop returns here.
            let started = Instant::now();
            let mut handle = spawn_loop(
                LoopConfig::new("t-rate")
                    .with_rate_hz(rate_hz)
                    .with_stats_every_ticks(10),
                |_| ControlFlow::Continue(()),
            )
            .expect("spawn");
            // Run until the loop has published its figures once (ten ticks), however late.
            let patience = started + Duration::from_secs(60);
            while handle.monitor().latest_stats().version == 0 && Instant::now() < patience {
                std::thread::sleep(Duration::from_millis(1));
            }
            let report = handle.stop_and_join().expect("join");
            let elapsed_s = started.elapsed().as_secs_f64();
            let ticks = report.recorder.ticks() as f64;
            assert!(ticks >= 10.0, "{ticks} ticks before the first figures");
            assert!(
                ticks <= rate_hz * elapsed_s + 2.0,
                "{ticks} ticks in {elapsed_s} s at {rate_hz} Hz"
            );
            let stats = report.recorder.stats();
            assert!(stats.achieved_rate_hz <= rate_hz * 1.01, "{stats:?}");
            assert!((stats.nominal_rate_hz - rate_hz).abs() < 1e-6);
        }
    }

    /// A woken loop whose period is far longer than the test ticks once at its start and
    /// then once per ring: every tick after the first is the bell's, none the period's. Its
    /// stop ends it at once, asleep as it is.
    #[test]
    fn each_ring_starts_one_tick_without_waiting_for_the_period() {
        let (bell, waiter) = crate::wake_bell(1000.0).expect("valid cap");
        let (tick_tx, tick_rx) = mpsc::channel();
        let handle = spawn_woken_loop(
            LoopConfig::new("t-woken").with_rate_hz(0.001),
            waiter,
            move |t| {
                let _ = tick_tx.send((t.index, t.skipped_before));
                ControlFlow::Continue(())
            },
        )
        .expect("spawn");
        assert_eq!(tick_rx.recv().expect("the first tick"), (0, 0));
        for index in 1..=3 {
            bell.ring();
            assert_eq!(tick_rx.recv().expect("a woken tick"), (index, 0));
        }
        let report = handle.stop_and_join().expect("join");
        assert_eq!(report.stop_reason, StopReason::StopRequested);
        assert_eq!(report.recorder.ticks(), 4, "no tick without a ring");
    }

    #[test]
    fn stats_are_published_while_running() {
        let mut handle = spawn_loop(
            LoopConfig::new("t-stats")
                .with_rate_hz(4000.0)
                .with_stats_every_ticks(10),
            |_| ControlFlow::Continue(()),
        )
        .expect("spawn");
        let deadline = Instant::now() + Duration::from_secs(10);
        while handle.monitor().latest_stats().version == 0 && Instant::now() < deadline {
            std::thread::sleep(Duration::from_millis(1));
        }
        let summary = handle.latest_summary();
        assert_eq!(summary.name, "t-stats");
        assert!(summary.stats.ticks >= 10);
        assert_eq!(summary.stats.ticks % 10, 0);
        handle.stop_and_join().expect("join");
    }

    #[test]
    fn a_blocking_receive_in_a_tick_is_caught_on_its_first_tick() {
        // The sender stays alive: without the check this tick would wait forever.
        let (_tx, rx) = mpsc::channel::<u32>();
        let handle = spawn_loop(LoopConfig::new("t-blocks"), move |_| {
            crate::assert_not_in_tick("mpsc::Receiver::recv");
            let _ = rx.recv();
            ControlFlow::Continue(())
        })
        .expect("spawn");
        match handle.join() {
            Err(LoopError::Panicked { loop_name, message }) => {
                assert_eq!(loop_name, "t-blocks");
                assert!(message.contains("mpsc::Receiver::recv"), "{message}");
                assert!(message.contains("t-blocks"), "names the thread: {message}");
            }
            other => panic!(
                "expected the check to stop the loop, got {:?}",
                other.map(|r| r.stop_reason)
            ),
        }
    }

    #[test]
    fn non_blocking_calls_in_a_tick_pass_and_the_mark_ends_with_the_tick() {
        let (tx, rx) = mpsc::channel::<u32>();
        tx.send(7).expect("send");
        let handle = spawn_loop(LoopConfig::new("t-try").with_rate_hz(4000.0), move |t| {
            assert!(crate::in_tick());
            // try_recv never waits: no check needed, nothing fires.
            let _ = rx.try_recv();
            if t.index == 9 {
                ControlFlow::Break(())
            } else {
                ControlFlow::Continue(())
            }
        })
        .expect("spawn");
        let report = handle.join().expect("no check fired");
        assert_eq!(report.stop_reason, StopReason::BodyFinished);
        assert!(!crate::in_tick(), "the caller was never in a tick");
    }

    #[test]
    fn panicking_body_is_reported_as_an_error() {
        let handle = spawn_loop(LoopConfig::new("t-panic"), |_| panic!("boom")).expect("spawn");
        match handle.join() {
            Err(LoopError::Panicked { loop_name, message }) => {
                assert_eq!(loop_name, "t-panic");
                assert!(message.contains("boom"));
            }
            other => panic!("expected a panic error, got {other:?}"),
        }
    }

    #[test]
    fn rt_request_is_reported_and_never_fails_the_loop() {
        let handle = spawn_loop(
            LoopConfig::new("t-rt").with_rt_priority(crate::DEFAULT_RT_PRIORITY),
            |t| {
                if t.index == 5 {
                    ControlFlow::Break(())
                } else {
                    ControlFlow::Continue(())
                }
            },
        )
        .expect("spawn");
        let rt = handle.rt_outcome();
        assert!(
            matches!(
                rt,
                RtOutcome::Granted { .. } | RtOutcome::Denied { .. } | RtOutcome::Unsupported
            ),
            "{rt:?}"
        );
        let report = handle.join().expect("join");
        assert_eq!(report.recorder.ticks(), 6);
        assert_eq!(report.rt, rt);
    }
}
