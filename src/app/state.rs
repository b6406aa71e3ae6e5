//! The sculpting app's state and its frame: panels for tools, material, device, display and
//! loop latency around the 3D view, and a top bar with undo, redo, save, load and export.
//!
//! Each frame reads the engine's latest view and meshes without waiting, draws, and sends
//! commands for what the user changed. Nothing here can stall the engine's loops (see
//! [`super::link`]). A frame is drawn only when something asks for one (see
//! [`super::redraw`]): an idle window draws nothing.
//!
//! The layout holds still: the side panels keep the width they start with (or the user drags
//! them to) and their contents wrap or scroll rather than widen them; the tool settings and
//! the pin list sit in areas of fixed height, so a new pin or another tool moves nothing.

use std::collections::VecDeque;
use std::path::PathBuf;
use std::time::Instant;

use crate::dynamics::Material;
use crate::io::{OutputKind, OutputRule};
use crate::mesh::MeshFormat;
use crate::render::{
    BoxOverlay, Camera, Disc, ForceOverlay, MeshChunk, QuadOverlay, SceneOptions, Shading,
    ToolOverlay, ToolStyle, Trackball, bounds_of, particle_discs, splat_discs,
};

use super::camera_input::SpaceMouseCamera;
use super::command::{EngineCommand, EngineEvent};
use super::csg_panel::CsgPanel;
use super::device_panel::haptic_gain_slider;
use super::device_panel::{DeviceAction, DevicePanel};
use super::emboss_panel::EmbossPanel;
use super::force_path_panel::ForcePathPanel;
use super::latency::LatencyHistory;
use super::library_panel::LibraryPanel;
use super::link::EngineLink;
use super::material_panel::{MaterialBrush, material_ui};
use super::palette::ToolPalette;
use super::pin_panel::PinPanel;
use super::pointer_tool::PointerTool;
use super::probe_panel::ProbePanel;
use super::redraw::{FrameStats, InFlight, PARTICLE_SETTLE_POLLS};
use super::view::{EngineView, LoopId, WorldBox};
use super::viewport::{DiscKey, SceneView, camera_input};

/// The session file the window saves to and autosaves next to when none is named.
pub const DEFAULT_SESSION: &str = "sculpt.dclay";

/// Set in the mesh version handed to the view while splats hide the mesh, so the view drops
/// the chunks and takes them again when the mesh comes back.
const HIDDEN_MESH_VERSION: u64 = 1 << 63;

/// Lines kept in the message log.
const LOG_LEN: usize = 50;

/// The controls panel's starting width, and the widths the user may drag it to, points.
pub const CONTROLS_WIDTH_PT: f32 = 300.0;
const CONTROLS_WIDTH_RANGE_PT: std::ops::RangeInclusive<f32> = 220.0..=560.0;
/// The latency panel's starting width, and the widths the user may drag it to, points.
pub const LATENCY_WIDTH_PT: f32 = 320.0;
const LATENCY_WIDTH_RANGE_PT: std::ops::RangeInclusive<f32> = 220.0..=560.0;
/// The height of the tool area (the tool buttons and the chosen tool's settings), points:
/// fixed, so the sections below stay put whichever tool is chosen.
const TOOL_AREA_PT: f32 = 330.0;
/// The height of the pin list, points (it scrolls beyond).
const PIN_LIST_PT: f32 = 120.0;

/// How the scene is drawn.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DisplaySettings {
    pub shading: Shading,
    pub tool_style: ToolStyle,
    pub show_force: bool,
    /// Arrow length per newton of force, world units.
    pub force_arrow_per_n: f32,
    pub show_workspace: bool,
    pub show_region: bool,
    /// Outline each detail patch (a refined box) over the view.
    pub show_detail_patches: bool,
    /// How a loaded point set is shown.
    pub points_as: PointsDisplay,
}

/// How a loaded point set is shown: its points as splats, or the clay they follow meshed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PointsDisplay {
    /// Oriented discs in each point's colour, sized by the local spacing; the mesh is hidden.
    #[default]
    Splats,
    /// The clay's mesh (the surface the points follow); no splats.
    Mesh,
}

/// What the last frame handed the renderer (also set without a GPU, where nothing is drawn).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SceneInput {
    /// Mesh chunks drawn.
    pub chunks: usize,
    /// Point-set splats drawn.
    pub splats: usize,
    /// Particle discs drawn.
    pub particles: usize,
}

impl Default for DisplaySettings {
    fn default() -> Self {
        Self {
            shading: Shading::default(),
            tool_style: ToolStyle::TipAndReach,
            show_force: true,
            force_arrow_per_n: 0.05,
            show_workspace: true,
            show_region: true,
            show_detail_patches: true,
            points_as: PointsDisplay::Splats,
        }
    }
}

/// The session worked on and the last mesh exported.
#[derive(Clone, Debug, PartialEq)]
pub struct FilePaths {
    /// Where Save writes and autosave writes beside: the session opened or last saved
    /// under a name (`None`: Save asks for a name).
    pub session: Option<PathBuf>,
    /// The last mesh exported.
    pub export: Option<PathBuf>,
    /// The file the clay was last imported from (a point cloud, mesh or volume): Save As and
    /// Export never replace it.
    pub imported: Option<PathBuf>,
}

impl Default for FilePaths {
    fn default() -> Self {
        Self {
            session: Some(DEFAULT_SESSION.into()),
            export: None,
            imported: None,
        }
    }
}

/// The whole app.
#[derive(Default)]
pub struct SculptApp {
    pub link: EngineLink,
    pub camera: Camera,
    pub trackball: Trackball,
    pub palette: ToolPalette,
    /// The material the sliders show and the engine was last sent.
    pub material: Material,
    /// Painting material onto the clay with the brush.
    pub material_brush: MaterialBrush,
    /// Automatic detail under brushes and force tools, as last set here.
    pub detail: super::detail_panel::DetailSettings,
    /// The Mask tool: painting, inverting and clearing the freeze mask.
    pub mask: super::mask_panel::MaskPanel,
    pub device: DevicePanel,
    pub display: DisplaySettings,
    pub files: FilePaths,
    /// New, Open, Save, Save As, Import, Export and the recent files.
    pub file_menu: super::file_menu::FileMenu,
    /// The question before a replacement drops or keeps the undo history.
    pub replace: super::replace_dialog::ReplaceDialog,
    /// The background load's progress (`None`: no load runs).
    pub load_progress: Option<super::command::LoadProgress>,
    pub latency: LatencyHistory,
    /// The platform probe and the readiness verdict.
    pub probe: ProbePanel,
    pub spacemouse: SpaceMouseCamera,
    /// Recent messages, newest last.
    pub log: VecDeque<String>,
    /// A copy of the latest engine view.
    pub view: EngineView,
    scene: Option<SceneView>,
    /// Which render profile the 3D view asks for: detected from the adapter unless
    /// `DYNACLAY_RENDER_PROFILE` (read by [`Self::new`]) or a caller forces one.
    pub render_request: crate::render::ProfileRequest,
    /// A view size at which the GPU refused to build the view, with why (retried on a new size).
    scene_refused: Option<((u32, u32), String)>,
    /// What the GUI device's fault callbacks saw (set by `run_gui` on eframe's device).
    pub gpu_faults: Option<std::sync::Arc<crate::render::GpuFaultLog>>,
    started: Option<Instant>,
    /// The engine's session-load count when the material sliders last took the engine's
    /// material (`None`: not yet): they follow the engine at start and after each load, and
    /// otherwise keep what the user set.
    material_loads_seen: Option<u64>,
    /// Whether the force-limit slider took the engine's limit once.
    force_limit_synced: bool,
    /// Settings that failed to reach the engine and are sent again next frame.
    tool_pending: bool,
    material_pending: bool,
    pub(super) detail_pending: bool,
    /// Whether the Space key currently holds a stroke.
    key_stroke: bool,
    /// Mesh version last framed by the camera (frames once when the first meshes arrive).
    framed: bool,
    /// The engine restarts seen (a Load of another clay layout): each frames the new clay.
    restarts_seen: u64,
    /// The mouse or pen as the sculpting tool (inert without a pointer device).
    pub pointer: PointerTool,
    /// Whether the held left drag sculpts (it began on the clay without Alt or Shift); a left
    /// drag that began off the clay, or with Alt, orbits.
    sculpt_drag: bool,
    /// The lazy mouse of the pointer's strokes (off by default).
    pub stroke_smoothing: super::stroke_smoothing::StrokeSmoothing,
    /// The 3D view's rectangle in the last frame, points.
    pub viewport_rect: Option<egui::Rect>,
    /// A pen's latest pressure, 0..1 (`None` for a mouse: full depth).
    pen_pressure: Option<f32>,
    /// Mirror planes for strokes, as last sent to the engine.
    pub symmetry: crate::engine::Symmetry,
    /// This frame's brush cursor: centre, radius in points and tint, painted over the scene.
    brush_cursor: Option<(egui::Pos2, f32, egui::Color32)>,
    /// The last surface point the brush was on, where "Refine here" adds a detail patch (and
    /// the tool library's selection, a CSG solid and an embossed image are placed).
    pub(crate) refine_at: Option<glam::Vec3>,
    /// The clay's outward normal at `refine_at`.
    pub(super) brush_normal: Option<glam::Vec3>,
    /// The tool library: tools made from the sculpt.
    pub library: LibraryPanel,
    /// The curve and the pivot of the curve and bend tools.
    pub force_path: ForcePathPanel,
    /// CSG with a session file or a solid.
    pub csg: CsgPanel,
    /// Embossing an image.
    pub emboss: EmbossPanel,
    /// Whether the tool last sent pulls outward for a negative press depth (see
    /// [`super::pointer_tool::raising_choice`]).
    raising_sent: bool,
    /// Pinning with the mouse, and the list of the clay's pins.
    pub pins: PinPanel,
    /// The question before a step removes more than half the clay.
    pub removal: super::removal_dialog::RemovalDialog,
    /// The "Compact RBF clay" switch.
    pub compact_on: bool,
    /// Its particle count `N` (0 until [`SculptApp::new`] sets the default).
    pub compact_particles: usize,
    /// What the last frame handed the renderer.
    pub scene_input: SceneInput,
    /// The discs of the last frame (particles and splats), rebuilt when their key changes.
    discs: Vec<Disc>,
    disc_key: DiscKey,
    /// The status line's frame figures.
    pub frames: FrameStats,
    /// Motion to photon: each frame with the mesh stamp it drew, per stroke.
    pub motion: crate::engine::MotionToPhoton,
    /// The previous frame's time as eframe measured it (set before each frame; `None` in
    /// headless frames).
    pub last_frame_s: Option<f32>,
    /// Whether the window's surface is sRGB (its clear colour is then given linear).
    srgb_window: bool,
    /// What was in flight at the end of the last frame (the window polls while any is).
    pub in_flight: InFlight,
    /// The controls panel's rectangle in the last frame, points.
    pub controls_rect: Option<egui::Rect>,
    /// The base lattice's box (first to last node) of the clay last published, where the
    /// mirror planes are drawn.
    clay_box: Option<WorldBox>,
    /// The particle view's version last seen, and the polls since it last changed.
    particles_seen: u64,
    particle_quiet_polls: u32,
}

