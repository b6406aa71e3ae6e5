//! Constrained particles on a sphere and a torus clay: on the surface, at the user's count,
//! evenly spaced.

use dynaclay::field::{
    BSplineLattice, Primitive, density_profile, fit_lattice, lattice_from_primitive,
};
use dynaclay::particles::{
    NeighbourSearch, ParticleParams, ParticleSystem, nearest_neighbour_distances,
};
use glam::Vec3;

const SPACING: f32 = 0.1;

fn clay(primitive: &Primitive, n: usize) -> BSplineLattice {
    lattice_from_primitive([n; 3], SPACING, Vec3::ZERO, primitive, 2.0 * SPACING, 2)
        .expect("clay fits")
}

fn sphere() -> BSplineLattice {
    clay(
        &Primitive::Sphere {
            centre: Vec3::splat(1.2),
            radius: 0.7,
        },
        25,
    )
}

fn torus() -> BSplineLattice {
    clay(
        &Primitive::Torus {
            centre: Vec3::splat(1.2),
            major_radius: 0.7,
            minor_radius: 0.3,
        },
        25,
    )
}

/// Distance to the surface, first order: `|F| / |∇F|`.
fn surface_distance(field: &BSplineLattice, p: Vec3) -> f32 {
    let (v, g) = field.value_and_gradient(p);
    (v - field.iso).abs() / g.length()
}

fn coefficient_of_variation(values: &[f32]) -> f32 {
    let n = values.len() as f32;
    let mean = values.iter().sum::<f32>() / n;
    let var = values.iter().map(|v| (v - mean) * (v - mean)).sum::<f32>() / n;
    var.sqrt() / mean
}

/// Checks shared by every shape: on the surface, at N within 2 %, evenly spaced.
///
/// The spacing bound: points scattered independently at random on a surface have
/// nearest-neighbour distances with a Rayleigh distribution, whose coefficient of variation is
/// `√(4/π − 1) ≈ 0.52`; a perfect hexagonal packing has 0. A settled repulsion system lands
/// well under half of the random figure, so 0.25 separates "evenly spaced" from "scattered"
/// with room for the curvature and the few particles still moving.
fn check(field: &BSplineLattice, system: &ParticleSystem, n: usize, what: &str) {
    let count = system.len();
    assert!(
        (count as f32 - n as f32).abs() <= 0.02 * n as f32,
        "{what}: {count} particles for N = {n}"
    );
    let worst = system
        .positions()
        .iter()
        .map(|&p| surface_distance(field, p))
        .fold(0.0f32, f32::max);
    assert!(
        worst < 1e-3,
        "{what}: a particle is {worst} off the surface"
    );
    let radius = 6.0 * system.sigmas().iter().copied().fold(0.0f32, f32::max);
    let nn = nearest_neighbour_distances(system.positions(), radius);
    assert!(
        nn.iter().all(|d| d.is_finite()),
        "{what}: isolated particle"
    );
    let cv = coefficient_of_variation(&nn);
    eprintln!("{what}: n = {count}, worst off-surface {worst:.2e}, NN CV {cv:.3}");
    assert!(cv < 0.25, "{what}: nearest-neighbour CV {cv}");
}

#[test]
fn random_start_on_a_sphere_settles_even_at_n() {
    let field = sphere();
    let n = 600;
    let mut system = ParticleSystem::new(ParticleParams::new(n)).unwrap();
    system.seed_random(&field, n, 1).unwrap();
    // Before settling the spacing is that of random points.
    let radius = 10.0 * system.sigmas()[0];
    let cv0 = coefficient_of_variation(&nearest_neighbour_distances(system.positions(), radius));
    assert!(cv0 > 0.35, "random start CV {cv0}");
    system.settle(&field, 150);
    check(&field, &system, n, "sphere");
}

#[test]
fn a_few_particles_grow_to_n_on_a_torus() {
    let field = torus();
    let n = 800;
    let mut system = ParticleSystem::new(ParticleParams::new(n)).unwrap();
    system.seed_random(&field, 8, 2).unwrap();
    assert_eq!(system.len(), 8);
    system.settle(&field, 300);
    check(&field, &system, n, "torus from 8");
}

