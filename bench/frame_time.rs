//! Frame time of the window's own drawing, offscreen, on the adapter `GpuContext::headless`
//! finds (lavapipe on a machine without a GPU).
//!
//! Part 1, the window frame: the real app ([`SculptApp::show`]) on an egui-wgpu render state
//! built on that adapter, so its 3D view renders through the same `SceneView`, renderer,
//! pipelines and shaders as `dynaclay gui`, with the render profile the window would choose
//! (and, for comparison, the full profile forced); then egui's own pass draws the whole window
//! into a 1400×900 texture (the window's default size), cleared first to the app's clear colour
//! as eframe clears the window, which is copied out and mapped. A
//! frame is timed from the start of the app's update until the mapped image is back on the
//! CPU, and the camera orbits by 2° before each frame, so every frame re-renders the scene (as
//! when orbiting). Every timed image is checked: the view must show clay-coloured pixels.
//!
//! Part 2, the scene pass alone: the `SceneRenderer` with the settings that matter on a
//! software adapter (MSAA 4× and per-pixel shading, one sample per-pixel, one sample
//! vertex-lit, and that with back faces culled), so that what each saving buys is seen apart; the same triangles merged into
//! one chunk (what one draw call per brick costs); and the upload of one changed brick
//! against all bricks.
//!
//! Scenes: the default clay as `dynaclay gui` starts it (the built-in script's clay, meshed
//! at the engine's resolution, bricks as the graphics loop publishes them), and a sculpt of at
//! least 500 000 triangles (the same clay with a ripple carved over its whole surface, meshed
//! finer).
//!
//! Not a criterion bench: it prints the median, the fastest and the slowest of each, the
//! adapter and the load average, and whether the frame-time floors hold (50 ms for the
//! default clay, 150 ms for the 500k sculpt). Exits cleanly with "skipped" without an adapter.
//! `cargo bench --bench frame_time` (`-- --frames N` for N timed frames per case, `-- --only
//! clay` or `-- --only sculpt` for one scene).

use std::sync::Arc;
use std::time::{Duration, Instant};

use dynaclay::app::{ChunkMesh, EngineView, MeshSet, SculptApp, engine_link, window_clear_color};
use dynaclay::engine::{EngineConfig, ScriptPlan, build_clay};
use dynaclay::field::MultiPatchField;
use dynaclay::mesh::{BrickOctree, SampleGrid};
use dynaclay::render::{
    Camera, FrameSettings, GpuContext, MeshChunk, MeshShading, NamedView, OFFSCREEN_FORMAT,
    ProfileChoice, ProfileRequest, RenderProfile, SceneOptions, SceneRenderer, bounds_of,
    chunk_views, supported_sample_count,
};
use dynaclay_devices::pointer::PointerConfig;

/// The window's default inner size, pixels (at one pixel per point).
const WINDOW: [u32; 2] = [1400, 900];
/// What eframe picks for its surface where it can (egui-wgpu's preferred framebuffer format).
const WINDOW_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;
/// Camera turn before each timed frame.
const ORBIT_STEP_RAD: f32 = 2.0 * std::f32::consts::PI / 180.0;
/// Triangles the large sculpt has at least.
const LARGE_TRIANGLES: usize = 500_000;
/// Frame-time floors of the window frame with the adapter's own profile, milliseconds.
const FLOOR_CLAY_MS: f64 = 50.0;
const FLOOR_LARGE_MS: f64 = 150.0;

/// The engine's mesh of `field`: the graphics loop's sampling grid and octree, each non-empty
/// brick a chunk (as the window's mesh sink publishes them).
fn engine_mesh(field: &MultiPatchField, cells_per_span: u32) -> MeshSet {
    let grid = SampleGrid::for_field(field, cells_per_span).expect("a grid for the clay");
    let mut octree = BrickOctree::new(grid);
    octree.rebuild(field);
    octree
        .bricks()
        .filter(|b| !b.mesh.indices.is_empty())
        .map(|b| Arc::new(ChunkMesh::from_octree_brick(b, None)))
        .collect()
}