/// The particle counts the panel offers.
const PARTICLE_RANGE: std::ops::RangeInclusive<usize> = 100..=20_000;

/// The particle counts the compact RBF clay takes.
const COMPACT_RANGE: std::ops::RangeInclusive<usize> =
    crate::rbf::CompactSettings::MIN_PARTICLES..=crate::rbf::CompactSettings::MAX_PARTICLES;

/// Brush radius factor per `[` or `]` press.
const BRUSH_STEP: f32 = 1.15;
/// Strength factor per scroll point with Shift held (one notch of about 50 points: ×1.22).
const STRENGTH_PER_SCROLL_POINT: f32 = 0.004;
/// Scroll points per line for wheels that report lines.
const POINTS_PER_LINE: f32 = 50.0;

impl SculptApp {
    /// The brush's radius, field units.
    fn brush_radius(&self) -> f32 {
        self.palette
            .choice()
            .spread_radius_fu()
            .unwrap_or(self.palette.radius_fu)
    }

    /// Asks for a detail patch two levels down (a quarter of the base knot spacing) over a box
    /// around the last surface point the brush was on: twice the brush radius, and at least
    /// two and a half base knot spans, on each side.
    fn refine_here(&mut self) {
        let Some(at) = self.refine_at else {
            return;
        };
        let spacing = self
            .link
            .field()
            .value
            .patches
            .first()
            .map_or(0.0, |p| p.lattice.spacing);
        let half = glam::Vec3::splat((2.0 * self.brush_radius()).max(2.5 * spacing));
        self.send(EngineCommand::Refine {
            lo: at - half,
            hi: at + half,
            level: 2,
        });
    }

    /// An app talking to the engine through `link`. The current tool and material are sent on
    /// the first frame.
    #[must_use]
    pub fn new(link: EngineLink) -> Self {
        let mut app = Self {
            link,
            tool_pending: true,
            compact_particles: crate::rbf::CompactSettings::DEFAULT_PARTICLES,
            ..Self::default()
        };
        match crate::render::ProfileRequest::from_env() {
            Ok(request) => app.render_request = request,
            Err(e) => app.note(format!("{e}; the profile follows the adapter")),
        }
        app
    }

    /// Sends `command`; a failure goes to the log. Returns whether it was queued.
    pub fn send(&mut self, command: EngineCommand) -> bool {
        match self.link.send(command) {
            Ok(()) => true,
            Err(e) => {
                self.note(e.to_string());
                false
            }
        }
    }

    /// Adds a line to the message log.
    pub fn note(&mut self, line: impl Into<String>) {
        if self.log.len() == LOG_LEN {
            self.log.pop_front();
        }
        self.log.push_back(line.into());
    }

    /// Takes in what the engine published since the last frame. Never waits.
    pub fn poll_engine(&mut self) {
        let t_s = self
            .started
            .get_or_insert_with(Instant::now)
            .elapsed()
            .as_secs_f64();
        while let Some(ev) = self.link.try_event() {
            let line = match ev {
                EngineEvent::Done { what, detail } => event_line(&what, &detail, false),
                EngineEvent::Failed { what, error } => event_line(&what, &error, true),
                EngineEvent::Library(tools) => {
                    let line = format!("library: {} tools", tools.len());
                    self.library.set_tools(tools, &mut self.palette);
                    self.tool_pending = true;
                    line
                }
                EngineEvent::Progress(progress) => {
                    self.load_progress = progress;
                    continue;
                }
                EngineEvent::FileDone { path, is_session } => {
                    if let Err(e) = self.file_menu.recent.add(&path) {
                        self.note(e.to_string());
                    }
                    if is_session {
                        self.files.session = Some(path);
                    } else {
                        self.files.imported = Some(path);
                    }
                    continue;
                }
            };
            self.note(line);
        }
        let snap = self.link.view();
        let version = snap.version;
        if version != 0 {
            self.view.clone_from(&snap.value);
            if self.view.restarts != self.restarts_seen {
                // A new engine on another clay: frame it when its meshes come, aim the
                // pointer through its workspace map, take the loaded session's material and
                // give it the tool in use.
                self.restarts_seen = self.view.restarts;
                self.framed = false;
                self.material_loads_seen = None;
                self.tool_pending = true;
                // The new engine starts from its defaults: give it the window's detail.
                self.detail_pending = self.detail != Default::default();
                if let Some(map) = self.view.workspace_map {
                    self.pointer.set_map(map);
                }
                // The new clay's box until its meshes arrive and frame it closely.
                if let Some(b) = self.view.clay_box {
                    self.camera.frame_box(b.min, b.max);
                }
            }
            if self.material_loads_seen != Some(self.view.sessions_loaded) {
                self.material = self.view.material;
                self.material_loads_seen = Some(self.view.sessions_loaded);
                // A material the user set before the load is superseded by the session's.
                self.material_pending = false;
            }
            let limit_n = self.view.device.max_force_n;
            if !self.force_limit_synced && limit_n.is_finite() && limit_n > 0.0 {
                self.device.max_force_n = limit_n.min(super::device_panel::MAX_FORCE_LIMIT_N);
                self.force_limit_synced = true;
            }
        }
        let base = self.link.field().value.base();
        self.clay_box = Some(WorldBox {
            min: base.origin,
            max: base.node_position(base.dims[0] - 1, base.dims[1] - 1, base.dims[2] - 1),
        });
        self.latency.record(version, t_s, &self.view.loops);
        self.probe.poll();
    }

    /// Sends settings changed or left pending.
    fn flush_settings(&mut self, tool_changed: bool, material_changed: bool) {
        self.tool_pending |= tool_changed;
        self.material_pending |= material_changed;
        if material_changed && self.material_loads_seen.is_none() {
            // Changed before the engine's first view: keep the user's choice.
            self.material_loads_seen = Some(self.view.sessions_loaded);
        }
        let raising = self.pointer.depth_spans < 0.0;
        self.tool_pending |= raising != self.raising_sent;
        if self.tool_pending {
            let choice = super::pointer_tool::raising_choice(self.palette.choice(), raising);
            self.tool_pending = !self.send(EngineCommand::SelectTool(choice));
            self.raising_sent = raising;
        }
        if self.material_pending {
            self.material_pending = !self.send(EngineCommand::SetMaterial(self.material));
        }
        if self.detail_pending {
            self.detail_pending = !self.send(self.detail.command());
        }
    }