#[test]
fn too_many_particles_die_down_to_n() {
    let field = sphere();
    let mut system = ParticleSystem::new(ParticleParams::new(1200)).unwrap();
    system.seed_random(&field, 1200, 3).unwrap();
    system.settle(&field, 60);
    system.set_target_count(400).unwrap();
    system.settle(&field, 250);
    check(&field, &system, 400, "sphere 1200 → 400");
}

#[test]
fn pds_and_all_pairs_take_identical_steps() {
    let field = torus();
    let mut a = ParticleSystem::new(ParticleParams::new(300)).unwrap();
    a.seed_random(&field, 300, 4).unwrap();
    let mut b = a.clone();
    b.set_search(NeighbourSearch::AllPairs);
    for _ in 0..20 {
        let ra = a.step(&field, ParticleSystem::DEFAULT_DT).unwrap();
        let rb = b.step(&field, ParticleSystem::DEFAULT_DT).unwrap();
        assert_eq!(ra, rb);
    }
    assert!(a.pds_level() >= 2);
    for (p, q) in a.positions().iter().zip(b.positions()) {
        assert!((*p - *q).length() < 1e-5, "{p} vs {q}");
    }
}

/// A sphere has one curvature: with curvature bias it is sampled as evenly as without, at N.
///
/// Measured: nearest-neighbour CV 0.065 unbiased, 0.105 with ratio 4. Not all of the unbiased
/// evenness: the fitted lattice's iso-surface ripples at the knot spacing (radius 7 knots
/// here), and the smoothed curvature still varies over the sphere (wanted density 2.2–4.0).
#[test]
fn curvature_bias_leaves_a_sphere_even() {
    let field = sphere();
    let n = 600;
    let mut params = ParticleParams::new(n);
    params.curvature_ratio = 4.0;
    let mut system = ParticleSystem::new(params).unwrap();
    system.seed_random(&field, n, 1).unwrap();
    system.settle(&field, 150);
    check(&field, &system, n, "sphere, curvature ratio 4");
    let radius = 6.0 * system.sigmas().iter().copied().fold(0.0f32, f32::max);
    let cv = coefficient_of_variation(&nearest_neighbour_distances(system.positions(), radius));
    assert!(cv < 0.13, "biased sphere NN CV {cv}");
}

#[test]
fn bad_inputs_are_refused() {
    assert!(ParticleSystem::new(ParticleParams::new(0)).is_err());
    let field = sphere();
    let mut s = ParticleSystem::new(ParticleParams::new(10)).unwrap();
    assert!(s.seed_random(&field, 0, 0).is_err());
    assert!(s.step(&field, f32::NAN).is_err());
    assert!(s.step(&field, -1.0).is_err());
    let empty = BSplineLattice::zeros([8; 3], 0.1, Vec3::ZERO).unwrap();
    assert!(s.seed_random(&empty, 10, 0).is_err());
}

/// Mean nearest-neighbour distance of the particles that `select` picks (all particles count
/// as neighbours).
fn mean_spacing(system: &ParticleSystem, select: impl Fn(Vec3) -> bool) -> f32 {
    let radius = 8.0 * system.sigmas().iter().copied().fold(0.0f32, f32::max);
    let nn = nearest_neighbour_distances(system.positions(), radius);
    let picked: Vec<f32> = system
        .positions()
        .iter()
        .zip(&nn)
        .filter(|(p, _)| select(**p))
        .map(|(_, d)| *d)
        .collect();
    assert!(
        picked.len() >= 10,
        "only {} particles selected",
        picked.len()
    );
    picked.iter().sum::<f32>() / picked.len() as f32
}

