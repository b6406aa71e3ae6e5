//! The haptic stage: one tick of the 1 kHz loop, callable directly from a test.
//!
//! Guarantee: after [`HapticStage::new`], [`HapticStage::tick`] allocates nothing, takes no
//! blocking lock and does bounded work: one device read and one write (through the safety
//! filter), one wait-free triple-buffer fetch and one publish, a patch copy of at most the
//! lattice's coefficients and of the stroke geometry (fixed capacity) when a new snapshot
//! arrived (the stage's copy of the field is sparse: before the copy, the uniform bricks it
//! would make dense are made dense with storage taken from a pool the simulation fills, at
//! most [`crate::HAPTIC_SPARE_BRICKS`] of them per tick; an update the pool cannot cover yet
//! waits for the next tick, see [`super::layout`]), the force renderer's bounded work ([`dynaclay_core::haptics::ForceRenderer`]: the touch
//! proxy, at most one sculpting reaction, blending, passivity and shaping), one relaxed load
//! each of the requested force limit ([`ForceLimit`]), applied to the filter in constant time
//! when it changed, and of the haptic gain ([`HapticGain`]), and one wait-free look for a
//! replacement device ([`super::DeviceSwapPort`]), installed by moving it into the slot (it
//! was opened, and the old one is closed, on another thread). No file or log I/O.
//!
//! Order within a tick: read the device → fetch the newest field patch → force limit → render
//! (touch, eq. 6 reaction, blend, fade by the snapshot's age, passivity, shaping) → safety
//! filter → write → publish the tool sample.
//! On a device error the filter has already sent zero; the tick publishes an idle sample and
//! returns, so the loop keeps its rate and retries next tick.

use std::time::Instant;

use dynaclay_devices::record::{ScheduleLog, ScheduleNote};
use dynaclay_devices::{HapticDevice, SafetyFilter};
use dynaclay_loops::{SnapshotReader, SnapshotWriter, Staleness};
use glam::{Quat, Vec3};

use super::clock::EngineClock;
use super::counters::EngineCounters;
use super::device_swap::{DeviceHandover, DeviceSwapPort};
use super::force_limit::ForceLimit;
use super::haptic_gain::HapticGain;
use super::layout::LayoutPort;
use super::motion_to_photon::FeltChange;
use super::tool_sample::ToolSample;
use super::update::FieldUpdate;
use super::workspace::WorkspaceMap;
use dynaclay_core::field::{AllocatingSpares, MultiPatchField};
use dynaclay_core::haptics::{FeltInput, FeltTool, ForceRenderer, HapticConfig, StrokeGeometry};

/// What one tick did (plain data, for tests and the lockstep driver).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HapticOutcome {
    /// The sample published to the simulation.
    pub sample: ToolSample,
    /// The force requested before the safety filter, newtons.
    pub requested_force_n: Vec3,
    /// Fade factor from the field snapshot's age (1 fresh, 0 stale).
    pub fade: f32,
    /// Whether the device read or write failed this tick.
    pub device_fault: bool,
    /// The passivity observer's energy account, joules (negative: a deficit being spent).
    pub passivity_energy_j: f32,
}

/// The haptic loop's state: the device (behind the safety filter), its own field copy and the
/// two triple-buffer ends.
pub struct HapticStage {
    device: SafetyFilter<Box<dyn HapticDevice>>,
    /// Boxed so that a new layout moves in by pointer (see [`super::layout`]).
    field: Box<MultiPatchField>,
    /// The layout generation of `field`.
    layout: u64,
    layouts: LayoutPort,
    updates: SnapshotReader<FieldUpdate>,
    samples: SnapshotWriter<ToolSample>,
    monitor: SnapshotWriter<ToolSample>,
    map: WorkspaceMap,
    staleness: Staleness,
    renderer: ForceRenderer,
    /// The held tool and stroke, from the newest patch.
    tool: FeltTool,
    stroke: StrokeGeometry,
    stroke_armed: bool,
    haptic_gain: HapticGain,
    counters: EngineCounters,
    ack: std::sync::Arc<std::sync::atomic::AtomicU64>,
    tick: u64,
    last: ToolSample,
    /// The user's force limit, and the request bits last applied to the filter.
    force_limit: ForceLimit,
    limit_seen: u32,
    /// Where a replacement device arrives while running, and the old one leaves.
    swaps: DeviceSwapPort,
    /// Whether a device is connected (false after a disconnect: the loop ticks idle).
    connected: bool,
    /// Where each tick's schedule is noted while a recording runs (see [`ScheduleNote`]).
    schedule: Option<ScheduleLog>,
    /// Version of the snapshot this tick fetched, if it fetched one.
    fetched: Option<u64>,
    /// The engine's clock: when each tick read the device.
    clock: EngineClock,
    /// What this loop has felt of the newest stroke's first change.
    felt: FeltChange,
    /// Failed reads since the last good one: a stroke is held through at most
    /// [`STROKE_HELD_THROUGH_FAULTS`] of them.
    faults_in_a_row: u32,
}

