//! Offscreen frames checked against geometry: the sphere's silhouette against the analytic
//! disk, its shading against a CPU reference (the golden image), a local edit against the
//! region it may touch, and the chunk store's upload counter.
//!
//! These need a GPU adapter (lavapipe or llvmpipe will do). Without one they print
//! "skipped: no GPU adapter" and pass, unless `DYNACLAY_REQUIRE_GPU` is set.

use glam::{Vec2, Vec3};

use super::*;

/// A headless renderer, or `None` (with a note) when the machine has no adapter.
fn offscreen(width: u32, height: u32) -> Option<OffscreenRenderer> {
    match OffscreenRenderer::new(width, height) {
        Ok(r) => Some(r),
        Err(e) if e.is_no_adapter() && !gpu_required() => {
            println!("skipped: {e}");
            None
        }
        Err(e) => panic!("{e} ({REQUIRE_GPU_ENV} is set, so a missing adapter fails)"),
    }
}

/// Owned mesh data of one chunk.
#[derive(Clone, Debug, Default)]
struct OwnedChunk {
    id: u64,
    version: u64,
    positions: Vec<[f32; 3]>,
    normals: Vec<[f32; 3]>,
    colors: Vec<[f32; 4]>,
    indices: Vec<u32>,
}

impl OwnedChunk {
    fn view(&self) -> MeshChunk<'_> {
        MeshChunk {
            id: self.id,
            version: self.version,
            positions: &self.positions,
            normals: &self.normals,
            colors: &self.colors,
            indices: &self.indices,
            cut: false,
        }
    }
}

fn views(chunks: &[OwnedChunk]) -> Vec<MeshChunk<'_>> {
    chunks.iter().map(OwnedChunk::view).collect()
}

/// A UV sphere split into eight chunks by the octant of each triangle's centroid, the way
/// octree bricks split a surface (vertices on a border are duplicated into each chunk).
fn sphere_chunks(centre: Vec3, radius: f32, segments: u32, rings: u32) -> Vec<OwnedChunk> {
    let mut positions = Vec::new();
    let mut normals = Vec::new();
    for r in 0..=rings {
        let theta = std::f32::consts::PI * r as f32 / rings as f32;
        for s in 0..=segments {
            let phi = std::f32::consts::TAU * s as f32 / segments as f32;
            let n = Vec3::new(
                theta.sin() * phi.cos(),
                theta.cos(),
                -theta.sin() * phi.sin(),
            );
            positions.push(centre + n * radius);
            normals.push(n);
        }
    }
    let at = |r: u32, s: u32| r * (segments + 1) + s;
    let mut chunks: Vec<OwnedChunk> = (0..8)
        .map(|i| OwnedChunk {
            id: 100 + i,
            version: 1,
            ..OwnedChunk::default()
        })
        .collect();
    let mut remap = vec![vec![u32::MAX; positions.len()]; 8];
    for r in 0..rings {
        for s in 0..segments {
            let quad = [at(r, s), at(r + 1, s), at(r + 1, s + 1), at(r, s + 1)];
            for tri in [[quad[0], quad[1], quad[2]], [quad[0], quad[2], quad[3]]] {
                let c = (positions[tri[0] as usize]
                    + positions[tri[1] as usize]
                    + positions[tri[2] as usize])
                    / 3.0
                    - centre;
                if (positions[tri[0] as usize] - positions[tri[1] as usize]).length_squared()
                    < 1e-12
                    && (positions[tri[1] as usize] - positions[tri[2] as usize]).length_squared()
                        < 1e-12
                {
                    continue;
                }
                let octant = usize::from(c.x > 0.0)
                    | usize::from(c.y > 0.0) << 1
                    | usize::from(c.z > 0.0) << 2;
                let chunk = &mut chunks[octant];
                for v in tri {
                    let slot = &mut remap[octant][v as usize];
                    if *slot == u32::MAX {
                        *slot = chunk.positions.len() as u32;
                        chunk.positions.push(positions[v as usize].into());
                        chunk.normals.push(normals[v as usize].into());
                    }
                    chunk.indices.push(*slot);
                }
            }
        }
    }
    chunks
}

/// Options for measurement: black background, one white key light from the upper left.
fn plain_options() -> SceneOptions {
    let mut o = SceneOptions {
        background: [0.0, 0.0, 0.0, 1.0],
        ..SceneOptions::default()
    };
    o.shading.material_color = [0.8, 0.8, 0.8];
    o.shading.lights[0] = Light {
        direction: Vec3::new(-0.5, 0.5, 1.0),
        color: [1.0, 1.0, 1.0],
    };
    o.shading.lights[1].color = [0.0; 3];
    o
}

fn front_camera(distance: f32) -> Camera {
    let mut c = Camera::named(NamedView::Front, Vec3::splat(-1.0), Vec3::splat(1.0));
    c.target = Vec3::ZERO;
    c.distance = distance;
    c
}

fn luminance(p: [u8; 4]) -> f32 {
    0.2126 * f32::from(p[0]) + 0.7152 * f32::from(p[1]) + 0.0722 * f32::from(p[2])
}

fn differs(a: [u8; 4], b: [u8; 4], tolerance: u8) -> bool {
    a.iter().zip(b).any(|(&x, y)| x.abs_diff(y) > tolerance)
}

/// Pixel radius of a sphere of `radius` at the target, seen from `distance` (perspective).
fn analytic_disk_radius_px(camera: &Camera, radius: f32, height: u32) -> f32 {
    let alpha = (radius / camera.distance).asin();
    alpha.tan() / (camera.fov_y_rad * 0.5).tan() * height as f32 * 0.5
}

const W: u32 = 256;
const H: u32 = 192;

#[test]
fn sphere_silhouette_matches_the_analytic_disk_and_background_is_clear() {
    let Some(mut r) = offscreen(W, H) else { return };
    let chunks = sphere_chunks(Vec3::ZERO, 1.0, 96, 48);
    let report = r.sync_chunks(&views(&chunks)).unwrap();
    assert_eq!(report.uploaded, 8);
    let camera = front_camera(3.5);
    let options = plain_options();
    let img = r.render(&camera, &options).unwrap();
    assert_eq!((img.width, img.height), (W, H));

    let bg = options.background.map(linear_to_srgb8);
    for (x, y) in [(0, 0), (W - 1, 0), (0, H - 1), (W - 1, H - 1)] {
        assert_eq!(
            img.pixel(x, y).unwrap(),
            bg,
            "corner ({x}, {y}) is not the clear colour"
        );
    }

    let covered = img
        .rgba8
        .chunks_exact(4)
        .filter(|p| differs([p[0], p[1], p[2], p[3]], bg, 2))
        .count();
    let measured = covered as f32 / (W * H) as f32;
    let rho = analytic_disk_radius_px(&camera, 1.0, H);
    let expected = std::f32::consts::PI * rho * rho / (W * H) as f32;
    let rel = (measured - expected).abs() / expected;
    assert!(
        rel < 0.03,
        "covered {measured:.4} vs analytic disk {expected:.4} ({rel:.3} off)"
    );
}

#[test]
fn shading_varies_with_the_normal() {
    let Some(mut r) = offscreen(W, H) else { return };
    let chunks = sphere_chunks(Vec3::ZERO, 1.0, 64, 32);
    r.sync_chunks(&views(&chunks)).unwrap();
    let camera = front_camera(3.5);
    let img = r.render(&camera, &plain_options()).unwrap();
    let rho = analytic_disk_radius_px(&camera, 1.0, H);
    let (cx, cy) = (W as f32 / 2.0, H as f32 / 2.0);
    let sample = |dx: f32, dy: f32| {
        luminance(
            img.pixel((cx + dx * rho) as u32, (cy - dy * rho) as u32)
                .unwrap(),
        )
    };
    // The light is up-left and toward the viewer: that side is brighter than down-right.
    let lit = sample(-0.45, 0.45);
    let unlit = sample(0.6, -0.6);
    let centre = sample(0.0, 0.0);
    let rim = sample(0.0, -0.95);
    assert!(lit > unlit + 40.0, "lit {lit} vs unlit {unlit}");
    assert!((centre - rim).abs() > 15.0, "centre {centre} vs rim {rim}");
}

/// Reference colour of a pixel: ray-cast the analytic sphere and shade it with the same
/// Blinn-Phong model the mesh pass uses. `None` for background or silhouette-edge pixels.
fn reference_pixel(
    camera: &Camera,
    options: &SceneOptions,
    radius: f32,
    x: u32,
    y: u32,
) -> Option<[u8; 3]> {
    let inv = camera.view_projection(W as f32 / H as f32).inverse();
    let ndc = Vec2::new(
        (x as f32 + 0.5) / W as f32 * 2.0 - 1.0,
        1.0 - (y as f32 + 0.5) / H as f32 * 2.0,
    );
    let far = inv.project_point3(ndc.extend(1.0));
    let eye = camera.eye();
    let d = (far - eye).normalize();
    // |eye + t d|² = r²
    let b = eye.dot(d);
    let disc = b * b - (eye.length_squared() - radius * radius);
    if disc < 0.0 {
        return None;
    }
    let t = -b - disc.sqrt();
    let p = eye + d * t;
    let n = p.normalize();
    let v = -d;
    // Skip the silhouette band, where coverage and tessellation dominate.
    if n.dot(v) < 0.25 {
        return None;
    }
    Some(blinn_phong_reference(
        camera,
        options,
        Vec3::from(options.shading.material_color),
        n,
        v,
    ))
}