#[test]
fn curvature_bias_packs_the_rims_of_a_cylinder() {
    // A capped cylinder: flat caps, a gently curved side, sharply curved rims.
    let (centre, radius, half_height) = (Vec3::splat(1.2), 0.6, 0.5);
    let field = clay(
        &Primitive::Cylinder {
            centre,
            radius,
            half_height,
        },
        25,
    );
    let n = 900;
    // Rim: near the circle where the side meets a cap; cap centre: flat, well inside the rim.
    let rim = |p: Vec3| {
        let d = p - centre;
        (d.truncate().length() - radius).abs() < 0.12 && (d.z.abs() - half_height).abs() < 0.12
    };
    let cap = |p: Vec3| {
        let d = p - centre;
        d.truncate().length() < 0.35 && d.z.abs() > 0.4
    };
    let mut ratios = Vec::new();
    for bias in [1.0f32, 4.0] {
        let mut params = ParticleParams::new(n);
        params.curvature_ratio = bias;
        let mut system = ParticleSystem::new(params).unwrap();
        system.seed_random(&field, n, 5).unwrap();
        system.settle(&field, 300);
        assert!((system.len() as f32 - n as f32).abs() <= 0.02 * n as f32);
        // Density ratio rim : cap, from the squared spacing ratio.
        let r = (mean_spacing(&system, cap) / mean_spacing(&system, rim)).powi(2);
        eprintln!(
            "curvature ratio {bias}: rim/cap particle density {r:.2}, n = {}",
            system.len()
        );
        ratios.push(r);
    }
    // 3.17 is measured at the rims against the caps with ratio 4 (1.97 before the pull along
    // the wanted density's gradient; the rims are about two particle spacings wide, and the
    // band also holds some of the less curved side and cap); `curvature_bias_reaches_the_
    // density_ratio_asked` measures reached against asked on broad parts.
    assert!(ratios[1] > 2.5, "biased rim/cap density {}", ratios[1]);
}

/// A box with rounded edges and corners: flat faces, cylindrical edges, spherical corners, each
/// several particle spacings across.
fn rounded_box(centre: Vec3, inner: f32, rounding: f32) -> BSplineLattice {
    let mut lattice = BSplineLattice::zeros([25; 3], SPACING, Vec3::ZERO).unwrap();
    fit_lattice(&mut lattice, 2, |x| {
        let q = ((x - centre).abs() - Vec3::splat(inner)).max(Vec3::ZERO);
        let inside = ((x - centre).abs() - Vec3::splat(inner))
            .max_element()
            .min(0.0);
        density_profile(q.length() + inside - rounding, 2.0 * SPACING)
    })
    .unwrap();
    lattice
}

