//! Adapter between the app's [`EngineLink`](super::EngineLink) and the threaded
//! [`Engine`]: a mesh sink on the graphics loop that publishes brick meshes, and a bridge
//! thread that turns app commands into engine commands and publishes the [`EngineView`].
//!
//! Guarantee: neither side ever waits for the app. The sink runs on the graphics loop (not the
//! haptic loop), copies only the bricks a refresh changed, publishes through a triple buffer
//! (a second one for the bridge thread's exports, and a third with its field copy for the
//! pointer's picking) and then asks for a repaint: no lock anywhere. The bridge thread is an ordinary thread: it sends engine
//! commands on the engine's own channel, reads the tool sample, the simulation's status and
//! each loop's latency figures wait-free, sets the force limit through an atomic the haptic
//! tick reads, and reads sessions and writes exports itself, so no loop does disk I/O for
//! the app.
//!
//! The app draws only when woken: the sink asks for a repaint after new meshes, and the
//! bridge after an answer for the app or a view that draws differently
//! ([`EngineView::same_picture`]: the loops' figures and the simulated time alone do not
//! wake it), so an idle window costs no frames.
//!
//! The device panel's connect and disconnect reach [`Engine::replace_device`] and
//! [`Engine::disconnect_device`] from the bridge thread: the device is opened and the old one
//! closed there, and the haptic loop switches between two ticks without stopping.
//!
//! Load reads a session, or fits a point cloud, mesh or volume as `dynaclay import` does
//! ([`crate::fit::import_session`]), here on the bridge thread. A clay whose patch layout
//! differs from the running one cannot enter the running loops (their copies are laid out
//! for it), so the bridge stops the engine ([`Engine::stop_keeping_parts`]: the device and
//! this sink come back), writes the replaced clay to [`RestartSettings::keep_replaced_at`] and
//! starts a new engine on the loaded clay with the same device.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::Duration;

use crossbeam::channel::{Receiver, Sender, bounded};
use dynaclay_devices::spec::DeviceSpec;
use dynaclay_devices::{DeviceInfo, HapticDevice};
use dynaclay_loops::{SnapshotReader, SnapshotWriter, snapshot_channel};
use glam::Vec3;

use super::command::{EngineCommand, EngineEvent};
use super::device_maker::MakeDeviceError;
use super::link::{EngineEndpoint, EventSender, RepaintSignal};
use super::meshes::{ChunkMesh, MeshSet};
use super::view::{DeviceLinkState, EngineView, WorldBox};
use crate::engine::{
    Command, CommandError, CompactRbfLink, Engine, EngineConfig, EngineError, EngineReport,
    LoadRefused, MeshSink, PushTool, StartOptions,
};
use crate::field::MultiPatchField;
use crate::fit::{
    FitProgress, ImportError, ImportSettings, import_cloud, import_session, is_point_cloud,
};
use crate::io::{Autosave, AutosavePolicy, Session, load_session, save_session};
use crate::mesh::{
    BrickOctree, ExportError, MeshFormat, RefreshReport, WeldPiece, split_non_manifold,
    weld_pieces, write_mesh,
};
use crate::particles::ParticleFollower;
use crate::pointset::{FollowedPoints, PointSet, PointSetFollower, PointSetOptions};
use crate::rbf::CompactSettings;
use crate::render::ChunkError;
use crate::render::surface_colors;
use crate::tools::{ColourField, FreezeMask};

mod commands;
mod devices;
mod load_worker;
mod loading;
mod sink;
#[cfg(test)]
mod tests;

use devices::closed_detail;
pub use sink::{ChunkExportError, GuiMeshSink, export_chunks};

/// How often the bridge drains commands and publishes the view.
const BRIDGE_PERIOD: Duration = Duration::from_millis(10);

/// Particle steps per update of the clay (and per idle update while they settle), a fixed
/// budget on the graphics loop.
const PARTICLE_STEPS_PER_UPDATE: usize = 2;

/// Point sets handed to the graphics loop and not yet taken, at most (it takes the newest).
const POINT_SETS_QUEUED: usize = 4;

