//! The simulation stage: applies the held tool — the contact push's or a force tool's force
//! vectors to the mass points of a local region around them, or a geometric tool at the tip —
//! steps the density-spring dynamics, applies non-real-time commands (tool steps, CSG,
//! undo/redo, material, saves) between steps, and publishes the field to the haptic and
//! graphics loops.
//!
//! Not hard real-time: it allocates when a region is created or moved, when a geometric tool
//! is applied, when a stroke's undo step is recorded, and when commands are applied; it never
//! blocks on another loop and never does file I/O (saves go to the I/O thread). All decisions
//! depend only on the tool samples, the commands and step counts — never on wall time — so a
//! lockstep run is reproducible bit for bit.
//!
//! Undo rule: one stroke (button 0 down to up) is one undo step. Every write to the clay is
//! preceded by a [`StepRecorder::touch`] of its box. A stroke's step is committed when the
//! stroke ends if no dynamics region is alive; otherwise when the region retires (the clay has
//! stopped moving), when the next stroke starts, or before any command that edits the clay —
//! so every change belongs to exactly one step and undo restores the field bit for bit.
//!
//! Compact RBF clay (Zhang et al. §5.4, `compact.rs`): when on, each committed contact stroke
//! or contact tool step sends a copy of the base patch to a worker thread; its answer (the
//! RBF's fit onto the lattice) is polled between steps and written as one more undo step, or
//! dropped and re-asked on the newer clay when the clay changed meanwhile.
//!
//! Detail patches (Hua & Qin eq. (3)): the region a stroke touches is simulated on the patch
//! in world coordinates that holds the most detail at the tool (the finest one whose support
//! holds the tip well inside); the other patches stay fixed and take part through the sum, in
//! the tool's forces as in what the haptic loop feels and the graphics loop meshes.
//!
//! Publication rule: every step publishes to both readers a [`FieldUpdate`] whose boxes are the
//! current region plus every box changed elsewhere (a retired region, an undo), per patch,
//! that a reader has not acknowledged yet. Readers store the version they applied in their ack atomics; a
//! changed box is dropped from the patch once both acks reach the first version that carried
//! it. So a reader that skips versions (triple buffers keep only the newest) still converges
//! to the simulation's field.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

mod commands;
mod compact;
mod constrain;
mod detail;
mod growth;
mod library;
mod mask;
mod material;
mod publication;
mod reach;
mod removal;
mod session_io;
mod stamps;

use session_io::CarriedSections;
pub use session_io::check_loadable;

use crossbeam::channel::{Receiver, Sender};
use dynaclay_devices::record::{ScheduleLog, ScheduleNote};
use dynaclay_loops::{SnapshotReader, SnapshotWriter, WakeBell, snapshot_channel};
use glam::{Quat, Vec3};

use super::clock::EngineClock;
use super::command::{Command, EditOutcome, EditReply, PushTool, Reply, ToolChoice};
use super::counters::EngineCounters;
use super::error::{CommandError, LatticeShape, LoadRefused, SaveError};
use super::layout::LayoutSender;
use super::live_tool::LiveTool;
use super::sim_status::SimStatus;
use super::symmetry::{Symmetry, clay_centre, mirror_body, mirror_force};
use super::tool_sample::ToolSample;
use super::update::{FieldUpdate, MAX_UPDATE_COEFFS};
use dynaclay_core::dynamics::{
    ConstraintSolver, Material, RegionState, Simulator, StepParams, ToolBody, ToolForce,
};
use dynaclay_core::field::{
    BSplineLattice, CoeffBox, DenseBudgetError, MultiPatchField, RefusedFolds, RegionSnapshot,
    coeff_box_around,
};
use dynaclay_core::io::{MaterialFields, Session};
use dynaclay_core::tools::{
    ApplyOptions, Clay, ColourField, FieldId, ForceTool, FreezeMask, History, StepRecorder,
    ToolAction, ToolError, ToolPose, ToolReport, ToolShape, apply_csg, apply_emboss, apply_stroke,
    apply_tool, csg_volume_change, facing_surface, tool_volume_change,
};

