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
use super::launch::MakeDeviceError;
use super::link::{EngineEndpoint, RepaintSignal};
use super::meshes::{ChunkMesh, MeshSet};
use super::view::{DeviceLinkState, EngineView, WorldBox};
use crate::engine::{
    Command, CommandError, CompactRbfLink, Engine, EngineConfig, EngineError, EngineReport,
    LoadRefused, MeshSink, PushTool, StartOptions,
};
use crate::field::MultiPatchField;
use crate::fit::{
    FitProgress, ImportError, ImportSettings, import_cloud, import_session, imported_session,
    is_point_cloud,
};
use crate::io::{Autosave, AutosavePolicy, Session, load_session, save_session};
use crate::mesh::{
    BrickOctree, ExportError, MeshFormat, RefreshReport, WeldPiece, weld_pieces, write_mesh,
};
use crate::particles::ParticleFollower;
use crate::pointset::{FollowedPoints, PointSet, PointSetFollower, PointSetOptions};
use crate::rbf::CompactSettings;
use crate::render::ChunkError;
use crate::render::paint_colors;
use crate::tools::ColourField;

/// How often the bridge drains commands and publishes the view.
const BRIDGE_PERIOD: Duration = Duration::from_millis(10);

/// Particle steps per update of the clay (and per idle update while they settle), a fixed
/// budget on the graphics loop.
const PARTICLE_STEPS_PER_UPDATE: usize = 2;

/// Point sets handed to the graphics loop and not yet taken, at most (it takes the newest).
const POINT_SETS_QUEUED: usize = 4;

/// How long a device switch waits for the haptic loop to take the new device.
const SWAP_TIMEOUT: Duration = Duration::from_secs(2);

/// Makes (without opening) the device a spec names; the bridge opens it through the engine.
pub type DeviceOpener =
    Box<dyn FnMut(&DeviceSpec) -> Result<Box<dyn HapticDevice>, MakeDeviceError> + Send>;

/// Publishes the graphics loop's brick meshes, painted, to the app.
pub struct GuiMeshSink {
    meshes: SnapshotWriter<MeshSet>,
    bricks: HashMap<[u32; 3], Arc<ChunkMesh>>,
    set: MeshSet,
    /// The latest set, for exports by the bridge thread (held only to clone the `Arc`s).
    exports: SnapshotWriter<MeshSet>,
    repaint: RepaintSignal,
    /// The clay's paint, as last handed over by the graphics stage.
    colour: Option<ColourField>,
    /// The clay, for the app's pointer picking.
    field: SnapshotWriter<MultiPatchField>,
    /// Version for the next chunk made: the renderer re-uploads a chunk whose version
    /// changed, and a recoloured brick keeps its octree version, so the sink numbers chunks.
    next_version: u64,
}

impl GuiMeshSink {
    /// A sink publishing on `meshes` (and on `exports` for the bridge thread's exports), unpainted until the
    /// graphics stage hands it paint.
    fn new(
        meshes: SnapshotWriter<MeshSet>,
        field: SnapshotWriter<MultiPatchField>,
        exports: SnapshotWriter<MeshSet>,
        repaint: RepaintSignal,
    ) -> Self {
        Self {
            field,
            meshes,
            bricks: HashMap::new(),
            set: MeshSet::new(),
            exports,
            repaint,
            colour: None,
            next_version: 0,
        }
    }

    fn chunk(&mut self, coord: [u32; 3], mesh: &crate::mesh::BrickMesh) -> Arc<ChunkMesh> {
        let colors = self
            .colour
            .as_ref()
            .map_or_else(Vec::new, |c| paint_colors(mesh, c));
        self.next_version += 1;
        Arc::new(ChunkMesh::from_brick(
            coord,
            self.next_version,
            mesh,
            colors,
        ))
    }

    fn publish(&mut self) {
        self.set.clear();
        self.set.extend(self.bricks.values().cloned());
        self.meshes.publish_clone_of(&self.set);
        self.exports.publish_clone_of(&self.set);
        self.repaint.request();
    }
}

impl MeshSink for GuiMeshSink {
    fn update(&mut self, octree: &BrickOctree, report: &RefreshReport) {
        for c in &report.removed {
            self.bricks.remove(c);
        }
        for c in &report.changed {
            match octree.brick(*c) {
                Some(b) if !b.mesh.indices.is_empty() => {
                    let chunk = self.chunk(*c, &b.mesh);
                    self.bricks.insert(*c, chunk);
                }
                _ => {
                    self.bricks.remove(c);
                }
            }
        }
        self.publish();
    }

    /// Recolours every brick whose paint changed (the others keep their chunk, so the
    /// renderer uploads only the repainted ones).
    fn paint(&mut self, octree: &BrickOctree, colour: Option<&ColourField>) {
        self.colour = colour.cloned();
        let coords: Vec<[u32; 3]> = self.bricks.keys().copied().collect();
        for c in coords {
            let Some(b) = octree.brick(c) else { continue };
            let colors = self
                .colour
                .as_ref()
                .map_or_else(Vec::new, |p| paint_colors(&b.mesh, p));
            if self
                .bricks
                .get(&c)
                .is_some_and(|held| held.colors == colors)
            {
                continue;
            }
            self.next_version += 1;
            let chunk = ChunkMesh::from_brick(c, self.next_version, &b.mesh, colors);
            self.bricks.insert(c, Arc::new(chunk));
        }
        self.publish();
    }

    fn field(&mut self, field: &MultiPatchField) {
        self.field.publish_clone_of(field);
    }

    /// The engine restarts on another clay: its bricks go, and the app sees no meshes until
    /// the new graphics loop publishes its own.
    fn restart(&mut self) {
        self.bricks.clear();
        self.colour = None;
        self.publish();
    }
}

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
/// clay, device and configuration); `device` describes the opened device for the panel;
/// `opener` makes the devices the panel connects later; `restart` says how to start again on
/// a loaded clay whose patch layout differs from the running one.
///
/// # Errors
/// Whatever `start` returns.
pub fn start_bridge(
    endpoint: EngineEndpoint,
    device: DeviceInfo,
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
    } = endpoint;
    let (exports_tx, exports) = snapshot_channel(&MeshSet::new());
    let sink = GuiMeshSink::new(meshes, field, exports_tx, repaint);
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
    let engine = start(Box::new(sink))?;
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
        device,
        connected: true,
        opener,
        tool_radius: PushTool::default().radius_fu,
        compact_particles: None,
        saves: Vec::new(),
        loads: Vec::new(),
        pin_replies: Vec::new(),
        refine_replies: Vec::new(),
        edit_replies: Vec::new(),
        pins_seen: None,
        pins_list: None,
        pin_lines: Vec::new(),
        pin_marks: Vec::new(),
        points: points_tx,
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
    events: Sender<EngineEvent>,
    view: SnapshotWriter<EngineView>,
    /// The latest meshes, for exports (read wait-free).
    exports: SnapshotReader<MeshSet>,
    device: DeviceInfo,
    /// Whether a device is connected (false after the panel's disconnect).
    connected: bool,
    opener: DeviceOpener,
    tool_radius: f32,
    saves: Vec<Receiver<Result<std::path::PathBuf, crate::engine::SaveError>>>,
    loads: Vec<PendingLoad>,
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
}

