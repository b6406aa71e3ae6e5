//! A stroke as the window drives it, run in the lockstep engine (deterministic): the window's
//! own [`PointerTool`] aims at points of the clay's top face through a camera looking down,
//! pressing at its default depth, and a pose device without force hands those tips to the
//! haptic loop one per millisecond of device time (the pointer's samples, interpolated at the
//! haptic rate). The engine holds the palette's [`ToolChoice`], as the window sends it. The
//! result is read back from an exported mesh. Shared by `#[path]` (this folder is not a test
//! target of its own).

// Each test that shares this file uses part of it.
#![allow(dead_code)]

use dynaclay::app::PointerTool;
use dynaclay::engine::{EngineConfig, HeadlessSink, Lockstep, ToolChoice, build_clay};
use dynaclay::field::BSplineLattice;
use dynaclay::io::ClaySpec;
use dynaclay::mesh::{BrickOctree, MeshFormat, SampleGrid, write_mesh};
use dynaclay::render::{Camera, NamedView};
use dynaclay::tools::Clay;
use dynaclay_devices::pointer::{PointerConfig, pointer_device};
use dynaclay_devices::{DeviceError, DeviceInfo, DeviceState, HapticDevice};
use glam::{Vec2, Vec3};

/// Device time per haptic tick, microseconds.
const TICK_US: u64 = 1000;

/// A pose device without force that plays a list of (device position, pressed) samples, one
/// per read, stamped with its own clock (one millisecond a read): what the window's pointer
/// hands the haptic loop, with no wall clock in it.
pub struct PathDevice {
    info: DeviceInfo,
    samples: Vec<(Vec3, bool)>,
    reads: u64,
    open: bool,
}

impl PathDevice {
    pub fn new(info: DeviceInfo, samples: Vec<(Vec3, bool)>) -> Self {
        assert!(!samples.is_empty());
        Self {
            info,
            samples,
            reads: 0,
            open: false,
        }
    }
}

impl HapticDevice for PathDevice {
    fn info(&self) -> DeviceInfo {
        self.info.clone()
    }

    fn open(&mut self) -> Result<(), DeviceError> {
        self.open = true;
        Ok(())
    }

    fn close(&mut self) -> Result<(), DeviceError> {
        self.open = false;
        Ok(())
    }

    fn is_open(&self) -> bool {
        self.open
    }

    fn read(&mut self) -> Result<DeviceState, DeviceError> {
        let i = (self.reads as usize).min(self.samples.len() - 1);
        let (position_m, pressed) = self.samples[i];
        self.reads += 1;
        Ok(DeviceState {
            position_m,
            orientation: None,
            velocity_m_per_s: Vec3::ZERO,
            buttons: u32::from(pressed),
            timestamp_us: self.reads * TICK_US,
            sequence: self.reads,
        })
    }

    fn write_force(&mut self, _force_n: Vec3) -> Result<(), DeviceError> {
        Ok(())
    }
}

/// The window's starting clay (the built-in script's block).
pub fn default_clay() -> BSplineLattice {
    build_clay(&ClaySpec::default()).unwrap()
}

/// A stroke along the clay's surface from `from` to `to` (points on or near the top face,
/// seen from above), pressed for `press_s` seconds after `hover_s` of hovering, then
/// released and left `settle_s` for the dynamics to come to rest.
#[derive(Clone, Copy, Debug)]
pub struct Stroke {
    pub from: Vec3,
    pub to: Vec3,
    pub hover_s: f32,
    pub press_s: f32,
    pub settle_s: f32,
}

impl Stroke {
    /// A one-second stroke from `from` to `to`.
    pub fn one_second(from: Vec3, to: Vec3) -> Self {
        Self {
            from,
            to,
            hover_s: 0.1,
            press_s: 1.0,
            settle_s: 0.5,
        }
    }
}

/// Where the window's pointer puts the tip for each millisecond of `stroke` on `field` (field
/// units), and whether it presses: the camera looks straight down on the lattice, and the
/// pointer aims through each surface point's pixel.
pub fn window_tips(field: &BSplineLattice, stroke: &Stroke) -> Vec<(Vec3, bool)> {
    let (lo, hi) = field.support();
    let camera = Camera::named(NamedView::Top, lo, hi);
    let density = dynaclay::field::MultiPatchField::new(field.clone());
    let (_device, handle) = pointer_device(PointerConfig::default());
    let map = config_for(field).map;
    let mut pointer = PointerTool::new(handle, map);
    let aspect = 1.0;
    let vp = camera.view_projection(aspect);
    let ndc = |x: Vec3| {
        let c = vp.project_point3(x);
        Vec2::new(c.x, c.y)
    };
    let ms = |s: f32| (s * 1000.0).round() as usize;
    let mut out = Vec::new();
    for _ in 0..ms(stroke.hover_s) {
        let pose = pointer.aim(&density, &camera, ndc(stroke.from), aspect, false, 1.0);
        out.push((pose.tip, false));
    }
    let n = ms(stroke.press_s);
    for i in 0..n {
        let u = i as f32 / (n - 1).max(1) as f32;
        let at = stroke.from.lerp(stroke.to, u);
        let pose = pointer.aim(&density, &camera, ndc(at), aspect, true, 1.0);
        assert!(pose.on_clay, "the stroke left the clay at {at}");
        out.push((pose.tip, true));
    }
    pointer.release();
    for _ in 0..ms(stroke.settle_s) {
        let pose = pointer.aim(&density, &camera, ndc(stroke.to), aspect, false, 1.0);
        out.push((pose.tip, false));
    }
    out
}