fn triangles(set: &MeshSet) -> usize {
    set.iter().map(|c| c.indices.len() / 3).sum()
}

/// The clay `dynaclay gui` starts with, and the engine's cells per knot span for it.
fn default_clay() -> (MultiPatchField, u32) {
    let script = ScriptPlan::builtin();
    let field = MultiPatchField::new(build_clay(&script.clay).expect("the built-in clay"));
    let info = PointerConfig::default().info();
    let cells = EngineConfig::for_clay(&field, &info).cells_per_span;
    (field, cells)
}

/// The default clay with a ripple carved over its surface (about three knot spans per
/// wavelength), meshed at the smallest resolution that gives [`LARGE_TRIANGLES`].
fn large_sculpt(clay: &MultiPatchField, base_cells: u32) -> (MeshSet, u32) {
    let mut field = clay.clone();
    let lattice = &mut field.patches[0].lattice;
    let k = std::f32::consts::TAU / (3.0 * lattice.spacing);
    let [nx, ny, nz] = lattice.dims;
    for z in 0..nz {
        for y in 0..ny {
            for x in 0..nx {
                let p = lattice.node_position(x, y, z);
                let n = lattice.index(x, y, z);
                let ripple = 0.12 * (k * p.x).sin() * (k * p.y).sin() * (k * p.z).sin();
                lattice
                    .coeffs
                    .set_flat(n, (lattice.coeffs[n] + ripple).clamp(0.0, 1.0));
            }
        }
    }
    let probe = engine_mesh(&field, base_cells);
    // Triangles grow with the square of the resolution.
    let ratio = LARGE_TRIANGLES as f64 / triangles(&probe).max(1) as f64;
    let mut cells = (f64::from(base_cells) * ratio.sqrt()).floor().max(1.0) as u32;
    loop {
        let set = engine_mesh(&field, cells);
        if triangles(&set) >= LARGE_TRIANGLES {
            return (set, cells);
        }
        cells += 1;
    }
}

/// An egui-wgpu render state on the headless device, as eframe makes one for its window.
fn render_state(gpu: &GpuContext) -> egui_wgpu::RenderState {
    let renderer = egui_wgpu::Renderer::new(
        &gpu.device,
        WINDOW_FORMAT,
        egui_wgpu::RendererOptions::default(),
    );
    egui_wgpu::RenderState {
        adapter: gpu.adapter.clone(),
        available_adapters: Vec::new(),
        instance: gpu.instance().clone(),
        device: gpu.device.clone(),
        queue: gpu.queue.clone(),
        target_format: WINDOW_FORMAT,
        renderer: Arc::new(egui::mutex::RwLock::new(renderer)),
    }
}

/// A colour texture with a mappable buffer to copy it into.
struct Readback {
    texture: wgpu::Texture,
    view: wgpu::TextureView,
    buffer: wgpu::Buffer,
    width: u32,
    height: u32,
    padded_row: u32,
}

impl Readback {
    fn new(device: &wgpu::Device, format: wgpu::TextureFormat, width: u32, height: u32) -> Self {
        let texture = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("bench target"),
            size: wgpu::Extent3d {
                width,
                height,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
        let padded_row = (4 * width).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
        let buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("bench readback"),
            size: u64::from(padded_row) * u64::from(height),
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        Self {
            view: texture.create_view(&wgpu::TextureViewDescriptor::default()),
            texture,
            buffer,
            width,
            height,
            padded_row,
        }
    }

    /// Records the copy of `texture` (this readback's own, or another of the same size).
    fn copy(&self, encoder: &mut wgpu::CommandEncoder, texture: &wgpu::Texture) {
        encoder.copy_texture_to_buffer(
            texture.as_image_copy(),
            wgpu::TexelCopyBufferInfo {
                buffer: &self.buffer,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(self.padded_row),
                    rows_per_image: Some(self.height),
                },
            },
            wgpu::Extent3d {
                width: self.width,
                height: self.height,
                depth_or_array_layers: 1,
            },
        );
    }

