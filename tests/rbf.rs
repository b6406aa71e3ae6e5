//! The RBF of the sculpt (Zhang et al. §5.3): its zero set against the clay's surface on a
//! sphere and a torus, greedy centre reduction, the file round trip, and the way back to a
//! clay.

use dynaclay::field::{
    BSplineLattice, Primitive, coeff_box_around, lattice_from_primitive, refit_box_edit,
};
use dynaclay::particles::{ParticleParams, ParticleSystem};
use dynaclay::rbf::{
    Rbf, RbfFile, RbfFileError, RbfOptions, clay_rbf_distance, decode, encode, fit_surface,
    read_rbf, write_rbf,
};
use dynaclay::tools::ContactParams;
use glam::{DVec3, Vec3};

const SPACING: f32 = 0.1;

fn clay(primitive: &Primitive) -> BSplineLattice {
    lattice_from_primitive([25; 3], SPACING, Vec3::ZERO, primitive, 2.0 * SPACING, 2)
        .expect("clay fits")
}

fn sphere() -> (BSplineLattice, f32) {
    let p = Primitive::Sphere {
        centre: Vec3::splat(1.2),
        radius: 0.7,
    };
    let (lo, hi) = p.bounds();
    (clay(&p), (hi - lo).length())
}

fn torus() -> (BSplineLattice, f32) {
    let p = Primitive::Torus {
        centre: Vec3::splat(1.2),
        major_radius: 0.7,
        minor_radius: 0.3,
    };
    let (lo, hi) = p.bounds();
    (clay(&p), (hi - lo).length())
}

fn particles(field: &BSplineLattice, n: usize, seed: u64) -> Vec<Vec3> {
    let mut s = ParticleSystem::new(ParticleParams::new(n)).unwrap();
    s.seed_random(field, n, seed).unwrap();
    s.settle(field, 120);
    s.positions().to_vec()
}

/// Distance from a clay surface point to the RBF's zero set along the clay's normal, by
/// bisection over `±reach`; `None` when `I` does not change sign there.
fn zero_set_distance(field: &BSplineLattice, rbf: &Rbf, p: Vec3, reach: f64) -> Option<f64> {
    let n = -field.gradient(p).normalize().as_dvec3();
    let p = p.as_dvec3();
    let f = |t: f64| rbf.value(p + n * t);
    let (mut a, mut b) = (-reach, reach);
    // Inside is positive: I(p − reach n) > 0 > I(p + reach n).
    if !(f(a) > 0.0 && f(b) < 0.0) {
        return None;
    }
    for _ in 0..60 {
        let m = 0.5 * (a + b);
        if f(m) > 0.0 { a = m } else { b = m }
    }
    Some(0.5 * (a + b))
}

/// The worst and mean distance from `samples` clay surface points to the RBF's zero set.
fn accuracy(field: &BSplineLattice, rbf: &Rbf, samples: &[Vec3], diag: f32) -> (f64, f64) {
    let reach = 0.05 * f64::from(diag);
    let mut worst = 0.0f64;
    let mut sum = 0.0;
    for &p in samples {
        let d = zero_set_distance(field, rbf, p, reach)
            .unwrap_or_else(|| panic!("no zero of the RBF within {reach} of {p}"))
            .abs();
        worst = worst.max(d);
        sum += d;
    }
    (worst, sum / samples.len() as f64)
}

/// The Hausdorff distance, both ways, between the meshes of the clay's surface and of the
/// RBF's zero set (same mesher, same grid: four cells per knot span). Returns the larger.
fn mesh_distance(field: &BSplineLattice, rbf: &Rbf, diag: f32, what: &str) -> f64 {
    let h = clay_rbf_distance(field, rbf, 4)
        .unwrap()
        .unwrap_or_else(|| panic!("{what}: an empty mesh"));
    eprintln!(
        "{what}: meshes: clay→RBF worst {:.4} mean {:.5}, RBF→clay worst {:.4} mean {:.5} \
         ({:.2}% of the diagonal {diag:.3})",
        h.a_to_b,
        h.mean_a_to_b,
        h.b_to_a,
        h.mean_b_to_a,
        100.0 * h.max() / diag
    );
    f64::from(h.max())
}

