//! Headless frames of the whole app (egui_kittest, no display server, no GPU): widgets are
//! found through the accessibility tree and clicked or set as a user would, and the commands
//! that reach the engine's end of the link are checked.

use egui::accesskit::Role;
use egui_kittest::Harness;
use egui_kittest::kittest::Queryable;

use dynaclay_devices::spec::DeviceSpec;
use dynaclay_loops::LatencyStats;

use super::command::{EngineCommand, EngineEvent};
use super::link::{EngineEndpoint, engine_link};
use super::state::SculptApp;
use super::view::{DeviceLinkState, EngineView};
use crate::dynamics::Material;
use crate::engine::ToolChoice;
use crate::tools::ForceTool;
use crate::tools::ToolAction;

fn harness() -> (Harness<'static, SculptApp>, EngineEndpoint) {
    let (link, end) = engine_link();
    let app = SculptApp::new(link);
    let h = Harness::builder()
        .with_size(egui::vec2(1400.0, 1000.0))
        .build_ui_state(|ui, app: &mut SculptApp| app.show(ui, None), app);
    (h, end)
}

fn drain(end: &EngineEndpoint) -> Vec<EngineCommand> {
    end.commands.try_iter().collect()
}

#[test]
fn the_first_frame_sends_the_current_tool() {
    let (mut h, end) = harness();
    h.run();
    let sent = drain(&end);
    assert!(
        matches!(
            sent.as_slice(),
            [EngineCommand::SelectTool(ToolChoice::Push(_))]
        ),
        "{sent:?}"
    );
}

#[test]
fn clicking_a_tool_selects_it_in_the_engine() {
    let (mut h, end) = harness();
    h.run();
    drain(&end);

    h.get_by_label("Smooth").click();
    h.run();
    let sent = drain(&end);
    let [EngineCommand::SelectTool(ToolChoice::Geometric(tool))] = sent.as_slice() else {
        panic!("expected one SelectTool, got {sent:?}");
    };
    assert!(matches!(tool.action, ToolAction::Smooth { .. }), "{tool:?}");

    h.get_by_label("Chisel").click();
    h.run();
    let sent = drain(&end);
    let [EngineCommand::SelectTool(force)] = sent.as_slice() else {
        panic!("expected one SelectTool, got {sent:?}");
    };
    assert!(
        matches!(
            force,
            ToolChoice::Force {
                tool: ForceTool::Chisel { .. },
                ..
            }
        ),
        "{force:?}"
    );
    assert_eq!(&h.state().palette.choice(), force);
}

#[test]
fn moving_a_material_slider_sets_the_engine_material() {
    let (mut h, end) = harness();
    h.run();
    drain(&end);

    h.get_by_role_and_label(Role::Slider, "Stiffness")
        .set_value_accesskit(5000.0);
    h.run();
    let sent = drain(&end);
    let [EngineCommand::SetMaterial(m)] = sent.as_slice() else {
        panic!("expected one SetMaterial, got {sent:?}");
    };
    assert!(
        (m.stiffness - 5000.0).abs() < 1.0,
        "stiffness {}",
        m.stiffness
    );
    assert_eq!(m.mass, Material::default().mass, "other fields unchanged");

    h.get_by_role_and_label(Role::Slider, "Plasticity /s")
        .set_value_accesskit(4.0);
    h.run();
    let sent = drain(&end);
    let [EngineCommand::SetMaterial(m2)] = sent.as_slice() else {
        panic!("expected one SetMaterial, got {sent:?}");
    };
    assert!((m2.plasticity_per_s - 4.0).abs() < 1e-3);
    assert!(
        (m2.stiffness - m.stiffness).abs() < 1e-3,
        "earlier change kept"
    );
}

#[test]
fn the_springs_selector_sends_the_material_with_its_neighbourhood() {
    let (mut h, end) = harness();
    h.run();
    drain(&end);
    h.get_by_role_and_label(Role::ComboBox, "Springs").click();
    h.run();
    h.get_by_label("26 neighbours").click();
    h.run();
    let sent = drain(&end);
    let [EngineCommand::SetMaterial(m)] = sent.as_slice() else {
        panic!("expected one SetMaterial, got {sent:?}");
    };
    assert_eq!(m.neighbourhood, crate::dynamics::Neighbourhood::TwentySix);
    assert_eq!(
        m.stiffness,
        Material::default().stiffness,
        "other fields unchanged"
    );
}

#[test]
fn the_material_brush_paints_around_the_last_brush_point_and_clears() {
    let (mut h, end) = harness();
    h.run();
    drain(&end);
    h.get_by_label("Paint material").click();
    h.run();
    // Before the brush was on the clay there is nowhere to paint: the button is disabled.
    h.get_by_label("Paint here").click();
    h.run();
    assert!(drain(&end).is_empty());
    let at = glam::Vec3::new(1.0, 1.7, 1.1);
    h.state_mut().refine_at = Some(at);
    h.run();
    h.get_by_label("Paint here").click();
    h.run();
    let sent = drain(&end);
    let [EngineCommand::PaintMaterial(paint)] = sent.as_slice() else {
        panic!("expected one PaintMaterial, got {sent:?}");
    };
    assert_eq!(
        paint.region,
        crate::dynamics::PaintRegion::Sphere {
            centre: at,
            radius_fu: 0.2
        }
    );
    assert_eq!(paint.stiffness, Some(5.0 * Material::PLASTIC.stiffness));
    assert_eq!((paint.mass, paint.damping), (None, None));
    h.get_by_label("Clear painted material").click();
    h.run();
    let sent = drain(&end);
    assert!(
        matches!(sent.as_slice(), [EngineCommand::ClearMaterialPaint]),
        "{sent:?}"
    );
}

#[test]
fn refine_here_asks_for_a_detail_patch_around_the_last_brush_point() {
    let (mut h, end) = harness();
    h.run();
    drain(&end);
    // Before the brush was on the clay there is nowhere to refine: the button is disabled.
    h.get_by_label("Refine here").click();
    h.run();
    assert!(drain(&end).is_empty());
    let at = glam::Vec3::new(1.0, 1.7, 1.1);
    h.state_mut().refine_at = Some(at);
    h.run();
    h.get_by_label("Refine here").click();
    h.run();
    let sent = drain(&end);
    let [EngineCommand::Refine { lo, hi, level }] = sent.as_slice() else {
        panic!("expected one Refine, got {sent:?}");
    };
    assert_eq!(*level, 2);
    assert!(
        lo.cmplt(at).all() && hi.cmpgt(at).all(),
        "{lo}..{hi} holds {at}"
    );
    assert!(
        ((*lo + *hi) * 0.5 - at).length() < 1e-5,
        "centred on the point"
    );
}

#[test]
fn history_buttons_and_save_send_their_commands() {
    let (mut h, end) = harness();
    h.run();
    drain(&end);
    for label in ["Undo", "Redo", "Save"] {
        h.get_by_label(label).click();
        h.run();
    }
    let sent = drain(&end);
    assert_eq!(
        sent,
        vec![
            EngineCommand::Undo,
            EngineCommand::Redo,
            EngineCommand::Save {
                path: "sculpt.dclay".into()
            },
        ]
    );
}

