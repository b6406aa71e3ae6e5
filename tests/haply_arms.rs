//! The Haply arms sculpting through the whole engine: the lockstep engine drives an Inverse3
//! (against a local WebSocket server answering as Haply's Inverse Service) and a 2DIY
//! (against a Haply board on a pseudo-terminal) along the shared push script. Each stand-in
//! plays the script's hand, one position per command the driver sends, so the run depends on
//! the commands and never on time. Both pass the simulated arm's checks: zero force at
//! connect, force within the device's bound, a disconnect in the middle of the stroke that
//! zeroes the force, keeps the engine ticking and keeps the sculpt made before it.

// The shared session's script and hand; its lockstep session and checks serve the other arms.
#[allow(dead_code)]
#[path = "support/arm_session.rs"]
mod arm_session;
mod common;
#[path = "../devices/tests/support/haply_standins.rs"]
mod haply_standins;

use std::time::Duration;

use arm_session::{push_plan, push_script, script_hand, script_text};
use dynaclay::engine::{Command, EngineConfig, HeadlessSink, Lockstep, build_clay};
use dynaclay_devices::inverse3::{Inverse3, Inverse3Config};
use dynaclay_devices::record::{Record, Recording};
use dynaclay_devices::two_diy::{SampleClock, TwoDiy, TwoDiyOptions, TwoDiyVersion};
use dynaclay_devices::{DeviceInfo, DeviceState, HapticDevice};
use glam::Vec3;
use haply_standins::{Fault, Hand, Standin};

/// Each read waits this long at most for its reply: long enough never to be late on a loaded
/// machine, so every tick reads the answer to the previous tick's command.
const PATIENT: Duration = Duration::from_secs(5);

/// Ticks of the run (1 ms of script time each) and the exchange whose reply never comes:
/// 0.7 s, in the middle of the stroke (0.1 s to 1.1 s).
const TICKS: u64 = 1300;
const DISCONNECT_AT: u64 = 700;

struct Outcome {
    faulted_ticks: u64,
    forces_at_arm: Vec<Vec3>,
    torques_at_arm: Vec<[f32; 2]>,
    /// Path points 0.05 above the hand's path the tool passed before the disconnect: the
    /// field there at the start, at the disconnect and at the end.
    groove_before_disconnect: Vec<(Vec3, f32, f32, f32)>,
    iso: f32,
    far_change: f32,
}

/// Runs the push script through `device` (made from its stand-in) in lockstep, disconnecting
/// the stand-in at [`DISCONNECT_AT`].
fn sculpt(
    info: &DeviceInfo,
    start: impl FnOnce(Hand) -> Standin,
    device: impl FnOnce(&Standin) -> Box<dyn HapticDevice>,
) -> Outcome {
    let script = push_script();
    let plan = push_plan(&script);
    let field = build_clay(&plan.clay).unwrap();
    let before = field.clone();
    let mut config = EngineConfig::for_field(&field, info);
    config.haptic_rt_priority = None;
    config.safety.soft_start_s = 0.1;
    config.haptics.tool_contact = plan.tool_contact;
    let standin = start(script_hand(info));
    standin.inject_at(DISCONNECT_AT, Fault::Close);
    let mut engine = Lockstep::new(
        &config,
        field,
        device(&standin),
        Box::new(HeadlessSink::default()),
        16,
    )
    .expect("the engine opens the arm");
    // Neither arm has a stroke button here (the Inverse3 without a paired handle): the stroke
    // is armed by command, as the window's stroke key does.
    engine
        .commands()
        .send(Command::StrokeStart)
        .expect("the simulation takes commands");
    let mut faulted_ticks = 0;
    let mut fault_seen = false;
    let mut at_fault = None;
    for tick in 0..TICKS {
        engine.step();
        let t = engine.latest_tool();
        if tick == 0 {
            assert_eq!(t.device_force_n, Vec3::ZERO, "zero force at connect");
        }
        assert!(
            t.device_force_n.length() <= info.max_force_n + 1e-4,
            "tick {tick}: {} N over the arm's {} N",
            t.device_force_n.length(),
            info.max_force_n
        );
        if t.device_fault {
            if !fault_seen {
                at_fault = Some(engine.field().clone());
            }
            fault_seen = true;
            faulted_ticks += 1;
            assert_eq!(
                t.device_force_n,
                Vec3::ZERO,
                "tick {tick}: force during the fault"
            );
            assert!(!t.in_contact, "tick {tick}");
        } else {
            assert!(!fault_seen, "tick {tick}: a disconnected arm came back");
        }
    }
    assert_eq!(engine.ticks(), TICKS, "the engine kept ticking");
    let report = engine.finish().expect("the run ends with its session");
    assert!(
        report.counters.device_read_faults > 0,
        "{:?}",
        report.counters
    );
    let after = &report.session.clay.density.patches[0].lattice;
    let at_fault: dynaclay::field::BSplineLattice = at_fault.expect("the disconnect was seen");
    assert!(
        after.coeffs.iter().all(|c| c.is_finite()),
        "NaN in the field"
    );
    // The groove along the part of the path the hand took well before the link went: the
    // stroke runs from 0.1 s to 1.1 s, so at 0.7 s the hand was 0.6 along it (x = 0.99);
    // the points up to x = 0.9 are behind the tool.
    let path = common::path_points(&script);
    let done = path
        .iter()
        .take(4)
        .skip(1)
        .map(|p| {
            let p = *p + Vec3::Y * 0.05;
            (p, before.value(p), at_fault.value(p), after.value(p))
        })
        .collect();
    let far = Vec3::new(0.95, 0.6, 0.95);
    let log = standin.log();
    Outcome {
        faulted_ticks,
        forces_at_arm: log.forces_n,
        torques_at_arm: log.torques_n_m,
        groove_before_disconnect: done,
        iso: before.iso,
        far_change: (after.value(far) - before.value(far)).abs(),
    }
}

