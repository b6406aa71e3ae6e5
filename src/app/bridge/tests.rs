use std::time::Instant;

use dynaclay_devices::{DeviceError, SimArmConfig, SimulatedArm, Trajectory};

use super::*;

/// The simulated arm as the device in use.
fn sim_in_use(info: DeviceInfo) -> DeviceInUse {
    DeviceInUse {
        spec: DeviceSpec::Sim,
        info,
    }
}
use crate::dynamics::Material;
use crate::engine::{EngineConfig, build_clay};
use crate::field::BSplineLattice;
use crate::io::{ClayShape, ClaySpec, MaterialFields, Session, save_session};
use crate::mesh::{MeshStats, SampleGrid};
use crate::tools::Clay;

/// Polls `link` until `done` holds for its view (or panics after a few seconds), taking
/// in the events on the way.
fn wait_for(
    link: &mut super::super::EngineLink,
    events: &mut Vec<EngineEvent>,
    what: &str,
    done: impl Fn(&EngineView, &[EngineEvent]) -> bool,
) {
    let start = Instant::now();
    loop {
        while let Some(ev) = link.try_event() {
            events.push(ev);
        }
        if done(&link.view().value, events) {
            return;
        }
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "timed out waiting for {what}; events {events:?}"
        );
        std::thread::sleep(Duration::from_millis(5));
    }
}

fn triangles(link: &mut super::super::EngineLink) -> usize {
    link.meshes()
        .value
        .iter()
        .map(|c| c.indices.len() / 3)
        .sum()
}

/// The compact RBF switch through the bridge reaches the running engine: its worker
/// interpolates the clay (one undo step, 3N centres shown in the view); switched off,
/// the view says so.
#[test]
fn the_compact_rbf_switch_reaches_the_engine_and_its_worker() {
    let field = build_clay(&ClaySpec {
        shape: ClayShape::Sphere,
        resolution: 14,
        ..ClaySpec::default()
    })
    .unwrap();
    let (mut link, bridge) = bridge_on(&field);
    let mut events = Vec::new();
    wait_for(&mut link, &mut events, "the first status", |_, _| true);
    link.send(EngineCommand::SetCompactRbf {
        particles: Some(60),
    })
    .unwrap();
    wait_for(&mut link, &mut events, "the first interpolation", |v, _| {
        v.compact.applied >= 1
    });
    let v = link.view().value.clone();
    assert!(v.compact.on);
    assert_eq!(v.compact.particles, 60);
    assert_eq!(v.compact.centres, Some(180));
    assert_eq!(v.compact.failed, 0);
    assert!(v.compact.last_s > 0.0);
    wait_for(&mut link, &mut events, "its undo step", |v, _| {
        v.undo_steps == 1
    });

    link.send(EngineCommand::SetCompactRbf { particles: None })
        .unwrap();
    wait_for(&mut link, &mut events, "the switch off", |v, _| {
        !v.compact.on
    });
    assert!(
        !events
            .iter()
            .any(|e| matches!(e, EngineEvent::Failed { .. })),
        "{events:?}"
    );
    bridge.stop().unwrap();
}

/// Particles through the running engine: off, none are published; switched on over a
/// still clay, the graphics loop's idle updates seed and settle them on the surface; a new
/// `N` is reached; switched off, they are dropped.
#[test]
fn particles_switched_on_settle_on_a_still_clay_and_go_when_switched_off() {
    let field = build_clay(&ClaySpec {
        shape: ClayShape::Sphere,
        resolution: 14,
        ..ClaySpec::default()
    })
    .unwrap();
    let (mut link, bridge) = bridge_on(&field);
    let wait_particles =
        |link: &mut super::super::EngineLink, what: &str, done: &dyn Fn(usize) -> bool| {
            let start = Instant::now();
            loop {
                let n = link.particles().value.positions.len();
                if done(n) {
                    return;
                }
                assert!(
                    start.elapsed() < Duration::from_secs(60),
                    "timed out waiting for {what}: {n} particles"
                );
                std::thread::sleep(Duration::from_millis(5));
            }
        };
    wait_for(&mut link, &mut Vec::new(), "the first meshes", |_, _| true);
    assert!(
        link.particles().value.positions.is_empty(),
        "off by default"
    );

    link.set_particle_count(300);
    link.set_particles_on(true);
    wait_particles(&mut link, "300 particles", &|n| n.abs_diff(300) <= 6);
    let view = link.particles().value.clone();
    assert_eq!(view.normals.len(), view.positions.len());
    assert_eq!(view.radii.len(), view.positions.len());
    for p in &view.positions {
        let (value, gradient) = crate::particles::ImplicitSurface::eval(&field, *p);
        let distance = value.abs() / gradient.length();
        assert!(
            distance < 0.1 * field.spacing,
            "{p}: {distance} off the surface"
        );
    }
    assert!(view.radii.iter().all(|r| *r > 0.0 && r.is_finite()));

    link.set_particle_count(150);
    wait_particles(&mut link, "150 particles", &|n| n.abs_diff(150) <= 4);

    link.set_particles_on(false);
    wait_particles(&mut link, "no particles", &|n| n == 0);
    bridge.stop().unwrap();
}

