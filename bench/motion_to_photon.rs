//! Motion to photon, end to end: the built-in stroke (`dynaclay run`'s script) on the default
//! clay, played by the simulated arm through the threaded engine (haptic, simulation and
//! graphics loops at their default rates), the window's mesh sink ([`GuiMeshSink`]) and the
//! window's scene renderer drawing offscreen on whatever adapter [`GpuContext::headless`]
//! finds (lavapipe without a GPU).
//!
//! The renderer is built as the window builds its 3D view's: with the render profile
//! [`ProfileChoice`] picks for that adapter (on a software adapter one sample, vertex-lit,
//! back faces culled; [`RENDER_PROFILE_ENV`](dynaclay::render::RENDER_PROFILE_ENV) forces
//! one, as in the window), at the size of the 3D view in the window's default layout (the app
//! laid out once, without a GPU, in a window of [`GuiOptions`]' default size at one pixel per
//! point). A frame is drawn as the window draws one: when the sink asks for a repaint, no
//! sooner than the display's next refresh (`--display-hz`, 60 by default; 0 draws at once).
//! Its time is taken once the GPU finished it.
//!
//! Reports per stroke hand → force (haptic ticks), hand → first visible change and hand →
//! settled shape (ms), as percentiles over the runs (one fresh engine and clay per run, so
//! every run is the same stroke on the same clay), with the stages each went through, and the
//! frames' own times. Writes `latency.json` (the engine's document, with only the
//! motion-to-photon figures) and `motion_to_photon.md` into `--out`.
//!
//! Prints "skipped: no GPU adapter" and exits cleanly when there is none.
//!
//! ```text
//! cargo bench --bench motion_to_photon -- [--runs 12] [--display-hz 60] [--profile P]
//!     [--size WxH] [--msaa N] [--graphics-hz HZ] [--graphics-max-hz HZ] [--out DIR]
//! ```
//!
//! `--profile` (`full`, `software` or `auto`) forces a render profile; `--size` replaces the
//! view's size and `--msaa` the profile's sample count (at most what the adapter supports):
//! they show what the frame's own cost does to the figures. `--graphics-hz` shows what the
//! graphics loop's period does, `--graphics-max-hz` what its cap on ticks woken by the
//! simulation's publications does (set it to the period's rate to see the loop without
//! early wake-ups). Each run also prints the graphics loop's re-meshes, the snapshots whose
//! re-mesh it held back as too small to see, and the bricks it re-meshed.
//!
//! Optimistic where the window is not: no egui compositing or presentation after the scene is
//! drawn, and one fixed camera. Pessimistic where it is: the frame waits for the GPU to finish.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use crossbeam::channel::bounded;
use dynaclay::app::{GuiMeshSink, GuiOptions, MeshSet, RepaintSignal, SculptApp, engine_link};
use dynaclay::engine::{
    CounterSnapshot, Engine, EngineConfig, MotionToPhoton, ScriptDriver, ScriptPlan, StrokeLatency,
    build_clay, summarize,
};
use dynaclay::render::{
    Camera, FrameSettings, GpuContext, MeshChunk, NamedView, OFFSCREEN_FORMAT, ProfileChoice,
    ProfileRequest, SceneOptions, SceneRenderer, supported_sample_count,
};
use dynaclay_devices::{SimArmConfig, SimulatedArm};
use dynaclay_loops::{ProfileDoc, Spread, motion_table, snapshot_channel};

/// How often the driver looks at the tool while waiting for a repaint (as `dynaclay run` does).
const DISPATCH_PERIOD: Duration = Duration::from_millis(2);

/// How long a run goes on past the script's end for its stroke to be known settled (the
/// simulation names the settled shape when the stroke's region retires).
const SETTLE_WAIT: Duration = Duration::from_secs(5);

