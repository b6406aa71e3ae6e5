//! A PLY cloud's per-vertex colours become the imported clay's paint: a sphere cloud red on
//! its upper half and blue on its lower half imports with red paint on the fitted surface above
//! the equator and blue below it (sampled at surface points away from the equator, where the
//! fit cannot be blamed for blending the two); the same cloud without colours imports
//! unpainted; colour properties that are odd are either read past (red or green without blue), refused with the line that has them
//! or read as clamped values, never a panic.

use std::path::Path;

use dynaclay_import::fit::{ImportSettings, import_cloud, import_session};
use glam::Vec3;

/// `n` points on the unit sphere (a Fibonacci spiral) with outward normals.
fn sphere(n: usize) -> Vec<Vec3> {
    let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
    (0..n)
        .map(|i| {
            let y = 1.0 - 2.0 * (i as f32 + 0.5) / n as f32;
            let r = (1.0 - y * y).sqrt();
            let t = golden * i as f32;
            Vec3::new(r * t.cos(), y, r * t.sin())
        })
        .collect()
}

/// An ASCII PLY of `points` with normals, and with `colour(p)` as `red green blue` (uchar)
/// when given.
fn write_ply(path: &Path, points: &[Vec3], colour: Option<&dyn Fn(Vec3) -> [u8; 3]>) {
    let mut text = format!(
        "ply\nformat ascii 1.0\nelement vertex {}\nproperty float x\nproperty float y\n\
         property float z\nproperty float nx\nproperty float ny\nproperty float nz\n",
        points.len()
    );
    if colour.is_some() {
        text.push_str("property uchar red\nproperty uchar green\nproperty uchar blue\n");
    }
    text.push_str("end_header\n");
    for &p in points {
        text.push_str(&format!("{} {} {} {} {} {}", p.x, p.y, p.z, p.x, p.y, p.z));
        if let Some(colour) = colour {
            let [r, g, b] = colour(p);
            text.push_str(&format!(" {r} {g} {b}"));
        }
        text.push('\n');
    }
    std::fs::write(path, text).unwrap();
}

fn settings() -> ImportSettings {
    ImportSettings {
        resolution: 16,
        resolution_from_points: false,
        max_depth: 0,
        ..ImportSettings::default()
    }
}

fn red_above_blue_below(p: Vec3) -> [u8; 3] {
    if p.y >= 0.0 { [255, 0, 0] } else { [0, 0, 255] }
}

#[test]
fn a_two_coloured_sphere_imports_painted_red_above_and_blue_below() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("ball.ply");
    write_ply(&path, &sphere(3000), Some(&red_above_blue_below));
    let mut notes = Vec::new();
    let imported = import_cloud(&path, &settings(), &mut |_| true, &mut |l| notes.push(l)).unwrap();
    assert!(
        notes
            .iter()
            .any(|l| l.contains("painted from the points' colours")),
        "{notes:?}"
    );
    let (to_field, centre) = (imported.fit.clone(), imported.fit.to_field(Vec3::ZERO));
    let session = imported.into_session(&path, 0);
    let paint = session.clay.colour.as_ref().expect("the clay is painted");
    assert!(paint.is_consistent());
    let density = &session.clay.density;
    // The colour lattices lie on the base lattice's nodes, as the paint brush's do.
    let base = density.base();
    assert_eq!(paint.channels[0].dims, base.dims);
    assert_eq!(paint.channels[0].origin, base.origin);
    assert_eq!(paint.channels[0].spacing, base.spacing);
    let radius = to_field.to_field(Vec3::X).x - centre.x;
    let (mut worst_red, mut worst_blue) = (f32::MAX, f32::MAX);
    let mut checked = 0;
    for d in sphere(400) {
        // Away from the equator: the two colours meet there, and the fit blends them.
        if d.y.abs() < 0.4 {
            continue;
        }
        // The fitted surface along the ray from the centre (inside above the iso-level).
        let (mut inside, mut outside) = (0.0f32, 2.0 * radius);
        assert!(density.value(centre + d * outside) < density.iso());
        for _ in 0..40 {
            let mid = 0.5 * (inside + outside);
            if density.value(centre + d * mid) > density.iso() {
                inside = mid;
            } else {
                outside = mid;
            }
        }
        let at = centre + d * inside;
        let rgba = paint.rgba(at);
        assert!(rgba.w > 0.99, "coverage {rgba} at {d}");
        let (want, other) = if d.y > 0.0 {
            (rgba.x, rgba.z)
        } else {
            (rgba.z, rgba.x)
        };
        assert!(
            want > 0.9 && other < 0.1 && rgba.y < 0.1,
            "{rgba} on the {} half at {d}",
            if d.y > 0.0 { "red" } else { "blue" }
        );
        if d.y > 0.0 {
            worst_red = worst_red.min(rgba.x);
        } else {
            worst_blue = worst_blue.min(rgba.z);
        }
        checked += 1;
    }
    println!("{checked} surface points: red ≥ {worst_red:.3} above, blue ≥ {worst_blue:.3} below");
    assert!(checked > 200);
}