/// Pins through the running engine: a pin's answer comes back as an event and the list
/// reaches the view; undo and "remove all" empty it again.
#[test]
fn pins_made_through_the_bridge_are_listed_and_follow_undo_and_removal() {
    let field = build_clay(&ClaySpec {
        shape: ClayShape::Sphere,
        resolution: 14,
        ..ClaySpec::default()
    })
    .unwrap();
    let centre = crate::engine::clay_centre(&field);
    let on = crate::dynamics::surface_point_on_ray(&field, centre, Vec3::X, 2.0, 0.01)
        .expect("the sphere has a surface along +x");
    let (mut link, bridge) = bridge_on(&field);
    let mut events = Vec::new();
    link.send(EngineCommand::Pin(crate::tools::PinRequest::Point(on)))
        .unwrap();
    wait_for(&mut link, &mut events, "the pin", |v, ev| {
        v.pins.len() == 1 && !ev.is_empty()
    });
    assert!(
        matches!(&events[..], [EngineEvent::Done { what, detail }] if what == "pins" && detail.contains("pinned a point")),
        "{events:?}"
    );
    assert!(link.view().value.pins[0].starts_with("0: point at"));
    link.send(EngineCommand::Undo).unwrap();
    wait_for(&mut link, &mut events, "the undo", |v, _| v.pins.is_empty());
    let curve = vec![on, on + Vec3::Y * 0.05, on + Vec3::Y * 0.1];
    link.send(EngineCommand::Pin(crate::tools::PinRequest::Curve(curve)))
        .unwrap();
    link.send(EngineCommand::Pin(crate::tools::PinRequest::Normal(on)))
        .unwrap();
    // The curve, then the normal and its point.
    wait_for(&mut link, &mut events, "two pins", |v, _| v.pins.len() == 3);
    link.send(EngineCommand::Unpin { index: None }).unwrap();
    wait_for(&mut link, &mut events, "the removal", |v, _| {
        v.pins.is_empty()
    });
    bridge.stop().unwrap();
}