    /// The overlays for this frame.
    #[must_use]
    pub fn scene_options(&self) -> SceneOptions {
        let v = &self.view;
        let d = &self.display;
        let boxed = |b: Option<WorldBox>, show: bool, color: [f32; 4]| {
            b.filter(|_| show).map(|b| BoxOverlay {
                min: b.min,
                max: b.max,
                color,
            })
        };
        SceneOptions {
            shading: d.shading,
            tool: (v.tool_radius > 0.0 && d.tool_style != ToolStyle::Hidden).then_some(
                ToolOverlay {
                    centre: v.tool_position,
                    radius: v.tool_radius,
                    style: d.tool_style,
                    color: if v.stroke_active {
                        [0.9, 0.35, 0.2, 0.35]
                    } else {
                        [0.3, 0.6, 0.9, 0.3]
                    },
                },
            ),
            force: (d.show_force && v.force_n.length_squared() > 0.0).then_some(ForceOverlay {
                origin: v.tool_position,
                force_n: v.force_n,
                length_per_newton: d.force_arrow_per_n,
                color: [1.0, 0.85, 0.2, 1.0],
            }),
            workspace_box: boxed(v.workspace, d.show_workspace, [0.5, 0.5, 0.55, 1.0]),
            region_box: boxed(v.region, d.show_region, [0.3, 0.8, 0.4, 1.0]),
            mirror_planes: self.mirror_planes(),
            ..SceneOptions::default()
        }
    }

    /// The mirror planes that are on (x, y, z), each through the clay's centre and across
    /// its box, as see-through quads.
    #[must_use]
    pub fn mirror_planes(&self) -> [Option<QuadOverlay>; 3] {
        let on = [self.symmetry.x, self.symmetry.y, self.symmetry.z];
        let Some(WorldBox { min: lo, max: hi }) = self.clay_box.filter(|_| on.contains(&true))
        else {
            return [None; 3];
        };
        // The engine mirrors about the clay's centre (`crate::engine::clay_centre`).
        let centre = (lo + hi) * 0.5;
        let colours = [
            [0.95, 0.35, 0.35, 0.18],
            [0.35, 0.9, 0.4, 0.18],
            [0.4, 0.55, 1.0, 0.18],
        ];
        std::array::from_fn(|axis| {
            if !on[axis] {
                return None;
            }
            // The plane's two in-plane axes, and its corners around the box's face.
            let (u, w) = ((axis + 1) % 3, (axis + 2) % 3);
            let corner = |a: f32, b: f32| {
                let mut p = glam::Vec3::ZERO;
                p[axis] = centre[axis];
                p[u] = a;
                p[w] = b;
                p
            };
            Some(QuadOverlay {
                corners: [
                    corner(lo[u], lo[w]),
                    corner(hi[u], lo[w]),
                    corner(hi[u], hi[w]),
                    corner(lo[u], hi[w]),
                ],
                color: colours[axis],
            })
        })
    }

    /// The detail patches' boxes (every patch but the base) in screen points over the view
    /// `rect`, as segments: twelve edges per patch, those with an end behind the eye left
    /// out. Empty while the display does not show them.
    #[must_use]
    pub fn detail_marks_on_screen(&mut self, rect: egui::Rect) -> Vec<[egui::Pos2; 2]> {
        if !self.display.show_detail_patches {
            return Vec::new();
        }
        let size = rect.size().max(egui::vec2(1.0, 1.0));
        let vp = self.camera.view_projection(size.x / size.y);
        let to_screen = |x: glam::Vec3| {
            let c = vp * x.extend(1.0);
            (c.w > 0.0).then(|| {
                egui::pos2(
                    rect.min.x + (c.x / c.w + 1.0) * 0.5 * size.x,
                    rect.min.y + (1.0 - c.y / c.w) * 0.5 * size.y,
                )
            })
        };
        let field = &self.link.field().value;
        let mut segments = Vec::new();
        for patch in field.patches.iter().skip(1) {
            let (lo, hi) = patch.world_support();
            let corner = |i: usize| {
                glam::Vec3::new(
                    if i & 1 == 0 { lo.x } else { hi.x },
                    if i & 2 == 0 { lo.y } else { hi.y },
                    if i & 4 == 0 { lo.z } else { hi.z },
                )
            };
            // The twelve edges join corners whose indices differ in one bit.
            for i in 0..8 {
                for bit in [1, 2, 4] {
                    if i & bit == 0
                        && let (Some(a), Some(b)) =
                            (to_screen(corner(i)), to_screen(corner(i | bit)))
                    {
                        segments.push([a, b]);
                    }
                }
            }
        }
        segments
    }

    /// Outlines the detail patches over the scene image.
    fn paint_detail_patches(&mut self, ui: &egui::Ui, rect: egui::Rect) {
        let painter = ui.painter_at(rect);
        let stroke = egui::Stroke::new(1.0, egui::Color32::from_rgb(120, 200, 230));
        for [a, b] in self.detail_marks_on_screen(rect) {
            painter.line_segment([a, b], stroke);
        }
    }

    /// What is in flight now (see [`InFlight`]); notes whether the particles still move.
    fn in_flight_now(&mut self) -> InFlight {
        let particles = if self.link.particles_on() {
            let version = self.link.particles().version;
            if version == self.particles_seen {
                self.particle_quiet_polls = self.particle_quiet_polls.saturating_add(1);
            } else {
                self.particles_seen = version;
                self.particle_quiet_polls = 0;
            }
            self.particle_quiet_polls < PARTICLE_SETTLE_POLLS
        } else {
            // Switched on, they are watched until they have been still for a while.
            self.particle_quiet_polls = 0;
            false
        };
        let points = &self.link.points().value;
        InFlight {
            stroke: self.view.stroke_active || self.sculpt_drag || self.key_stroke,
            probe: self.probe.is_running(),
            points: points.loaded && !points.settled,
            particles,
            spacemouse: self.spacemouse.is_connected(),
            file_dialog: self.file_menu.dialog_open(),
        }
    }

    /// The status line: the last frame's time and the frame rate, the loops' rates, the
    /// render profile, the tool, and what keeps the window polling.
    #[must_use]
    pub fn status_line(&self) -> String {
        use std::fmt::Write;
        let mut line = match self.frames.last_frame_ms() {
            Some(ms) => format!("frame {ms:.1} ms"),
            None => "frame –".to_owned(),
        };
        let _ = write!(line, " · {} frames/s · loops", self.frames.frames_per_s());
        for id in super::view::LoopId::ALL {
            let stats = &self.view.loops[id.index()];
            if stats.ticks == 0 {
                let _ = write!(line, " {} –", id.name());
            } else {
                let _ = write!(line, " {} {:.0} Hz", id.name(), stats.achieved_rate_hz);
            }
        }
        if let Some(scene) = &self.scene {
            let _ = write!(line, " · {}", scene.profile().short());
        }
        let _ = write!(line, " · tool {}", self.palette.choice().name());
        if let Some(stroke) = self.motion.latest()
            && let Some(first) = stroke.first_visible
        {
            // Plain words: the window's default font has no arrow glyphs.
            let _ = write!(line, " · stroke to screen {:.0} ms", first.total_ms());
            if let Some(settled) = stroke.settled {
                let _ = write!(line, ", settled {:.0} ms", settled.total_ms());
            }
            let all = self.motion.summary("window");
            if all.first_visible_ms.count > 1 {
                let _ = write!(
                    line,
                    " (p95 {:.0} ms over {} strokes)",
                    all.first_visible_ms.p95, all.first_visible_ms.count
                );
            }
        }
        let busy = self.in_flight.names();
        if !busy.is_empty() {
            let _ = write!(line, " · polling for {}", busy.join(", "));
        }
        line
    }

