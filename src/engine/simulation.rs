//! The simulation stage: applies the tool's force vector to the mass points of a local region
//! around the tool, steps the density-spring dynamics, and publishes the field to the haptic
//! and graphics loops.
//!
//! Not hard real-time: it allocates when a region is created or moved, when a stroke's undo
//! step is recorded, and when commands are applied; it never blocks on another loop. All
//! decisions depend only on the tool samples, the commands and step counts — never on wall
//! time — so a lockstep run is reproducible bit for bit.
//!
//! Publication rule: every step publishes to both readers a [`FieldPatch`] whose box is the
//! current region plus every box changed elsewhere (a retired region, an undo) that a reader
//! has not acknowledged yet. Readers store the version they applied in their ack atomics; a
//! changed box is dropped from the patch once both acks reach the first version that carried
//! it. So a reader that skips versions (triple buffers keep only the newest) still converges
//! to the simulation's field.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use crossbeam::channel::{Receiver, Sender};
use dynaclay_loops::SnapshotWriter;
use glam::Vec3;

use super::command::{Command, ForceTool};
use super::counters::EngineCounters;
use super::patch::{FieldPatch, union_box};
use super::tool_sample::ToolSample;
use crate::dynamics::{Material, RegionState, Simulator, StepParams, ToolForce};
use crate::field::{BSplineLattice, CoeffBox, RegionSnapshot, coeff_box_around};
use crate::io::{MaterialFields, Session};
use crate::tools::{Clay, FieldId, History, StepRecorder};

/// Settings of the simulation stage.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SimConfig {
    /// Material of new regions.
    pub material: Material,
    /// Step parameters (time step, adaptivity).
    pub step: StepParams,
    /// The force tool.
    pub tool: ForceTool,
    /// Half the edge of the simulated region around the tool, field units.
    pub region_half: f32,
    /// Mass points per knot span inside the region.
    pub samples_per_span: usize,
    /// Steps without contact after which the region is retired (and the stroke's undo step
    /// is recorded).
    pub retire_after_steps: u32,
    /// Memory bound of the undo history, bytes.
    pub history_budget_bytes: usize,
}

impl Default for SimConfig {
    fn default() -> Self {
        Self {
            material: Material::PLASTIC,
            step: StepParams::default(),
            tool: ForceTool::default(),
            region_half: 0.5,
            samples_per_span: 2,
            retire_after_steps: 400,
            history_budget_bytes: crate::tools::DEFAULT_BUDGET_BYTES,
        }
    }
}

/// A save the simulation thread hands to whoever does the file I/O.
#[derive(Debug)]
pub struct SaveJob {
    /// Destination.
    pub path: std::path::PathBuf,
    /// The session to write.
    pub session: Session,
    /// Where the result goes.
    pub reply: Option<Sender<Result<std::path::PathBuf, String>>>,
}

/// What one step did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SimOutcome {
    /// Whether a region was stepped.
    pub stepped: bool,
    /// Whether a tool force was applied.
    pub pushed: bool,
    /// Whether the step was refused (non-finite values kept out).
    pub rejected: bool,
}

/// The readers' end of the publication acks.
#[derive(Clone, Debug, Default)]
pub struct Acks {
    /// Version last applied by the haptic loop.
    pub haptic: Arc<AtomicU64>,
    /// Version last applied by the graphics loop.
    pub graphics: Arc<AtomicU64>,
}

/// The simulation's state: the authoritative clay, the active region, the history.
pub struct SimulationStage {
    config: SimConfig,
    clay: Clay,
    history: History,
    recorder: Option<StepRecorder>,
    simulator: Simulator,
    region: Option<RegionState>,
    idle_steps: u32,
    stroke_armed: bool,
    was_active: bool,
    scratch: RegionSnapshot,
    to_haptic: SnapshotWriter<FieldPatch>,
    to_graphics: SnapshotWriter<FieldPatch>,
    acks: Acks,
    pending: Option<CoeffBox>,
    pending_since: u64,
    commands: Receiver<Command>,
    saves: Option<Sender<SaveJob>>,
    counters: EngineCounters,
    steps: u64,
    sim_time_s: f64,
}

