//! The window's files, driven headless as a user would (egui_kittest) through the typed-path
//! fallback that stands in for the desktop's dialog: New and Save As reach a running engine
//! and write the session (read back from disk), the session's name and the engine's autosave
//! follow Save As, a replacement asks before it drops an undo history, and an import runs
//! beside the window's frames and hands its clay over when done.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use dynaclay_devices::spec::DeviceSpec;
use dynaclay_devices::{DeviceError, HapticDevice, SimArmConfig, SimulatedArm, Trajectory};
use egui::accesskit::Role;
use egui_kittest::Harness;
use egui_kittest::kittest::{NodeT, Queryable};

use super::bridge::{DeviceInUse, DeviceOpener, EngineBridge, RestartSettings, start_bridge};
use super::command::{ClaySource, EngineCommand};
use super::file_menu::FileRequest;
use super::link::engine_link;
use super::state::SculptApp;
use crate::engine::{Engine, EngineConfig, build_clay};
use crate::io::{ClayShape, ClaySpec, load_session};

/// A generous bound against a hang only; nothing is timed.
const HANG: Duration = Duration::from_secs(120);

fn harness_for(app: SculptApp) -> Harness<'static, SculptApp> {
    Harness::builder()
        .with_size(egui::vec2(1400.0, 1000.0))
        .build_ui_state(|ui, app: &mut SculptApp| app.show(ui, None), app)
}

/// An app on a running engine (a simulated arm, a ball at resolution 12) that restarts on a
/// clay of another layout; `first` is the session the window starts with.
fn app_on_engine(first: &Path) -> (SculptApp, EngineBridge) {
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
    let restart = RestartSettings {
        config,
        autosave: Some(first.to_path_buf()),
        keep_replaced_at: first.with_extension("replaced.dclay"),
    };
    let opener: DeviceOpener = Box::new(|spec: &DeviceSpec| {
        Err(DeviceError::NotFound {
            what: format!("{spec} in this test"),
        }
        .into())
    });
    let in_use = DeviceInUse {
        spec: DeviceSpec::Sim,
        info,
    };
    let (link, endpoint) = engine_link();
    let bridge = start_bridge(endpoint, in_use, opener, Some(restart), |sink| {
        Engine::start(&config, field.clone(), device, sink)
    })
    .unwrap();
    let mut app = SculptApp::new(link);
    app.files.session = Some(first.to_path_buf());
    (app, bridge)
}