/// Settings of the simulation stage.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SimConfig {
    /// Material of new regions.
    pub material: Material,
    /// Step parameters (time step, adaptivity).
    pub step: StepParams,
    /// The contact push held at the start (a [`Command::SetTool`] changes the tool).
    pub tool: PushTool,
    /// Half the edge of the simulated region around the tool, field units, on the base; on a
    /// detail patch it shrinks with the patch's knot spacing, so a region holds as many knot
    /// spans (and its step costs as much) at every level. The region always holds the tool's
    /// forces' reach besides.
    pub region_half: f32,
    /// Mass points per knot span inside the region.
    pub samples_per_span: usize,
    /// Steps without contact after which the region is retired (and the stroke's undo step
    /// is recorded).
    pub retire_after_steps: u32,
    /// Memory bound of the undo history, bytes.
    pub history_budget_bytes: usize,
    /// Least device time between two applications of a held geometric tool, microseconds.
    pub geometric_interval_us: u64,
    /// What a step that would remove more than half the clay does: applied and reported
    /// (scripts), or held until the user answers (the window).
    pub removal_guard: super::RemovalGuard,
    /// Whether a geometric brush narrower than three knot spans of the patch under it adds a
    /// detail patch under itself first (see `simulation/detail.rs`). The window's Detail
    /// switches and a script's `detail` step set this and [`Self::auto_detail_force`]
    /// ([`Command::SetAutoDetail`]).
    pub auto_detail: bool,
    /// Whether a force tool's spread (the push's, a pull's...) narrower than three knot spans
    /// also refines under itself before its region is set up (with `auto_detail` on). On by
    /// default, with [`Self::detail_base_yield`]: on a detail patch the clay then keeps the
    /// material's behaviour in every lockstep test (a stiff painted half dents 0.1180 against
    /// the soft half's 0.1395, at most 0.85x asked; a heavy half lags; a chisel of gain 2e9
    /// keeps its depth within 6.2%, 10% allowed; the narrow push's groove is 0.034-0.036 wide
    /// against its chord 0.040; the narrow chisel's recorded session has no flip; the narrow
    /// elastic press springs back). A detail patch's mass points scale stiffness by their
    /// volume, as mass and damping, which leaves the clay there softer against its inertia by
    /// the spacing ratio squared. Scaling stiffness by the spacing instead, as
    /// the springs' energy asks, closed a narrow press over its tip (the walls of the hole
    /// sealed above it, and sprang shut again when the tool left); the push's body
    /// (`dynaclay_core::dynamics::ToolBody`) and a yield density scaled by the spacing as well
    /// kept it open (0.118 deep on a level-2 patch, 0.120 on an automatic level-3 one, 0.109
    /// on the base), but a narrow push drawn along the top then pressed a groove 30% wider
    /// than its spread (`tests/adaptive_clay.rs`): the consistent springs smooth detail that
    /// fine away; the stiffness scaled by the spacing squared barely moved the stiff half
    /// (0.1290 against 0.1301). A region a stroke moves on hands its perfectly elastic points'
    /// rest over to
    /// the next (`RegionState::carry_rest_from`), so an elastic press on a patch, whose region
    /// a deep press outgrows, springs back (`tests/material_fields.rs`: 0.017 of a 0.100 dent
    /// left with this on, was 0.080); a plastic point takes the clay as it is as its new rest
    /// (carrying that over too let the default plastic clay's grooves spring back past the
    /// push's tolerances). With this on and the volume-scaled material alone, a stiff painted
    /// half sprang back less than on the base (dent 0.129 against 0.140 on the soft half) and
    /// a chisel of a huge gain (2e9) cut short on a patch (worst 16%): the yield density and
    /// the travel of [`Self::detail_base_yield`] fix both. (A narrow chisel's cut
    /// on a patch, which a skin of clay used to close, stays open: the chisel has a body, see
    /// `live_tool::chisel_body`.) A two-level material on the patch
    /// ([`Self::two_level_detail`]) fixed the stiff half, the heavy half and the chisel but not
    /// the narrow press, the narrow groove or the narrow chisel's recorded session.
    pub auto_detail_force: bool,
    /// Whether a force tool's region on a detail patch takes a two-level material
    /// (`RegionState::set_coarse_springs`, `coarse.rs` in `dynaclay_core::dynamics`): the
    /// patch's volume-scaled springs plus springs one base mass spacing apart on the deviation
    /// averaged around them, so a dent as large as the base's mass spacing meets the base's
    /// stiffness, with the tool's travel per step and the step's halving threshold reckoned
    /// in the base's knot spans. Off by default. Measured with [`Self::auto_detail_force`] on
    /// (lockstep tests, two runs that differ only in the rounding order of the coarse force):
    /// the stiff painted half springs back on a patch (dent 0.116 against 0.140 on the soft
    /// half, 0.85x asked; volume-scaled 0.129) and the chisel of gain 2e9 keeps its depth
    /// (worst 6.2% and 9.7%; volume-scaled 16%); but the narrow elastic press of
    /// `tests/material_fields.rs` (level 2) is 0.099 deep with some neighbourhoods and
    /// reads 0.024 deep with another (26 in one run, 18 in the other), the narrow push's
    /// groove (`tests/adaptive_clay.rs`) comes out 0.028 and 0.013 wide at its narrowest
    /// against the chord 0.040 (25% allowed), and in one run the narrow chisel's recorded
    /// session (`tests/haptic_quality.rs`) flipped 8 times. The first two are skins of clay
    /// the coarse springs close over the narrow hole, not shallow dents (the crossings along
    /// the lines the tests measure on, printed by a temporary probe): the press's hole is
    /// 0.099 deep under a sliver about 0.0005 thick (a fiftieth of the patch's knot span, the
    /// depth below which the push's body fades) 0.025 below the top on its axis alone; the
    /// groove is 0.043 wide between its walls where it reads 0.013, with a skin from 0.006 to
    /// 0.020 below the top along its middle, and 0.021 wide where the skin is not (its floor
    /// 0.028 deep); where it reads 0.048 a sliver floats 0.014-0.018 above the top. The heavy painted half, 0.041
    /// deep after 200 steps against the unpainted 0.066 while the per-step travel cap was
    /// sized by the region's mean mass, lags as asked since the cap is sized by the unpainted
    /// mass at most: 220 against 160 steps to 0.03 deep, 0.021 against 0.066 after 200 steps
    /// (asked: at least 30 steps later, under half). Measured again after that change: the
    /// stiff half 0.116 against 0.140, the chisel of gain 2e9 within its tolerances, the
    /// groove 0.013 / 0.021 / 0.048 wide along its length, the narrow elastic press stalled at
    /// 0.025 with 18 neighbours. Coarse
    /// springs one base knot span apart kept the groove (0.032-0.033) with the travel in
    /// the patch's spans, but the narrow elastic press stalled at 0.022 then, and with the
    /// travel in base spans the soft half of the stiff-half test was left undented (0.0015).
    pub two_level_detail: bool,
    /// Whether a region on a detail patch (without [`Self::two_level_detail`]) takes the
    /// material's yield density times the spacing ratio (the base's knot spacing over the
    /// patch's) and reckons the step's halving threshold in the base's knot spans
    /// (`RegionState::set_base_step_threshold`); the push's and the strokes' travel per step
    /// stays in the patch's spans, while the chisel's and the squirt's planned targets are
    /// reached at up to the base's travel per step, never further in a step than what is left
    /// of the force's vector (`RegionState::set_planned_travel_ratio`). On by default.
    /// Measured with [`Self::auto_detail_force`] on (lockstep tests, `bench/RESULTS.md`,
    /// "Force tools refining under themselves: the yield on a patch" and "... by default"):
    /// the stiff painted half springs back (dent 0.1180 against 0.1395 on the soft half,
    /// 0.85x asked, so within 0.5% of the bound; 0.1294 without this), the narrow push's
    /// groove is 0.034-0.036 wide against the chord 0.040, the narrow chisel's recorded
    /// session keeps its steady ticks (0.89 of the rule, no flip) and the narrow elastic press
    /// springs back (elastic clay has no yield); the chisel of gain 2e9 keeps its depth within
    /// 6.2% (with the chisel's travel in the patch's spans it cut 30% short: slow, not
    /// stopped, as a second more showed). The scaled yield alone (the patch's own threshold)
    /// failed the narrow chisel's session (1.53 of the rule); every force tool's travel in the
    /// base's spans pressed the narrow groove to 0.019-0.031 wide, and the push's travel at
    /// the base's pace far from its end left the stiff half as deep as the soft (0.1254
    /// against 0.1400).
    pub detail_base_yield: bool,
}

impl Default for SimConfig {
    fn default() -> Self {
        Self {
            material: Material::PLASTIC,
            step: StepParams::default(),
            tool: PushTool::default(),
            region_half: 0.5,
            samples_per_span: 2,
            retire_after_steps: 400,
            history_budget_bytes: dynaclay_core::tools::DEFAULT_BUDGET_BYTES,
            geometric_interval_us: 10_000,
            removal_guard: super::RemovalGuard::Warn,
            auto_detail: true,
            auto_detail_force: true,
            two_level_detail: false,
            detail_base_yield: true,
        }
    }
}

/// Work the simulation thread hands to the I/O thread.
#[derive(Debug)]
pub enum IoJob {
    /// Write a session file (boxed: a session is large and autosave notes are frequent).
    Save(Box<SaveJob>),
    /// An undo step was committed (a stroke or a tool step ended): counts toward autosave.
    Committed,
    /// The session file at this path was loaded and is now the one being worked on: autosave
    /// writes its recovery file beside it from now on.
    Follow(std::path::PathBuf),
    /// Test-only (the `fault-injection` feature): the I/O worker panics on taking it.
    #[cfg(feature = "fault-injection")]
    InjectPanic,
}