#[test]
fn connecting_the_device_sends_the_parsed_spec_and_limit() {
    let (mut h, end) = harness();
    h.run();
    drain(&end);
    // The device section sits below the sculpting sections: bring it into view first.
    h.get_by_label("Connect").scroll_to_me();
    h.run();
    h.get_by_label("Connect").click();
    h.run();
    assert_eq!(
        drain(&end),
        vec![EngineCommand::ConnectDevice {
            spec: DeviceSpec::Sim,
            max_force_n: 3.0
        }]
    );
}

#[test]
fn published_state_reaches_the_panels_without_commands_back() {
    let (mut h, mut end) = harness();
    h.run();
    drain(&end);

    let mut loops = [LatencyStats::default(); 3];
    loops[0].ticks = 1000;
    loops[0].achieved_rate_hz = 999.5;
    loops[0].nominal_rate_hz = 1000.0;
    loops[0].period_error.p99_us = 12.0;
    let view = EngineView {
        material: Material::PLASTIC,
        undo_steps: 2,
        loops,
        ..EngineView::default()
    };
    let mut connected = view.clone();
    connected.device.state = DeviceLinkState::Connected;
    connected.device.name = "simulated arm".into();
    end.view.publish_clone_of(&connected);
    end.events
        .send(EngineEvent::Done {
            what: "save".into(),
            detail: "wrote sculpt.dclay".into(),
        })
        .unwrap();
    h.run();

    let app = h.state();
    assert_eq!(
        app.material,
        Material::PLASTIC,
        "sliders follow the engine's material"
    );
    assert_eq!(app.latency.samples[0].len(), 1);
    assert_eq!(
        app.log.back().map(String::as_str),
        Some("save: wrote sculpt.dclay")
    );
    h.get_by_label("simulated arm");
    h.get_by_label("connected");
    assert!(drain(&end).is_empty(), "reading state sends nothing");
}

#[test]
fn dragging_in_the_view_orbits_and_scrolling_zooms() {
    let (mut h, _end) = harness();
    h.run();
    let before = h.state().camera;
    let centre = egui::pos2(700.0, 500.0);
    let press = |pressed| egui::Event::PointerButton {
        pos: centre,
        button: egui::PointerButton::Primary,
        pressed,
        modifiers: egui::Modifiers::NONE,
    };
    h.event(egui::Event::PointerMoved(centre));
    h.event(press(true));
    h.step();
    for i in 1..=5 {
        h.event(egui::Event::PointerMoved(
            centre + egui::vec2(12.0 * i as f32, 0.0),
        ));
        h.step();
    }
    h.event(press(false));
    h.run();
    let after = h.state().camera;
    assert!(
        (after.yaw_rad - before.yaw_rad).abs() > 1e-3,
        "yaw {} -> {}",
        before.yaw_rad,
        after.yaw_rad
    );

    h.event(egui::Event::MouseWheel {
        unit: egui::MouseWheelUnit::Point,
        delta: egui::vec2(0.0, 120.0),
        phase: egui::TouchPhase::Move,
        modifiers: egui::Modifiers::NONE,
        source: egui::MouseWheelSource::Wheel,
    });
    h.run();
    assert!(h.state().camera.distance < after.distance);
}

/// Opens the latency panel's details (closed at first): the probe's figures and the plots.
fn open_latency_details(h: &mut Harness<'static, SculptApp>) {
    h.get_by_label("details").click();
    h.run();
}

fn loop_stats(ticks: u64, rate_hz: f64, p99_us: f64) -> LatencyStats {
    let mut s = LatencyStats {
        ticks,
        achieved_rate_hz: rate_hz,
        nominal_rate_hz: 1000.0,
        deadline_misses: 2,
        ..LatencyStats::default()
    };
    s.period_error.p99_us = p99_us;
    s.compute.p50_us = 3.0;
    s.compute.p99_us = 8.5;
    s
}

#[test]
fn the_latency_panel_shows_each_loops_published_figures() {
    let (mut h, mut end) = harness();
    h.run();
    open_latency_details(&mut h);
    assert_eq!(h.query_all_by_label("no figures yet").count(), 3);

    let view = EngineView {
        loops: [
            loop_stats(1000, 999.5, 12.0),
            loop_stats(980, 980.0, 40.0),
            loop_stats(60, 59.9, 900.0),
        ],
        ..EngineView::default()
    };
    end.view.publish_clone_of(&view);
    h.run();
    h.get_by_label("1000 / 1000 Hz, 2 misses, 0 late >1 ms");
    h.get_by_label("period error p99 12.0 µs, compute p50 3.0 / p99 8.5 µs");
    h.get_by_label("980 / 1000 Hz, 2 misses, 0 late >1 ms");
    h.get_by_label("period error p99 900.0 µs, compute p50 3.0 / p99 8.5 µs");
    assert!(h.query_by_label("no figures yet").is_none());
    assert!(h.state().latency.samples.iter().all(|s| s.len() == 1));

    // The bridge republishes the view often; only loops with new figures add a point.
    let mut next = view.clone();
    next.tool_position.x = 1.0;
    end.view.publish_clone_of(&next);
    h.run();
    next.loops[0] = loop_stats(2000, 1000.0, 15.0);
    end.view.publish_clone_of(&next);
    h.run();
    let lens: Vec<usize> = h.state().latency.samples.iter().map(|s| s.len()).collect();
    assert_eq!(lens, vec![2, 1, 1]);
    h.get_by_label("period error p99 15.0 µs, compute p50 3.0 / p99 8.5 µs");
}