    /// One frame of the whole app. `gpu` is eframe's wgpu state (`None` in headless tests:
    /// everything but the 3D image works).
    pub fn show(&mut self, ui: &mut egui::Ui, gpu: Option<&egui_wgpu::RenderState>) {
        self.frames.record(Instant::now(), self.last_frame_s);
        self.poll_engine();
        self.keyboard(ui);
        let side = unfilled(egui::Frame::side_top_panel(ui.style()));
        egui::Panel::top("dynaclay top bar")
            .frame(side)
            .show(ui, |ui| self.top_bar(ui));
        egui::Panel::bottom("dynaclay log")
            .frame(side)
            .show(ui, |ui| {
                // One line each, cut short rather than wrapped, so the panel's height holds.
                ui.add(
                    egui::Label::new(self.log.back().map_or("ready", String::as_str)).truncate(),
                );
                ui.add(egui::Label::new(egui::RichText::new(self.status_line()).weak()).truncate());
            });
        let mut tool_changed = false;
        let mut material_changed = false;
        let controls = egui::Panel::left("dynaclay controls")
            .frame(side)
            .resizable(true)
            .default_size(CONTROLS_WIDTH_PT)
            .size_range(CONTROLS_WIDTH_RANGE_PT)
            .show(ui, |ui| {
                // Not shrunk to the contents: the panel keeps its width, and the contents
                // wrap to it; a row that cannot wrap (a slider and its name) scrolls
                // sideways rather than widen the panel.
                egui::ScrollArea::both()
                    .auto_shrink([false, false])
                    .show(ui, |ui| {
                        egui::CollapsingHeader::new("Tools")
                            .default_open(true)
                            .show(ui, |ui| {
                                egui::ScrollArea::both()
                                    .id_salt("dynaclay tool area")
                                    .min_scrolled_height(TOOL_AREA_PT)
                                    .max_height(TOOL_AREA_PT)
                                    .auto_shrink([false, false])
                                    .show(ui, |ui| tool_changed = self.palette.ui(ui));
                            });
                        egui::CollapsingHeader::new("Pointer")
                            .default_open(true)
                            .show(ui, |ui| tool_changed |= self.pointer_ui(ui));
                        egui::CollapsingHeader::new("Mask")
                            .default_open(false)
                            .show(ui, |ui| {
                                if let Some(command) = self.mask.ui(ui) {
                                    self.send(command);
                                }
                            });
                        tool_changed |= self.sculpt_sections(ui);
                        egui::CollapsingHeader::new("Material")
                            .default_open(true)
                            .show(ui, |ui| {
                                material_changed = material_ui(ui, &mut self.material);
                                if let Some(command) = self.material_brush.ui(ui, self.refine_at) {
                                    self.send(command);
                                }
                                // The one haptic gain, shown here and in the device panel.
                                if haptic_gain_slider(ui, &mut self.device.haptic_gain) {
                                    let gain = self.device.haptic_gain;
                                    self.send(EngineCommand::SetHapticGain { gain });
                                }
                            });
                        egui::CollapsingHeader::new("Pins")
                            .default_open(true)
                            .show(ui, |ui| {
                                if let Some(command) =
                                    self.pins.ui(ui, &self.view.pins, PIN_LIST_PT)
                                {
                                    self.send(command);
                                }
                            });
                        egui::CollapsingHeader::new("Particles on the clay")
                            .default_open(true)
                            .show(ui, |ui| {
                                self.particles_ui(ui);
                                self.compact_ui(ui);
                            });
                        if self.link.points().value.loaded {
                            egui::CollapsingHeader::new("Point set")
                                .default_open(true)
                                .show(ui, |ui| self.points_ui(ui));
                        }
                        egui::CollapsingHeader::new("Device")
                            .default_open(true)
                            .show(ui, |ui| self.device_ui(ui));
                        egui::CollapsingHeader::new("Display")
                            .default_open(false)
                            .show(ui, |ui| self.display_ui(ui));
                    });
            });
        self.controls_rect = Some(controls.response.rect);
        egui::Panel::right("dynaclay latency")
            .frame(side)
            .resizable(true)
            .default_size(LATENCY_WIDTH_PT)
            .size_range(LATENCY_WIDTH_RANGE_PT)
            .show(ui, |ui| {
                // Not shrunk to the wrapped labels: the plots take the panel's width.
                egui::ScrollArea::both()
                    .auto_shrink([false, false])
                    .show(ui, |ui| {
                        let haptic = &self.view.loops[LoopId::Haptic.index()];
                        self.probe.ui(ui, haptic, |ui| self.latency.ui(ui));
                    });
            });
        self.flush_settings(tool_changed, material_changed);
        let question = self.view.removal_question;
        if let Some(answer) = self.removal.show(ui.ctx(), question) {
            self.send(answer);
        }
        let chosen = self.file_menu.poll();
        let asked = self.file_menu.windows(ui.ctx());
        for request in [chosen, asked].into_iter().flatten() {
            self.file_request(request);
        }
        if let Some(command) = self.replace.show(ui.ctx()) {
            self.send(command);
        }
        egui::CentralPanel::default()
            .frame(unfilled(egui::Frame::central_panel(ui.style())))
            .show(ui, |ui| self.viewport(ui, gpu));
        // Everything else that changes wakes the window itself (input, the engine's signal).
        self.in_flight = self.in_flight_now();
        if let Some(after) = self.in_flight.poll_after() {
            ui.ctx().request_repaint_after(after);
        }
    }

    /// The rule the window's outputs obey: never the imported file, and only over a file of
    /// their own kind that this program wrote.
    fn output_rule(&self) -> OutputRule {
        match &self.files.imported {
            Some(path) => OutputRule::new().input("the imported file", path),
            None => OutputRule::new(),
        }
    }

    /// Carries out what the File controls asked: Save and Export go to the engine at once;
    /// Open, Import and New replace the clay, after the question when it has a history.
    pub fn file_request(&mut self, request: super::file_menu::FileRequest) {
        use super::command::ClaySource;
        use super::file_menu::FileRequest;
        use super::replace_dialog::is_session_path;
        let replacement = match request {
            FileRequest::Save => {
                match self.files.session.clone() {
                    Some(path) => {
                        self.send(EngineCommand::Save { path });
                    }
                    None => {
                        if let Some(note) = self
                            .file_menu
                            .pick(super::file_dialog::FilePurpose::SaveAs, None)
                        {
                            self.note(note);
                        }
                    }
                }
                return;
            }
            FileRequest::SaveAs(path) => {
                // A name without an extension is a session; another extension is refused
                // (Save writes only sessions: a mesh is exported).
                let path = if path.extension().is_none() {
                    path.with_extension("dclay")
                } else {
                    path
                };
                if is_session_path(&path) {
                    match self.output_rule().check("save", &path, OutputKind::Session) {
                        Ok(()) => {
                            self.send(EngineCommand::Save { path });
                        }
                        Err(refused) => self.note(refused.to_string()),
                    }
                } else {
                    self.note(format!(
                        "save: {} is not a session file: sessions end in .dclay (Export writes \
                         meshes)",
                        path.display()
                    ));
                }
                return;
            }
            FileRequest::Export(path) => {
                if MeshFormat::from_path(&path).is_some() {
                    match self.output_rule().check("export", &path, OutputKind::Mesh) {
                        Ok(()) => {
                            self.files.export = Some(path.clone());
                            self.send(EngineCommand::Export { path });
                        }
                        Err(refused) => self.note(refused.to_string()),
                    }
                } else {
                    self.note(format!(
                        "export: cannot tell the mesh format of {}: use .obj, .ply or .stl",
                        path.display()
                    ));
                }
                return;
            }
            FileRequest::Open(path) if !is_session_path(&path) => {
                self.note(format!(
                    "open: {} is not a session (.dclay); Import fits point clouds, meshes and \
                     volumes",
                    path.display()
                ));
                return;
            }
            FileRequest::Import(path) if is_session_path(&path) => {
                self.note(format!(
                    "import: {} is a session; Open it instead",
                    path.display()
                ));
                return;
            }
            FileRequest::Import(path) if !crate::fit::is_importable(&path) => {
                self.note(format!(
                    "import: cannot read {}: import takes {}",
                    path.display(),
                    super::file_dialog::FilePurpose::Import.hint()
                ));
                return;
            }
            FileRequest::Open(path) | FileRequest::Import(path) => ClaySource::File(path),
            FileRequest::New(spec) => ClaySource::New(spec),
        };
        if let Some(command) =
            self.replace
                .ask(replacement, self.view.undo_steps, self.view.redo_steps)
        {
            self.send(command);
        }
    }

    fn keyboard(&mut self, ui: &egui::Ui) {
        if ui.ctx().egui_wants_keyboard_input() {
            return;
        }
        let (smaller, larger) = ui.input_mut(|i| {
            (
                i.consume_key(egui::Modifiers::NONE, egui::Key::OpenBracket),
                i.consume_key(egui::Modifiers::NONE, egui::Key::CloseBracket),
            )
        });
        if smaller || larger {
            self.scale_brush(if larger { BRUSH_STEP } else { 1.0 / BRUSH_STEP });
        }
        let (undo, redo, space_down) = ui.input_mut(|i| {
            let redo = i.consume_key(
                egui::Modifiers::COMMAND | egui::Modifiers::SHIFT,
                egui::Key::Z,
            ) || i.consume_key(egui::Modifiers::COMMAND, egui::Key::Y);
            let undo = i.consume_key(egui::Modifiers::COMMAND, egui::Key::Z);
            (undo, redo, i.key_down(egui::Key::Space))
        });
        if undo {
            self.send(EngineCommand::Undo);
        }
        self.file_shortcuts(ui);
        if redo {
            self.send(EngineCommand::Redo);
        }
        if space_down != self.key_stroke {
            self.key_stroke = space_down;
            self.send(if space_down {
                EngineCommand::StrokeStart
            } else {
                EngineCommand::StrokeStop
            });
        }
    }

