//! Engine-wide event counters, shared between the loops and whoever watches them.
//!
//! Guarantee: every update is one relaxed atomic add or store — wait-free and allocation-free,
//! safe on the haptic path. Counters carry no data that other memory depends on, so Relaxed
//! suffices; a reader gets each value eventually and the final values after the loops are
//! joined (thread join synchronises).

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

/// The live counters (cheap to clone: an `Arc`).
#[derive(Clone, Debug, Default)]
pub struct EngineCounters {
    inner: Arc<Inner>,
}

#[derive(Debug, Default)]
struct Inner {
    haptic_ticks: AtomicU64,
    device_read_faults: AtomicU64,
    device_write_faults: AtomicU64,
    stale_ticks: AtomicU64,
    contact_ticks: AtomicU64,
    nonfinite_forces: AtomicU64,
    device_swaps: AtomicU64,
    sim_steps: AtomicU64,
    sim_substeps: AtomicU64,
    sim_nonfinite_rejected: AtomicU64,
    snapshots_published: AtomicU64,
    commands_applied: AtomicU64,
    command_errors: AtomicU64,
    graphics_updates: AtomicU64,
    bricks_remeshed: AtomicU64,
    graphics_deferred: AtomicU64,
    peak_force_milli_n: AtomicU64,
    clay_growths: AtomicU64,
    budget_refusals: AtomicU64,
    auto_refines: AtomicU64,
    auto_coarsenings: AtomicU64,
    haptic_updates_awaiting_bricks: AtomicU64,
    updates_as_copies: AtomicU64,
}

/// A plain copy of the counters at one moment.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct CounterSnapshot {
    /// Haptic ticks run.
    pub haptic_ticks: u64,
    /// Device `read` calls that failed (disconnect, timeout, protocol, end of replay).
    pub device_read_faults: u64,
    /// Device `write_force` calls that failed.
    pub device_write_faults: u64,
    /// Haptic ticks whose field snapshot was past the staleness limit (force faded to zero).
    pub stale_ticks: u64,
    /// Haptic ticks with the tool in contact during an active stroke.
    pub contact_ticks: u64,
    /// Computed forces that were NaN or infinite and replaced by zero before the filter.
    pub nonfinite_forces: u64,
    /// Devices replaced (connected, switched or disconnected) while the engine ran.
    #[serde(default)]
    pub device_swaps: u64,
    /// Simulation steps taken.
    pub sim_steps: u64,
    /// Adaptive sub-steps inside those steps.
    pub sim_substeps: u64,
    /// Simulation steps rejected because they produced a non-finite value.
    pub sim_nonfinite_rejected: u64,
    /// Region snapshots published by the simulation.
    pub snapshots_published: u64,
    /// Commands applied by the simulation thread.
    pub commands_applied: u64,
    /// Commands that failed (reported on the reply channel or logged at the end).
    pub command_errors: u64,
    /// Graphics updates (snapshots turned into meshes).
    pub graphics_updates: u64,
    /// Octree bricks re-meshed by those updates.
    pub bricks_remeshed: u64,
    /// Snapshots whose change the graphics loop applied but did not re-mesh yet: too small to
    /// see (see [`crate::graphics`]).
    #[serde(default)]
    pub graphics_deferred: u64,
    /// Largest force magnitude sent to the device, millinewtons.
    pub peak_force_milli_n: u64,
    /// Times the base patch grew to take an edit past its box.
    #[serde(default)]
    pub clay_growths: u64,
    /// Edits refused for one of the clay's budgets (its dense bricks or its box): a stroke's
    /// region, a tool's application, a growth. Each left the clay as it was; the latest is in
    /// [`crate::SimStatus::budget_refusal`] and the run's report.
    #[serde(default)]
    pub budget_refusals: u64,
    /// Detail patches added under a fine brush without being asked.
    #[serde(default)]
    pub auto_refines: u64,
    /// Detail patches folded back into coarser ones once a step had wiped their detail.
    #[serde(default)]
    pub auto_coarsenings: u64,
    /// Haptic ticks that left a new field update unapplied because the pool of spare dense
    /// bricks could not yet cover it (see [`crate::HAPTIC_SPARE_BRICKS`]); the tick applies it once the
    /// simulation has topped the pool up.
    #[serde(default)]
    pub haptic_updates_awaiting_bricks: u64,
    /// Publications whose changed boxes held more than
    /// [`crate::MAX_UPDATE_COEFFS`] coefficients, sent to the loops as a copy of the
    /// clay instead.
    #[serde(default)]
    pub updates_as_copies: u64,
}

