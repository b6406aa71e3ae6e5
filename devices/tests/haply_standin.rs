//! The Haply drivers against stand-ins that speak the real protocols: the Inverse3 against a
//! local WebSocket server answering as Haply's Inverse Service, the 2DIY against a Haply board
//! on a pseudo-terminal (`support/haply_standins.rs`). What they report, that every tick's
//! force reaches the device once, zero force on connect and after every fault, the safety
//! filter's ramp (checked against the timestamps the driver reported, whatever the clock
//! did), a disconnect, typed errors, and a haptic path that allocates nothing.
//!
//! The drivers here wait up to seconds for each reply (`reply_wait`), so each `read` sees the
//! answer to the previous command however loaded the machine is; nothing asserts a rate.

mod common;
#[path = "support/haply_standins.rs"]
mod haply_standins;

use std::time::Duration;

use common::allocations;
use dynaclay_devices::codec::haply_board as hb;
use dynaclay_devices::inverse3::{Inverse3, Inverse3Config};
use dynaclay_devices::open::{DriverOptions, build_driver};
use dynaclay_devices::spec::DeviceSpec;
use dynaclay_devices::two_diy::{
    DEVICE_ID, TwoDiy, TwoDiyOptions, TwoDiyVersion, device_to_board_force,
};
use dynaclay_devices::{DeviceError, HapticDevice, SafetyConfig, SafetyFilter, soft_start_gain};
use glam::{DVec2, Vec3};
use haply_standins::{Fault, Standin, inverse3_service, two_diy_board};

/// Long enough that a reply is never late on a loaded machine; the loop never waits this
/// long unless the stand-in is gone.
const PATIENT: Duration = Duration::from_secs(5);

fn inverse3(standin: &Standin) -> Inverse3 {
    Inverse3::new(Inverse3Config {
        url: standin.address.clone(),
        connect_timeout: PATIENT,
        reply_timeout: PATIENT,
        reply_wait: PATIENT,
        ..Inverse3Config::default()
    })
}

fn two_diy(standin: &Standin, version: TwoDiyVersion) -> TwoDiy {
    TwoDiy::new(
        &standin.address,
        TwoDiyOptions {
            version,
            handshake_timeout: PATIENT,
            reply_wait: PATIENT,
            stale_after: PATIENT,
            ..TwoDiyOptions::default()
        },
    )
}

/// A filter with a ramp of `soft_start_s` and a slew limit too high to matter.
fn filtered<D: HapticDevice>(device: D, soft_start_s: f32) -> SafetyFilter<D> {
    SafetyFilter::with_config(
        device,
        SafetyConfig {
            soft_start_s,
            slew_rate_n_per_s: 1e9,
            ..SafetyConfig::default()
        },
    )
}

/// A hand moving 0.1 mm along device x per exchange from `start`.
fn drifting(start: Vec3) -> haply_standins::Hand {
    Box::new(move |k| start + Vec3::X * (1e-4 * k as f32))
}

fn still(at: Vec3) -> haply_standins::Hand {
    Box::new(move |_| at)
}

/// A point in the middle of the 2DIY's workspace (device frame).
fn two_diy_middle(version: TwoDiyVersion) -> Vec3 {
    TwoDiy::info_for(version).workspace_center_m()
}

// ---------------------------------------------------------------------------------------
// Inverse3

#[test]
fn inverse3_reports_the_arm_in_the_device_frame_one_fresh_sample_per_exchange() {
    let start = Vec3::new(0.01, 0.15, 0.12);
    let s = inverse3_service(drifting(start));
    let mut arm = inverse3(&s);
    assert_eq!(arm.info(), Inverse3::published_info());
    arm.open().unwrap();
    assert_eq!(arm.device_id(), Some("049D"));
    let first = arm.read().unwrap();
    // The opening zero force was exchange 0; this read's keep-alive is exchange 1.
    assert_eq!(first.sequence, 2);
    assert!(
        first.position_m.abs_diff_eq(start + Vec3::X * 1e-4, 1e-6),
        "{}",
        first.position_m
    );
    assert!(
        first.velocity_m_per_s.abs_diff_eq(Vec3::X * 0.1, 1e-4),
        "{}",
        first.velocity_m_per_s
    );
    assert_eq!(first.buttons, 0b010, "VerseGrip button b");
    for k in 0..50u64 {
        let s = arm.read().unwrap();
        assert_eq!(s.sequence, first.sequence + k + 1);
        assert!(s.timestamp_us >= first.timestamp_us);
    }
}