#[test]
fn the_machine_section_shows_the_probes_figures_and_the_verdict() {
    let (mut h, _end) = harness();
    h.run();
    // The app built for tests does not probe by itself.
    h.get_by_label("not probed yet");
    assert!(!h.state().probe.is_running());
    open_latency_details(&mut h);
    h.get_by_label("no probe figures yet");

    let mut wakeup = loop_stats(1000, 999.8, 4.0);
    wakeup.lateness.p99_us = 3.0;
    wakeup.lateness.p999_us = 30.0;
    wakeup.lateness.max_us = 120.0;
    let summary = dynaclay_loops::ProbeSummary {
        wakeup_rt: dynaclay_loops::RtOutcome::Granted { priority: 80 },
        wakeup,
        stall_rt: dynaclay_loops::RtOutcome::NotRequested,
        stalls: dynaclay_loops::StallStats {
            seconds: 0.5,
            gap_threshold_us: 20.0,
            gaps: 7,
            stolen_ms: 1.25,
            max_gap_us: 400.0,
            gap_counts: None,
        },
    };
    h.state_mut()
        .probe
        .finish(Ok(super::probe_panel::ProbeOutcome::before_engine(
            &summary,
            Some(0.1),
        )));
    h.run();
    assert!(h.query_by_label("not probed yet").is_none());
    h.get_by_label("wake-up p99 3.0 µs, p99.9 30.0 µs, max 120.0 µs");
    h.get_by_label("host stalls: 7 gaps, 2.50 ms/s, worst 400 µs");
    h.get_by_label_contains("1000 Hz: ");
    h.get_by_label_contains("4000 Hz: ");

    h.get_by_label_contains("before the engine started");

    // A probe beside the engine keeps the stalls counted at launch and says so.
    let stalls = h.state().probe.last.as_ref().and_then(|(_, o)| o.stalls);
    let mut later = wakeup;
    later.lateness.p99_us = 5.0;
    h.state_mut().probe.finish(Ok(super::probe_panel::judge(
        dynaclay_loops::RtOutcome::Granted { priority: 79 },
        later,
        stalls,
        true,
        None,
    )));
    h.run();
    h.get_by_label("wake-up p99 5.0 µs, p99.9 30.0 µs, max 120.0 µs");
    h.get_by_label("host stalls: 7 gaps, 2.50 ms/s, worst 400 µs");
    h.get_by_label("(stalls counted at launch, before the engine started)");
    h.get_by_label_contains("beside the engine");

    // A failed probe says why and keeps the last figures.
    h.state_mut()
        .probe
        .finish(Err("cannot run the platform probe: test".into()));
    h.run();
    h.get_by_label("cannot run the platform probe: test");
    h.get_by_label("wake-up p99 5.0 µs, p99.9 30.0 µs, max 120.0 µs");
}

#[test]
fn the_latency_panel_is_one_plain_line_until_its_details_are_opened() {
    let (mut h, mut end) = harness();
    h.run();
    // A probe at launch that saw 2 ms host stalls five times a second: alone, it fails 1 kHz.
    let mut gap_counts = dynaclay_loops::GapCounts::default();
    for _ in 0..5 {
        gap_counts.add(2_000_000);
    }
    let stalls = dynaclay_loops::StallStats {
        seconds: 1.0,
        gap_threshold_us: 20.0,
        gaps: 5,
        stolen_ms: 10.0,
        max_gap_us: 2000.0,
        gap_counts: Some(gap_counts),
    };
    let mut wakeup = loop_stats(1000, 999.8, 4.0);
    wakeup.lateness.p99_us = 3.0;
    wakeup.lateness.p999_us = 30.0;
    wakeup.lateness.max_us = 120.0;
    let summary = dynaclay_loops::ProbeSummary {
        wakeup_rt: dynaclay_loops::RtOutcome::Granted { priority: 80 },
        wakeup,
        stall_rt: dynaclay_loops::RtOutcome::Granted { priority: 80 },
        stalls,
    };
    h.state_mut()
        .probe
        .finish(Ok(super::probe_panel::ProbeOutcome::before_engine(
            &summary, None,
        )));
    h.run();
    h.get_by_label_contains("not suited for 1 kHz: host stalls up to 2000 µs");
    // The figures and the loops' plots wait behind "details".
    assert!(h.query_by_label_contains("wake-up p99 ").is_none());
    assert!(h.query_by_label("no figures yet").is_none());
    assert!(h.query_by_label("Probe again").is_none());

    // The haptic loop then meets every deadline for five seconds: its record outweighs the
    // probe, and the line says so.
    let mut haptic = loop_stats(5000, 1000.0, 12.0);
    haptic.deadline_misses = 0;
    haptic.elapsed_s = 5.0;
    haptic.lateness.max_us = 70.0;
    haptic.compute.max_us = 40.0;
    let view = EngineView {
        loops: [haptic, LatencyStats::default(), LatencyStats::default()],
        ..EngineView::default()
    };
    end.view.publish_clone_of(&view);
    h.run();
    assert!(h.query_by_label_contains("not suited for 1 kHz").is_none());
    h.get_by_label_contains("marginal for 1 kHz: ");

    open_latency_details(&mut h);
    h.get_by_label("wake-up p99 3.0 µs, p99.9 30.0 µs, max 120.0 µs");
    h.get_by_label("Probe again");
    h.get_by_label_contains("1000 Hz: marginal");
    assert_eq!(h.query_all_by_label("no figures yet").count(), 2);
}

#[test]
fn probe_again_runs_the_wake_up_probe_on_a_worker_and_shows_it() {
    let (mut h, _end) = harness();
    h.run();
    open_latency_details(&mut h);
    h.get_by_label("Probe again").click();
    // Single frames: the spinner keeps asking for repaints while the probe runs.
    h.step();
    assert!(h.state().probe.is_running());
    // The worker sleeps through half a second of wake-ups; the frame only polls it.
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(30);
    while h.state().probe.is_running() && std::time::Instant::now() < deadline {
        std::thread::sleep(std::time::Duration::from_millis(20));
        h.step();
    }
    assert!(!h.state().probe.is_running(), "the probe never finished");
    h.run();
    h.get_by_label_contains("beside the engine");
    h.get_by_label_contains("wake-up p99 ");
    // No stall counts: none were made at launch here.
    h.get_by_label("host stalls: not counted (counted only before the engine starts)");
}

#[test]
fn the_latency_panel_draws_histograms_and_timelines_from_the_loops_bins() {
    let (mut h, mut end) = harness();
    h.run();
    open_latency_details(&mut h);
    let mut view = EngineView::default();
    for (i, stats) in view.loops.iter_mut().enumerate() {
        *stats = loop_stats(1000 * (i as u64 + 1), 999.0, 10.0);
        for _ in 0..1000 {
            stats.period_error_bins.record(2_000);
            stats.compute_bins.record(8_000);
        }
    }
    end.view.publish_clone_of(&view);
    h.run();
    let (period_error, compute) = h.state().latency.window_bins(0);
    assert_eq!((period_error.total(), compute.total()), (1000, 1000));
    // Each loop's histogram has a bar per non-empty bin of each quantity.
    assert_eq!(super::latency::histogram_bars(&compute).len(), 1);
    // The plots replaced the strip charts and the frame still draws.
    h.run();
    assert!(h.query_by_label("no figures yet").is_none());
}

#[test]
fn the_compact_rbf_switch_sends_its_count_and_the_view_shows_centres_and_time() {
    let (mut h, mut end) = harness();
    h.run();
    drain(&end);
    // The section sits below the tool area: bring it into view first.
    h.get_by_label("Compact RBF clay (600 particles)")
        .scroll_to_me();
    h.run();
    h.get_by_label("Compact RBF clay (600 particles)").click();
    h.run();
    assert_eq!(
        drain(&end),
        vec![EngineCommand::SetCompactRbf {
            particles: Some(600)
        }]
    );
    end.view.publish_clone_of(&EngineView {
        compact: compact_status(),
        ..EngineView::default()
    });
    h.run();
    h.get_by_label("1800 centres; last re-interpolation 0.42 s; 3 applied, 0 failed");
    h.get_by_label("Compact RBF clay (600 particles)").click();
    h.run();
    assert_eq!(
        drain(&end),
        vec![EngineCommand::SetCompactRbf { particles: None }]
    );
}