/// The running engine behind the bridge: loading a session replaces the field in every
/// loop and the meshes; a corrupt file is refused with its reason and changes nothing;
/// the force limit reaches the safety filter (capped at the device's own maximum); the
/// latency figures of all three loops reach the view.
#[test]
fn the_bridge_loads_sessions_sets_the_force_limit_and_publishes_loop_figures() {
    let field = build_clay(&ClaySpec {
        shape: ClayShape::Sphere,
        resolution: 14,
        ..ClaySpec::default()
    })
    .unwrap();
    let arm = SimArmConfig::default();
    let info = arm.info.clone();
    let device_max_n = info.max_force_n;
    let mut config = EngineConfig::for_field(&field, &info);
    config.haptic_rt_priority = None;
    // The tool waits at a workspace corner, away from the clay.
    let device: Box<dyn HapticDevice> =
        Box::new(SimulatedArm::new(arm, Trajectory::hold(Vec3::splat(-0.09))));

    // A session on the same lattice with the top half carved away, and a corrupt copy.
    let mut carved: BSplineLattice = field.clone();
    let d = carved.dims;
    for k in d[2] / 2..d[2] {
        for j in 0..d[1] {
            for i in 0..d[0] {
                let idx = carved.index(i, j, k);
                carved.coeffs.set_flat(idx, 0.0);
            }
        }
    }
    let dir = tempfile::tempdir().unwrap();
    let good = dir.path().join("carved.dclay");
    let session = Session {
        clay: Clay::single(carved.clone()),
        material: MaterialFields {
            uniform: Material::ELASTIC,
            grids: Vec::new(),
        },
        ..Session::default()
    };
    save_session(&good, &session).unwrap();
    let corrupt = dir.path().join("corrupt.dclay");
    let mut bytes = std::fs::read(&good).unwrap();
    let mid = bytes.len() / 2;
    bytes[mid] ^= 0x5a;
    std::fs::write(&corrupt, &bytes).unwrap();

    let (mut link, endpoint) = super::super::engine_link();
    let bridge = start_bridge(endpoint, sim_in_use(info), no_devices(), None, |sink| {
        Engine::start(&config, field.clone(), device, sink)
    })
    .unwrap();
    let mut events = Vec::new();
    wait_for(&mut link, &mut events, "first meshes", |v, _| {
        v.device.state == DeviceLinkState::Connected
    });
    let start = Instant::now();
    while triangles(&mut link) == 0 && start.elapsed() < Duration::from_secs(60) {
        std::thread::sleep(Duration::from_millis(5));
    }
    let whole_triangles = triangles(&mut link);
    assert!(whole_triangles > 0);
    assert_eq!(link.view().value.device.max_force_n, device_max_n);

    link.send(EngineCommand::Load { path: good.clone() })
        .unwrap();
    wait_for(&mut link, &mut events, "the load", |v, ev| {
        v.sessions_loaded == 1 && ev.iter().any(|e| matches!(e, EngineEvent::Done { .. }))
    });
    // (a loaded session's tool library comes as its own event, and the background load
    // reports its progress and the file it opened)
    events.retain(|e| {
        !matches!(
            e,
            EngineEvent::Library(_) | EngineEvent::Progress(_) | EngineEvent::FileDone { .. }
        )
    });
    assert!(
        matches!(&events[..], [EngineEvent::Done { what, detail }] if what == "load" && detail.contains("carved.dclay")),
        "{events:?}"
    );
    assert_eq!(link.view().value.material, Material::ELASTIC);
    let start = Instant::now();
    while triangles(&mut link) >= whole_triangles && start.elapsed() < Duration::from_secs(60) {
        std::thread::sleep(Duration::from_millis(5));
    }
    let carved_triangles = triangles(&mut link);
    assert!(
        carved_triangles < whole_triangles,
        "meshes follow the load: {whole_triangles} -> {carved_triangles} triangles"
    );

    events.clear();
    link.send(EngineCommand::Load {
        path: corrupt.clone(),
    })
    .unwrap();
    wait_for(&mut link, &mut events, "the refusal", |_, ev| {
        ev.iter().any(|e| matches!(e, EngineEvent::Failed { .. }))
    });
    // (the background load reports its progress before it fails)
    events.retain(|e| !matches!(e, EngineEvent::Progress(_)));
    let [EngineEvent::Failed { what, error }] = &events[..] else {
        panic!("expected one failure, got {events:?}");
    };
    assert_eq!(what, "load");
    assert!(error.contains("corrupt.dclay"), "{error}");

    link.send(EngineCommand::SetMaxForce { max_force_n: 0.5 })
        .unwrap();
    wait_for(&mut link, &mut events, "the force limit", |v, _| {
        v.device.max_force_n == 0.5
    });
    link.send(EngineCommand::SetMaxForce { max_force_n: 100.0 })
        .unwrap();
    wait_for(&mut link, &mut events, "the device's own limit", |v, _| {
        v.device.max_force_n == device_max_n
    });
    assert!(
        events
            .iter()
            .any(|e| matches!(e, EngineEvent::Done { detail, .. } if detail.contains("maximum"))),
        "{events:?}"
    );

    // Export writes the meshes the graphics loop handed over (read wait-free).
    let exported = dir.path().join("carved.obj");
    link.send(EngineCommand::Export {
        path: exported.clone(),
    })
    .unwrap();
    wait_for(&mut link, &mut events, "the export", |_, ev| {
        ev.iter().any(|e| {
            matches!(e, EngineEvent::Done { what, detail } if what == "export" && detail.contains("triangles"))
        })
    });
    let obj = std::fs::read_to_string(&exported).unwrap();
    assert!(obj.lines().filter(|l| l.starts_with("f ")).count() > 100);

    // The loops publish figures about once a second.
    wait_for(&mut link, &mut events, "loop figures", |v, _| {
        v.loops
            .iter()
            .all(|s| s.ticks > 0 && s.achieved_rate_hz > 0.0)
    });
    let loops = link.view().value.loops;
    assert!((loops[0].nominal_rate_hz - 1000.0).abs() < 0.1);
    assert!(
        (loops[2].nominal_rate_hz - 60.0).abs() < 0.1,
        "{}",
        loops[2].nominal_rate_hz
    );
    assert!(loops[0].compute.p99_us > 0.0);

    let report = bridge.stop().unwrap();
    assert_eq!(
        report.session.clay.density.patches[0].lattice, carved,
        "the corrupt file changed nothing"
    );
    assert_eq!(report.haptic_field.base(), &carved);
    assert_eq!(report.session.material.uniform, Material::ELASTIC);
    assert_eq!(report.safety.clamped, 0, "the tool never touched the clay");
}

