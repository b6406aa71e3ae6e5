//! Constrained particles on a 64³ sphere clay (radius 1.575, area ≈ 31 world units²):
//! the PDS against naive all-pairs neighbour search in the same run.
//!
//! Three groups:
//! - `particles_step`: one step of N = 1k, 10k and 20k particles already spread over the
//!   surface (PDS at every N; all-pairs at 1k and 10k — at 20k one all-pairs step takes about
//!   four times the 10k one, which this shared machine cannot afford in every run; the steps
//!   are identical, `tests/particles.rs` checks it), and the PDS step with curvature ratio 4.
//! - `particles_settle`: a random start (seeded, points projected onto the surface) settled by
//!   `SETTLE_STEPS` steps plus the final projection, PDS at 1k, 10k and 20k and (at 1k)
//!   all-pairs. Seeding is outside the timing; each iteration clones the seeded system.
//! - `particles_follow`: one update of the [`ParticleFollower`] as the graphics loop calls it
//!   on a changed clay (`FOLLOW_STEPS` steps, the projection, and the publication of positions,
//!   normals and radii), at N = 1k, 10k and 20k (the GUI's slider goes to 20 000), on particles
//!   already settled by earlier updates.
//!
//! Before timing, the run prints how many steps a random start needs until the
//! nearest-neighbour coefficient of variation falls below 0.15 (random points: ≈ 0.52), so
//! the settle time is read against the quality it buys. Run with
//! `cargo bench --bench particles`.

use std::hint::black_box;
use std::time::Duration;

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use dynaclay::engine::{HeadlessSink, build_clay};
use dynaclay::field::{BSplineLattice, MultiPatchField};
use dynaclay::io::{ClayShape, ClaySpec};
use dynaclay::particles::{
    NeighbourSearch, ParticleFollower, ParticleParams, ParticleSystem, nearest_neighbour_distances,
};

/// Steps in the timed settle.
const SETTLE_STEPS: usize = 10;

/// Steps per follower update: the GUI's budget (`PARTICLE_STEPS_PER_UPDATE` in
/// `src/app/bridge.rs`).
const FOLLOW_STEPS: usize = 2;

/// The particle counts timed; 20 000 is the top of the GUI's slider.
const COUNTS: [usize; 3] = [1_000, 10_000, 20_000];

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
    for n in COUNTS {
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
    for n in COUNTS {
        let mut spread = seeded(&field, n);
        spread.settle(&field, 40);
        let searches: &[(&str, NeighbourSearch)] = if n <= 10_000 {
            &[
                ("pds", NeighbourSearch::Pds),
                ("all_pairs", NeighbourSearch::AllPairs),
            ]
        } else {
            &[("pds", NeighbourSearch::Pds)]
        };
        for &(name, search) in searches {
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
        // With curvature bias (ratio 4): the curvature, its smoothing and the pull added.
        let mut params = ParticleParams::new(n);
        params.curvature_ratio = 4.0;
        let mut s = ParticleSystem::new(params).expect("n > 0");
        s.from_positions(spread.positions(), spread.sigmas()[0]);
        s.settle(&field, 20);
        group.bench_function(BenchmarkId::new("pds_curvature_ratio_4", n), |b| {
            b.iter(|| {
                black_box(
                    s.step(&field, ParticleSystem::DEFAULT_DT)
                        .expect("valid dt"),
                );
            });
        });
    }
    group.finish();

    let mut group = c.benchmark_group("particles_settle");
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(8));
    for n in COUNTS {
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

    let clay = MultiPatchField::new(field.clone());
    let mut group = c.benchmark_group("particles_follow");
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(5));
    for n in COUNTS {
        let (mut follower, _view) =
            ParticleFollower::new(HeadlessSink::default(), n, FOLLOW_STEPS).expect("n > 0");
        // The first update seeds; twenty more settle (40 steps), as after a pause in sculpting.
        for _ in 0..21 {
            follower.follow(&clay);
        }
        group.bench_function(BenchmarkId::new("update", n), |b| {
            b.iter(|| follower.follow(black_box(&clay)));
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