fn compact_status() -> crate::engine::CompactStatus {
    crate::engine::CompactStatus {
        on: true,
        particles: 600,
        centres: Some(1800),
        busy: false,
        applied: 3,
        superseded: 0,
        failed: 0,
        last_s: 0.42,
        last_residual_fu: 1e-6,
    }
}

#[test]
fn undo_and_redo_counts_are_shown() {
    let (mut h, mut end) = harness();
    h.run();
    h.get_by_label("0 undo · 0 redo");
    end.view.publish_clone_of(&EngineView {
        undo_steps: 3,
        redo_steps: 1,
        ..EngineView::default()
    });
    h.run();
    h.get_by_label("3 undo · 1 redo");
}

#[test]
fn the_force_limit_slider_follows_the_engine_then_sets_its_limit() {
    let (mut h, mut end) = harness();
    h.run();
    let mut view = EngineView::default();
    view.device.state = DeviceLinkState::Connected;
    view.device.name = "simulated arm".into();
    view.device.has_force = true;
    view.device.max_force_n = 8.0;
    view.device.device_max_force_n = 8.0;
    end.view.publish_clone_of(&view);
    h.run();
    assert_eq!(
        h.state().device.max_force_n,
        8.0,
        "starts at the engine's limit"
    );
    h.get_by_label("force limit 8.00 N (device max 8.00 N), peak 0.00 N");
    drain(&end);

    h.get_by_role_and_label(Role::Slider, "Max force N")
        .set_value_accesskit(2.5);
    h.run();
    assert_eq!(
        drain(&end),
        vec![EngineCommand::SetMaxForce { max_force_n: 2.5 }]
    );
    // The engine's later figures do not move the slider back.
    view.device.max_force_n = 2.5;
    end.view.publish_clone_of(&view);
    h.run();
    assert_eq!(h.state().device.max_force_n, 2.5);
}

#[test]
fn sliders_take_the_material_of_a_loaded_session_but_keep_user_changes_otherwise() {
    let (mut h, mut end) = harness();
    h.run();
    let mut view = EngineView {
        material: Material::PLASTIC,
        ..EngineView::default()
    };
    end.view.publish_clone_of(&view);
    h.run();
    assert_eq!(h.state().material, Material::PLASTIC);

    h.get_by_role_and_label(Role::Slider, "Stiffness")
        .set_value_accesskit(5000.0);
    h.run();
    // A view published before the engine applied the change must not undo it.
    end.view.publish_clone_of(&view);
    h.run();
    assert!((h.state().material.stiffness - 5000.0).abs() < 1.0);

    view.material = Material::ELASTIC;
    view.sessions_loaded = 1;
    end.view.publish_clone_of(&view);
    end.events
        .send(EngineEvent::Done {
            what: "load".into(),
            detail: "loaded a.dclay".into(),
        })
        .unwrap();
    h.run();
    assert_eq!(h.state().material, Material::ELASTIC);
    h.get_by_label("load: loaded a.dclay");
}

#[test]
fn an_engine_restarted_on_another_clay_is_framed_and_given_the_tool_and_its_material() {
    let (mut h, mut end) = harness();
    h.run();
    let mut view = EngineView {
        material: Material::PLASTIC,
        ..EngineView::default()
    };
    end.view.publish_clone_of(&view);
    h.run();
    drain(&end);
    let before = h.state().camera.target;
    let (min, max) = (glam::Vec3::splat(10.0), glam::Vec3::splat(12.0));
    view.restarts = 1;
    view.clay_box = Some(super::view::WorldBox { min, max });
    view.material = Material::ELASTIC;
    end.view.publish_clone_of(&view);
    end.events
        .send(EngineEvent::Done {
            what: "load".into(),
            detail: "big.dclay has another clay layout: restarted the engine on it".into(),
        })
        .unwrap();
    h.run();
    let target = h.state().camera.target;
    assert!(
        (target - glam::Vec3::splat(11.0)).length() < 1e-4,
        "framed the new clay: {before} -> {target}"
    );
    assert_eq!(
        h.state().material,
        Material::ELASTIC,
        "the new session's material"
    );
    let sent = drain(&end);
    assert!(
        sent.iter()
            .any(|c| matches!(c, EngineCommand::SelectTool(_))),
        "the tool in use reaches the new engine: {sent:?}"
    );
    h.get_by_label("load: big.dclay has another clay layout: restarted the engine on it");
}

#[test]
fn a_refused_load_is_shown_with_its_reason() {
    let (mut h, end) = harness();
    h.run();
    end.events
        .send(EngineEvent::Failed {
            what: "load".into(),
            error: "bad.dclay: section \"density\" checksum mismatch".into(),
        })
        .unwrap();
    h.run();
    h.get_by_label("load failed: bad.dclay: section \"density\" checksum mismatch");
}

#[test]
fn the_haptic_gain_is_one_value_set_from_the_material_or_the_device_panel() {
    let (mut h, end) = harness();
    h.run();
    drain(&end);
    let sliders = h
        .get_all_by_role_and_label(Role::Slider, "Haptic gain")
        .count();
    assert_eq!(sliders, 2, "in the material and the device panel");
    h.get_all_by_role_and_label(Role::Slider, "Haptic gain")
        .next()
        .unwrap()
        .set_value_accesskit(2.5);
    h.run();
    assert_eq!(
        drain(&end),
        vec![EngineCommand::SetHapticGain { gain: 2.5 }]
    );
    assert_eq!(h.state().device.haptic_gain, 2.5);
    h.get_all_by_role_and_label(Role::Slider, "Haptic gain")
        .last()
        .unwrap()
        .set_value_accesskit(0.5);
    h.run();
    assert_eq!(
        drain(&end),
        vec![EngineCommand::SetHapticGain { gain: 0.5 }]
    );
    assert_eq!(h.state().device.haptic_gain, 0.5);
}