    /// Waits for the GPU and counts the pixels inside `rect` (pixels) that `is_clay` accepts.
    fn count(
        &self,
        device: &wgpu::Device,
        rect: [u32; 4],
        is_clay: impl Fn([u8; 4]) -> bool,
    ) -> usize {
        let slice = self.buffer.slice(..);
        let (tx, rx) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            let _ = tx.send(r);
        });
        device
            .poll(wgpu::PollType::wait_indefinitely())
            .expect("the GPU finished");
        rx.recv().expect("map callback").expect("mapped");
        let mut clay = 0;
        {
            let data = slice.get_mapped_range().expect("mapped range");
            let [x0, y0, x1, y1] = rect;
            for y in y0..y1.min(self.height) {
                let row = &data[(y * self.padded_row) as usize..];
                for x in x0..x1.min(self.width) {
                    let p = &row[(4 * x) as usize..(4 * x + 4) as usize];
                    if is_clay([p[0], p[1], p[2], p[3]]) {
                        clay += 1;
                    }
                }
            }
        }
        self.buffer.unmap();
        clay
    }
}

/// A pixel of lit, unpainted clay (the default material is a warm brown: red well over blue)
/// in an RGBA image.
fn is_clay_rgba(p: [u8; 4]) -> bool {
    p[0] > 40 && u16::from(p[0]) > u16::from(p[2]) + 15
}

/// Median, fastest and slowest of `times`, milliseconds.
fn summary(times: &mut [Duration]) -> (f64, f64, f64) {
    times.sort_unstable();
    let ms = |d: Duration| d.as_secs_f64() * 1e3;
    (
        ms(times[times.len() / 2]),
        ms(times[0]),
        ms(times[times.len() - 1]),
    )
}

fn load_average() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .map(|s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
        .unwrap_or_else(|_| "unknown".to_owned())
}