/// The density reached against the density asked, on a shape with flat and curved parts: a
/// rounded box (flat faces, edges of curvature 1/r, corners of curvature norm √2/r), each part
/// several particle spacings across. Density is particles per unit area over a whole part:
/// the eight corners together are a sphere of radius r, the six faces squares of side twice
/// the flat half-width; a particle is in a corner where all three of its coordinates lie
/// beyond the flat part, on a face where exactly one does.
#[test]
fn curvature_bias_reaches_the_density_ratio_asked() {
    let (centre, flat, r) = (Vec3::splat(1.2), 0.35f32, 0.35f32);
    let field = rounded_box(centre, flat, r);
    let corner_area = 4.0 * std::f32::consts::PI * r * r;
    let face_area = 6.0 * (2.0 * flat) * (2.0 * flat);
    let n = 900;
    for ratio in [1.0f32, 2.0, 4.0] {
        let mut params = ParticleParams::new(n);
        params.curvature_ratio = ratio;
        let mut system = ParticleSystem::new(params).unwrap();
        system.seed_random(&field, n, 5).unwrap();
        system.settle(&field, 300);
        assert!((system.len() as f32 - n as f32).abs() <= 0.02 * n as f32);
        let wanted: Vec<f32> = system.wanted_density().collect();
        let beyond = |p: Vec3| {
            ((p - centre).abs() - Vec3::splat(flat))
                .to_array()
                .iter()
                .filter(|c| **c > 0.0)
                .count()
        };
        let (mut corners, mut faces) = ((0usize, 0.0f32), (0usize, 0.0f32));
        for (p, w) in system.positions().iter().zip(&wanted) {
            match beyond(*p) {
                3 => corners = (corners.0 + 1, corners.1 + w),
                1 => faces = (faces.0 + 1, faces.1 + w),
                _ => {}
            }
        }
        assert!(corners.0 >= 10 && faces.0 >= 10, "{corners:?} {faces:?}");
        let asked = (corners.1 / corners.0 as f32) / (faces.1 / faces.0 as f32);
        let reached = (corners.0 as f32 / corner_area) / (faces.0 as f32 / face_area);
        eprintln!(
            "curvature ratio {ratio}: corners/faces density asked {asked:.2}, reached \
             {reached:.2} ({} corner and {} face particles)",
            corners.0, faces.0
        );
        // Measured: ratio 1 → 0.98 (asked 1.00), 2 → 1.83 (asked 1.76, 104%), 4 → 2.98 (asked
        // 2.81, 106%); with seed 6: 1.03, 1.82 (104%), 3.04 (109%). The particles follow the
        // energy's full gradient in the metric of the wanted density, the pull along `∇ sᵢ`
        // included, so the settled density is the asked one within 10%.
        assert!(
            reached >= 0.9 * asked && reached <= 1.1 * asked,
            "ratio {ratio}: asked {asked:.2}, reached {reached:.2}"
        );
        if ratio == 1.0 {
            assert!((reached - 1.0).abs() < 0.1, "unbiased: {reached:.2}");
        }
    }
}

/// The density reached against the density asked on a capsule: a cylinder of curvature norm
/// `1/r` between two hemispheres of `√2/r`, each several particle spacings across. Density is
/// particles per unit area over the two caps together (a sphere of radius `r`) against the
/// side (a cylinder of length `2L`); a particle is on a cap where it lies beyond the side's
/// ends.
#[test]
fn curvature_bias_reaches_the_density_ratio_asked_on_a_capsule() {
    let (centre, half_length, r) = (Vec3::splat(1.2), 0.4f32, 0.45f32);
    let mut field = BSplineLattice::zeros([25; 3], SPACING, Vec3::ZERO).unwrap();
    fit_lattice(&mut field, 2, |x| {
        let d = x - centre;
        let axis = Vec3::new(0.0, 0.0, d.z.clamp(-half_length, half_length));
        density_profile((d - axis).length() - r, 2.0 * SPACING)
    })
    .unwrap();
    let cap_area = 4.0 * std::f32::consts::PI * r * r;
    let side_area = 2.0 * std::f32::consts::PI * r * (2.0 * half_length);
    let n = 900;
    for ratio in [2.0f32, 4.0] {
        let mut params = ParticleParams::new(n);
        params.curvature_ratio = ratio;
        let mut system = ParticleSystem::new(params).unwrap();
        system.seed_random(&field, n, 7).unwrap();
        system.settle(&field, 300);
        assert!((system.len() as f32 - n as f32).abs() <= 0.02 * n as f32);
        let (mut caps, mut side) = ((0usize, 0.0f32), (0usize, 0.0f32));
        for (p, w) in system.positions().iter().zip(system.wanted_density()) {
            if (p.z - centre.z).abs() > half_length {
                caps = (caps.0 + 1, caps.1 + w);
            } else {
                side = (side.0 + 1, side.1 + w);
            }
        }
        assert!(caps.0 >= 10 && side.0 >= 10, "{caps:?} {side:?}");
        let asked = (caps.1 / caps.0 as f32) / (side.1 / side.0 as f32);
        let reached = (caps.0 as f32 / cap_area) / (side.0 as f32 / side_area);
        eprintln!(
            "capsule, curvature ratio {ratio}: caps/side density asked {asked:.2}, reached \
             {reached:.2} ({} cap and {} side particles)",
            caps.0, side.0
        );
        assert!(
            reached >= 0.9 * asked && reached <= 1.1 * asked,
            "capsule, ratio {ratio}: asked {asked:.2}, reached {reached:.2}"
        );
    }
}