/// A left drag over the clay in the viewport, with the app's pointer tool feeding a pointer
/// device in a lockstep engine: the clay gives way under the dragged path and nowhere far
/// from it. Alt + left drag over the same clay orbits instead and changes nothing.
#[test]
fn a_left_drag_over_the_clay_sculpts_under_the_pointer_and_nowhere_else() {
    use dynaclay_devices::pointer::{PointerConfig, pointer_device};
    use glam::Vec3;

    use super::pointer_tool::PointerTool;
    use crate::engine::{EngineConfig, HeadlessSink, Lockstep, build_clay};
    use crate::io::ClaySpec;
    use crate::render::{Camera, NamedView};

    let field = build_clay(&ClaySpec::default()).unwrap();
    let start = field.clone();
    // The device's clock steps 1 ms a haptic tick: the run does not depend on wall time.
    let pointer = PointerConfig::stepped(1_000);
    let mut config = EngineConfig::for_field(&field, &pointer.info());
    config.haptic_rt_priority = None;
    config.safety.soft_start_s = 0.05;
    let (device, handle) = pointer_device(pointer);
    let mut engine = Lockstep::new(
        &config,
        field,
        Box::new(device),
        Box::new(HeadlessSink::default()),
        64,
    )
    .unwrap();

    let (link, mut end) = engine_link();
    let mut app = SculptApp::new(link);
    app.pointer = PointerTool::new(handle, config.map);
    let mut h = Harness::builder()
        .with_size(egui::vec2(1400.0, 1000.0))
        .build_ui_state(|ui, app: &mut SculptApp| app.show(ui, None), app);
    end.field.publish_clone_of(engine.density());
    h.run();
    // Looking down on the block's top face (y = 1.725; the block spans 0.575..1.725).
    let (lo, hi) = (Vec3::splat(0.575), Vec3::splat(1.725));
    h.state_mut().camera = Camera::named(NamedView::Top, lo, hi);
    h.run();
    let rect = h.state().viewport_rect.expect("the view was laid out");
    let camera = h.state().camera;
    let to_screen = |x: Vec3| {
        let c = camera
            .view_projection(rect.width() / rect.height())
            .project_point3(x);
        egui::pos2(
            rect.min.x + (c.x + 1.0) * 0.5 * rect.width(),
            rect.min.y + (1.0 - c.y) * 0.5 * rect.height(),
        )
    };
    let (from, to) = (Vec3::new(0.95, 1.725, 1.15), Vec3::new(1.35, 1.725, 1.15));
    // One frame, then 20 haptic/simulation ticks with the newest field published.
    let mut frame = |h: &mut Harness<'static, SculptApp>, engine: &mut Lockstep| {
        h.step();
        for _ in 0..20 {
            engine.step();
        }
        end.field.publish_clone_of(engine.density());
    };

    // Alt + left drag orbits: the camera turns, the clay is untouched (a drag across the
    // view's vertical tips the eye off the pole).
    let (orbit_from, orbit_to) = (Vec3::new(1.15, 1.725, 1.35), Vec3::new(1.15, 1.725, 0.95));
    h.hover_at(to_screen(orbit_from));
    frame(&mut h, &mut engine);
    h.event(egui::Event::PointerButton {
        pos: to_screen(orbit_from),
        button: egui::PointerButton::Primary,
        pressed: true,
        modifiers: egui::Modifiers::ALT,
    });
    for i in 1..=5 {
        h.hover_at(to_screen(orbit_from.lerp(orbit_to, i as f32 / 5.0)));
        frame(&mut h, &mut engine);
    }
    h.event(egui::Event::PointerButton {
        pos: to_screen(orbit_to),
        button: egui::PointerButton::Primary,
        pressed: false,
        modifiers: egui::Modifiers::ALT,
    });
    frame(&mut h, &mut engine);
    assert_ne!(h.state().camera, camera, "Alt + left drag orbits");
    assert_eq!(
        engine.field().coeffs,
        start.coeffs,
        "orbiting changed the clay"
    );
    h.state_mut().camera = camera;
    frame(&mut h, &mut engine);

    // A plain left drag from `from` to `to` sculpts.
    h.hover_at(to_screen(from));
    frame(&mut h, &mut engine);
    h.drag_at(to_screen(from));
    for i in 0..=40 {
        h.hover_at(to_screen(from.lerp(to, i as f32 / 40.0)));
        frame(&mut h, &mut engine);
        if i == 20 {
            assert!(
                h.state().pointer.last_sample().unwrap().pressed,
                "the drag presses the device's button"
            );
        }
    }
    h.drop_at(to_screen(to));
    for _ in 0..20 {
        frame(&mut h, &mut engine);
    }
    assert!(!h.state().pointer.last_sample().unwrap().pressed);
    assert_eq!(h.state().camera, camera, "sculpting does not orbit");

    let end_field = engine.field();
    let iso = start.iso;
    for x in [1.05, 1.15, 1.25] {
        let under = Vec3::new(x, 1.67, 1.15);
        assert!(
            start.value(under) > iso && end_field.value(under) < iso,
            "under the path at x = {x}: {} → {}",
            start.value(under),
            end_field.value(under)
        );
    }
    // Far from the path the density springs carry at most a trace of the push (a hundredth,
    // against the half that the clay under the path lost).
    for far in [
        Vec3::new(0.7, 1.67, 0.7),
        Vec3::new(1.6, 1.67, 1.6),
        Vec3::new(1.15, 0.7, 1.15),
    ] {
        assert!(
            (end_field.value(far) - start.value(far)).abs() < 1e-2,
            "far from the path at {far}: {} → {}",
            start.value(far),
            end_field.value(far)
        );
    }
}

/// The brush bindings: `]` and `[` scale every tool's radius, Shift + wheel the strength,
/// Ctrl + wheel the press depth; a plain wheel still zooms and leaves the brush alone.
#[test]
fn brush_keys_and_wheels_change_size_strength_and_depth() {
    use dynaclay_devices::pointer::{PointerConfig, pointer_device};

    use super::pointer_tool::PointerTool;
    use crate::engine::WorkspaceMap;

    let (mut h, end) = harness();
    let config = PointerConfig::default();
    let (_device, handle) = pointer_device(config);
    let map = WorkspaceMap::fitting(
        config.workspace_min_m,
        config.workspace_max_m,
        glam::Vec3::ZERO,
        glam::Vec3::splat(2.3),
        30.0,
    );
    h.state_mut().pointer = PointerTool::new(handle, map);
    h.run();
    drain(&end);
    let radius = h.state().palette.force.radius_fu;
    h.key_press(egui::Key::CloseBracket);
    h.run();
    assert!(h.state().palette.force.radius_fu > radius * 1.1);
    let sent = drain(&end);
    assert!(
        matches!(sent.as_slice(), [EngineCommand::SelectTool(t)] if t.spread_radius_fu().is_some_and(|r| r > radius * 1.1)),
        "{sent:?}"
    );
    h.key_press(egui::Key::OpenBracket);
    h.run();
    assert!((h.state().palette.force.radius_fu - radius).abs() < 1e-5);

    let rect = h.state().viewport_rect.unwrap();
    let wheel = |modifiers| egui::Event::MouseWheel {
        unit: egui::MouseWheelUnit::Point,
        delta: egui::vec2(0.0, 100.0),
        phase: egui::TouchPhase::Move,
        modifiers,
        source: egui::MouseWheelSource::Wheel,
    };
    h.hover_at(rect.center());
    h.run();
    let (gain, depth, distance) = (
        h.state().palette.force.gain,
        h.state().pointer.depth_spans,
        h.state().camera.distance,
    );
    h.event(egui::Event::ModifiersChanged(egui::Modifiers::SHIFT));
    h.event(wheel(egui::Modifiers::SHIFT));
    h.run();
    h.event(egui::Event::ModifiersChanged(egui::Modifiers::NONE));
    h.run();
    assert!(
        h.state().palette.force.gain > gain * 1.2,
        "Shift + wheel: strength"
    );
    assert_eq!(h.state().pointer.depth_spans, depth);
    h.event(egui::Event::ModifiersChanged(egui::Modifiers::CTRL));
    h.event(wheel(egui::Modifiers::CTRL));
    h.run();
    h.event(egui::Event::ModifiersChanged(egui::Modifiers::NONE));
    h.run();
    assert!(h.state().pointer.depth_spans > depth, "Ctrl + wheel: depth");
    assert_eq!(
        h.state().camera.distance,
        distance,
        "brush wheels do not zoom"
    );
    h.event(wheel(egui::Modifiers::NONE));
    h.run();
    assert!(h.state().camera.distance < distance, "a plain wheel zooms");
}

