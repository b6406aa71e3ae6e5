//! Detail where the brush is fine and room where the clay goes, judged on what a run exports:
//! a script's remove brush of 1/256 of the default clay's size, with no refine step, carves a
//! groove whose width on `sculpt.obj` is within 25% of the brush's chord; and an add stroke
//! that leaves the starting box extends the exported clay past it, rounded (no flat face where
//! the box was).

use std::path::Path;
use std::process::Command;

use glam::Vec3;

const BIN: &str = env!("CARGO_BIN_EXE_dynaclay");

/// The default block: a 24³ lattice of knot spacing 0.1 from the origin (2.3 across); the
/// block's top face is at y = 1.725, its middle at x = z = 1.15.
const SIZE: f32 = 2.3;
const TOP_Y: f32 = 1.725;
const MID: f32 = 1.15;

/// Runs `script` in lockstep into `dir/out`; returns the exported mesh (vertices, triangles).
fn run(dir: &Path, script: &str) -> (Vec<Vec3>, Vec<[usize; 3]>) {
    let path = dir.join("script.toml");
    std::fs::write(&path, script).unwrap();
    let out = dir.join("out");
    let run = Command::new(BIN)
        .args(["run", "--lockstep", "--no-rt", "--script"])
        .arg(&path)
        .arg("--out")
        .arg(&out)
        .output()
        .expect("binary runs");
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let text = std::fs::read_to_string(out.join("sculpt.obj")).unwrap();
    let numbers = |l: &str| -> Vec<f32> {
        l.split_whitespace()
            .map(|x| x.split('/').next().unwrap().parse().unwrap())
            .collect()
    };
    let mut vertices = Vec::new();
    let mut triangles = Vec::new();
    for line in text.lines() {
        if let Some(v) = line.strip_prefix("v ") {
            let v = numbers(v);
            vertices.push(Vec3::new(v[0], v[1], v[2]));
        } else if let Some(f) = line.strip_prefix("f ") {
            let f = numbers(f);
            triangles.push([f[0] as usize - 1, f[1] as usize - 1, f[2] as usize - 1]);
        }
    }
    (vertices, triangles)
}

/// Where the line `from + t · dir` crosses the triangles (Möller–Trumbore), as `t`s.
fn crossings(vertices: &[Vec3], triangles: &[[usize; 3]], from: Vec3, dir: Vec3) -> Vec<f32> {
    let mut out = Vec::new();
    for t in triangles {
        let [a, b, c] = t.map(|i| vertices[i]);
        let (e1, e2) = (b - a, c - a);
        let p = dir.cross(e2);
        let det = e1.dot(p);
        if det.abs() < 1e-12 {
            continue;
        }
        let s = from - a;
        let u = s.dot(p) / det;
        let q = s.cross(e1);
        let v = dir.dot(q) / det;
        if u < 0.0 || v < 0.0 || u + v > 1.0 {
            continue;
        }
        out.push(e2.dot(q) / det);
    }
    out
}

#[test]
fn a_brush_of_a_256th_of_the_clay_carves_a_groove_of_its_width_on_the_exported_mesh() {
    let dir = tempfile::tempdir().unwrap();
    let radius = 0.5 * SIZE / 256.0;
    // Centred on the top face, along x, for 0.04 field units.
    let positions: Vec<String> = (0..=16)
        .map(|n| format!("[{}, {TOP_Y}, {MID}]", MID - 0.02 + 0.0025 * n as f32))
        .collect();
    let script = format!(
        "version = 1\n[[step]]\ndo = \"tool\"\nshape = {{ kind = \"sphere\", radius_fu = {radius} }}\n\
         action = {{ kind = \"remove\" }}\npositions = [{}]\nduration_s = 1.0\nfalloff_fu = {}\n",
        positions.join(", "),
        0.25 * radius
    );
    let (vertices, triangles) = run(dir.path(), &script);
    // Across the groove half a radius below the top, in the stroke's middle.
    let depth = 0.5 * radius;
    let from = Vec3::new(MID, TOP_Y - depth, MID);
    let hits = crossings(&vertices, &triangles, from, Vec3::Z);
    let right = hits
        .iter()
        .copied()
        .filter(|&t| t > 0.0)
        .fold(f32::INFINITY, f32::min);
    let left = hits
        .iter()
        .copied()
        .filter(|&t| t < 0.0)
        .fold(f32::NEG_INFINITY, f32::max);
    let groove = right - left;
    let chord = 2.0 * (radius * radius - depth * depth).sqrt();
    eprintln!(
        "brush {:.5} wide: groove {groove:.5} on sculpt.obj ({} triangles), chord {chord:.5}, {:+.1}%",
        2.0 * radius,
        triangles.len(),
        100.0 * (groove - chord) / chord
    );
    assert!(
        (groove - chord).abs() <= 0.25 * chord,
        "groove {groove} against the brush's chord {chord}"
    );
}

#[test]
fn an_add_stroke_past_the_box_extends_the_exported_clay_beyond_it_rounded() {
    let dir = tempfile::tempdir().unwrap();
    // From the block's +x face out to 0.6 past the lattice's last node (x = 2.3).
    let positions: Vec<String> = (0..=30)
        .map(|n| format!("[{}, {MID}, {MID}]", 1.7 + 0.04 * n as f32))
        .collect();
    let script = format!(
        "version = 1\n[[step]]\ndo = \"tool\"\nshape = {{ kind = \"sphere\", radius_fu = 0.2 }}\n\
         action = {{ kind = \"add\", deposit_rate_per_s = 4.0 }}\npositions = [{}]\n\
         duration_s = 6.0\nfalloff_fu = 0.05\n",
        positions.join(", ")
    );
    let (vertices, _) = run(dir.path(), &script);
    let reach = vertices
        .iter()
        .map(|v| v.x)
        .fold(f32::NEG_INFINITY, f32::max);
    // Where the support of the 24³ lattice ended, the clay would have been cut flat.
    let old_support_x = SIZE + 0.2;
    assert!(
        reach > SIZE + 0.6,
        "the clay reaches x = {reach}, past the old support at {old_support_x}"
    );
    // Rounded: near the far end, the clay narrows (no flat face where the box was).
    let width_at = |x: f32| {
        let ys: Vec<f32> = vertices
            .iter()
            .filter(|v| (v.x - x).abs() < 0.02)
            .map(|v| v.y)
            .collect();
        ys.iter().copied().fold(f32::NEG_INFINITY, f32::max)
            - ys.iter().copied().fold(f32::INFINITY, f32::min)
    };
    let (middle, end) = (width_at(SIZE + 0.2), width_at(reach - 0.05));
    eprintln!(
        "clay reaches x = {reach:.3}; height {middle:.3} at the old support, {end:.3} near the end"
    );
    assert!(
        end < middle,
        "the end is rounded: {end} near the tip against {middle} further in"
    );
}