/// Forwards each answer that arrived on `pending` as an event (`describe` turns a success
/// into its detail line) and forgets the channels that answered or hung up.
fn forward_replies<T, E: std::fmt::Display>(
    pending: &mut Vec<Receiver<Result<T, E>>>,
    events: &Sender<EngineEvent>,
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
        forward_replies(&mut self.saves, &self.events, "save", |p| {
            format!("wrote {}", p.display())
        });
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
        let engine = self.engine_mut();
        let tool = engine.latest_tool();
        let counters = engine.counters().snapshot();
        let loops = engine.loop_stats().map(|(_, stats)| stats);
        let force_limit_n = engine.force_limit().applied_n();
        let (restarts, new_clay) = (self.restarts, self.new_clay);
        let device = &self.device;
        let connected = self.connected;
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
            v.tool_position = tool.resting_at.unwrap_or(tool.tip);
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
        });
    }

    /// Serves the Load button: a session is read here, an importable file (point cloud, mesh,
    /// volume) is fitted here as `dynaclay import` fits it (its report and progress go to the
    /// log); the result is offered to the running simulation, and a refusal for its layout
    /// restarts the engine on it (see [`Bridge::poll_loads`]).
    fn load(&mut self, path: &Path) {
        if is_point_cloud(path) {
            return match self.import_points(path) {
                Ok((session, points)) => self.offer(session, path, true, points),
                Err(error) => self.fail("load", error),
            };
        }
        let session = if crate::fit::is_importable(path) {
            match self.import(path) {
                Ok(s) => s,
                Err(error) => return self.fail("load", error),
            }
        } else {
            match load_session(path) {
                Ok(s) => s,
                Err(e) => return self.fail("load", CommandError::Read(e).to_string()),
            }
        };
        self.offer(session, path, true, None);
    }

    /// Tells the log one line of a load in progress.
    fn say_load(&self, detail: String) {
        let _ = self.events.send(EngineEvent::Done {
            what: "load".into(),
            detail,
        });
    }

    /// Fits a point cloud as [`Bridge::import`] does and builds its point-set surface (Guo &
    /// Qin §3) in the clay's units, here on the bridge thread: the clay is the fit, and the
    /// points, with their normals (oriented over a spanning tree when the file has none),
    /// follow it. A cloud whose point set cannot be built still loads its clay (the log says
    /// why it has no points).
    fn import_points(&self, path: &Path) -> Result<(Session, Option<Box<FollowedPoints>>), String> {
        let say = |detail: String| self.say_load(detail);
        say(format!("importing {}", path.display()));
        let imported = import_cloud(
            path,
            &ImportSettings::default(),
            &mut fit_stage_reporter(&say),
            &mut |line| say(line),
        )
        .map_err(|e| format!("{}: {e}", path.display()))?;
        let cloud = imported.cloud_in_field_units();
        let points = match PointSet::build(&cloud, &PointSetOptions::default()) {
            Ok((mut set, times)) => {
                if let Some(colours) = imported.colours.as_ref().filter(|c| c.len() == set.len()) {
                    set.colours.clone_from(colours);
                }
                say(format!(
                    "point set: {} points, spacing {:.4}, built in {:.0} ms; shown as splats \
                     following the clay",
                    set.len(),
                    set.spacing_fu,
                    times.total_ns() as f64 / 1e6
                ));
                Some(Box::new(FollowedPoints::of_set(&set)))
            }
            Err(e) => {
                self.fail(
                    "load",
                    format!("{}: no point set ({e}); the clay loads", path.display()),
                );
                None
            }
        };
        let now = std::time::SystemTime::now()
            .duration_since(std::time::SystemTime::UNIX_EPOCH)
            .map_or(0, |d| d.as_secs());
        Ok((imported_session(imported.fit.field, path, now), points))
    }

    /// Fits `path` with `dynaclay import`'s defaults (a volume without `--iso` at its
    /// mid-range intensity), telling the log each stage and report line.
    fn import(&self, path: &Path) -> Result<Session, String> {
        let say = |detail: String| self.say_load(detail);
        say(format!("importing {}", path.display()));
        let settings = ImportSettings {
            midrange_iso: true,
            ..ImportSettings::default()
        };
        let session = import_session(
            path,
            &settings,
            &mut fit_stage_reporter(&say),
            &mut |line| say(line),
        );
        session.map_err(|e| match e {
            ImportError::NeedsDims => format!(
                "{}: a raw volume does not say its dimensions; run `dynaclay import {} --dims \
                 X,Y,Z --iso V --out SESSION.dclay` and load the session",
                path.display(),
                path.display()
            ),
            other => format!("{}: {other}", path.display()),
        })
    }

    /// Offers `session` to the running simulation; with `retry`, a refusal for its layout
    /// restarts the engine on it.
    fn offer(
        &mut self,
        session: Session,
        source: &Path,
        retry: bool,
        points: Option<Box<FollowedPoints>>,
    ) {
        let (tx, rx) = bounded(1);
        let kept = (retry && self.restart.is_some()).then(|| Box::new(session.clone()));
        let tools = session.tools.clone();
        let sent = self.engine().commands().send(Command::Load {
            session: Box::new(session),
            source: source.to_path_buf(),
            reply: Some(tx),
        });
        if sent.is_err() {
            return self.fail("load", CommandError::Stopped.to_string());
        }
        self.loads.push(PendingLoad {
            reply: rx,
            session: kept,
            source: source.to_path_buf(),
            points,
            tools,
        });
    }

    /// Forwards the simulation's answers to loads; a session refused because its patch
    /// layout differs from the running clay's starts a new engine on it.
    fn poll_loads(&mut self) {
        let mut restart = None;
        let events = &self.events;
        let points = &self.points;
        self.loads.retain_mut(|pending| {
            let answer = match pending.reply.try_recv() {
                Ok(answer) => answer,
                Err(crossbeam::channel::TryRecvError::Empty) => return true,
                Err(crossbeam::channel::TryRecvError::Disconnected) => Err(CommandError::Stopped),
            };
            let event = match answer {
                Ok(detail) => {
                    // The clay is in: its points (or none) follow it from now on. A full
                    // queue means the graphics loop stalled; it takes the newest when back.
                    let _ = points.try_send(pending.points.take());
                    let _ = events.send(EngineEvent::Library(std::mem::take(&mut pending.tools)));
                    EngineEvent::Done {
                        what: "load".into(),
                        detail,
                    }
                }
                Err(CommandError::Load(
                    LoadRefused::PatchLayout { .. } | LoadRefused::LatticeMismatch { .. },
                )) if pending.session.is_some() && restart.is_none() => {
                    restart = pending
                        .session
                        .take()
                        .map(|s| (s, pending.source.clone(), pending.points.take()));
                    return false;
                }
                Err(error) => EngineEvent::Failed {
                    what: "load".into(),
                    error: error.to_string(),
                },
            };
            let _ = events.send(event);
            false
        });
        if let Some((session, source, points)) = restart {
            self.restart_on(*session, &source, points);
        }
    }

    /// Stops the engine (its device closed, the replaced clay written to
    /// [`RestartSettings::keep_replaced_at`]) and starts a new one on `session`'s clay with
    /// the same device, force limit and haptic gain; the session's paint, pins and material
    /// are then installed by a load, as at launch.
    fn restart_on(&mut self, session: Session, source: &Path, points: Option<Box<FollowedPoints>>) {
        let what = "load";
        let Some(settings) = self.restart.clone() else {
            return self.fail(what, "the engine cannot restart here".into());
        };
        if !self.connected {
            return self.fail(
                what,
                format!(
                    "{}: its clay needs a new engine, which starts with the device: connect one \
                     first",
                    source.display()
                ),
            );
        }
        let density = session.clay.density.clone();
        if !density.patches[0].is_identity() {
            return self.fail(
                what,
                format!("{}: the session's base patch is mapped", source.display()),
            );
        }
        let old = settings.config;
        let mut config = EngineConfig::for_clay(&density, &self.device);
        config.haptic_rate_hz = old.haptic_rate_hz;
        config.sim_rate_hz = old.sim_rate_hz;
        config.graphics_rate_hz = old.graphics_rate_hz;
        config.haptic_rt_priority = old.haptic_rt_priority;
        config.stale_fresh = old.stale_fresh;
        config.stale_limit = old.stale_limit;
        config.safety = old.safety;
        config.sim.material = session.material.uniform;
        let Some(engine) = self.engine.take() else {
            return;
        };
        let force_limit_n = engine.force_limit().requested_n();
        let gain = engine.haptic_gain().get();
        let stopped = match engine.stop_keeping_parts() {
            Ok(s) => s,
            Err(e) => return self.fail(what, format!("stopping the engine: {e}")),
        };
        let kept = match save_session(&settings.keep_replaced_at, &stopped.report.session) {
            Ok(()) => format!(
                "the replaced clay, unsaved work included, is in {}",
                settings.keep_replaced_at.display()
            ),
            Err(e) => format!("the replaced clay could not be kept: {e}"),
        };
        let Some(device) = stopped.device else {
            return self.fail(what, "the device left with the old engine".into());
        };
        let autosave = settings
            .autosave
            .as_ref()
            .map(|p| Autosave::new(p, AutosavePolicy::default(), std::time::Instant::now()));
        let started = Engine::start_with(
            &config,
            density.clone(),
            device,
            stopped.sink,
            StartOptions {
                autosave,
                schedule: None,
            },
        );
        let engine = match started {
            Ok(engine) => engine,
            Err(e) => {
                return self.fail(
                    what,
                    format!(
                        "the engine could not start on {}: {e}; {kept}",
                        source.display()
                    ),
                );
            }
        };
        let _ = engine.force_limit().request(force_limit_n);
        let _ = engine.haptic_gain().set(gain);
        self.engine = Some(engine);
        self.restarts += 1;
        if let Some(n) = self.compact_particles {
            self.set_compact("compact RBF clay", Some(n));
        }
        let base = density.base();
        let top = base.node_position(base.dims[0] - 1, base.dims[1] - 1, base.dims[2] - 1);
        self.new_clay = Some((
            WorldBox {
                min: base.origin,
                max: top,
            },
            config.map,
        ));
        self.pins_seen = None;
        self.pins_list = None;
        self.pin_lines.clear();
        self.pin_marks.clear();
        let _ = self.events.send(EngineEvent::Done {
            what: what.into(),
            detail: format!(
                "{} has another clay layout ({}×{}×{} coefficients, {} patch(es)): restarted \
                 the engine on it with the same device; {kept}",
                source.display(),
                base.dims[0],
                base.dims[1],
                base.dims[2],
                density.patches.len()
            ),
        });
        self.offer(session, source, false, points);
    }

    /// Makes the device `spec` names and switches the running engine to it (the force limit
    /// asked for applies from its first tick); the old device is closed here.
    fn connect(&mut self, what: &str, spec: &DeviceSpec, max_force_n: f32) {
        if let Err(e) = self.engine().force_limit().request(max_force_n) {
            self.fail(what, e.to_string());
            return;
        }
        let device = match (self.opener)(spec) {
            Ok(d) => d,
            Err(e) => {
                self.fail(what, format!("{spec}: {e}"));
                return;
            }
        };
        match self.engine().replace_device(device, SWAP_TIMEOUT) {
            Ok(report) => {
                let Some(connected) = report.connected else {
                    self.fail(
                        what,
                        format!("{spec}: the engine parked instead of connecting"),
                    );
                    return;
                };
                self.connected = true;
                let mut detail = format!("{} connected", connected.name);
                if let Some(replaced) = &report.replaced {
                    detail = format!("{detail}; {}", closed_detail(&replaced.name, &report.close));
                }
                self.device = connected;
                let _ = self.events.send(EngineEvent::Done {
                    what: what.into(),
                    detail,
                });
            }
            Err(e) => self.fail(what, format!("{spec}: {e}")),
        }
    }

    /// Asks the engine for its pins when their revision moved, and takes the list in when
    /// the answer arrived.
    fn poll_pins(&mut self, revision: u64) {
        // One question at a time: a newer revision is asked about once the answer is in.
        if self.pins_seen != Some(revision) && self.pins_list.is_none() {
            let (tx, rx) = bounded(1);
            if self
                .engine()
                .commands()
                .send(Command::ListPins { reply: tx })
                .is_ok()
            {
                self.pins_seen = Some(revision);
                self.pins_list = Some(rx);
            }
        }
        let Some(pins) = self.pins_list.as_ref().and_then(|rx| rx.try_recv().ok()) else {
            return;
        };
        self.pins_list = None;
        self.pin_lines = pins
            .iter()
            .enumerate()
            .map(|(i, p)| crate::tools::describe_pin(i, p))
            .collect();
        self.pin_marks = pins
            .into_iter()
            .map(|p| match p {
                crate::dynamics::Constraint::Point { at }
                | crate::dynamics::Constraint::Normal { at, .. } => vec![at],
                crate::dynamics::Constraint::Curve { points } => points,
            })
            .collect();
    }

    fn fail(&self, what: &str, error: String) {
        let _ = self.events.send(EngineEvent::Failed {
            what: what.into(),
            error,
        });
    }

    fn send(&self, what: &str, cmd: Command) {
        if self.engine().commands().send(cmd).is_err() {
            self.fail(what, "the simulation loop has stopped".into());
        }
    }

    /// Starts a compact RBF worker of `particles` particles (on this thread, never a loop) and
    /// hands it to the engine, or switches the mode off.
    fn set_compact(&mut self, what: &str, particles: Option<usize>) {
        self.compact_particles = particles;
        let link = match particles.map(|n| CompactRbfLink::spawn(CompactSettings::new(n))) {
            None => None,
            Some(Ok(link)) => Some(Box::new(link)),
            Some(Err(e)) => {
                self.compact_particles = None;
                return self.fail(what, e.to_string());
            }
        };
        self.send(what, Command::SetCompactRbf(link));
    }

    fn apply(&mut self, cmd: EngineCommand) {
        let what = cmd.name();
        match cmd {
            EngineCommand::SelectTool(choice) => {
                // The view's brush keeps the last spread radius through a geometric tool.
                if let Some(r) = choice.spread_radius_fu() {
                    self.tool_radius = r;
                }
                self.send(what, Command::SetTool(choice));
            }
            EngineCommand::SetMaterial(m) => self.send(what, Command::SetMaterial(m)),
            EngineCommand::PaintMaterial(paint) => {
                self.send(what, Command::PaintMaterial { paint, reply: None });
            }
            EngineCommand::ClearMaterialPaint => self.send(what, Command::ClearMaterialPaint),
            EngineCommand::StrokeStart => self.send(what, Command::StrokeStart),
            EngineCommand::StrokeStop => self.send(what, Command::StrokeStop),
            EngineCommand::SetSymmetry(s) => self.send(what, Command::SetSymmetry(s)),
            EngineCommand::SetCompactRbf { particles } => self.set_compact(what, particles),
            EngineCommand::Undo => self.send(what, Command::Undo),
            EngineCommand::Redo => self.send(what, Command::Redo),
            EngineCommand::Pin(request) => {
                let (tx, rx) = bounded(1);
                self.pin_replies.push(rx);
                self.send(
                    what,
                    Command::Constrain {
                        request,
                        reply: Some(tx),
                    },
                );
            }
            EngineCommand::Refine { lo, hi, level } => {
                let (tx, rx) = bounded(1);
                self.refine_replies.push(rx);
                self.send(
                    what,
                    Command::Refine {
                        lo,
                        hi,
                        level,
                        reply: Some(tx),
                    },
                );
            }
            EngineCommand::Unpin { index } => {
                let (tx, rx) = bounded(1);
                self.pin_replies.push(rx);
                self.send(
                    what,
                    Command::Unconstrain {
                        index,
                        reply: Some(tx),
                    },
                );
            }
            EngineCommand::Save { path } => {
                let (tx, rx) = bounded(1);
                self.saves.push(rx);
                self.send(
                    what,
                    Command::Save {
                        path,
                        reply: Some(tx),
                    },
                );
            }
            EngineCommand::Export { path } => {
                let set = self.exports.latest().value.clone();
                let ev = match export_chunks(&set, &path) {
                    Ok(n) => EngineEvent::Done {
                        what: what.into(),
                        detail: format!("wrote {} ({n} triangles)", path.display()),
                    },
                    Err(error) => EngineEvent::Failed {
                        what: what.into(),
                        error: error.to_string(),
                    },
                };
                let _ = self.events.send(ev);
            }
            EngineCommand::Load { path } => self.load(&path),
            EngineCommand::AnswerRemoval { yes } => {
                self.send(what, Command::AnswerRemoval(yes));
            }
            edit @ (EngineCommand::AddTool(_)
            | EngineCommand::Csg { .. }
            | EngineCommand::Emboss { .. }) => match super::edit_requests::edit_command(edit) {
                Some(Ok((cmd, pending))) => {
                    self.edit_replies.push((what, pending));
                    self.send(what, cmd);
                }
                Some(Err(error)) => self.fail(what, error),
                None => {}
            },
            EngineCommand::SetMaxForce { max_force_n } => {
                match self.engine().force_limit().request(max_force_n) {
                    Ok(()) => {
                        let device_max = self.device.max_force_n;
                        let detail = if max_force_n > device_max {
                            format!(
                                "{max_force_n:.2} N asked; the device's own maximum {device_max:.2} N applies"
                            )
                        } else {
                            format!("{max_force_n:.2} N")
                        };
                        let _ = self.events.send(EngineEvent::Done {
                            what: what.into(),
                            detail,
                        });
                    }
                    Err(error) => self.fail(what, error.to_string()),
                }
            }
            EngineCommand::SetHapticGain { gain } => match self.engine().haptic_gain().set(gain) {
                Ok(()) => {
                    let _ = self.events.send(EngineEvent::Done {
                        what: what.into(),
                        detail: format!("{gain:.2}"),
                    });
                }
                Err(error) => self.fail(what, error.to_string()),
            },
            EngineCommand::ConnectDevice { spec, max_force_n } => {
                self.connect(what, &spec, max_force_n);
            }
            EngineCommand::DisconnectDevice => {
                match self.engine().disconnect_device(SWAP_TIMEOUT) {
                    Ok(report) => {
                        // The panel keeps the last device's description, shown as disconnected.
                        self.connected = false;
                        let detail = match &report.replaced {
                            Some(replaced) => closed_detail(&replaced.name, &report.close),
                            None => "no device was connected".into(),
                        };
                        let _ = self.events.send(EngineEvent::Done {
                            what: what.into(),
                            detail,
                        });
                    }
                    Err(e) => self.fail(what, e.to_string()),
                }
            }
        }
    }
}