/// Loads that need another engine: a session on another lattice restarts the engine on
/// it (the replaced clay kept on disk, the view reporting the new clay's box), an
/// imported point cloud is fitted on the bridge thread and restarts it again, and bad
/// files are refused with their name, leaving the running clay as it was.
#[test]
fn loads_of_another_layout_restart_the_engine_and_imports_are_fitted() {
    let field = build_clay(&ClaySpec {
        shape: ClayShape::Sphere,
        resolution: 14,
        ..ClaySpec::default()
    })
    .unwrap();
    let arm = SimArmConfig::default();
    let info = arm.info.clone();
    let mut config = EngineConfig::for_field(&field, &info);
    config.haptic_rt_priority = None;
    let device: Box<dyn HapticDevice> =
        Box::new(SimulatedArm::new(arm, Trajectory::hold(Vec3::splat(-0.09))));
    let dir = tempfile::tempdir().unwrap();
    let small = build_clay(&ClaySpec {
        shape: ClayShape::Sphere,
        resolution: 10,
        ..ClaySpec::default()
    })
    .unwrap();
    let other = dir.path().join("small.dclay");
    save_session(
        &other,
        &Session {
            clay: Clay::single(small.clone()),
            material: MaterialFields {
                uniform: Material::ELASTIC,
                grids: Vec::new(),
            },
            ..Session::default()
        },
    )
    .unwrap();
    let kept = dir.path().join("sculpt.replaced.dclay");
    let restart = RestartSettings {
        config,
        autosave: None,
        keep_replaced_at: kept.clone(),
    };
    let (mut link, endpoint) = super::super::engine_link();
    let bridge = start_bridge(
        endpoint,
        sim_in_use(info),
        no_devices(),
        Some(restart),
        |sink| Engine::start(&config, field.clone(), device, sink),
    )
    .unwrap();
    let mut events = Vec::new();
    wait_for(&mut link, &mut events, "the first view", |v, _| {
        v.device.state == DeviceLinkState::Connected
    });

    link.send(EngineCommand::Load {
        path: other.clone(),
    })
    .unwrap();
    wait_for(&mut link, &mut events, "the restart", |v, _| {
        v.restarts == 1 && v.sessions_loaded == 1
    });
    assert!(
        events.iter().any(|e| matches!(e, EngineEvent::Done { what, detail }
            if what == "load" && detail.contains("restarted the engine") && detail.contains("sculpt.replaced.dclay"))),
        "{events:?}"
    );
    let view = link.view().value.clone();
    let top = small.node_position(small.dims[0] - 1, small.dims[1] - 1, small.dims[2] - 1);
    assert_eq!(
        view.clay_box,
        Some(WorldBox {
            min: small.origin,
            max: top
        })
    );
    assert_eq!(view.material, Material::ELASTIC, "the session's material");
    assert!(view.workspace_map.is_some());
    let replaced = crate::io::load_session(&kept).unwrap();
    assert_eq!(
        replaced.clay.density.base(),
        &field,
        "the replaced clay is kept"
    );
    let start = Instant::now();
    while triangles(&mut link) == 0 && start.elapsed() < Duration::from_secs(60) {
        std::thread::sleep(Duration::from_millis(5));
    }
    assert!(triangles(&mut link) > 0, "the new clay is meshed");

    // Bad files: named in the log, the clay unchanged.
    events.clear();
    let bad = dir.path().join("bad.ply");
    std::fs::write(
        &bad,
        "ply\nformat ascii 1.0\nelement vertex 3\nend_header\n1 2\n",
    )
    .unwrap();
    // One load at a time: the second is sent once the first is refused.
    link.send(EngineCommand::Load { path: bad }).unwrap();
    wait_for(&mut link, &mut events, "the first refusal", |_, ev| {
        ev.iter().any(|e| matches!(e, EngineEvent::Failed { .. }))
    });
    link.send(EngineCommand::Load {
        path: dir.path().join("missing.xyz"),
    })
    .unwrap();
    wait_for(&mut link, &mut events, "two refusals", |_, ev| {
        ev.iter()
            .filter(|e| matches!(e, EngineEvent::Failed { .. }))
            .count()
            == 2
    });
    let failures: Vec<&String> = events
        .iter()
        .filter_map(|e| match e {
            EngineEvent::Failed { error, .. } => Some(error),
            EngineEvent::Done { .. }
            | EngineEvent::Library(_)
            | EngineEvent::Progress(_)
            | EngineEvent::FileDone { .. } => None,
        })
        .collect();
    assert!(failures[0].contains("bad.ply"), "{failures:?}");
    assert!(failures[1].contains("missing.xyz"), "{failures:?}");
    assert_eq!(link.view().value.restarts, 1, "nothing restarted");

    // A point cloud is fitted on the bridge thread, with its report in the log.
    events.clear();
    let cloud = dir.path().join("ball.xyz");
    let mut text = String::new();
    let n = 400;
    let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
    for i in 0..n {
        let y = 1.0 - 2.0 * (i as f32 + 0.5) / n as f32;
        let r = (1.0 - y * y).sqrt();
        let t = golden * i as f32;
        let (x, z) = (r * t.cos(), r * t.sin());
        text.push_str(&format!("{x} {y} {z} {x} {y} {z}\n"));
    }
    std::fs::write(&cloud, text).unwrap();
    link.send(EngineCommand::Load { path: cloud }).unwrap();
    let start = Instant::now();
    loop {
        while let Some(ev) = link.try_event() {
            events.push(ev);
        }
        if link.view().value.restarts == 2 && link.view().value.sessions_loaded == 1 {
            break;
        }
        // A generous bound only against a hang; nothing is timed.
        assert!(start.elapsed() < Duration::from_secs(120), "{events:?}");
        std::thread::sleep(Duration::from_millis(5));
    }
    assert!(
        events.iter().any(|e| matches!(e, EngineEvent::Done { detail, .. } if detail.contains("400 points with normals"))),
        "{events:?}"
    );
    assert!(
        events.iter().any(|e| matches!(e, EngineEvent::Done { detail, .. } if detail.contains("fitting the base lattice"))),
        "{events:?}"
    );
    let report = bridge.stop().unwrap();
    assert_eq!(report.session.clay.density.base().dims, [32, 32, 32]);
    assert_eq!(report.session.meta.name, "ball");
}