/// The colour the mesh pass gives a surface point of albedo `albedo` (linear), unit normal
/// `n` and unit direction `v` toward the eye, computed on the CPU: ambient plus each light's
/// Lambert and Blinn-Phong terms (environment off), in 8-bit sRGB.
fn blinn_phong_reference(
    camera: &Camera,
    options: &SceneOptions,
    albedo: Vec3,
    n: Vec3,
    v: Vec3,
) -> [u8; 3] {
    let s = &options.shading;
    let mut lit = albedo * s.ambient;
    let to_world = camera.view().inverse();
    for light in &s.lights {
        let l = to_world.transform_vector3(light.direction).normalize();
        let ndl = n.dot(l).max(0.0);
        let h = (l + v).normalize();
        let spec = if ndl > 0.0 {
            s.specular * n.dot(h).max(0.0).powf(s.shininess)
        } else {
            0.0
        };
        lit += Vec3::from(light.color) * (albedo * ndl + Vec3::splat(spec));
    }
    [
        linear_to_srgb8(lit.x),
        linear_to_srgb8(lit.y),
        linear_to_srgb8(lit.z),
    ]
}

#[test]
fn golden_sphere_matches_a_ray_cast_reference_within_tolerance() {
    let Some(mut r) = offscreen(W, H) else { return };
    let chunks = sphere_chunks(Vec3::ZERO, 1.0, 128, 64);
    r.sync_chunks(&views(&chunks)).unwrap();
    let camera = front_camera(3.5);
    let options = plain_options();
    let img = r.render(&camera, &options).unwrap();
    let mut errors = Vec::new();
    for y in 0..H {
        for x in 0..W {
            if let Some(want) = reference_pixel(&camera, &options, 1.0, x, y) {
                let got = img.pixel(x, y).unwrap();
                let e = (0..3).map(|c| got[c].abs_diff(want[c])).max().unwrap_or(0);
                errors.push(e);
            }
        }
    }
    assert!(
        errors.len() > 5000,
        "reference covers {} pixels",
        errors.len()
    );
    errors.sort_unstable();
    let mean = errors.iter().map(|&e| f64::from(e)).sum::<f64>() / errors.len() as f64;
    let p99 = errors[errors.len() * 99 / 100];
    assert!(mean < 2.0, "mean channel error {mean:.2} levels");
    assert!(p99 <= 8, "99th percentile channel error {p99} levels");
}

#[test]
fn a_local_edit_changes_only_pixels_near_the_edit() {
    let Some(mut r) = offscreen(W, H) else { return };
    let mut chunks = sphere_chunks(Vec3::ZERO, 1.0, 64, 32);
    r.sync_chunks(&views(&chunks)).unwrap();
    let camera = front_camera(3.5);
    let options = plain_options();
    let before = r.render(&camera, &options).unwrap();

    // Push a bump out of the front-upper-right octant's chunk (+x, +y, +z → octant 7).
    let centre = Vec3::new(0.45, 0.45, 0.77).normalize();
    let edit_radius = 0.25;
    let chunk = &mut chunks[7];
    let mut touched = vec![false; chunk.positions.len()];
    for (i, (p, n)) in chunk
        .positions
        .iter_mut()
        .zip(&mut chunk.normals)
        .enumerate()
    {
        let d = (Vec3::from(*p) - centre).length();
        if d < edit_radius {
            let w = 1.0 - (d / edit_radius).powi(2);
            let tilt = (Vec3::from(*p) - centre) * 2.0 * w;
            *p = (Vec3::from(*p) + Vec3::from(*n) * 0.12 * w * w).into();
            *n = (Vec3::from(*n) + tilt).normalize().into();
            touched[i] = true;
        }
    }
    assert!(touched.iter().filter(|&&t| t).count() > 5);
    chunk.version += 1;
    // The region a frame may change: every triangle touching a moved vertex, before and after.
    let vp = camera.view_projection(W as f32 / H as f32);
    let (mut lo, mut hi) = (Vec2::splat(f32::MAX), Vec2::splat(f32::MIN));
    let original = sphere_chunks(Vec3::ZERO, 1.0, 64, 32);
    for tri in chunk.indices.chunks_exact(3) {
        if tri.iter().any(|&i| touched[i as usize]) {
            for &i in tri {
                for p in [
                    chunk.positions[i as usize],
                    original[7].positions[i as usize],
                ] {
                    let ndc = vp.project_point3(Vec3::from(p));
                    let px = Vec2::new(
                        (ndc.x + 1.0) * 0.5 * W as f32,
                        (1.0 - ndc.y) * 0.5 * H as f32,
                    );
                    lo = lo.min(px);
                    hi = hi.max(px);
                }
            }
        }
    }
    let (lo, hi) = (lo - Vec2::splat(2.0), hi + Vec2::splat(2.0));

    let report = r.sync_chunks(&views(&chunks)).unwrap();
    assert_eq!(report.uploaded, 1, "only the edited chunk is uploaded");
    let after = r.render(&camera, &options).unwrap();
    let mut changed = 0;
    for y in 0..H {
        for x in 0..W {
            if differs(before.pixel(x, y).unwrap(), after.pixel(x, y).unwrap(), 2) {
                changed += 1;
                let p = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
                assert!(
                    p.cmpge(lo).all() && p.cmple(hi).all(),
                    "pixel ({x}, {y}) changed outside the edit's region {lo}..{hi}"
                );
            }
        }
    }
    assert!(
        changed > 30,
        "the edit is visible ({changed} pixels changed)"
    );
}

#[test]
fn only_dirty_chunks_are_uploaded_and_absent_ones_are_dropped() {
    let Some(mut r) = offscreen(32, 32) else {
        return;
    };
    let mut chunks = sphere_chunks(Vec3::ZERO, 1.0, 16, 8);
    let first = r.sync_chunks(&views(&chunks)).unwrap();
    assert_eq!((first.uploaded, first.resident), (8, 8));
    let stats = r.renderer().upload_stats();
    assert_eq!(stats.chunk_uploads, 8);

    let again = r.sync_chunks(&views(&chunks)).unwrap();
    assert_eq!(again.uploaded, 0);
    assert_eq!(
        r.renderer().upload_stats(),
        stats,
        "unchanged chunks cost no upload"
    );

    chunks[3].version += 1;
    let one = r.sync_chunks(&views(&chunks)).unwrap();
    assert_eq!(one.uploaded, 1);
    let after = r.renderer().upload_stats();
    assert_eq!(after.chunk_uploads, 9);
    assert_eq!(
        after.buffers_created, stats.buffers_created,
        "same-size data reuses the buffers"
    );
    let chunk_bytes =
        (chunks[3].positions.len() * size_of::<MeshVertex>() + chunks[3].indices.len() * 4) as u64;
    assert_eq!(after.bytes_uploaded - stats.bytes_uploaded, chunk_bytes);

    let removed = chunks.remove(5);
    let dropped = r.sync_chunks(&views(&chunks)).unwrap();
    assert_eq!(
        (dropped.uploaded, dropped.removed, dropped.resident),
        (0, 1, 7)
    );
    chunks.push(removed);
    assert_eq!(
        r.sync_chunks(&views(&chunks)).unwrap().uploaded,
        1,
        "a returning chunk is uploaded"
    );

    let mut dup = views(&chunks);
    dup.push(dup[0]);
    assert!(matches!(
        r.sync_chunks(&dup),
        Err(RenderError::Chunk(ChunkError::DuplicateId { .. }))
    ));
    let mut bad = chunks[0].clone();
    bad.version += 1;
    bad.indices.push(0);
    let err = r.sync_chunks(&[bad.view()]).unwrap_err();
    assert!(
        err.to_string().contains("not a whole number of triangles"),
        "{err}"
    );
}

#[test]
fn environment_modes_follow_their_definitions() {
    let Some(mut r) = offscreen(128, 96) else {
        return;
    };
    let chunks = sphere_chunks(Vec3::ZERO, 1.0, 64, 32);
    r.sync_chunks(&views(&chunks)).unwrap();
    let camera = front_camera(3.5);
    let mut o = plain_options();
    let off = r.render(&camera, &o).unwrap();
    o.shading.environment = EnvironmentMode::Transparent;
    o.shading.environment_opacity = 0.0;
    assert_eq!(
        r.render(&camera, &o).unwrap(),
        off,
        "a fully transparent layer shows nothing"
    );
    o.shading.environment = EnvironmentMode::Opaque;
    let opaque = r.render(&camera, &o).unwrap();
    assert_ne!(opaque, off);
    o.shading.environment = EnvironmentMode::ClearCoat;
    o.shading.environment_opacity = 1.0;
    assert_eq!(
        r.render(&camera, &o).unwrap(),
        opaque,
        "an opaque coat is the opaque texture"
    );
    o.shading.environment_opacity = 0.0;
    let coat = r.render(&camera, &o).unwrap();
    // Facing the viewer the coat is clear; toward the rim it reflects the environment.
    let rho = analytic_disk_radius_px(&camera, 1.0, 96);
    let mean_diff = |lo: f32, hi: f32| {
        let (mut sum, mut n) = (0.0, 0);
        for y in 0..96 {
            for x in 0..128 {
                let d = Vec2::new(x as f32 + 0.5 - 64.0, y as f32 + 0.5 - 48.0).length() / rho;
                if (lo..hi).contains(&d) {
                    let (a, b) = (coat.pixel(x, y).unwrap(), off.pixel(x, y).unwrap());
                    sum += (0..3).map(|c| f32::from(a[c].abs_diff(b[c]))).sum::<f32>() / 3.0;
                    n += 1;
                }
            }
        }
        sum / n.max(1) as f32
    };
    let (centre, rim) = (mean_diff(0.0, 0.3), mean_diff(0.9, 0.98));
    assert!(
        centre < 1.0,
        "clear coat facing the viewer changes the colour by {centre}"
    );
    assert!(
        rim > 3.0 && rim > 5.0 * centre,
        "clear coat at the rim: {rim} vs centre {centre}"
    );
}