/// Failed reads in a row through which a held stroke stays held (100 ms at 1 kHz). A read
/// that fails says nothing of the buttons: a lost sample must not release the stroke and start
/// another (a second undo step, the tool's grab and targets forgotten, the groove carved on
/// differently than the unbroken stroke), while an arm that stays gone does end it.
pub const STROKE_HELD_THROUGH_FAULTS: u32 = 100;

impl HapticStage {
    /// Builds the stage around an opened device.
    ///
    /// `field` is the starting field (the simulation's at version 0); `ack` receives the
    /// version of every patch applied, so the simulation knows what this reader has seen.
    /// Samples go to the simulation on `samples` and to observers (GUI, tests) on `monitor`.
    #[allow(clippy::too_many_arguments)] // set-up only: each part is a distinct channel end
    #[must_use]
    pub fn new(
        device: SafetyFilter<Box<dyn HapticDevice>>,
        field: MultiPatchField,
        layouts: LayoutPort,
        updates: SnapshotReader<FieldUpdate>,
        samples: SnapshotWriter<ToolSample>,
        monitor: SnapshotWriter<ToolSample>,
        map: WorkspaceMap,
        staleness: Staleness,
        haptics: HapticConfig,
        counters: EngineCounters,
        ack: std::sync::Arc<std::sync::atomic::AtomicU64>,
        swaps: DeviceSwapPort,
        clock: EngineClock,
    ) -> Self {
        let requested = device.config().max_force_n;
        let force_limit = ForceLimit::new(requested, device.max_force_n());
        // The copy stays as sparse as `field`: the tick makes bricks dense from the layout
        // port's pool of spares before it writes an update that needs them.
        Self {
            limit_seen: force_limit.requested_bits(),
            force_limit,
            device,
            field: Box::new(field),
            layout: 0,
            layouts,
            updates,
            samples,
            monitor,
            map,
            staleness,
            renderer: ForceRenderer::new(haptics),
            tool: FeltTool::Push,
            stroke: StrokeGeometry::default(),
            stroke_armed: false,
            haptic_gain: HapticGain::new(haptics.haptic_gain),
            counters,
            ack,
            tick: 0,
            last: ToolSample::IDLE,
            swaps,
            connected: true,
            schedule: None,
            fetched: None,
            clock,
            felt: FeltChange::default(),
            faults_in_a_row: 0,
        }
    }

    /// Notes every tick's snapshot and fade into `log` from now on, so that a replay can give
    /// each tick what this run's tick saw (see [`super::ScheduledReplay`]).
    pub fn set_schedule_log(&mut self, log: ScheduleLog) {
        self.schedule = Some(log);
    }

    /// The device behind the safety filter.
    #[must_use]
    pub fn device(&self) -> &SafetyFilter<Box<dyn HapticDevice>> {
        &self.device
    }

    /// The device, out of its safety filter (to start another engine with it).
    #[must_use]
    pub fn into_device(self) -> Box<dyn HapticDevice> {
        self.device.into_inner()
    }

    /// The device, mutably (to close it at the end).
    pub fn device_mut(&mut self) -> &mut SafetyFilter<Box<dyn HapticDevice>> {
        &mut self.device
    }

