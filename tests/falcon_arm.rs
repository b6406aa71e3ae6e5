//! The Novint Falcon sculpting through the whole engine: the lockstep engine drives the
//! Falcon driver over the Novint firmware's framing on a pseudo-terminal, against a stand-in
//! that answers each command frame with one status frame, its encoders placed by the shared
//! push script's hand (one position per command, so the run depends on the commands and never
//! on time). It passes the simulated arm's checks: zero force at connect, force within the
//! arm's bound, zero force on a fault (a stray byte on the line) and the soft start after it,
//! then, tick by tick, the force of the same session run without the stray byte; a disconnect
//! in the middle of the stroke (the terminal hangs up) that keeps the engine ticking and keeps
//! the groove made before it; and the frames the stand-in received show one command per tick,
//! zero until the first force and on the fault.

#[path = "support/arm_session.rs"]
mod arm_session;
mod common;
#[path = "../devices/tests/support/falcon_standin.rs"]
mod falcon_standin;

use std::time::Duration;

use arm_session::{DISCONNECT_AT, FAULT_AT, Session, TICKS};
use dynaclay_devices::falcon::{Falcon, FalconOptions, SampleClock};
use dynaclay_devices::record::{Record, Recording};
use dynaclay_devices::serial_link::BaudPolicy;
use dynaclay_devices::{DeviceInfo, DeviceState, HapticDevice};
use falcon_standin::{FalconFaults, FalconLog, falcon_board};
use glam::Vec3;

/// Each wait of the driver (a reply, the handshake, homing) lasts this long at most: long
/// enough never to be late on a loaded machine, so every tick reads the answer to the
/// previous tick's command.
const PATIENT: Duration = Duration::from_secs(5);

/// Exchanges of `open` before the first tick: the firmware check, one homing command (the
/// stand-in homes at once), the green LED. Tick 0's read then sends a keep-alive (exchange 3)
/// and every tick t writes exchange t + 4, whose reply tick t + 1 reads: tick t reads the
/// reply to exchange t + 3.
const OPEN_EXCHANGES: u64 = 3;

fn options(sysfs: &std::path::Path) -> FalconOptions {
    FalconOptions {
        baud_policy: BaudPolicy::Tolerant,
        homing_timeout: PATIENT,
        handshake_timeout: PATIENT,
        reply_wait: PATIENT,
        stale_after: PATIENT,
        // A pseudo-terminal has no FTDI latency timer; the driver says why not and goes on.
        usb_serial_sysfs: sysfs.to_path_buf(),
        // The lockstep run's clock: the stand-in's one reply per command, 1 ms apart (on the
        // host's clock the soft start and the velocities would follow this machine's speed).
        sample_clock: SampleClock::LOCKSTEP_1KHZ,
        ..FalconOptions::default()
    }
}

/// A Falcon session in lockstep on a fresh stand-in that hangs up at tick [`DISCONNECT_AT`]'s
/// exchange; with `stray_byte`, a stray byte also comes before tick [`FAULT_AT`]'s reply (the
/// one failed read). Hands back what the stand-in received as well.
fn falcon_session(sysfs: &std::path::Path, stray_byte: bool) -> (DeviceInfo, Session, FalconLog) {
    let info = Falcon::new("unopened", options(sysfs)).info();
    let mut board = None;
    let s = arm_session::sculpt(
        &info,
        |hand| {
            let b = falcon_board(
                hand,
                FalconFaults {
                    stray_byte_at: stray_byte.then_some(FAULT_AT + OPEN_EXCHANGES),
                    hang_up_at: Some(DISCONNECT_AT + OPEN_EXCHANGES),
                },
            );
            let arm = Falcon::new(&b.path, options(sysfs));
            board = Some(b);
            Box::new(arm)
        },
        |_| {},
    );
    let log = board.expect("the stand-in ran").log();
    (info, s, log)
}