/// A fit's progress callback that tells `say` each stage: signing, the base lattice, and each
/// depth of detail patches once. It never cancels the fit.
fn fit_stage_reporter(say: &impl Fn(String)) -> impl FnMut(FitProgress) -> bool + '_ {
    let mut last_depth = None;
    move |stage| {
        match stage {
            FitProgress::Signing => say("signing the points".into()),
            FitProgress::Base => say("fitting the base lattice".into()),
            FitProgress::Detail { depth, of, .. } => {
                if last_depth != Some(depth) {
                    last_depth = Some(depth);
                    say(format!("depth {depth}: fitting {of} detail patches"));
                }
            }
        }
        true
    }
}

/// "NAME closed", or the close error with it.
fn closed_detail(name: &str, close: &Result<(), dynaclay_devices::DeviceError>) -> String {
    match close {
        Ok(()) => format!("{name} closed"),
        Err(e) => format!("{name} closed with an error: {e}"),
    }
}

/// Why [`export_chunks`] wrote nothing.
#[derive(Debug, thiserror::Error)]
pub enum ChunkExportError {
    /// The path's extension names no mesh format.
    #[error("{}: unknown mesh format (use .obj, .ply or .stl)", path.display())]
    UnknownFormat {
        /// The path asked for.
        path: PathBuf,
    },
    /// A chunk is not a consistent brick mesh (attributes, indices or edge ids).
    #[error("{}: {source}", path.display())]
    Chunk {
        /// The path asked for.
        path: PathBuf,
        /// What is wrong with the chunk.
        source: ChunkError,
    },
    /// Writing the file failed (the error names the path).
    #[error(transparent)]
    Write(#[from] ExportError),
}

/// Welds the chunks with the mesher's own welding ([`weld_pieces`]: vertices on shared brick
/// faces are merged by edge id) and writes them in the format named by `path`'s extension;
/// returns the triangle count. Chunks are welded in id order, so the same set always writes
/// the same file.
///
/// # Errors
/// An unknown extension, an inconsistent chunk or the writer's error, naming the path.
pub fn export_chunks(set: &MeshSet, path: &Path) -> Result<usize, ChunkExportError> {
    let format = MeshFormat::from_path(path).ok_or_else(|| ChunkExportError::UnknownFormat {
        path: path.to_path_buf(),
    })?;
    let mut chunks: Vec<&ChunkMesh> = set.iter().map(|c| &**c).collect();
    chunks.sort_by_key(|c| c.id);
    let bad = |source| ChunkExportError::Chunk {
        path: path.to_path_buf(),
        source,
    };
    for c in &chunks {
        c.as_chunk().validate().map_err(bad)?;
        if c.edge_ids.len() != c.positions.len() {
            return Err(bad(ChunkError::AttributeLength {
                id: c.id,
                attribute: "edge_ids",
                expected: c.positions.len(),
                got: c.edge_ids.len(),
            }));
        }
    }
    let pieces: Vec<WeldPiece<'_, [f32; 3]>> = chunks
        .iter()
        .map(|c| WeldPiece {
            positions: &c.positions,
            normals: &c.normals,
            edge_ids: &c.edge_ids,
            indices: &c.indices,
        })
        .collect();
    let mesh = weld_pieces(&pieces);
    write_mesh(path, &mesh, format)?;
    Ok(mesh.triangles.len())
}

#[cfg(test)]
mod tests {
    use std::time::Instant;