macro_rules! bump {
    ($($name:ident),* $(,)?) => {
        $(
            #[doc = concat!("Adds `n` to `", stringify!($name), "`.")]
            #[inline]
            pub fn $name(&self, n: u64) {
                self.inner.$name.fetch_add(n, Ordering::Relaxed);
            }
        )*
    };
}

impl EngineCounters {
    /// Fresh counters, all zero.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    bump!(
        haptic_ticks,
        device_read_faults,
        device_write_faults,
        stale_ticks,
        contact_ticks,
        nonfinite_forces,
        device_swaps,
        sim_steps,
        sim_substeps,
        sim_nonfinite_rejected,
        snapshots_published,
        commands_applied,
        command_errors,
        graphics_updates,
        bricks_remeshed,
        graphics_deferred,
        clay_growths,
        budget_refusals,
        auto_refines,
        auto_coarsenings,
        haptic_updates_awaiting_bricks,
        updates_as_copies,
    );

    /// Raises the recorded peak force to `force_n` if larger.
    #[inline]
    pub fn note_force(&self, force_n: f32) {
        if force_n.is_finite() && force_n > 0.0 {
            let milli = (force_n * 1000.0) as u64;
            self.inner
                .peak_force_milli_n
                .fetch_max(milli, Ordering::Relaxed);
        }
    }

    /// Haptic ticks so far (cheap; for watchdogs and tests).
    #[must_use]
    pub fn haptic_tick_count(&self) -> u64 {
        self.inner.haptic_ticks.load(Ordering::Relaxed)
    }

    /// A copy of every counter.
    #[must_use]
    pub fn snapshot(&self) -> CounterSnapshot {
        let i = &self.inner;
        let r = |a: &AtomicU64| a.load(Ordering::Relaxed);
        CounterSnapshot {
            haptic_ticks: r(&i.haptic_ticks),
            device_read_faults: r(&i.device_read_faults),
            device_write_faults: r(&i.device_write_faults),
            stale_ticks: r(&i.stale_ticks),
            contact_ticks: r(&i.contact_ticks),
            nonfinite_forces: r(&i.nonfinite_forces),
            device_swaps: r(&i.device_swaps),
            sim_steps: r(&i.sim_steps),
            sim_substeps: r(&i.sim_substeps),
            sim_nonfinite_rejected: r(&i.sim_nonfinite_rejected),
            snapshots_published: r(&i.snapshots_published),
            commands_applied: r(&i.commands_applied),
            command_errors: r(&i.command_errors),
            graphics_updates: r(&i.graphics_updates),
            bricks_remeshed: r(&i.bricks_remeshed),
            graphics_deferred: r(&i.graphics_deferred),
            peak_force_milli_n: r(&i.peak_force_milli_n),
            clay_growths: r(&i.clay_growths),
            budget_refusals: r(&i.budget_refusals),
            auto_refines: r(&i.auto_refines),
            auto_coarsenings: r(&i.auto_coarsenings),
            haptic_updates_awaiting_bricks: r(&i.haptic_updates_awaiting_bricks),
            updates_as_copies: r(&i.updates_as_copies),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_and_peaks() {
        let c = EngineCounters::new();
        let c2 = c.clone();
        c.haptic_ticks(3);
        c2.device_read_faults(1);
        c.note_force(1.5);
        c.note_force(0.5);
        c.note_force(f32::NAN);
        let s = c.snapshot();
        assert_eq!(s.haptic_ticks, 3);
        assert_eq!(s.device_read_faults, 1);
        assert_eq!(s.peak_force_milli_n, 1500);
    }
}