    /// The desktop's file shortcuts: Ctrl+N New, Ctrl+O Open, Ctrl+S Save, Ctrl+Shift+S
    /// Save As, Ctrl+I Import, Ctrl+E Export.
    fn file_shortcuts(&mut self, ui: &egui::Ui) {
        use super::file_dialog::FilePurpose;
        let (cmd, cmd_shift) = (
            egui::Modifiers::COMMAND,
            egui::Modifiers::COMMAND | egui::Modifiers::SHIFT,
        );
        let (new, open, save_as, save, import, export) = ui.input_mut(|i| {
            (
                i.consume_key(cmd, egui::Key::N),
                i.consume_key(cmd, egui::Key::O),
                i.consume_key(cmd_shift, egui::Key::S),
                i.consume_key(cmd, egui::Key::S),
                i.consume_key(cmd, egui::Key::I),
                i.consume_key(cmd, egui::Key::E),
            )
        });
        if self.file_menu.is_picking() {
            return;
        }
        let session = self.files.session.clone();
        let purpose = if open {
            Some(FilePurpose::Open)
        } else if save_as {
            Some(FilePurpose::SaveAs)
        } else if import {
            Some(FilePurpose::Import)
        } else if export {
            Some(FilePurpose::Export)
        } else {
            None
        };
        if let Some(purpose) = purpose
            && let Some(note) = self.file_menu.pick(purpose, session.as_deref())
        {
            self.note(note);
        }
        if save {
            self.file_request(super::file_menu::FileRequest::Save);
        }
        if new {
            self.file_menu.open_new_dialog();
        }
    }

    /// Scales the brush (every tool's radius) by `factor`, within the sliders' range.
    pub fn scale_brush(&mut self, factor: f32) {
        let p = &mut self.palette;
        p.radius_fu = (p.radius_fu * factor).clamp(0.005, 1.0);
        p.force.radius_fu = (p.force.radius_fu * factor).clamp(0.005, 1.0);
        self.tool_pending = true;
    }

    /// Scales the strength (force gain and the geometric tools' rates) by `factor`, within
    /// the sliders' range.
    pub fn scale_strength(&mut self, factor: f32) {
        if !(factor.is_finite() && factor > 0.0) {
            return;
        }
        let p = &mut self.palette;
        p.force.gain = (p.force.gain * factor).clamp(1.0e3, 1.0e9);
        for rate in [
            &mut p.deposit_rate_per_s,
            &mut p.remove_rate_per_s,
            &mut p.smooth_rate_per_s,
            &mut p.paint_rate_per_s,
            &mut p.stamp.rate_per_s,
            &mut p.contact_rate_per_s,
        ] {
            *rate = (*rate * factor).clamp(1.0e-3, 1.0e3);
        }
        self.tool_pending = true;
    }

    /// The pointer panel: press depth and strength, and the bindings.
    fn pointer_ui(&mut self, ui: &mut egui::Ui) -> bool {
        if !self.pointer.is_connected() {
            ui.label("The engine's device is not the mouse (start with --device mouse).");
            return false;
        }
        ui.add(
            egui::Slider::new(
                &mut self.pointer.depth_spans,
                -super::pointer_tool::MAX_DEPTH_SPANS..=super::pointer_tool::MAX_DEPTH_SPANS,
            )
            .text("Press depth (spans)"),
        )
        .on_hover_text(
            "How far below the surface a stroke presses; below zero the tip is held above the \
             surface and the stroke pulls the clay out toward it",
        );
        let changed = ui
            .add(
                egui::Slider::new(&mut self.palette.force.gain, 1.0e3..=1.0e9)
                    .logarithmic(true)
                    .text("Strength"),
            )
            .changed();
        ui.add(
            egui::Slider::new(&mut self.stroke_smoothing.strength, 0.0..=1.0)
                .text("Stroke smoothing"),
        )
        .on_hover_text(format!(
            "Lazy mouse: the brush trails the pointer on a string up to {:.0} points long, \
             so jitter shorter than the string never reaches the clay; 0 is off",
            super::stroke_smoothing::MAX_STRING_PT
        ));
        ui.horizontal_wrapped(|ui| {
            ui.label("Mirror");
            let before = self.symmetry;
            ui.checkbox(&mut self.symmetry.x, "X");
            ui.checkbox(&mut self.symmetry.y, "Y");
            ui.checkbox(&mut self.symmetry.z, "Z");
            if self.symmetry != before && !self.send(EngineCommand::SetSymmetry(self.symmetry)) {
                self.symmetry = before;
            }
        });
        ui.label("Left drag on the clay: stroke · Alt+left or left off the clay: orbit");
        ui.label("Right, middle or Shift+left: pan · wheel: zoom");
        ui.label("Ctrl+wheel: depth (below 0: pull out) · Shift+wheel: strength · [ ]: brush size");
        changed
    }

    fn top_bar(&mut self, ui: &mut egui::Ui) {
        ui.horizontal_wrapped(|ui| {
            let (undo_n, redo_n) = (self.view.undo_steps, self.view.redo_steps);
            if ui
                .button("Undo")
                .on_hover_text(format!("Ctrl+Z ({undo_n} steps)"))
                .clicked()
            {
                self.send(EngineCommand::Undo);
            }
            if ui
                .button("Redo")
                .on_hover_text(format!("Ctrl+Shift+Z ({redo_n} steps)"))
                .clicked()
            {
                self.send(EngineCommand::Redo);
            }
            // A fixed width, so the bar does not shift as the counts grow.
            ui.add_sized(
                [110.0, ui.spacing().interact_size.y],
                egui::Label::new(
                    egui::RichText::new(format!("{undo_n} undo · {redo_n} redo")).weak(),
                ),
            );
            ui.separator();
            let refine = ui
                .add_enabled(self.refine_at.is_some(), egui::Button::new("Refine here"))
                .on_hover_text(
                    "Add a detail patch at a quarter of the knot spacing around the last point \
                     the brush was on: strokes there carve finer features",
                );
            if refine.clicked() {
                self.refine_here();
            }
            ui.separator();
            let session = self.files.session.clone();
            let busy = self.load_progress.is_some();
            if let Some(request) = self.file_menu.bar_ui(ui, session.as_deref(), busy) {
                self.file_request(request);
            }
            // The session's name: what Save writes (and autosave writes beside).
            let name = session.as_deref().map_or_else(
                || "unsaved".to_owned(),
                |p| {
                    p.file_name()
                        .map_or_else(|| p.display().to_string(), |n| n.to_string_lossy().into())
                },
            );
            ui.add(egui::Label::new(egui::RichText::new(name).weak()).truncate())
                .on_hover_text(session.map_or_else(String::new, |p| p.display().to_string()));
            if let Some(progress) = &self.load_progress {
                ui.add(
                    egui::ProgressBar::new(progress.fraction)
                        .desired_width(160.0)
                        .text(format!(
                            "{}: {}",
                            short_name(&progress.source),
                            progress.stage
                        )),
                );
            }
            ui.separator();
            let active = self.view.stroke_active;
            if ui
                .selectable_label(active, "Sculpt")
                .on_hover_text("hold Space to sculpt")
                .clicked()
            {
                self.send(if active {
                    EngineCommand::StrokeStop
                } else {
                    EngineCommand::StrokeStart
                });
            }
        });
    }

    fn device_ui(&mut self, ui: &mut egui::Ui) {
        let status = self.view.device.clone();
        match self.device.ui(ui, &status) {
            Some(DeviceAction::Connect { spec, max_force_n }) => {
                // One process cannot read the same SpaceMouse as camera and as tool.
                if spec == dynaclay_devices::spec::DeviceSpec::SpaceMouse
                    && self.spacemouse.is_connected()
                {
                    self.spacemouse.disconnect();
                }
                self.send(EngineCommand::ConnectDevice { spec, max_force_n });
            }
            Some(DeviceAction::Disconnect) => {
                self.send(EngineCommand::DisconnectDevice);
            }
            Some(DeviceAction::SetMaxForce { max_force_n }) => {
                self.send(EngineCommand::SetMaxForce { max_force_n });
            }
            Some(DeviceAction::SetHapticGain { gain }) => {
                self.send(EngineCommand::SetHapticGain { gain });
            }
            None => {}
        }
        ui.separator();
        // A toggle: shown selected while the SpaceMouse drives the camera.
        let camera_on = self.spacemouse.is_connected();
        if ui
            .selectable_label(camera_on, "SpaceMouse camera")
            .on_hover_text("Fly the camera with a SpaceMouse")
            .clicked()
        {
            if camera_on {
                self.spacemouse.disconnect();
            } else {
                self.spacemouse.connect();
            }
        }
        if !self.spacemouse.status.is_empty() {
            ui.weak(&self.spacemouse.status);
        }
    }