#[test]
fn a_falcon_sculpts_in_lockstep_through_its_framing_and_a_disconnect_keeps_the_sculpt() {
    let sysfs = tempfile::tempdir().unwrap();
    // The same session without the stray byte: what the press feels like unbroken.
    let (_, unbroken, _) = falcon_session(sysfs.path(), false);
    let (info, s, log) = falcon_session(sysfs.path(), true);
    arm_session::check_session("falcon", &info, &s);
    // The samples are stamped by reply count, so the run depends on the exchanges alone: up to
    // the stray byte the two sessions are the same bit for bit, and their clocks agree on every
    // tick but the failed read's (which reports the sample before it).
    let before_fault = FAULT_AT as usize;
    assert_eq!(
        s.sent_per_tick[..before_fault],
        unbroken.sent_per_tick[..before_fault]
    );
    let clocks_differ: Vec<usize> = (0..TICKS as usize)
        .filter(|t| s.device_time_us[*t] != unbroken.device_time_us[*t])
        .collect();
    assert_eq!(clocks_differ, [before_fault]);

    // At the arm: open's three frames (one of them homing), tick 0's keep-alive, then one
    // command per tick until the terminal hung up on tick DISCONNECT_AT - 1's.
    let open = OPEN_EXCHANGES as usize;
    assert_eq!(
        log.motor_commands.len() as u64,
        OPEN_EXCHANGES + 1 + DISCONNECT_AT
    );
    let homing: Vec<usize> = (0..log.homing.len()).filter(|i| log.homing[*i]).collect();
    assert_eq!(homing, [1], "one homing command, in open");
    // Zero force at connect: nothing but zero until the engine's first write, tick 0's.
    assert!(
        log.motor_commands[..=open].iter().all(|m| *m == [0; 3]),
        "{:?}",
        &log.motor_commands[..=open]
    );
    // Tick t's command is frame t + 4: zero whenever the engine sent zero (the fault's tick
    // among them), and the push reached the motors.
    for (t, sent) in s
        .sent_per_tick
        .iter()
        .take(DISCONNECT_AT as usize)
        .enumerate()
    {
        if *sent == Vec3::ZERO {
            assert_eq!(log.motor_commands[t + open + 1], [0; 3], "tick {t}");
        }
    }
    assert_eq!(s.sent_per_tick[FAULT_AT as usize], Vec3::ZERO);
    assert!(
        log.motor_commands.iter().any(|m| *m != [0; 3]),
        "the push reached the motors"
    );
    assert_eq!(s.sent_per_tick.len() as u64, TICKS);
}

#[test]
fn the_doctor_opens_a_falcon_on_its_stand_in_homes_it_and_sends_nothing_but_zero() {
    // The hand held at the workspace's centre, whatever the exchange.
    let center = Falcon::new("unopened", FalconOptions::default())
        .info()
        .workspace_center_m();
    let board = falcon_board(Box::new(move |_| center), FalconFaults::default());
    // The command as a user runs it: the driver's default options (strict baud changes,
    // default waits), no firmware file (the stand-in's firmware answers at once).
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_dynaclay"))
        .args([
            "devices",
            "--doctor",
            &format!("falcon:{}", board.path),
            "--seconds",
            "0.2",
        ])
        .env_remove("DYNACLAY_FALCON_FIRMWARE")
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{text}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // Whatever rate this machine reached, the report gives the period percentiles, the
    // latency timer's fate (a pseudo-terminal has none) and a clean link.
    for field in [
        "zero force every tick",
        "read rate:",
        "fresh-sample rate:",
        "p99",
        "verdict:",
        "FTDI latency timer: not set",
        "is not a USB-serial port",
        "0 malformed, 0 stray bytes, firmware uploads 0",
    ] {
        assert!(text.contains(field), "{field} missing from {text}");
    }
    // At the arm: homing in open (as many homing frames as the replies took, on a loaded
    // machine), then the loop's frames; zero on every motor in every frame.
    let log = board.log();
    let last_homing = log.homing.iter().rposition(|h| *h).expect("homed in open");
    assert!(log.motor_commands.len() > last_homing + 2, "{log:?}");
    assert!(log.motor_commands.iter().all(|m| *m == [0; 3]), "{log:?}");
}