#[test]
fn inverse3_force_is_zero_on_connect_and_reaches_the_service_once_per_tick() {
    let s = inverse3_service(still(Vec3::new(0.0, 0.15, 0.12)));
    let mut dev = filtered(inverse3(&s), 0.0);
    dev.open().unwrap();
    assert_eq!(
        s.exchanges(),
        1,
        "open waits for the reply to its one command"
    );
    assert_eq!(
        s.log().forces_n,
        vec![Vec3::ZERO],
        "the first command is zero force"
    );
    let ticks = 200usize;
    for k in 0..ticks {
        dev.read().unwrap();
        dev.write_force(Vec3::new(0.5, -0.25, 0.001 * k as f32))
            .unwrap();
        // The command carries exactly the filter's output.
        let out = dev.output_force_n();
        assert!(
            s.wait_for(PATIENT, |l| l.forces_n.len() == 2 + k + 1),
            "tick {k}"
        );
        assert_eq!(*s.log().forces_n.last().unwrap(), out, "tick {k}");
    }
    dev.read().unwrap();
    let log = s.log();
    // open's zero, the first read's keep-alive, then one command per write, no more.
    assert_eq!(log.forces_n.len(), 2 + ticks);
    assert_eq!(dev.device().commands_sent(), 2 + ticks as u64);
    assert_eq!(log.forces_n[1], Vec3::ZERO);
    assert_eq!(
        log.forces_n[2],
        Vec3::ZERO,
        "no elapsed time yet: the filter holds zero"
    );
    assert!(log.forces_n[3..].iter().all(|f| f.x == 0.5 && f.y == -0.25));
    dev.close().unwrap();
    let log = s.log();
    assert_eq!(
        *log.forces_n.last().unwrap(),
        Vec3::ZERO,
        "close sends zero"
    );
}

#[test]
fn inverse3_soft_start_ramps_the_force_on_the_reported_timestamps() {
    let s = inverse3_service(still(Vec3::new(0.0, 0.15, 0.12)));
    let ramp_s = 0.02;
    let mut dev = filtered(inverse3(&s), ramp_s);
    dev.open().unwrap();
    let request = Vec3::new(0.0, 2.0, 0.0);
    let mut t0 = None;
    let mut previous = 0.0f32;
    let mut done = false;
    for k in 0..1_000_000 {
        let state = dev.read().unwrap();
        let t0 = *t0.get_or_insert(state.timestamp_us);
        dev.write_force(request).unwrap();
        let sent = dev.output_force_n().y;
        let progress = (state.timestamp_us - t0) as f32 * 1e-6 / ramp_s;
        let expected = 2.0 * soft_start_gain(progress);
        assert!(
            (sent - expected).abs() < 1e-5,
            "tick {k}: sent {sent}, ramp gives {expected}"
        );
        assert!(sent >= previous, "tick {k}: the ramp went down");
        previous = sent;
        if progress >= 1.0 {
            done = true;
            break;
        }
    }
    assert!(
        done && previous == 2.0,
        "the ramp ends at the request: {previous}"
    );
    dev.read().unwrap();
    let log = s.log();
    assert!(
        log.forces_n.windows(2).all(|w| w[1].y >= w[0].y),
        "monotone at the arm"
    );
    assert_eq!(log.forces_n.last().unwrap().y, 2.0);
}

#[test]
fn inverse3_protocol_faults_are_typed_named_and_end_in_zero_force() {
    for (fault, what, detail) in [
        (
            Fault::Garbage,
            "Inverse Service message is not JSON",
            "line 1, column",
        ),
        (
            Fault::WrongType,
            "Inverse Service message field of the wrong type",
            "inverse3[0].state.cursor_position.y",
        ),
        (
            Fault::Binary,
            "Inverse Service sent a binary message",
            "binary message of 3 bytes",
        ),
        (
            Fault::Oversize,
            "Inverse Service message too large",
            "refused",
        ),
    ] {
        let s = inverse3_service(still(Vec3::new(0.0, 0.15, 0.12)));
        let mut dev = filtered(inverse3(&s), 0.0);
        dev.open().unwrap();
        for _ in 0..20 {
            dev.read().unwrap();
            dev.write_force(Vec3::new(1.0, 0.0, 0.0)).unwrap();
        }
        assert_eq!(dev.output_force_n(), Vec3::new(1.0, 0.0, 0.0));
        s.inject(fault);
        let err = loop {
            // The reply to the last write is the faulty one.
            match dev.read() {
                Ok(_) => dev.write_force(Vec3::new(1.0, 0.0, 0.0)).unwrap(),
                Err(e) => break e,
            }
        };
        match &err {
            DeviceError::Protocol { what: w, .. } => assert_eq!(*w, what, "{fault:?}"),
            other => panic!("{fault:?}: expected a protocol error, got {other:?}"),
        }
        let words = dev.device().fault_detail().unwrap();
        assert!(words.contains(detail), "{fault:?}: {words}");
        assert!(dev.fault_latched());
        assert_eq!(
            dev.output_force_n(),
            Vec3::ZERO,
            "{fault:?}: the filter sends zero"
        );
        // The driver's last command, after the faulty reply, is zero force.
        assert!(
            s.wait_for(PATIENT, |l| !l.after_fault.is_empty()),
            "{fault:?}: no command after the fault"
        );
        assert_eq!(s.log().after_fault, vec![Vec3::ZERO], "{fault:?}");
        // The fault stays: every later call says so, and nothing more is sent.
        assert_eq!(dev.read().unwrap_err(), err);
        assert_eq!(dev.device_mut().write_force(Vec3::X).unwrap_err(), err);
        assert_eq!(s.log().after_fault.len(), 1);
    }
}

