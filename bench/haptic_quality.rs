//! Haptic quality benchmark: how stiff the clay can feel before the arm buzzes, how smooth and
//! how passive it is, and how late the force follows the tip — the touch renderer
//! (`dynaclay::haptics::ForceRenderer`: proxy, shaping, passivity), the same renderer with
//! tool-shaped contact (the palette's default sphere, radius 0.25, resting on the clay with
//! its point shell), and a plain penalty wall (`F = k · depth · n`, nothing else) on the same
//! simulated arm; then the renderer's tick cost with each contact, the largest tool the
//! palette makes (a sphere of radius 1) included.
//!
//! Usage: `cargo bench --bench haptic_quality` (no arguments). Deterministic: the simulated
//! arm runs on its own clock, so the figures do not depend on the machine's load.
//!
//! The scene: the default 20³ block on the simulated arm; the hand comes down onto the top
//! face's centre to a target 10 mm below it, holds 1.1 s with a ±1 mm, 2 Hz sideways wobble,
//! and leaves. The arm's grip is 300 N/m and 2 N·s/m; its position is reported with 5 µm of
//! noise. For each stiffness the run is *stable* when, over the hold, the force's ripple (its
//! standard deviation about a 20 ms moving mean) is at most 1% of the mean force (so a
//! buzz counts, the slow wobble does not) and the device gives back no more energy over
//! the press–release than the hand put in (within 1% of the peak). Reported per rate:
//! - the highest stable stiffness, N/m (doubling from 250 N/m);
//! - at the device's rated stiffness (3 kN/m): ripple, energy balance, and the force latency,
//!   the lag in ticks that best aligns the force with the reported depth during the hold.
//!
//! With tool-shaped contact the hand's path is lifted by the tool's reach below its centre, so
//! the tool rests on the face where the point rests in the other runs.
//!
//! Tick cost: the wall-clock time of `ForceRenderer::render` on each tick of the hold at 1 kHz
//! and 3 kN/m, p50 and p99 (this one is timed, so it depends on the machine's load).
//!
//! Where it is optimistic: a flat face and a point-mass arm; real arms have structural modes.
//! Where it is pessimistic: the grip's damping is low for a human hand.

use dynaclay::engine::{CLAY_SPACING, EngineConfig, build_clay};
use dynaclay::field::MultiPatchField;
use dynaclay::haptics::{FeltInput, FeltTool, ForceRenderer, StrokeGeometry, ToolShell};
use dynaclay::io::{ClayShape, ClaySpec};
use dynaclay::tools::ToolShape;
use dynaclay_devices::{
    Fault, FaultKind, HapticDevice, Interpolation, SimArmConfig, SimulatedArm, Trajectory, Waypoint,
};
use glam::Vec3;

/// The top face of the default block, device metres.
const TOP_Y_M: f32 = 0.05;

#[allow(clippy::large_enum_variant)] // a plain copyable value per run
#[derive(Clone, Copy, PartialEq)]
enum Renderer {
    Proxy,
    /// The renderer with a geometric tool of this shell resting on the clay.
    Tool(ToolShell),
    PenaltyWall,
}

impl Renderer {
    fn name(&self) -> &'static str {
        match self {
            Self::Proxy => "proxy + shaping + passivity",
            Self::Tool(_) => "tool-shaped contact (sphere r 0.25)",
            Self::PenaltyWall => "plain penalty wall",
        }
    }

    /// How far the hand's path is lifted, device metres: the tool's reach below its centre.
    fn lift_m(&self, field_per_m: f32) -> f32 {
        match self {
            Self::Tool(shell) => {
                let low = shell.points().iter().map(|p| p.y).fold(0.0, f32::min);
                -low / field_per_m
            }
            _ => 0.0,
        }
    }
}

fn sphere_shell(radius_fu: f32) -> ToolShell {
    ToolShell::of(&ToolShape::Sphere { radius_fu }).expect("a sphere has a shell")
}

struct Run {
    ripple: f32,
    mean_n: f32,
    absorbed_j: f64,
    peak_j: f64,
    latency_ticks: i32,
    /// Render time per tick over the hold, microseconds, sorted.
    tick_us: Vec<f64>,
}

impl Run {
    fn stable(&self) -> bool {
        self.mean_n > 0.1 && self.ripple <= 0.01 && self.absorbed_j >= -0.01 * self.peak_j
    }
}