/// A save the simulation thread hands to whoever does the file I/O.
#[derive(Debug)]
pub struct SaveJob {
    /// Destination.
    pub path: std::path::PathBuf,
    /// Whether autosave follows the file (see [`crate::Command::Save`]).
    pub as_session: bool,
    /// The session to write.
    pub session: Session,
    /// Where the result goes.
    pub reply: Option<super::SaveReply>,
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
    tool: LiveTool,
    simulator: Simulator,
    region: Option<RegionState>,
    /// The density patch the region simulates (its lattice is the one stepped).
    region_patch: usize,
    /// The uniform material the live region was made with (before its patch's volume
    /// ratio), under the painted grids.
    region_material: Material,
    /// The painted material: grids of mass, damping, stiffness and drift rate over the base patch (see
    /// `material.rs`), applied to every region's mass points.
    material_grids: Vec<dynaclay_core::io::MaterialGrid>,
    /// The clay's pins as the live region holds them (see `constrain.rs`).
    region_pins: ConstraintSolver,
    /// Bumped by every command that may change the clay's pins (see [`SimStatus`]).
    pins_revision: u64,
    idle_steps: u32,
    stroke_armed: bool,
    was_active: bool,
    /// The clay as it was when the held stroke began, for a profiled brush: each application
    /// faces this clay where it acts ([`dynaclay_core::tools::facing_surface`]), so the brush
    /// follows the surface along the stroke while the groove it carves never turns it. Kept
    /// between strokes (`stroke_clay_held` says whether it is this stroke's).
    stroke_clay: Option<MultiPatchField>,
    stroke_clay_held: bool,
    scratch: RegionSnapshot,
    to_haptic: SnapshotWriter<FieldUpdate>,
    to_graphics: SnapshotWriter<FieldUpdate>,
    acks: Acks,
    /// Per density patch, the box changed outside the region that a reader may not have yet.
    pending: Vec<Option<CoeffBox>>,
    /// Per density patch, the boxes published since the readers' copies were last made (a
    /// new layout): the readers never compact their copies, so the bricks these boxes reach
    /// bound the dense bricks they may hold beyond [`Self::reader_dense_at_layout`] (see
    /// `reach.rs` and `publication.rs`).
    reader_reach: Vec<reach::Reach>,
    /// Dense bricks of the density patches when the readers' copies were last made.
    reader_dense_at_layout: usize,
    /// The patch layout's generation (bumped when a detail patch is added).
    layout_generation: u64,
    /// Where new layouts go to the haptic and graphics loops (none in a bare stage).
    layout_senders: Vec<LayoutSender>,
    pending_since: u64,
    commands: Receiver<Command>,
    io: Option<Sender<IoJob>>,
    counters: EngineCounters,
    steps: u64,
    sim_time_s: f64,
    /// Observers' view of this stage, published every step.
    status: SnapshotWriter<SimStatus>,
    status_reader: Option<SnapshotReader<SimStatus>>,
    sessions_loaded: u64,
    /// The clay's paint for the graphics loop, published when it changed (see
    /// [`COLOUR_PUBLISH_EVERY_STEPS`]).
    colour: SnapshotWriter<Option<ColourField>>,
    colour_reader: Option<SnapshotReader<Option<ColourField>>>,
    colour_dirty: bool,
    colour_published_step: u64,
    /// The clay's freeze mask for the graphics loop (drawn as a tint), published with the
    /// next step after it changed (a mask edit, undo or redo, a new clay).
    mask_out: SnapshotWriter<Option<FreezeMask>>,
    mask_reader: Option<SnapshotReader<Option<FreezeMask>>>,
    mask_dirty: bool,
    /// Mirror planes strokes are copied across.
    symmetry: Symmetry,
    /// This step's tool forces with their mirrored copies (used only while mirroring).
    mirrored_forces: Vec<ToolForce>,
    /// This step's tool bodies and their mirrored copies, with symmetry on.
    mirrored_bodies: Vec<ToolBody>,
    /// The session's parts the engine does not simulate, carried unchanged from the loaded
    /// session into every session it hands back.
    carried: CarriedSections,
    /// Where each step's schedule is noted while a recording runs (see [`ScheduleNote`]).
    schedule: Option<ScheduleLog>,
    /// Commands applied since the last step (noted with the next step).
    commands_since_step: u32,
    /// The compact RBF clay, when on (see `compact.rs`).
    compact: Option<super::compact_rbf::CompactState>,
    /// Bumped by every committed step, undo, redo, load and refine: which clay a
    /// re-interpolation was computed from.
    clay_revision: u64,
    /// Whether the stroke being recorded is made with a contact tool.
    stroke_is_contact: bool,
    /// The guard against steps that remove most of the clay (see `removal.rs`).
    removal: removal::RemovalState,
    /// The engine's clock: when each step began and each snapshot was published.
    clock: EngineClock,
    /// The newest stroke's way to the screen (see `stamps.rs`).
    track: stamps::StrokeTrack,
    /// Rung when a publication carries a change, so the graphics loop re-meshes at once
    /// instead of at its next period (none in a lockstep run, whose driver ticks graphics).
    graphics_wake: Option<WakeBell>,
    /// The clay changed since the last publication (a region step, a marked box).
    changed_since_publish: bool,
    /// The folds of detail patches found refused, by their inputs (see `detail.rs`).
    refused_folds: RefusedFolds,
    /// The newest edit refused or clipped for one of the clay's budgets (published in
    /// [`SimStatus::budget_refusal`]).
    budget_refusal: Option<crate::BudgetRefusal>,
}

/// The [`FieldId`] of density patch `patch` (the engine's clays hold at most `u16::MAX + 1`
/// patches: [`FieldUpdate`] names them by `u16`).
fn density_id(patch: usize) -> FieldId {
    FieldId::Density(u16::try_from(patch).unwrap_or(u16::MAX))
}

/// The bounding box of `forces` grown by their spread radii, if there are any.
fn forces_bounds(forces: &[ToolForce]) -> Option<(Vec3, Vec3)> {
    forces.iter().fold(None, |acc, f| {
        let r = Vec3::splat(f.radius);
        let (lo, hi) = (f.start.min(f.end) - r, f.start.max(f.end) + r);
        Some(match acc {
            Some((a, b)) => (a.min(lo), b.max(hi)),
            None => (lo, hi),
        })
    })
}

impl SimulationStage {
    /// Builds the stage over `field` (it becomes the clay's density).
    #[allow(clippy::too_many_arguments)] // set-up only: each part is a distinct channel end
    #[must_use]
    pub fn new(
        config: SimConfig,
        field: MultiPatchField,
        to_haptic: SnapshotWriter<FieldUpdate>,
        to_graphics: SnapshotWriter<FieldUpdate>,
        acks: Acks,
        commands: Receiver<Command>,
        io: Option<Sender<IoJob>>,
        counters: EngineCounters,
        clock: EngineClock,
    ) -> Self {
        let largest = field
            .patches
            .iter()
            .map(|p| p.lattice.coeffs.len())
            .max()
            .unwrap_or(0);
        // A region's box, not the clay's: it grows on the simulation thread if a region needs
        // more.
        let scratch = RegionSnapshot::with_capacity(largest.min(MAX_UPDATE_COEFFS));
        let pending = vec![None; field.patches.len()];
        let reader_reach = vec![reach::Reach::default(); field.patches.len()];
        let reader_dense_at_layout = field.dense_brick_count();
        let (status, status_reader) = snapshot_channel(&SimStatus::default());
        let (colour, colour_reader) = snapshot_channel(&None);
        let (mask_out, mask_reader) = snapshot_channel(&None);
        Self {
            config,
            clay: Clay {
                density: field,
                colour: None,
                constraints: Vec::new(),
                mask: None,
            },
            history: History::new(config.history_budget_bytes),
            recorder: None,
            tool: LiveTool::new(ToolChoice::Push(config.tool)),
            symmetry: Symmetry::OFF,
            // Room for every force of the held tool and its seven mirrored copies.
            mirrored_forces: Vec::with_capacity(8 * super::live_tool::MAX_FORCES),
            // The same for the bodies (the chisel's stand over each of its forces).
            mirrored_bodies: Vec::with_capacity(8 * super::live_tool::MAX_FORCES),
            simulator: Simulator::new(config.step),
            region: None,
            region_patch: 0,
            region_material: config.material,
            material_grids: Vec::new(),
            region_pins: ConstraintSolver::empty(),
            pins_revision: 0,
            idle_steps: 0,
            stroke_armed: false,
            was_active: false,
            stroke_clay: None,
            stroke_clay_held: false,
            scratch,
            to_haptic,
            to_graphics,
            acks,
            pending,
            reader_reach,
            reader_dense_at_layout,
            layout_generation: 0,
            layout_senders: Vec::new(),
            pending_since: 0,
            commands,
            io,
            counters,
            steps: 0,
            sim_time_s: 0.0,
            status,
            status_reader: Some(status_reader),
            sessions_loaded: 0,
            budget_refusal: None,
            colour,
            colour_reader: Some(colour_reader),
            colour_dirty: false,
            colour_published_step: 0,
            mask_out,
            mask_reader: Some(mask_reader),
            mask_dirty: false,
            carried: CarriedSections::default(),
            schedule: None,
            commands_since_step: 0,
            compact: None,
            clay_revision: 0,
            stroke_is_contact: false,
            removal: removal::RemovalState::default(),
            clock,
            track: stamps::StrokeTrack::default(),
            graphics_wake: None,
            changed_since_publish: false,
            refused_folds: RefusedFolds::default(),
        }
    }