fn check_sculpt_kept(name: &str, o: &Outcome) {
    // Exchange 0 is open's zero force, exchange 1 the first read's keep-alive, and tick t's
    // command exchange t + 2: the reply that never came was tick DISCONNECT_AT - 2's, which
    // tick DISCONNECT_AT - 1 reads; from there on every tick saw the fault.
    assert_eq!(o.faulted_ticks, TICKS - (DISCONNECT_AT - 1), "{name}");
    for (p, was, at_fault, at_end) in &o.groove_before_disconnect {
        assert!(*was > o.iso, "{name}: clay was there at {p}");
        // The press took the field down by a good part of its margin over the iso-level...
        assert!(
            was - at_fault > 0.25 * (was - o.iso),
            "{name}: no groove at {p} by the disconnect: {was} → {at_fault}"
        );
        // ...and what the disconnect found is what the session kept (the clay settles a
        // little once the tool has gone, never back up toward the untouched block).
        assert!(
            (at_end - at_fault).abs() < 0.05 && *at_end < was - 0.25 * (was - o.iso),
            "{name}: the groove at {p} was not kept: {at_fault} at the disconnect, {at_end} at the end"
        );
    }
    assert!(
        o.far_change < 1e-3,
        "{name}: changed far away ({})",
        o.far_change
    );
}

#[test]
fn an_inverse3_sculpts_in_lockstep_and_a_disconnect_mid_stroke_keeps_the_sculpt() {
    let info = Inverse3::published_info();
    let o = sculpt(&info, haply_standins::inverse3_service, |s| {
        Box::new(Inverse3::new(Inverse3Config {
            url: s.address.clone(),
            connect_timeout: PATIENT,
            reply_timeout: PATIENT,
            reply_wait: PATIENT,
            ..Inverse3Config::default()
        }))
    });
    check_sculpt_kept("inverse3", &o);
    // At the arm: zero at connect, one command per tick until the link went, never over 4 N.
    assert_eq!(o.forces_at_arm[0], Vec3::ZERO);
    assert_eq!(o.forces_at_arm.len() as u64, DISCONNECT_AT + 1);
    assert!(
        o.forces_at_arm.iter().any(|f| f.length() > 0.5),
        "the push was felt"
    );
    assert!(o.forces_at_arm.iter().all(|f| f.length() <= 4.0 + 1e-4));
}

#[test]
fn a_two_diy_sculpts_its_plane_in_lockstep_and_a_disconnect_mid_stroke_keeps_the_sculpt() {
    let version = TwoDiyVersion::V3;
    let info = TwoDiy::info_for(version);
    let o = sculpt(
        &info,
        |hand| haply_standins::two_diy_board(version, hand),
        |s| {
            Box::new(TwoDiy::new(
                &s.address,
                TwoDiyOptions {
                    version,
                    handshake_timeout: PATIENT,
                    reply_wait: PATIENT,
                    stale_after: PATIENT,
                    // Lockstep's clock: one reply per tick, 1 ms apart.
                    sample_clock: SampleClock::LOCKSTEP_1KHZ,
                    ..TwoDiyOptions::default()
                },
            ))
        },
    );
    check_sculpt_kept("2diy", &o);
    assert_eq!(o.torques_at_arm[0], [0.0, 0.0], "zero torques at connect");
    assert_eq!(o.torques_at_arm.len() as u64, DISCONNECT_AT + 1);
    assert!(
        o.torques_at_arm.iter().any(|t| t[0] != 0.0 || t[1] != 0.0),
        "the push reached the motors"
    );
}