struct Args {
    runs: usize,
    display_hz: f64,
    /// The view's size (`None`: the window's default 3D view).
    size: Option<(u32, u32)>,
    /// The render profile (`Auto`: as the window chooses, including what
    /// [`RENDER_PROFILE_ENV`](dynaclay::render::RENDER_PROFILE_ENV) forces).
    profile: ProfileRequest,
    /// Whether `--profile` set [`Self::profile`] (rather than the environment).
    profile_flag: bool,
    /// Samples per pixel (`None`: the profile's).
    msaa: Option<u32>,
    /// The graphics loop's rate (`None`: the engine's default).
    graphics_hz: Option<f64>,
    /// The graphics loop's cap on woken ticks (`None`: the engine's default).
    graphics_max_hz: Option<f64>,
    out: PathBuf,
}

fn parse_args() -> Args {
    let mut args = Args {
        runs: 12,
        display_hz: 60.0,
        size: None,
        profile: ProfileRequest::from_env().unwrap_or_else(|e| panic!("{e}")),
        profile_flag: false,
        msaa: None,
        graphics_hz: None,
        graphics_max_hz: None,
        out: PathBuf::from("target/tmp/motion_to_photon"),
    };
    let mut it = std::env::args().skip(1);
    while let Some(a) = it.next() {
        match a.as_str() {
            "--runs" => args.runs = it.next().and_then(|v| v.parse().ok()).unwrap_or(args.runs),
            "--display-hz" => {
                args.display_hz = it
                    .next()
                    .and_then(|v| v.parse().ok())
                    .unwrap_or(args.display_hz);
            }
            "--out" => args.out = it.next().map_or(args.out, PathBuf::from),
            "--msaa" => args.msaa = it.next().and_then(|v| v.parse().ok()),
            "--profile" => {
                let value = it.next().unwrap_or_default();
                args.profile = value.parse().unwrap_or_else(|e| panic!("--profile: {e}"));
                args.profile_flag = true;
            }
            "--graphics-hz" => {
                args.graphics_hz = it
                    .next()
                    .and_then(|v| v.parse().ok())
                    .filter(|hz: &f64| hz.is_finite() && *hz > 0.0);
            }
            "--graphics-max-hz" => {
                args.graphics_max_hz = it
                    .next()
                    .and_then(|v| v.parse().ok())
                    .filter(|hz: &f64| hz.is_finite() && *hz > 0.0);
            }
            "--size" => {
                let wh: Vec<u32> = it
                    .next()
                    .unwrap_or_default()
                    .split('x')
                    .filter_map(|v| v.parse().ok())
                    .collect();
                if let [w, h] = wh[..] {
                    args.size = Some((w.max(1), h.max(1)));
                }
            }
            // cargo bench passes --bench; criterion-style flags are not ours.
            _ => {}
        }
    }
    args.runs = args.runs.max(1);
    args
}

/// The 3D view's size in pixels when the window opens at its default size: the app laid out
/// once (without a GPU, at one pixel per point) and its view's rectangle read back.
fn default_view_size() -> (u32, u32) {
    let [w, h] = GuiOptions::default().window_size_pt;
    let (link, _end) = engine_link();
    let mut app = SculptApp::new(link);
    let ctx = egui::Context::default();
    // The second pass lays out with the sizes the first measured, as a window's frames do.
    for _ in 0..2 {
        let input = egui::RawInput {
            screen_rect: Some(egui::Rect::from_min_size(
                egui::Pos2::ZERO,
                egui::vec2(w, h),
            )),
            ..Default::default()
        };
        let _ = ctx.run_ui(input, |ui| app.show(ui, None));
    }
    let view = app.viewport_rect.expect("the app laid out its 3D view");
    (
        (view.width().round() as u32).max(1),
        (view.height().round() as u32).max(1),
    )
}

/// One run's strokes and frames.
struct RunFigures {
    strokes: Vec<StrokeLatency>,
    frame_ms: Vec<f64>,
    triangles: usize,
    /// The engine's counters at the end of the run.
    counters: CounterSnapshot,
}

