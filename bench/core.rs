//! Core benchmarks: one simulation step at Hua & Qin Table 1 sizes and beyond (32³ and 64³
//! also split over two threads), the engine's 11³/21³ step on a single patch against the same
//! step on a detail patch of a two-level clay (eq. (3): the forces integrated over the sum),
//! the same engine-shaped step on a detail patch at levels 1, 2 and 3 against the base (level
//! 0) in one run (`step_levels`), one field evaluation with gradient, one 4-point force
//! integral, and the lane-blocked Gram solve against the plain line-by-line sweep.
//!
//! Run: `cargo bench --bench core -- --warm-up-time 1 --measurement-time 3`.
//! Optimistic where noted: the step benches keep one tool force active on a sphere; a step
//! with no force skips nothing else, so it costs the same within noise. Every timed step's
//! result is checked: failures are counted in the loop and the benchmark fails at the end if
//! any step failed. The line-by-line Gram solve gets the same right-hand side every iteration
//! (a fresh copy made outside the timing).

use std::hint::black_box;

use criterion::{BatchSize, BenchmarkId, Criterion, criterion_group, criterion_main};
use dynaclay::dynamics::{
    Distribution, Material, RegionState, Simulator, StepParams, ToolForce, force_integral,
};
use dynaclay::engine::FieldUpdate;
use dynaclay::field::{
    AllocatingSpares, BSplineLattice, CoeffBox, KronScratch, MultiPatchField, OtherPatches,
    Primitive, RegionSnapshot, SpareBrick, SpareGroup, SpareStorage, lattice_from_primitive,
};
use glam::Vec3;

/// A sphere on a lattice of `n + 4` coefficients per axis; the region is the central `n³`
/// coefficients with `m³` mass points.
fn setup(n: usize, m: usize) -> (BSplineLattice, RegionState, ToolForce) {
    let dims = [n + 4; 3];
    let spacing = 1.0 / (n + 3) as f32;
    let centre = Vec3::splat(0.5);
    let sphere = Primitive::Sphere {
        centre,
        radius: 0.3,
    };
    let lattice = lattice_from_primitive(dims, spacing, Vec3::ZERO, &sphere, 2.0 * spacing, 2)
        .expect("sphere fits");
    let region = CoeffBox {
        min: [2; 3],
        max: [n + 1; 3],
    };
    let state = RegionState::new(&lattice, region, [m; 3], Material::PLASTIC).expect("region");
    let force = ToolForce {
        start: centre + Vec3::X * 0.3,
        end: centre + Vec3::X * 0.36,
        distribution: Distribution::Gaussian,
        radius: 2.0 * spacing,
        gain: 1e3,
    };
    (lattice, state, force)
}

fn step(c: &mut Criterion) {
    let mut group = c.benchmark_group("step");
    for (n, m) in [
        (5, 5),
        (5, 10),
        (10, 10),
        (10, 15),
        (15, 15),
        (32, 32),
        (64, 64),
        // The engine's regions: two mass points per knot span.
        (11, 21),
        (16, 31),
        (32, 63),
    ] {
        let threads: &[usize] = if n >= 32 { &[1, 2] } else { &[1] };
        for &threads in threads {
            let (mut lattice, mut state, force) = setup(n, m);
            let mut sim = Simulator::new(StepParams {
                threads,
                ..StepParams::default()
            });
            let mut snap = RegionSnapshot::default();
            let id = if threads == 1 {
                format!("{n}^3/{m}^3")
            } else {
                format!("{n}^3/{m}^3/{threads}_threads")
            };
            let mut failures = 0u64;
            group.bench_function(BenchmarkId::from_parameter(&id), |b| {
                b.iter(|| {
                    let r = sim.step(&mut state, &mut lattice, &[force], &mut snap);
                    failures += u64::from(black_box(r.is_err()));
                });
            });
            assert_eq!(failures, 0, "step {id}: {failures} timed steps failed");
        }
    }
    group.finish();
}