/// An opener that makes nothing (for tests that never use the device panel).
/// A bridge over a running engine on `field`, the simulated arm waiting at a workspace
/// corner, away from the clay; no real-time priority.
fn bridge_on(field: &BSplineLattice) -> (super::super::EngineLink, EngineBridge) {
    let arm = SimArmConfig::default();
    let info = arm.info.clone();
    let mut config = EngineConfig::for_field(field, &info);
    config.haptic_rt_priority = None;
    let device: Box<dyn HapticDevice> =
        Box::new(SimulatedArm::new(arm, Trajectory::hold(Vec3::splat(-0.09))));
    let (link, endpoint) = super::super::engine_link();
    let bridge = start_bridge(endpoint, sim_in_use(info), no_devices(), None, |sink| {
        Engine::start(&config, field.clone(), device, sink)
    })
    .unwrap();
    (link, bridge)
}

fn no_devices() -> DeviceOpener {
    Box::new(|spec: &DeviceSpec| {
        Err(DeviceError::NotFound {
            what: format!("{spec} in this test"),
        }
        .into())
    })
}

/// The device panel's commands reach the running engine: connect switches to a new
/// device (the old one closed, the asked force limit applied), a device that cannot be
/// made is refused and leaves the current one, disconnect parks the haptic loop and a
/// later connect brings a device back; the engine runs throughout.
#[test]
fn the_panel_switches_disconnects_and_reconnects_devices() {
    let field = build_clay(&ClaySpec {
        shape: ClayShape::Sphere,
        resolution: 12,
        ..ClaySpec::default()
    })
    .unwrap();
    let mut first = SimArmConfig::default();
    first.info.name = "arm 1".into();
    let info = first.info.clone();
    let mut config = EngineConfig::for_field(&field, &info);
    config.haptic_rt_priority = None;
    let device: Box<dyn HapticDevice> = Box::new(SimulatedArm::new(
        first,
        Trajectory::hold(Vec3::splat(-0.09)),
    ));
    // Simulated arms, numbered from 2; any other spec cannot be made here.
    let mut made = 1;
    let opener: DeviceOpener = Box::new(move |spec: &DeviceSpec| match spec {
        DeviceSpec::Sim => {
            made += 1;
            let mut arm = SimArmConfig::default();
            arm.info.name = format!("arm {made}");
            let held = Trajectory::hold(Vec3::splat(0.09));
            Ok(Box::new(SimulatedArm::new(arm, held)) as Box<dyn HapticDevice>)
        }
        other => Err(DeviceError::NotFound {
            what: format!("{other}: no such port"),
        }
        .into()),
    });
    let (mut link, endpoint) = super::super::engine_link();
    let bridge = start_bridge(endpoint, sim_in_use(info), opener, None, |sink| {
        Engine::start(&config, field.clone(), device, sink)
    })
    .unwrap();
    let mut events = Vec::new();
    wait_for(&mut link, &mut events, "the first arm", |v, _| {
        v.device.state == DeviceLinkState::Connected && v.device.name == "arm 1"
    });

    link.send(EngineCommand::ConnectDevice {
        spec: DeviceSpec::Sim,
        max_force_n: 1.5,
    })
    .unwrap();
    wait_for(&mut link, &mut events, "the switch", |v, ev| {
        v.device.name == "arm 2" && !ev.is_empty()
    });
    assert!(
        matches!(&events[..], [EngineEvent::Done { detail, .. }] if detail == "arm 2 connected; arm 1 closed"),
        "{events:?}"
    );
    wait_for(&mut link, &mut events, "the asked limit", |v, _| {
        v.device.max_force_n == 1.5 && v.device.state == DeviceLinkState::Connected
    });

    events.clear();
    let falcon = DeviceSpec::Falcon {
        path: "/dev/ttyUSB9".into(),
    };
    link.send(EngineCommand::ConnectDevice {
        spec: falcon,
        max_force_n: 1.5,
    })
    .unwrap();
    wait_for(&mut link, &mut events, "the refusal", |_, ev| {
        !ev.is_empty()
    });
    assert!(
        matches!(&events[..], [EngineEvent::Failed { error, .. }] if error.contains("no such port")),
        "{events:?}"
    );
    assert_eq!(link.view().value.device.name, "arm 2", "still connected");

    events.clear();
    link.send(EngineCommand::DisconnectDevice).unwrap();
    wait_for(&mut link, &mut events, "the disconnect", |v, ev| {
        v.device.state == DeviceLinkState::Disconnected && !ev.is_empty()
    });
    assert!(
        matches!(&events[..], [EngineEvent::Done { detail, .. }] if detail == "arm 2 closed"),
        "{events:?}"
    );
    let ticks = link.view().value.loops[0].ticks;

    events.clear();
    link.send(EngineCommand::ConnectDevice {
        spec: DeviceSpec::Sim,
        max_force_n: 1.0,
    })
    .unwrap();
    wait_for(&mut link, &mut events, "the reconnect", |v, ev| {
        v.device.name == "arm 3" && v.device.state == DeviceLinkState::Connected && !ev.is_empty()
    });
    assert!(
        matches!(&events[..], [EngineEvent::Done { detail, .. }] if detail == "arm 3 connected"),
        "{events:?}"
    );
    wait_for(
        &mut link,
        &mut events,
        "the haptic loop's figures",
        |v, _| v.loops[0].ticks > ticks,
    );
    let report = bridge.stop().unwrap();
    assert_eq!(report.counters.device_swaps, 3);
    assert_eq!(report.counters.device_read_faults, 0);
}