#[test]
fn paint_overlays_and_msaa_show_in_the_frame() {
    let Some(mut r) = offscreen(W, H) else { return };
    let mut chunks = sphere_chunks(Vec3::ZERO, 1.0, 64, 32);
    for c in &mut chunks {
        c.colors = vec![[0.9, 0.05, 0.05, 1.0]; c.positions.len()];
    }
    r.sync_chunks(&views(&chunks)).unwrap();
    let camera = front_camera(3.5);
    let mut o = plain_options();
    let img = r.render(&camera, &o).unwrap();
    let centre = img.pixel(W / 2, H / 2).unwrap();
    assert!(
        centre[0] > 2 * centre[1].max(1) && centre[0] > 100,
        "painted red: {centre:?}"
    );

    // A see-through tool to the left of the sphere, a force arrow and a workspace box.
    let tool_centre = Vec3::new(-1.6, 0.0, 0.0);
    o.tool = Some(ToolOverlay {
        centre: tool_centre,
        radius: 0.3,
        style: ToolStyle::Transparent,
        color: [0.2, 0.5, 1.0, 0.4],
    });
    o.force = Some(ForceOverlay {
        origin: Vec3::new(1.2, -0.8, 0.0),
        force_n: Vec3::new(0.0, 1.0, 0.0),
        length_per_newton: 0.5,
        color: [1.0, 1.0, 0.0, 1.0],
    });
    o.workspace_box = Some(BoxOverlay {
        min: Vec3::splat(-1.25),
        max: Vec3::splat(1.25),
        color: [0.0, 1.0, 0.0, 1.0],
    });
    let with = r.render(&camera, &o).unwrap();
    let vp = camera.view_projection(W as f32 / H as f32);
    let to_px = |p: Vec3| {
        let n = vp.project_point3(p);
        (
            ((n.x + 1.0) * 0.5 * W as f32) as u32,
            ((1.0 - n.y) * 0.5 * H as f32) as u32,
        )
    };
    let (tx, ty) = to_px(tool_centre);
    let tool = with.pixel(tx, ty).unwrap();
    assert!(
        tool[2] > tool[0] + 20 && tool[2] > 40,
        "blue see-through tool: {tool:?}"
    );
    let (ax, ay) = to_px(Vec3::new(1.2, -0.6, 0.0));
    let arrow = (ax.saturating_sub(1)..=ax + 1).any(|x| {
        let p = with.pixel(x, ay).unwrap();
        p[0] > 100 && p[1] > 100 && p[2] < 60
    });
    assert!(arrow, "yellow force arrow near ({ax}, {ay})");
    let green = with
        .rgba8
        .chunks_exact(4)
        .filter(|p| p[1] > 100 && p[0] < 60 && p[2] < 60)
        .count();
    assert!(green > 100, "workspace box edges: {green} green pixels");
    if r.renderer().sample_count() > 1 {
        // Multisampling leaves intermediate shades along the silhouette.
        let bg = o.background.map(linear_to_srgb8);
        let row = H / 2;
        let edge = (0..W).any(|x| {
            let p = img.pixel(x, row).unwrap();
            p != bg && p[0] < centre[0] / 3 && p[0] > bg[0] + 2
        });
        assert!(edge, "anti-aliased silhouette edge on row {row}");
    }
}

#[test]
fn render_to_png_writes_a_readable_file_and_reports_the_adapter() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sphere.png");
    let chunks = sphere_chunks(Vec3::ZERO, 1.0, 32, 16);
    let v = views(&chunks);
    let options = SceneOptions::default();
    let camera = scene_camera(NamedView::Iso, &v, &options);
    match render_to_png(&v, &options, &camera, 80, 0, &path) {
        Ok(outcome) => {
            println!(
                "rendered on {} with {}x MSAA",
                outcome.adapter, outcome.sample_count
            );
            assert_eq!(
                (outcome.width, outcome.height),
                (80, 1),
                "sizes are clamped to 1"
            );
            assert!(!outcome.adapter.name.is_empty());
            assert_eq!(
                outcome.triangles,
                chunks.iter().map(|c| c.indices.len() / 3).sum::<usize>()
            );
            let img = Image::read_png(&path).unwrap();
            assert_eq!((img.width, img.height), (80, 1));
        }
        Err(e) if e.is_no_adapter() && !gpu_required() => println!("skipped: {e}"),
        Err(e) => panic!("{e}"),
    }
}

#[test]
fn no_adapter_error_is_worded_for_users() {
    let e = RenderError::NoAdapter {
        tried: vec!["Vulkan (no adapter)".into(), "GL (no adapter)".into()],
    };
    assert!(e.is_no_adapter());
    assert_eq!(
        e.to_string(),
        "no GPU adapter: tried Vulkan (no adapter); GL (no adapter)"
    );
}

/// Writes one frame per environment mode, with every overlay, for a person to look at:
/// `DYNACLAY_RENDER_SAMPLES=/tmp/frames cargo test --release --lib sample_frames -- --ignored`.
#[test]
#[ignore = "writes sample images for visual review"]
fn sample_frames() {
    let Ok(dir) = std::env::var("DYNACLAY_RENDER_SAMPLES") else {
        println!("set DYNACLAY_RENDER_SAMPLES to a directory");
        return;
    };
    let Some(mut r) = offscreen(640, 480) else {
        return;
    };
    let mut chunks = sphere_chunks(Vec3::ZERO, 1.0, 128, 64);
    for c in &mut chunks[..2] {
        c.colors = vec![[0.1, 0.3, 0.9, 0.8]; c.positions.len()];
    }
    r.sync_chunks(&views(&chunks)).unwrap();
    let mut o = SceneOptions {
        tool: Some(ToolOverlay {
            centre: Vec3::new(0.9, 0.9, 0.6),
            radius: 0.35,
            style: ToolStyle::Transparent,
            color: [0.3, 0.6, 1.0, 0.35],
        }),
        force: Some(ForceOverlay {
            origin: Vec3::new(0.9, 0.9, 0.6),
            force_n: Vec3::new(-0.4, -0.6, -0.2),
            length_per_newton: 1.0,
            color: [1.0, 0.9, 0.1, 1.0],
        }),
        workspace_box: Some(BoxOverlay {
            min: Vec3::splat(-1.5),
            max: Vec3::splat(1.5),
            color: [0.5, 0.5, 0.55, 1.0],
        }),
        region_box: Some(BoxOverlay {
            min: Vec3::new(0.3, 0.3, 0.0),
            max: Vec3::new(1.4, 1.4, 1.2),
            color: [0.9, 0.3, 0.3, 1.0],
        }),
        ..SceneOptions::default()
    };
    let camera = Camera::named(NamedView::Iso, Vec3::splat(-1.5), Vec3::splat(1.5));
    for (name, mode) in [
        ("off", EnvironmentMode::Off),
        ("opaque", EnvironmentMode::Opaque),
        ("transparent", EnvironmentMode::Transparent),
        ("clearcoat", EnvironmentMode::ClearCoat),
    ] {
        o.shading.environment = mode;
        let path = std::path::Path::new(&dir).join(format!("sphere_{name}.png"));
        r.render(&camera, &o).unwrap().write_png(&path).unwrap();
    }
    o.tool = o.tool.map(|t| ToolOverlay {
        style: ToolStyle::Wireframe,
        ..t
    });
    let path = std::path::Path::new(&dir).join("sphere_wire_tool.png");
    r.render(&camera, &o).unwrap().write_png(&path).unwrap();
}

#[test]
fn a_gpu_allocation_the_device_refuses_is_an_error_value_not_a_panic() {
    let Some(r) = offscreen(8, 8) else {
        return;
    };
    let gpu = r.gpu();
    let too_big = gpu.device.limits().max_buffer_size.saturating_add(1);
    let err = gpu
        .guarded("a test buffer", |device, _| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("too big"),
                size: too_big,
                usage: wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        })
        .map(|_| ())
        .unwrap_err();
    assert!(
        matches!(
            err,
            RenderError::Gpu { .. } | RenderError::OutOfMemory { .. }
        ),
        "{err}"
    );
    assert!(err.to_string().contains("a test buffer"), "{err}");
    // The scope took the error: the device goes on working.
    gpu.guarded("a small buffer", |device, _| {
        device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("small"),
            size: 256,
            usage: wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        })
    })
    .unwrap();
}

/// A headless GPU context, or `None` (with a note) when the machine has no adapter.
fn context() -> Option<GpuContext> {
    match GpuContext::headless() {
        Ok(g) => Some(g),
        Err(e) if e.is_no_adapter() && !gpu_required() => {
            println!("skipped: {e}");
            None
        }
        Err(e) => panic!("{e} ({REQUIRE_GPU_ENV} is set, so a missing adapter fails)"),
    }
}

#[test]
fn an_error_outside_any_scope_is_counted_and_reported_not_a_panic() {
    let Some(gpu) = context() else {
        return;
    };
    // The handler the GUI installs on eframe's device, on a device made the same way.
    let log = GpuFaultLog::install(&gpu.device, true);
    let too_big = gpu.device.limits().max_buffer_size.saturating_add(1);
    // No error scope here: wgpu's default handler would panic.
    let _invalid = gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("too big, unscoped"),
        size: too_big,
        usage: wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    assert_eq!(log.error_count(), 1);
    let (oom, message) = log.first_error().expect("the first error is kept");
    assert!(
        !oom,
        "a size over the limit is a validation error: {message}"
    );
    assert!(log.lost().is_none());
    let err = log.check("a test buffer").unwrap_err();
    assert!(matches!(err, RenderError::Gpu { .. }), "{err}");
    // A scoped failure is the scope's, not the handler's.
    let scoped = guarded_on(&gpu.device, "a scoped buffer", || {
        gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("too big, scoped"),
            size: too_big,
            usage: wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        })
    });
    assert!(scoped.is_err());
    assert_eq!(log.error_count(), 1, "the scope caught the second one");
}