/// After the soft start that follows the stray byte, the Falcon should feel what the same
/// session without it feels (the check the Touch and the omega.3 pass).
/// (The passivity observer keeps its energy account through the one-tick fault: emptied, the
/// encoders' whole-count steps would tip it below zero and a damper would push sideways.)
#[test]
fn after_a_stray_byte_a_falcon_feels_what_the_unbroken_session_feels() {
    let sysfs = tempfile::tempdir().unwrap();
    let (_, unbroken, _) = falcon_session(sysfs.path(), false);
    let (_, s, _) = falcon_session(sysfs.path(), true);
    arm_session::check_return_after_fault("falcon", &s, &unbroken);
}

/// Runs `dynaclay run --lockstep --record` for [`TICKS`] samples of the pressing script with a
/// Falcon on a fresh stand-in playing the script's hand, as a user runs it (the driver's
/// default options, no firmware file); returns what it printed, its recording and the
/// stand-in's timing ([`standin_timing`]).
fn lockstep_run_through_the_cli(dir: &std::path::Path, name: &str) -> (String, Recording, String) {
    let script = dir.join("press.toml");
    std::fs::write(&script, arm_session::script_text()).unwrap();
    let info = Falcon::new("unopened", FalconOptions::default()).info();
    let board = falcon_board(arm_session::script_hand(&info), FalconFaults::default());
    let recording = dir.join(format!("{name}.rec"));
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_dynaclay"))
        .args(["run", "--lockstep", "--no-rt", "--seconds"])
        .arg(format!("{}", TICKS as f64 * 1e-3))
        .arg("--script")
        .arg(&script)
        .args(["--device", &format!("falcon:{}", board.path), "--record"])
        .arg(&recording)
        .arg("--out")
        .arg(dir.join(name))
        .env_remove("DYNACLAY_FALCON_FIRMWARE")
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "{name}: exit {:?}\n{stdout}\n{}",
        out.status.code(),
        String::from_utf8_lossy(&out.stderr)
    );
    let recording = Recording::parse(&std::fs::read(&recording).unwrap()).unwrap();
    assert_eq!(recording.dropped, 0, "{name}: the recording is whole");
    (stdout, recording, standin_timing(&board.log()))
}

/// What the stand-in saw of a run, for a failure message: the commands it decoded, the replies
/// the terminal refused, and each pause of over 200 ms between two commands (exchange, the
/// pause, then how much of it the stand-in took to reply and how much passed from its reply
/// to the next command), in milliseconds.
fn standin_timing(log: &FalconLog) -> String {
    let pauses: Vec<(usize, u128, u128, u128)> = log
        .decoded_at
        .windows(2)
        .zip(&log.replied_at)
        .enumerate()
        .map(|(i, (w, replied))| {
            (
                i + 1,
                (w[1] - w[0]).as_millis(),
                (*replied - w[0]).as_millis(),
                (w[1] - *replied).as_millis(),
            )
        })
        .filter(|(_, pause_ms, _, _)| *pause_ms > 200)
        .collect();
    format!(
        "stand-in: {} commands decoded, replies refused {:?}, pauses (exchange, ms, to reply, \
         reply to next command) {pauses:?}",
        log.motor_commands.len(),
        log.reply_write_errors
    )
}