/// A 16³ sphere clay meshed in full by the octree.
fn meshed_sphere() -> (BSplineLattice, BrickOctree, RefreshReport) {
    let lattice = build_clay(&ClaySpec {
        shape: ClayShape::Sphere,
        resolution: 16,
        ..ClaySpec::default()
    })
    .unwrap();
    let grid = SampleGrid::for_lattice(&lattice, 2).unwrap();
    let mut octree = BrickOctree::new(grid);
    let report = octree.rebuild(&lattice);
    (lattice, octree, report)
}

/// A sphere through the real octree mesher, published by the sink and exported welded.
#[test]
fn sink_publishes_bricks_and_export_welds_them_closed() {
    let (_, octree, report) = meshed_sphere();

    let (mut link, end) = super::super::link::engine_link();
    let (exports, _exported) = snapshot_channel(&MeshSet::new());
    let mut sink = GuiMeshSink::new(end.meshes, end.field, exports, end.repaint);
    sink.update(&octree, &report);
    let published = link.meshes().value.clone();
    assert!(published.len() > 1, "sphere spans several bricks");
    let tris: usize = published.iter().map(|c| c.indices.len() / 3).sum();
    assert_eq!(tris, octree.triangle_count());

    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sphere.obj");
    let n = export_chunks(&published, &path).unwrap();
    assert!(n > 100);
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.lines().filter(|l| l.starts_with("f ")).count() == n);
    let welded = octree.weld();
    assert!(MeshStats::of(&welded).is_closed_manifold());
    // One welding: the export is the octree's weld, vertex for vertex.
    assert_eq!(n, welded.triangle_count());
    let vertices = text.lines().filter(|l| l.starts_with("v ")).count();
    assert_eq!(vertices, welded.positions.len());
    assert!(matches!(
        export_chunks(&published, &dir.path().join("x.abc")),
        Err(ChunkExportError::UnknownFormat { .. })
    ));
    let mut broken = (*published[0]).clone();
    broken.edge_ids.pop();
    let broken: MeshSet = vec![Arc::new(broken)];
    assert!(matches!(
        export_chunks(&broken, &path),
        Err(ChunkExportError::Chunk { .. })
    ));
}