    use dynaclay_devices::{DeviceError, SimArmConfig, SimulatedArm, Trajectory};

    use super::*;
    use crate::dynamics::Material;
    use crate::engine::{EngineConfig, build_clay};
    use crate::field::BSplineLattice;
    use crate::io::{ClayShape, ClaySpec, MaterialFields, Session, save_session};
    use crate::mesh::{MeshStats, SampleGrid};
    use crate::tools::Clay;

    /// Polls `link` until `done` holds for its view (or panics after a few seconds), taking
    /// in the events on the way.
    fn wait_for(
        link: &mut super::super::EngineLink,
        events: &mut Vec<EngineEvent>,
        what: &str,
        done: impl Fn(&EngineView, &[EngineEvent]) -> bool,
    ) {
        let start = Instant::now();
        loop {
            while let Some(ev) = link.try_event() {
                events.push(ev);
            }
            if done(&link.view().value, events) {
                return;
            }
            assert!(
                start.elapsed() < Duration::from_secs(60),
                "timed out waiting for {what}; events {events:?}"
            );
            std::thread::sleep(Duration::from_millis(5));
        }
    }

    fn triangles(link: &mut super::super::EngineLink) -> usize {
        link.meshes()
            .value
            .iter()
            .map(|c| c.indices.len() / 3)
            .sum()
    }