/// How long a device switch waits for the haptic loop to take the new device.
const SWAP_TIMEOUT: Duration = Duration::from_secs(2);

/// The device the engine starts with: the spec it was made from and what its driver says.
#[derive(Clone, Debug)]
pub struct DeviceInUse {
    /// The spec as `--device` takes it (the panels show it as the device in use).
    pub spec: DeviceSpec,
    /// The driver's description.
    pub info: DeviceInfo,
}

/// Makes (without opening) the device a spec names; the bridge opens it through the engine.
pub type DeviceOpener =
    Box<dyn FnMut(&DeviceSpec) -> Result<Box<dyn HapticDevice>, MakeDeviceError> + Send>;

/// A running bridge; stopping it stops the engine.
pub struct EngineBridge {
    stop: Arc<AtomicBool>,
    thread: JoinHandle<Result<EngineReport, EngineError>>,
}

impl EngineBridge {
    /// Stops the bridge, then the engine, and returns the engine's report.
    ///
    /// # Errors
    /// The engine's error from [`Engine::stop`]; a panicked bridge thread is reported as
    /// [`EngineError::Lost`].
    pub fn stop(self) -> Result<EngineReport, EngineError> {
        self.stop.store(true, Ordering::Relaxed);
        dynaclay_loops::assert_not_in_tick("EngineBridge::stop joining the bridge");
        self.thread
            .join()
            .unwrap_or(Err(EngineError::Lost("gui bridge")))
    }
}

/// Starts the engine with a mesh sink that feeds `endpoint`, and a bridge thread that serves
/// the app's commands. `start` receives the sink and starts the engine (the caller chooses
/// clay, device and configuration); `device` names and describes the opened device for the
/// panel;
/// `opener` makes the devices the panel connects later; `restart` says how to start again on
/// a loaded clay whose patch layout differs from the running one.
///
/// # Errors
/// Whatever `start` returns.
pub fn start_bridge(
    endpoint: EngineEndpoint,
    device: DeviceInUse,
    opener: DeviceOpener,
    restart: Option<RestartSettings>,
    start: impl FnOnce(Box<dyn MeshSink>) -> Result<Engine, EngineError>,
) -> Result<EngineBridge, EngineError> {
    let EngineEndpoint {
        commands,
        events,
        view,
        meshes,
        field,
        particles,
        points,
        repaint,
        mesh_stamps,
    } = endpoint;
    let (exports_tx, exports) = snapshot_channel(&MeshSet::new());
    let sink = GuiMeshSink::new(meshes, field, exports_tx, repaint.clone());
    // No point set until a point cloud is loaded: then the bridge hands its points over and
    // they follow each new copy of the clay on the graphics loop.
    let (points_tx, points_rx) = bounded(POINT_SETS_QUEUED);
    let sink = PointSetFollower::new(sink, points_rx, points);
    // Off until the app turns the particles on: then the follower takes its fixed budget of
    // steps on each new copy of the clay (and a bounded number of idle updates after it).
    let sink = ParticleFollower::with_handles(
        sink,
        particles.view,
        particles.count,
        particles.on,
        PARTICLE_STEPS_PER_UPDATE,
    );
    let mut engine = start(Box::new(sink))?;
    send_stamps(&mut engine, &mesh_stamps);
    let stop = Arc::new(AtomicBool::new(false));
    let flag = Arc::clone(&stop);
    let mut bridge = Bridge {
        engine: Some(engine),
        restart,
        restarts: 0,
        new_clay: None,
        commands,
        events,
        view,
        exports,
        device: device.info,
        spec: Some(device.spec),
        connected: true,
        repaint,
        shown: None,
        refusal_shown: None,
        opener,
        tool_radius: PushTool::default().radius_fu,
        compact_particles: None,
        saves: Vec::new(),
        loads: Vec::new(),
        load_worker: None,
        session_path: None,
        pin_replies: Vec::new(),
        refine_replies: Vec::new(),
        edit_replies: Vec::new(),
        pins_seen: None,
        pins_list: None,
        pin_lines: Vec::new(),
        pin_marks: Vec::new(),
        points: points_tx,
        mesh_stamps,
    };
    let thread = std::thread::Builder::new()
        .name("dynaclay-gui-bridge".into())
        .spawn(move || {
            while !flag.load(Ordering::Relaxed)
                && bridge.engine.as_ref().is_some_and(Engine::is_alive)
            {
                bridge.serve();
                std::thread::sleep(BRIDGE_PERIOD);
            }
            match bridge.engine.take() {
                Some(engine) => engine.stop(),
                None => Err(EngineError::Lost(
                    "engine (its restart on a loaded clay failed)",
                )),
            }
        })
        .map_err(|source| {
            EngineError::Loop(dynaclay_loops::LoopError::Spawn {
                loop_name: "gui bridge".into(),
                source,
            })
        })?;
    Ok(EngineBridge { stop, thread })
}