/// Runs frames until `done` holds, sleeping between them (the engine works on its threads).
fn run_until(
    h: &mut Harness<'static, SculptApp>,
    what: &str,
    done: impl Fn(&mut SculptApp) -> bool,
) {
    let start = Instant::now();
    loop {
        h.run();
        if done(h.state_mut()) {
            return;
        }
        assert!(start.elapsed() < HANG, "no {what}; log {:?}", h.state().log);
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// Types `path` into the typed-path box and presses OK.
fn type_path(h: &mut Harness<'static, SculptApp>, path: &Path) {
    type_text(h, &path.display().to_string());
}

/// Types `text` into the typed-path box (which takes the focus as it shows) and presses OK.
fn type_text(h: &mut Harness<'static, SculptApp>, text: &str) {
    h.run();
    let field = h.get_by_role_and_label(Role::TextInput, "Path");
    assert!(field.is_focused(), "the box takes the keyboard as it shows");
    // Replace what the box starts with (Save As offers the session's own name).
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::A);
    h.run();
    h.key_press(egui::Key::Backspace);
    h.run();
    h.get_by_role_and_label(Role::TextInput, "Path")
        .type_text(text);
    h.run();
    h.get_by_label("OK").click();
    h.run();
}

#[test]
fn save_as_and_new_through_the_typed_path_write_the_session_and_autosave_follows() {
    let dir = tempfile::tempdir().unwrap();
    let first = dir.path().join("first.dclay");
    let second = dir.path().join("second");
    let second_file: PathBuf = dir.path().join("second.dclay");
    let (app, bridge) = app_on_engine(&first);
    let mut h = harness_for(app);
    h.run();

    // Save As, typed without an extension: a session named second.dclay.
    h.get_by_label("Save As…").click();
    h.run();
    assert!(
        h.query_by_label("OK").is_some(),
        "the typed-path box stands in for the dialog"
    );
    type_path(&mut h, &second);
    run_until(&mut h, "session written", |app| {
        app.files.session.as_deref() == Some(second_file.as_path())
    });
    let saved = load_session(&second_file).unwrap();
    assert_eq!(saved.clay.density.patches[0].lattice.dims, [12; 3]);
    assert_eq!(
        h.state().file_menu.recent.paths(),
        std::slice::from_ref(&second_file)
    );

    // New: a plastic block at resolution 10 (another layout: a new engine on it).
    h.get_by_label("New…").click();
    h.run();
    let spec = h.state_mut().file_menu.new_dialog_mut().unwrap();
    spec.shape = ClayShape::Block;
    spec.resolution = 10;
    spec.material = super::new_clay::MaterialPreset::Plastic;
    h.get_by_label("Create").click();
    run_until(&mut h, "restart on the new clay", |app| {
        app.view.restarts == 1
    });
    // The replaced clay (and from now on autosave) follows the session saved last, not the
    // one the window started with.
    assert!(
        dir.path().join("second.replaced.dclay").is_file(),
        "{:?}",
        h.state().log
    );
    assert!(!dir.path().join("first.replaced.dclay").exists());
    run_until(&mut h, "the new clay loaded", |app| {
        app.log.iter().any(|l| l.contains("loaded new clay"))
    });

    // Save writes the new clay under the current name.
    let before = std::fs::metadata(&second_file).unwrap().modified().unwrap();
    h.get_by_label("Save").click();
    run_until(&mut h, "second save", |_| {
        load_session(&second_file).is_ok_and(|s| s.clay.density.patches[0].lattice.dims == [10; 3])
    });
    let saved = load_session(&second_file).unwrap();
    assert_eq!(saved.material.uniform, crate::dynamics::Material::PLASTIC);
    assert!(std::fs::metadata(&second_file).unwrap().modified().unwrap() >= before);
    drop(h);
    bridge.stop().unwrap();
}

#[test]
fn replacing_a_clay_with_history_asks_first_and_honours_the_answer() {
    let (link, end) = engine_link();
    let mut h = harness_for(SculptApp::new(link));
    h.run();
    let _: Vec<_> = end.commands.try_iter().collect();
    let other = PathBuf::from("other.dclay");

    // No history: nothing to ask, nothing kept.
    h.state_mut().file_request(FileRequest::Open(other.clone()));
    h.run();
    let sent: Vec<_> = end.commands.try_iter().collect();
    assert_eq!(
        sent,
        [EngineCommand::Replace {
            with: ClaySource::File(other.clone()),
            keep_history: false
        }]
    );

    h.state_mut().view.undo_steps = 3;
    for (answer, keep) in [
        ("Keep undo history", Some(true)),
        ("Drop undo history", Some(false)),
        ("Cancel", None),
    ] {
        h.state_mut().file_request(FileRequest::Open(other.clone()));
        h.run();
        assert!(
            end.commands.try_iter().next().is_none(),
            "nothing replaced before the answer"
        );
        assert!(h.state().replace.is_open());
        h.get_by_label(answer).click();
        h.run();
        let sent: Vec<_> = end.commands.try_iter().collect();
        match keep {
            Some(keep_history) => assert_eq!(
                sent,
                [EngineCommand::Replace {
                    with: ClaySource::File(other.clone()),
                    keep_history
                }]
            ),
            None => assert!(sent.is_empty(), "{sent:?}"),
        }
        assert!(!h.state().replace.is_open());
    }

    // Open takes sessions, Import the rest: each refuses the other's files with a reason.
    h.state_mut()
        .file_request(FileRequest::Open(PathBuf::from("scan.ply")));
    h.state_mut()
        .file_request(FileRequest::Import(PathBuf::from("s.dclay")));
    h.run();
    assert!(end.commands.try_iter().next().is_none());
    let log: Vec<&String> = h.state().log.iter().collect();
    assert!(log.iter().any(|l| l.contains("Import fits")), "{log:?}");
    assert!(log.iter().any(|l| l.contains("Open it instead")), "{log:?}");
}

#[test]
fn a_session_without_a_name_is_saved_through_save_as_and_a_loaded_cloud_never_blocks_save() {
    let (link, end) = engine_link();
    let mut app = SculptApp::new(link);
    app.files.session = None;
    let mut h = harness_for(app);
    h.run();
    let _: Vec<_> = end.commands.try_iter().collect();
    h.get_by_label("Save").click();
    h.run();
    type_path(&mut h, Path::new("named.dclay"));
    let sent: Vec<_> = end.commands.try_iter().collect();
    assert_eq!(
        sent,
        [EngineCommand::Save {
            path: "named.dclay".into()
        }]
    );
    // A mesh name is not a session.
    h.get_by_label("Save As…").click();
    h.run();
    // The box starts with the session's name (none here).
    type_text(&mut h, "x.obj");
    assert!(end.commands.try_iter().next().is_none());
    assert!(
        h.state()
            .log
            .back()
            .unwrap()
            .contains("Export writes meshes")
    );

    // An imported cloud is not the session: Save still writes the session by its name.
    h.state_mut().files.session = Some("work.dclay".into());
    h.state_mut()
        .file_request(FileRequest::Import(PathBuf::from("scan.ply")));
    h.get_by_label("Save").click();
    h.run();
    let sent: Vec<_> = end.commands.try_iter().collect();
    assert_eq!(
        sent,
        [
            EngineCommand::Replace {
                with: ClaySource::File("scan.ply".into()),
                keep_history: false
            },
            EngineCommand::Save {
                path: "work.dclay".into()
            }
        ]
    );
}

#[test]
fn an_import_runs_beside_the_frames_and_hands_its_clay_and_points_over() {
    let dir = tempfile::tempdir().unwrap();
    let (app, bridge) = app_on_engine(&dir.path().join("first.dclay"));
    // 3000 points on a ball with normals, as binary PLY.
    let n = 3000;
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
    let colours = vec![[200, 200, 200]; n];
    let ply = dir.path().join("ball.ply");
    crate::pointset::write_point_ply(&ply, &points, &normals, &colours).unwrap();

    let mut h = harness_for(app);
    h.run();
    h.get_by_label("Import…").click();
    h.run();
    type_path(&mut h, &ply);
    // Frames go on while the worker fits (each h.run() returns at once: the app only reads
    // what the worker sent).
    let mut fractions = Vec::new();
    let start = Instant::now();
    loop {
        h.run();
        let app = h.state_mut();
        if let Some(p) = &app.load_progress {
            fractions.push(p.fraction);
        }
        let loaded = app.link.points().value.loaded;
        if loaded && app.load_progress.is_none() {
            break;
        }
        assert!(start.elapsed() < HANG, "no import; log {:?}", app.log);
        std::thread::sleep(Duration::from_millis(5));
    }
    // Whether a frame fell inside the fit depends on scheduling, so only what frames saw is
    // checked here; the bar itself is driven deterministically in the test below.
    assert!(
        fractions.windows(2).all(|w| w[1] >= w[0]),
        "the bar only moves on: {fractions:?}"
    );
    assert!(fractions.iter().all(|f| (0.0..=1.0).contains(f)));
    // The log names the points imported; the panel shows the points following the clay,
    // which the follower resamples to the clay's area at its spacing (a few percent more here).
    let shown = h.state_mut().link.points().value.positions.len();
    assert!(
        shown.abs_diff(n) * 10 < n,
        "{shown} points shown of {n} imported"
    );
    // The panel names both counts when they differ, the log's among them.
    let panel = super::state::points_line(&h.state_mut().link.points().value);
    assert!(
        panel.contains(&format!("{shown} points"))
            && (shown == n || panel.contains(&format!("the {n} loaded"))),
        "panel line {panel:?} for {shown} shown of {n} loaded"
    );
    let line = format!("point set: {n} points");
    assert!(
        h.state().log.iter().any(|l| l.contains(&line)),
        "{line:?} in {:?}",
        h.state().log
    );
    // The cloud joins the recent files; the session's name stays (Save is not the cloud's).
    assert_eq!(
        h.state().file_menu.recent.paths(),
        std::slice::from_ref(&ply)
    );
    assert_eq!(
        h.state().files.session.as_deref(),
        Some(dir.path().join("first.dclay").as_path())
    );

    // No output replaces the imported cloud, nor a file of another kind: Export onto the
    // cloud and Save As onto a foreign file are refused with the reason, and both stay as
    // they were.
    assert_eq!(h.state().files.imported.as_deref(), Some(ply.as_path()));
    let cloud_bytes = std::fs::read(&ply).unwrap();
    h.state_mut().file_request(FileRequest::Export(ply.clone()));
    h.run();
    let logged = |h: &Harness<'static, SculptApp>, text: &str| {
        h.state().log.iter().any(|line| line.contains(text))
    };
    assert!(
        logged(&h, "an output never replaces an input"),
        "export over the cloud: {:?}",
        h.state().log
    );
    let foreign = dir.path().join("notes.dclay");
    std::fs::write(&foreign, b"a user's own notes").unwrap();
    h.state_mut()
        .file_request(FileRequest::SaveAs(foreign.clone()));
    h.run();
    assert!(
        logged(&h, "not a session this program wrote"),
        "save as over a foreign file: {:?}",
        h.state().log
    );
    // A new mesh name is written (the export goes to the engine's meshes).
    let mesh = dir.path().join("ball-mesh.obj");
    h.state_mut()
        .file_request(FileRequest::Export(mesh.clone()));
    run_until(&mut h, "export", |_| mesh.exists());
    assert_eq!(std::fs::read(&ply).unwrap(), cloud_bytes);
    assert_eq!(std::fs::read(&foreign).unwrap(), b"a user's own notes");
    drop(h);
    bridge.stop().unwrap();
}