fn trajectory(lift_m: f32) -> Trajectory {
    let top = TOP_Y_M + lift_m;
    let mut w = vec![
        Waypoint::new(0.0, Vec3::new(0.0, top + 0.03, 0.0)),
        Waypoint::new(0.3, Vec3::new(0.0, top + 0.01, 0.0)),
        Waypoint::new(0.6, Vec3::new(0.0, top - 0.01, 0.0)),
    ];
    for i in 0..10 {
        let x = if i % 2 == 0 { 0.001 } else { -0.001 };
        w.push(Waypoint::new(
            0.7 + 0.125 * f64::from(i),
            Vec3::new(x, top - 0.01, 0.0),
        ));
    }
    w.push(Waypoint::new(2.2, Vec3::new(0.0, top + 0.03, 0.0)));
    w.push(Waypoint::new(2.6, Vec3::new(0.0, top + 0.04, 0.0)));
    Trajectory::new(w, Interpolation::Smooth).expect("trajectory")
}

fn run(
    field: &MultiPatchField,
    config: &EngineConfig,
    renderer: Renderer,
    stiffness_n_per_m: f32,
    step_us: u64,
) -> Run {
    let arm_config = SimArmConfig {
        step_us,
        hand_stiffness_n_per_m: 300.0,
        hand_damping_n_s_per_m: 2.0,
        faults: vec![Fault {
            start_s: 0.0,
            duration_s: f64::INFINITY,
            kind: FaultKind::Noise { std_m: 5e-6 },
        }],
        ..SimArmConfig::default()
    };
    let max_n = arm_config.info.max_force_n;
    let lift_m = renderer.lift_m(config.map.field_per_m);
    let mut arm = SimulatedArm::new(arm_config, trajectory(lift_m));
    arm.open().expect("arm opens");
    let mut haptics = config.haptics;
    haptics.touch_stiffness_n_per_m = stiffness_n_per_m;
    let mut proxy = ForceRenderer::new(haptics);
    let stroke = StrokeGeometry::default();
    let map = config.map;
    let ticks = (2.6e6 / step_us as f64) as usize;
    let hold = ((0.9e6 / step_us as f64) as usize)..((1.8e6 / step_us as f64) as usize);
    let (mut absorbed, mut peak) = (0.0f64, 0.0f64);
    let mut last_x = arm.effector_position_m();
    let mut sent = Vec3::ZERO;
    let (mut forces, mut depths) = (Vec::new(), Vec::new());
    let mut tick_us = Vec::with_capacity(hold.len());
    for tick in 0..ticks {
        let state = arm.read().expect("arm reads");
        // True work at the port over the interval that just ended.
        let x = arm.effector_position_m();
        absorbed -= f64::from(arm.motor_force_n().dot(x - last_x));
        peak = peak.max(absorbed);
        last_x = x;
        let force = match renderer {
            Renderer::Proxy | Renderer::Tool(_) => {
                let tool = match renderer {
                    Renderer::Tool(shell) => FeltTool::Geometric(Some(shell)),
                    _ => FeltTool::Geometric(None),
                };
                let started = std::time::Instant::now();
                let felt = proxy
                    .render(&FeltInput {
                        field,
                        tip: map.to_field(state.position_m),
                        position_m: state.position_m,
                        velocity_m_per_s: state.velocity_m_per_s,
                        time_us: state.timestamp_us,
                        field_per_m: map.field_per_m,
                        force_n_per_reaction: map.force_n_per_reaction,
                        stroke_active: false,
                        tool,
                        stroke: &stroke,
                        fade: 1.0,
                        saturation_n: max_n,
                        sent_n: sent,
                        rotation: glam::Quat::IDENTITY,
                        tool_contact: true,
                    })
                    .force_n;
                if hold.contains(&tick) {
                    tick_us.push(started.elapsed().as_secs_f64() * 1e6);
                }
                felt
            }
            Renderer::PenaltyWall => {
                let depth = (TOP_Y_M - state.position_m.y).max(0.0);
                Vec3::Y * (stiffness_n_per_m * depth)
            }
        };
        let force = force.clamp_length_max(max_n);
        arm.write_force(force).expect("arm takes the force");
        sent = force;
        if hold.contains(&tick) {
            forces.push(force.y);
            depths.push(TOP_Y_M + lift_m - state.position_m.y);
        }
    }
    let mean_n = forces.iter().sum::<f32>() / forces.len() as f32;
    // Ripple about a 20 ms moving mean: the wobble is slow, a buzz is not.
    let window = (20_000 / step_us) as usize;
    let mut ripple_sq = 0.0f32;
    for i in window..forces.len() - window {
        let local = forces[i - window..i + window].iter().sum::<f32>() / (2 * window) as f32;
        ripple_sq += (forces[i] - local).powi(2);
    }
    let ripple = (ripple_sq / (forces.len() - 2 * window) as f32).sqrt() / mean_n.abs().max(1e-6);
    Run {
        ripple,
        mean_n,
        absorbed_j: absorbed,
        peak_j: peak,
        latency_ticks: best_lag(&depths, &forces),
        tick_us: {
            tick_us.sort_by(f64::total_cmp);
            tick_us
        },
    }
}

