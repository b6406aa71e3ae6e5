//! The RBF of the sculpt (Zhang et al. §5.3): the dense solve for 1k, 3k and 5k centres and the
//! cost of evaluating it per point against the B-spline field it came from.
//!
//! Centres: settled particles on a 64³ sphere clay (radius 1.575), three constraints each
//! (surface, inner, outer), so `k` centres come from `k/3` particles. The solve is nalgebra's
//! dense LU in f64 (`⅔ (k+4)³` flops), timed once per size after the particles are settled
//! (the setup is outside the timing); evaluation is timed over 10 000 points near the surface,
//! median of five passes. Not criterion: one 5k solve takes about a minute on this machine.
//! Run with `cargo bench --bench rbf`; `cargo bench --bench rbf -- compact` runs only the
//! second part: the compact RBF clay's per-stroke re-interpolation (Zhang et al. §5.4) at the
//! default `N` = 600 on the default 24³ block, after a contact dent of the engine's tool: warm
//! particle steps, the 1800-centre solve and the fit of `I` onto the lattice, median of five
//! strokes, with the process's CPU time per stroke (`/proc/self/stat`).

use std::hint::black_box;
use std::time::Instant;

use dynaclay::engine::build_clay;
use dynaclay::io::{ClayShape, ClaySpec};
use dynaclay::particles::{ParticleParams, ParticleSystem};
use dynaclay::rbf::{CompactClay, CompactSettings, RbfOptions, fit_surface};
use dynaclay::tools::{
    ApplyOptions, Clay, ContactParams, GeometricTool, ToolAction, ToolPose, ToolShape, apply_tool,
};
use glam::Vec3;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// CPU time of this process (all threads, user and system), seconds, from `/proc/self/stat`
/// (10 ms ticks).
fn cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // Fields after the parenthesised name; utime and stime are the 14th and 15th overall.
    let rest = stat.rsplit_once(')')?.1;
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks = f.get(11)?.parse::<f64>().ok()? + f.get(12)?.parse::<f64>().ok()?;
    Some(ticks / 100.0)
}

/// The compact RBF clay's cost per stroke at the default `N`.
fn compact() {
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    let settings = CompactSettings::default();
    println!(
        "\ncompact RBF clay: default 24³ block, N = {}; load average {}",
        settings.particles,
        load.trim()
    );
    let lattice = build_clay(&ClaySpec::default()).expect("the clay fits");
    let mut compact = CompactClay::new(settings).expect("the default N");
    let t = Instant::now();
    let first = compact.reinterpolate(&lattice).expect("I⁰");
    println!(
        "I⁰ (seeded, {} settle steps): {:.2} s, {} centres",
        settings.settle_steps,
        t.elapsed().as_secs_f64(),
        first.report.centres
    );
    let mut clay = Clay::single(first.lattice);
    let tool = GeometricTool {
        shape: ToolShape::Sphere { radius_fu: 0.2 },
        action: ToolAction::Contact(ContactParams {
            alpha: -1.0,
            rate_per_s: 2.0,
        }),
        falloff_fu: 0.1,
    };
    let (mut wall, mut cpu, mut steps) = (Vec::new(), Vec::new(), Vec::new());
    // The block's top face is at y = 1.725; dents along it.
    for k in 0..5 {
        let at = Vec3::new(0.8 + 0.15 * k as f32, 1.725, 1.15);
        apply_tool(
            &mut clay,
            &tool,
            &ToolPose::at(at),
            0.3,
            &ApplyOptions::default(),
            None,
        )
        .expect("the dent");
        let (t, c) = (Instant::now(), cpu_seconds());
        let r = compact.reinterpolate(clay.base()).expect("re-interpolated");
        wall.push(t.elapsed().as_secs_f64());
        cpu.push(cpu_seconds().zip(c).map_or(f64::NAN, |(b, a)| b - a));
        steps.push(r.particle_steps);
        assert_eq!(r.report.centres, first.report.centres);
        clay = Clay::single(r.lattice);
    }
    println!("| N | centres | per stroke (median of 5) | CPU per stroke | particle steps |");
    println!("| --- | --- | --- | --- | --- |");
    println!(
        "| {} | {} | {:.2} s | {:.2} s | {:?} |",
        settings.particles,
        first.report.centres,
        median(wall),
        median(cpu),
        steps
    );
}

fn main() {
    compact();
    if std::env::args().any(|a| a == "compact") {
        return;
    }
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    println!("rbf: 64³ sphere clay; load average {}", load.trim());
    let field = build_clay(&ClaySpec {
        shape: ClayShape::Sphere,
        resolution: 64,
        session: None,
    })
    .expect("the clay fits");
    println!("| centres | solve (one run) | RBF value per point | B-spline value per point |");
    println!("| --- | --- | --- | --- |");
    for centres in [1_000usize, 3_000, 5_000] {
        let n = centres / 3;
        let mut particles = ParticleSystem::new(ParticleParams::new(n)).expect("n > 0");
        particles.seed_random(&field, n, 3).expect("a surface");
        particles.settle(&field, 40);
        let options = RbfOptions {
            max_centres: 6_000,
            ..RbfOptions::with_offset(0.05)
        };
        let start = Instant::now();
        let (rbf, report) =
            fit_surface(&field, particles.positions(), &options).expect("the system solves");
        let solve = start.elapsed().as_secs_f64();
        // Points near the surface: the particles of a second, smaller set, pushed out a little.
        let probes: Vec<Vec3> = particles
            .positions()
            .iter()
            .cycle()
            .take(10_000)
            .enumerate()
            .map(|(i, p)| *p + Vec3::splat(0.01 * (i % 7) as f32))
            .collect();
        let mut rbf_times = Vec::new();
        let mut spline_times = Vec::new();
        for _ in 0..5 {
            let t = Instant::now();
            let mut s = 0.0f64;
            for p in &probes {
                s += rbf.value(p.as_dvec3());
            }
            black_box(s);
            rbf_times.push(t.elapsed().as_secs_f64() / probes.len() as f64);
            let t = Instant::now();
            let mut s = 0.0f32;
            for p in &probes {
                s += field.value(*p);
            }
            black_box(s);
            spline_times.push(t.elapsed().as_secs_f64() / probes.len() as f64);
        }
        println!(
            "| {} | {:.2} s | {:.1} µs | {:.3} µs |",
            report.centres,
            solve,
            median(rbf_times) * 1e6,
            median(spline_times) * 1e6
        );
    }
}