fn check_shape(field: &BSplineLattice, diag: f32, n: usize, what: &str) -> Rbf {
    let surface = particles(field, n, 1);
    let (rbf, report) = fit_surface(field, &surface, &RbfOptions::with_offset(0.05)).unwrap();
    assert_eq!(report.constraints, 3 * surface.len());
    assert_eq!(report.centres, report.constraints);
    assert!(report.max_residual < 1e-6, "{what}: {report:?}");
    // Other surface points than the particles: a second, independently seeded set.
    let samples = particles(field, 500, 99);
    let (worst, mean) = accuracy(field, &rbf, &samples, diag);
    eprintln!(
        "{what}: {} centres, zero set from the clay along its normal: worst {worst:.4}, mean \
         {mean:.5} (bounding-box diagonal {diag:.3}, {:.2}% worst)",
        report.centres,
        100.0 * worst / f64::from(diag)
    );
    assert!(worst < 0.01 * f64::from(diag), "{what}: worst {worst}");
    let hausdorff = mesh_distance(field, &rbf, diag, what);
    assert!(
        hausdorff < 0.01 * f64::from(diag),
        "{what}: Hausdorff {hausdorff} on meshes"
    );
    rbf
}

#[test]
fn sphere_zero_set_within_one_percent() {
    let (field, diag) = sphere();
    check_shape(&field, diag, 400, "sphere");
}

#[test]
fn torus_zero_set_within_one_percent() {
    let (field, diag) = torus();
    check_shape(&field, diag, 600, "torus");
}

#[test]
fn sculpted_clay_zero_set_within_one_percent() {
    // Twelve contact actions (dents and bulges, Zhang §3) on the sphere, as the tools apply
    // them: a local least-squares refit of the contact rule.
    let (mut field, diag) = sphere();
    let width = 2.0 * SPACING;
    for k in 0..12 {
        let (u, v) = (k as f32 * 2.399_963, (k as f32 + 0.5) / 12.0);
        let z = 1.0 - 2.0 * v;
        let s = (1.0 - z * z).sqrt();
        let tool = Primitive::Sphere {
            centre: Vec3::splat(1.2) + Vec3::new(s * u.cos(), s * u.sin(), z) * 0.7,
            radius: 0.35,
        };
        let params = ContactParams::with_alpha(if k % 2 == 0 { -1.5 } else { 1.5 });
        let (lo, hi) = tool.bounds();
        let b = coeff_box_around(&field, lo - width, hi + width, 1).unwrap();
        let iso = field.iso;
        refit_box_edit(&mut field, b.min, b.max, 2, |x, old| {
            params.apply(old, tool.density(x, width), iso, 0.003)
        })
        .unwrap();
    }
    check_shape(&field, diag, 500, "sculpted sphere");
}

#[test]
fn greedy_reduction_keeps_the_limit_and_the_accuracy() {
    let (field, diag) = sphere();
    let surface = particles(&field, 400, 1);
    let options = RbfOptions {
        max_centres: 450,
        ..RbfOptions::with_offset(0.05)
    };
    let (rbf, report) = fit_surface(&field, &surface, &options).unwrap();
    eprintln!("greedy: {report:?}");
    assert!(report.centres <= 450);
    assert!(report.greedy_rounds >= 1);
    assert_eq!(rbf.len(), report.centres);
    let samples = particles(&field, 300, 7);
    let (worst, _) = accuracy(&field, &rbf, &samples, diag);
    assert!(worst < 0.01 * f64::from(diag), "greedy: worst {worst}");
    let hausdorff = mesh_distance(&field, &rbf, diag, "greedy");
    assert!(
        hausdorff < 0.01 * f64::from(diag),
        "greedy: Hausdorff {hausdorff}"
    );
}