    /// A handle on the force limit: requests made through it reach the safety filter at the
    /// next tick (see [`ForceLimit`]).
    #[must_use]
    pub fn force_limit(&self) -> ForceLimit {
        self.force_limit.clone()
    }

    /// A handle on the haptic gain: changes made through it apply from the next tick.
    #[must_use]
    pub fn haptic_gain(&self) -> HapticGain {
        self.haptic_gain.clone()
    }

    /// This stage's copy of the field.
    #[must_use]
    pub fn field(&self) -> &MultiPatchField {
        &self.field
    }

    /// Applies the newest field update without touching the device (used at shutdown).
    pub fn sync_field(&mut self) {
        if let Some(generation) = self.layouts.install(&mut self.field) {
            self.layout = generation;
        }
        let stamped = self.updates.latest();
        if stamped.value.layout == self.layout {
            if !stamped
                .value
                .densify_for_copy(&mut self.field, &mut &self.layouts)
            {
                // Shutdown only: the simulation has stopped topping the pool up; the bricks
                // still missing are allocated here, off the loop.
                stamped
                    .value
                    .densify_for_copy(&mut self.field, &mut AllocatingSpares);
            }
            stamped.value.copy_into(&mut self.field);
            self.ack
                .store(stamped.version, std::sync::atomic::Ordering::Release);
        }
    }

    /// The last sample published.
    #[must_use]
    pub fn last_sample(&self) -> ToolSample {
        self.last
    }

    /// Runs one tick at wall time `now` (used for the snapshot's age).
    pub fn tick(&mut self, now: Instant) -> HapticOutcome {
        self.tick_faded(now, None)
    }

    /// Runs one tick as a recorded run's tick ran: with the staleness fade it applied,
    /// instead of one from the snapshot's age.
    pub fn tick_as_recorded(&mut self, now: Instant, fade: f32) -> HapticOutcome {
        self.tick_faded(now, Some(fade))
    }

    fn tick_faded(&mut self, now: Instant, fade: Option<f32>) -> HapticOutcome {
        self.fetched = None;
        let out = self.tick_inner(now, fade);
        if let Some(log) = &self.schedule {
            log.note(&ScheduleNote::Tick {
                tick: self.tick,
                snapshot_version: self.fetched,
                fade: out.fade,
            });
        }
        out
    }

    fn tick_inner(&mut self, now: Instant, recorded_fade: Option<f32>) -> HapticOutcome {
        self.tick += 1;
        self.counters.haptic_ticks(1);
        if let Some(new) = self.swaps.take() {
            self.install(new);
        }
        if !self.connected {
            // Parked: keep the field copy current (and acknowledged) for the next device.
            self.refresh_field(now);
            return self.publish_idle(false);
        }
        let read = self.device.read();
        let read_ns = self.clock.now_ns();
        let state = match read {
            Ok(s) => {
                self.faults_in_a_row = 0;
                s
            }
            Err(_) => {
                // The filter latched the fault and sent zero already.
                self.counters.device_read_faults(1);
                self.renderer.device_fault();
                self.faults_in_a_row = self.faults_in_a_row.saturating_add(1);
                return self.publish_idle(true);
            }
        };

        let age = self.refresh_field(now);
        let fade = recorded_fade.unwrap_or_else(|| self.staleness.factor(age) as f32);
        if fade <= 0.0 {
            self.counters.stale_ticks(1);
        }
        let tip = self.map.to_field(state.position_m);
        // The workspace map scales and shifts; it does not turn, so the device's orientation is
        // the tool's in field coordinates.
        let rotation = state
            .orientation
            .filter(|q| q.is_finite() && q.length_squared() > 0.5)
            .map_or(Quat::IDENTITY, Quat::normalize);
        let stroke_active = state.button(0) || self.stroke_armed;
        self.apply_force_limit();
        self.renderer.set_haptic_gain(self.haptic_gain.get());
        let felt = self.renderer.render(&FeltInput {
            field: &self.field,
            tip,
            position_m: state.position_m,
            velocity_m_per_s: state.velocity_m_per_s,
            time_us: state.timestamp_us,
            field_per_m: self.map.field_per_m,
            force_n_per_reaction: self.map.force_n_per_reaction,
            stroke_active,
            tool: self.tool,
            stroke: &self.stroke,
            fade,
            saturation_n: self.device.max_force_n(),
            sent_n: self.device.output_force_n(),
            rotation,
            tool_contact: self.device.has_force(),
        });
        let in_contact = felt.touch.touching || felt.sculpting;
        if in_contact {
            self.counters.contact_ticks(1);
        }
        let mut requested = felt.force_n;
        if !requested.is_finite() {
            self.counters.nonfinite_forces(1);
            requested = Vec3::ZERO;
        }
        let device_fault = match self.device.write_force(requested) {
            Ok(()) => false,
            Err(_) => {
                self.counters.device_write_faults(1);
                self.renderer.device_fault();
                true
            }
        };
        let out = self.device.output_force_n();
        self.counters.note_force(out.length());
        let (force_from, force_to) = felt.vector.unwrap_or((tip, tip));
        let sample = ToolSample {
            tip_fu: tip,
            force_from_fu: force_from,
            force_to_fu: force_to,
            stroke_active,
            // A stale field must not keep pushing the clay either.
            in_contact: felt.sculpting && fade > 0.0,
            touching: felt.touch.touching,
            device_force_n: out,
            device_time_us: state.timestamp_us,
            device_fault,
            tick: self.tick,
            rotation,
            resting_at: felt.resting_at,
            press: felt.press,
            force_yield: felt.force_yield,
            read_ns,
            felt: self.felt,
        };
        self.publish(sample, now);
        HapticOutcome {
            sample,
            requested_force_n: requested,
            fade,
            device_fault,
            passivity_energy_j: felt.energy_j,
        }
    }