#[test]
fn a_cloud_without_colours_imports_unpainted() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("plain.ply");
    write_ply(&path, &sphere(1500), None);
    let session = import_session(&path, &settings(), &mut |_| true, &mut |_| {}).unwrap();
    assert!(session.clay.colour.is_none());
}

#[test]
fn odd_colour_properties_are_refused_by_line_or_read_clamped() {
    let dir = tempfile::tempdir().unwrap();
    let points = sphere(1500);
    let body: String = points
        .iter()
        .map(|p| format!("{} {} {} {} {} {} 300 -4\n", p.x, p.y, p.z, p.x, p.y, p.z))
        .collect();
    let header = |colour_lines: &str| {
        format!(
            "ply\nformat ascii 1.0\nelement vertex {}\nproperty float x\nproperty float y\n\
             property float z\nproperty float nx\nproperty float ny\nproperty float nz\n\
             {colour_lines}end_header\n",
            points.len()
        )
    };
    // Red and green without blue: not colours (valid PLY properties of other meaning), so the
    // clay imports unpainted.
    let partial = dir.path().join("partial.ply");
    std::fs::write(
        &partial,
        header("property int red\nproperty int green\n") + &body,
    )
    .unwrap();
    let session = import_session(&partial, &settings(), &mut |_| true, &mut |_| {}).unwrap();
    assert!(
        session.clay.colour.is_none(),
        "red and green alone paint nothing"
    );
    // Integers out of 0..=255 and a colour channel as a float: clamped, and the clay painted.
    let clamped = dir.path().join("clamped.ply");
    let body3: String = points
        .iter()
        .map(|p| {
            format!(
                "{} {} {} {} {} {} 300 -4 0.5\n",
                p.x, p.y, p.z, p.x, p.y, p.z
            )
        })
        .collect();
    std::fs::write(
        &clamped,
        header("property int red\nproperty short green\nproperty double blue\n") + &body3,
    )
    .unwrap();
    let imported = import_cloud(&clamped, &settings(), &mut |_| true, &mut |_| {}).unwrap();
    let colours = imported.colours.as_ref().unwrap();
    assert!(
        colours.iter().all(|&c| c == [255, 0, 128]),
        "{:?}",
        colours[0]
    );
    let at = imported.fit.to_field(Vec3::Y);
    let rgba = imported.paint.as_ref().unwrap().rgba(at);
    assert!(
        (rgba - glam::Vec4::new(1.0, 0.0, 128.0 / 255.0, 1.0))
            .abs()
            .max_element()
            < 0.02
    );
    // A colour given as a list per vertex: refused.
    let listed = dir.path().join("listed.ply");
    std::fs::write(&listed, header("property list uchar uchar red\n") + &body).unwrap();
    let e = import_session(&listed, &settings(), &mut |_| true, &mut |_| {}).unwrap_err();
    assert!(e.to_string().contains("listed.ply:10"), "{e}");
}