    /// The particles on the clay: the switch and `N`, stored straight into the graphics loop's
    /// follower through the link (no command, no wait).
    fn particles_ui(&mut self, ui: &mut egui::Ui) {
        let mut on = self.link.particles_on();
        if ui
            .checkbox(&mut on, "Particles")
            .on_hover_text("Show the constrained particles as discs on the clay")
            .changed()
        {
            self.link.set_particles_on(on);
        }
        let mut n = self.link.particle_count();
        if ui
            .add(
                egui::Slider::new(&mut n, PARTICLE_RANGE)
                    .logarithmic(true)
                    .text("Particles N"),
            )
            .changed()
        {
            self.link.set_particle_count(n);
        }
        if on {
            let shown = self.link.particles().value.positions.len();
            ui.weak(format!("{shown} particles on the clay"));
        }
    }

    /// The compact RBF clay (Zhang et al. §5.4): the switch and `N` go to the engine as a
    /// command; the centre count and the last re-interpolation's time come back in the view.
    fn compact_ui(&mut self, ui: &mut egui::Ui) {
        let before = (self.compact_on, self.compact_particles);
        ui.checkbox(
            &mut self.compact_on,
            format!("Compact RBF clay ({} particles)", self.compact_particles),
        )
        .on_hover_text(
            "Hold the clay as an RBF of 3N centres: after each contact stroke the particles \
             resample it and the RBF is interpolated again (one undo step), so its size stays \
             fixed",
        );
        ui.add(
            egui::Slider::new(&mut self.compact_particles, COMPACT_RANGE)
                .logarithmic(true)
                .text("Compact N"),
        );
        let changed = (self.compact_on, self.compact_particles) != before;
        // A new N restarts the mode only when it is on.
        if changed && (self.compact_on || before.0) {
            let particles = self.compact_on.then_some(self.compact_particles);
            self.send(EngineCommand::SetCompactRbf { particles });
        }
        let c = self.view.compact;
        if c.on {
            let centres = c
                .centres
                .map_or_else(|| "no RBF yet".to_owned(), |k| format!("{k} centres"));
            let busy = if c.busy { ", re-interpolating" } else { "" };
            ui.weak(format!(
                "{centres}; last re-interpolation {:.2} s{busy}; {} applied, {} failed",
                c.last_s, c.applied, c.failed
            ));
        }
    }

    /// A loaded point set: splats or the meshed clay, and how many points follow it.
    fn points_ui(&mut self, ui: &mut egui::Ui) {
        let d = &mut self.display;
        ui.horizontal_wrapped(|ui| {
            ui.radio_value(&mut d.points_as, PointsDisplay::Splats, "Splats")
                .on_hover_text("The points as oriented discs in their colours");
            ui.radio_value(&mut d.points_as, PointsDisplay::Mesh, "Mesh")
                .on_hover_text("The clay the points follow, meshed");
        });
        let p = &self.link.points().value;
        ui.weak(points_line(p));
    }

    fn display_ui(&mut self, ui: &mut egui::Ui) {
        use crate::render::EnvironmentMode as E;
        let d = &mut self.display;
        egui::ComboBox::from_label("Environment")
            .selected_text(format!("{:?}", d.shading.environment))
            .show_ui(ui, |ui| {
                for m in [E::Off, E::Opaque, E::Transparent, E::ClearCoat] {
                    ui.selectable_value(&mut d.shading.environment, m, format!("{m:?}"));
                }
            });
        ui.add(
            egui::Slider::new(&mut d.shading.environment_opacity, 0.0..=1.0)
                .text("Environment opacity"),
        );
        ui.add(egui::Slider::new(&mut d.shading.specular, 0.0..=1.0).text("Specular"));
        ui.add(
            egui::Slider::new(&mut d.shading.shininess, 1.0..=256.0)
                .logarithmic(true)
                .text("Shininess"),
        );
        ui.horizontal_wrapped(|ui| {
            ui.label("Clay colour");
            ui.color_edit_button_rgb(&mut d.shading.material_color);
        });
        egui::ComboBox::from_label("Tool drawn")
            .selected_text(format!("{:?}", d.tool_style))
            .show_ui(ui, |ui| {
                for s in [
                    ToolStyle::Hidden,
                    ToolStyle::TipAndReach,
                    ToolStyle::Transparent,
                    ToolStyle::Wireframe,
                ] {
                    ui.selectable_value(&mut d.tool_style, s, format!("{s:?}"));
                }
            });
        ui.checkbox(&mut d.show_force, "Force arrow");
        ui.checkbox(&mut d.show_workspace, "Workspace box");
        ui.checkbox(&mut d.show_region, "Simulated region box");
        ui.checkbox(&mut d.show_detail_patches, "Show detail patches")
            .on_hover_text("Outline each refined box (detail patch) of the clay");
    }

    fn viewport(&mut self, ui: &mut egui::Ui, gpu: Option<&egui_wgpu::RenderState>) {
        let rect = ui.available_rect_before_wrap();
        let response = ui.allocate_rect(rect, egui::Sense::click_and_drag());
        self.viewport_rect = Some(rect);
        self.pointer_input(ui, &response);
        camera_input(
            ui,
            &response,
            &mut self.camera,
            &self.trackball,
            self.sculpt_drag,
        );
        if self.spacemouse.poll(&mut self.camera) {
            ui.ctx().request_repaint();
        }
        let options = self.scene_options();
        self.update_discs();
        let splats_only =
            self.display.points_as == PointsDisplay::Splats && self.disc_key.points != 0;
        // The stamp before the meshes: the meshes drawn are then at least as new as it says.
        let drawn_stamp = self.link.mesh_stamp();
        if drawn_stamp.is_some_and(|(_, new_engine)| new_engine) {
            self.motion = crate::engine::MotionToPhoton::new();
        }
        let (meshes, _) = self.link.scene();
        let mut chunks: Vec<MeshChunk<'_>> = meshes.value.iter().map(|c| c.as_chunk()).collect();
        let bounds = bounds_of(&chunks);
        // Splats replace the mesh: its chunks leave the GPU under a version of their own.
        let mesh_version = if splats_only {
            chunks.clear();
            meshes.version | HIDDEN_MESH_VERSION
        } else {
            meshes.version
        };
        self.scene_input.chunks = chunks.len();
        let frame_now = response.double_clicked() || (!self.framed && bounds.is_some());
        if frame_now && let Some((lo, hi)) = bounds {
            self.camera.frame_box(lo, hi);
            self.framed = true;
        }
        let Some(rs) = gpu else {
            centred_note(ui, rect, "3D view needs a wgpu device (none in this run)");
            self.paint_detail_patches(ui, rect);
            self.paint_pins(ui, rect);
            self.paint_sculpt_marks(ui, rect);
            self.paint_brush_cursor(ui, rect);
            return;
        };
        let ppp = ui.ctx().pixels_per_point();
        let size = (
            (rect.width() * ppp).round().max(1.0) as u32,
            (rect.height() * ppp).round().max(1.0) as u32,
        );
        if let Some(lost) = self.gpu_faults.as_ref().and_then(|f| f.lost()) {
            centred_note(
                ui,
                rect,
                &format!(
                    "the GPU device was lost ({lost}); the sculpt is kept and autosaved: save \
                     it and restart the window"
                ),
            );
            return;
        }
        if self.scene.is_none() {
            if let Some((refused, why)) = &self.scene_refused
                && *refused == size
            {
                centred_note(ui, rect, why);
                return;
            }
            match SceneView::new(rs, self.render_request, size.0, size.1) {
                Ok(view) => {
                    // Chosen once per view: said in the log and on stderr, and kept in the
                    // status line.
                    let line = view.profile().to_string();
                    eprintln!("dynaclay: {line}");
                    // The log directly: `self.note` would borrow all of `self`, and the
                    // meshes' chunks still borrow the link.
                    if self.log.len() == LOG_LEN {
                        self.log.pop_front();
                    }
                    self.log.push_back(line);
                    self.scene = Some(view);
                    self.scene_refused = None;
                }
                Err(e) => {
                    let why = format!("cannot build the 3D view: {e}");
                    centred_note(ui, rect, &why);
                    self.scene_refused = Some((size, why));
                    return;
                }
            }
        }
        let Some(scene) = self.scene.as_mut() else {
            return;
        };
        scene.set_discs(rs, self.disc_key, &self.discs);
        let image = scene.draw(rs, size, &chunks, mesh_version, &self.camera, &options);
        // The frame's time: its scene submitted to the GPU (egui composites and presents it
        // after this update; that wait is not counted).
        if image.is_some()
            && let (Some((stamp, _)), Some(now_ns)) = (drawn_stamp, self.link.engine_now_ns())
        {
            self.motion.frame(now_ns, &stamp);
        }
        let problem = scene.problem();
        if let Some(image) = image {
            image.paint_at(ui, rect);
            self.paint_detail_patches(ui, rect);
            self.paint_pins(ui, rect);
            self.paint_sculpt_marks(ui, rect);
            self.paint_brush_cursor(ui, rect);
        }
        if let Some(problem) = problem {
            centred_note(ui, rect, &problem);
        }
        if let Some(faults) = &self.gpu_faults
            && faults.error_count() > 0
        {
            ui.painter().text(
                rect.left_bottom() + egui::vec2(8.0, -8.0),
                egui::Align2::LEFT_BOTTOM,
                format!("{} GPU errors (see stderr)", faults.error_count()),
                egui::FontId::proportional(12.0),
                ui.visuals().warn_fg_color,
            );
        }
    }