    /// The compact RBF switch through the bridge reaches the running engine: its worker
    /// interpolates the clay (one undo step, 3N centres shown in the view); switched off,
    /// the view says so.
    #[test]
    fn the_compact_rbf_switch_reaches_the_engine_and_its_worker() {
        let field = build_clay(&ClaySpec {
            shape: ClayShape::Sphere,
            resolution: 14,
            ..ClaySpec::default()
        })
        .unwrap();
        let (mut link, bridge) = bridge_on(&field);
        let mut events = Vec::new();
        wait_for(&mut link, &mut events, "the first status", |_, _| true);
        link.send(EngineCommand::SetCompactRbf {
            particles: Some(60),
        })
        .unwrap();
        wait_for(&mut link, &mut events, "the first interpolation", |v, _| {
            v.compact.applied >= 1
        });
        let v = link.view().value.clone();
        assert!(v.compact.on);
        assert_eq!(v.compact.particles, 60);
        assert_eq!(v.compact.centres, Some(180));
        assert_eq!(v.compact.failed, 0);
        assert!(v.compact.last_s > 0.0);
        wait_for(&mut link, &mut events, "its undo step", |v, _| {
            v.undo_steps == 1
        });

        link.send(EngineCommand::SetCompactRbf { particles: None })
            .unwrap();
        wait_for(&mut link, &mut events, "the switch off", |v, _| {
            !v.compact.on
        });
        assert!(
            !events
                .iter()
                .any(|e| matches!(e, EngineEvent::Failed { .. })),
            "{events:?}"
        );
        bridge.stop().unwrap();
    }

    /// Particles through the running engine: off, none are published; switched on over a
    /// still clay, the graphics loop's idle updates seed and settle them on the surface; a new
    /// `N` is reached; switched off, they are dropped.
    #[test]
    fn particles_switched_on_settle_on_a_still_clay_and_go_when_switched_off() {
        let field = build_clay(&ClaySpec {
            shape: ClayShape::Sphere,
            resolution: 14,
            ..ClaySpec::default()
        })
        .unwrap();
        let (mut link, bridge) = bridge_on(&field);
        let wait_particles =
            |link: &mut super::super::EngineLink, what: &str, done: &dyn Fn(usize) -> bool| {
                let start = Instant::now();
                loop {
                    let n = link.particles().value.positions.len();
                    if done(n) {
                        return;
                    }
                    assert!(
                        start.elapsed() < Duration::from_secs(60),
                        "timed out waiting for {what}: {n} particles"
                    );
                    std::thread::sleep(Duration::from_millis(5));
                }
            };
        wait_for(&mut link, &mut Vec::new(), "the first meshes", |_, _| true);
        assert!(
            link.particles().value.positions.is_empty(),
            "off by default"
        );

        link.set_particle_count(300);
        link.set_particles_on(true);
        wait_particles(&mut link, "300 particles", &|n| n.abs_diff(300) <= 6);
        let view = link.particles().value.clone();
        assert_eq!(view.normals.len(), view.positions.len());
        assert_eq!(view.radii.len(), view.positions.len());
        for p in &view.positions {
            let (value, gradient) = crate::particles::ImplicitSurface::eval(&field, *p);
            let distance = value.abs() / gradient.length();
            assert!(
                distance < 0.1 * field.spacing,
                "{p}: {distance} off the surface"
            );
        }
        assert!(view.radii.iter().all(|r| *r > 0.0 && r.is_finite()));

        link.set_particle_count(150);
        wait_particles(&mut link, "150 particles", &|n| n.abs_diff(150) <= 4);

        link.set_particles_on(false);
        wait_particles(&mut link, "no particles", &|n| n == 0);
        bridge.stop().unwrap();
    }

    /// Pins through the running engine: a pin's answer comes back as an event and the list
    /// reaches the view; undo and "remove all" empty it again.
    #[test]
    fn pins_made_through_the_bridge_are_listed_and_follow_undo_and_removal() {
        let field = build_clay(&ClaySpec {
            shape: ClayShape::Sphere,
            resolution: 14,
            ..ClaySpec::default()
        })
        .unwrap();
        let centre = crate::engine::clay_centre(&field);
        let on = crate::dynamics::surface_point_on_ray(&field, centre, Vec3::X, 2.0, 0.01)
            .expect("the sphere has a surface along +x");
        let (mut link, bridge) = bridge_on(&field);
        let mut events = Vec::new();
        link.send(EngineCommand::Pin(crate::tools::PinRequest::Point(on)))
            .unwrap();
        wait_for(&mut link, &mut events, "the pin", |v, ev| {
            v.pins.len() == 1 && !ev.is_empty()
        });
        assert!(
            matches!(&events[..], [EngineEvent::Done { what, detail }] if what == "pins" && detail.contains("pinned a point")),
            "{events:?}"
        );
        assert!(link.view().value.pins[0].starts_with("0: point at"));
        link.send(EngineCommand::Undo).unwrap();
        wait_for(&mut link, &mut events, "the undo", |v, _| v.pins.is_empty());
        let curve = vec![on, on + Vec3::Y * 0.05, on + Vec3::Y * 0.1];
        link.send(EngineCommand::Pin(crate::tools::PinRequest::Curve(curve)))
            .unwrap();
        link.send(EngineCommand::Pin(crate::tools::PinRequest::Normal(on)))
            .unwrap();
        // The curve, then the normal and its point.
        wait_for(&mut link, &mut events, "two pins", |v, _| v.pins.len() == 3);
        link.send(EngineCommand::Unpin { index: None }).unwrap();
        wait_for(&mut link, &mut events, "the removal", |v, _| {
            v.pins.is_empty()
        });
        bridge.stop().unwrap();
    }