/// Times `frames` whole-window frames of the app showing `meshes` with the profile `request`
/// asks for; returns the profile's words, the median frame time (ms) and the 3D view's size
/// in pixels.
fn window_frames(
    gpu: &GpuContext,
    meshes: &MeshSet,
    request: ProfileRequest,
    frames: usize,
) -> (String, f64, [u32; 2]) {
    let rs = render_state(gpu);
    let (device, queue) = (&gpu.device, &gpu.queue);
    let (link, mut end) = engine_link();
    let mut app = SculptApp::new(link);
    app.render_request = request;
    end.meshes.publish_clone_of(meshes);
    end.view.publish_clone_of(&EngineView::default());
    let ctx = egui::Context::default();
    let target = Readback::new(device, WINDOW_FORMAT, WINDOW[0], WINDOW[1]);
    let screen = egui_wgpu::ScreenDescriptor {
        size_in_pixels: WINDOW,
        pixels_per_point: 1.0,
    };
    // As eframe clears the window: to the app's clear colour (the panels' fill).
    let clear = ctx.global_style().visuals.clone();
    let clear = window_clear_color(&clear, WINDOW_FORMAT.is_srgb()).map(f64::from);
    let clear = wgpu::Color {
        r: clear[0],
        g: clear[1],
        b: clear[2],
        a: clear[3],
    };
    let frame = |app: &mut SculptApp| {
        let input = egui::RawInput {
            screen_rect: Some(egui::Rect::from_min_size(
                egui::Pos2::ZERO,
                egui::vec2(WINDOW[0] as f32, WINDOW[1] as f32),
            )),
            ..Default::default()
        };
        let start = Instant::now();
        let output = ctx.run_ui(input, |ui| app.show(ui, Some(&rs)));
        let jobs = ctx.tessellate(output.shapes, output.pixels_per_point);
        let update = start.elapsed();
        let egui_triangles: usize = jobs
            .iter()
            .map(|j| match &j.primitive {
                egui::epaint::Primitive::Mesh(m) => m.indices.len() / 3,
                egui::epaint::Primitive::Callback(_) => 0,
            })
            .sum();
        let mut egui_renderer = rs.renderer.write();
        for (id, deltas) in &output.textures_delta.set {
            for delta in deltas {
                egui_renderer.update_texture(device, queue, *id, delta);
            }
        }
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("bench window"),
        });
        let mut commands =
            egui_renderer.update_buffers(device, queue, &mut encoder, &jobs, &screen);
        {
            let mut pass = encoder
                .begin_render_pass(&wgpu::RenderPassDescriptor {
                    label: Some("bench egui"),
                    color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                        view: &target.view,
                        depth_slice: None,
                        resolve_target: None,
                        ops: wgpu::Operations {
                            load: wgpu::LoadOp::Clear(clear),
                            store: wgpu::StoreOp::Store,
                        },
                    })],
                    depth_stencil_attachment: None,
                    timestamp_writes: None,
                    occlusion_query_set: None,
                    multiview_mask: None,
                })
                .forget_lifetime();
            egui_renderer.render(&mut pass, &jobs, &screen);
        }
        for id in &output.textures_delta.free {
            egui_renderer.free_texture(id);
        }
        drop(egui_renderer);
        target.copy(&mut encoder, &target.texture);
        commands.push(encoder.finish());
        queue.submit(commands);
        let rect = app.viewport_rect.expect("the app laid out its 3D view");
        let rect = [
            rect.min.x.max(0.0) as u32,
            rect.min.y.max(0.0) as u32,
            rect.max.x.max(0.0) as u32,
            rect.max.y.max(0.0) as u32,
        ];
        let clay = target.count(device, rect, is_clay_rgba);
        let area = ((rect[2] - rect[0]) * (rect[3] - rect[1])) as usize;
        (clay, area, update, egui_triangles)
    };
    // Untimed: the first frames build the view, upload every brick and settle egui's layout.
    for _ in 0..3 {
        frame(&mut app);
    }
    let mut times = Vec::with_capacity(frames);
    let mut updates = Vec::with_capacity(frames);
    let mut last_s = None;
    for _ in 0..frames {
        app.camera.orbit(ORBIT_STEP_RAD, 0.0);
        app.last_frame_s = last_s;
        let start = Instant::now();
        let (clay, area, update, _) = frame(&mut app);
        let took = start.elapsed();
        last_s = Some(took.as_secs_f32());
        times.push(took);
        updates.push(update);
        assert!(
            clay * 50 > area,
            "the view shows too little clay: {clay} of {area} pixels"
        );
    }
    // The same window with the camera still: the 3D view is not re-rendered (its key is
    // unchanged), so this is the app and egui's pass alone.
    let mut still = Vec::with_capacity(frames);
    let mut egui_triangles = 0;
    for _ in 0..frames {
        let start = Instant::now();
        let (clay, area, _, triangles) = frame(&mut app);
        still.push(start.elapsed());
        egui_triangles = triangles;
        assert!(clay * 50 > area, "the view shows too little clay");
    }
    let (still, _, _) = summary(&mut still);
    let profile = ProfileChoice::for_adapter(&gpu.adapter, OFFSCREEN_FORMAT, request);
    let (median, fastest, slowest) = summary(&mut times);
    let (update, _, _) = summary(&mut updates);
    println!(
        "  window frame, {:<40} median {median:7.1} ms  (fastest {fastest:.1}, slowest {slowest:.1}; {frames} frames; app update and tessellation {update:.1} ms of it)",
        profile.short(),
    );
    println!(
        "    with the camera still (no 3D re-render: the app and egui's pass of {egui_triangles} triangles over the window): median {still:.1} ms"
    );
    println!("    status line: {}", app.status_line());
    let view = app.viewport_rect.expect("the app laid out its 3D view");
    let size = [view.width().round() as u32, view.height().round() as u32];
    (profile.short(), median, size)
}