    /// The force most recently sent to the device, newtons.
    #[must_use]
    pub fn output_force_n(&self) -> Vec3 {
        self.device.output_force_n()
    }

    /// Copies the newest field patch into this stage's field, and its tool and stroke into
    /// this stage, if it is new, and returns the snapshot's age at `now`.
    fn refresh_field(&mut self, now: Instant) -> std::time::Duration {
        if let Some(generation) = self.layouts.install(&mut self.field) {
            self.layout = generation;
        }
        let stamped = self.updates.latest();
        let version = stamped.version;
        self.fetched = Some(version);
        if version != self.ack.load(std::sync::atomic::Ordering::Relaxed) {
            self.tool = stamped.value.tool;
            self.stroke_armed = stamped.value.stroke_armed;
            self.stroke.copy_from(&stamped.value.stroke);
            // An update for another layout waits until that layout's copy arrives; one whose
            // values need more dense bricks than the pool holds yet waits for the pool to be
            // topped up (the bricks taken so far stay dense: no value changes).
            let ready = stamped.value.layout == self.layout
                && stamped
                    .value
                    .densify_for_copy(&mut self.field, &mut &self.layouts);
            if stamped.value.layout == self.layout && !ready {
                self.counters.haptic_updates_awaiting_bricks(1);
            }
            if ready {
                stamped.value.copy_into(&mut self.field);
                // The first snapshot holding the newest stroke's first change: this tick's
                // force is the first rendered on the clay that change made.
                let strokes = stamped.value.stroke_stamps;
                if let Some(first) = strokes.first_change
                    && strokes.stroke != self.felt.stroke
                    && version >= first.snapshot_version
                {
                    self.felt = FeltChange {
                        stroke: strokes.stroke,
                        ticks: self.tick.saturating_sub(first.sample_tick),
                    };
                }
                // NOTE: Release pairs with the simulation's Acquire load: once it sees this
                // version acknowledged, every coefficient of that update is in our copy.
                self.ack
                    .store(version, std::sync::atomic::Ordering::Release);
            }
        }
        stamped.age_at(now)
    }

    /// Whether a device is connected (false after a disconnect).
    #[must_use]
    pub fn is_connected(&self) -> bool {
        self.connected
    }