    /// Rebuilds this frame's discs when the particles, the point set or the display mode
    /// changed: the particles when they are on, the splats when a point set is loaded and
    /// shown as splats.
    fn update_discs(&mut self) {
        let splats = self.display.points_as == PointsDisplay::Splats;
        let (_, particles) = self.link.scene();
        let particles_key = particles.map_or(0, |p| p.version + 1);
        let points = self.link.points();
        let points_key = if points.value.loaded && splats {
            points.version + 1
        } else {
            0
        };
        let key = DiscKey {
            particles: particles_key,
            points: points_key,
        };
        if key == self.disc_key {
            return;
        }
        self.disc_key = key;
        self.discs.clear();
        if points_key != 0 {
            let p = &self.link.points().value;
            splat_discs(
                &mut self.discs,
                &p.positions,
                &p.normals,
                &p.colours,
                &p.radii,
                &p.normal_gradients,
            );
        }
        self.scene_input.splats = self.discs.len();
        if let (_, Some(particles)) = self.link.scene() {
            let p = &particles.value;
            particle_discs(&mut self.discs, &p.positions, &p.normals, &p.radii);
        }
        self.scene_input.particles = self.discs.len() - self.scene_input.splats;
    }

    /// The 3D view's problem, if it has one (a refused size or mesh, a failed frame, or a
    /// view the GPU would not build).
    #[must_use]
    pub fn view_problem(&self) -> Option<String> {
        match &self.scene {
            Some(scene) => scene.problem(),
            None => self.scene_refused.as_ref().map(|(_, why)| why.clone()),
        }
    }
}

impl SculptApp {
    /// The pointer as the tool: chooses between sculpting and orbiting when the left button
    /// goes down, aims the tool under the pointer, reads the brush wheels and paints the
    /// brush cursor.
    fn pointer_input(&mut self, ui: &egui::Ui, response: &egui::Response) {
        let (pressed, down, mut modifiers, pos, wheel, press_modifiers) = ui.input(|i| {
            let mut wheel = (0.0f32, egui::Modifiers::NONE);
            let mut press_modifiers = None;
            for e in &i.events {
                if let egui::Event::PointerButton {
                    button: egui::PointerButton::Primary,
                    pressed: true,
                    modifiers,
                    ..
                } = e
                {
                    press_modifiers = Some(*modifiers);
                }
                if let egui::Event::MouseWheel {
                    unit,
                    delta,
                    modifiers,
                    ..
                } = e
                {
                    let per = match unit {
                        egui::MouseWheelUnit::Point => 1.0,
                        egui::MouseWheelUnit::Line => POINTS_PER_LINE,
                        egui::MouseWheelUnit::Page => 10.0 * POINTS_PER_LINE,
                    };
                    wheel.0 += (delta.y + delta.x) * per;
                    wheel.1 = *modifiers;
                }
                if let egui::Event::Touch { force: Some(f), .. } = e {
                    self.pen_pressure = Some(f.clamp(0.0, 1.0));
                }
            }
            (
                i.pointer.primary_pressed(),
                i.pointer.primary_down(),
                i.modifiers,
                i.pointer.latest_pos(),
                wheel,
                press_modifiers,
            )
        });
        // The modifiers held when the button went down decide between sculpting and orbiting.
        if let Some(m) = press_modifiers {
            modifiers = m;
        }
        self.brush_cursor = None;
        if self.force_path.picking() {
            let hit = self.clay_hit(response.rect, pos);
            let starts = pressed && response.hovered() && hit.is_some();
            self.pointer.release();
            self.path_pick_input(hit, starts);
            // A press on the clay picks; one beside it orbits.
            self.sculpt_drag = starts || (self.sculpt_drag && down);
            return;
        }
        if self.pins.active {
            self.pin_input(response, pos, pressed, down, modifiers);
            return;
        }
        if self.mask.active {
            self.mask_input(response, pos, pressed, down, modifiers);
            return;
        }
        if self.material_brush.active {
            self.material_paint_input(response, pos, pressed, down);
            return;
        }
        if !self.pointer.is_connected() {
            self.sculpt_drag = false;
            return;
        }
        if response.hovered() && wheel.0 != 0.0 {
            if wheel.1.ctrl || wheel.1.command {
                self.pointer.scroll_depth(wheel.0);
            } else if wheel.1.shift {
                self.scale_strength((wheel.0 * STRENGTH_PER_SCROLL_POINT).exp());
            }
        }
        if pressed && response.hovered() {
            self.sculpt_drag =
                !modifiers.alt && !modifiers.shift && self.pointer.pose.is_some_and(|p| p.on_clay);
        }
        if !down {
            self.sculpt_drag = false;
        }
        if !self.sculpt_drag {
            self.force_path.end_recording();
        }
        let rect = response.rect;
        let over = pos.filter(|p| rect.contains(*p));
        let Some(p) = over.or(pos.filter(|_| self.sculpt_drag)) else {
            self.stroke_smoothing.cancel();
            self.pointer.release();
            return;
        };
        let size = rect.size().max(egui::vec2(1.0, 1.0));
        let to_ndc = |p: glam::Vec2| {
            glam::Vec2::new(
                2.0 * (p.x - rect.min.x) / size.x - 1.0,
                1.0 - 2.0 * (p.y - rect.min.y) / size.y,
            )
        };
        let pointer_pt = glam::Vec2::new(p.x, p.y);
        let pressure = self
            .pen_pressure
            .filter(|_| self.sculpt_drag)
            .unwrap_or(1.0);
        // The lazy mouse: a held stroke's brush trails the pointer on a string; when the
        // stroke ends, the brush is drawn the rest of the way before it lifts.
        let brush_pt = if self.sculpt_drag {
            self.stroke_smoothing.follow(pointer_pt)
        } else {
            if let Some(tail) = self.stroke_smoothing.finish(pointer_pt) {
                // The tail is drawn pressed, and handed over twice: the second, still
                // sample is a dwell at the tail's end, so the device presses there before the
                // release that follows (a segment toward a released sample is played lifted).
                let field = &self.link.field().value;
                for _ in 0..2 {
                    self.pointer.aim(
                        field,
                        &self.camera,
                        to_ndc(tail),
                        size.x / size.y,
                        true,
                        self.pen_pressure.unwrap_or(1.0),
                    );
                }
                response.ctx.request_repaint();
                return;
            }
            pointer_pt
        };
        let field = &self.link.field().value;
        let pose = self.pointer.aim(
            field,
            &self.camera,
            to_ndc(brush_pt),
            size.x / size.y,
            self.sculpt_drag,
            pressure,
        );
        if !pose.on_clay {
            return;
        }
        if self.sculpt_drag {
            let spacing = self.link.field().value.finest_spacing();
            self.force_path.record(pose.surface, spacing);
        }
        self.refine_at = Some(pose.surface);
        self.brush_normal = Some(pose.normal);
        // The brush cursor: the tool's footprint on the surface, tinted by the tool.
        let radius = self.brush_radius();
        let aspect = size.x / size.y;
        let to_screen = |x: glam::Vec3| {
            let c = self.camera.view_projection(aspect).project_point3(x);
            egui::pos2(
                rect.min.x + (c.x + 1.0) * 0.5 * size.x,
                rect.min.y + (1.0 - c.y) * 0.5 * size.y,
            )
        };
        let (right, _) = self.camera.right_up();
        let centre = to_screen(pose.surface);
        let rim = to_screen(pose.surface + right * radius);
        let tint = brush_tint(&self.palette.choice(), self.sculpt_drag);
        self.brush_cursor = Some((centre, (rim - centre).length(), tint));
    }

    /// With the Mask tool on, a left drag that starts on the clay paints the freeze mask along
    /// its path with the brush's radius (Ctrl held: erases it) instead of sculpting; a press
    /// beside the clay orbits.
    fn mask_input(
        &mut self,
        response: &egui::Response,
        pos: Option<egui::Pos2>,
        pressed: bool,
        down: bool,
        modifiers: egui::Modifiers,
    ) {
        self.pointer.release();
        let hit = self.clay_hit(response.rect, pos);
        if let Some(at) = hit {
            self.refine_at = Some(at);
        }
        let starts = pressed && response.hovered() && hit.is_some();
        let held = down && (self.mask.painting() || starts);
        let erase_held = modifiers.ctrl || modifiers.command;
        let radius = self.brush_radius();
        if let Some(edit) = self.mask.pointer(hit, held, radius, erase_held) {
            self.send(EngineCommand::Mask(edit));
        }
        self.sculpt_drag = self.mask.painting();
    }