#[test]
fn a_resize_over_the_texture_limit_is_refused_and_keeps_the_old_target() {
    let Some(gpu) = context() else {
        return;
    };
    let samples = supported_sample_count(&gpu.adapter, OFFSCREEN_FORMAT);
    let mut r = SceneRenderer::new(&gpu.device, &gpu.queue, OFFSCREEN_FORMAT, samples, 16, 8);
    let over = gpu.device.limits().max_texture_dimension_2d + 1;
    let err = r.try_resize(&gpu.device, over, 8).unwrap_err();
    assert!(matches!(err, RenderError::Gpu { .. }), "{err}");
    assert!(err.to_string().contains("the view's textures"), "{err}");
    assert_eq!(r.size(), (16, 8), "the old target stays");
    assert!(r.try_resize(&gpu.device, 32, 24).unwrap(), "a new size");
    assert_eq!(r.size(), (32, 24));
    gpu.check_faults("the test").unwrap();
}

/// Whether a pixel has the particle discs' colour (a saturated green the grey clay and the
/// black background never take).
fn is_disc_colour(p: [u8; 4]) -> bool {
    let want = PARTICLE_DISC_COLOR.map(linear_to_srgb8);
    p[..3].iter().zip(want).all(|(&x, y)| x.abs_diff(y) <= 24)
}

/// Pixel position of world point `p`.
fn to_pixel(camera: &Camera, p: Vec3) -> Vec2 {
    let ndc = camera
        .view_projection(W as f32 / H as f32)
        .project_point3(p);
    Vec2::new(
        (ndc.x + 1.0) * 0.5 * W as f32,
        (1.0 - ndc.y) * 0.5 * H as f32,
    )
}

#[test]
fn particle_discs_appear_where_the_particles_are_and_the_clay_hides_those_behind_it() {
    let Some(mut r) = offscreen(W, H) else { return };
    let chunks = sphere_chunks(Vec3::ZERO, 1.0, 64, 32);
    r.sync_chunks(&views(&chunks)).unwrap();
    let camera = front_camera(3.5);
    let options = plain_options();
    let count = |img: &Image| {
        img.rgba8
            .chunks_exact(4)
            .filter(|p| is_disc_colour([p[0], p[1], p[2], p[3]]))
            .count()
    };
    let bare = r.render(&camera, &options).unwrap();
    assert_eq!(count(&bare), 0, "no disc colour without particles");

    // Particles on the unit sphere: three facing the camera, one on the far side.
    let toward = camera.eye().normalize();
    let side = toward.any_orthonormal_vector();
    let front = [
        toward,
        (toward + 0.5 * side).normalize(),
        (toward - 0.5 * side).normalize(),
    ];
    // Behind the clay, off the line of the front ones so no front disc covers its pixel.
    let back = (-toward + 0.6 * toward.cross(side)).normalize();
    let radius = 0.4;
    let mut positions: Vec<Vec3> = front.to_vec();
    positions.push(back);
    let normals = positions.clone();
    let radii = vec![radius; positions.len()];
    let mut discs = Vec::new();
    particle_discs(&mut discs, &positions, &normals, &radii);
    assert_eq!(discs.len(), 4);
    r.set_discs(&discs).unwrap();
    assert_eq!(r.renderer().disc_count(), 4);
    let img = r.render(&camera, &options).unwrap();

    // Each front disc covers its particle's pixel, and about the disc's projected area is
    // green around it (its inner 85% is green, the rim darker): the disc's radius in pixels
    // is measured along its edge that faces the camera square on.
    let rd = radius * DISC_SCALE;
    let lifted = |p: Vec3| p * (1.0 + DISC_LIFT * rd);
    let centres: Vec<Vec2> = front
        .iter()
        .map(|p| to_pixel(&camera, lifted(*p)))
        .collect();
    let disc_pxs: Vec<f32> = front
        .iter()
        .map(|p| {
            let t = p
                .cross(toward)
                .try_normalize()
                .unwrap_or(side.cross(toward));
            to_pixel(&camera, lifted(*p) + t * rd).distance(to_pixel(&camera, lifted(*p)))
        })
        .collect();
    let disc_px = disc_pxs.iter().copied().fold(0.0, f32::max);
    for ((p, c), r_px) in front.iter().zip(&centres).zip(&disc_pxs) {
        let disc_px = *r_px;
        let pixel = img.pixel(c.x as u32, c.y as u32).unwrap();
        assert!(is_disc_colour(pixel), "{p} at {c}: {pixel:?}");
        let near = img
            .rgba8
            .chunks_exact(4)
            .enumerate()
            .filter(|(i, px)| {
                let at = Vec2::new((*i as u32 % W) as f32, (*i as u32 / W) as f32);
                at.distance(*c) <= disc_px + 2.0 && is_disc_colour([px[0], px[1], px[2], px[3]])
            })
            .count() as f32;
        let foreshortened = p.dot(toward);
        let expected = std::f32::consts::PI * (0.85 * disc_px).powi(2) * foreshortened;
        assert!(
            near > 0.6 * expected && near < 1.6 * expected,
            "{p}: {near} green pixels, about {expected} expected"
        );
    }
    // No green far from the front discs: the one behind the clay is hidden.
    let hidden = to_pixel(&camera, back);
    assert!(!is_disc_colour(
        img.pixel(hidden.x as u32, hidden.y as u32).unwrap()
    ));
    let stray = img
        .rgba8
        .chunks_exact(4)
        .enumerate()
        .filter(|(i, px)| {
            let at = Vec2::new((*i as u32 % W) as f32, (*i as u32 / W) as f32);
            is_disc_colour([px[0], px[1], px[2], px[3]])
                && centres.iter().all(|c| at.distance(*c) > disc_px + 2.0)
        })
        .count();
    assert_eq!(stray, 0, "disc colour away from every visible particle");

    r.set_discs(&[]).unwrap();
    assert_eq!(count(&r.render(&camera, &options).unwrap()), 0);
}

/// Point-set splats alone (no mesh): discs in each point's own colour cover the sphere's
/// disk without holes, red where the points project left of the centre and blue right of
/// it, and nothing is drawn outside the sphere.
#[test]
fn point_set_splats_cover_the_surface_in_their_colours() {
    let Some(mut r) = offscreen(W, H) else { return };
    let camera = front_camera(3.5);
    let options = plain_options();
    let n = 3000;
    let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
    let positions: Vec<Vec3> = (0..n)
        .map(|i| {
            let y = 1.0 - 2.0 * (i as f32 + 0.5) / n as f32;
            let s = (1.0 - y * y).sqrt();
            let t = golden * i as f32;
            Vec3::new(s * t.cos(), y, s * t.sin())
        })
        .collect();
    // The mean spacing of n points on the unit sphere, about √(4π / n).
    let spacing = (4.0 * std::f32::consts::PI / n as f32).sqrt();
    let centre_x = W as f32 / 2.0;
    let colours: Vec<[u8; 3]> = positions
        .iter()
        .map(|&p| {
            if to_pixel(&camera, p).x < centre_x {
                [255, 0, 0]
            } else {
                [0, 0, 255]
            }
        })
        .collect();
    let mut discs = Vec::new();
    splat_discs(
        &mut discs,
        &positions,
        &positions,
        &colours,
        &vec![spacing; n],
        &[],
    );
    r.set_discs(&discs).unwrap();
    assert_eq!(r.renderer().disc_count(), n);
    let img = r.render(&camera, &options).unwrap();

    let rho = analytic_disk_radius_px(&camera, 1.0, H);
    let (cx, cy) = (W as f32 / 2.0, H as f32 / 2.0);
    let red = |p: [u8; 4]| p[0] > 40 && p[0] > 3 * p[1].max(p[2]);
    let blue = |p: [u8; 4]| p[2] > 40 && p[2] > 3 * p[0].max(p[1]);
    let (mut inside, mut wrong, mut outside_lit) = (0, 0, 0);
    for y in 0..H {
        for x in 0..W {
            let (dx, dy) = (x as f32 + 0.5 - cx, y as f32 + 0.5 - cy);
            let d = (dx * dx + dy * dy).sqrt();
            let p = img.pixel(x, y).unwrap();
            if d < 0.9 * rho && dx.abs() > 0.1 * rho {
                inside += 1;
                let ok = if dx < 0.0 { red(p) } else { blue(p) };
                if !ok {
                    wrong += 1;
                }
            } else if d > 1.1 * rho && luminance(p) > 8.0 {
                outside_lit += 1;
            }
        }
    }
    assert!(inside > 1000, "{inside} pixels inside");
    assert!(
        wrong * 100 <= inside,
        "{wrong} of {inside} pixels inside the disk lack their splat's colour"
    );
    assert_eq!(outside_lit, 0, "nothing outside the sphere");
    r.set_discs(&[]).unwrap();
    assert_eq!(r.renderer().disc_count(), 0);
}