#[test]
fn file_round_trip_and_import_as_clay() {
    let (field, _) = sphere();
    let surface = particles(&field, 300, 1);
    let (rbf, _) = fit_surface(&field, &surface, &RbfOptions::with_offset(0.05)).unwrap();
    let file = RbfFile {
        rbf,
        dims: field.dims,
        spacing: field.spacing,
        origin: field.origin,
        iso: field.iso,
    };
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sphere.rbf");
    write_rbf(&path, &file).unwrap();
    let back = read_rbf(&path).unwrap();
    assert_eq!(back, file);

    // The imported clay's surface lies where the original's did (within a fifth of a span).
    let clay = back.to_clay(2).unwrap();
    let probes = particles(&field, 300, 5);
    for p in probes {
        let (v, g) = clay.value_and_gradient(p);
        let d = (v - clay.iso).abs() / g.length();
        assert!(d < 0.2 * SPACING, "imported surface {d} from {p}");
    }
}

#[test]
fn damaged_files_are_refused_with_reasons() {
    let file = RbfFile {
        rbf: Rbf {
            centres: vec![DVec3::ZERO, DVec3::X],
            weights: vec![1.0, -1.0],
            poly: [0.1, 0.0, 0.0, 1.0],
        },
        dims: [8, 8, 8],
        spacing: 0.1,
        origin: Vec3::ZERO,
        iso: 0.5,
    };
    let bytes = encode(&file).unwrap();
    let path = std::path::Path::new("x.rbf");
    assert_eq!(decode(&bytes, path).unwrap(), file);
    let mut flipped = bytes.clone();
    flipped[90] ^= 1;
    assert!(matches!(
        decode(&flipped, path),
        Err(RbfFileError::Checksum { .. })
    ));
    assert!(matches!(
        decode(&bytes[..bytes.len() - 5], path),
        Err(RbfFileError::Truncated { .. })
    ));
    assert!(matches!(
        decode(b"not an rbf file at all", path),
        Err(RbfFileError::NotRbf { .. })
    ));
    let mut newer = bytes.clone();
    newer[8] = 9;
    assert!(matches!(
        decode(&newer, path),
        Err(RbfFileError::UnsupportedVersion { found: 9, .. })
    ));
    let mut huge = bytes;
    huge[12..16].copy_from_slice(&u32::MAX.to_le_bytes());
    assert!(matches!(
        decode(&huge, path),
        Err(RbfFileError::TooManyCentres { .. })
    ));
    assert!(matches!(
        read_rbf(std::path::Path::new("/nonexistent/x.rbf")),
        Err(RbfFileError::Read { .. })
    ));
}

#[test]
fn every_cut_of_a_file_is_refused_as_short_and_never_read_past() {
    let file = RbfFile {
        rbf: Rbf {
            centres: vec![DVec3::ZERO, DVec3::X, DVec3::Y],
            weights: vec![1.0, -1.0, 0.5],
            poly: [0.1, 0.0, 0.0, 1.0],
        },
        dims: [8, 8, 8],
        spacing: 0.1,
        origin: Vec3::ZERO,
        iso: 0.5,
    };
    let bytes = encode(&file).unwrap();
    let path = std::path::Path::new("cut.rbf");
    for len in 0..bytes.len() {
        let refused = decode(&bytes[..len], path).unwrap_err();
        if len < 12 {
            // Too short to hold the magic and the version.
            assert!(
                matches!(refused, RbfFileError::NotRbf { .. }),
                "{len}: {refused}"
            );
        } else {
            assert!(
                matches!(refused, RbfFileError::Truncated { len: l, .. } if l == len),
                "{len}: {refused}"
            );
        }
    }
    // One byte more than the file says is refused too.
    let mut longer = bytes.clone();
    longer.push(0);
    assert!(matches!(
        decode(&longer, path),
        Err(RbfFileError::Truncated { .. })
    ));
}