/// A sphere clay with a rippled detail patch over half of it, meshed by the multi-level
/// mesher into the window's bricks, as the graphics loop draws a clay with detail: the
/// ripple's saddles leave leaf faces whose corners alternate in sign, and there dual
/// contouring's one vertex per leaf joins two sheets with an edge of four triangles. The
/// window's export cuts them apart: closed, oriented and edge-manifold, with the same
/// triangles, area and volume as the bricks drawn.
#[test]
fn export_of_a_clay_with_detail_cuts_sheets_sharing_an_edge_apart() {
    use crate::mesh::{AdaptiveBricks, TriMesh};
    let base = build_clay(&ClaySpec {
        shape: ClayShape::Sphere,
        resolution: 16,
        ..ClaySpec::default()
    })
    .unwrap();
    let plain = base.clone();
    let mut field = MultiPatchField::new(base);
    let d = field
        .refine(Vec3::splat(0.2), Vec3::new(1.3, 1.3, 0.8), 2)
        .unwrap();
    let ripple = move |x: Vec3| {
        plain.value_and_gradient(x).0 + RIPPLE * (40.0 * x.x).sin() * (40.0 * x.y).sin()
    };
    const RIPPLE: f32 = 0.12;
    field.fit_detail(d, 2, ripple).unwrap();
    let grid = SampleGrid::for_field(&field, 2).unwrap();
    let mut octree = BrickOctree::new(grid);
    let options = crate::engine::level_mesh_options(2);
    let (_levels, report) = AdaptiveBricks::new(&field, &options, &mut octree).unwrap();

    let (mut link, end) = super::super::link::engine_link();
    let (exports, _exported) = snapshot_channel(&MeshSet::new());
    let mut sink = GuiMeshSink::new(end.meshes, end.field, exports, end.repaint);
    sink.update(&octree, &report);
    let published = link.meshes().value.clone();
    let drawn = MeshStats::of(&octree.weld());
    println!("drawn: {drawn:?}");
    assert!(drawn.non_manifold_edges > 0, "{drawn:?}");
    assert_eq!(drawn.boundary_edges, 0, "{drawn:?}");

    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("rippled.obj");
    let n = export_chunks(&published, &path).unwrap();
    let (positions, triangles) = crate::fit::mesh::read_mesh(&path).unwrap();
    let exported = MeshStats::of(&TriMesh {
        normals: vec![Vec3::Z; positions.len()],
        positions,
        triangles,
    });
    println!("exported: {exported:?}");
    assert_eq!(n, drawn.triangles);
    assert_eq!(exported.triangles, drawn.triangles);
    assert_eq!(exported.non_manifold_edges, 0, "{exported:?}");
    assert_eq!(exported.boundary_edges, 0, "{exported:?}");
    assert_eq!(exported.misoriented_edges, 0, "{exported:?}");
    assert!(exported.vertices > drawn.vertices, "{exported:?}");
    // Nothing moved (the file holds the positions to its printed digits).
    assert!((exported.area - drawn.area).abs() <= 1e-4 * drawn.area);
    assert!((exported.volume - drawn.volume).abs() <= 1e-4 * drawn.volume);
}

/// Paint reaches the chunks: painting the low-x half red recolours (and re-versions)
/// exactly the bricks it covers; clearing the paint takes the colour off again.
#[test]
fn sink_recolours_the_bricks_paint_covers() {
    let (lattice, octree, report) = meshed_sphere();
    let (mut link, end) = super::super::link::engine_link();
    let mut sink = GuiMeshSink::new(
        end.meshes,
        end.field,
        snapshot_channel(&MeshSet::new()).0,
        end.repaint,
    );
    sink.update(&octree, &report);
    let before = link.meshes().value.clone();
    assert!(before.iter().all(|c| c.colors.is_empty()), "unpainted");

    let mut colour = ColourField::matching(&lattice).unwrap();
    let d = lattice.dims;
    for k in 0..d[2] {
        for j in 0..d[1] {
            for i in 0..d[0] / 3 {
                let idx = lattice.index(i, j, k);
                colour.channels[0].coeffs.set_flat(idx, 1.0);
                colour.channels[3].coeffs.set_flat(idx, 1.0);
            }
        }
    }
    sink.paint(&octree, Some(&colour));
    let painted = link.meshes().value.clone();
    assert_eq!(painted.len(), before.len(), "the same bricks");
    let by_id = |set: &MeshSet, id: u64| set.iter().find(|c| c.id == id).cloned().unwrap();
    let (mut recoloured, mut kept, mut red) = (0, 0, 0);
    for chunk in &painted {
        let old = by_id(&before, chunk.id);
        if chunk.colors.is_empty() {
            assert!(
                Arc::ptr_eq(chunk, &old),
                "an unpainted brick keeps its chunk"
            );
            kept += 1;
        } else {
            assert_ne!(
                chunk.version, old.version,
                "a repainted brick is re-uploaded"
            );
            assert!(
                chunk.colors.iter().any(|c| c[3] > 0.0),
                "brick {} carries paint",
                chunk.id
            );
            red += chunk
                .colors
                .iter()
                .filter(|c| c[0] > 0.9 && c[3] > 0.9)
                .count();
            recoloured += 1;
        }
    }
    assert!(
        recoloured > 0 && kept > 0,
        "{recoloured} recoloured, {kept} kept"
    );

    assert!(red > 0, "fully painted vertices are red");

    sink.paint(&octree, None);
    let cleared = link.meshes().value.clone();
    assert!(cleared.iter().all(|c| c.colors.is_empty()), "paint cleared");
}