#[test]
fn inverse3_disconnect_is_reported_and_the_filter_sends_zero() {
    let s = inverse3_service(still(Vec3::new(0.0, 0.15, 0.12)));
    let mut dev = filtered(inverse3(&s), 0.0);
    dev.open().unwrap();
    for _ in 0..10 {
        dev.read().unwrap();
        dev.write_force(Vec3::new(0.0, 0.0, 1.5)).unwrap();
    }
    s.inject(Fault::Close);
    let err = loop {
        match dev.read() {
            Ok(_) => {
                let _ = dev.write_force(Vec3::new(0.0, 0.0, 1.5));
            }
            Err(e) => break e,
        }
    };
    assert_eq!(err, DeviceError::Disconnected);
    assert!(dev.fault_latched());
    assert_eq!(dev.output_force_n(), Vec3::ZERO);
    assert_eq!(
        dev.write_force(Vec3::Z).unwrap_err(),
        DeviceError::Disconnected
    );
    assert_eq!(dev.output_force_n(), Vec3::ZERO, "zero while latched");
    assert_eq!(dev.read().unwrap_err(), DeviceError::Disconnected);
    dev.close().unwrap();
    assert!(!dev.is_open());
}

#[test]
fn inverse3_spec_builds_a_driver_for_the_url_and_an_absent_service_is_not_found() {
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let spec: DeviceSpec = format!("inverse3:ws://127.0.0.1:{port}").parse().unwrap();
    let mut dev = SafetyFilter::new(build_driver(&spec, &DriverOptions::default()).unwrap());
    match dev.open().unwrap_err() {
        DeviceError::NotFound { what } => {
            assert!(what.contains(&format!("127.0.0.1:{port}")), "{what}");
            assert!(what.contains("Inverse Service"), "{what}");
        }
        other => panic!("expected NotFound, got {other:?}"),
    }
    // Through the spec, against the stand-in: the same driver opens.
    let s = inverse3_service(still(Vec3::new(0.0, 0.15, 0.12)));
    let spec: DeviceSpec = format!("inverse3:{}", s.address).parse().unwrap();
    let mut dev = SafetyFilter::new(build_driver(&spec, &DriverOptions::default()).unwrap());
    dev.open().unwrap();
    assert!(dev.info().name.contains("Inverse3"));
    assert_eq!(dev.max_force_n(), 4.0);
}

// ---------------------------------------------------------------------------------------
// 2DIY

#[test]
fn two_diy_sets_up_the_board_as_haply_does_and_sends_zero_torque_first() {
    for version in [TwoDiyVersion::V3, TwoDiyVersion::V2] {
        let s = two_diy_board(version, still(two_diy_middle(version)));
        let mut dev = filtered(two_diy(&s, version), 0.0);
        dev.open().unwrap();
        let log = s.log();
        assert_eq!(log.resets, 1);
        let mut expected = [0u8; hb::MAX_HOST_MESSAGE];
        let n = hb::encode_setup(DEVICE_ID, &version.ports(), &mut expected).unwrap();
        assert_eq!(log.setup, expected[..n].to_vec(), "{version:?}");
        assert_eq!(
            log.torques_n_m,
            vec![[0.0, 0.0]],
            "{version:?}: zero torques first"
        );
        let state = dev.read().unwrap();
        assert!(
            state.position_m.abs_diff_eq(two_diy_middle(version), 1e-5),
            "{version:?}: {}",
            state.position_m
        );
        assert_eq!(state.position_m.z, 0.0, "the plane is z = 0");
    }
}