fn main() {
    let args = parse_args();
    let gpu = match GpuContext::headless() {
        Ok(g) => g,
        Err(e) if e.is_no_adapter() => {
            println!("skipped: {e}");
            return;
        }
        Err(e) => panic!("{e}"),
    };
    let supported = supported_sample_count(&gpu.adapter, OFFSCREEN_FORMAT);
    let choice = ProfileChoice::for_adapter(&gpu.adapter, OFFSCREEN_FORMAT, args.profile);
    let settings = FrameSettings {
        sample_count: args
            .msaa
            .map_or(choice.settings.sample_count, |m| m.clamp(1, supported)),
        ..choice.settings
    };
    let size = args.size.unwrap_or_else(default_view_size);
    let frame_words = format!(
        "{}x{} {} profile, MSAA {}x{}",
        size.0,
        size.1,
        choice.profile.name(),
        settings.sample_count,
        if args.msaa.is_some() || args.size.is_some() {
            " (overridden)"
        } else {
            ""
        }
    );
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    if args.profile_flag {
        println!(
            "render profile {} forced by --profile on {}: {}",
            choice.profile.name(),
            choice.adapter_name,
            choice.short()
        );
    } else {
        println!("{choice}");
    }
    println!(
        "adapter: {}; {frame_words}; {settings:?}; display {} Hz; graphics loop {}, woken up to {}; load average {}",
        gpu.summary,
        args.display_hz,
        args.graphics_hz.map_or_else(
            || "at its default rate".to_string(),
            |hz| format!("{hz} Hz")
        ),
        args.graphics_max_hz
            .map_or_else(|| "its default cap".to_string(), |hz| format!("{hz} Hz")),
        load.split_whitespace()
            .take(3)
            .collect::<Vec<_>>()
            .join(" ")
    );
    let plan = ScriptPlan::builtin();
    let mut strokes = Vec::new();
    let mut frame_ms = Vec::new();
    for run in 0..args.runs {
        let figures = one_run(&gpu, settings, size, &plan, &args);
        let first = figures
            .strokes
            .iter()
            .filter_map(|s| s.first_visible)
            .map(|p| format!("{:.1}", p.total_ms()))
            .collect::<Vec<_>>();
        let settled = figures
            .strokes
            .iter()
            .filter_map(|s| s.settled)
            .map(|p| format!("{:.1}", p.total_ms()))
            .collect::<Vec<_>>();
        let frames = Spread::of(&figures.frame_ms);
        println!(
            "run {run}: first visible {} ms, settled {} ms; {} frames (p50 {:.1} ms, max {:.1} ms), {} triangles; graphics: {} re-meshes, {} held back, {} bricks",
            first.join(", "),
            settled.join(", "),
            frames.count,
            frames.p50,
            frames.max,
            figures.triangles,
            figures.counters.graphics_updates,
            figures.counters.graphics_deferred,
            figures.counters.bricks_remeshed,
        );
        strokes.extend(figures.strokes);
        frame_ms.extend(figures.frame_ms);
    }
    let presenter = format!(
        "offscreen scene renderer on {}, {frame_words} ({} Hz display)",
        gpu.summary, args.display_hz
    );
    let summary = summarize(&strokes, &presenter);
    let frames = Spread::of(&frame_ms);
    let mut md = String::from("# Motion to photon: the built-in stroke, offscreen\n\n");
    md.push_str(&motion_table(&summary));
    md.push_str(&format!(
        "\nFrames (draw and GPU finish, ms): n {} p50 {:.1} p95 {:.1} max {:.1}\n",
        frames.count, frames.p50, frames.p95, frames.max
    ));
    println!("\n{md}");
    let doc = ProfileDoc {
        motion_to_photon: Some(summary),
        ..ProfileDoc::default()
    };
    std::fs::create_dir_all(&args.out).expect("output directory");
    let json = doc.to_json().expect("the document serialises");
    std::fs::write(args.out.join("latency.json"), json).expect("latency.json written");
    std::fs::write(args.out.join("motion_to_photon.md"), md).expect("report written");
    println!("wrote {}", args.out.display());
}