/// The lag (ticks, 0..=20) at which the force best correlates with the depth.
fn best_lag(depth: &[f32], force: &[f32]) -> i32 {
    let mean = |v: &[f32]| v.iter().sum::<f32>() / v.len() as f32;
    let (md, mf) = (mean(depth), mean(force));
    let mut best = (f32::MIN, 0);
    for lag in 0..=20usize {
        let n = depth.len() - lag;
        let c: f32 = (0..n)
            .map(|i| (depth[i] - md) * (force[i + lag] - mf))
            .sum::<f32>()
            / n as f32;
        if c > best.0 {
            best = (c, lag as i32);
        }
    }
    best.1
}

fn main() {
    let field = build_clay(&ClaySpec {
        shape: ClayShape::Block,
        resolution: 20,
        ..ClaySpec::default()
    })
    .expect("clay");
    let arm = SimArmConfig::default();
    let mut config = EngineConfig::for_field(&field, &arm.info);
    let density = MultiPatchField::new(field.clone());
    config.safety.soft_start_s = 0.0;
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    println!(
        "haptic_quality: 20³ block ({CLAY_SPACING} field units per knot), simulated arm, grip \
         300 N/m 2 N·s/m, 5 µm noise; load average {}",
        load.trim()
    );
    println!(
        "| rate | renderer | highest stable stiffness | at 3 kN/m: ripple | energy balance (net / peak) | force latency |"
    );
    println!("| --- | --- | --- | --- | --- | --- |");
    for (rate, step_us) in [("1 kHz", 1000u64), ("4 kHz", 250)] {
        let mut highest = [0.0f32; 3];
        for (slot, renderer) in [
            Renderer::Proxy,
            Renderer::Tool(sphere_shell(0.25)),
            Renderer::PenaltyWall,
        ]
        .into_iter()
        .enumerate()
        {
            let mut k = 250.0f32;
            let mut sweep = String::new();
            while k <= 256_000.0 {
                let r = run(&density, &config, renderer, k, step_us);
                sweep += &format!(
                    " {k:.0}: ripple {:.2}%, net {:+.3} mJ{};",
                    r.ripple * 100.0,
                    r.absorbed_j * 1e3,
                    if r.stable() { "" } else { " (unstable)" }
                );
                if r.stable() {
                    highest[slot] = k;
                }
                k *= 2.0;
            }
            eprintln!("sweep, {rate}:{sweep}");
            let at = run(&density, &config, renderer, 3000.0, step_us);
            println!(
                "| {rate} | {} | {:.0} N/m | {:.2}% of {:.2} N | {:+.3} / {:.2} mJ | {} ticks |",
                renderer.name(),
                highest[slot],
                at.ripple * 100.0,
                at.mean_n,
                at.absorbed_j * 1e3,
                at.peak_j * 1e3,
                at.latency_ticks
            );
        }
        for (slot, what) in [(0, "proxy"), (1, "tool-shaped contact")] {
            let ratio = if highest[2] > 0.0 {
                format!("{:.1}×", highest[slot] / highest[2])
            } else {
                "the wall is never stable".to_owned()
            };
            println!("| {rate} | ratio {what} / wall | {ratio} | | | |");
        }
    }

    println!();
    println!("Render tick cost at 1 kHz, 3 kN/m, over the hold (timed on this machine):");
    println!("| contact | p50 | p99 | max |");
    println!("| --- | --- | --- | --- |");
    for (what, renderer) in [
        ("point proxy", Renderer::Proxy),
        (
            "sphere r 0.25 (palette default)",
            Renderer::Tool(sphere_shell(0.25)),
        ),
        (
            "sphere r 1 (largest the palette makes)",
            Renderer::Tool(sphere_shell(1.0)),
        ),
        (
            "box 0.25 × 0.15 × 0.15 (palette default box)",
            Renderer::Tool(
                ToolShell::of(&ToolShape::Box {
                    half_extents_fu: Vec3::new(0.25, 0.15, 0.15),
                })
                .expect("a box has a shell"),
            ),
        ),
    ] {
        let r = run(&density, &config, renderer, 3000.0, 1000);
        let at = |q: f64| r.tick_us[((r.tick_us.len() - 1) as f64 * q).round() as usize];
        assert!(
            r.mean_n > 0.1 && !r.tick_us.is_empty(),
            "{what}: the hold was in contact"
        );
        println!(
            "| {what} | {:.1} µs | {:.1} µs | {:.1} µs |",
            at(0.5),
            at(0.99),
            r.tick_us.last().copied().unwrap_or(0.0)
        );
    }
}