    /// Puts `new` in the device slot and sends the old device back to be closed off this
    /// thread. Constant work, no allocation: the devices move by value.
    fn install(&mut self, mut new: DeviceHandover) {
        if self.connected {
            // The old device must not keep the last force while it waits to be closed: a
            // disabled filter sends zero at once, not slewed down.
            self.device.set_forces_enabled(false);
            let _ = self.device.write_force(Vec3::ZERO);
        }
        std::mem::swap(&mut self.device, &mut new.device);
        std::mem::swap(&mut self.map, &mut new.map);
        std::mem::swap(&mut self.connected, &mut new.connected);
        self.faults_in_a_row = 0;
        self.renderer.reset();
        // Re-apply the user's limit to the new filter at this tick.
        self.limit_seen = !self.force_limit.requested_bits();
        self.apply_force_limit();
        self.counters.device_swaps(1);
        // NOTE: cannot fail: `take` only hands out a device while the retired slot has room.
        if let Err(old) = self.swaps.retire(new) {
            std::mem::forget(old);
        }
    }

    /// Applies a changed force-limit request to the filter (constant work, no allocation).
    fn apply_force_limit(&mut self) {
        let bits = self.force_limit.requested_bits();
        if bits != self.limit_seen {
            self.limit_seen = bits;
            self.device.set_max_force_n(f32::from_bits(bits));
            self.force_limit.set_applied(self.device.max_force_n());
        }
    }

    /// Publishes a tick with no contact and no force. A read fault holds a held stroke for
    /// [`STROKE_HELD_THROUGH_FAULTS`] failed reads in a row (no contact meanwhile, so nothing
    /// is pushed); idle without a device, the stroke ends.
    fn publish_idle(&mut self, device_fault: bool) -> HapticOutcome {
        let held = device_fault
            && self.last.stroke_active
            && self.faults_in_a_row <= STROKE_HELD_THROUGH_FAULTS;
        let sample = ToolSample {
            stroke_active: held,
            in_contact: false,
            touching: false,
            device_force_n: Vec3::ZERO,
            device_fault,
            tick: self.tick,
            felt: self.felt,
            ..self.last
        };
        self.publish(sample, Instant::now());
        HapticOutcome {
            sample,
            requested_force_n: Vec3::ZERO,
            fade: 0.0,
            device_fault,
            passivity_energy_j: 0.0,
        }
    }

    fn publish(&mut self, sample: ToolSample, now: Instant) {
        self.last = sample;
        *self.samples.back_mut() = sample;
        self.samples.publish_at(now);
        *self.monitor.back_mut() = sample;
        self.monitor.publish_at(now);
    }
}

#[cfg(test)]
mod tests {
    use std::time::Instant;

    use super::STROKE_HELD_THROUGH_FAULTS;
    use dynaclay_devices::{Fault, FaultKind, SimArmConfig, SimulatedArm};

    use super::super::{EngineConfig, HeadlessSink, ScriptPlan, build, build_clay};
    use dynaclay_core::dynamics::Material;
    use dynaclay_core::field::BSplineLattice;
    use dynaclay_core::io::parse_script;

    /// A push along the top of the block (the whole-engine tests' stroke).
    const PUSH: &str = r#"
version = 1

[clay]
shape = "block"
resolution = 20

[[step]]
do = "stroke"
start_s = 0.1
path = [[0.75, 1.3, 0.95], [1.15, 1.3, 0.95]]
duration_s = 1.0
hover_fu = 0.3
"#;

    /// The [`PUSH`] script's plan and its clay.
    fn push_plan() -> (ScriptPlan, BSplineLattice) {
        let script = parse_script(PUSH, "test").unwrap();
        let plan = ScriptPlan::new(
            &script,
            "test",
            std::path::Path::new("."),
            &[],
            Material::PLASTIC,
        )
        .unwrap();
        let field = build_clay(&plan.clay).unwrap();
        (plan, field)
    }

