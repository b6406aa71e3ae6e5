//! Builds the three stages and the channels between them (shared by the threaded engine and
//! the lockstep driver).

use std::time::Duration;

use crossbeam::channel::{Receiver, Sender};
use dynaclay_devices::{HapticDevice, SafetyFilter};
use dynaclay_loops::{SnapshotReader, Staleness, snapshot_channel};

use super::clock::EngineClock;
use super::command::Command;
use super::config::EngineConfig;
use super::counters::EngineCounters;
use super::device_swap::{DeviceSwapRequest, device_swap_channel};
use super::error::EngineError;
use super::graphics::{GraphicsStage, MeshSink};
use super::haptic::HapticStage;
use super::layout::{HAPTIC_SPARE_BRICKS, layout_channel, layout_channel_with_spares};
use super::motion_to_photon::MeshStamp;
use super::simulation::{Acks, IoJob, SimulationStage};
use super::tool_sample::ToolSample;
use super::update::FieldUpdate;
use dynaclay_core::field::MultiPatchField;

/// The three stages, connected.
pub struct Stages {
    pub haptic: HapticStage,
    pub sim: SimulationStage,
    pub graphics: GraphicsStage,
    /// The simulation's end of the tool-sample buffer.
    pub samples: SnapshotReader<ToolSample>,
    /// Observers' end of the tool samples (cursor drawing, tests).
    pub tool_monitor: SnapshotReader<ToolSample>,
    /// Where commands go.
    pub commands: Sender<Command>,
    /// File work handed out by the simulation (saves, autosave notes).
    pub io_jobs: Receiver<IoJob>,
    pub counters: EngineCounters,
    /// Where a replacement device is handed to the haptic stage while it runs.
    pub device_swaps: DeviceSwapRequest,
    /// The clock every stage stamps with: stepped in a lockstep build (its driver moves it),
    /// the wall clock otherwise.
    pub clock: EngineClock,
    /// Whoever draws frames: the stamp of the graphics loop's newest meshes (see
    /// [`super::motion_to_photon`]).
    pub mesh_stamps: SnapshotReader<MeshStamp>,
}

/// Opens `device` behind the safety filter and builds the stages around `field` (the clay's
/// density: one lattice, or a base patch with detail patches).
/// `lockstep` disables the staleness fade (a lockstep simulation cannot fall behind).
///
/// # Errors
/// When the device does not open or the mesh grid cannot be made.
pub fn build(
    config: &EngineConfig,
    field: impl Into<MultiPatchField>,
    device: Box<dyn HapticDevice>,
    sink: Box<dyn MeshSink>,
    lockstep: bool,
) -> Result<Stages, EngineError> {
    let mut device = SafetyFilter::with_config(device, config.safety);
    device.open()?;
    let counters = EngineCounters::new();
    let field = field.into();
    let empty = FieldUpdate::with_capacity_for(&field);
    let (to_haptic, from_sim_h) = snapshot_channel(&empty);
    let (to_graphics, from_sim_g) = snapshot_channel(&empty);
    let (samples_tx, samples_rx) = snapshot_channel(&ToolSample::IDLE);
    let (monitor_tx, monitor_rx) = snapshot_channel(&ToolSample::IDLE);
    let (cmd_tx, cmd_rx) = crossbeam::channel::unbounded();
    let (io_tx, io_rx) = crossbeam::channel::unbounded();
    let acks = Acks::default();
    let (device_swaps, swap_port) = device_swap_channel();
    let (haptic_layouts, haptic_layout_port) = layout_channel_with_spares(HAPTIC_SPARE_BRICKS);
    let (graphics_layouts, graphics_layout_port) = layout_channel();
    let clock = if lockstep {
        EngineClock::stepped()
    } else {
        EngineClock::wall()
    };
    let (mesh_stamps_tx, mesh_stamps) = snapshot_channel(&MeshStamp::default());
    let staleness = if lockstep {
        Staleness::new(Duration::MAX, Duration::MAX)
    } else {
        Staleness::new(config.stale_fresh, config.stale_limit)
    };
    let haptic = HapticStage::new(
        device,
        field.clone(),
        haptic_layout_port,
        from_sim_h,
        samples_tx,
        monitor_tx,
        config.map,
        staleness,
        config.haptics,
        counters.clone(),
        acks.haptic.clone(),
        swap_port,
        clock.clone(),
    );
    // The graphics stage is built after the simulation, whose paint channel it reads.
    let (graphics_field, graphics_ack) = (field.clone(), acks.graphics.clone());
    let mut sim = SimulationStage::new(
        config.sim,
        field,
        to_haptic,
        to_graphics,
        acks,
        cmd_rx,
        Some(io_tx),
        counters.clone(),
        clock.clone(),
    );
    sim.set_layout_senders([haptic_layouts, graphics_layouts]);
    let colours = sim
        .take_colour_reader()
        .ok_or(EngineError::Lost("simulation paint"))?;
    let masks = sim
        .take_mask_reader()
        .ok_or(EngineError::Lost("simulation mask"))?;
    let mut graphics = GraphicsStage::new(
        graphics_field,
        graphics_layout_port,
        config.cells_per_span,
        from_sim_g,
        colours,
        graphics_ack,
        sink,
        counters.clone(),
        clock.clone(),
        mesh_stamps_tx,
    )?;
    graphics.set_mask_reader(masks);
    Ok(Stages {
        haptic,
        sim,
        graphics,
        samples: samples_rx,
        tool_monitor: monitor_rx,
        commands: cmd_tx,
        io_jobs: io_rx,
        counters,
        device_swaps,
        clock,
        mesh_stamps,
    })
}