/// The engine settings the window starts with for `field` and the pointer.
pub fn config_for(field: &BSplineLattice) -> EngineConfig {
    let mut config = EngineConfig::for_field(field, &PointerConfig::default().info());
    config.haptic_rt_priority = None;
    config
}

/// The device samples (device metres, pressed) of `stroke` on `field` as the window hands
/// them over, one per millisecond, for an engine mapped by `config`.
pub fn device_samples(
    field: &BSplineLattice,
    config: &EngineConfig,
    stroke: &Stroke,
) -> Vec<(Vec3, bool)> {
    window_tips(field, stroke)
        .iter()
        .map(|&(tip, pressed)| (config.map.to_device(tip), pressed))
        .collect()
}

/// A lockstep engine on `field` with `config`, its device playing `samples`.
pub fn lockstep(
    field: &BSplineLattice,
    config: &EngineConfig,
    samples: Vec<(Vec3, bool)>,
) -> Lockstep {
    let device = PathDevice::new(PointerConfig::default().info(), samples);
    Lockstep::new(
        config,
        field.clone(),
        Box::new(device),
        Box::new(HeadlessSink::default()),
        1_000_000,
    )
    .unwrap()
}

/// Runs `stroke` on `field` holding `choice`, as the window would; returns the clay after.
pub fn run_stroke(field: &BSplineLattice, choice: ToolChoice, stroke: &Stroke) -> Clay {
    let config = config_for(field);
    let samples = device_samples(field, &config, stroke);
    let ticks = samples.len();
    let mut run = lockstep(field, &config, samples);
    run.commands()
        .send(dynaclay::engine::Command::SetTool(choice))
        .unwrap();
    for _ in 0..ticks {
        run.step();
    }
    run.finish().unwrap().session.clay
}

/// A mesh read back from an exported OBJ file.
pub struct Exported {
    pub positions: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
}

/// Meshes `clay`'s density (four cells a knot span, as the window does), writes it as OBJ in
/// `dir` and reads it back.
pub fn export(clay: &Clay, dir: &std::path::Path, name: &str) -> Exported {
    let base = clay.base();
    let mut octree = BrickOctree::new(SampleGrid::for_lattice(base, 4).unwrap());
    octree.rebuild(&clay.density);
    let path = dir.join(name);
    write_mesh(&path, &octree.weld(), MeshFormat::Obj).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    let mut positions = Vec::new();
    let mut triangles = Vec::new();
    for line in text.lines() {
        if let Some(l) = line.strip_prefix("v ") {
            let v: Vec<f32> = l.split_whitespace().map(|x| x.parse().unwrap()).collect();
            positions.push(Vec3::new(v[0], v[1], v[2]));
        } else if let Some(l) = line.strip_prefix("f ") {
            let f: Vec<u32> = l
                .split_whitespace()
                .map(|x| x.split('/').next().unwrap().parse::<u32>().unwrap() - 1)
                .collect();
            assert_eq!(f.len(), 3, "a face that is not a triangle: {line}");
            triangles.push([f[0], f[1], f[2]]);
        }
    }
    Exported {
        positions,
        triangles,
    }
}

impl Exported {
    /// Highest vertex within `r` of the vertical line through (x, z).
    pub fn top_at(&self, x: f32, z: f32, r: f32) -> f32 {
        self.positions
            .iter()
            .filter(|v| (v.x - x).hypot(v.z - z) < r)
            .map(|v| v.y)
            .fold(f32::NEG_INFINITY, f32::max)
    }

    /// The enclosed volume (divergence theorem over the closed mesh), field units³.
    pub fn volume(&self) -> f32 {
        self.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| self.positions[i as usize]);
                a.dot(b.cross(c)) / 6.0
            })
            .sum()
    }

    /// The number of connected pieces (vertices joined by triangle edges).
    pub fn components(&self) -> usize {
        let n = self.positions.len();
        let mut parent: Vec<usize> = (0..n).collect();
        fn find(p: &mut [usize], mut i: usize) -> usize {
            while p[i] != i {
                p[i] = p[p[i]];
                i = p[i];
            }
            i
        }
        for t in &self.triangles {
            for k in 0..3 {
                let (a, b) = (
                    find(&mut parent, t[k] as usize),
                    find(&mut parent, t[(k + 1) % 3] as usize),
                );
                if a != b {
                    parent[a] = b;
                }
            }
        }
        let mut roots: Vec<usize> = (0..n).map(|i| find(&mut parent, i)).collect();
        roots.sort_unstable();
        roots.dedup();
        roots.len()
    }
}