/// A wall thinner than the splats' rim push, seen face on: the near side's splats (blue,
/// facing the eye) and the far side's (red, facing away, a tenth of a radius behind and
/// sampled half a spacing apart, as a wall's two sides are) overlap on screen, and where a
/// near splat's rim is pushed back past the far side's centre the far one would win. Splats
/// are one-sided, so no red pixel shows; drawn two-sided (the same discs with
/// `one_sided: 0`), the far side shows through as specks, which this test also checks so it
/// knows the wall is thin enough to matter.
#[test]
fn a_thin_wall_does_not_show_its_far_side_through_the_splats() {
    let Some(mut r) = offscreen(W, H) else { return };
    let camera = front_camera(3.5);
    assert!(camera.eye().z > 1.0, "the front view looks down -z");
    let options = plain_options();
    let spacing = 0.05;
    let radius = spacing;
    let sheet = |z: f32, offset: f32| -> Vec<Vec3> {
        let steps = (1.2 / spacing) as i32;
        (-steps..=steps)
            .flat_map(|i| {
                (-steps..=steps).map(move |j| {
                    Vec3::new(i as f32 * spacing + offset, j as f32 * spacing + offset, z)
                })
            })
            .collect()
    };
    let near = sheet(0.0, 0.0);
    let far = sheet(-0.1 * radius, 0.5 * spacing);
    let positions: Vec<Vec3> = near.iter().chain(&far).copied().collect();
    let normals: Vec<Vec3> = near
        .iter()
        .map(|_| Vec3::Z)
        .chain(far.iter().map(|_| -Vec3::Z))
        .collect();
    let colours: Vec<[u8; 3]> = near
        .iter()
        .map(|_| [0, 0, 255])
        .chain(far.iter().map(|_| [255, 0, 0]))
        .collect();
    let mut discs = Vec::new();
    let n = positions.len();
    splat_discs(
        &mut discs,
        &positions,
        &normals,
        &colours,
        &vec![radius; n],
        &[],
    );
    assert!(discs.iter().all(|d| d.one_sided == 1));
    let reddish = |img: &Image| {
        let mut count = 0;
        for y in H / 4..3 * H / 4 {
            for x in W / 4..3 * W / 4 {
                let p = img.pixel(x, y).unwrap();
                if p[0] > 40 && p[0] > 2 * p[2] {
                    count += 1;
                }
            }
        }
        count
    };
    r.set_discs(&discs).unwrap();
    let one_sided = r.render(&camera, &options).unwrap();
    assert_eq!(reddish(&one_sided), 0, "the far side shows through");
    let two_sided: Vec<Disc> = discs.iter().map(|d| Disc { one_sided: 0, ..*d }).collect();
    r.set_discs(&two_sided).unwrap();
    let shown = reddish(&r.render(&camera, &options).unwrap());
    assert!(
        shown > 50,
        "two-sided, the far side shows through in {shown} pixels: the wall is too thick to test"
    );
}

#[test]
fn a_software_adapter_gets_one_sample_and_vertex_lit_shading() {
    let mut cpu = wgpu::AdapterInfo::new(wgpu::DeviceType::Cpu, wgpu::Backend::Vulkan);
    cpu.name = "llvmpipe (LLVM 15.0.7, 256 bits)".into();
    // lavapipe does support 4× MSAA: the software profile declines it all the same.
    let soft = ProfileChoice::from_info(&cpu, 4, ProfileRequest::Auto);
    assert_eq!(soft.profile, RenderProfile::Software);
    assert_eq!(
        soft.settings,
        FrameSettings {
            sample_count: 1,
            shading: MeshShading::VertexLit,
            cull_back_faces: true,
            coarse_far_bricks: true,
        }
    );
    assert_eq!(soft.settings, FrameSettings::SOFTWARE);
    assert!(!soft.forced);
    let line = soft.to_string();
    assert!(
        line.contains("llvmpipe") && line.contains("software adapter"),
        "{line}"
    );
    assert_eq!(
        soft.short(),
        "software render: no MSAA, vertex-lit, back faces culled, far bricks coarse"
    );

    for kind in [
        wgpu::DeviceType::DiscreteGpu,
        wgpu::DeviceType::IntegratedGpu,
        wgpu::DeviceType::VirtualGpu,
        wgpu::DeviceType::Other,
    ] {
        let info = wgpu::AdapterInfo::new(kind, wgpu::Backend::Vulkan);
        let full = ProfileChoice::from_info(&info, 4, ProfileRequest::Auto);
        assert_eq!(full.profile, RenderProfile::Full, "{kind:?}");
        assert_eq!(
            full.settings,
            FrameSettings {
                sample_count: PREFERRED_SAMPLES,
                shading: MeshShading::PerPixel,
                cull_back_faces: false,
                coarse_far_bricks: false,
            }
        );
        // Without multisampling support the full profile draws one sample.
        let single = ProfileChoice::from_info(&info, 1, ProfileRequest::Auto);
        assert_eq!(single.settings.sample_count, 1);
        assert_eq!(single.settings.shading, MeshShading::PerPixel);
    }

    // Forced either way, and said so.
    let gpu = wgpu::AdapterInfo::new(wgpu::DeviceType::DiscreteGpu, wgpu::Backend::Vulkan);
    let forced = ProfileChoice::from_info(&gpu, 4, ProfileRequest::Force(RenderProfile::Software));
    assert_eq!(forced.settings, FrameSettings::SOFTWARE);
    assert!(forced.forced && forced.to_string().contains(RENDER_PROFILE_ENV));
    let forced = ProfileChoice::from_info(&cpu, 4, ProfileRequest::Force(RenderProfile::Full));
    assert_eq!(forced.settings.sample_count, PREFERRED_SAMPLES);
    assert_eq!(forced.settings.shading, MeshShading::PerPixel);
    assert!(!forced.settings.cull_back_faces);
    assert_eq!(forced.short(), "MSAA 4×, per-pixel shading");
}

#[test]
fn the_profile_override_parses_its_three_words_and_names_a_bad_one() {
    assert_eq!("".parse(), Ok(ProfileRequest::Auto));
    assert_eq!(" Auto ".parse(), Ok(ProfileRequest::Auto));
    assert_eq!(
        "software".parse(),
        Ok(ProfileRequest::Force(RenderProfile::Software))
    );
    assert_eq!(
        "FULL".parse(),
        Ok(ProfileRequest::Force(RenderProfile::Full))
    );
    let bad = "fast".parse::<ProfileRequest>().unwrap_err();
    assert_eq!(bad.value, "fast");
    let message = bad.to_string();
    assert!(
        message.contains(RENDER_PROFILE_ENV) && message.contains("\"fast\""),
        "{message}"
    );
}

/// The vertex-lit pass's colour at a pixel: ambient plus the key light's diffuse term at the
/// analytic sphere's normal (the fill light and the highlight are not part of it). `None` for
/// background and silhouette-band pixels.
fn vertex_lit_reference(
    camera: &Camera,
    options: &SceneOptions,
    radius: f32,
    x: u32,
    y: u32,
) -> Option<[u8; 3]> {
    let inv = camera.view_projection(W as f32 / H as f32).inverse();
    let ndc = Vec2::new(
        (x as f32 + 0.5) / W as f32 * 2.0 - 1.0,
        1.0 - (y as f32 + 0.5) / H as f32 * 2.0,
    );
    let eye = camera.eye();
    let d = (inv.project_point3(ndc.extend(1.0)) - eye).normalize();
    let b = eye.dot(d);
    let disc = b * b - (eye.length_squared() - radius * radius);
    if disc < 0.0 {
        return None;
    }
    let n = (eye + d * (-b - disc.sqrt())).normalize();
    if n.dot(-d) < 0.25 {
        return None;
    }
    let s = &options.shading;
    let albedo = Vec3::from(s.material_color);
    let key = s.lights[0];
    let l = camera
        .view()
        .inverse()
        .transform_vector3(key.direction)
        .normalize();
    let lit = albedo * s.ambient + Vec3::from(key.color) * albedo * n.dot(l).max(0.0);
    Some([
        linear_to_srgb8(lit.x),
        linear_to_srgb8(lit.y),
        linear_to_srgb8(lit.z),
    ])
}

#[test]
fn the_software_profile_draws_the_clay_vertex_lit_by_the_key_light() {
    let Some(gpu) = context() else { return };
    let mut r = OffscreenRenderer::with_settings(gpu, FrameSettings::SOFTWARE, W, H).unwrap();
    assert_eq!(r.renderer().sample_count(), 1);
    assert_eq!(r.renderer().shading(), MeshShading::VertexLit);
    let mut chunks = sphere_chunks(Vec3::ZERO, 1.0, 128, 64);
    r.sync_chunks(&views(&chunks)).unwrap();
    let camera = front_camera(3.5);
    // A bright fill light from the lower right and a strong highlight: the vertex-lit pass
    // must show neither.
    let mut options = plain_options();
    options.shading.lights[1] = Light {
        direction: Vec3::new(0.6, -0.6, 0.5),
        color: [1.0, 1.0, 1.0],
    };
    options.shading.specular = 1.0;
    let img = r.render(&camera, &options).unwrap();

    // Coverage: the analytic disk, within 3 %.
    let bg = options.background.map(linear_to_srgb8);
    let covered = img
        .rgba8
        .chunks_exact(4)
        .filter(|p| differs([p[0], p[1], p[2], p[3]], bg, 2))
        .count();
    let measured = covered as f32 / (W * H) as f32;
    let rho = analytic_disk_radius_px(&camera, 1.0, H);
    let expected = std::f32::consts::PI * rho * rho / (W * H) as f32;
    let rel = (measured - expected).abs() / expected;
    assert!(
        rel < 0.03,
        "covered {measured:.4} vs analytic disk {expected:.4}"
    );

    // Shading follows the normal: the key light's side is bright, the far side is ambient.
    let (cx, cy) = (W as f32 / 2.0, H as f32 / 2.0);
    let sample = |dx: f32, dy: f32| {
        luminance(
            img.pixel((cx + dx * rho) as u32, (cy - dy * rho) as u32)
                .unwrap(),
        )
    };
    let lit = sample(-0.45, 0.45);
    let unlit = sample(0.6, -0.6);
    assert!(lit > unlit + 60.0, "lit {lit} vs unlit {unlit}");

    // Against the per-vertex model on the analytic sphere: interpolation error only.
    let mut errors = Vec::new();
    for y in 0..H {
        for x in 0..W {
            if let Some(want) = vertex_lit_reference(&camera, &options, 1.0, x, y) {
                let got = img.pixel(x, y).unwrap();
                errors.push((0..3).map(|c| got[c].abs_diff(want[c])).max().unwrap_or(0));
            }
        }
    }
    assert!(errors.len() > 5000, "reference covers {}", errors.len());
    errors.sort_unstable();
    let mean = errors.iter().map(|&e| f64::from(e)).sum::<f64>() / errors.len() as f64;
    let p99 = errors[errors.len() * 99 / 100];
    assert!(mean < 2.0, "mean channel error {mean:.2} levels");
    assert!(p99 <= 8, "99th percentile channel error {p99} levels");

    // Paint still shows: the octant nearest the eye, painted red, turns its part of the disk
    // red.
    let facing = |c: &OwnedChunk| {
        let sum: Vec3 = c.positions.iter().map(|&p| Vec3::from(p)).sum();
        sum.dot(camera.eye()) / c.positions.len().max(1) as f32
    };
    let painted = chunks
        .iter_mut()
        .max_by(|a, b| facing(a).total_cmp(&facing(b)))
        .unwrap();
    painted.colors = vec![[1.0, 0.0, 0.0, 1.0]; painted.positions.len()];
    painted.version += 1;
    let report = r.sync_chunks(&views(&chunks)).unwrap();
    assert_eq!(report.uploaded, 1, "only the repainted chunk is uploaded");
    let img = r.render(&camera, &options).unwrap();
    let red = img
        .rgba8
        .chunks_exact(4)
        .filter(|p| p[0] > 60 && p[1] < 10 && p[2] < 10)
        .count();
    assert!(
        red > covered / 16 && red < covered / 2,
        "{red} red pixels of {covered} covered"
    );
}

