//! A mesh imports with its own topology: the exported surface of the fitted clay (meshed as
//! `dynaclay import --mesh` meshes it, four cells per knot span, welded) has the input's piece
//! count and genus, and lies near the input both ways (99th percentile of vertex-to-surface
//! distances, percent of the input's diagonal).
//!
//! Spot (Keenan Crane's closed genus-0 cartoon cow, public domain, `tests/data/spot.obj`)
//! takes the signed-distance path. A sphere open at its base through a hole 31% of its size
//! wide (as the Stanford bunny is, 28%) came back hollowed and in pieces when it was fitted as
//! a point cloud, whose flood of the outside passes holes wider than its gap; its hole is now
//! capped and it takes the signed-distance path as one closed genus-0 piece.
//!
//! With `DYNACLAY_MODELS=<folder>` the ignored `public_models` test reports the same figures
//! for the public models found there (spot, the Stanford bunny, fandisk, rocker arm).

mod support;

use std::collections::HashMap;
use std::path::Path;

use dynaclay_core::mesh::{BrickOctree, SampleGrid, TriMesh};
use dynaclay_import::fit::mesh::{read_mesh, sample_triangles};
use dynaclay_import::fit::{FitPath, ImportSettings, ImportedFit, fit_import};
use glam::Vec3;
use support::{pieces, quantile_distance};

/// What one import produced: the path, the pieces (Euler characteristic, closed), and the
/// 99th-percentile distances from the fitted mesh's vertices to the input and from points
/// spread evenly over the input's area to the fitted mesh, percent of the input's diagonal.
struct Outcome {
    path: FitPath,
    pieces: Vec<(i64, bool)>,
    p99_to_input: f32,
    p99_to_fit: f32,
    notes: Vec<String>,
}

fn import_and_measure(path: &Path, settings: &ImportSettings) -> Outcome {
    let mut notes = Vec::new();
    let fit: ImportedFit =
        fit_import(path, settings, &mut |_| true, &mut |l| notes.push(l)).unwrap();
    // As `dynaclay import --mesh` meshes the clay.
    let grid = SampleGrid::for_field(&fit.field, 4).unwrap();
    let fitted = BrickOctree::build(grid, &fit.field).weld();
    let (vertices, triangles) = read_mesh(path).unwrap();
    // Evenly over the input's area (its vertices crowd where its triangles are small).
    let input_samples: Vec<Vec3> = sample_triangles(&vertices, &triangles, path)
        .unwrap()
        .points
        .iter()
        .map(|&p| fit.to_field(p))
        .collect();
    let input = TriMesh {
        positions: vertices.iter().map(|&p| fit.to_field(p)).collect(),
        normals: vec![Vec3::Y; vertices.len()],
        triangles,
    };
    let (lo, hi) = input
        .positions
        .iter()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(a, b), &p| {
            (a.min(p), b.max(p))
        });
    let diagonal = (hi - lo).length();
    Outcome {
        path: fit.path,
        pieces: pieces(&fitted),
        p99_to_input: 100.0 * quantile_distance(&fitted.positions, &input, 0.99) / diagonal,
        p99_to_fit: 100.0 * quantile_distance(&input_samples, &fitted, 0.99) / diagonal,
        notes,
    }
}

fn report(name: &str, o: &Outcome) {
    for line in &o.notes {
        println!("  {line}");
    }
    let genus: Vec<i64> = o.pieces.iter().map(|&(chi, _)| (2 - chi) / 2).collect();
    println!(
        "{name}: {} pieces, genus {genus:?}, closed {:?}; p99 distance fitted → input {:.3}%, \
         input → fitted {:.3}% of the diagonal",
        o.pieces.len(),
        o.pieces.iter().map(|p| p.1).collect::<Vec<_>>(),
        o.p99_to_input,
        o.p99_to_fit
    );
}

/// A UV sphere of radius 1 (`rings` × `segments`), wound outward, without the triangles
/// below `floor` (a hole at its base), as OBJ text.
fn sphere_obj(rings: usize, segments: usize, floor: f32) -> String {
    let mut text = String::new();
    let mut index = HashMap::new();
    let mut vertex = |text: &mut String, r: usize, s: usize| -> usize {
        let key = if r == 0 || r == rings {
            (r, 0)
        } else {
            (r, s % segments)
        };
        let next = index.len() + 1;
        *index.entry(key).or_insert_with(|| {
            let theta = std::f32::consts::PI * key.0 as f32 / rings as f32;
            let phi = std::f32::consts::TAU * key.1 as f32 / segments as f32;
            let (y, ring) = (theta.cos(), theta.sin());
            text.push_str(&format!(
                "v {} {y} {}\n",
                ring * phi.cos(),
                ring * phi.sin()
            ));
            next
        })
    };
    let mut faces = Vec::new();
    for r in 0..rings {
        for s in 0..segments {
            let a = vertex(&mut text, r, s);
            let b = vertex(&mut text, r + 1, s);
            let c = vertex(&mut text, r + 1, s + 1);
            let d = vertex(&mut text, r, s + 1);
            let low = (std::f32::consts::PI * (r + 1) as f32 / rings as f32).cos();
            if low < floor {
                continue;
            }
            for t in [[a, d, c], [a, c, b]] {
                if t[0] != t[1] && t[1] != t[2] && t[0] != t[2] {
                    faces.push(t);
                }
            }
        }
    }
    for [a, b, c] in faces {
        text.push_str(&format!("f {a} {b} {c}\n"));
    }
    text
}

#[test]
fn spot_imports_as_one_closed_genus_zero_piece_near_its_mesh() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/data/spot.obj");
    let o = import_and_measure(&path, &ImportSettings::default());
    report("spot", &o);
    assert!(matches!(o.path, FitPath::ClosedMesh(_)), "{:?}", o.path);
    assert_eq!(o.pieces, vec![(2, true)], "one closed piece of genus 0");
    assert!(
        o.p99_to_input < 1.0,
        "fitted → input p99 {}%",
        o.p99_to_input
    );
    assert!(o.p99_to_fit < 1.0, "input → fitted p99 {}%", o.p99_to_fit);
}

#[test]
fn a_sphere_open_through_a_wide_hole_at_its_base_imports_closed_in_one_piece() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("open-ball.obj");
    // Triangles below y = −0.95 removed: a hole about 0.62 wide, 31% of the sphere's size.
    std::fs::write(&path, sphere_obj(48, 96, -0.95)).unwrap();
    let o = import_and_measure(&path, &ImportSettings::default());
    report("open sphere", &o);
    let FitPath::CappedMesh(check) = o.path else {
        panic!("{:?}", o.path)
    };
    assert!(check.boundary_edges > 0);
    assert!(
        o.notes.iter().any(|l| l.contains("capped 1 hole (")),
        "{:?}",
        o.notes
    );
    assert_eq!(o.pieces, vec![(2, true)], "one closed piece of genus 0");
    // The cap is no part of the input: the input lies on the fit, and the fit on the input
    // but for the cap (a few percent of the area).
    assert!(o.p99_to_fit < 1.0, "input → fitted p99 {}%", o.p99_to_fit);
}

#[test]
#[ignore = "needs DYNACLAY_MODELS, a folder of the public models"]
fn public_models() {
    let folder = std::env::var("DYNACLAY_MODELS").expect("DYNACLAY_MODELS");
    for name in ["spot", "stanford-bunny", "fandisk", "rocker-arm"] {
        let path = Path::new(&folder).join(format!("{name}.obj"));
        if path.exists() {
            report(name, &import_and_measure(&path, &ImportSettings::default()));
        }
    }
}