    /// Sends every new patch layout to the readers behind `senders` (the haptic and graphics
    /// loops; see [`super::layout`]).
    pub fn set_layout_senders(&mut self, senders: [LayoutSender; 2]) {
        self.layout_senders = senders.into();
    }

    /// Rings `bell` whenever a publication carries a change of the clay (a region step, a
    /// stroke of a geometric tool, an undo, a load), so the graphics loop re-meshes at once.
    pub fn set_graphics_wake(&mut self, bell: WakeBell) {
        self.graphics_wake = Some(bell);
    }

    /// Notes every step's tool sample and command count into `log` from now on, so that a
    /// replay can run the steps as this run did (see [`super::ScheduledReplay`]).
    pub fn set_schedule_log(&mut self, log: ScheduleLog) {
        self.schedule = Some(log);
    }

    /// Steps taken so far (the number the next step is noted with).
    #[must_use]
    pub fn steps_taken(&self) -> u64 {
        self.steps
    }

    /// Version of the newest field snapshot published to the haptic loop (0 before the
    /// first step).
    #[must_use]
    pub fn snapshot_version(&self) -> u64 {
        self.to_haptic.version()
    }

    /// The authoritative field's base patch.
    #[must_use]
    pub fn lattice(&self) -> &BSplineLattice {
        self.clay.base()
    }

    /// The authoritative field: the clay's density, every patch.
    #[must_use]
    pub fn field(&self) -> &MultiPatchField {
        &self.clay.density
    }

    /// The clay (for saving at the end).
    #[must_use]
    pub fn clay(&self) -> &Clay {
        &self.clay
    }

    /// The step held until the user says it may remove more than half the clay, if any
    /// (as [`SimStatus::removal_question`] publishes it).
    #[must_use]
    pub fn removal_question(&self) -> Option<super::RemovalQuestion> {
        self.removal.question
    }

    /// Undo steps available.
    #[must_use]
    pub fn undo_len(&self) -> usize {
        self.history.undo_len()
    }

    /// Redo steps available.
    #[must_use]
    pub fn redo_len(&self) -> usize {
        self.history.redo_len()
    }

    /// The tool held.
    #[must_use]
    pub fn tool(&self) -> &ToolChoice {
        self.tool.choice()
    }