#[test]
fn the_software_profile_skips_triangles_seen_from_behind_and_without_culling_they_show() {
    // One quad facing the camera, wound counter-clockwise (front), and one beside it wound
    // clockwise (its back seen).
    let positions = [
        [-0.9, -0.4, 0.0],
        [-0.1, -0.4, 0.0],
        [-0.1, 0.4, 0.0],
        [-0.9, 0.4, 0.0],
        [0.1, -0.4, 0.0],
        [0.9, -0.4, 0.0],
        [0.9, 0.4, 0.0],
        [0.1, 0.4, 0.0],
    ];
    let normals = [[0.0, 0.0, 1.0]; 8];
    let indices = [0, 1, 2, 0, 2, 3, 4, 6, 5, 4, 7, 6];
    let chunk = MeshChunk {
        id: 1,
        version: 1,
        positions: &positions,
        normals: &normals,
        colors: &[],
        indices: &indices,
        cut: false,
    };
    let camera = front_camera(3.0);
    let options = plain_options();
    let bg = options.background.map(linear_to_srgb8);
    let covered = |settings: FrameSettings| {
        let gpu = context()?;
        let mut r = OffscreenRenderer::with_settings(gpu, settings, W, H).unwrap();
        r.sync_chunks(&[chunk]).unwrap();
        let img = r.render(&camera, &options).unwrap();
        let side = |x0: u32, x1: u32| {
            (0..H)
                .flat_map(|y| (x0..x1).map(move |x| (x, y)))
                .filter(|&(x, y)| differs(img.pixel(x, y).unwrap(), bg, 2))
                .count()
        };
        Some((side(0, W / 2), side(W / 2, W)))
    };
    let Some((front, back)) = covered(FrameSettings::SOFTWARE) else {
        return;
    };
    assert!(
        front > 1000,
        "the front-facing quad is drawn: {front} pixels"
    );
    assert_eq!(back, 0, "the back-facing quad is culled");
    let both = FrameSettings {
        cull_back_faces: false,
        ..FrameSettings::SOFTWARE
    };
    let (front_again, back) = covered(both).unwrap();
    assert_eq!(front_again, front);
    assert!(
        back.abs_diff(front) < front / 20,
        "without culling both quads show: {front} and {back} pixels"
    );
}

#[test]
fn far_bricks_are_drawn_coarse_without_holes_and_near_ones_in_full() {
    // A ball meshed by the octree the engine uses, fine enough that its edges span under a
    // pixel at distance 4: many bricks, in groups of 4 × 4 × 4.
    let centre = Vec3::splat(1.2);
    let mut lattice = crate::field::BSplineLattice::zeros([24; 3], 0.1, Vec3::ZERO).unwrap();
    for k in 0..24 {
        for j in 0..24 {
            for i in 0..24 {
                let d = (lattice.node_position(i, j, k) - centre).length() - 0.8;
                let n = lattice.index(i, j, k);
                lattice.coeffs.set_flat(n, (0.5 - d / 0.6).clamp(0.0, 1.0));
            }
        }
    }
    let grid = crate::mesh::SampleGrid::for_lattice(&lattice, 8).unwrap();
    let octree = crate::mesh::BrickOctree::build(grid, &lattice);
    let meshes = octree_chunks(&octree, None);
    let chunks = chunk_views(&meshes);
    let fine_triangles: usize = chunks.iter().map(MeshChunk::triangle_count).sum();
    assert!(chunks.len() > 64, "{} bricks", chunks.len());
    let options = plain_options();
    let bg = options.background.map(linear_to_srgb8);
    let camera = |distance: f32| {
        let mut c = front_camera(distance);
        c.target = centre;
        c
    };
    let draw = |settings: FrameSettings, distance: f32| {
        let gpu = context()?;
        let mut r = OffscreenRenderer::with_settings(gpu, settings, W, H).unwrap();
        r.sync_chunks(&chunks).unwrap();
        let img = r.render(&camera(distance), &options).unwrap();
        Some((img, r.last_draw()))
    };
    let every_triangle = FrameSettings {
        coarse_far_bricks: false,
        ..FrameSettings::SOFTWARE
    };
    let Some((full, full_draw)) = draw(every_triangle, 4.0) else {
        return;
    };
    let (coarse, coarse_draw) = draw(FrameSettings::SOFTWARE, 4.0).unwrap();
    assert_eq!(full_draw.coarse_chunks, 0);
    assert_eq!(full_draw.triangles, fine_triangles);
    assert_eq!(full_draw.draw_calls, chunks.len());
    assert!(
        coarse_draw.coarse_chunks * 10 >= chunks.len() * 9,
        "{} of {} bricks drawn coarse",
        coarse_draw.coarse_chunks,
        chunks.len()
    );
    assert!(
        coarse_draw.draw_calls * 8 <= chunks.len(),
        "{coarse_draw:?}"
    );
    assert!(
        coarse_draw.triangles * 2 < fine_triangles,
        "{} of {fine_triangles} triangles drawn",
        coarse_draw.triangles
    );
    // The same disk: coverage within half a percent (a hole or a crack would uncover pixels),
    // and the shading within a level on average.
    let covered = |img: &Image| {
        img.rgba8
            .chunks_exact(4)
            .filter(|p| differs([p[0], p[1], p[2], p[3]], bg, 2))
            .count()
    };
    let (a, b) = (covered(&full), covered(&coarse));
    assert!(a > 2000, "{a} pixels covered");
    assert!(
        a.abs_diff(b) * 200 <= a,
        "{a} pixels covered in full, {b} coarse"
    );
    let mean_error = full
        .rgba8
        .iter()
        .zip(&coarse.rgba8)
        .map(|(&x, &y)| f64::from(x.abs_diff(y)))
        .sum::<f64>()
        / full.rgba8.len() as f64;
    assert!(
        mean_error < 1.0,
        "mean channel error {mean_error:.3} levels"
    );

    // Up close the groups facing the eye are drawn in full.
    let (_, near_draw) = draw(FrameSettings::SOFTWARE, 1.3).unwrap();
    assert!(
        near_draw.coarse_chunks < coarse_draw.coarse_chunks
            && near_draw.triangles > coarse_draw.triangles,
        "near {near_draw:?}, far {coarse_draw:?}"
    );
}

/// The default block meshed as the window meshes it, each brick coloured by
/// [`surface_colors`] under `mask` (no paint); a masked set's versions differ from an
/// unmasked one's, so the renderer uploads its colours.
fn block_chunks(
    lattice: &crate::field::BSplineLattice,
    mask: Option<&crate::tools::FreezeMask>,
) -> Vec<OwnedChunk> {
    let mut octree =
        crate::mesh::BrickOctree::new(crate::mesh::SampleGrid::for_lattice(lattice, 2).unwrap());
    octree.rebuild(lattice);
    octree
        .bricks()
        .filter(|b| !b.mesh.indices.is_empty())
        .map(|b| {
            let chunk = ChunkMesh::from_brick(
                b.coord,
                b.version,
                &b.mesh,
                surface_colors(&b.mesh, None, mask),
            );
            OwnedChunk {
                id: chunk.id,
                version: chunk.version + if mask.is_some() { 1 << 32 } else { 0 },
                positions: chunk.positions,
                normals: chunk.normals,
                colors: chunk.colors,
                indices: chunk.indices,
            }
        })
        .collect()
}