    #[test]
    fn a_force_limit_request_clamps_the_output_from_the_next_tick() {
        let (plan, field) = push_plan();
        let arm = SimArmConfig::default();
        let device_max_n = arm.info.max_force_n;
        let mut config = EngineConfig::for_field(&field, &arm.info);
        config.haptics.tool_contact = plan.tool_contact;
        config.safety.soft_start_s = 0.0;
        let trajectory = plan.trajectory(&config.map).unwrap();
        let device = Box::new(SimulatedArm::new(arm, trajectory));
        let mut stages = build(
            &config,
            field,
            device,
            Box::new(HeadlessSink::default()),
            true,
        )
        .unwrap();
        let limit = stages.haptic.force_limit();
        assert_eq!(
            limit.applied_n(),
            device_max_n,
            "starts at the device's own"
        );

        // The push would ask for over 1 N; the renderer saturates smoothly at the limit the
        // filter applies, and the filter clamps what is left over.
        let cap_n = 0.1;
        limit.request(cap_n).unwrap();
        let (mut peak_n, mut near_cap) = (0.0f32, 0);
        for _ in 0..1400 {
            let out = stages.haptic.tick(Instant::now());
            let sent_n = out.sample.device_force_n.length();
            peak_n = peak_n.max(sent_n);
            if sent_n > 0.95 * cap_n {
                near_cap += 1;
            }
            stages.sim.apply_commands();
            let sample = stages.samples.latest().value;
            stages.sim.step(&sample);
        }
        assert_eq!(limit.applied_n(), cap_n);
        assert!(
            near_cap > 100,
            "the push was held at the cap ({near_cap} ticks within 5% of it)"
        );
        assert!(peak_n <= cap_n + 1e-5, "peak {peak_n} N over the cap");

        // A request above the device's own maximum is capped by it.
        limit.request(1000.0).unwrap();
        stages.haptic.tick(Instant::now());
        assert_eq!(limit.applied_n(), device_max_n);
        assert_eq!(stages.haptic.device().max_force_n(), device_max_n);
    }

    /// A few failed reads mid-stroke hold the stroke (no contact, no force meanwhile); an arm
    /// that stays silent ends it after [`STROKE_HELD_THROUGH_FAULTS`] failed reads.
    #[test]
    fn a_short_fault_holds_the_stroke_and_a_long_one_ends_it() {
        let (plan, field) = push_plan();
        // The stroke's button is held from 0.1 s to 1.4 s: 5 ms of silence at 0.6 s, and
        // 300 ms from 0.9 s.
        let arm = SimArmConfig {
            faults: vec![
                Fault::new(0.6, 0.005, FaultKind::Stall),
                Fault::new(0.9, 0.3, FaultKind::Stall),
            ],
            ..SimArmConfig::default()
        };
        let mut config = EngineConfig::for_field(&field, &arm.info);
        config.haptics.tool_contact = plan.tool_contact;
        let trajectory = plan.trajectory(&config.map).unwrap();
        let device = Box::new(SimulatedArm::new(arm, trajectory));
        let mut stages = build(
            &config,
            field,
            device,
            Box::new(HeadlessSink::default()),
            true,
        )
        .unwrap();
        // Per fault (in order): its faulted ticks, and how many of them held the stroke.
        let mut faults: Vec<(u32, u32)> = Vec::new();
        let mut was_fault = false;
        let mut stroke_before_fault = Vec::new();
        let mut last_stroke = false;
        for _ in 0..1400 {
            let out = stages.haptic.tick(Instant::now());
            let s = out.sample;
            if s.device_fault {
                if !was_fault {
                    faults.push((0, 0));
                    stroke_before_fault.push(last_stroke);
                }
                let f = faults.last_mut().unwrap();
                f.0 += 1;
                f.1 += u32::from(s.stroke_active);
                assert!(!s.in_contact, "no contact during a fault");
                assert_eq!(s.device_force_n, glam::Vec3::ZERO, "zero during a fault");
            }
            was_fault = s.device_fault;
            last_stroke = s.stroke_active;
            stages.sim.apply_commands();
            let sample = stages.samples.latest().value;
            stages.sim.step(&sample);
        }
        assert_eq!(faults.len(), 2, "{faults:?}");
        assert_eq!(stroke_before_fault, [true, true], "both came mid-stroke");
        let (short, long) = (faults[0], faults[1]);
        assert!(
            short.0 >= 1 && short.1 == short.0,
            "held through: {short:?}"
        );
        assert!(long.0 > STROKE_HELD_THROUGH_FAULTS + 1, "{long:?}");
        assert_eq!(
            long.1, STROKE_HELD_THROUGH_FAULTS,
            "ended after the hold: {long:?}"
        );
    }
}