impl SimulationStage {
    /// Builds the stage over `lattice` (it becomes the clay's single density patch).
    #[allow(clippy::too_many_arguments)] // set-up only: each part is a distinct channel end
    #[must_use]
    pub fn new(
        config: SimConfig,
        lattice: BSplineLattice,
        to_haptic: SnapshotWriter<FieldPatch>,
        to_graphics: SnapshotWriter<FieldPatch>,
        acks: Acks,
        commands: Receiver<Command>,
        saves: Option<Sender<SaveJob>>,
        counters: EngineCounters,
    ) -> Self {
        let scratch = RegionSnapshot::with_capacity(lattice.coeffs.len());
        Self {
            config,
            clay: Clay::single(lattice),
            history: History::new(config.history_budget_bytes),
            recorder: None,
            simulator: Simulator::new(config.step),
            region: None,
            idle_steps: 0,
            stroke_armed: false,
            was_active: false,
            scratch,
            to_haptic,
            to_graphics,
            acks,
            pending: None,
            pending_since: 0,
            commands,
            saves,
            counters,
            steps: 0,
            sim_time_s: 0.0,
        }
    }

    /// The authoritative field.
    #[must_use]
    pub fn lattice(&self) -> &BSplineLattice {
        &self.clay.patches[0]
    }

    /// The clay (for saving at the end).
    #[must_use]
    pub fn clay(&self) -> &Clay {
        &self.clay
    }

    /// The session as it stands: the clay and the material.
    #[must_use]
    pub fn session(&self) -> Session {
        Session {
            clay: self.clay.clone(),
            material: MaterialFields {
                uniform: self.config.material,
                grids: Vec::new(),
            },
            ..Session::default()
        }
    }

    /// Undo steps available.
    #[must_use]
    pub fn undo_len(&self) -> usize {
        self.history.undo_len()
    }

    /// Applies every queued command (non-blocking).
    pub fn apply_commands(&mut self) {
        while let Ok(cmd) = self.commands.try_recv() {
            let ok = self.apply(cmd);
            self.counters.commands_applied(1);
            if !ok {
                self.counters.command_errors(1);
            }
        }
    }

    fn apply(&mut self, cmd: Command) -> bool {
        match cmd {
            Command::SetTool(tool) => {
                self.config.tool = tool;
                true
            }
            Command::SetMaterial(m) => {
                self.config.material = m;
                true
            }
            Command::StrokeStart => {
                self.stroke_armed = true;
                true
            }
            Command::StrokeStop => {
                self.stroke_armed = false;
                true
            }
            Command::Undo | Command::Redo => {
                self.retire_region();
                let whole = CoeffBox::whole(self.lattice().dims);
                let done = if matches!(cmd, Command::Undo) {
                    self.history.undo(&mut self.clay)
                } else {
                    self.history.redo(&mut self.clay)
                };
                self.mark_changed(whole);
                done.is_ok()
            }
            Command::Snapshot { reply } => reply.send(self.session()).is_ok(),
            Command::Save { path, reply } => match &self.saves {
                Some(saves) => saves
                    .send(SaveJob {
                        path,
                        session: self.session(),
                        reply,
                    })
                    .is_ok(),
                None => {
                    if let Some(r) = reply {
                        let _ = r.send(Err("this engine has no I/O thread".to_owned()));
                    }
                    false
                }
            },
        }
    }

    /// One step under `sample`: region upkeep, dynamics, publication.
    pub fn step(&mut self, sample: &ToolSample) -> SimOutcome {
        let mut out = SimOutcome::default();
        let active = sample.stroke_active;
        if active && !self.was_active {
            // A new stroke is a new undo step.
            self.commit_recorder();
            self.recorder = Some(StepRecorder::new("stroke"));
        }
        self.was_active = active;

        let push = sample.in_contact
            && sample.force_from.is_finite()
            && sample.force_to.is_finite()
            && sample.force_from != sample.force_to;
        if push {
            self.ensure_region(sample.force_from, sample.force_to);
            self.idle_steps = 0;
        } else if self.region.is_some() {
            self.idle_steps += 1;
            if self.idle_steps > self.config.retire_after_steps {
                self.retire_region();
            }
        }

        if let Some(region) = self.region.as_mut() {
            if let Some(rec) = self.recorder.as_mut() {
                rec.touch(&self.clay, FieldId::Density(0), region.coeff_box());
            }
            let tool = self.config.tool;
            let forces = [ToolForce {
                start: sample.force_from,
                end: sample.force_to,
                distribution: tool.distribution,
                radius: tool.radius,
                gain: tool.gain,
            }];
            let forces: &[ToolForce] = if push { &forces } else { &[] };
            let lattice = &mut self.clay.patches[0];
            match self
                .simulator
                .step(region, lattice, forces, &mut self.scratch)
            {
                Ok(report) => {
                    out.stepped = true;
                    out.pushed = push;
                    self.sim_time_s += f64::from(report.dt_s);
                    self.counters.sim_substeps(u64::from(report.halvings) + 1);
                }
                Err(_) => {
                    out.rejected = true;
                    self.counters.sim_nonfinite_rejected(1);
                }
            }
        }
        self.steps += 1;
        self.counters.sim_steps(1);
        self.publish();
        out
    }