    /// With the material brush on, a left drag that starts on the clay paints material along
    /// its path instead of sculpting (a press beside the clay orbits).
    fn material_paint_input(
        &mut self,
        response: &egui::Response,
        pos: Option<egui::Pos2>,
        pressed: bool,
        down: bool,
    ) {
        self.pointer.release();
        let hit = self.clay_hit(response.rect, pos);
        if let Some(at) = hit {
            self.refine_at = Some(at);
        }
        let starts = pressed && response.hovered() && hit.is_some();
        let held = down && (self.material_brush.painting() || starts);
        if let Some(paint) = self.material_brush.pointer(hit, held) {
            self.send(EngineCommand::PaintMaterial(paint));
        }
        self.sculpt_drag = self.material_brush.painting();
    }

    /// The clay surface point under the screen point `pos` of the view `rect`, if the ray
    /// through it meets the clay.
    fn clay_hit(&mut self, rect: egui::Rect, pos: Option<egui::Pos2>) -> Option<glam::Vec3> {
        let p = pos.filter(|p| rect.contains(*p))?;
        let size = rect.size().max(egui::vec2(1.0, 1.0));
        let ndc = glam::Vec2::new(
            2.0 * (p.x - rect.min.x) / size.x - 1.0,
            1.0 - 2.0 * (p.y - rect.min.y) / size.y,
        );
        let (origin, direction) = self.camera.ray_through(ndc, size.x / size.y);
        crate::field::pick_surface(
            &self.link.field().value,
            crate::field::Ray { origin, direction },
        )
        .map(|h| h.point)
    }

    /// Sends the palette's tool now (and again next frame if the queue refuses it).
    pub(super) fn resend_tool(&mut self) {
        self.flush_settings(true, false);
    }

    /// With pin mode on, the left button pins instead of sculpting: a click on the clay pins
    /// a point (Ctrl: a normal), a drag that starts on the clay pins the curve it traces.
    fn pin_input(
        &mut self,
        response: &egui::Response,
        pos: Option<egui::Pos2>,
        pressed: bool,
        down: bool,
        modifiers: egui::Modifiers,
    ) {
        self.pointer.release();
        let spacing = self.link.field().value.finest_spacing();
        let hit = self.clay_hit(response.rect, pos);
        // A gesture starts only with a press on the clay; a press beside it orbits.
        let starts = pressed && response.hovered() && hit.is_some();
        let held = down && (self.pins.tracing() || starts);
        let ctrl = modifiers.ctrl || modifiers.command;
        if let Some(command) = self.pins.pointer(hit, held, ctrl, spacing) {
            self.send(command);
        }
        self.sculpt_drag = self.pins.tracing();
    }

    /// The pins' marks in screen points over the view `rect`: one position per point pin,
    /// the polyline of a curve pin. Marks behind the eye are left out.
    #[must_use]
    pub fn pin_marks_on_screen(&self, rect: egui::Rect) -> Vec<Vec<egui::Pos2>> {
        let size = rect.size().max(egui::vec2(1.0, 1.0));
        let vp = self.camera.view_projection(size.x / size.y);
        self.view
            .pin_marks
            .iter()
            .map(|mark| {
                mark.iter()
                    .filter_map(|&x| {
                        let c = vp * x.extend(1.0);
                        (c.w > 0.0).then(|| {
                            egui::pos2(
                                rect.min.x + (c.x / c.w + 1.0) * 0.5 * size.x,
                                rect.min.y + (1.0 - c.y / c.w) * 0.5 * size.y,
                            )
                        })
                    })
                    .collect()
            })
            .collect()
    }

    /// Marks the pins over the scene image: a ringed dot per point, a line per curve.
    fn paint_pins(&self, ui: &egui::Ui, rect: egui::Rect) {
        let painter = ui.painter_at(rect);
        let colour = egui::Color32::from_rgb(60, 200, 90);
        for mark in self.pin_marks_on_screen(rect) {
            match mark.as_slice() {
                [p] => {
                    painter.circle_filled(*p, 3.5, colour);
                    painter.circle_stroke(*p, 6.0, egui::Stroke::new(1.5, colour));
                }
                points => {
                    painter.add(egui::Shape::line(
                        points.to_vec(),
                        egui::Stroke::new(2.5, colour),
                    ));
                }
            }
        }
    }

    /// Paints the brush cursor over the scene image.
    fn paint_brush_cursor(&self, ui: &egui::Ui, rect: egui::Rect) {
        if let Some((centre, radius, tint)) = self.brush_cursor {
            let painter = ui.painter_at(rect);
            painter.circle_stroke(centre, radius, egui::Stroke::new(2.0, tint));
            painter.circle_filled(centre, 2.5, tint);
        }
    }
}

/// The brush cursor's colour: warm for force tools, green for adding, red for removing,
/// blue for the others; brighter while a stroke is held.
fn brush_tint(choice: &crate::engine::ToolChoice, pressing: bool) -> egui::Color32 {
    use crate::tools::ToolAction;
    let [r, g, b] = match choice {
        crate::engine::ToolChoice::Push(_) | crate::engine::ToolChoice::Force { .. } => {
            [240, 150, 60]
        }
        crate::engine::ToolChoice::Geometric(t) => match t.action {
            ToolAction::Add { .. } => [90, 210, 110],
            ToolAction::Remove => [230, 80, 70],
            _ => [90, 160, 240],
        },
    };
    let alpha = if pressing { 255 } else { 170 };
    egui::Color32::from_rgba_unmultiplied(r, g, b, alpha)
}

/// The file name of `source` (a path), or `source` itself.
fn short_name(source: &str) -> std::borrow::Cow<'_, str> {
    std::path::Path::new(source)
        .file_name()
        .map_or(std::borrow::Cow::Borrowed(source), |n| n.to_string_lossy())
}

/// The points panel's line: the points shown and, where the follower has resampled them to
/// the clay's area, the count the load reported, so the panel and the log never name two
/// counts without saying why.
#[must_use]
pub fn points_line(view: &crate::pointset::PointSetView) -> String {
    let state = if view.settled { "settled" } else { "following" };
    let shown = view.positions.len();
    if shown == view.arrived {
        format!("{shown} points, {state}")
    } else {
        format!(
            "{shown} points, {state} (resampled to the clay from the {} loaded)",
            view.arrived
        )
    }
}

/// The log line of an engine answer, naming its command once: a detail or an error that
/// already starts with the command's name (an error whose own message names what failed)
/// is not prefixed with it again.
#[must_use]
pub fn event_line(what: &str, text: &str, failed: bool) -> String {
    let rest = text
        .strip_prefix(what)
        .and_then(|r| r.strip_prefix(':').or_else(|| r.strip_prefix(' ')))
        .map_or(text, str::trim_start);
    if failed {
        format!("{what} failed: {rest}")
    } else {
        format!("{what}: {rest}")
    }
}

/// Text painted over the view; painted rather than a label widget so it never takes the
/// pointer drags meant for the camera.
fn centred_note(ui: &egui::Ui, rect: egui::Rect, text: &str) {
    ui.painter().text(
        rect.center(),
        egui::Align2::CENTER_CENTER,
        text,
        egui::FontId::proportional(14.0),
        ui.visuals().weak_text_color(),
    );
}

/// `frame` without its fill. The panels are not filled: the window is cleared to their fill
/// colour instead ([`window_clear_color`]), so it looks the same, but egui's shader no longer
/// runs over every pixel of the window. On a software adapter that shader is the frame's main
/// cost (several times a plain textured quad per pixel on lavapipe), so each pixel it need not
/// touch counts.
fn unfilled(frame: egui::Frame) -> egui::Frame {
    frame.fill(egui::Color32::TRANSPARENT)
}

/// The colour the window is cleared to before egui draws: the panels' fill (the panels
/// themselves are not filled, see [`unfilled`]), in the gamma space of a `Unorm` target; for
/// an sRGB target (`srgb_target`) it is given linear, as such a target expects.
#[must_use]
pub fn window_clear_color(visuals: &egui::Visuals, srgb_target: bool) -> [f32; 4] {
    if srgb_target {
        egui::Rgba::from(visuals.panel_fill).to_array()
    } else {
        visuals.panel_fill.to_normalized_gamma_f32()
    }
}

impl eframe::App for SculptApp {
    fn clear_color(&self, visuals: &egui::Visuals) -> [f32; 4] {
        window_clear_color(visuals, self.srgb_window)
    }

    fn ui(&mut self, ui: &mut egui::Ui, frame: &mut eframe::Frame) {
        self.last_frame_s = frame.info().cpu_usage;
        let gpu = frame.wgpu_render_state().cloned();
        self.srgb_window = gpu.as_ref().is_some_and(|rs| rs.target_format.is_srgb());
        self.show(ui, gpu.as_ref());
    }
}