/// One fresh engine on the default clay playing the built-in stroke, its meshes drawn as the
/// window draws them.
fn one_run(
    gpu: &GpuContext,
    settings: FrameSettings,
    size: (u32, u32),
    plan: &ScriptPlan,
    args: &Args,
) -> RunFigures {
    let display_hz = args.display_hz;
    let field = build_clay(&plan.clay).expect("the built-in clay");
    let (lo, hi) = {
        let b = &field;
        let last = b.dims.map(|d| d - 1);
        (b.origin, b.node_position(last[0], last[1], last[2]))
    };
    let arm_config = SimArmConfig::default();
    let mut config = EngineConfig::for_field(&field, &arm_config.info);
    config.haptics.tool_contact = plan.tool_contact;
    if let Some(hz) = args.graphics_hz {
        config.graphics_rate_hz = hz;
    }
    if let Some(hz) = args.graphics_max_hz {
        config.graphics_max_rate_hz = hz;
    }
    let arm = SimulatedArm::new(
        arm_config,
        plan.trajectory(&config.map).expect("the built-in path"),
    );

    let (meshes_tx, mut meshes) = snapshot_channel(&MeshSet::new());
    let (field_tx, _field) =
        snapshot_channel(&dynaclay::field::MultiPatchField::from(field.clone()));
    let (exports_tx, _exports) = snapshot_channel(&MeshSet::new());
    let repaint = RepaintSignal::default();
    let (wake_tx, wake) = bounded::<()>(1);
    repaint.install(move || {
        // A full slot already asks for a frame.
        let _ = wake_tx.try_send(());
    });
    let sink = GuiMeshSink::new(meshes_tx, field_tx, exports_tx, repaint);
    let mut engine =
        Engine::start(&config, field, Box::new(arm), Box::new(sink)).expect("the engine starts");
    let mut stamps = engine.take_mesh_stamps().expect("the mesh stamps");
    let clock = engine.clock();

    let (device, queue) = (&gpu.device, &gpu.queue);
    let mut renderer =
        SceneRenderer::with_settings(device, queue, OFFSCREEN_FORMAT, settings, size.0, size.1);
    let camera = Camera::named(NamedView::Iso, lo, hi);
    let options = SceneOptions::default();
    let refresh = (display_hz > 0.0).then(|| Duration::from_secs_f64(1.0 / display_hz));

    let mut driver = ScriptDriver::new(plan);
    let commands = engine.commands();
    let mut ledger = MotionToPhoton::new();
    let mut frame_ms = Vec::new();
    let mut wanted = false;
    let mut last_frame: Option<Instant> = None;
    let started = Instant::now();
    let script = Duration::from_secs_f64(plan.seconds);
    let settled = |l: &MotionToPhoton| {
        l.strokes().next().is_some() && l.strokes().all(|s| s.settled.is_some())
    };
    while engine.is_alive()
        && (started.elapsed() < script
            || (!settled(&ledger) && started.elapsed() < script + SETTLE_WAIT))
    {
        let sample = engine.latest_tool();
        driver.dispatch(&sample, &commands);
        wanted |= wake.recv_timeout(DISPATCH_PERIOD).is_ok();
        ledger.observe(&stamps.latest().value);
        if !wanted {
            continue;
        }
        // The display's next refresh: a frame waits for it as the window's does.
        if let (Some(period), Some(at)) = (refresh, last_frame)
            && at.elapsed() < period
        {
            std::thread::sleep(period - at.elapsed());
        }
        wanted = false;
        last_frame = Some(Instant::now());
        let frame_start = Instant::now();
        // The stamp before the meshes: the meshes drawn are at least as new as it says.
        let stamp = stamps.latest().value;
        let set = &meshes.latest().value;
        let chunks: Vec<MeshChunk<'_>> = set.iter().map(|c| c.as_chunk()).collect();
        renderer
            .sync_chunks(device, queue, &chunks)
            .expect("valid chunks");
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("motion to photon frame"),
        });
        renderer.render(device, queue, &mut encoder, &camera, &options);
        queue.submit([encoder.finish()]);
        device
            .poll(wgpu::PollType::wait_indefinitely())
            .expect("the GPU finished the frame");
        ledger.frame(clock.now_ns(), &stamp);
        frame_ms.push(frame_start.elapsed().as_secs_f64() * 1e3);
    }
    drop(commands);
    let triangles = renderer.triangle_count();
    let report = engine.stop().expect("the engine stops");
    RunFigures {
        strokes: ledger.strokes().copied().collect(),
        frame_ms,
        triangles,
        counters: report.counters,
    }
}