#[test]
fn masked_clay_is_drawn_darker_and_the_rest_as_before() {
    use crate::tools::{Clay, MaskBrush, MaskEdit, MaskMode};
    let Some(mut r) = offscreen(W, H) else { return };
    let lattice = crate::engine::build_clay(&crate::io::ClaySpec::default()).unwrap();
    // The block spans [0.575, 1.725]; a full-strength dab at the middle of its top.
    let (lo, hi) = (Vec3::splat(0.575), Vec3::splat(1.725));
    let dab = Vec3::new(1.15, 1.725, 1.15);
    let mut clay = Clay::single(lattice.clone());
    MaskEdit::Paint {
        brush: MaskBrush {
            radius_fu: 0.3,
            strength: 1.0,
            mode: MaskMode::Freeze,
        },
        centres_fu: vec![dab],
    }
    .apply(&mut clay, None)
    .unwrap();
    let mask = clay.mask.clone().expect("the dab made a mask");
    let camera = Camera::named(NamedView::Top, lo, hi);
    let o = plain_options();
    let frame = |r: &mut OffscreenRenderer, chunks: &[OwnedChunk]| {
        r.sync_chunks(&views(chunks)).unwrap();
        r.render(&camera, &o).unwrap()
    };
    let plain = frame(&mut r, &block_chunks(&lattice, None));
    let masked = frame(&mut r, &block_chunks(&lattice, Some(&mask)));
    let vp = camera.view_projection(W as f32 / H as f32);
    let to_px = |p: Vec3| {
        let n = vp.project_point3(p);
        (
            ((n.x + 1.0) * 0.5 * W as f32) as u32,
            ((1.0 - n.y) * 0.5 * H as f32) as u32,
        )
    };
    // Under the dab's inner half the hold is full: the albedo is mixed MASK_TINT_OPACITY of
    // the way to the tint, so the lit colour (linear) drops to about 0.45 of the plain one:
    // below 0.8 of it in 8-bit sRGB, whatever the shading profile.
    let (cx, cy) = to_px(dab);
    let (before, after) = (plain.pixel(cx, cy).unwrap(), masked.pixel(cx, cy).unwrap());
    eprintln!("under the mask: plain {before:?}, masked {after:?}");
    assert!(luminance(before) > 40.0, "the top is lit: {before:?}");
    assert!(
        luminance(after) < 0.8 * luminance(before),
        "masked clay is darker: {after:?} against {before:?}"
    );
    // Beyond the dab's radius the clay is drawn exactly as without a mask.
    for corner in [
        Vec3::new(0.7, 1.725, 0.7),
        Vec3::new(1.6, 1.725, 0.7),
        Vec3::new(0.7, 1.725, 1.6),
        Vec3::new(1.6, 1.725, 1.6),
    ] {
        let (x, y) = to_px(corner);
        let (a, b) = (plain.pixel(x, y).unwrap(), masked.pixel(x, y).unwrap());
        assert!(
            !differs(a, b, 1),
            "unmasked at {corner}: {b:?} against {a:?}"
        );
    }
    // Every pixel that changed is darker, and they lie within the dab's reach: its radius,
    // two knot spans more (a held coefficient's basis reaches that far) and a mesh cell.
    let reach = 0.3 + 2.5 * lattice.spacing;
    let (rim_x, _) = to_px(dab + Vec3::X * reach);
    let radius_px = rim_x.abs_diff(cx) as f32 + 2.0;
    let mut darker = 0;
    for y in 0..H {
        for x in 0..W {
            let (a, b) = (plain.pixel(x, y).unwrap(), masked.pixel(x, y).unwrap());
            if differs(a, b, 1) {
                assert!(
                    luminance(b) < luminance(a),
                    "({x}, {y}) lighter: {b:?} vs {a:?}"
                );
                let d = (x as f32 - cx as f32).hypot(y as f32 - cy as f32);
                assert!(d <= radius_px, "({x}, {y}) changed {d} px from the dab");
                darker += 1;
            }
        }
    }
    assert!(darker > 50, "{darker} pixels tinted");
}

/// The default block with a groove carved along x across the middle of its top (a Remove
/// ball of radius 0.15 centred on the top at z = 1.15, from x = 0.75 to 1.55).
fn grooved_block() -> crate::field::BSplineLattice {
    use crate::tools::{ApplyOptions, Clay, GeometricTool, ToolAction, ToolPose, ToolShape};
    let lattice = crate::engine::build_clay(&crate::io::ClaySpec::default()).unwrap();
    let mut clay = Clay::single(lattice);
    let ball = GeometricTool {
        shape: ToolShape::Sphere { radius_fu: 0.15 },
        action: ToolAction::Remove,
        falloff_fu: 0.05,
    };
    for i in 0..=16 {
        let pose = ToolPose {
            position_fu: Vec3::new(0.75 + 0.05 * i as f32, GROOVE_TOP, GROOVE_Z),
            rotation: glam::Quat::IDENTITY,
        };
        crate::tools::apply_tool(&mut clay, &ball, &pose, 0.5, &ApplyOptions::default(), None)
            .unwrap();
    }
    clay.base().clone()
}

/// The pixels that `mesh` shows as clay, two pixels or more inside its silhouette, and
/// `splats` leaves as background (dark): holes in the splats' cover.
fn splat_holes(mesh: &Image, splats: &Image) -> Vec<(u32, u32)> {
    let clay = |img: &Image, x: u32, y: u32| luminance(img.pixel(x, y).unwrap()) > 8.0;
    let mut holes = Vec::new();
    for y in 2..mesh.height - 2 {
        for x in 2..mesh.width - 2 {
            let inside = (y - 2..=y + 2).all(|v| (x - 2..=x + 2).all(|u| clay(mesh, u, v)));
            if inside && !clay(splats, x, y) {
                holes.push((x, y));
            }
        }
    }
    holes
}

/// The default block's top and where the groove runs across it.
const GROOVE_TOP: f32 = 1.725;
const GROOVE_Z: f32 = 1.15;

/// Luminance along the line across the groove at `x` on the top (z from 0.85 to 1.45, one
/// sample per 0.01), in `img` seen by `camera`.
fn across_groove(img: &Image, camera: &Camera, x: f32) -> Vec<f32> {
    let vp = camera.view_projection(W as f32 / H as f32);
    (0..=60)
        .map(|i| {
            let n = vp.project_point3(Vec3::new(x, GROOVE_TOP, 0.85 + 0.01 * i as f32));
            let (x, y) = ((n.x + 1.0) * 0.5 * W as f32, (1.0 - n.y) * 0.5 * H as f32);
            luminance(img.pixel(x as u32, y as u32).unwrap())
        })
        .collect()
}

/// The clay's own shading where [`across_groove`] samples an image at `x`: each sample's pixel
/// ray-cast onto the clay (marched 0.001 apart from just above the top, then bisected), lit
/// as the mesh pass lights it ([`blinn_phong_reference`]) with albedo `albedo` and the
/// clay's unit normal there, as luminance.
fn clay_across_groove(
    field: &crate::field::MultiPatchField,
    camera: &Camera,
    options: &SceneOptions,
    albedo: Vec3,
    x: f32,
) -> Vec<f32> {
    let vp = camera.view_projection(W as f32 / H as f32);
    let inv = vp.inverse();
    let eye = camera.eye();
    let inside = |p: Vec3| field.value_and_gradient(p).0 > field.iso();
    (0..=60)
        .map(|i| {
            let on_top = Vec3::new(x, GROOVE_TOP, 0.85 + 0.01 * i as f32);
            let n = vp.project_point3(on_top);
            let (px, py) = (
                ((n.x + 1.0) * 0.5 * W as f32).floor(),
                ((1.0 - n.y) * 0.5 * H as f32).floor(),
            );
            let ndc = Vec2::new(
                (px + 0.5) / W as f32 * 2.0 - 1.0,
                1.0 - (py + 0.5) / H as f32 * 2.0,
            );
            let d = (inv.project_point3(ndc.extend(1.0)) - eye).normalize();
            let start = (on_top - eye).length() - 0.05;
            let step = 0.001;
            let k = (0..400)
                .find(|&k| inside(eye + d * (start + step * (k + 1) as f32)))
                .unwrap_or_else(|| panic!("the ray through ({px}, {py}) meets the clay"));
            let (mut a, mut b) = (start + step * k as f32, start + step * (k + 1) as f32);
            for _ in 0..30 {
                let m = 0.5 * (a + b);
                if inside(eye + d * m) {
                    b = m;
                } else {
                    a = m;
                }
            }
            let p = eye + d * b;
            let normal = -field.value_and_gradient(p).1.normalize();
            let [r, g, b] = blinn_phong_reference(camera, options, albedo, normal, -d);
            luminance([r, g, b, 255])
        })
        .collect()
}