/// The mask reaches the chunks as a tint: masking the low-x third darkens (and re-versions)
/// the bricks it covers, over their paint, and leaves the others' chunks as they were; a
/// cleared mask takes the tint off again.
#[test]
fn sink_tints_the_bricks_the_mask_covers() {
    use crate::render::{MASK_TINT_OPACITY, tinted};
    let (lattice, octree, report) = meshed_sphere();
    let (mut link, end) = super::super::link::engine_link();
    let mut sink = GuiMeshSink::new(
        end.meshes,
        end.field,
        snapshot_channel(&MeshSet::new()).0,
        end.repaint,
    );
    sink.update(&octree, &report);
    let before = link.meshes().value.clone();
    let mut mask = FreezeMask::matching(&lattice.clone().into()).unwrap();
    let d = lattice.dims;
    for k in 0..d[2] {
        for j in 0..d[1] {
            for i in 0..d[0] / 3 {
                mask.patches[0].coeffs.set_flat(lattice.index(i, j, k), 1.0);
            }
        }
    }
    sink.mask(&octree, Some(&mask));
    let masked = link.meshes().value.clone();
    assert_eq!(masked.len(), before.len(), "the same bricks");
    let (mut tinted_bricks, mut kept, mut dark) = (0, 0, 0);
    for chunk in &masked {
        let old = before.iter().find(|c| c.id == chunk.id).unwrap();
        if chunk.colors.is_empty() {
            assert!(Arc::ptr_eq(chunk, old), "an unmasked brick keeps its chunk");
            kept += 1;
            continue;
        }
        assert_ne!(chunk.version, old.version, "a tinted brick is re-uploaded");
        tinted_bricks += 1;
        for (c, p) in chunk.colors.iter().zip(&chunk.positions) {
            let hold = mask.value_at(glam::Vec3::from_array(*p));
            let expected = tinted([0.0; 4], hold);
            assert!(
                c.iter().zip(expected).all(|(a, b)| (a - b).abs() < 1e-6),
                "vertex at {p:?}: {c:?}, the tint of hold {hold} is {expected:?}"
            );
            if c[3] > 0.5 * MASK_TINT_OPACITY {
                dark += 1;
            }
        }
    }
    assert!(
        tinted_bricks > 0 && kept > 0 && dark > 0,
        "{tinted_bricks} tinted, {kept} kept, {dark} vertices over half masked"
    );
    sink.mask(&octree, None);
    let cleared = link.meshes().value.clone();
    assert!(cleared.iter().all(|c| c.colors.is_empty()), "tint cleared");
}

#[test]
fn a_refused_edit_is_shown_once_and_a_new_refusal_again() {
    use crate::engine::BudgetRefusal;
    use crate::field::DenseBudgetError;
    let first = BudgetRefusal::DenseBricks(DenseBudgetError {
        dense: 10,
        more: 5,
        at: None,
    });
    let second = BudgetRefusal::ClayBox {
        dims: [2048; 3],
        total: 2048 * 2048 * 2048,
    };
    let mut shown = None;
    assert!(budget_refusal_event(&mut shown, None).is_none());
    let Some(EngineEvent::Failed { what, error }) = budget_refusal_event(&mut shown, Some(first))
    else {
        panic!("a refusal is shown");
    };
    assert_eq!(what, "edit");
    assert!(error.contains("refused and nothing changed"), "{error}");
    assert!(
        budget_refusal_event(&mut shown, Some(first)).is_none(),
        "the same refusal, published with every status, is shown once"
    );
    let Some(EngineEvent::Failed { error, .. }) = budget_refusal_event(&mut shown, Some(second))
    else {
        panic!("a clipped growth is shown");
    };
    assert!(error.contains("clipped to the clay's box"), "{error}");
    assert!(budget_refusal_event(&mut shown, None).is_none());
    assert_eq!(shown, None);
}