    /// Makes sure the region covers the force vector `from → to` with its spread.
    fn ensure_region(&mut self, from: Vec3, to: Vec3) {
        let r = Vec3::splat(self.config.tool.radius);
        let lattice = &self.clay.patches[0];
        let Some(needed) = coeff_box_around(lattice, from.min(to) - r, from.max(to) + r, 0) else {
            return;
        };
        if let Some(region) = &self.region {
            let b = region.coeff_box();
            if contains(&b, &needed) {
                return;
            }
        }
        let half = Vec3::splat(self.config.region_half);
        let centre = (from + to) * 0.5;
        let Some(around) = coeff_box_around(lattice, centre - half, centre + half, 0) else {
            return;
        };
        let b = union_box(Some(around), needed);
        self.retire_region();
        let n = b.dims();
        let s = self.config.samples_per_span.max(1);
        let mass_dims = [(n[0] - 1) * s + 1, (n[1] - 1) * s + 1, (n[2] - 1) * s + 1];
        match RegionState::new(&self.clay.patches[0], b, mass_dims, self.config.material) {
            Ok(state) => self.region = Some(state),
            Err(_) => self.counters.command_errors(1),
        }
    }

    /// Ends the active region: its final coefficients stay in the lattice and are published
    /// until both readers have them; the stroke's undo step is recorded if no stroke is held.
    fn retire_region(&mut self) {
        if let Some(region) = self.region.take() {
            self.mark_changed(region.coeff_box());
        }
        self.idle_steps = 0;
        if !self.was_active {
            self.commit_recorder();
        }
    }

    fn commit_recorder(&mut self) {
        if let Some(rec) = self.recorder.take() {
            self.history.commit(rec, &self.clay);
        }
    }

    /// Records that `b` changed outside the region's regular publication.
    fn mark_changed(&mut self, b: CoeffBox) {
        self.pending = Some(union_box(self.pending, b));
        self.pending_since = self.to_haptic.version() + 1;
    }

    fn publish(&mut self) {
        // NOTE: Acquire pairs with the readers' Release store of their ack: once a reader has
        // acknowledged a version, it holds every coefficient that version carried.
        let seen = self
            .acks
            .haptic
            .load(Ordering::Acquire)
            .min(self.acks.graphics.load(Ordering::Acquire));
        if self.pending.is_some() && seen >= self.pending_since {
            self.pending = None;
        }
        let region = self.region.as_ref().map(RegionState::coeff_box);
        let b = match (region, self.pending) {
            (Some(r), p) => Some(union_box(p, r)),
            (None, p) => p,
        };
        let lattice = &self.clay.patches[0];
        for w in [&mut self.to_haptic, &mut self.to_graphics] {
            let patch = w.back_mut();
            match b {
                Some(b) => patch.capture(lattice, b),
                None => {
                    patch.coeff_box = None;
                    patch.coeffs.clear();
                }
            }
            patch.stroke_armed = self.stroke_armed;
            patch.sim_time_s = self.sim_time_s;
            patch.sim_step = self.steps;
            w.publish();
        }
        self.counters.snapshots_published(1);
    }

    /// Publishes the current field without stepping (used at shutdown so readers catch up).
    pub fn publish_now(&mut self) {
        self.publish();
    }

    /// Ends the session: retires the region and records the last stroke's undo step.
    pub fn finish(&mut self) {
        self.was_active = false;
        self.retire_region();
    }
}

fn contains(outer: &CoeffBox, inner: &CoeffBox) -> bool {
    (0..3).all(|a| outer.min[a] <= inner.min[a] && inner.max[a] <= outer.max[a])
}
