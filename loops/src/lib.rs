//! Fixed-rate real-time loops, lock-free triple-buffer exchange and latency recording. Knows
//! nothing of geometry.
//!
//! Guarantees on the real-time path (after set-up): [`SnapshotWriter::publish`],
//! [`SnapshotReader::latest`], [`LatencyRecorder::record_tick`], [`Heartbeat::beat`],
//! [`StopFlag::is_stopped`] and [`Staleness::factor`] are wait-free and never allocate; the loop
//! body run by [`spawn_loop`]/[`run_loop`] is surrounded by nothing that allocates or locks.
//! Set-up (spawning, priority requests, pinning, building recorders and channels) allocates
//! and makes system calls, and so do reports (JSON, Markdown, SVG); keep those off the loop.
//!
//! - [`runner`](spawn_loop): absolute-deadline loop on `spin_sleep_util::Interval`, overrun
//!   policy, stop flag, named threads, per-tick [`TickInfo`].
//! - [`request_realtime`] / [`pin_current_thread`]: SCHED_FIFO and core pinning as outcome
//!   values ([`RtOutcome`], [`PinOutcome`]); never fail a loop.
//! - [`snapshot_channel`]: versioned, time-stamped triple buffer (the `triple_buffer` crate).
//! - [`LatencyRecorder`] → [`LatencyStats`] → [`LoopSummary`] → JSON, [`markdown_table`],
//!   [`latency_svg`] / [`latency_png`].
//! - [`assert_not_in_tick`]: the "a tick never blocks" rule, checked at every blocking point
//!   (each tick is marked on its thread; see the `blocking` module's docs for the rule).
//! - [`wake_bell`] + [`spawn_woken_loop`]: a loop that also ticks when another thread rings
//!   its [`WakeBell`] (lock-free), no faster than a rate cap.
//! - [`Staleness`] (fade factor from data age) and [`Watchdog`] (stalled-loop detection).
//! - [`LogBins`]: coarse half-octave bins published with [`LatencyStats`] for live plots.
//! - [`Timeline`]: a recorder's run over time in fixed memory, for the timeline plot.
//! - [`run_probes`]: the platform probe (cyclictest-style wake-ups, host stalls) →
//!   [`ProbeSummary`]; [`read_platform_facts`] + [`verdict`]: is the machine fit for a rate;
//!   [`ProfileDoc`] (the `latency.json` document), [`profile_report`], [`probe_table`],
//!   [`compare_table`].

#![deny(unsafe_op_in_unsafe_fn)]
#![warn(clippy::undocumented_unsafe_blocks)]
#![warn(missing_docs)]

mod blocking;
mod exchange;
mod glyphs;
mod live;
mod motion;
mod plot;
mod priority;
mod probe;
mod readiness;
mod recorder;
mod report;
mod runner;
mod staleness;
mod summary;
mod table;
mod timeline;
mod wake;
mod watchdog;

pub use blocking::{
    BLOCKING_CHECK_PANICS, TickMark, assert_not_in_tick, blocking_in_tick_count, enter_tick,
    in_tick,
};
pub use exchange::{SnapshotReader, SnapshotWriter, Stamped, snapshot_channel};
pub use live::{LOG_BINS, LogBins};
pub use motion::{MotionToPhotonSummary, Spread, StageSpreads, motion_table};
pub use plot::{
    PlotError, latency_png, latency_svg, page_size, share_label, time_label, write_latency_svg,
};
pub use priority::{
    DEFAULT_RT_PRIORITY, PinOutcome, RtOutcome, current_schedule, pin_current_thread,
    request_realtime,
};
pub use probe::{
    DEFAULT_GAP_THRESHOLD, GAP_FLOORS_NS, GapCounts, ProbeRun, ProbeSummary, StallCounter,
    StallStats, run_probes, run_stall_probe, run_wakeup_probe,
};
pub use readiness::{
    FACT_FILE_CAP, Finding, Grade, LoopRecord, Measure, PlatformFacts, Problem, THRESHOLDS,
    Threshold, Verdict, busy_fraction, cpu_jiffies, plain_summary, read_fact_file,
    read_platform_facts, verdict, verdict_text,
};
pub use recorder::{
    LATE_1MS, LATE_2MS, LatencyRecorder, LatencyStats, MAX_RECORDABLE, Percentiles, TickTiming,
};
pub use report::{HAPTIC_LOOP, profile_report};
pub use runner::{
    LoopConfig, LoopControl, LoopError, LoopHandle, LoopMonitor, LoopReport, MAX_RATE_HZ,
    OverrunPolicy, StopFlag, StopReason, TickInfo, loop_control, run_loop, spawn_loop,
    spawn_loop_with, spawn_woken_loop,
};
pub use staleness::Staleness;
pub use summary::{LoopSummary, ProfileDoc, summaries_from_json, summaries_to_json};
pub use table::{compare_table, markdown_table, probe_table};
pub use timeline::{FIRST_WINDOW, TIMELINE_WINDOWS, Timeline, TimelineWindow};
pub use wake::{
    MAX_WAKE_RATE_HZ, WakeBell, WakeDecision, WakeError, WakeSchedule, WakeWaiter, wake_bell,
};
pub use watchdog::{Heartbeat, Liveness, Watchdog};
