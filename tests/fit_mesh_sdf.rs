//! Closed meshes are fitted from their signed distance, open ones as point clouds
//! (`dynaclay import`, the GUI's Load: [`fit_import`]). A triangulated sphere (OBJ) and torus
//! (binary STL) take the signed-distance path; the fitted zero set, meshed, lies within 1% of
//! the shape's size of the true surface both ways and is closed with the shape's Euler
//! characteristic. The same torus with some faces wound the wrong way (ASCII STL) is repaired
//! and takes the same path; a sphere wound inward is signed the right way round; a sphere
//! with a cap of triangles removed takes the cloud path, and the log says why.

use std::path::Path;

use dynaclay::fit::{FitPath, ImportSettings, ImportedFit, fit_import};
use dynaclay::mesh::{TriMesh, hausdorff};
use glam::Vec3;

#[path = "support/topology.rs"]
mod topology;

use topology::{mesh_of, topology};

#[path = "support/meshes.rs"]
mod meshes;

use meshes::{Mesh, icosphere, torus, write_ascii_stl, write_binary_stl, write_obj};

fn import(path: &Path, settings: &ImportSettings) -> (ImportedFit, Vec<String>) {
    let mut notes = Vec::new();
    let fit = fit_import(path, settings, &mut |_| true, &mut |line| notes.push(line)).unwrap();
    for line in &notes {
        println!("{line}");
    }
    (fit, notes)
}

/// Checks that `fit` took the signed-distance path and that its zero set is closed with
/// Euler characteristic `euler` and within 1% of `size` (file units) of the surface: the
/// fitted mesh's vertices to `sdf` (the shape's exact distance, file units) and, both ways,
/// to the input triangulation.
fn check_surface(
    name: &str,
    fit: &ImportedFit,
    input: &Mesh,
    sdf: impl Fn(Vec3) -> f32,
    size: f32,
    euler: i64,
) {
    assert!(
        matches!(fit.path, FitPath::ClosedMesh(c) if c.is_closed()),
        "{name}: {:?}",
        fit.path
    );
    let mesh = mesh_of(&fit.field);
    let (closed, chi) = topology(&mesh);
    let to_file = |p: Vec3| (p - fit.offset) / fit.scale;
    let to_shape = mesh
        .positions
        .iter()
        .map(|&p| sdf(to_file(p)).abs())
        .fold(0.0f32, f32::max);
    let truth = TriMesh {
        positions: input.0.iter().map(|&p| fit.to_field(p)).collect(),
        normals: vec![Vec3::Y; input.0.len()],
        triangles: input.1.clone(),
    };
    let h = hausdorff(&mesh, &truth).unwrap();
    let field_size = size * fit.scale;
    println!(
        "{name}: {} patches, mesh → shape {:.3}%, Hausdorff to the input {:.3}% / {:.3}%, \
         closed {closed}, Euler {chi}",
        fit.field.patches.len(),
        100.0 * to_shape / size,
        100.0 * h.a_to_b / field_size,
        100.0 * h.b_to_a / field_size
    );
    assert!(closed, "{name}: the fitted surface is closed");
    assert_eq!(chi, euler, "{name}: Euler characteristic");
    assert!(to_shape <= 0.01 * size, "{name}: {to_shape} from the shape");
    assert!(
        h.max() <= 0.01 * field_size,
        "{name}: Hausdorff {h:?} over 1% of {field_size}"
    );
}

fn sphere_sdf(p: Vec3) -> f32 {
    p.length() - 1.0
}

fn torus_sdf(p: Vec3) -> f32 {
    let q = Vec3::new(p.x, 0.0, p.z).length() - 3.0;
    (q * q + p.y * p.y).sqrt() - 1.0
}