/// Times `frames` scene passes alone with `settings` (view size `size`), each waited for and
/// read back; every image is checked for clay.
fn scene_frames(
    gpu: &GpuContext,
    meshes: &MeshSet,
    settings: FrameSettings,
    size: [u32; 2],
    frames: usize,
    what: &str,
) {
    let (device, queue) = (&gpu.device, &gpu.queue);
    let mut renderer =
        SceneRenderer::with_settings(device, queue, OFFSCREEN_FORMAT, settings, size[0], size[1]);
    let chunks: Vec<MeshChunk<'_>> = meshes.iter().map(|c| c.as_chunk()).collect();
    renderer
        .sync_chunks(device, queue, &chunks)
        .expect("valid chunks");
    let (lo, hi) = bounds_of(&chunks).expect("a non-empty mesh");
    let mut camera = Camera::named(NamedView::Iso, lo, hi);
    let options = SceneOptions::default();
    let readback = Readback::new(device, OFFSCREEN_FORMAT, size[0], size[1]);
    let all = [0, 0, size[0], size[1]];
    let mut times = Vec::with_capacity(frames);
    for i in 0..frames + 2 {
        camera.orbit(ORBIT_STEP_RAD, 0.0);
        let start = Instant::now();
        let mut encoder = device.create_command_encoder(&Default::default());
        renderer.render(device, queue, &mut encoder, &camera, &options);
        readback.copy(&mut encoder, renderer.target());
        queue.submit([encoder.finish()]);
        let clay = readback.count(device, all, is_clay_rgba);
        let took = start.elapsed();
        assert!(
            clay * 20 > (size[0] * size[1]) as usize,
            "the frame shows too little clay: {clay} pixels"
        );
        if i >= 2 {
            times.push(took);
        }
    }
    let label = format!(
        "MSAA {}, {}{}{}",
        settings.sample_count,
        match settings.shading {
            MeshShading::PerPixel => "per-pixel",
            MeshShading::VertexLit => "vertex-lit",
        },
        if settings.cull_back_faces {
            ", culled"
        } else {
            ""
        },
        if settings.coarse_far_bricks {
            ", far coarse"
        } else {
            ""
        }
    );
    let drawn = renderer.last_draw();
    let (median, fastest, slowest) = summary(&mut times);
    println!(
        "  scene pass, {label:<40}{what:<18} median {median:7.1} ms  (fastest {fastest:.1}, slowest {slowest:.1}; {} triangles drawn, {} bricks coarse)",
        drawn.triangles, drawn.coarse_chunks
    );
}

/// Times the upload of one changed brick (the median-sized one) against all bricks, each
/// followed by a frame that waits for the GPU.
fn upload_frames(gpu: &GpuContext, meshes: &MeshSet, settings: FrameSettings, size: [u32; 2]) {
    let (device, queue) = (&gpu.device, &gpu.queue);
    let mut renderer =
        SceneRenderer::with_settings(device, queue, OFFSCREEN_FORMAT, settings, size[0], size[1]);
    let mut owned: Vec<ChunkMesh> = meshes.iter().map(|c| (**c).clone()).collect();
    renderer
        .sync_chunks(device, queue, &chunk_views(&owned))
        .expect("valid chunks");
    let mut order: Vec<usize> = (0..owned.len()).collect();
    order.sort_by_key(|&i| owned[i].indices.len());
    let median = order[order.len() / 2];
    let (lo, hi) = bounds_of(&chunk_views(&owned)).expect("a non-empty mesh");
    let camera = Camera::named(NamedView::Iso, lo, hi);
    let options = SceneOptions::default();
    let mut time = |owned: &mut [ChunkMesh], all: bool| {
        let mut times = Vec::new();
        for _ in 0..5 {
            if all {
                owned.iter_mut().for_each(|c| c.version += 1);
            } else {
                owned[median].version += 1;
            }
            let start = Instant::now();
            let report = renderer
                .sync_chunks(device, queue, &chunk_views(owned))
                .expect("valid chunks");
            let mut encoder = device.create_command_encoder(&Default::default());
            renderer.render(device, queue, &mut encoder, &camera, &options);
            queue.submit([encoder.finish()]);
            device
                .poll(wgpu::PollType::wait_indefinitely())
                .expect("the GPU finished");
            times.push(start.elapsed());
            let expected = if all { owned.len() } else { 1 };
            assert_eq!(report.uploaded, expected, "bricks uploaded");
        }
        summary(&mut times).0
    };
    let one = time(&mut owned, false);
    let every = time(&mut owned, true);
    println!(
        "  upload + frame: one changed brick ({} tris) {one:.1} ms; all {} bricks {every:.1} ms",
        owned[median].indices.len() / 3,
        owned.len()
    );
}

