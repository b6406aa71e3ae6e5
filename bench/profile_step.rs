//! Profiling harness for the simulation step: `profile_step N M STEPS [THREADS]` runs one
//! warm-up step and then STEPS steps at N³ coefficients / M³ mass points (the setup of
//! `bench/core.rs`), printing the mean wall time per step, the mean time of each stage, and a checksum of the
//! coefficients (equal before and after a change that must not alter the numbers). Meant for instruction counts, which
//! do not depend on the machine's load:
//! `cargo build --release --bench profile_step`, then
//! `valgrind --tool=callgrind --toggle-collect='*Simulator*step*' target/release/deps/profile_step-* 32 32 25`
//! (per-step counts by the difference of two runs with different STEPS).
use dynaclay::dynamics::{Distribution, Material, RegionState, Simulator, StepParams, ToolForce};
use dynaclay::field::{
    BSplineLattice, CoeffBox, Primitive, RegionSnapshot, lattice_from_primitive,
};
use glam::Vec3;

fn setup(n: usize, m: usize) -> (BSplineLattice, RegionState, ToolForce) {
    let dims = [n + 4; 3];
    let spacing = 1.0 / (n + 3) as f32;
    let centre = Vec3::splat(0.5);
    let sphere = Primitive::Sphere {
        centre,
        radius: 0.3,
    };
    let lattice =
        lattice_from_primitive(dims, spacing, Vec3::ZERO, &sphere, 2.0 * spacing, 2).unwrap();
    let region = CoeffBox {
        min: [2; 3],
        max: [n + 1; 3],
    };
    let state = RegionState::new(&lattice, region, [m; 3], Material::PLASTIC).unwrap();
    let force = ToolForce {
        start: centre + Vec3::X * 0.3,
        end: centre + Vec3::X * 0.36,
        distribution: Distribution::Gaussian,
        radius: 2.0 * spacing,
        gain: 1e3,
    };
    (lattice, state, force)
}

fn main() {
    let a: Vec<usize> = std::env::args()
        .skip(1)
        .map(|s| s.parse().unwrap())
        .collect();
    let (n, m, steps) = (a[0], a[1], a[2]);
    let (mut lattice, mut state, force) = setup(n, m);
    let threads = a.get(3).copied().unwrap_or(1);
    let mut sim = Simulator::new(StepParams {
        threads,
        ..StepParams::default()
    });
    let mut snap = RegionSnapshot::default();
    sim.step(&mut state, &mut lattice, &[force], &mut snap)
        .unwrap();
    let mut stages = [0u64; 6];
    let t = std::time::Instant::now();
    for _ in 0..steps {
        let ok = sim
            .step(&mut state, &mut lattice, &[force], &mut snap)
            .is_ok();
        assert!(ok, "a step failed");
        let l = sim.counters.last;
        for (s, v) in stages.iter_mut().zip([
            l.gather_forces_ns,
            l.spring_forces_ns,
            l.solve_accel_ns,
            l.constrain_ns,
            l.integrate_ns,
            l.publish_ns,
        ]) {
            *s += v;
        }
    }
    let el = t.elapsed();
    let s: f64 = state.p.iter().map(|&v| f64::from(v)).sum();
    let per = |v: u64| v as f64 / 1e3 / steps as f64;
    println!(
        "{n}^3/{m}^3 {threads} thread(s): {:.1} us/step  checksum {s:.9e}  stages us: gather {:.1} springs {:.1} solve {:.1} constrain {:.1} integrate {:.1} publish {:.1}",
        el.as_secs_f64() * 1e6 / steps as f64,
        per(stages[0]),
        per(stages[1]),
        per(stages[2]),
        per(stages[3]),
        per(stages[4]),
        per(stages[5]),
    );
}
