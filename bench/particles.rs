//! Constrained particles on a 64³ sphere clay (radius 1.575, area ≈ 31 world units²):
//! the PDS against naive all-pairs neighbour search in the same run.
//!
//! Two groups:
//! - `particles_step`: one step of N = 1k and 10k particles already spread over the surface
//!   (PDS and all-pairs; the steps are identical, `tests/particles.rs` checks it).
//! - `particles_settle`: a random start (seeded, points projected onto the surface) settled by
//!   `SETTLE_STEPS` steps plus the final projection, PDS and (at 1k) all-pairs. Seeding is
//!   outside the timing; each iteration clones the seeded system.
//!
//! Before timing, the run prints how many steps a random start needs until the
//! nearest-neighbour coefficient of variation falls below 0.15 (random points: ≈ 0.52), so
//! the settle time is read against the quality it buys. Run with
//! `cargo bench --bench particles`.

use std::hint::black_box;
use std::time::Duration;

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use dynaclay::engine::build_clay;
use dynaclay::field::BSplineLattice;
use dynaclay::io::{ClayShape, ClaySpec};
use dynaclay::particles::{
    NeighbourSearch, ParticleParams, ParticleSystem, nearest_neighbour_distances,
};

/// Steps in the timed settle.
const SETTLE_STEPS: usize = 10;

fn clay() -> BSplineLattice {
    build_clay(&ClaySpec {
        shape: ClayShape::Sphere,
        resolution: 64,
        session: None,
    })
    .expect("the clay fits")
}

fn seeded(field: &BSplineLattice, n: usize) -> ParticleSystem {
    let mut s = ParticleSystem::new(ParticleParams::new(n)).expect("n > 0");
    s.seed_random(field, n, 11)
        .expect("the sphere has a surface");
    s
}

fn nn_cv(s: &ParticleSystem) -> f32 {
    let radius = 8.0 * s.sigmas().iter().copied().fold(0.0f32, f32::max);
    let d = nearest_neighbour_distances(s.positions(), radius);
    let n = d.len() as f32;
    let mean = d.iter().sum::<f32>() / n;
    let var = d.iter().map(|v| (v - mean) * (v - mean)).sum::<f32>() / n;
    var.sqrt() / mean
}

fn convergence(field: &BSplineLattice) {
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    println!("particles: 64³ sphere clay; load average {}", load.trim());
    for n in [1_000usize, 10_000] {
        let mut s = seeded(field, n);
        let cv0 = nn_cv(&s);
        let mut reached = None;
        let mut cv_at_settle = 0.0;
        for step in 1..=200 {
            s.step(field, ParticleSystem::DEFAULT_DT)
                .expect("dt is valid");
            if step == SETTLE_STEPS {
                cv_at_settle = nn_cv(&s);
            }
            if reached.is_none() && step % 5 == 0 && nn_cv(&s) < 0.15 {
                reached = Some(step);
            }
            if reached.is_some() && step >= SETTLE_STEPS {
                break;
            }
        }
        println!(
            "N = {n}: NN CV {cv0:.3} at the random start, {cv_at_settle:.3} after {SETTLE_STEPS} \
             steps; below 0.15 after {reached:?} steps (checked every 5); count {} PDS level k = {}",
            s.len(),
            s.pds_level()
        );
    }
}

fn bench(c: &mut Criterion) {
    let field = clay();
    convergence(&field);

    let mut group = c.benchmark_group("particles_step");
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(5));
    for n in [1_000usize, 10_000] {
        let mut spread = seeded(&field, n);
        spread.settle(&field, 40);
        for (name, search) in [
            ("pds", NeighbourSearch::Pds),
            ("all_pairs", NeighbourSearch::AllPairs),
        ] {
            let mut s = spread.clone();
            s.set_search(search);
            group.bench_function(BenchmarkId::new(name, n), |b| {
                b.iter(|| {
                    black_box(
                        s.step(&field, ParticleSystem::DEFAULT_DT)
                            .expect("valid dt"),
                    );
                });
            });
        }
    }
    group.finish();

    let mut group = c.benchmark_group("particles_settle");
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(8));
    for n in [1_000usize, 10_000] {
        let start = seeded(&field, n);
        let searches: &[(&str, NeighbourSearch)] = if n <= 1_000 {
            &[
                ("pds", NeighbourSearch::Pds),
                ("all_pairs", NeighbourSearch::AllPairs),
            ]
        } else {
            &[("pds", NeighbourSearch::Pds)]
        };
        for &(name, search) in searches {
            group.bench_function(BenchmarkId::new(name, n), |b| {
                b.iter_batched(
                    || {
                        let mut s = start.clone();
                        s.set_search(search);
                        s
                    },
                    |mut s| black_box(s.settle(&field, SETTLE_STEPS)),
                    criterion::BatchSize::LargeInput,
                );
            });
        }
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