    /// The running engine behind the bridge: loading a session replaces the field in every
    /// loop and the meshes; a corrupt file is refused with its reason and changes nothing;
    /// the force limit reaches the safety filter (capped at the device's own maximum); the
    /// latency figures of all three loops reach the view.
    #[test]
    fn the_bridge_loads_sessions_sets_the_force_limit_and_publishes_loop_figures() {
        let field = build_clay(&ClaySpec {
            shape: ClayShape::Sphere,
            resolution: 14,
            ..ClaySpec::default()
        })
        .unwrap();
        let arm = SimArmConfig::default();
        let info = arm.info.clone();
        let device_max_n = info.max_force_n;
        let mut config = EngineConfig::for_field(&field, &info);
        config.haptic_rt_priority = None;
        // The tool waits at a workspace corner, away from the clay.
        let device: Box<dyn HapticDevice> =
            Box::new(SimulatedArm::new(arm, Trajectory::hold(Vec3::splat(-0.09))));

        // A session on the same lattice with the top half carved away, and a corrupt copy.
        let mut carved: BSplineLattice = field.clone();
        let d = carved.dims;
        for k in d[2] / 2..d[2] {
            for j in 0..d[1] {
                for i in 0..d[0] {
                    let idx = carved.index(i, j, k);
                    carved.coeffs[idx] = 0.0;
                }
            }
        }
        let dir = tempfile::tempdir().unwrap();
        let good = dir.path().join("carved.dclay");
        let session = Session {
            clay: Clay::single(carved.clone()),
            material: MaterialFields {
                uniform: Material::ELASTIC,
                grids: Vec::new(),
            },
            ..Session::default()
        };
        save_session(&good, &session).unwrap();
        let corrupt = dir.path().join("corrupt.dclay");
        let mut bytes = std::fs::read(&good).unwrap();
        let mid = bytes.len() / 2;
        bytes[mid] ^= 0x5a;
        std::fs::write(&corrupt, &bytes).unwrap();

        let (mut link, endpoint) = super::super::engine_link();
        let bridge = start_bridge(endpoint, info, no_devices(), None, |sink| {
            Engine::start(&config, field.clone(), device, sink)
        })
        .unwrap();
        let mut events = Vec::new();
        wait_for(&mut link, &mut events, "first meshes", |v, _| {
            v.device.state == DeviceLinkState::Connected
        });
        let start = Instant::now();
        while triangles(&mut link) == 0 && start.elapsed() < Duration::from_secs(60) {
            std::thread::sleep(Duration::from_millis(5));
        }
        let whole_triangles = triangles(&mut link);
        assert!(whole_triangles > 0);
        assert_eq!(link.view().value.device.max_force_n, device_max_n);

        link.send(EngineCommand::Load { path: good.clone() })
            .unwrap();
        wait_for(&mut link, &mut events, "the load", |v, ev| {
            v.sessions_loaded == 1 && ev.iter().any(|e| matches!(e, EngineEvent::Done { .. }))
        });
        // (a loaded session's tool library comes as its own event)
        events.retain(|e| !matches!(e, EngineEvent::Library(_)));
        assert!(
            matches!(&events[..], [EngineEvent::Done { what, detail }] if what == "load" && detail.contains("carved.dclay")),
            "{events:?}"
        );
        assert_eq!(link.view().value.material, Material::ELASTIC);
        let start = Instant::now();
        while triangles(&mut link) >= whole_triangles && start.elapsed() < Duration::from_secs(60) {
            std::thread::sleep(Duration::from_millis(5));
        }
        let carved_triangles = triangles(&mut link);
        assert!(
            carved_triangles < whole_triangles,
            "meshes follow the load: {whole_triangles} -> {carved_triangles} triangles"
        );

        events.clear();
        link.send(EngineCommand::Load {
            path: corrupt.clone(),
        })
        .unwrap();
        wait_for(&mut link, &mut events, "the refusal", |_, ev| {
            !ev.is_empty()
        });
        let [EngineEvent::Failed { what, error }] = &events[..] else {
            panic!("expected one failure, got {events:?}");
        };
        assert_eq!(what, "load");
        assert!(error.contains("corrupt.dclay"), "{error}");

        link.send(EngineCommand::SetMaxForce { max_force_n: 0.5 })
            .unwrap();
        wait_for(&mut link, &mut events, "the force limit", |v, _| {
            v.device.max_force_n == 0.5
        });
        link.send(EngineCommand::SetMaxForce { max_force_n: 100.0 })
            .unwrap();
        wait_for(&mut link, &mut events, "the device's own limit", |v, _| {
            v.device.max_force_n == device_max_n
        });
        assert!(
            events.iter().any(
                |e| matches!(e, EngineEvent::Done { detail, .. } if detail.contains("maximum"))
            ),
            "{events:?}"
        );

        // Export writes the meshes the graphics loop handed over (read wait-free).
        let exported = dir.path().join("carved.obj");
        link.send(EngineCommand::Export {
            path: exported.clone(),
        })
        .unwrap();
        wait_for(&mut link, &mut events, "the export", |_, ev| {
            ev.iter().any(|e| {
                matches!(e, EngineEvent::Done { what, detail } if what == "export" && detail.contains("triangles"))
            })
        });
        let obj = std::fs::read_to_string(&exported).unwrap();
        assert!(obj.lines().filter(|l| l.starts_with("f ")).count() > 100);

        // The loops publish figures about once a second.
        wait_for(&mut link, &mut events, "loop figures", |v, _| {
            v.loops
                .iter()
                .all(|s| s.ticks > 0 && s.achieved_rate_hz > 0.0)
        });
        let loops = link.view().value.loops;
        assert!((loops[0].nominal_rate_hz - 1000.0).abs() < 0.1);
        assert!(
            (loops[2].nominal_rate_hz - 60.0).abs() < 0.1,
            "{}",
            loops[2].nominal_rate_hz
        );
        assert!(loops[0].compute.p99_us > 0.0);

        let report = bridge.stop().unwrap();
        assert_eq!(
            report.session.clay.density.patches[0].lattice, carved,
            "the corrupt file changed nothing"
        );
        assert_eq!(report.haptic_field.base(), &carved);
        assert_eq!(report.session.material.uniform, Material::ELASTIC);
        assert_eq!(report.safety.clamped, 0, "the tool never touched the clay");
    }