/// Pin mode: a click on the clay pins a point where the pointer meets the clay, a drag pins
/// the curve it traced, and the list's buttons remove one pin or all; nothing sculpts or
/// orbits meanwhile.
#[test]
fn with_pin_mode_a_click_pins_a_point_a_drag_a_curve_and_the_list_deletes() {
    use glam::Vec3;

    use crate::engine::build_clay;
    use crate::io::ClaySpec;
    use crate::render::{Camera, NamedView};
    use crate::tools::PinRequest;

    let (mut h, mut end) = harness();
    let field = crate::field::MultiPatchField::new(build_clay(&ClaySpec::default()).unwrap());
    end.field.publish_clone_of(&field);
    h.run();
    let (lo, hi) = (Vec3::splat(0.575), Vec3::splat(1.725));
    h.state_mut().camera = Camera::named(NamedView::Top, lo, hi);
    h.get_by_label("Pin with the mouse").click();
    h.run();
    drain(&end);
    assert!(h.state().pins.active);
    let rect = h.state().viewport_rect.expect("the view was laid out");
    let camera = h.state().camera;
    let to_screen = |x: Vec3| {
        let c = camera
            .view_projection(rect.width() / rect.height())
            .project_point3(x);
        egui::pos2(
            rect.min.x + (c.x + 1.0) * 0.5 * rect.width(),
            rect.min.y + (1.0 - c.y) * 0.5 * rect.height(),
        )
    };

    // A click on the top face pins a point on it.
    let target = Vec3::new(1.0, 1.725, 1.2);
    h.hover_at(to_screen(target));
    h.run();
    h.drag_at(to_screen(target));
    h.run();
    h.drop_at(to_screen(target));
    h.run();
    let sent = drain(&end);
    let [EngineCommand::Pin(PinRequest::Point(at))] = sent.as_slice() else {
        panic!("a click pins a point: {sent:?}");
    };
    assert!((*at - target).length() < 0.02, "pinned at {at}");
    assert!((field.value(*at) - field.iso()).abs() < 1e-3, "on the clay");

    // A drag across the top face pins the traced curve; the camera stays put.
    let (from, to) = (Vec3::new(0.8, 1.725, 1.0), Vec3::new(1.4, 1.725, 1.0));
    h.hover_at(to_screen(from));
    h.run();
    h.drag_at(to_screen(from));
    for i in 0..=20 {
        h.hover_at(to_screen(from.lerp(to, i as f32 / 20.0)));
        h.run();
    }
    h.drop_at(to_screen(to));
    h.run();
    let sent = drain(&end);
    let [EngineCommand::Pin(PinRequest::Curve(points))] = sent.as_slice() else {
        panic!("a drag pins a curve: {sent:?}");
    };
    assert!(points.len() >= 10, "{} points", points.len());
    assert!((points[0] - from).length() < 0.02 && (points[points.len() - 1] - to).length() < 0.02);
    assert_eq!(h.state().camera, camera, "pinning does not orbit");

    // The engine's list, with a delete button per pin and one for all.
    let view = EngineView {
        pins: vec![
            "0: point at [1.000, 1.725, 1.200]".into(),
            "1: curve of 13 points from [0.800, 1.725, 1.000] to [1.400, 1.725, 1.000]".into(),
        ],
        pin_marks: vec![vec![target], vec![from, to]],
        ..EngineView::default()
    };
    end.view.publish_clone_of(&view);
    h.run();
    h.get_by_label("1: curve of 13 points from [0.800, 1.725, 1.000] to [1.400, 1.725, 1.000]");
    // The marks land where the pins were made on the screen.
    let marks = h.state().pin_marks_on_screen(rect);
    assert_eq!(marks.len(), 2);
    assert!(
        (marks[0][0] - to_screen(target)).length() < 1.0,
        "{marks:?}"
    );
    assert!((marks[1][1] - to_screen(to)).length() < 1.0, "{marks:?}");
    let deletes: Vec<_> = h.get_all_by_label("Delete").collect();
    assert_eq!(deletes.len(), 2);
    deletes[1].click();
    h.run();
    assert_eq!(drain(&end), vec![EngineCommand::Unpin { index: Some(1) }]);
    h.get_by_label("Remove all pins").click();
    h.run();
    assert_eq!(drain(&end), vec![EngineCommand::Unpin { index: None }]);
}

/// eframe's render state, built on a headless device the way eframe builds it on a window's,
/// or `None` (with a note) when the machine has no adapter.
fn render_state() -> Option<(crate::render::GpuContext, egui_wgpu::RenderState)> {
    use crate::render::{GpuContext, REQUIRE_GPU_ENV, gpu_required};
    let gpu = match GpuContext::headless() {
        Ok(g) => g,
        Err(e) if e.is_no_adapter() && !gpu_required() => {
            println!("skipped: {e}");
            return None;
        }
        Err(e) => panic!("{e} ({REQUIRE_GPU_ENV} is set, so a missing adapter fails)"),
    };
    let format = wgpu::TextureFormat::Rgba8UnormSrgb;
    let renderer =
        egui_wgpu::Renderer::new(&gpu.device, format, egui_wgpu::RendererOptions::default());
    let rs = egui_wgpu::RenderState {
        adapter: gpu.adapter.clone(),
        available_adapters: Vec::new(),
        instance: gpu.instance().clone(),
        device: gpu.device.clone(),
        queue: gpu.queue.clone(),
        target_format: format,
        renderer: std::sync::Arc::new(egui::mutex::RwLock::new(renderer)),
    };
    Some((gpu, rs))
}

