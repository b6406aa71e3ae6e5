//! Adapter between the app's [`EngineLink`](super::EngineLink) and the threaded
//! [`Engine`]: a mesh sink on the graphics loop that publishes brick meshes, and a bridge
//! thread that turns app commands into engine commands and publishes the [`EngineView`].
//!
//! Guarantee: neither side ever waits for the app. The sink runs on the graphics loop (not the
//! haptic loop), copies only the bricks a refresh changed, publishes through a triple buffer
//! and then asks for a repaint. The bridge thread is an ordinary thread: it sends engine
//! commands on the engine's own channel, reads the tool sample wait-free, and writes exports
//! itself, so no loop does disk I/O for the app.

use std::collections::HashMap;
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::Duration;

use crossbeam::channel::{Receiver, Sender, bounded};
use dynaclay_devices::DeviceInfo;
use dynaclay_loops::SnapshotWriter;
use glam::Vec3;
use parking_lot::Mutex;

use super::command::{EngineCommand, EngineEvent, ForceMode, ForceTool, ToolChoice};
use super::link::{EngineEndpoint, RepaintSignal};
use super::meshes::{ChunkMesh, MeshSet};
use super::view::{DeviceLinkState, EngineView};
use crate::engine::{
    Command, Engine, EngineError, EngineReport, ForceStrokeTool, MeshSink, PushTool,
    ToolChoice as EngineToolChoice,
};
use crate::mesh::{BrickOctree, MeshFormat, RefreshReport, TriMesh, write_mesh};

/// How often the bridge drains commands and publishes the view.
const BRIDGE_PERIOD: Duration = Duration::from_millis(10);

/// Publishes the graphics loop's brick meshes to the app.
pub struct GuiMeshSink {
    meshes: SnapshotWriter<MeshSet>,
    bricks: HashMap<[u32; 3], Arc<ChunkMesh>>,
    set: MeshSet,
    /// The latest set, for exports by the bridge thread (held only to clone the `Arc`s).
    shared: Arc<Mutex<MeshSet>>,
    repaint: RepaintSignal,
}

impl MeshSink for GuiMeshSink {
    fn update(&mut self, octree: &BrickOctree, report: &RefreshReport) {
        for c in &report.removed {
            self.bricks.remove(c);
        }
        for c in &report.changed {
            match octree.brick(*c) {
                Some(b) if !b.mesh.indices.is_empty() => {
                    let mesh = ChunkMesh::from_brick(*c, b.version, &b.mesh, Vec::new());
                    self.bricks.insert(*c, Arc::new(mesh));
                }
                _ => {
                    self.bricks.remove(c);
                }
            }
        }
        self.set.clear();
        self.set.extend(self.bricks.values().cloned());
        self.meshes.publish_clone_of(&self.set);
        self.shared.lock().clone_from(&self.set);
        self.repaint.request();
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
        self.thread
            .join()
            .unwrap_or(Err(EngineError::Lost("gui bridge")))
    }
}

/// Starts the engine with a mesh sink that feeds `endpoint`, and a bridge thread that serves
/// the app's commands. `start` receives the sink and starts the engine (the caller chooses
/// clay, device and configuration); `device` describes the opened device for the panel.
///
/// # Errors
/// Whatever `start` returns.
pub fn start_bridge(
    endpoint: EngineEndpoint,
    device: DeviceInfo,
    start: impl FnOnce(Box<dyn MeshSink>) -> Result<Engine, EngineError>,
) -> Result<EngineBridge, EngineError> {
    let EngineEndpoint {
        commands,
        events,
        view,
        meshes,
        repaint,
    } = endpoint;
    let shared = Arc::new(Mutex::new(MeshSet::new()));
    let sink = GuiMeshSink {
        meshes,
        bricks: HashMap::new(),
        set: MeshSet::new(),
        shared: Arc::clone(&shared),
        repaint,
    };
    let engine = start(Box::new(sink))?;
    let stop = Arc::new(AtomicBool::new(false));
    let flag = Arc::clone(&stop);
    let mut bridge = Bridge {
        engine,
        commands,
        events,
        view,
        shared,
        device,
        tool_radius: PushTool::default().radius,
        saves: Vec::new(),
    };
    let thread = std::thread::Builder::new()
        .name("dynaclay-gui-bridge".into())
        .spawn(move || {
            while !flag.load(Ordering::Relaxed) && bridge.engine.is_alive() {
                bridge.serve();
                std::thread::sleep(BRIDGE_PERIOD);
            }
            bridge.engine.stop()
        })
        .map_err(|source| {
            EngineError::Loop(dynaclay_loops::LoopError::Spawn {
                loop_name: "gui bridge".into(),
                source,
            })
        })?;
    Ok(EngineBridge { stop, thread })
}