    /// Loads that need another engine: a session on another lattice restarts the engine on
    /// it (the replaced clay kept on disk, the view reporting the new clay's box), an
    /// imported point cloud is fitted on the bridge thread and restarts it again, and bad
    /// files are refused with their name, leaving the running clay as it was.
    #[test]
    fn loads_of_another_layout_restart_the_engine_and_imports_are_fitted() {
        let field = build_clay(&ClaySpec {
            shape: ClayShape::Sphere,
            resolution: 14,
            ..ClaySpec::default()
        })
        .unwrap();
        let arm = SimArmConfig::default();
        let info = arm.info.clone();
        let mut config = EngineConfig::for_field(&field, &info);
        config.haptic_rt_priority = None;
        let device: Box<dyn HapticDevice> =
            Box::new(SimulatedArm::new(arm, Trajectory::hold(Vec3::splat(-0.09))));
        let dir = tempfile::tempdir().unwrap();
        let small = build_clay(&ClaySpec {
            shape: ClayShape::Sphere,
            resolution: 10,
            ..ClaySpec::default()
        })
        .unwrap();
        let other = dir.path().join("small.dclay");
        save_session(
            &other,
            &Session {
                clay: Clay::single(small.clone()),
                material: MaterialFields {
                    uniform: Material::ELASTIC,
                    grids: Vec::new(),
                },
                ..Session::default()
            },
        )
        .unwrap();
        let kept = dir.path().join("sculpt.replaced.dclay");
        let restart = RestartSettings {
            config,
            autosave: None,
            keep_replaced_at: kept.clone(),
        };
        let (mut link, endpoint) = super::super::engine_link();
        let bridge = start_bridge(endpoint, info, no_devices(), Some(restart), |sink| {
            Engine::start(&config, field.clone(), device, sink)
        })
        .unwrap();
        let mut events = Vec::new();
        wait_for(&mut link, &mut events, "the first view", |v, _| {
            v.device.state == DeviceLinkState::Connected
        });

        link.send(EngineCommand::Load {
            path: other.clone(),
        })
        .unwrap();
        wait_for(&mut link, &mut events, "the restart", |v, _| {
            v.restarts == 1 && v.sessions_loaded == 1
        });
        assert!(
            events.iter().any(|e| matches!(e, EngineEvent::Done { what, detail }
                if what == "load" && detail.contains("restarted the engine") && detail.contains("sculpt.replaced.dclay"))),
            "{events:?}"
        );
        let view = link.view().value.clone();
        let top = small.node_position(small.dims[0] - 1, small.dims[1] - 1, small.dims[2] - 1);
        assert_eq!(
            view.clay_box,
            Some(WorldBox {
                min: small.origin,
                max: top
            })
        );
        assert_eq!(view.material, Material::ELASTIC, "the session's material");
        assert!(view.workspace_map.is_some());
        let replaced = crate::io::load_session(&kept).unwrap();
        assert_eq!(
            replaced.clay.density.base(),
            &field,
            "the replaced clay is kept"
        );
        let start = Instant::now();
        while triangles(&mut link) == 0 && start.elapsed() < Duration::from_secs(60) {
            std::thread::sleep(Duration::from_millis(5));
        }
        assert!(triangles(&mut link) > 0, "the new clay is meshed");

        // Bad files: named in the log, the clay unchanged.
        events.clear();
        let bad = dir.path().join("bad.ply");
        std::fs::write(
            &bad,
            "ply\nformat ascii 1.0\nelement vertex 3\nend_header\n1 2\n",
        )
        .unwrap();
        link.send(EngineCommand::Load { path: bad }).unwrap();
        link.send(EngineCommand::Load {
            path: dir.path().join("missing.xyz"),
        })
        .unwrap();
        wait_for(&mut link, &mut events, "two refusals", |_, ev| {
            ev.iter()
                .filter(|e| matches!(e, EngineEvent::Failed { .. }))
                .count()
                == 2
        });
        let failures: Vec<&String> = events
            .iter()
            .filter_map(|e| match e {
                EngineEvent::Failed { error, .. } => Some(error),
                EngineEvent::Done { .. } | EngineEvent::Library(_) => None,
            })
            .collect();
        assert!(failures[0].contains("bad.ply"), "{failures:?}");
        assert!(failures[1].contains("missing.xyz"), "{failures:?}");
        assert_eq!(link.view().value.restarts, 1, "nothing restarted");

        // A point cloud is fitted on the bridge thread, with its report in the log.
        events.clear();
        let cloud = dir.path().join("ball.xyz");
        let mut text = String::new();
        let n = 400;
        let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
        for i in 0..n {
            let y = 1.0 - 2.0 * (i as f32 + 0.5) / n as f32;
            let r = (1.0 - y * y).sqrt();
            let t = golden * i as f32;
            let (x, z) = (r * t.cos(), r * t.sin());
            text.push_str(&format!("{x} {y} {z} {x} {y} {z}\n"));
        }
        std::fs::write(&cloud, text).unwrap();
        link.send(EngineCommand::Load { path: cloud }).unwrap();
        let start = Instant::now();
        loop {
            while let Some(ev) = link.try_event() {
                events.push(ev);
            }
            if link.view().value.restarts == 2 && link.view().value.sessions_loaded == 1 {
                break;
            }
            // A generous bound only against a hang; nothing is timed.
            assert!(start.elapsed() < Duration::from_secs(120), "{events:?}");
            std::thread::sleep(Duration::from_millis(5));
        }
        assert!(
            events.iter().any(|e| matches!(e, EngineEvent::Done { detail, .. } if detail.contains("400 points with normals"))),
            "{events:?}"
        );
        assert!(
            events.iter().any(|e| matches!(e, EngineEvent::Done { detail, .. } if detail.contains("fitting the base lattice"))),
            "{events:?}"
        );
        let report = bridge.stop().unwrap();
        assert_eq!(report.session.clay.density.base().dims, [32, 32, 32]);
        assert_eq!(report.session.meta.name, "ball");
    }

    /// An opener that makes nothing (for tests that never use the device panel).
    /// A bridge over a running engine on `field`, the simulated arm waiting at a workspace
    /// corner, away from the clay; no real-time priority.
    fn bridge_on(field: &BSplineLattice) -> (super::super::EngineLink, EngineBridge) {
        let arm = SimArmConfig::default();
        let info = arm.info.clone();
        let mut config = EngineConfig::for_field(field, &info);
        config.haptic_rt_priority = None;
        let device: Box<dyn HapticDevice> =
            Box::new(SimulatedArm::new(arm, Trajectory::hold(Vec3::splat(-0.09))));
        let (link, endpoint) = super::super::engine_link();
        let bridge = start_bridge(endpoint, info, no_devices(), None, |sink| {
            Engine::start(&config, field.clone(), device, sink)
        })
        .unwrap();
        (link, bridge)
    }

    fn no_devices() -> DeviceOpener {
        Box::new(|spec: &DeviceSpec| {
            Err(DeviceError::NotFound {
                what: format!("{spec} in this test"),
            }
            .into())
        })
    }