#[test]
fn the_view_survives_a_size_and_a_mesh_the_gpu_refuses() {
    use crate::render::{Camera, MeshChunk, SceneOptions};
    let Some((gpu, rs)) = render_state() else {
        return;
    };
    let log = crate::render::GpuFaultLog::install(&rs.device, true);
    let mut view = super::SceneView::new(&rs, crate::render::ProfileRequest::Auto, 64, 48)
        .expect("a small view");
    let camera = Camera::default();
    let options = SceneOptions::default();
    let p = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    let n = [[0.0, 0.0, 1.0]; 3];
    let chunk = |indices: &'static [u32], version| MeshChunk {
        id: 1,
        version,
        positions: &p,
        normals: &n,
        colors: &[],
        indices,
        cut: false,
    };
    static GOOD: [u32; 3] = [0, 1, 2];
    // An index past the vertices: the upload refuses it.
    static BAD: [u32; 3] = [0, 1, 7];
    assert!(
        view.draw(&rs, (64, 48), &[chunk(&GOOD, 1)], 1, &camera, &options)
            .is_some()
    );
    assert_eq!(view.problem(), None);

    // A window wider than the device's texture limit: refused, the last size's image stays.
    let over = rs.device.limits().max_texture_dimension_2d + 1;
    let shown = view.draw(&rs, (over, 48), &[chunk(&GOOD, 1)], 1, &camera, &options);
    assert!(shown.is_some(), "the last image is still shown");
    assert_eq!(view.size(), (64, 48));
    let problem = view.problem().expect("the refusal is said");
    assert!(problem.contains(&format!("{over}×48")), "{problem}");
    // Back to a size the GPU takes: the problem goes.
    assert!(
        view.draw(&rs, (80, 60), &[chunk(&GOOD, 1)], 1, &camera, &options)
            .is_some()
    );
    assert_eq!(view.size(), (80, 60));
    assert_eq!(view.problem(), None);

    // A mesh that cannot be uploaded: said, the frame still drawn, a new mesh recovers.
    let shown = view.draw(&rs, (80, 60), &[chunk(&BAD, 2)], 2, &camera, &options);
    assert!(shown.is_some());
    let problem = view.problem().expect("the refused mesh is said");
    assert!(problem.contains("cannot show the clay"), "{problem}");
    assert!(
        view.draw(&rs, (80, 60), &[chunk(&GOOD, 3)], 3, &camera, &options)
            .is_some()
    );
    assert_eq!(view.problem(), None);
    assert_eq!(log.error_count(), 0, "every failure was caught in a scope");
    gpu.check_faults("the test").unwrap();
}

#[test]
fn the_app_draws_its_view_on_a_gpu_with_the_fault_log_installed() {
    let Some((_gpu, rs)) = render_state() else {
        return;
    };
    let (link, _end) = engine_link();
    let mut app = SculptApp::new(link);
    app.gpu_faults = Some(crate::render::GpuFaultLog::install(&rs.device, true));
    let mut h = Harness::builder()
        .with_size(egui::vec2(1400.0, 1000.0))
        .build_ui_state(move |ui, app: &mut SculptApp| app.show(ui, Some(&rs)), app);
    h.run();
    assert_eq!(h.state().view_problem(), None);
    let faults = h.state().gpu_faults.clone().expect("installed");
    assert_eq!(faults.error_count(), 0);
}

#[test]
fn the_particles_switch_and_n_reach_the_followers_handles() {
    use std::sync::atomic::Ordering;

    let (mut h, mut end) = harness();
    h.run();
    drain(&end);
    let (count, on) = (
        std::sync::Arc::clone(&end.particles.count),
        std::sync::Arc::clone(&end.particles.on),
    );
    assert!(!on.load(Ordering::Relaxed), "off by default");

    // The section sits below the tool area: bring it into view first.
    h.get_by_role_and_label(Role::CheckBox, "Particles")
        .scroll_to_me();
    h.run();
    h.get_by_role_and_label(Role::CheckBox, "Particles").click();
    h.run();
    assert!(on.load(Ordering::Relaxed));

    h.get_by_role_and_label(Role::Slider, "Particles N")
        .set_value_accesskit(5000.0);
    h.run();
    assert_eq!(count.load(Ordering::Relaxed), 5000);
    // Neither reaches the engine as a command.
    assert!(drain(&end).is_empty());

    // The view's particles are reported under the panel.
    let view = crate::particles::ParticleView {
        positions: vec![glam::Vec3::ZERO; 3],
        ..crate::particles::ParticleView::default()
    };
    end.particles.view.publish_clone_of(&view);
    h.run();
    h.get_by_label("3 particles on the clay");

    h.get_by_role_and_label(Role::CheckBox, "Particles").click();
    h.run();
    assert!(!on.load(Ordering::Relaxed));
    assert_eq!(count.load(Ordering::Relaxed), 5000, "N is kept while off");
}

/// A point cloud loaded in the running app: the bridge fits the clay and builds the point
/// set, the graphics loop's follower publishes its points, and the panel's Splats / Mesh
/// switch decides what the renderer gets (splats and no mesh, or the mesh and no splats).
#[test]
fn a_loaded_point_cloud_shows_as_splats_or_as_the_mesh() {
    use std::time::{Duration, Instant};

    use dynaclay_devices::{DeviceError, HapticDevice, SimArmConfig, SimulatedArm, Trajectory};

    use super::bridge::{RestartSettings, start_bridge};
    use super::state::PointsDisplay;
    use crate::engine::{Engine, EngineConfig, build_clay};
    use crate::io::{ClayShape, ClaySpec};

    let field = build_clay(&ClaySpec {
        shape: ClayShape::Sphere,
        resolution: 12,
        ..ClaySpec::default()
    })
    .unwrap();
    let arm = SimArmConfig::default();
    let info = arm.info.clone();
    let mut config = EngineConfig::for_field(&field, &info);
    config.haptic_rt_priority = None;
    let device: Box<dyn HapticDevice> = Box::new(SimulatedArm::new(
        arm,
        Trajectory::hold(glam::Vec3::splat(-0.09)),
    ));
    let dir = tempfile::tempdir().unwrap();
    let restart = RestartSettings {
        config,
        autosave: None,
        keep_replaced_at: dir.path().join("replaced.dclay"),
    };

    // 600 points on a sphere with normals, half of them red, as binary PLY.
    let n = 600;
    let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
    let points: Vec<glam::Vec3> = (0..n)
        .map(|i| {
            let y = 1.0 - 2.0 * (i as f32 + 0.5) / n as f32;
            let r = (1.0 - y * y).sqrt();
            let t = golden * i as f32;
            glam::Vec3::new(r * t.cos(), y, r * t.sin()) * 2.0
        })
        .collect();
    let normals: Vec<glam::Vec3> = points.iter().map(|p| p.normalize()).collect();
    let colours: Vec<[u8; 3]> = (0..n)
        .map(|i| {
            if i % 2 == 0 {
                [220, 30, 30]
            } else {
                [200, 200, 200]
            }
        })
        .collect();
    let ply = dir.path().join("ball.ply");
    crate::pointset::write_point_ply(&ply, &points, &normals, &colours).unwrap();

    let (link, endpoint) = engine_link();
    let opener: super::bridge::DeviceOpener = Box::new(|spec: &DeviceSpec| {
        Err(DeviceError::NotFound {
            what: format!("{spec} in this test"),
        }
        .into())
    });
    let in_use = super::bridge::DeviceInUse {
        spec: DeviceSpec::Sim,
        info,
    };
    let bridge = start_bridge(endpoint, in_use, opener, Some(restart), |sink| {
        Engine::start(&config, field.clone(), device, sink)
    })
    .unwrap();
    let app = SculptApp::new(link);
    let mut h = Harness::builder()
        .with_size(egui::vec2(1400.0, 1000.0))
        .build_ui_state(|ui, app: &mut SculptApp| app.show(ui, None), app);
    h.run();
    assert!(
        h.query_by_role_and_label(Role::RadioButton, "Splats")
            .is_none(),
        "no point-set switch before a point set is loaded"
    );
    h.state_mut()
        .file_request(super::file_menu::FileRequest::Import(ply.clone()));
    h.run();

    // A generous bound only against a hang; nothing is timed.
    let start = Instant::now();
    let loaded = |h: &mut Harness<'static, SculptApp>| {
        let p = &h.state_mut().link.points().value;
        p.loaded && !p.positions.is_empty()
    };
    while !loaded(&mut h) {
        assert!(
            start.elapsed() < Duration::from_secs(120),
            "no point set; log {:?}",
            h.state().log
        );
        std::thread::sleep(Duration::from_millis(20));
        h.run();
    }
    let view = h.state_mut().link.points().value.clone();
    assert_eq!(view.positions.len(), view.radii.len());
    assert!(view.colours.contains(&[220, 30, 30]), "the file's colours");
    assert!(view.spacing_fu > 0.0);
    assert!(
        h.state()
            .log
            .iter()
            .any(|l| l.contains("point set: 600 points")),
        "{:?}",
        h.state().log
    );

    // Splats by default: the renderer gets splats and no mesh.
    h.run();
    assert_eq!(h.state().display.points_as, PointsDisplay::Splats);
    let input = h.state().scene_input;
    assert!(input.splats > 0 && input.chunks == 0, "{input:?}");

    // Mesh: the clay's chunks, no splats (once the new engine's meshes arrive).
    h.get_by_role_and_label(Role::RadioButton, "Mesh")
        .scroll_to_me();
    h.run();
    h.get_by_role_and_label(Role::RadioButton, "Mesh").click();
    h.run();
    assert_eq!(h.state().display.points_as, PointsDisplay::Mesh);
    let start = Instant::now();
    while h.state().scene_input.chunks == 0 {
        assert!(start.elapsed() < Duration::from_secs(120), "no mesh");
        std::thread::sleep(Duration::from_millis(20));
        h.run();
    }
    assert_eq!(h.state().scene_input.splats, 0);

    h.get_by_role_and_label(Role::RadioButton, "Splats").click();
    h.run();
    let input = h.state().scene_input;
    assert!(input.splats > 0 && input.chunks == 0, "{input:?}");
    drop(h);
    bridge.stop().unwrap();
}