/// How the bridge restarts the engine on a loaded clay whose patch layout differs from the
/// running one (the loops hold copies laid out for the running clay, so such a clay needs a
/// new engine).
#[derive(Clone, Debug)]
pub struct RestartSettings {
    /// The running engine's configuration: the new one keeps its rates, real-time priority,
    /// staleness limits and safety settings, with the workspace map and force scale fitted
    /// to the new clay ([`EngineConfig::for_clay`]).
    pub config: EngineConfig,
    /// The session path autosave writes its recovery file next to, for the new engine.
    pub autosave: Option<PathBuf>,
    /// Where the replaced clay is written before the new one starts, so no work is lost.
    pub keep_replaced_at: PathBuf,
}

/// A load the simulation has not answered yet; `session` is kept to restart on when the
/// simulation refuses it for its layout.
struct PendingLoad {
    reply: Receiver<Result<String, CommandError>>,
    session: Option<Box<Session>>,
    source: PathBuf,
    /// The loaded point set, handed to the graphics loop once the clay is in (`None`: the
    /// load brings none, and the points shown so far go).
    points: Option<Box<FollowedPoints>>,
    /// The session's tool library, handed to the app once the clay is in.
    tools: Vec<crate::io::ToolPreset>,
}

struct Bridge {
    /// The running engine (`None` only after a restart failed; the bridge then stops).
    engine: Option<Engine>,
    commands: Receiver<EngineCommand>,
    events: EventSender,
    view: SnapshotWriter<EngineView>,
    /// The latest meshes, for exports (read wait-free).
    exports: SnapshotReader<MeshSet>,
    device: DeviceInfo,
    /// The spec of the device in use, or of the last one after the panel's disconnect (the
    /// view's state says which).
    spec: Option<DeviceSpec>,
    /// Whether a device is connected (false after the panel's disconnect).
    connected: bool,
    /// Wakes the app after an answer or a view that draws differently.
    repaint: RepaintSignal,
    /// The view the app was last woken for (`None`: never).
    shown: Option<EngineView>,
    /// The simulation's newest refused edit as last shown in the log (see
    /// [`budget_refusal_event`]).
    refusal_shown: Option<crate::engine::BudgetRefusal>,
    opener: DeviceOpener,
    tool_radius: f32,
    saves: Vec<Receiver<Result<std::path::PathBuf, crate::engine::SaveError>>>,
    loads: Vec<PendingLoad>,
    /// The Open, Import or New being read, fitted or built (one at a time).
    load_worker: Option<load_worker::LoadWorker>,
    /// The session worked on since the last Save or Open of a session file (`None`: the one
    /// the window started with): an engine restarted on another clay autosaves beside it.
    session_path: Option<PathBuf>,
    /// How the engine restarts on a clay of another layout (`None`: such loads are refused).
    restart: Option<RestartSettings>,
    /// Restarts so far (see [`EngineView::restarts`]).
    restarts: u64,
    /// The compact RBF clay's particle count while the app has it on (given again to an
    /// engine restarted on another clay).
    compact_particles: Option<usize>,
    /// The clay's box and workspace map since the last restart.
    new_clay: Option<(WorldBox, crate::engine::WorkspaceMap)>,
    /// Answers to pin and unpin commands.
    pin_replies: Vec<Receiver<Result<String, crate::engine::CommandError>>>,
    /// Answers to "refine here" not yet shown.
    refine_replies: Vec<Receiver<Result<String, crate::engine::CommandError>>>,
    /// Answers to the library, CSG and emboss edits not yet shown.
    edit_replies: super::edit_requests::PendingEdits,
    /// The pins revision last asked about, and the list asked for.
    pins_seen: Option<u64>,
    pins_list: Option<Receiver<Vec<crate::dynamics::Constraint>>>,
    /// The latest pin list, one line each (copied into every view: the view's buffers
    /// rotate, so each publication carries the whole list).
    pin_lines: Vec<String>,
    /// Where the pins are (see [`EngineView::pin_marks`]).
    pin_marks: Vec<Vec<Vec3>>,
    /// Point sets for the graphics loop's follower (`None`: drop the points).
    points: Sender<Option<Box<FollowedPoints>>>,
    /// Where each engine started sends the app its clock and mesh stamps.
    mesh_stamps: Sender<super::link::MeshStampSource>,
}