    /// The device panel's commands reach the running engine: connect switches to a new
    /// device (the old one closed, the asked force limit applied), a device that cannot be
    /// made is refused and leaves the current one, disconnect parks the haptic loop and a
    /// later connect brings a device back; the engine runs throughout.
    #[test]
    fn the_panel_switches_disconnects_and_reconnects_devices() {
        let field = build_clay(&ClaySpec {
            shape: ClayShape::Sphere,
            resolution: 12,
            ..ClaySpec::default()
        })
        .unwrap();
        let mut first = SimArmConfig::default();
        first.info.name = "arm 1".into();
        let info = first.info.clone();
        let mut config = EngineConfig::for_field(&field, &info);
        config.haptic_rt_priority = None;
        let device: Box<dyn HapticDevice> = Box::new(SimulatedArm::new(
            first,
            Trajectory::hold(Vec3::splat(-0.09)),
        ));
        // Simulated arms, numbered from 2; any other spec cannot be made here.
        let mut made = 1;
        let opener: DeviceOpener = Box::new(move |spec: &DeviceSpec| match spec {
            DeviceSpec::Sim => {
                made += 1;
                let mut arm = SimArmConfig::default();
                arm.info.name = format!("arm {made}");
                let held = Trajectory::hold(Vec3::splat(0.09));
                Ok(Box::new(SimulatedArm::new(arm, held)) as Box<dyn HapticDevice>)
            }
            other => Err(DeviceError::NotFound {
                what: format!("{other}: no such port"),
            }
            .into()),
        });
        let (mut link, endpoint) = super::super::engine_link();
        let bridge = start_bridge(endpoint, info, opener, None, |sink| {
            Engine::start(&config, field.clone(), device, sink)
        })
        .unwrap();
        let mut events = Vec::new();
        wait_for(&mut link, &mut events, "the first arm", |v, _| {
            v.device.state == DeviceLinkState::Connected && v.device.name == "arm 1"
        });

        link.send(EngineCommand::ConnectDevice {
            spec: DeviceSpec::Sim,
            max_force_n: 1.5,
        })
        .unwrap();
        wait_for(&mut link, &mut events, "the switch", |v, ev| {
            v.device.name == "arm 2" && !ev.is_empty()
        });
        assert!(
            matches!(&events[..], [EngineEvent::Done { detail, .. }] if detail == "arm 2 connected; arm 1 closed"),
            "{events:?}"
        );
        wait_for(&mut link, &mut events, "the asked limit", |v, _| {
            v.device.max_force_n == 1.5 && v.device.state == DeviceLinkState::Connected
        });

        events.clear();
        let falcon = DeviceSpec::Falcon {
            path: "/dev/ttyUSB9".into(),
        };
        link.send(EngineCommand::ConnectDevice {
            spec: falcon,
            max_force_n: 1.5,
        })
        .unwrap();
        wait_for(&mut link, &mut events, "the refusal", |_, ev| {
            !ev.is_empty()
        });
        assert!(
            matches!(&events[..], [EngineEvent::Failed { error, .. }] if error.contains("no such port")),
            "{events:?}"
        );
        assert_eq!(link.view().value.device.name, "arm 2", "still connected");

        events.clear();
        link.send(EngineCommand::DisconnectDevice).unwrap();
        wait_for(&mut link, &mut events, "the disconnect", |v, ev| {
            v.device.state == DeviceLinkState::Disconnected && !ev.is_empty()
        });
        assert!(
            matches!(&events[..], [EngineEvent::Done { detail, .. }] if detail == "arm 2 closed"),
            "{events:?}"
        );
        let ticks = link.view().value.loops[0].ticks;

        events.clear();
        link.send(EngineCommand::ConnectDevice {
            spec: DeviceSpec::Sim,
            max_force_n: 1.0,
        })
        .unwrap();
        wait_for(&mut link, &mut events, "the reconnect", |v, ev| {
            v.device.name == "arm 3"
                && v.device.state == DeviceLinkState::Connected
                && !ev.is_empty()
        });
        assert!(
            matches!(&events[..], [EngineEvent::Done { detail, .. }] if detail == "arm 3 connected"),
            "{events:?}"
        );
        wait_for(
            &mut link,
            &mut events,
            "the haptic loop's figures",
            |v, _| v.loops[0].ticks > ticks,
        );
        let report = bridge.stop().unwrap();
        assert_eq!(report.counters.device_swaps, 3);
        assert_eq!(report.counters.device_read_faults, 0);
    }

    /// A 16³ sphere clay meshed in full by the octree.
    fn meshed_sphere() -> (BSplineLattice, BrickOctree, RefreshReport) {
        let lattice = build_clay(&ClaySpec {
            shape: ClayShape::Sphere,
            resolution: 16,
            ..ClaySpec::default()
        })
        .unwrap();
        let grid = SampleGrid::for_lattice(&lattice, 2).unwrap();
        let mut octree = BrickOctree::new(grid);
        let report = octree.rebuild(&lattice);
        (lattice, octree, report)
    }

    /// A sphere through the real octree mesher, published by the sink and exported welded.
    #[test]
    fn sink_publishes_bricks_and_export_welds_them_closed() {
        let (_, octree, report) = meshed_sphere();

        let (mut link, end) = super::super::link::engine_link();
        let (exports, _exported) = snapshot_channel(&MeshSet::new());
        let mut sink = GuiMeshSink::new(end.meshes, end.field, exports, end.repaint);
        sink.update(&octree, &report);
        let published = link.meshes().value.clone();
        assert!(published.len() > 1, "sphere spans several bricks");
        let tris: usize = published.iter().map(|c| c.indices.len() / 3).sum();
        assert_eq!(tris, octree.triangle_count());

        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("sphere.obj");
        let n = export_chunks(&published, &path).unwrap();
        assert!(n > 100);
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.lines().filter(|l| l.starts_with("f ")).count() == n);
        let welded = octree.weld();
        assert!(MeshStats::of(&welded).is_closed_manifold());
        // One welding: the export is the octree's weld, vertex for vertex.
        assert_eq!(n, welded.triangle_count());
        let vertices = text.lines().filter(|l| l.starts_with("v ")).count();
        assert_eq!(vertices, welded.positions.len());
        assert!(matches!(
            export_chunks(&published, &dir.path().join("x.abc")),
            Err(ChunkExportError::UnknownFormat { .. })
        ));
        let mut broken = (*published[0]).clone();
        broken.edge_ids.pop();
        let broken: MeshSet = vec![Arc::new(broken)];
        assert!(matches!(
            export_chunks(&broken, &path),
            Err(ChunkExportError::Chunk { .. })
        ));
    }

    /// Paint reaches the chunks: painting the low-x half red recolours (and re-versions)
    /// exactly the bricks it covers; clearing the paint takes the colour off again.
    #[test]
    fn sink_recolours_the_bricks_paint_covers() {
        let (lattice, octree, report) = meshed_sphere();
        let (mut link, end) = super::super::link::engine_link();
        let mut sink = GuiMeshSink::new(
            end.meshes,
            end.field,
            snapshot_channel(&MeshSet::new()).0,
            end.repaint,
        );
        sink.update(&octree, &report);
        let before = link.meshes().value.clone();
        assert!(before.iter().all(|c| c.colors.is_empty()), "unpainted");

        let mut colour = ColourField::matching(&lattice).unwrap();
        let d = lattice.dims;
        for k in 0..d[2] {
            for j in 0..d[1] {
                for i in 0..d[0] / 3 {
                    let idx = lattice.index(i, j, k);
                    colour.channels[0].coeffs[idx] = 1.0;
                    colour.channels[3].coeffs[idx] = 1.0;
                }
            }
        }
        sink.paint(&octree, Some(&colour));
        let painted = link.meshes().value.clone();
        assert_eq!(painted.len(), before.len(), "the same bricks");
        let by_id = |set: &MeshSet, id: u64| set.iter().find(|c| c.id == id).cloned().unwrap();
        let (mut recoloured, mut kept, mut red) = (0, 0, 0);
        for chunk in &painted {
            let old = by_id(&before, chunk.id);
            if chunk.colors.is_empty() {
                assert!(
                    Arc::ptr_eq(chunk, &old),
                    "an unpainted brick keeps its chunk"
                );
                kept += 1;
            } else {
                assert_ne!(
                    chunk.version, old.version,
                    "a repainted brick is re-uploaded"
                );
                assert!(
                    chunk.colors.iter().any(|c| c[3] > 0.0),
                    "brick {} carries paint",
                    chunk.id
                );
                red += chunk
                    .colors
                    .iter()
                    .filter(|c| c[0] > 0.9 && c[3] > 0.9)
                    .count();
                recoloured += 1;
            }
        }
        assert!(
            recoloured > 0 && kept > 0,
            "{recoloured} recoloured, {kept} kept"
        );

        assert!(red > 0, "fully painted vertices are red");

        sink.paint(&octree, None);
        let cleared = link.meshes().value.clone();
        assert!(cleared.iter().all(|c| c.colors.is_empty()), "paint cleared");
    }
}