#[test]
fn two_diy_torques_are_the_jacobian_transpose_of_the_filtered_force_once_per_tick() {
    let version = TwoDiyVersion::V3;
    let s = two_diy_board(version, drifting(two_diy_middle(version) - Vec3::X * 0.01));
    let mut dev = filtered(two_diy(&s, version), 0.0);
    dev.open().unwrap();
    let pg = version.pantograph();
    let ticks = 200usize;
    for k in 0..ticks {
        let state = dev.read().unwrap();
        assert_eq!(
            state.sequence,
            k as u64 + 2,
            "one fresh sample per exchange"
        );
        dev.write_force(Vec3::new(0.4, -0.3, 7.0)).unwrap();
        assert!(
            s.wait_for(PATIENT, |l| l.torques_n_m.len() == 2 + k + 1),
            "tick {k}"
        );
        // The torques for the filter's output at the pose this tick read.
        let p = DVec2::new(
            -f64::from(state.position_m.x),
            -f64::from(state.position_m.y),
        );
        let (t1, t2) = pg.inverse(p).unwrap();
        let tau = pg
            .forward(t1, t2)
            .unwrap()
            .torques_n_m(device_to_board_force(dev.output_force_n()));
        let got = *s.log().torques_n_m.last().unwrap();
        for j in 0..2 {
            assert!(
                (f64::from(got[j]) - tau[j]).abs() < 1e-5,
                "tick {k}: {got:?} vs {tau:?}"
            );
        }
        if k > 0 {
            assert!(
                got[0] != 0.0 || got[1] != 0.0,
                "tick {k}: force reaches the motors"
            );
        }
    }
    assert_eq!(dev.device().exchanges().0, 2 + ticks as u64);
    dev.close().unwrap();
    assert!(s.wait_for(PATIENT, |l| l.torques_n_m.len() == 3 + ticks));
    assert_eq!(
        *s.log().torques_n_m.last().unwrap(),
        [0.0, 0.0],
        "close sends zero"
    );
}

#[test]
fn two_diy_soft_start_ramps_on_the_reported_timestamps() {
    let version = TwoDiyVersion::V3;
    let at = two_diy_middle(version);
    let s = two_diy_board(version, still(at));
    let ramp_s = 0.02;
    let mut dev = filtered(two_diy(&s, version), ramp_s);
    dev.open().unwrap();
    let request = Vec3::new(0.0, 1.5, 0.0);
    let pg = version.pantograph();
    let (t1, t2) = pg
        .inverse(DVec2::new(-f64::from(at.x), -f64::from(at.y)))
        .unwrap();
    let pose = pg.forward(t1, t2).unwrap();
    let mut t0 = None;
    let mut done = false;
    for k in 0..1_000_000 {
        let state = dev.read().unwrap();
        let t0 = *t0.get_or_insert(state.timestamp_us);
        dev.write_force(request).unwrap();
        let progress = (state.timestamp_us - t0) as f32 * 1e-6 / ramp_s;
        let expected = pose.torques_n_m(device_to_board_force(request * soft_start_gain(progress)));
        assert!(s.wait_for(PATIENT, |l| l.torques_n_m.len() == k + 3));
        let got = *s.log().torques_n_m.last().unwrap();
        for j in 0..2 {
            assert!(
                (f64::from(got[j]) - expected[j]).abs() < 1e-5,
                "tick {k}: {got:?} vs {expected:?}"
            );
        }
        if progress >= 1.0 {
            done = true;
            break;
        }
    }
    assert!(done);
}