struct Bridge {
    engine: Engine,
    commands: Receiver<EngineCommand>,
    events: Sender<EngineEvent>,
    view: SnapshotWriter<EngineView>,
    shared: Arc<Mutex<MeshSet>>,
    device: DeviceInfo,
    tool_radius: f32,
    saves: Vec<Receiver<Result<std::path::PathBuf, String>>>,
}

impl Bridge {
    fn serve(&mut self) {
        while let Ok(cmd) = self.commands.try_recv() {
            self.apply(cmd);
        }
        self.saves.retain(|rx| match rx.try_recv() {
            Ok(r) => {
                let ev = match r {
                    Ok(p) => EngineEvent::Done {
                        what: "save".into(),
                        detail: format!("wrote {}", p.display()),
                    },
                    Err(error) => EngineEvent::Failed {
                        what: "save".into(),
                        error,
                    },
                };
                let _ = self.events.send(ev);
                false
            }
            Err(crossbeam::channel::TryRecvError::Empty) => true,
            Err(crossbeam::channel::TryRecvError::Disconnected) => false,
        });
        let tool = self.engine.latest_tool();
        let counters = self.engine.counters().snapshot();
        let device = &self.device;
        let radius = self.tool_radius;
        self.view.write_with(|v| {
            v.tool_position = tool.tip;
            v.tool_radius = radius;
            v.force_n = if tool.device_force_n.is_finite() {
                tool.device_force_n
            } else {
                Vec3::ZERO
            };
            v.stroke_active = tool.stroke_active;
            v.device.state = if tool.device_fault {
                DeviceLinkState::Faulted
            } else {
                DeviceLinkState::Connected
            };
            v.device.name.clone_from(&device.name);
            v.device.max_force_n = device.max_force_n;
            v.device.has_force = device.has_force;
            v.device.peak_force_n = counters.peak_force_milli_n as f32 / 1000.0;
        });
    }

    fn fail(&self, what: &str, error: String) {
        let _ = self.events.send(EngineEvent::Failed {
            what: what.into(),
            error,
        });
    }

    fn send(&self, what: &str, cmd: Command) {
        if self.engine.commands().send(cmd).is_err() {
            self.fail(what, "the simulation loop has stopped".into());
        }
    }

    fn apply(&mut self, cmd: EngineCommand) {
        let what = cmd.name();
        match cmd {
            EngineCommand::SelectTool(ToolChoice::Force(t)) => {
                self.tool_radius = t.radius_m;
                self.send(what, Command::SetTool(engine_force_tool(&t)));
            }
            EngineCommand::SelectTool(ToolChoice::Geometric(t)) => {
                self.send(what, Command::SetTool(EngineToolChoice::Geometric(t)));
            }
            EngineCommand::SetMaterial(m) => self.send(what, Command::SetMaterial(m)),
            EngineCommand::StrokeStart => self.send(what, Command::StrokeStart),
            EngineCommand::StrokeStop => self.send(what, Command::StrokeStop),
            EngineCommand::Undo => self.send(what, Command::Undo),
            EngineCommand::Redo => self.send(what, Command::Redo),
            EngineCommand::Save { path } => {
                let (tx, rx) = bounded(1);
                self.saves.push(rx);
                self.send(what, Command::Save {
                    path,
                    reply: Some(tx),
                });
            }
            EngineCommand::Export { path } => {
                let set = self.shared.lock().clone();
                let ev = match export_chunks(&set, &path) {
                    Ok(n) => EngineEvent::Done {
                        what: what.into(),
                        detail: format!("wrote {} ({n} triangles)", path.display()),
                    },
                    Err(error) => EngineEvent::Failed {
                        what: what.into(),
                        error,
                    },
                };
                let _ = self.events.send(ev);
            }
            EngineCommand::Load { path } => self.fail(
                what,
                format!("{}: the running engine cannot replace its session yet", path.display()),
            ),
            EngineCommand::ConnectDevice { spec, .. } => self.fail(
                what,
                format!("{spec}: the running engine cannot switch devices yet; restart with --device {spec}"),
            ),
            EngineCommand::DisconnectDevice | EngineCommand::SetMaxForce { .. } => self.fail(
                what,
                "the running engine cannot change its device or force limit yet".into(),
            ),
        }
    }
}