fn main() {
    let mut frames = 20;
    let mut only = None;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        if a == "--only" {
            only = Some(args.next().expect("--only takes clay or sculpt"));
        } else if a == "--frames" {
            frames = args
                .next()
                .and_then(|v| v.parse().ok())
                .filter(|&n| n > 0)
                .expect("--frames takes a positive count");
        }
    }
    let gpu = match GpuContext::headless() {
        Ok(g) => g,
        Err(e) if e.is_no_adapter() => {
            println!("skipped: {e}");
            return;
        }
        Err(e) => panic!("{e}"),
    };
    let own = ProfileChoice::for_adapter(&gpu.adapter, OFFSCREEN_FORMAT, ProfileRequest::Auto);
    println!("adapter: {}", gpu.summary);
    println!("{own}");
    println!("load average before: {}", load_average());

    let (clay, cells) = default_clay();
    let clay_mesh = engine_mesh(&clay, cells);
    let meshing = Instant::now();
    let (large, large_cells) = large_sculpt(&clay, cells);
    println!(
        "meshes: default clay {} triangles in {} bricks ({cells} cells per span); sculpt {} triangles in {} bricks ({large_cells} cells per span, meshed in {:.1} s)",
        triangles(&clay_mesh),
        clay_mesh.len(),
        triangles(&large),
        large.len(),
        meshing.elapsed().as_secs_f64()
    );

    let supported = supported_sample_count(&gpu.adapter, OFFSCREEN_FORMAT);
    let variants = [
        RenderProfile::Full.settings(supported),
        FrameSettings {
            sample_count: 1,
            shading: MeshShading::PerPixel,
            cull_back_faces: false,
            coarse_far_bricks: false,
        },
        FrameSettings {
            cull_back_faces: false,
            coarse_far_bricks: false,
            ..FrameSettings::SOFTWARE
        },
        FrameSettings {
            coarse_far_bricks: false,
            ..FrameSettings::SOFTWARE
        },
        FrameSettings::SOFTWARE,
    ];
    let mut verdicts = Vec::new();
    for (name, meshes, floor_ms) in [
        ("default clay", &clay_mesh, FLOOR_CLAY_MS),
        ("500k sculpt", &large, FLOOR_LARGE_MS),
    ] {
        if only.as_deref().is_some_and(|o| !name.contains(o)) {
            continue;
        }
        println!("{name} ({} triangles):", triangles(meshes));
        let (_, full, _) = window_frames(
            &gpu,
            meshes,
            ProfileRequest::Force(RenderProfile::Full),
            frames,
        );
        let (chosen, median, view) = window_frames(&gpu, meshes, ProfileRequest::Auto, frames);
        verdicts.push(format!(
            "{name}: window frame {median:.1} ms with this adapter's profile ({chosen}; \
             {full:.1} ms with the full profile), floor {floor_ms} ms: {}",
            if median <= floor_ms { "met" } else { "MISSED" }
        ));
        println!("  3D view {}×{} pixels", view[0], view[1]);
        for settings in variants {
            scene_frames(&gpu, meshes, settings, view, frames, "");
        }
        // The same triangles as one chunk: what the per-brick draw calls cost.
        let mut merged = ChunkMesh {
            id: 1,
            version: 1,
            ..ChunkMesh::default()
        };
        for c in meshes.iter() {
            let base = merged.positions.len() as u32;
            merged.positions.extend_from_slice(&c.positions);
            merged.normals.extend_from_slice(&c.normals);
            merged.indices.extend(c.indices.iter().map(|i| i + base));
        }
        let merged = vec![Arc::new(merged)];
        scene_frames(
            &gpu,
            &merged,
            own.settings,
            view,
            frames,
            " (one draw call)",
        );
        upload_frames(&gpu, meshes, own.settings, view);
    }
    println!("load average after: {}", load_average());
    for v in verdicts {
        println!("{v}");
    }
}