#[test]
fn two_diy_a_stray_byte_is_a_protocol_fault_then_the_stream_realigns_and_force_ramps_back() {
    let version = TwoDiyVersion::V3;
    let s = two_diy_board(version, still(two_diy_middle(version)));
    let mut dev = filtered(two_diy(&s, version), 0.01);
    dev.open().unwrap();
    for _ in 0..5 {
        dev.read().unwrap();
        dev.write_force(Vec3::new(0.5, 0.0, 0.0)).unwrap();
    }
    s.inject(Fault::Garbage);
    let err = loop {
        match dev.read() {
            Ok(_) => dev.write_force(Vec3::new(0.5, 0.0, 0.0)).unwrap(),
            Err(e) => break e,
        }
    };
    match err {
        DeviceError::Protocol { what, offset } => {
            assert_eq!(what, "device id of the reply");
            // Each reply is 9 bytes; the stray byte came before reply number `offset / 9`.
            assert_eq!(offset % 9, 0, "{offset}");
        }
        other => panic!("expected a protocol error, got {other:?}"),
    }
    assert!(dev.fault_latched());
    dev.write_force(Vec3::new(0.5, 0.0, 0.0)).unwrap();
    let sent = dev.device().exchanges().0 as usize;
    assert!(s.wait_for(PATIENT, |l| l.torques_n_m.len() == sent));
    assert_eq!(
        *s.log().torques_n_m.last().unwrap(),
        [0.0, 0.0],
        "zero while latched"
    );
    // The realigned stream gives good samples; the force comes back through a new ramp.
    let mut sent = Vec::new();
    for _ in 0..5000 {
        dev.read().unwrap();
        dev.write_force(Vec3::new(0.5, 0.0, 0.0)).unwrap();
        sent.push(dev.output_force_n().x);
        if sent.last() == Some(&0.5) {
            break;
        }
    }
    assert!(!dev.fault_latched());
    assert_eq!(sent[0], 0.0, "the ramp restarts from zero");
    assert!(sent.windows(2).all(|w| w[1] >= w[0]));
    assert_eq!(*sent.last().unwrap(), 0.5);
}

#[test]
fn two_diy_unplugged_is_a_disconnect_and_a_silent_port_is_not_found() {
    let version = TwoDiyVersion::V3;
    let s = two_diy_board(version, still(two_diy_middle(version)));
    let mut dev = filtered(two_diy(&s, version), 0.0);
    dev.open().unwrap();
    for _ in 0..5 {
        dev.read().unwrap();
        dev.write_force(Vec3::new(0.5, 0.0, 0.0)).unwrap();
    }
    s.inject(Fault::Close);
    let err = loop {
        match dev.read() {
            Ok(_) => {
                let _ = dev.write_force(Vec3::new(0.5, 0.0, 0.0));
            }
            Err(e) => break e,
        }
    };
    assert_eq!(err, DeviceError::Disconnected);
    assert_eq!(
        dev.read().unwrap_err(),
        DeviceError::Disconnected,
        "it stays gone"
    );
    assert!(dev.fault_latched());
    assert_eq!(dev.output_force_n(), Vec3::ZERO);
    drop(dev);

    // A board that never answers: the handshake's bounded wait ends in NotFound.
    let quiet = two_diy_board(version, still(two_diy_middle(version)));
    quiet.inject(Fault::Silent);
    let path = quiet.address.clone();
    let mut silent = TwoDiy::new(
        &path,
        TwoDiyOptions {
            handshake_timeout: Duration::from_millis(50),
            ..TwoDiyOptions::default()
        },
    );
    match silent.open().unwrap_err() {
        DeviceError::NotFound { what } => {
            assert!(what.contains(&path) && what.contains("firmware"), "{what}");
        }
        other => panic!("expected NotFound, got {other:?}"),
    }
    assert!(!silent.is_open());
}

// ---------------------------------------------------------------------------------------
// Both

#[test]
fn the_haptic_path_of_both_drivers_allocates_nothing_faults_included() {
    let inv = inverse3_service(drifting(Vec3::new(0.0, 0.15, 0.12)));
    let mut a = filtered(inverse3(&inv), 0.01);
    a.open().unwrap();
    let board = two_diy_board(TwoDiyVersion::V3, still(two_diy_middle(TwoDiyVersion::V3)));
    let mut b = filtered(two_diy(&board, TwoDiyVersion::V3), 0.01);
    b.open().unwrap();
    for dev in [&mut a as &mut dyn HapticDevice, &mut b] {
        dev.read().unwrap();
        dev.write_force(Vec3::X * 0.1).unwrap();
    }
    // Exchanges so far: open's, the first read's keep-alive, the first write. Tick k's write
    // is exchange 3 + k; its reply is read at tick k + 1.
    inv.inject_at(3 + 100, Fault::Garbage);
    board.inject_at(3 + 100, Fault::Garbage);
    let before = allocations();
    for _ in 0..300 {
        for dev in [&mut a as &mut dyn HapticDevice, &mut b] {
            let _ = dev.read();
            let _ = dev.write_force(Vec3::new(0.2, -0.1, 0.05));
        }
    }
    assert_eq!(allocations() - before, 0, "allocations on the haptic path");
    assert_eq!(
        a.counters().read_faults,
        199,
        "the Inverse3 fault is terminal"
    );
    assert_eq!(b.counters().read_faults, 1, "the 2DIY realigns");
}