/// Particles following the clay in the graphics loop: each field update takes a fixed budget
/// of steps and publishes the particles wait-free; a grown clay is followed, and a new `N`
/// set through the handle is reached.
#[test]
fn a_follower_tracks_the_clay_and_the_count_a_viewer_sets() {
    use dynaclay::engine::{HeadlessSink, MeshSink};
    use dynaclay::particles::ParticleFollower;
    use std::sync::atomic::Ordering;

    let small = sphere();
    let grown = clay(
        &Primitive::Sphere {
            centre: Vec3::splat(1.2),
            radius: 0.8,
        },
        25,
    );
    let (mut follower, mut view) = ParticleFollower::new(HeadlessSink::default(), 400, 10).unwrap();
    let (small_clay, grown_clay) = (
        dynaclay::field::MultiPatchField::new(small.clone()),
        dynaclay::field::MultiPatchField::new(grown.clone()),
    );
    assert!(view.latest().is_initial());
    for _ in 0..12 {
        follower.field(&small_clay);
    }
    let seen = view.latest();
    assert_eq!(seen.value.updates, 12);
    assert!((seen.value.positions.len() as f32 - 400.0).abs() <= 8.0);
    assert_eq!(seen.value.normals.len(), seen.value.positions.len());
    // The clay grows: a few updates bring the particles onto the new surface.
    for _ in 0..4 {
        follower.field(&grown_clay);
    }
    let seen = &view.latest().value;
    for (p, n) in seen.positions.iter().zip(&seen.normals) {
        assert!(surface_distance(&grown, *p) < 0.05 * SPACING, "{p}");
        let radial = (*p - Vec3::splat(1.2)).normalize();
        assert!(n.dot(radial) > 0.99, "normal {n} at {p}");
    }
    // A viewer asks for 250 particles.
    follower.count_handle().store(250, Ordering::Relaxed);
    for _ in 0..30 {
        follower.field(&grown_clay);
    }
    let count = view.latest().value.positions.len();
    assert!((count as f32 - 250.0).abs() <= 5.0, "count {count}");
    assert!(follower.last_error().is_none());
}

/// The follower's switch and idle updates: off, it places nothing and publishes an empty view;
/// on over a still clay, idle updates seed and settle the particles, a bounded number after
/// each change; off again, they are dropped.
#[test]
fn a_switched_follower_settles_on_idle_updates_and_stops() {
    use dynaclay::engine::{HeadlessSink, MeshSink};
    use dynaclay::particles::ParticleFollower;
    use std::sync::atomic::Ordering;

    let clay = dynaclay::field::MultiPatchField::new(sphere());
    let (mut follower, mut view) = ParticleFollower::new(HeadlessSink::default(), 300, 2).unwrap();
    follower.set_settle_updates(5);
    let on = follower.switch_handle();
    on.store(false, Ordering::Relaxed);
    follower.field(&clay);
    follower.idle(&clay);
    assert!(follower.particles().is_empty());
    assert!(view.latest().value.positions.is_empty());
    let quiet = view.latest().version;
    for _ in 0..3 {
        follower.idle(&clay);
    }
    assert_eq!(view.latest().version, quiet, "off and idle: no work");

    on.store(true, Ordering::Relaxed);
    for _ in 0..20 {
        follower.idle(&clay);
    }
    let seen = view.latest();
    assert_eq!(
        seen.version,
        quiet + 5,
        "five idle updates after switching on"
    );
    assert!(seen.value.positions.len().abs_diff(300) <= 6);

    follower.count_handle().store(200, Ordering::Relaxed);
    for _ in 0..20 {
        follower.idle(&clay);
    }
    assert_eq!(view.latest().version, quiet + 10, "five more after a new N");

    on.store(false, Ordering::Relaxed);
    follower.idle(&clay);
    assert!(view.latest().value.positions.is_empty());
    assert!(follower.particles().is_empty());
}