    /// One step under `sample`: stroke bookkeeping, the held tool, region upkeep, dynamics,
    /// publication.
    pub fn step(&mut self, sample: &ToolSample) -> SimOutcome {
        if let Some(log) = &self.schedule {
            log.note(&ScheduleNote::Step {
                step: self.steps,
                sample_tick: sample.tick,
                commands: self.commands_since_step,
            });
        }
        self.commands_since_step = 0;
        let mut out = SimOutcome::default();
        self.track.step_began(
            sample.tick,
            sample.read_ns,
            self.clock.now_ns(),
            sample.felt,
        );
        let active = sample.stroke_active;
        if active && !self.was_active {
            self.track.stroke_started();
            // A new stroke is a new undo step.
            self.commit_recorder();
            self.recorder = Some(StepRecorder::new(self.tool.choice().name()));
            self.stroke_is_contact = self.tool.choice().is_contact();
            self.tool.end_stroke();
            self.removal
                .stroke_started(self.tool.choice(), &self.clay, sample.device_time_us);
            self.stroke_clay_held = matches!(
                self.tool.choice(),
                ToolChoice::Geometric(tool) if matches!(tool.shape, ToolShape::Profiled { .. })
            );
            if self.stroke_clay_held {
                // NOTE: the simulation thread may allocate; this copy is made once a stroke,
                // for profiled brushes only.
                match &mut self.stroke_clay {
                    Some(copy) => copy.clone_from(&self.clay.density),
                    None => self.stroke_clay = Some(self.clay.density.clone()),
                }
            }
        } else if !active && self.was_active {
            self.tool.release();
            self.removal.stroke_ended(self.config.removal_guard);
            if self.region.is_none() {
                // Nothing keeps moving: the stroke's step is complete.
                self.commit_recorder();
                self.track.settle();
            }
        }
        self.was_active = active;

        if let Some(due) = self
            .tool
            .geometric_due(sample, self.config.geometric_interval_us)
        {
            // Along the tip's path since the last application: a continuous groove.
            for i in 0..due.count {
                self.apply_held_geometric(due.point(i), due.rotation, due.dwell_s);
            }
            if due.count > 0 {
                self.track.changed_by_hand();
            }
        }

        // A force tool finer than the base refines under itself before its region is set up
        // (when automatic detail for force tools is on).
        self.refine_under_force_tool(sample);
        // The patch that would hold this step's region: its mass points set the step.
        let sculpted = self.sculpted_patch_at(sample.tip_fu);
        let spacing = self.clay.density.patches[sculpted].lattice.spacing;
        let mass_step = spacing / self.config.samples_per_span.max(1) as f32;
        self.tool
            .update_forces(sample, &self.clay.density, mass_step);
        let mirroring = self.symmetry.any() && !self.tool.forces().is_empty();
        if mirroring {
            self.mirror_forces();
        }
        let bounds = if mirroring {
            forces_bounds(&self.mirrored_forces)
        } else {
            self.tool.force_bounds()
        };
        let push = match bounds {
            Some((lo, hi)) => {
                self.ensure_region(lo, hi);
                self.idle_steps = 0;
                true
            }
            None => {
                if self.region.is_some() {
                    self.idle_steps += 1;
                    if self.idle_steps > self.config.retire_after_steps {
                        self.track.settle();
                        self.retire_region();
                    }
                }
                false
            }
        };

        if let Some(region) = self.region.as_mut() {
            if let Some(rec) = self.recorder.as_mut() {
                rec.touch(
                    &self.clay,
                    density_id(self.region_patch),
                    region.coeff_box(),
                );
            }
            let forces: &[ToolForce] = match (push, mirroring) {
                (false, _) => &[],
                (true, false) => self.tool.forces(),
                (true, true) => &self.mirrored_forces,
            };
            self.simulator.set_force_yield(sample.force_yield);
            self.simulator.set_tool_bodies(match (push, mirroring) {
                (false, _) => &[],
                (true, false) => self.tool.bodies(),
                (true, true) => &self.mirrored_bodies,
            });
            let (patch, region_box) = (self.region_patch, region.coeff_box());
            if let Some(p) = self.clay.density.patches.get(patch) {
                self.track.before_region_step(&p.lattice, patch, region_box);
            }
            // The region's patch moves; the other patches take part in the forces. Pins hold
            // the surface of the sum on whichever patch moves (see `constrain.rs`).
            let pins = Some(&mut self.region_pins);
            let stepped =
                self.clay
                    .density
                    .split_patch_mut(self.region_patch)
                    .map(|(lattice, others)| {
                        self.simulator.step_layered(
                            region,
                            lattice,
                            others,
                            forces,
                            pins,
                            &mut self.scratch,
                        )
                    });
            match stepped {
                Some(Ok(report)) => {
                    out.stepped = true;
                    self.changed_since_publish = true;
                    out.pushed = push;
                    if push {
                        self.track.changed_by_hand();
                    }
                    self.track.after_region_step(
                        &self.clay.density.patches[patch].lattice,
                        patch,
                        region_box,
                    );
                    self.sim_time_s += f64::from(report.dt_s);
                    self.counters.sim_substeps(u64::from(report.halvings) + 1);
                }
                // A step refused for a non-finite value, or a region whose patch is gone
                // (never: regions retire before the layout changes).
                Some(Err(_)) | None => {
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

    /// Fills `mirrored_forces` with this step's tool forces and their mirrored copies.
    fn mirror_forces(&mut self) {
        let centre = clay_centre(self.clay.base());
        self.mirrored_forces.clear();
        self.mirrored_forces.extend_from_slice(self.tool.forces());
        for flip in self.symmetry.flips() {
            for f in self.tool.forces() {
                self.mirrored_forces.push(mirror_force(f, centre, flip));
            }
        }
        self.mirrored_bodies.clear();
        self.mirrored_bodies.extend_from_slice(self.tool.bodies());
        for flip in self.symmetry.flips() {
            for b in self.tool.bodies() {
                self.mirrored_bodies.push(mirror_body(b, centre, flip));
            }
        }
    }

    /// Applies the held geometric tool at `at`, turned by `rotation`, and at its mirrored
    /// copies (one stroke, one undo step; a mirrored copy keeps the rotation, so a turned
    /// tool that is not symmetric about the mirror plane is not mirrored exactly).
    fn apply_held_geometric(&mut self, at: Vec3, rotation: Quat, dwell_s: f32) {
        self.apply_held_geometric_at(at, rotation, dwell_s);
        if self.symmetry.any() {
            let centre = clay_centre(self.clay.base());
            for image in self.symmetry.images(at, centre) {
                self.apply_held_geometric_at(image, rotation, dwell_s);
            }
        }
    }

    /// Applies the held geometric tool at `at`, turned by `rotation`, for `dwell_s` (recorded
    /// in the stroke's step), reloads the dynamics region it may have changed and marks the
    /// box for publication.
    fn apply_held_geometric_at(&mut self, at: Vec3, rotation: Quat, dwell_s: f32) {
        let ToolChoice::Geometric(tool) = self.tool.choice() else {
            return;
        };
        // A profiled brush faces the clay where it acts (as the clay was when the stroke
        // began), turned by the hand from there.
        let rotation = if matches!(tool.shape, ToolShape::Profiled { .. }) {
            let clay = self
                .stroke_clay
                .as_ref()
                .filter(|_| self.stroke_clay_held)
                .unwrap_or(&self.clay.density);
            facing_surface(clay, at) * rotation
        } else {
            rotation
        };
        let pose = ToolPose {
            position_fu: at,
            rotation,
        };
        let guard = self.config.removal_guard;
        if !self.removal.admits(guard, &self.clay, tool, &pose, dwell_s) {
            return;
        }
        let grows = tool
            .action
            .can_add_clay()
            .then(|| tool.influence_box(&pose, self.clay.base().spacing));
        // A smoothing over detail smooths every patch under it; a brush finer than the base
        // gets its detail patch (world boxes: growth keeps them).
        let smoothed = self.patches_smoothed(tool, std::slice::from_ref(&pose));
        let detail = self.detail_for_brush(tool, std::slice::from_ref(&pose));
        if let Some((lo, hi)) = grows {
            self.make_room(lo, hi);
        }
        let (patches, own_term) = match (smoothed, detail) {
            (Some(patches), _) => (patches, true),
            (None, Some(detail)) => (vec![self.patch_for_detail(detail)], false),
            (None, None) => (vec![0], false),
        };
        for patch in patches {
            let ToolChoice::Geometric(tool) = self.tool.choice() else {
                return;
            };
            let options = ApplyOptions {
                patch,
                own_term,
                ..ApplyOptions::default()
            };
            let result = apply_tool(
                &mut self.clay,
                tool,
                &pose,
                dwell_s,
                &options,
                self.recorder.as_mut(),
            );
            self.colour_dirty |= tool.action.paints();
            match result {
                Ok(report) => {
                    if let Some(b) = report.coeff_box {
                        let edited = usize::from(report.patch);
                        if let Some(region) = self.region.as_mut()
                            && edited == self.region_patch
                        {
                            // The region's own copy of the coefficients is stale now.
                            region.reload(&self.clay.density.patches[edited].lattice);
                            self.rebuild_pins();
                        }
                        self.mark_changed(edited, b);
                    }
                }
                Err(ToolError::DenseBudget(refused)) => self.refuse_for_budget(refused),
                Err(_) => self.counters.command_errors(1),
            }
        }
    }

    /// Counts and publishes an edit refused because it could pass the clay's dense-brick
    /// budget (the clay is unchanged; [`SimStatus::budget_refusal`] says what and where).
    pub(super) fn refuse_for_budget(&mut self, refused: DenseBudgetError) {
        self.counters.command_errors(1);
        self.note_budget_refusal(refused.into());
    }

    /// Keeps `refusal` as the latest edit refused for the clay's budgets (published in the
    /// status, handed back in the run's report) and counts it.
    pub(super) fn note_budget_refusal(&mut self, refusal: crate::BudgetRefusal) {
        self.counters.budget_refusals(1);
        self.budget_refusal = Some(refusal);
    }

    /// The latest edit refused for the clay's budgets, if any was.
    #[must_use]
    pub fn last_budget_refusal(&self) -> Option<crate::BudgetRefusal> {
        self.budget_refusal
    }

    /// The patch a region at `x` simulates: the finest patch in world coordinates whose
    /// support holds `x` well inside, else the base.
    fn sculpted_patch_at(&self, x: Vec3) -> usize {
        let field = &self.clay.density;
        let mut best = (0, f32::INFINITY);
        for (n, p) in field.patches.iter().enumerate() {
            if !p.is_identity() {
                continue;
            }
            let (lo, hi) = p.lattice.support();
            let margin = Vec3::splat(p.lattice.spacing);
            let inside = x.cmpge(lo + margin).all() && x.cmple(hi - margin).all();
            if (n == 0 || inside) && p.lattice.spacing < best.1 {
                best = (n, p.lattice.spacing);
            }
        }
        best.0
    }

    /// The patch a region over the box `lo..hi` (the force vectors with their spread)
    /// simulates: the finest patch at its centre ([`Self::sculpted_patch_at`]); among the
    /// patches of that spacing that hold the centre, the live region's own when its support
    /// holds the whole box with two of its spans to spare, else the newest that does. So a
    /// stroke that has run off the patch it started on (a chisel's targets planned along its
    /// whole path, each step's forces reaching back to its start) is simulated on the patch
    /// added under all of it, and no force falls outside the region's mass points.
    fn region_patch_for(&self, lo: Vec3, hi: Vec3) -> usize {
        let centre = (lo + hi) * 0.5;
        let finest = self.sculpted_patch_at(centre);
        if finest == 0 {
            return 0;
        }
        let patches = &self.clay.density.patches;
        let spacing = patches[finest].lattice.spacing;
        let holds_box = |n: usize| {
            patches.get(n).is_some_and(|p| {
                let (plo, phi) = p.lattice.support();
                let margin = Vec3::splat(2.0 * p.lattice.spacing);
                n > 0
                    && p.is_identity()
                    && p.lattice.spacing == spacing
                    && lo.cmpge(plo + margin).all()
                    && hi.cmple(phi - margin).all()
            })
        };
        if self.region.is_some() && holds_box(self.region_patch) {
            return self.region_patch;
        }
        (1..patches.len())
            .rev()
            .find(|&n| holds_box(n))
            .unwrap_or(finest)
    }

    /// Makes sure the region covers the box `lo..hi` (the force vectors with their spread),
    /// on the patch [`Self::region_patch_for`] picks.
    fn ensure_region(&mut self, lo: Vec3, hi: Vec3) {
        // A region whose box reaches more bricks than the clay's whole budget, even at the
        // base's spacing, is refused before the clay grows for it: growing would give the
        // clay a box it never fills.
        if let Some(refused) = self.region_past_dense_budget(lo, hi) {
            self.retire_region();
            self.refuse_for_budget(refused);
            self.rebuild_pins();
            return;
        }
        // The base grows under a stroke that reaches past it, whichever patch the region is
        // on: a detail patch holds only what the base's box holds.
        let mut patch = self.region_patch_for(lo, hi);
        if self.make_room(lo, hi) {
            patch = self.region_patch_for(lo, hi);
        }
        let lattice = &self.clay.density.patches[patch].lattice;
        let Some(needed) = coeff_box_around(lattice, lo, hi, 0) else {
            return;
        };
        if let Some(region) = &self.region
            && self.region_patch == patch
        {
            let b = region.coeff_box();
            if b.contains_box(&needed) {
                return;
            }
        }
        // As many knot spans of its own patch at every level: the step costs the same.
        let half =
            Vec3::splat(self.config.region_half * lattice.spacing / self.clay.base().spacing);
        let centre = (lo + hi) * 0.5;
        let Some(around) = coeff_box_around(lattice, centre - half, centre + half, 0) else {
            return;
        };
        let b = around.union(&needed);
        // A region that moves on over the same patch hands its elastic memory over.
        let previous = if self.region_patch == patch {
            self.region.take()
        } else {
            None
        };
        if let Some(old) = &previous {
            self.mark_changed(patch, old.coeff_box());
        }
        self.retire_region();
        // The region's coefficients are written every step: the bricks its box reaches must
        // fit the clay's budget first (past it the stroke simulates nothing and says why).
        if let Err(refused) = self.clay.check_dense_room(density_id(patch), b) {
            self.refuse_for_budget(refused);
            self.rebuild_pins();
            return;
        }
        self.region_patch = patch;
        let n = b.dims();
        let s = self.config.samples_per_span.max(1);
        let mass_dims = [(n[0] - 1) * s + 1, (n[1] - 1) * s + 1, (n[2] - 1) * s + 1];
        let lattice = &self.clay.density.patches[patch].lattice;
        self.region_material = self.config.material;
        match RegionState::new(lattice, b, mass_dims, self.region_material_of(patch)) {
            Ok(mut state) => {
                if self.config.two_level_detail {
                    // Coarse springs one base mass spacing apart: every `ratio`-th point.
                    let ratio = self.spacing_ratio(patch);
                    state.set_coarse_springs(ratio, ratio);
                } else if self.config.detail_base_yield {
                    let ratio = self.spacing_ratio(patch);
                    state.set_base_step_threshold(ratio);
                    // The chisel's and the squirt's targets, planned along the stroke, are
                    // reached at the base's pace (the push's travel stays the patch's: at
                    // the base's, a stiff painted half dented as deep as the soft one).
                    if matches!(
                        self.tool.choice(),
                        ToolChoice::Force {
                            tool: ForceTool::Chisel { .. } | ForceTool::Squirt { .. },
                            ..
                        }
                    ) {
                        state.set_planned_travel_ratio(ratio);
                    }
                }
                self.apply_painted_material(&mut state);
                if let Some(old) = &previous {
                    state.carry_rest_from(old);
                }
                dynaclay_core::tools::region_holds(&self.clay, patch, b, &mut state.held);
                self.region = Some(state);
            }
            Err(_) => self.counters.command_errors(1),
        }
        self.rebuild_pins();
    }

    /// Ends the active region: its final coefficients stay in the lattice and are published
    /// until both readers have them; the stroke's undo step is recorded if no stroke is held.
    fn retire_region(&mut self) {
        if let Some(region) = self.region.take() {
            self.mark_changed(self.region_patch, region.coeff_box());
        }
        self.idle_steps = 0;
        if !self.was_active {
            self.commit_recorder();
        }
    }

    fn commit_recorder(&mut self) {
        if let Some(rec) = self.recorder.take() {
            let changed = self.commit(rec);
            if std::mem::take(&mut self.stroke_is_contact) && changed {
                self.contact_committed();
            }
        }
    }

    /// Records a finished step and tells the I/O thread (autosave counts strokes); returns
    /// whether the step changed the clay.
    fn commit(&mut self, mut rec: StepRecorder) -> bool {
        self.coarsen_wiped_detail(&mut rec);
        let changed = self.history.commit(rec, &self.clay);
        if changed {
            self.clay_revision += 1;
            if let Some(io) = &self.io {
                let _ = io.send(IoJob::Committed);
            }
        }
        changed
    }

    /// Ends a held or settling stroke now: the region retires and the stroke's step is
    /// committed; a stroke still held continues as a new stroke from the next step.
    fn end_stroke_now(&mut self) {
        if self.was_active {
            self.removal.stroke_ended(self.config.removal_guard);
        }
        self.was_active = false;
        self.track.settle();
        self.retire_region();
        self.commit_recorder();
        self.tool.end_stroke();
    }

    /// Ends the session: retires the region and records the last stroke's undo step.
    pub fn finish(&mut self) {
        self.track.settle();
        if self.was_active {
            self.removal.stroke_ended(self.config.removal_guard);
        }
        self.was_active = false;
        self.retire_region();
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;
    use std::time::Instant;

    use crossbeam::channel::bounded;
    use dynaclay_devices::{SimArmConfig, SimulatedArm, Trajectory};

    use super::super::{EngineConfig, HeadlessSink, Stages, build, build_clay};
    use super::*;
    use dynaclay_core::io::{ClayShape, ClaySpec};

    fn stages() -> Stages {
        stages_on_sphere(12)
    }

    /// A held stroke in lockstep: the tip at `tip_at(t)` for `t` from 0 to 1 over `steps`
    /// simulation steps (one per millisecond of device time), then `settle` more steps at the
    /// end with the stroke released.
    pub(super) fn drag_tip(s: &mut Stages, tip_at: impl Fn(f32) -> Vec3, steps: u64, settle: u64) {
        for n in 0..=steps + settle {
            let tip = tip_at(n.min(steps) as f32 / steps as f32);
            let sample = ToolSample {
                tip_fu: tip,
                force_from_fu: tip,
                force_to_fu: tip,
                stroke_active: n < steps,
                device_time_us: n * 1000,
                tick: n,
                ..ToolSample::IDLE
            };
            s.haptic.tick(Instant::now());
            s.sim.apply_commands();
            s.sim.step(&sample);
            s.graphics.tick();
        }
    }

    /// The top of the sphere clay of [`stages_on_sphere`] above its centre, to half a
    /// thousandth.
    pub(super) fn sphere_top(s: &Stages) -> Vec3 {
        let lattice = s.sim.lattice();
        let last = lattice.dims[0] - 1;
        let mut top = (lattice.origin + lattice.node_position(last, last, last)) * 0.5;
        while s.sim.clay.density.is_inside(top + Vec3::Y * 0.0005) {
            top.y += 0.0005;
        }
        top
    }

    /// The stages on a sphere clay of `resolution`³ coefficients, the tool waiting at a
    /// workspace corner, away from the clay.
    pub(super) fn stages_on_sphere(resolution: usize) -> Stages {
        let field = build_clay(&ClaySpec {
            shape: ClayShape::Sphere,
            resolution,
            ..ClaySpec::default()
        })
        .unwrap();
        let config = EngineConfig::for_field(&field, &SimArmConfig::default_info());
        let arm = SimulatedArm::with_trajectory(Trajectory::hold(Vec3::splat(-0.09)));
        build(
            &config,
            field,
            Box::new(arm),
            Box::new(HeadlessSink::default()),
            true,
        )
        .unwrap()
    }

    /// One undo step made by hand: raise a few coefficients.
    fn record_an_edit(sim: &mut SimulationStage) {
        let b = CoeffBox {
            min: [2; 3],
            max: [4; 3],
        };
        let mut rec = StepRecorder::new("edit");
        rec.touch(&sim.clay, FieldId::Density(0), b);
        let idx = sim.clay.density.patches[0].lattice.index(3, 3, 3);
        sim.clay.density.patches[0]
            .lattice
            .coeffs
            .add_flat(idx, 0.25);
        assert!(sim.history.commit(rec, &sim.clay));
        sim.mark_changed(0, b);
    }

    fn session_with(lattice: BSplineLattice, material: Material) -> Session {
        Session {
            clay: Clay::single(lattice),
            material: MaterialFields {
                uniform: material,
                grids: Vec::new(),
            },
            ..Session::default()
        }
    }

    fn run_ticks(s: &mut Stages, n: usize) {
        for _ in 0..n {
            s.haptic.tick(Instant::now());
            s.sim.apply_commands();
            let sample = s.samples.latest().value;
            s.sim.step(&sample);
            s.graphics.tick();
        }
    }

    #[test]
    fn loading_replaces_the_clay_in_every_loop_and_clears_history() {
        let mut s = stages();
        let mut status = s.sim.take_status_reader().unwrap();
        assert!(s.sim.take_status_reader().is_none(), "one observer end");
        record_an_edit(&mut s.sim);
        run_ticks(&mut s, 3);
        assert_eq!(status.latest().value.undo_steps, 1);
        let triangles_before = s.graphics.octree().triangle_count();

        // A different sculpt on the same lattice: a slab carved off the top.
        let mut loaded = s.sim.lattice().clone();
        let d = loaded.dims;
        for k in d[2] / 2..d[2] {
            for j in 0..d[1] {
                for i in 0..d[0] {
                    let idx = loaded.index(i, j, k);
                    loaded.coeffs.set_flat(idx, 0.0);
                }
            }
        }
        let (tx, rx) = bounded(1);
        s.commands
            .send(Command::Load {
                session: Box::new(session_with(loaded.clone(), Material::ELASTIC)),
                source: "carved.dclay".into(),
                keep_history: false,
                reply: Some(tx),
            })
            .unwrap();
        run_ticks(&mut s, 3);
        let summary = rx.try_recv().unwrap().unwrap();
        assert!(summary.contains("carved.dclay"), "{summary}");
        assert_eq!(s.sim.lattice(), &loaded);
        assert_eq!(s.haptic.field().base(), &loaded, "haptic copy republished");
        assert_eq!(
            s.graphics.field().base(),
            &loaded,
            "graphics copy republished"
        );
        let triangles_after = s.graphics.octree().triangle_count();
        assert!(
            triangles_after < triangles_before,
            "meshes follow: {triangles_before} -> {triangles_after} triangles"
        );
        let st = status.latest().value;
        assert_eq!((st.undo_steps, st.redo_steps), (0, 0), "history cleared");
        assert_eq!(st.material, Material::ELASTIC);
        assert_eq!(st.sessions_loaded, 1);
    }

    #[test]
    fn a_load_that_keeps_history_is_one_undo_step_back_to_the_replaced_clay() {
        let mut s = stages();
        let mut status = s.sim.take_status_reader().unwrap();
        record_an_edit(&mut s.sim);
        run_ticks(&mut s, 3);
        assert_eq!(status.latest().value.undo_steps, 1);
        let edited = s.sim.lattice().clone();
        let mut loaded = edited.clone();
        let top = loaded.dims[2] - 1;
        for j in 0..loaded.dims[1] {
            for i in 0..loaded.dims[0] {
                let idx = loaded.index(i, j, top);
                loaded.coeffs.set_flat(idx, 0.0);
            }
        }
        assert_ne!(loaded, edited);
        let (tx, rx) = bounded(1);
        s.commands
            .send(Command::Load {
                session: Box::new(session_with(loaded.clone(), Material::ELASTIC)),
                source: "other.dclay".into(),
                keep_history: true,
                reply: Some(tx),
            })
            .unwrap();
        run_ticks(&mut s, 3);
        let summary = rx.try_recv().unwrap().unwrap();
        assert!(summary.contains("undo history kept"), "{summary}");
        assert_eq!(s.sim.lattice(), &loaded);
        assert_eq!(status.latest().value.undo_steps, 2, "the edit and the load");

        s.commands.send(Command::Undo).unwrap();
        run_ticks(&mut s, 3);
        assert_eq!(
            s.sim.lattice(),
            &edited,
            "Undo brings the replaced clay back"
        );
        assert_eq!(
            s.graphics.field().base(),
            &edited,
            "and republishes it to the loops"
        );
        s.commands.send(Command::Undo).unwrap();
        run_ticks(&mut s, 3);
        assert_ne!(s.sim.lattice(), &edited, "the edit before it still undoes");
        assert_eq!(status.latest().value.undo_steps, 0);
    }

    #[test]
    fn loading_a_session_file_moves_autosave_beside_it_and_an_imported_scan_does_not() {
        let mut s = stages();
        let (io_tx, io_rx) = crossbeam::channel::unbounded();
        s.sim.io = Some(io_tx);
        for source in ["elsewhere/next.dclay", "scan.ply"] {
            let (tx, rx) = bounded(1);
            let same = session_with(s.sim.lattice().clone(), Material::ELASTIC);
            s.commands
                .send(Command::Load {
                    session: Box::new(same),
                    source: source.into(),
                    keep_history: false,
                    reply: Some(tx),
                })
                .unwrap();
            run_ticks(&mut s, 2);
            rx.try_recv().unwrap().unwrap();
        }
        let followed: Vec<std::path::PathBuf> = io_rx
            .try_iter()
            .filter_map(|job| match job {
                IoJob::Follow(path) => Some(path),
                _ => None,
            })
            .collect();
        assert_eq!(followed, [std::path::PathBuf::from("elsewhere/next.dclay")]);
    }

    #[test]
    fn a_loaded_session_comes_back_whole_paint_patches_grids_tools_and_metadata() {
        let mut s = stages();
        let running = s.sim.lattice().clone();
        let mut colour = dynaclay_core::tools::ColourField::matching(&running).unwrap();
        colour.channels[2].coeffs.set_flat(11, 0.5);
        let full = Session {
            clay: Clay {
                density: MultiPatchField::new(running),
                colour: Some(colour),
                constraints: Vec::new(),
                mask: None,
            },
            material: MaterialFields {
                uniform: Material::PLASTIC,
                grids: vec![dynaclay_core::io::MaterialGrid {
                    name: "damping".into(),
                    dims: [1, 1, 2],
                    values: vec![0.5, 1.5],
                }],
            },
            tools: vec![dynaclay_core::io::ToolPreset {
                name: "ball".into(),
                shape: dynaclay_core::tools::ToolShape::Sphere { radius_fu: 0.1 },
                action: dynaclay_core::tools::ToolAction::Add {
                    deposit_rate_per_s: 2.0,
                },
                falloff_fu: 0.02,
            }],
            meta: dynaclay_core::io::SessionMeta {
                name: "whole".into(),
                created_unix_s: 10,
                saved_unix_s: 20,
                writer: "dynaclay test".into(),
            },
        };
        s.sim
            .load(full.clone(), Path::new("full.dclay"), false)
            .unwrap();
        run_ticks(&mut s, 3);
        assert_eq!(s.sim.session(), full);
    }

    #[test]
    fn a_session_that_does_not_fit_is_refused_and_changes_nothing() {
        let mut s = stages();
        let mut status = s.sim.take_status_reader().unwrap();
        record_an_edit(&mut s.sim);
        run_ticks(&mut s, 2);
        let before = s.sim.lattice().clone();
        let material = s.sim.config.material;

        let mut smaller = build_clay(&ClaySpec {
            shape: ClayShape::Block,
            resolution: 10,
            ..ClaySpec::default()
        })
        .unwrap();
        let mut nan = before.clone();
        nan.coeffs.set_flat(7, f32::NAN);
        let mut none = session_with(before.clone(), Material::ELASTIC);
        none.clay.density.patches.clear();
        let mut two = session_with(before.clone(), Material::ELASTIC);
        two.clay
            .density
            .patches
            .push(dynaclay_core::field::Patch::identity(before.clone()));
        smaller.iso = before.iso;
        let cases = [
            (
                session_with(smaller, Material::ELASTIC),
                "differs",
                "LatticeMismatch",
            ),
            (
                session_with(nan, Material::ELASTIC),
                "coefficient 7",
                "NonFinite",
            ),
            (none, "no density patch", "NoPatch"),
            (two, "laid out", "PatchLayout"),
        ];
        for (session, expected, kind) in cases {
            let (tx, rx) = bounded(1);
            s.commands
                .send(Command::Load {
                    session: Box::new(session),
                    source: "other.dclay".into(),
                    keep_history: false,
                    reply: Some(tx),
                })
                .unwrap();
            run_ticks(&mut s, 2);
            let err = rx.try_recv().unwrap().unwrap_err();
            let CommandError::Load(refused) = &err else {
                panic!("a load refusal: {err:?}");
            };
            assert!(format!("{refused:?}").starts_with(kind), "{refused:?}");
            let shown = err.to_string();
            assert!(
                shown.contains("other.dclay") && shown.contains(expected),
                "{shown}"
            );
        }
        assert_eq!(s.sim.lattice(), &before);
        assert_eq!(s.haptic.field().base(), &before);
        assert_eq!(s.sim.config.material, material);
        let st = status.latest().value;
        assert_eq!((st.undo_steps, st.sessions_loaded), (1, 0));
        assert_eq!(s.counters.snapshot().command_errors, 4);
        assert!(
            check_loadable(
                &MultiPatchField::new(before.clone()),
                &session_with(before.clone(), material),
                Path::new("x")
            )
            .is_ok()
        );
    }
}

#[cfg(test)]
mod compact_tests {
    use std::time::Instant;

    use super::super::{CompactRbfLink, Stages};
    use super::*;
    use dynaclay_core::tools::{ContactParams, GeometricTool, ToolShape};
    use dynaclay_import::rbf::CompactSettings;

    fn stages() -> Stages {
        super::tests::stages_on_sphere(14)
    }

    fn dent(at: Vec3) -> Command {
        Command::ApplyTool {
            tool: GeometricTool {
                shape: ToolShape::Sphere { radius_fu: 0.2 },
                action: ToolAction::Contact(ContactParams {
                    alpha: -1.0,
                    rate_per_s: 2.0,
                }),
                falloff_fu: 0.1,
            },
            poses: vec![ToolPose::at(at)],
            duration_s: 0.3,
            patch: 0,
            reply: None,
        }
    }

    fn tick(s: &mut Stages) {
        s.haptic.tick(Instant::now());
        s.sim.apply_commands();
        let sample = s.samples.latest().value;
        s.sim.step(&sample);
    }

    #[test]
    fn a_contact_step_made_while_a_reinterpolation_runs_is_reinterpolated_on_the_newer_clay() {
        let mut s = stages();
        let link = CompactRbfLink::spawn(CompactSettings::new(120)).unwrap();
        let top = Vec3::new(0.65, 0.65 + 0.325, 0.65);
        // Both in one batch: the dent lands while I⁰ is being computed from the clay before it.
        s.commands
            .send(Command::SetCompactRbf(Some(Box::new(link))))
            .unwrap();
        s.commands.send(dent(top)).unwrap();
        tick(&mut s);
        assert!(s.sim.compact_status().busy);
        assert_eq!(s.sim.undo_len(), 1, "the dent");
        s.sim.settle_compact();
        let status = s.sim.compact_status();
        assert_eq!(
            (status.applied, status.superseded, status.failed),
            (1, 1, 0),
            "{status:?}"
        );
        assert_eq!(status.centres, Some(360));
        assert!(!status.busy);
        // The applied RBF holds the dent: it is the clay's fit, one more undo step.
        assert_eq!(s.sim.undo_len(), 2);
        let fit = s.sim.compact_rbf().unwrap().to_clay(2).unwrap();
        assert_eq!(fit.coeffs, s.sim.lattice().coeffs);
        assert!(s.sim.lattice().value(top - Vec3::Y * 0.05) < s.sim.lattice().iso);

        // Undo takes the re-interpolation back; an answer is not asked for again.
        let fitted = s.sim.lattice().clone();
        s.commands.send(Command::Undo).unwrap();
        tick(&mut s);
        assert_ne!(s.sim.lattice().coeffs, fitted.coeffs);
        assert!(!s.sim.compact_in_flight());
        assert_eq!(s.sim.redo_len(), 1);

        // Off: the worker is dropped; further contact steps are plain edits.
        s.commands.send(Command::SetCompactRbf(None)).unwrap();
        s.commands.send(dent(Vec3::new(0.65, 0.325, 0.65))).unwrap();
        tick(&mut s);
        assert_eq!(
            s.sim.compact_status(),
            super::super::CompactStatus::default()
        );
        assert!(!s.sim.compact_in_flight());
    }
}