/// The engine's region (11³ coefficients, two mass points per span) stepped on a single
/// patch, and on a level-1 detail patch of a two-level clay whose base is the same sphere: the
/// step's own work is the same shape; the difference is the forces' line integrals over the
/// sum of both patches.
fn step_layered(c: &mut Criterion) {
    let mut group = c.benchmark_group("step_two_level");
    let (n, m) = (11, 21);
    let (mut lattice, mut state, force) = setup(n, m);
    let mut sim = Simulator::new(StepParams::default());
    let mut snap = RegionSnapshot::default();
    let mut failures = 0u64;
    group.bench_function("single_patch/11^3/21^3", |b| {
        b.iter(|| {
            let r = sim.step(&mut state, &mut lattice, &[force], &mut snap);
            failures += u64::from(black_box(r.is_err()));
        });
    });
    assert_eq!(failures, 0, "single patch: {failures} timed steps failed");

    let (base, _, force) = setup(n, m);
    let mut clay = MultiPatchField::new(base);
    let at = force.start;
    let half = Vec3::splat(8.0 * clay.base().spacing);
    let detail = clay.refine(at - half, at + half, 1).expect("detail patch");
    let dims = clay.patches[detail].lattice.dims;
    let region = CoeffBox {
        min: dims.map(|d| (d - n) / 2),
        max: dims.map(|d| (d - n) / 2 + n - 1),
    };
    let mut state = RegionState::new(
        &clay.patches[detail].lattice,
        region,
        [m; 3],
        Material::PLASTIC.for_volume_ratio(0.125),
    )
    .expect("region on the detail patch");
    let mut sim = Simulator::new(StepParams::default());
    let mut failures = 0u64;
    group.bench_function("detail_patch/11^3/21^3", |b| {
        b.iter(|| {
            let (lattice, others): (&mut BSplineLattice, OtherPatches<'_>) =
                clay.split_patch_mut(detail).expect("the detail patch");
            let r = sim.step_layered(&mut state, lattice, others, &[force], None, &mut snap);
            failures += u64::from(black_box(r.is_err()));
        });
    });
    assert_eq!(failures, 0, "detail patch: {failures} timed steps failed");
    group.finish();
}

/// The engine-shaped region (11³ coefficients, two mass points per knot span) on the base of a
/// clay (level 0) and on a detail patch of it at levels 1, 2 and 3, in one run: the engine
/// gives a region as many knot spans of its own patch at every level (so the step's own passes
/// are the same shape), its material scaled by the mass point's volume. The tool force is
/// timed two ways on each detail patch: scaled with the patch (radius two of its spans, as on
/// the base: the same work but for the line integrals over the sum of the patches) and as a
/// tool of fixed size meets it (radius two base spans, as `step_two_level`: its spread covers
/// more of the finer mass points). Each detail patch is 20 of its knot spans across around the
/// force, the region at its middle. Read the levels by their ratio to level 0 in the same run.
fn step_levels(c: &mut Criterion) {
    let mut group = c.benchmark_group("step_levels");
    let (n, m) = (11, 21);
    for level in 0..=3_u32 {
        for scaled in [true, false] {
            if level == 0 && !scaled {
                // The same step as the scaled one.
                continue;
            }
            let (base, _, base_force) = setup(n, m);
            let base_spacing = base.spacing;
            let mut clay = MultiPatchField::new(base);
            let at = base_force.start;
            let patch = if level == 0 {
                0
            } else {
                let spacing = base_spacing / (1_u32 << level) as f32;
                let half = Vec3::splat(10.0 * spacing);
                clay.refine(at - half, at + half, level)
                    .expect("detail patch")
            };
            let lattice = &clay.patches[patch].lattice;
            let scale = lattice.spacing / base_spacing;
            let force = if scaled {
                ToolForce {
                    end: at + (base_force.end - at) * scale,
                    radius: base_force.radius * scale,
                    ..base_force
                }
            } else {
                base_force
            };
            let region = if level == 0 {
                CoeffBox {
                    min: [2; 3],
                    max: [n + 1; 3],
                }
            } else {
                let dims = lattice.dims;
                CoeffBox {
                    min: dims.map(|d| (d - n) / 2),
                    max: dims.map(|d| (d - n) / 2 + n - 1),
                }
            };
            let mut state = RegionState::new(
                lattice,
                region,
                [m; 3],
                Material::PLASTIC.for_volume_ratio(scale.powi(3)),
            )
            .expect("region");
            let mut sim = Simulator::new(StepParams::default());
            let mut snap = RegionSnapshot::default();
            let mut failures = 0u64;
            let id = format!(
                "level_{level}/{n}^3/{m}^3/{}",
                if scaled {
                    "force_2_spans"
                } else {
                    "force_2_base_spans"
                }
            );
            group.bench_function(&id, |b| {
                b.iter(|| {
                    let (lattice, others): (&mut BSplineLattice, OtherPatches<'_>) =
                        clay.split_patch_mut(patch).expect("the patch");
                    let r =
                        sim.step_layered(&mut state, lattice, others, &[force], None, &mut snap);
                    failures += u64::from(black_box(r.is_err()));
                });
            });
            assert_eq!(failures, 0, "{id}: {failures} timed steps failed");
        }
    }
    group.finish();
}

fn solve(c: &mut Criterion) {
    let mut group = c.benchmark_group("solve_gram");
    for n in [15, 32, 64] {
        let (_, state, _) = setup(n, n);
        let basis = state.basis;
        let mut x: Vec<f32> = (0..basis.coeff_count()).map(|i| (i % 7) as f32).collect();
        let b_in = x.clone();
        let mut scratch = KronScratch::for_basis(&basis);
        group.bench_function(BenchmarkId::new("lane_blocked", n), |b| {
            b.iter(|| basis.solve_gram_into(black_box(&b_in), &mut x, &mut scratch));
        });
        group.bench_function(BenchmarkId::new("line_by_line", n), |b| {
            b.iter_batched_ref(
                || b_in.clone(),
                |x| basis.solve_gram_line_by_line(black_box(x)),
                BatchSize::LargeInput,
            );
        });
        let mut d = vec![0.0; basis.sample_count()];
        group.bench_function(BenchmarkId::new("apply", n), |b| {
            b.iter(|| basis.apply(black_box(&x), &mut d, &mut scratch));
        });
        group.bench_function(BenchmarkId::new("project", n), |b| {
            b.iter(|| basis.project(black_box(&d), &mut x, 1.0, &mut scratch));
        });
    }
    group.finish();
}

fn evaluate(c: &mut Criterion) {
    let (lattice, _, force) = setup(32, 32);
    let points: Vec<Vec3> = (0..1024)
        .map(|i| {
            let f = i as f32;
            Vec3::new(
                (f * 0.618_034).fract(),
                (f * 0.414_213_6).fract(),
                (f * 0.732_050_8).fract(),
            ) * 0.8
                + Vec3::splat(0.1)
        })
        .collect();
    let mut i = 0;
    c.bench_function("value_and_gradient", |b| {
        b.iter(|| {
            i = (i + 1) & 1023;
            black_box(lattice.value_and_gradient(black_box(points[i])))
        });
    });
    c.bench_function("force_integral", |b| {
        b.iter(|| {
            black_box(force_integral(
                &lattice,
                black_box(force.start),
                black_box(force.end),
            ))
        });
    });
}

/// A pool of spares that is always empty: the steady state of a stroke's writes.
struct DrySpares;

impl SpareStorage for DrySpares {
    fn spare_brick(&mut self) -> Option<SpareBrick> {
        None
    }
    fn spare_group(&mut self) -> Option<SpareGroup> {
        None
    }
}

/// The haptic loop's copy of the field, sparse (uniform bricks one value, as now) against
/// every brick dense (the obvious alternative, as the copy was before): the tick's integral
/// over each, and the tick's write of a stroke's published box into each. In the sparse copy
/// the write first checks that every brick it needs is dense
/// (`FieldUpdate::densify_for_copy`, with an empty pool: the steady state of a stroke, whose
/// bricks were made dense from the pool by its first publication).
fn haptic_copy(c: &mut Criterion) {
    // A ball of radius 0.3 on 64³ coefficients, its density ramped over two knot spans and
    // clamped to [0, 1], as the clay's is: the bricks inside and far outside hold one value.
    let (_, _, force) = setup(32, 32);
    let spacing = 1.0 / 63.0;
    let mut lattice = BSplineLattice::zeros([64; 3], spacing, Vec3::ZERO).expect("lattice");
    lattice.coeffs.update_each(|n, c| {
        let at = Vec3::new(
            (n % 64) as f32,
            ((n / 64) % 64) as f32,
            (n / (64 * 64)) as f32,
        ) * spacing;
        let depth = 0.3 - (at - Vec3::splat(0.5)).length();
        *c = (0.5 + depth / (2.0 * spacing)).clamp(0.0, 1.0);
    });
    let mut sparse = MultiPatchField::new(lattice);
    sparse.compact();
    let mut dense = sparse.clone();
    dense.densify_all();
    // The published box of a stroke on the sphere's +x side: 24³ coefficients, each moved.
    let published = CoeffBox {
        min: [40, 20, 20],
        max: [63, 43, 43],
    };
    let mut moved = sparse.clone();
    let coeffs = &mut moved.patches[0].lattice.coeffs;
    for k in published.min[2]..=published.max[2] {
        for j in published.min[1]..=published.max[1] {
            for i in published.min[0]..=published.max[0] {
                let v = coeffs.get(i, j, k);
                coeffs.set(i, j, k, v * 0.99 + 0.001 * (i + j + k) as f32);
            }
        }
    }
    let mut update = FieldUpdate::with_capacity_for(&moved);
    update.capture(&moved, 0, published);
    assert!(update.densify_for_copy(&mut sparse, &mut AllocatingSpares));
    let bricks = |f: &MultiPatchField| f.patches[0].lattice.coeffs.dense_brick_count();
    eprintln!(
        "haptic_copy: dense bricks {} of {} (sparse copy), {} (dense copy)",
        bricks(&sparse),
        sparse.patches[0].lattice.coeffs.brick_count(),
        bricks(&dense)
    );
    let mut group = c.benchmark_group("haptic_copy");
    for (name, copy) in [("dense", &dense), ("sparse", &sparse)] {
        group.bench_function(BenchmarkId::new("force_integral", name), |b| {
            b.iter(|| {
                black_box(force_integral(
                    &copy.patches[0].lattice,
                    black_box(force.start),
                    black_box(force.end),
                ))
            });
        });
    }
    group.bench_function(BenchmarkId::new("write_update", "dense"), |b| {
        b.iter(|| black_box(update.copy_into(&mut dense)));
    });
    group.bench_function(BenchmarkId::new("write_update", "sparse"), |b| {
        b.iter(|| {
            let ready = update.densify_for_copy(&mut sparse, &mut DrySpares);
            black_box(ready && update.copy_into(&mut sparse))
        });
    });
    group.finish();
}

criterion_group!(
    benches,
    step,
    step_layered,
    step_levels,
    solve,
    evaluate,
    haptic_copy
);
criterion_main!(benches);
