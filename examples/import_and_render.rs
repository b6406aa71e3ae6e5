//! Import a point cloud as a clay and render it to a PNG offscreen.
//!
//! A torus is sampled as 20 000 oriented points and written as an `.xyz` file (six numbers a
//! line: position and normal), fitted as a clay (the base lattice and its detail patches),
//! meshed, checked against the analytic torus, and drawn through the window's own renderer
//! into an image. Run with
//!
//! ```text
//! cargo run --release --example import_and_render [OUT.png]
//! ```
//!
//! Rendering needs a GPU adapter (a software one such as lavapipe will do); without one the
//! example says so and stops after the import, unless `DYNACLAY_REQUIRE_GPU=1` makes that a
//! failure.

use std::error::Error;
use std::f32::consts::TAU;
use std::fmt::Write as _;
use std::path::PathBuf;

use dynaclay::fit::{ImportSettings, fit_import};
use dynaclay::io::{OutputKind, OutputRule};
use dynaclay::mesh::{BrickOctree, SampleGrid};
use dynaclay::render::{
    NamedView, SceneOptions, chunk_views, gpu_required, octree_chunks, render_to_png, scene_camera,
};
use glam::Vec3;

/// The torus: ring radius `R`, tube radius `r`.
const R: f32 = 1.0;
const TUBE: f32 = 0.4;

fn main() {
    if let Err(e) = run() {
        eprintln!("import_and_render: {e}");
        std::process::exit(1);
    }
}

fn run() -> Result<(), Box<dyn Error>> {
    let out = match std::env::args_os().nth(1) {
        Some(path) => PathBuf::from(path),
        None => std::env::temp_dir().join(format!("dynaclay-torus-{}.png", std::process::id())),
    };
    // As every dynaclay output: an image file, never over a file of another kind, checked first.
    OutputRule::new().check("OUT.png", &out, OutputKind::Image)?;
    let work = std::env::temp_dir().join(format!("dynaclay-example-{}", std::process::id()));
    std::fs::create_dir_all(&work)?;
    let cloud_path = work.join("torus.xyz");

    // 20 000 points on a torus (a golden-angle lattice in its two angles), with normals.
    let n = 20_000;
    let mut text = String::new();
    for i in 0..n {
        let u = TAU * (i as f32 / n as f32);
        let v = TAU * ((i as f32 * 0.618_034) % 1.0);
        let ring = Vec3::new(u.cos(), 0.0, u.sin());
        let normal = ring * v.cos() + Vec3::Y * v.sin();
        let p = ring * R + normal * TUBE;
        writeln!(
            text,
            "{} {} {} {} {} {}",
            p.x, p.y, p.z, normal.x, normal.y, normal.z
        )?;
    }
    std::fs::write(&cloud_path, text)?;

    // Fit it; the fit maps the file's units into field units (`to_field`).
    let fit = fit_import(
        &cloud_path,
        &ImportSettings::default(),
        &mut |_| true,
        &mut |line| println!("import: {line}"),
    )?;
    std::fs::remove_dir_all(&work)?;
    let field = &fit.field;
    let octree = BrickOctree::build(SampleGrid::for_field(field, 4)?, field);
    let mesh = octree.weld();

    // How far the imported surface lies from the torus, in the file's units.
    let torus_distance = |p: Vec3| {
        let ring = Vec3::new(p.x, 0.0, p.z).length() - R;
        (ring * ring + p.y * p.y).sqrt() - TUBE
    };
    let mut errors: Vec<f32> = mesh
        .positions
        .iter()
        .map(|&p| torus_distance((p - fit.offset) / fit.scale).abs())
        .collect();
    errors.sort_by(f32::total_cmp);
    let diameter = 2.0 * (R + TUBE);
    println!(
        "imported {} patches, {} triangles; distance to the torus p50 {:.3}% / max {:.3}% of its diameter",
        field.patches.len(),
        mesh.triangles.len(),
        100.0 * errors[errors.len() / 2] / diameter,
        100.0 * errors[errors.len() - 1] / diameter
    );

    // Draw it through the window's renderer, offscreen.
    let chunks = octree_chunks(&octree, None);
    let views = chunk_views(&chunks);
    let options = SceneOptions::default();
    let camera = scene_camera(NamedView::Iso, &views, &options);
    match render_to_png(&views, &options, &camera, 640, 480, &out) {
        Ok(outcome) => println!(
            "wrote {} ({} triangles drawn)",
            outcome.path.display(),
            outcome.triangles
        ),
        Err(e) if e.is_no_adapter() && !gpu_required() => {
            println!("no GPU adapter here, so no image: {e}");
        }
        Err(e) => return Err(e.into()),
    }
    Ok(())
}