/// Welds the chunks (vertices on shared brick faces coincide exactly) and writes them in the
/// format named by `path`'s extension; returns the triangle count.
///
/// # Errors
/// An unknown extension or the writer's error, naming the path.
pub fn export_chunks(set: &MeshSet, path: &Path) -> Result<usize, String> {
    let format = MeshFormat::from_path(path).ok_or_else(|| {
        format!(
            "{}: unknown mesh format (use .obj, .ply or .stl)",
            path.display()
        )
    })?;
    let mut mesh = TriMesh::default();
    let mut index: HashMap<[u32; 3], u32> = HashMap::new();
    for chunk in set {
        let map: Vec<u32> = chunk
            .positions
            .iter()
            .zip(&chunk.normals)
            .map(|(p, n)| {
                let key = p.map(f32::to_bits);
                *index.entry(key).or_insert_with(|| {
                    mesh.positions.push(Vec3::from(*p));
                    mesh.normals.push(Vec3::from(*n));
                    (mesh.positions.len() - 1) as u32
                })
            })
            .collect();
        for t in chunk.indices.chunks_exact(3) {
            let tri = [map[t[0] as usize], map[t[1] as usize], map[t[2] as usize]];
            if tri[0] != tri[1] && tri[1] != tri[2] && tri[0] != tri[2] {
                mesh.triangles.push(tri);
            }
        }
    }
    write_mesh(path, &mesh, format).map_err(|e| e.to_string())?;
    Ok(mesh.triangles.len())
}

/// The engine tool for an app force tool: the point grab is the contact push felt through the
/// arm (Hua & Qin's single force vector); the others drive the dynamics with their own force
/// vectors each step.
fn engine_force_tool(t: &ForceTool) -> EngineToolChoice {
    let stroke = |tool| {
        EngineToolChoice::Force(ForceStrokeTool {
            tool,
            curve: Vec::new(),
            pivot: Vec3::ZERO,
        })
    };
    match t.mode {
        ForceMode::PointGrab => EngineToolChoice::Push(PushTool {
            distribution: t.distribution,
            radius: t.radius_m,
            gain: t.gain,
        }),
        ForceMode::Area => stroke(crate::tools::ForceTool::Area {
            distribution: t.distribution,
            radius_m: t.radius_m,
            tracks: 8,
            gain: t.gain,
        }),
        ForceMode::Chisel => stroke(crate::tools::ForceTool::Chisel {
            depth_m: t.depth_m,
            radius_m: t.radius_m,
            gain: t.gain,
        }),
        ForceMode::Squirt => stroke(crate::tools::ForceTool::Squirt {
            depth_m: t.depth_m,
            radius_m: t.radius_m,
            gain: t.gain,
        }),
        ForceMode::Pull => stroke(crate::tools::ForceTool::Pull {
            distribution: t.distribution,
            radius_m: t.radius_m,
            gain: t.gain,
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::build_clay;
    use crate::io::{ClayShape, ClaySpec};
    use crate::mesh::{MeshStats, SampleGrid};

    /// A sphere through the real octree mesher, published by the sink and exported welded.
    #[test]
    fn sink_publishes_bricks_and_export_welds_them_closed() {
        let lattice = build_clay(&ClaySpec {
            shape: ClayShape::Sphere,
            resolution: 16,
        })
        .unwrap();
        let grid = SampleGrid::for_lattice(&lattice, 2).unwrap();
        let mut octree = BrickOctree::new(grid);
        let report = octree.rebuild(&lattice);

        let (mut link, end) = super::super::link::engine_link();
        let shared = Arc::new(Mutex::new(MeshSet::new()));
        let mut sink = GuiMeshSink {
            meshes: end.meshes,
            bricks: HashMap::new(),
            set: MeshSet::new(),
            shared: Arc::clone(&shared),
            repaint: end.repaint,
        };
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
        assert!(export_chunks(&published, &dir.path().join("x.abc")).is_err());
    }
}