#[test]
fn a_closed_sphere_obj_is_fitted_from_its_signed_distance_within_one_percent() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("ball.obj");
    let sphere = icosphere(4);
    write_obj(&path, &sphere);
    let (fit, notes) = import(&path, &ImportSettings::default());
    assert!(
        notes.iter().any(|l| l.contains("the mesh is closed")),
        "{notes:?}"
    );
    assert!(
        notes.iter().any(|l| l.contains("signed distance")),
        "{notes:?}"
    );
    check_surface("sphere", &fit, &sphere, sphere_sdf, 2.0, 2);
}

#[test]
fn a_closed_torus_stl_is_fitted_from_its_signed_distance_within_one_percent() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("ring.stl");
    let ring = torus(3.0, 1.0, 96, 48);
    write_binary_stl(&path, &ring);
    let (fit, _) = import(&path, &ImportSettings::default());
    check_surface("torus", &fit, &ring, torus_sdf, 8.0, 0);
}

#[test]
fn faces_wound_the_wrong_way_are_repaired_and_the_torus_still_fits() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("ring.stl");
    let mut ring = torus(3.0, 1.0, 64, 32);
    let mut wrong = 0;
    for (n, t) in ring.1.iter_mut().enumerate() {
        if n % 7 == 3 {
            t.swap(1, 2);
            wrong += 1;
        }
    }
    write_ascii_stl(&path, &ring);
    let settings = ImportSettings {
        max_depth: 1,
        ..ImportSettings::default()
    };
    let (fit, notes) = import(&path, &settings);
    let FitPath::ClosedMesh(check) = fit.path else {
        panic!("{:?}", fit.path)
    };
    assert_eq!(check.reoriented, wrong);
    assert!(
        notes
            .iter()
            .any(|l| l.contains(&format!("{wrong} faces wound against"))),
        "{notes:?}"
    );
    // Put the winding back to compare with the true surface.
    for (n, t) in ring.1.iter_mut().enumerate() {
        if n % 7 == 3 {
            t.swap(1, 2);
        }
    }
    check_surface("torus, repaired", &fit, &ring, torus_sdf, 8.0, 0);
}

#[test]
fn a_sphere_wound_inward_is_still_solid_inside() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("inward.obj");
    let (v, mut t) = icosphere(3);
    for tri in &mut t {
        tri.swap(1, 2);
    }
    write_obj(&path, &(v.clone(), t.clone()));
    let settings = ImportSettings {
        resolution: 16,
        max_depth: 0,
        error_percent: 2.0,
        ..ImportSettings::default()
    };
    let (fit, notes) = import(&path, &settings);
    assert!(matches!(fit.path, FitPath::ClosedMesh(_)), "{:?}", fit.path);
    assert!(notes.iter().any(|l| l.contains("wind inward")), "{notes:?}");
    let field = &fit.field;
    assert!(field.value(fit.to_field(Vec3::ZERO)) > field.iso());
    assert!(field.value(fit.to_field(Vec3::splat(1.3))) < field.iso());
}

#[test]
fn a_sphere_with_a_cap_removed_takes_the_cloud_path_and_says_why() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cup.obj");
    let (v, t) = icosphere(3);
    let kept: Vec<[u32; 3]> = t
        .into_iter()
        .filter(|tri| tri.iter().map(|&i| v[i as usize].y).sum::<f32>() / 3.0 < 0.8)
        .collect();
    write_obj(&path, &(v, kept));
    let settings = ImportSettings {
        resolution: 16,
        max_depth: 0,
        ..ImportSettings::default()
    };
    let (fit, notes) = import(&path, &settings);
    let FitPath::OpenMesh(check) = fit.path else {
        panic!("{:?}", fit.path)
    };
    assert!(check.boundary_edges > 0 && !check.is_closed());
    assert!(
        notes.iter().any(|l| l.contains("the mesh is open")
            && l.contains(&format!("{} boundary edges", check.boundary_edges))),
        "{notes:?}"
    );
    assert!(
        notes.iter().any(|l| l.contains("as a point cloud")),
        "{notes:?}"
    );
    assert!(
        fit.field.patches[0]
            .lattice
            .coeffs
            .iter()
            .all(|c| c.is_finite())
    );
}
