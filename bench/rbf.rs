//! The RBF of the sculpt (Zhang et al. §5.3): the dense solve for 1k, 3k and 5k centres and the
//! cost of evaluating it per point against the B-spline field it came from.
//!
//! Centres: settled particles on a 64³ sphere clay (radius 1.575), three constraints each
//! (surface, inner, outer), so `k` centres come from `k/3` particles. The solve is nalgebra's
//! dense LU in f64 (`⅔ (k+4)³` flops), timed once per size after the particles are settled
//! (the setup is outside the timing); evaluation is timed over 10 000 points near the surface,
//! median of five passes. Not criterion: one 5k solve takes about a minute on this machine.
//! Run with `cargo bench --bench rbf`.

use std::hint::black_box;
use std::time::Instant;

use dynaclay::engine::build_clay;
use dynaclay::io::{ClayShape, ClaySpec};
use dynaclay::particles::{ParticleParams, ParticleSystem};
use dynaclay::rbf::{RbfOptions, fit_surface};
use glam::Vec3;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
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
