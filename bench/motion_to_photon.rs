//! Motion to photon, end to end: the built-in stroke (`dynaclay run`'s script) on the default
//! clay, played by the simulated arm through the threaded engine (haptic, simulation and
//! graphics loops at their default rates), the window's mesh sink ([`GuiMeshSink`]) and the
//! window's scene renderer drawing offscreen on whatever adapter [`GpuContext::headless`]
//! finds (lavapipe without a GPU). A frame is drawn as the window draws one: when the sink asks
//! for a repaint, no sooner than the display's next refresh (`--display-hz`, 60 by default;
//! 0 draws at once). Its time is taken once the GPU finished it.
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
//! cargo bench --bench motion_to_photon -- [--runs 12] [--display-hz 60] [--size 1280x720]
//!     [--msaa N] [--graphics-hz HZ] [--out DIR]
//! ```
//!
//! `--size` and `--msaa` (1, or at most what the adapter supports; the window takes the
//! most) show what the frame's own cost does to the figures; `--graphics-hz` what the
//! graphics loop's period does.
//!
//! Optimistic where the window is not: no egui compositing or presentation after the scene is
//! drawn, and one fixed camera. Pessimistic where it is: the frame waits for the GPU to finish.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use crossbeam::channel::bounded;
use dynaclay::app::{GuiMeshSink, MeshSet, RepaintSignal};
use dynaclay::engine::{
    Engine, EngineConfig, MotionToPhoton, ScriptDriver, ScriptPlan, StrokeLatency, build_clay,
    summarize,
};
use dynaclay::render::{
    Camera, GpuContext, MeshChunk, NamedView, OFFSCREEN_FORMAT, SceneOptions, SceneRenderer,
    supported_sample_count,
};
use dynaclay_devices::{SimArmConfig, SimulatedArm};
use dynaclay_loops::{ProfileDoc, Spread, motion_table, snapshot_channel};

/// The offscreen frame's size: about a window's 3D view.
const FRAME_SIZE: (u32, u32) = (1280, 720);

/// How often the driver looks at the tool while waiting for a repaint (as `dynaclay run` does).
const DISPATCH_PERIOD: Duration = Duration::from_millis(2);

/// How long a run goes on past the script's end for its stroke to be known settled (the
/// simulation names the settled shape when the stroke's region retires).
const SETTLE_WAIT: Duration = Duration::from_secs(5);

struct Args {
    runs: usize,
    display_hz: f64,
    size: (u32, u32),
    /// Multisampling asked for (`None`: the window's choice, the most the adapter supports).
    msaa: Option<u32>,
    /// The graphics loop's rate (`None`: the engine's default).
    graphics_hz: Option<f64>,
    out: PathBuf,
}

fn parse_args() -> Args {
    let mut args = Args {
        runs: 12,
        display_hz: 60.0,
        size: FRAME_SIZE,
        msaa: None,
        graphics_hz: None,
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
            "--graphics-hz" => {
                args.graphics_hz = it
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
                    args.size = (w.max(1), h.max(1));
                }
            }
            // cargo bench passes --bench; criterion-style flags are not ours.
            _ => {}
        }
    }
    args.runs = args.runs.max(1);
    args
}

/// One run's strokes and frames.
struct RunFigures {
    strokes: Vec<StrokeLatency>,
    frame_ms: Vec<f64>,
    triangles: usize,
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
    let samples = args.msaa.map_or(supported, |m| m.clamp(1, supported));
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    println!(
        "adapter: {}; {}x{} MSAA {samples}x; display {} Hz; graphics loop {}; load average {}",
        gpu.summary,
        args.size.0,
        args.size.1,
        args.display_hz,
        args.graphics_hz.map_or_else(
            || "at its default rate".to_string(),
            |hz| format!("{hz} Hz")
        ),
        load.split_whitespace()
            .take(3)
            .collect::<Vec<_>>()
            .join(" ")
    );
    let plan = ScriptPlan::builtin();
    let mut strokes = Vec::new();
    let mut frame_ms = Vec::new();
    for run in 0..args.runs {
        let figures = one_run(&gpu, samples, &plan, &args);
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
            "run {run}: first visible {} ms, settled {} ms; {} frames (p50 {:.1} ms, max {:.1} ms), {} triangles",
            first.join(", "),
            settled.join(", "),
            frames.count,
            frames.p50,
            frames.max,
            figures.triangles
        );
        strokes.extend(figures.strokes);
        frame_ms.extend(figures.frame_ms);
    }
    let presenter = format!(
        "offscreen scene renderer on {}, {}x{} MSAA {samples}x ({} Hz display)",
        gpu.summary, args.size.0, args.size.1, args.display_hz
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
fn one_run(gpu: &GpuContext, samples: u32, plan: &ScriptPlan, args: &Args) -> RunFigures {
    let (display_hz, size) = (args.display_hz, args.size);
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
    let mut renderer = SceneRenderer::new(device, queue, OFFSCREEN_FORMAT, samples, size.0, size.1);
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
    engine.stop().expect("the engine stops");
    RunFigures {
        strokes: ledger.strokes().copied().collect(),
        frame_ms,
        triangles,
    }
}