#[test]
fn the_progress_bar_follows_the_loads_events_and_holds_back_another_replacement() {
    let (link, end) = engine_link();
    let mut h = harness_for(SculptApp::new(link));
    h.run();
    let free = |h: &Harness<'static, SculptApp>, label: &str| {
        !h.get_by_label(label).accesskit_node().is_disabled()
    };
    assert!(free(&h, "Import…") && free(&h, "New…") && free(&h, "Open…"));
    for fraction in [0.0, 0.4, 0.9] {
        end.events
            .send(super::command::EngineEvent::Progress(Some(
                super::command::LoadProgress {
                    source: "/data/scan.ply".into(),
                    fraction,
                    stage: "fitting".into(),
                },
            )))
            .unwrap();
        h.run();
        let shown = h.state().load_progress.as_ref().map(|p| p.fraction);
        assert_eq!(shown, Some(fraction));
        // Saving stays open; another replacement waits for this one.
        assert!(free(&h, "Save"));
        assert!(!free(&h, "Import…") && !free(&h, "New…") && !free(&h, "Open…"));
        assert!(
            h.state().log.iter().all(|l| !l.contains("fitting")),
            "progress is not logged"
        );
    }
    end.events
        .send(super::command::EngineEvent::Progress(None))
        .unwrap();
    h.run();
    assert!(h.state().load_progress.is_none());
    assert!(free(&h, "Import…"));
}