/// Forwards each answer that arrived on `pending` as an event (`describe` turns a success
/// into its detail line) and forgets the channels that answered or hung up.
/// Hands the app `engine`'s clock and mesh stamps (a closed app end is nothing to report).
fn send_stamps(engine: &mut Engine, to: &Sender<super::link::MeshStampSource>) {
    if let Some(stamps) = engine.take_mesh_stamps() {
        let _ = to.send(super::link::MeshStampSource {
            clock: engine.clock(),
            stamps,
        });
    }
}

fn forward_replies<T, E: std::fmt::Display>(
    pending: &mut Vec<Receiver<Result<T, E>>>,
    events: &EventSender,
    what: &str,
    describe: impl Fn(T) -> String,
) {
    pending.retain(|rx| match rx.try_recv() {
        Ok(r) => {
            let ev = match r {
                Ok(v) => EngineEvent::Done {
                    what: what.into(),
                    detail: describe(v),
                },
                Err(error) => EngineEvent::Failed {
                    what: what.into(),
                    error: error.to_string(),
                },
            };
            let _ = events.send(ev);
            false
        }
        Err(crossbeam::channel::TryRecvError::Empty) => true,
        Err(crossbeam::channel::TryRecvError::Disconnected) => {
            let _ = events.send(EngineEvent::Failed {
                what: what.into(),
                error: "the engine stopped before answering".into(),
            });
            false
        }
    });
}

impl Bridge {
    /// Tells the app each save that finished; a saved session is the session worked on
    /// from now on (the engine's autosave follows it too, see `Command::Save`).
    fn forward_saves(&mut self) {
        let events = &self.events;
        let session_path = &mut self.session_path;
        self.saves.retain(|rx| {
            let event = match rx.try_recv() {
                Ok(Ok(path)) => {
                    *session_path = Some(path.clone());
                    let _ = events.send(EngineEvent::FileDone {
                        path: path.clone(),
                        is_session: true,
                    });
                    EngineEvent::Done {
                        what: "save".into(),
                        detail: format!("wrote {}", path.display()),
                    }
                }
                Ok(Err(error)) => EngineEvent::Failed {
                    what: "save".into(),
                    error: error.to_string(),
                },
                Err(crossbeam::channel::TryRecvError::Empty) => return true,
                Err(crossbeam::channel::TryRecvError::Disconnected) => EngineEvent::Failed {
                    what: "save".into(),
                    error: "the engine stopped before answering".into(),
                },
            };
            let _ = events.send(event);
            false
        });
    }

    /// The running engine. Only called while one runs: the serve loop stops at once when a
    /// failed restart left none.
    fn engine(&self) -> &Engine {
        self.engine
            .as_ref()
            .expect("the bridge serves only while an engine runs")
    }

    fn engine_mut(&mut self) -> &mut Engine {
        self.engine
            .as_mut()
            .expect("the bridge serves only while an engine runs")
    }