#[test]
fn a_step_that_would_remove_most_of_the_clay_is_asked_about_first() {
    use crate::engine::RemovalQuestion;
    let (mut h, mut end) = harness();
    h.run();
    drain(&end);
    // The engine holds a CSG intersection for what it would remove, and asks.
    let asked = RemovalQuestion {
        what: "intersection",
        percent: 87.0,
        stroke: false,
    };
    end.view.publish_clone_of(&EngineView {
        removal_question: Some(asked),
        ..EngineView::default()
    });
    h.run();
    h.get_by_label("This intersection step would remove about 87% of the clay's volume.");
    h.get_by_label("Remove it").click();
    h.run();
    assert_eq!(
        drain(&end),
        vec![EngineCommand::AnswerRemoval { yes: true }]
    );
    // Answered: not asked again while the engine still shows the question.
    h.run();
    assert!(h.query_by_label("Remove it").is_none());
    // A held stroke's question: keeping the clay says no.
    end.view.publish_clone_of(&EngineView {
        removal_question: Some(RemovalQuestion {
            what: "remove",
            percent: 55.0,
            stroke: true,
        }),
        ..EngineView::default()
    });
    h.run();
    h.get_by_label("This remove stroke would remove about 55% of the clay's volume.");
    h.get_by_label("Keep the clay").click();
    h.run();
    assert_eq!(
        drain(&end),
        vec![EngineCommand::AnswerRemoval { yes: false }]
    );
}

/// One frame of the whole app on `rs`, at 1000×700 points.
fn gpu_frame(app: &mut SculptApp, ctx: &egui::Context, rs: &egui_wgpu::RenderState) {
    let input = egui::RawInput {
        screen_rect: Some(egui::Rect::from_min_size(
            egui::Pos2::ZERO,
            egui::vec2(1000.0, 700.0),
        )),
        ..Default::default()
    };
    let _ = ctx.run_ui(input, |ui| app.show(ui, Some(rs)));
}

#[test]
fn the_render_profile_is_chosen_once_logged_and_shown_in_the_status_line() {
    use crate::render::{ProfileChoice, ProfileRequest, RenderProfile};
    let Some((gpu, rs)) = render_state() else {
        return;
    };
    let ctx = egui::Context::default();
    for (request, words) in [
        (
            ProfileRequest::Force(RenderProfile::Software),
            "software render: no MSAA, vertex-lit",
        ),
        (
            ProfileRequest::Force(RenderProfile::Full),
            "per-pixel shading",
        ),
    ] {
        let (link, _end) = engine_link();
        let mut app = SculptApp::new(link);
        app.render_request = request;
        assert!(
            !app.status_line().contains(words),
            "no view yet: {}",
            app.status_line()
        );
        gpu_frame(&mut app, &ctx, &rs);
        gpu_frame(&mut app, &ctx, &rs);
        let status = app.status_line();
        assert!(status.contains(words), "{status}");
        let said: Vec<&String> = app
            .log
            .iter()
            .filter(|l| l.starts_with("render profile"))
            .collect();
        assert_eq!(said.len(), 1, "said once: {:?}", app.log);
        let expected =
            ProfileChoice::for_adapter(&gpu.adapter, crate::render::OFFSCREEN_FORMAT, request);
        assert_eq!(*said[0], expected.to_string());
        assert!(
            said[0].contains("forced by DYNACLAY_RENDER_PROFILE"),
            "{}",
            said[0]
        );
    }
    // Left to the adapter: the profile its device type calls for.
    let (link, _end) = engine_link();
    let mut app = SculptApp::new(link);
    app.render_request = ProfileRequest::Auto;
    gpu_frame(&mut app, &ctx, &rs);
    let detected = RenderProfile::detect(gpu.adapter.get_info().device_type);
    let software = app.status_line().contains("software render");
    assert_eq!(
        software,
        detected == RenderProfile::Software,
        "{}",
        app.status_line()
    );
}

#[test]
fn the_detail_switches_reach_the_engine_and_force_tools_need_automatic_detail() {
    let (mut h, end) = harness();
    h.run();
    h.get_by_label("Detail").click();
    h.run();
    drain(&end);

    // Each click and what it sent to the engine.
    let mut click = |label: &str| {
        h.get_by_label(label).click();
        h.run();
        drain(&end)
    };
    let sent = |automatic, force_tools| {
        vec![EngineCommand::SetAutoDetail {
            automatic,
            force_tools,
        }]
    };
    // On by default, as the engine's: the first click turns it off.
    assert_eq!(click("Under force tools too"), sent(true, false));
    assert_eq!(click("Under force tools too"), sent(true, true));
    assert_eq!(click("Automatic detail"), sent(false, true));
    // With automatic detail off the force tools' switch is greyed out: a click sends nothing.
    assert!(click("Under force tools too").is_empty());
}