/// `dynaclay run` with each Haply arm on the command line, in real time against its stand-in
/// (the hand resting in the middle of the workspace): the run opens the arm through its spec,
/// says which device it drove and writes the session. Nothing about rates is asserted.
#[test]
fn a_headless_run_drives_each_haply_arm_through_its_spec() {
    let inverse3 = haply_standins::inverse3_service(Box::new(|_| {
        Inverse3::published_info().workspace_center_m()
    }));
    let version = TwoDiyVersion::V3;
    let board = haply_standins::two_diy_board(
        version,
        Box::new(move |_| TwoDiy::info_for(version).workspace_center_m()),
    );
    for spec in [
        format!("inverse3:{}", inverse3.address),
        format!("2diy:{}", board.address),
    ] {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("out");
        let run = std::process::Command::new(env!("CARGO_BIN_EXE_dynaclay"))
            .args([
                "run",
                "--seconds",
                "0.3",
                "--no-rt",
                "--device",
                &spec,
                "--out",
            ])
            .arg(&out)
            .output()
            .unwrap();
        let stdout = String::from_utf8_lossy(&run.stdout);
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert!(
            run.status.success(),
            "{spec}: exit {:?}\nstdout: {stdout}\nstderr: {stderr}",
            run.status.code()
        );
        assert!(
            stdout.contains(&format!("device {spec}")),
            "{spec}: {stdout}"
        );
        assert!(out.join("session.dclay").is_file(), "{spec}: no session");
    }
    // Each arm was opened with zero force and sent commands all through the run.
    assert_eq!(inverse3.log().forces_n[0], Vec3::ZERO);
    assert!(inverse3.exchanges() > 10, "{}", inverse3.exchanges());
    assert_eq!(board.log().torques_n_m[0], [0.0, 0.0]);
    assert!(board.exchanges() > 10, "{}", board.exchanges());
}

/// `dynaclay run --lockstep --record` for [`TICKS`] samples of the pressing script with a 2DIY
/// on a fresh board stand-in playing the script's hand, as a user runs it; returns its
/// recording.
fn two_diy_lockstep_run(dir: &std::path::Path, name: &str) -> Recording {
    let script = dir.join("press.toml");
    std::fs::write(&script, script_text()).unwrap();
    let version = TwoDiyVersion::V3;
    let board = haply_standins::two_diy_board(version, script_hand(&TwoDiy::info_for(version)));
    let recording = dir.join(format!("{name}.rec"));
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_dynaclay"))
        .args(["run", "--lockstep", "--no-rt", "--seconds"])
        .arg(format!("{}", TICKS as f64 * 1e-3))
        .arg("--script")
        .arg(&script)
        .args(["--device", &format!("2diy:{}", board.address), "--record"])
        .arg(&recording)
        .arg("--out")
        .arg(dir.join(name))
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{name}: exit {:?}\n{stdout}\n{}",
        out.status.code(),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        stdout.contains(&format!("{TICKS} samples of 2diy:")),
        "{name}: {stdout}"
    );
    let recording = Recording::parse(&std::fs::read(&recording).unwrap()).unwrap();
    assert_eq!(recording.dropped, 0, "{name}: the recording is whole");
    recording
}

/// `dynaclay run --lockstep` takes a 2DIY: its samples are stamped by reply count, 1 ms
/// apart, so two runs of the same script against the same stand-in read the same samples and
/// send the same forces, bit for bit (on the host's clock the soft start and the velocities
/// would follow the machine's speed). The press reached the arm.
#[test]
fn a_lockstep_run_takes_a_two_diy_and_runs_the_same_every_time() {
    let dir = tempfile::tempdir().unwrap();
    let first = two_diy_lockstep_run(dir.path(), "first");
    let second = two_diy_lockstep_run(dir.path(), "second");
    let reads: Vec<DeviceState> = first
        .records
        .iter()
        .filter_map(|r| match r {
            Record::Read(Ok(s)) => Some(*s),
            _ => None,
        })
        .collect();
    assert!(reads.len() as u64 > TICKS, "{} reads", reads.len());
    for (k, w) in reads.windows(2).enumerate() {
        assert_eq!(w[1].timestamp_us - w[0].timestamp_us, 1000, "read {k}");
    }
    let pressed = first
        .records
        .iter()
        .filter(|r| matches!(r, Record::Write { force_n, .. } if force_n.length() > 0.01))
        .count();
    assert!(pressed > 100, "{pressed} writes pressed");
    assert_eq!(first.records, second.records, "the two runs differ");
}