    fn serve(&mut self) {
        while self.engine.is_some()
            && let Ok(cmd) = self.commands.try_recv()
        {
            self.apply(cmd);
        }
        if self.engine.is_none() {
            return;
        }
        self.forward_saves();
        self.poll_load_worker();
        self.poll_loads();
        if self.engine.is_none() {
            return;
        }
        forward_replies(&mut self.pin_replies, &self.events, "pins", |detail| detail);
        forward_replies(&mut self.refine_replies, &self.events, "refine", |detail| {
            detail
        });
        super::edit_requests::forward_edits(&mut self.edit_replies, &self.events);
        // Nothing to show before the simulation's first step (its material is not known yet).
        let Some(status) = self.engine_mut().sim_status() else {
            return;
        };
        self.poll_pins(status.pins_revision);
        if let Some(event) = budget_refusal_event(&mut self.refusal_shown, status.budget_refusal) {
            let _ = self.events.send(event);
        }
        let engine = self.engine_mut();
        let tool = engine.latest_tool();
        let counters = engine.counters().snapshot();
        let loops = engine.loop_stats().map(|(_, stats)| stats);
        let force_limit_n = engine.force_limit().applied_n();
        let (restarts, new_clay) = (self.restarts, self.new_clay);
        let device = &self.device;
        let spec = &self.spec;
        let connected = self.connected;
        let shown = &mut self.shown;
        let mut new_picture = false;
        let radius = self.tool_radius;
        let (pin_lines, pin_marks) = (&self.pin_lines, &self.pin_marks);
        self.view.write_with(|v| {
            v.restarts = restarts;
            if let Some((clay_box, map)) = new_clay {
                v.clay_box = Some(clay_box);
                v.workspace_map = Some(map);
            }
            v.pins.clone_from(pin_lines);
            v.pin_marks.clone_from(pin_marks);
            v.loops = loops;
            v.undo_steps = status.undo_steps;
            v.redo_steps = status.redo_steps;
            v.material = status.material;
            v.sessions_loaded = status.sessions_loaded;
            v.region = status.region.map(|(min, max)| WorldBox { min, max });
            v.sim_time_s = status.sim_time_s;
            v.compact = status.compact;
            v.removal_question = status.removal_question;
            // A tool felt with its shape is drawn where it rests on the clay (the hand's
            // device may be pressed past it), so the clay is where the tool is drawn.
            v.tool_position = tool.resting_at.unwrap_or(tool.tip_fu);
            v.tool_radius = radius;
            v.force_n = if tool.device_force_n.is_finite() {
                tool.device_force_n
            } else {
                Vec3::ZERO
            };
            v.stroke_active = tool.stroke_active;
            v.device.state = if !connected {
                DeviceLinkState::Disconnected
            } else if tool.device_fault {
                DeviceLinkState::Faulted
            } else {
                DeviceLinkState::Connected
            };
            v.device.name.clone_from(&device.name);
            v.device.max_force_n = force_limit_n;
            v.device.device_max_force_n = device.max_force_n;
            v.device.has_force = device.has_force;
            v.device.peak_force_n = counters.peak_force_milli_n as f32 / 1000.0;
            v.device.spec.clone_from(spec);
            if !shown.as_ref().is_some_and(|s| s.same_picture(v)) {
                new_picture = true;
                match shown {
                    Some(s) => s.clone_from(v),
                    None => *shown = Some(v.clone()),
                }
            }
        });
        // Answers for the log wake the app as they are sent (see `EventSender`).
        if new_picture {
            self.repaint.request();
        }
    }
}

/// The log line for an edit the simulation refused or clipped for one of the clay's budgets (a
/// stroke of the hand, which has no reply to carry it): the status holds the newest refusal, so
/// one line is shown each time it differs from the one `shown` last.
fn budget_refusal_event(
    shown: &mut Option<crate::engine::BudgetRefusal>,
    now: Option<crate::engine::BudgetRefusal>,
) -> Option<EngineEvent> {
    if now == *shown {
        return None;
    }
    *shown = now;
    now.map(|refused| EngineEvent::Failed {
        what: "edit".into(),
        error: refused.to_string(),
    })
}