/// `dynaclay run --lockstep` takes a Falcon: its samples are stamped by reply count, one
/// millisecond apart, so two runs of the same script against the same stand-in are the same
/// exchange for exchange: every sample read, every force sent and the clay they leave, bit for
/// bit (on the host's clock the soft start and the velocities would follow the machine's
/// speed). The press reached the motors.
#[test]
fn a_lockstep_run_takes_a_falcon_and_runs_the_same_every_time() {
    let dir = tempfile::tempdir().unwrap();
    let (said, first, timing) = lockstep_run_through_the_cli(dir.path(), "first");
    let (_, second, second_timing) = lockstep_run_through_the_cli(dir.path(), "second");
    assert!(
        said.contains(&format!("{TICKS} samples of falcon:")) && said.contains("in lockstep"),
        "{said}"
    );
    let reads: Vec<DeviceState> = first
        .records
        .iter()
        .filter_map(|r| match r {
            Record::Read(Ok(s)) => Some(*s),
            _ => None,
        })
        .collect();
    // One good read per sample (and one for the step that installs the starting session),
    // each the next reply on the device's clock: 1 ms later than the one before.
    // A failed read with the record before it (the write whose reply it waited for).
    let failed: Vec<(usize, &[Record])> = first
        .records
        .windows(2)
        .enumerate()
        .filter(|(_, w)| matches!(w[1], Record::Read(Err(_))))
        .map(|(i, w)| (i + 1, w))
        .collect();
    assert!(
        reads.len() as u64 > TICKS,
        "{} reads; failed reads (record index, the record before and it): {failed:?}; {timing}",
        reads.len()
    );
    for (k, w) in reads.windows(2).enumerate() {
        assert_eq!(w[1].timestamp_us - w[0].timestamp_us, 1000, "read {k}");
    }
    let pressed = first
        .records
        .iter()
        .filter(|r| matches!(r, Record::Write { force_n, .. } if force_n.length() > 0.01))
        .count();
    assert!(pressed > 100, "{pressed} writes pressed");
    assert_eq!(
        first.records, second.records,
        "the two runs differ; first {timing}; second {second_timing}"
    );
    let field = |name: &str| {
        let path = dir.path().join(name).join("session.dclay");
        let session = dynaclay::io::decode(&std::fs::read(&path).unwrap(), &path).unwrap();
        session.clay.density.patches[0]
            .lattice
            .coeffs
            .iter()
            .map(|c| c.to_bits())
            .collect::<Vec<_>>()
    };
    assert_eq!(field("first"), field("second"), "the two sculpts differ");
}

/// The steady-contact rule on a recorded lockstep Falcon session (`dynaclay run --lockstep
/// --record` against the stand-in): while the tool follows the stroke's path, pressed into
/// the clay, no tick changes the force sent to the Falcon by more than 7% of it plus 0.02 N
/// (the fade rule every change of a steady force is held to, as on the simulated arm), and the
/// force never turns to pull the tool into the clay.
#[test]
fn a_recorded_lockstep_falcon_stroke_holds_the_steady_contact_rule() {
    let dir = tempfile::tempdir().unwrap();
    let (_, recording, timing) = lockstep_run_through_the_cli(dir.path(), "steady");
    // Each force sent, with the device time of the sample it was rendered from.
    let mut sent = Vec::new();
    let mut time_us = None;
    for r in &recording.records {
        match r {
            Record::Read(Ok(s)) => time_us = Some(s.timestamp_us),
            Record::Write { force_n, .. } => {
                if let Some(t) = time_us.take() {
                    sent.push((t, *force_n));
                }
            }
            _ => {}
        }
    }
    // The stroke: the hand leaves hover at 0.1 s, reaches the path 0.3 s later and follows it
    // to 1.4 s. Steady contact: from 0.1 s after reaching the path (the descent's passing peak
    // is over) to the end of the run.
    let steady: Vec<Vec3> = sent
        .iter()
        .filter(|(t, _)| (500_000..TICKS * 1000).contains(t))
        .map(|(_, f)| *f)
        .collect();
    assert!(steady.len() > 700, "{} steady ticks", steady.len());
    let weakest = steady.iter().map(|f| f.length()).fold(f32::MAX, f32::min);
    assert!(
        weakest > arm_session::PRESSED_N,
        "{weakest} N: the tool left the clay in steady contact; {timing}"
    );
    let (worst_tick, worst_share) = steady
        .windows(2)
        .map(|w| (w[1] - w[0]).length() / (0.07 * w[0].length() + 0.02))
        .enumerate()
        .fold((0, 0.0_f32), |a, (i, s)| if s > a.1 { (i, s) } else { a });
    let mean = steady.iter().sum::<Vec3>() / steady.len() as f32;
    println!(
        "falcon steady contact: {} ticks, mean {mean} N, weakest {weakest:.4} N, largest step \
         {worst_share:.3} of the rule (tick {worst_tick} of the window)",
        steady.len()
    );
    assert!(
        worst_share <= 1.0,
        "a steady-contact tick changed the force by {worst_share} of 7% of it plus 0.02 N \
         ({} → {} N)",
        steady[worst_tick],
        steady[worst_tick + 1]
    );
    // The press pushes the tool out of the clay (up, +y) throughout.
    let pulls = steady.iter().filter(|f| f.y < -1e-3).count();
    assert_eq!(pulls, 0, "ticks pulling the tool in");
}