/// A sculpted groove reads as a groove in splats as in the mesh: points that sat on the
/// block before it was carved follow the clay into the groove (as many updates as the
/// window's follower takes), and their splats, drawn alone, shade the line across the groove
/// as the mesh does: the wall turned from the light dark at the same place, and the whole
/// profile, relative to the flat top, within 0.1 RMS of the mesh's. And without facets: over
/// the groove's straight part, pixel by pixel, within 0.06 of the clay's own brightness
/// (ray-cast, [`clay_across_groove`]) at the 95th percentile (0.3 at most), sharp steps in at
/// most 1% of the neighbouring samples, and no line varying more than 1.3 times the clay's +
/// 0.1 ([`GrooveFacets`]); the same splats lit flat, one normal each, fail these. And the
/// splats cover the clay: at most one pixel in 2000 of the mesh's clay, away from its
/// silhouette, is left as background ([`splat_holes`]; the splats are one-sided). The clay,
/// not the mesh, is the reference for the facets: the mesh's normals, interpolated across
/// triangles two to a knot span, are themselves 0.05 off the clay's at the 95th percentile
/// (printed) and soften the steep wall's turn from the light, which the splats follow.
#[test]
fn a_sculpted_groove_shades_in_splats_as_in_the_mesh() {
    use crate::pointset::{DEFAULT_COLOUR, FollowOptions, FollowedPoints, PointFollower};
    let Some(mut r) = offscreen(W, H) else { return };
    let flat = crate::engine::build_clay(&crate::io::ClaySpec::default()).unwrap();
    let grooved = grooved_block();
    let (lo, hi) = (Vec3::splat(0.575), Vec3::splat(1.725));
    let mut camera = Camera::named(NamedView::Top, lo, hi);
    camera.distance *= 0.6;
    let o = plain_options();

    r.sync_chunks(&views(&block_chunks(&grooved, None)))
        .unwrap();
    let mesh = r.render(&camera, &o).unwrap();

    // The points: the flat block's mesh vertices, then followed onto the grooved clay.
    let mut octree =
        crate::mesh::BrickOctree::new(crate::mesh::SampleGrid::for_lattice(&flat, 2).unwrap());
    octree.rebuild(&flat);
    let (mut positions, mut normals) = (Vec::new(), Vec::new());
    for b in octree.bricks() {
        positions.extend_from_slice(&b.mesh.positions);
        normals.extend_from_slice(&b.mesh.normals);
    }
    let n = positions.len();
    let spacing = 0.5 * flat.spacing;
    let points = FollowedPoints {
        positions,
        normals,
        colours: vec![DEFAULT_COLOUR; n],
        options: None,
    };
    let mut follower = PointFollower::new(points, FollowOptions::for_spacing(spacing, n)).unwrap();
    let field = crate::field::MultiPatchField::from(grooved.clone());
    // As many updates as the window's follower takes after a change, at most.
    let mut last = None;
    for _ in 0..crate::pointset::PointSetFollower::<crate::engine::HeadlessSink>::SETTLE_UPDATES {
        let report = follower.update(&field).unwrap();
        last = Some(report);
        if report.settled {
            break;
        }
    }
    eprintln!(
        "{} points after following: {last:?}",
        follower.positions().len()
    );
    let mut discs = Vec::new();
    splat_discs(
        &mut discs,
        follower.positions(),
        follower.normals(),
        follower.colours(),
        follower.radii(),
        follower.normal_gradients(),
    );
    r.sync_chunks(&[]).unwrap();
    r.set_discs(&discs).unwrap();
    let splats = r.render(&camera, &o).unwrap();
    if let Ok(dir) = std::env::var("DYNACLAY_GROOVE_PNG") {
        mesh.write_png(&std::path::Path::new(&dir).join("groove_mesh.png"))
            .unwrap();
        splats
            .write_png(&std::path::Path::new(&dir).join("groove_splats.png"))
            .unwrap();
    }

    // No holes: every pixel the mesh covers, away from its silhouette, a splat covers (the
    // splats are one-sided, so a hole shows the background, not the clay's far side).
    let holes = splat_holes(&mesh, &splats);
    let clay_pixels = (0..H)
        .flat_map(|y| (0..W).map(move |x| (x, y)))
        .filter(|&(x, y)| luminance(mesh.pixel(x, y).unwrap()) > 8.0)
        .count();
    eprintln!(
        "splat holes: {} of {clay_pixels} clay pixels, at {:?}",
        holes.len(),
        &holes[..holes.len().min(20)]
    );
    assert!(
        clay_pixels > W as usize * H as usize / 2,
        "the block fills the view"
    );
    assert!(
        holes.len() * 2000 <= clay_pixels,
        "the splats leave {} holes in {clay_pixels} pixels of clay: {holes:?}",
        holes.len()
    );
    let (m, s) = (
        across_groove(&mesh, &camera, 1.15),
        across_groove(&splats, &camera, 1.15),
    );
    eprintln!("across the groove, mesh: {m:?}\nsplats: {s:?}");
    // Each profile relative to its own flat top (the splats have the points' colour, the mesh
    // the clay's): the shading the groove's shape gives, whatever the albedo.
    let top = |p: &[f32]| (p[..5].iter().sum::<f32>() + p[56..].iter().sum::<f32>()) / 10.0;
    let relative = |p: &[f32]| -> Vec<f32> {
        let t = top(p);
        assert!(t > 40.0, "the top is lit ({t})");
        p.iter().map(|&x| x / t).collect()
    };
    let (m, s) = (relative(&m), relative(&s));
    let darkest = |p: &[f32]| {
        p.iter()
            .enumerate()
            .min_by(|a, b| a.1.total_cmp(b.1))
            .map(|(i, &x)| (i, x))
            .unwrap()
    };
    let ((mesh_at, mesh_dark), (splat_at, splat_dark)) = (darkest(&m), darkest(&s));
    let rms = (m.iter().zip(&s).map(|(a, b)| (a - b).powi(2)).sum::<f32>() / m.len() as f32).sqrt();
    eprintln!(
        "darkest: mesh {mesh_dark:.3} at {mesh_at}, splats {splat_dark:.3} at {splat_at}; \
         RMS difference {rms:.3}"
    );
    assert!(
        mesh_dark < 0.6,
        "the mesh shades the groove's wall: {mesh_dark}"
    );
    assert!(
        splat_dark < 0.6 && splat_at.abs_diff(mesh_at) <= 3,
        "the splats shade the same wall: {splat_dark} at {splat_at}, the mesh {mesh_dark} at \
         {mesh_at} (0.01 apart)"
    );
    assert!(
        rms < 0.1,
        "the splats' shading across the groove follows the mesh's within {rms}"
    );

    // Facets, pixel by pixel over the groove's straight part, against the clay ray-cast and
    // lit with the points' colour (the relative profiles then share one sRGB curve).
    let splat_albedo = Vec3::from(DEFAULT_COLOUR.map(srgb8_to_linear));
    let clay = |x: f32| clay_across_groove(&field, &camera, &o, splat_albedo, x);
    let smooth = GrooveFacets::measure(clay, &splats, &camera);
    eprintln!("splats lit with their normals' gradients, against the clay: {smooth:?}");
    let against_mesh =
        GrooveFacets::measure(|x| across_groove(&mesh, &camera, x), &splats, &camera);
    eprintln!("the same splats against the mesh: {against_mesh:?}");
    let mesh_albedo = Vec3::from(o.shading.material_color);
    let mesh_off = GrooveFacets::measure(
        |x| clay_across_groove(&field, &camera, &o, mesh_albedo, x),
        &mesh,
        &camera,
    );
    eprintln!("the mesh against the clay: {mesh_off:?}");

    // The same splats, each lit with its one normal (flat discs), are caught by the
    // same measures: they are what the measures are for.
    let mut flat_discs = Vec::new();
    splat_discs(
        &mut flat_discs,
        follower.positions(),
        follower.normals(),
        follower.colours(),
        follower.radii(),
        &[],
    );
    r.set_discs(&flat_discs).unwrap();
    let faceted = r.render(&camera, &o).unwrap();
    if let Ok(dir) = std::env::var("DYNACLAY_GROOVE_PNG") {
        faceted
            .write_png(&std::path::Path::new(&dir).join("groove_flat_splats.png"))
            .unwrap();
    }
    let flat_lit = GrooveFacets::measure(clay, &faceted, &camera);
    eprintln!("splats lit flat: {flat_lit:?}");
    assert!(
        flat_lit.failures().is_some(),
        "flat-lit splats show facets the measures catch: {flat_lit:?}"
    );
    if let Some(why) = smooth.failures() {
        panic!("the splats shade the groove as the mesh does: {why}");
    }
}

/// How much a splat image of the grooved block departs from a reference (the clay ray-cast,
/// or the mesh image) over the groove's straight part: 41 lines across it (x from 0.95 to
/// 1.35, 0.01 apart), 61 samples each (z from 0.85 to 1.45), each profile's brightness
/// relative to its own flat top.
#[derive(Debug)]
struct GrooveFacets {
    /// 95th percentile of the sample-by-sample difference, fractions of the top.
    p95: f32,
    /// The largest difference.
    largest: f32,
    /// Neighbouring samples whose difference exceeds the reference's by more than 0.06 of the top
    /// (a disc's edge), and the steps in all.
    sharp_steps: usize,
    steps: usize,
    /// The largest ratio, over the lines, of the splats' total variation to 1.3 × the
    /// reference's + 0.1 (a faceted profile climbs and drops at every disc).
    variation_ratio: f32,
}

impl GrooveFacets {
    /// `reference(x)`: the reference's 61 samples along the line at `x`.
    fn measure(reference: impl Fn(f32) -> Vec<f32>, splats: &Image, camera: &Camera) -> Self {
        let relative = |p: Vec<f32>| -> Vec<f32> {
            let t = (p[..5].iter().sum::<f32>() + p[56..].iter().sum::<f32>()) / 10.0;
            assert!(t > 40.0, "the top is lit ({t})");
            p.iter().map(|&x| x / t).collect()
        };
        let variation = |p: &[f32]| p.windows(2).map(|w| (w[1] - w[0]).abs()).sum::<f32>();
        let (mut differences, mut sharp_steps, mut steps) = (Vec::new(), 0, 0);
        let mut variation_ratio = 0.0f32;
        for k in 0..=40 {
            let x = 0.95 + 0.01 * k as f32;
            let m = relative(reference(x));
            let s = relative(across_groove(splats, camera, x));
            differences.extend(m.iter().zip(&s).map(|(a, b)| (a - b).abs()));
            for (dm, ds) in m.windows(2).zip(s.windows(2)) {
                steps += 1;
                if (ds[1] - ds[0]).abs() > (dm[1] - dm[0]).abs() + 0.06 {
                    sharp_steps += 1;
                }
            }
            variation_ratio = variation_ratio.max(variation(&s) / (1.3 * variation(&m) + 0.1));
        }
        differences.sort_by(f32::total_cmp);
        Self {
            p95: differences[differences.len() * 95 / 100],
            largest: differences[differences.len() - 1],
            sharp_steps,
            steps,
            variation_ratio,
        }
    }

    /// What is wrong, if anything: a 95th percentile over 0.06 or a largest difference over
    /// 0.3, sharp steps in more than 1% of the steps, a line varying more than its bound.
    fn failures(&self) -> Option<String> {
        let mut why = Vec::new();
        if self.p95 > 0.06 || self.largest > 0.3 {
            why.push(format!(
                "difference p95 {:.3}, largest {:.3}",
                self.p95, self.largest
            ));
        }
        if self.sharp_steps * 100 > self.steps {
            why.push(format!(
                "{} sharp steps of {}",
                self.sharp_steps, self.steps
            ));
        }
        if self.variation_ratio > 1.0 {
            why.push(format!(
                "total variation {:.2} of its bound",
                self.variation_ratio
            ));
        }
        (!why.is_empty()).then(|| why.join("; "))
    }
}
