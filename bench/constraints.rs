//! Cost of geometric constraints (Hua & Qin §7.3): one simulation step with 0, 10, 100 and
//! 1000 point pins on a sphere, on 16³/31³ and 32³/63³ regions (two mass points per knot span,
//! as the engine makes them). The target: with 100 pins a step costs at most 1.3× the
//! unconstrained step. The constraint stage's set-up (clustering, the SVD or eigensolve) runs
//! once, outside the timed loop, as it does in the engine when a region is made.
//!
//! Run: `cargo bench --bench constraints -- --warm-up-time 1 --measurement-time 3`.
//! Optimistic where noted: the pins are spread evenly over the sphere (a Fibonacci lattice),
//! so clusters are small until there are so many that they merge; a long pinned curve makes
//! one large cluster, whose dense solve grows with the square of its rows.

use std::hint::black_box;

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use dynaclay::dynamics::{
    Constraint, ConstraintPath, ConstraintRow, ConstraintSolver, Distribution, Material,
    RegionState, Simulator, StepParams, ToolForce, project_onto_surface,
};
use dynaclay::field::{
    BSplineLattice, CoeffBox, MultiPatchField, Primitive, RegionSnapshot, lattice_from_primitive,
};
use glam::Vec3;

const CENTRE: Vec3 = Vec3::splat(0.5);
const RADIUS: f32 = 0.3;

/// A sphere on a lattice of `n + 4` coefficients per axis; the region is the central `n³`
/// coefficients with `(2n − 1)³` mass points; one tool force pulls at +x.
fn setup(n: usize) -> (BSplineLattice, RegionState, ToolForce) {
    let spacing = 1.0 / (n + 3) as f32;
    let sphere = Primitive::Sphere {
        centre: CENTRE,
        radius: RADIUS,
    };
    let lattice =
        lattice_from_primitive([n + 4; 3], spacing, Vec3::ZERO, &sphere, 2.0 * spacing, 2)
            .expect("sphere fits");
    let region = CoeffBox {
        min: [2; 3],
        max: [n + 1; 3],
    };
    let m = 2 * n - 1;
    let state = RegionState::new(&lattice, region, [m; 3], Material::PLASTIC).expect("region");
    let force = ToolForce {
        start: CENTRE + Vec3::X * RADIUS,
        end: CENTRE + Vec3::X * (RADIUS + 0.06),
        distribution: Distribution::Gaussian,
        radius: 2.0 * spacing,
        gain: 1e3,
    };
    (lattice, state, force)
}

/// `count` point pins spread over the sphere (a Fibonacci lattice), each on the surface.
fn pins(lattice: &BSplineLattice, count: usize) -> Vec<ConstraintRow> {
    let clay = MultiPatchField::new(lattice.clone());
    let golden = std::f32::consts::PI * (3.0 - 5.0_f32.sqrt());
    (0..count)
        .flat_map(|i| {
            let y = 1.0 - 2.0 * (i as f32 + 0.5) / count as f32;
            let r = (1.0 - y * y).sqrt();
            let a = golden * i as f32;
            let dir = Vec3::new(r * a.cos(), y, r * a.sin());
            let near = CENTRE + dir * RADIUS;
            let at = project_onto_surface(&clay, near, 0.1).expect("surface near the sphere");
            Constraint::Point { at }.rows(lattice).expect("rows")
        })
        .collect()
}

fn constrained_step(c: &mut Criterion) {
    let mut group = c.benchmark_group("constrained_step");
    for n in [16, 32] {
        for count in [0, 10, 100, 1000] {
            let (mut lattice, mut state, force) = setup(n);
            let rows = pins(&lattice, count);
            let mut solver = ConstraintSolver::new(&rows, &lattice, &state, ConstraintPath::Auto);
            let r = solver.report();
            eprintln!(
                "{n}^3/{m}^3 with {count} pins: rows {}, rank {}, clusters {} projected / {} reduced",
                r.rows,
                r.rank,
                r.projected_clusters,
                r.reduced_clusters,
                m = 2 * n - 1
            );
            let mut sim = Simulator::new(StepParams::default());
            let mut snap = RegionSnapshot::default();
            let id = format!("{n}^3/{}^3/{count}_pins", 2 * n - 1);
            let mut failures = 0u64;
            group.bench_function(BenchmarkId::from_parameter(&id), |b| {
                b.iter(|| {
                    let r = sim.step_constrained(
                        &mut state,
                        &mut lattice,
                        &[force],
                        Some(&mut solver),
                        &mut snap,
                    );
                    failures += u64::from(black_box(r.is_err()));
                });
            });
            assert_eq!(failures, 0, "step {id}: {failures} timed steps failed");
        }
    }
    group.finish();
}

criterion_group!(benches, constrained_step);
criterion_main!(benches);
