//! Serial drivers end to end over real pseudo-terminal pairs, with simulated firmware threads.
//!
//! Each test creates a PTY pair, runs a firmware simulation on the master side and points the
//! driver at the slave's path, exactly as it would open `/dev/ttyUSB0`. A PTY has no line rate,
//! so the drivers run with `BaudPolicy::Tolerant` (a refused baud change is noted, not fatal);
//! the bootloader's byte sequence is otherwise the real one.

use std::io::{Read, Write};
use std::sync::atomic::{AtomicBool, AtomicU8, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use dynaclay_devices::codec::falcon::{self as fc, FalconStatus};
use dynaclay_devices::codec::frame::{
    self, DeviceMsg, FrameEvent, FrameReader, HostMsg, MAX_FRAME,
};
use dynaclay_devices::delta::Delta;
use dynaclay_devices::falcon::{BOOT_HELLO, Falcon, FalconOptions};
use dynaclay_devices::kinematics::JointMap;
use dynaclay_devices::profile::DeviceProfile;
use dynaclay_devices::serial_arm::{SerialArm, SerialArmOptions};
use dynaclay_devices::serial_link::BaudPolicy;
use dynaclay_devices::{DeviceError, HapticDevice, SafetyConfig, SafetyFilter};
use glam::{DVec3, Vec3};
use serialport::{SerialPort, TTYPort};

/// Fault to inject on the firmware's next reply.
mod fault {
    pub const NONE: u8 = 0;
    pub const GARBAGE: u8 = 1;
    pub const BAD_FRAME: u8 = 2;
    pub const SHORT_FRAME: u8 = 3;
    pub const CLOSE: u8 = 4;
}

struct Sim {
    path: String,
    fault: Arc<AtomicU8>,
    stop: Arc<AtomicBool>,
    commands: Arc<AtomicU64>,
    /// Commands with the homing-mode bit set (Falcon).
    homing_commands: Arc<AtomicU64>,
    /// Commands with any motor command other than zero (Falcon).
    nonzero_commands: Arc<AtomicU64>,
    last_force: Arc<Mutex<[i16; 3]>>,
    handle: Option<JoinHandle<()>>,
}

impl Sim {
    fn inject(&self, f: u8) {
        self.fault.store(f, Ordering::SeqCst);
    }
    fn last_force(&self) -> [i16; 3] {
        *self.last_force.lock().unwrap()
    }
}

impl Drop for Sim {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(h) = self.handle.take() {
            let _ = h.join();
        }
    }
}

fn pty() -> (TTYPort, String) {
    let (mut master, slave) = TTYPort::pair().expect("pseudo-terminal pair");
    let path = slave.name().expect("slave path");
    drop(slave); // the driver opens the node itself
    master.set_timeout(Duration::from_millis(1)).unwrap();
    (master, path)
}

fn read_some(master: &mut TTYPort, buf: &mut [u8]) -> usize {
    master.read(buf).unwrap_or(0)
}

/// Where the simulated tool is at time `t`: a 1 cm circle around the Falcon's home.
fn falcon_position(home: DVec3, t: f64) -> DVec3 {
    home + DVec3::new(
        0.01 * (2.0 * t).sin(),
        0.01 * (2.0 * t).cos(),
        0.005 * t.sin(),
    )
}

/// The bootloader's answer to the handshake as most hosts see it.
const HELLO_REPLY: &[u8] = &[0x0a, 0x44, 0x2c, 0x0d];
/// The same answer after a `00`, as libnifalcon sees it through libftdi.
const HELLO_REPLY_AFTER_ZERO: &[u8] = &[0x00, 0x0a, 0x44, 0x2c, 0x0d];

/// A simulated Falcon: stuck in the bootloader until `firmware_len` bytes are uploaded (0: its
/// firmware already runs), then answering each command frame with one reply. Homing follows
/// libnifalcon's reading of the Novint firmware: the command's byte 13 bit 0 asks for homing,
/// and the reply's byte 13 (minus 0x41) carries the homed flags of motors 1, 2, 3 in bits 4,
/// 5, 6; motor i+1 reports homed after `homing_ticks × (i+1) / 3` homing commands.
fn spawn_falcon(firmware_len: usize, homing_ticks: u32) -> Sim {
    spawn_falcon_answering(firmware_len, homing_ticks, HELLO_REPLY)
}

fn spawn_falcon_answering(
    firmware_len: usize,
    homing_ticks: u32,
    hello_reply: &'static [u8],
) -> Sim {
    let (mut master, path) = pty();
    let profile = DeviceProfile::built_in("falcon").unwrap();
    let delta = Delta::from_geometry(&profile.geometry).unwrap();
    let joints = JointMap {
        motors: profile.motors.unwrap(),
    };
    let fault = Arc::new(AtomicU8::new(0));
    let stop = Arc::new(AtomicBool::new(false));
    let commands = Arc::new(AtomicU64::new(0));
    let homing_commands = Arc::new(AtomicU64::new(0));
    let nonzero_commands = Arc::new(AtomicU64::new(0));
    let last_force = Arc::new(Mutex::new([0i16; 3]));
    let (f2, s2, c2, l2, h2, n2) = (
        fault.clone(),
        stop.clone(),
        commands.clone(),
        last_force.clone(),
        homing_commands.clone(),
        nonzero_commands.clone(),
    );
    let handle = std::thread::spawn(move || {
        #[derive(PartialEq)]
        enum Stage {
            Boot,
            Start,
            Upload(usize),
            Running,
        }
        let mut stage = if firmware_len == 0 {
            Stage::Running
        } else {
            Stage::Boot
        };
        let mut window: Vec<u8> = Vec::new();
        let mut homed = 0u8;
        let mut homing_seen = 0u32;
        let t0 = Instant::now();
        let mut buf = [0u8; 256];
        while !s2.load(Ordering::SeqCst) {
            let n = read_some(&mut master, &mut buf);
            for &b in &buf[..n] {
                match stage {
                    Stage::Boot => {
                        window.push(b);
                        if window.ends_with(&BOOT_HELLO) {
                            let _ = master.write_all(hello_reply);
                            stage = Stage::Start;
                            window.clear();
                        }
                    }
                    Stage::Start => {
                        if b == b'A' {
                            let _ = master.write_all(b"A");
                            stage = Stage::Upload(0);
                        }
                    }
                    Stage::Upload(k) => {
                        let _ = master.write_all(&[b]); // the bootloader echoes every byte
                        stage = if k + 1 == firmware_len {
                            Stage::Running
                        } else {
                            Stage::Upload(k + 1)
                        };
                    }
                    Stage::Running => {
                        if b == fc::START {
                            window.clear();
                        }
                        window.push(b);
                        if window.len() < fc::FRAME_LEN {
                            continue;
                        }
                        let Ok(cmd) = fc::decode_command(&window) else {
                            window.clear();
                            continue;
                        };
                        // The homing-mode bit, read from the raw byte.
                        let homing_bit = (window[13] - 0x41) & 0x1 != 0;
                        assert_eq!(homing_bit, cmd.homing);
                        window.clear();
                        c2.fetch_add(1, Ordering::SeqCst);
                        *l2.lock().unwrap() = cmd.motor;
                        if cmd.motor != [0; 3] {
                            n2.fetch_add(1, Ordering::SeqCst);
                        }
                        if homing_bit {
                            homing_seen += 1;
                            h2.fetch_add(1, Ordering::SeqCst);
                            for motor in 0..3u32 {
                                if homing_seen * 3 >= homing_ticks * (motor + 1) {
                                    homed |= 1 << motor;
                                }
                            }
                        }
                        let p = falcon_position(delta.home_guess_m, t0.elapsed().as_secs_f64());
                        let q = delta.inverse(p).unwrap();
                        let counts = joints.counts(q).map(|c| c.round() as i16);
                        let mut frame = fc::encode_status(&FalconStatus {
                            encoders: counts,
                            buttons: 0,
                            homed: 0,
                        });
                        // Homed flags in bits 4..6 of byte 13, written by hand (not through
                        // the codec under test); byte 14 is not read, so fill it with noise.
                        frame[13] = 0x41 + (homed << 4);
                        frame[14] = b'~';
                        match f2.swap(fault::NONE, Ordering::SeqCst) {
                            fault::GARBAGE => {
                                let _ = master.write_all(b"\x00\xffnoise");
                                let _ = master.write_all(&frame);
                            }
                            fault::BAD_FRAME => {
                                let mut bad = frame;
                                bad[6] = b'z';
                                let _ = master.write_all(&bad);
                            }
                            fault::SHORT_FRAME => {
                                let _ = master.write_all(&frame[..7]);
                                let _ = master.write_all(&frame);
                            }
                            fault::CLOSE => return, // drops the master: the peer hangs up
                            _ => {
                                let _ = master.write_all(&frame);
                            }
                        }
                    }
                }
            }
        }
    });
    Sim {
        path,
        fault,
        stop,
        commands,
        homing_commands,
        nonzero_commands,
        last_force,
        handle: Some(handle),
    }
}

fn cartesian_position_um(t: f64) -> [i32; 3] {
    [
        (20_000.0 * t.sin()) as i32,
        (10_000.0 * t.cos()) as i32,
        -5_000,
    ]
}

fn spawn_cartesian(home_after: Duration) -> Sim {
    let (mut master, path) = pty();
    let fault = Arc::new(AtomicU8::new(0));
    let stop = Arc::new(AtomicBool::new(false));
    let commands = Arc::new(AtomicU64::new(0));
    let last_force = Arc::new(Mutex::new([0i16; 3]));
    let (f2, s2, c2, l2) = (
        fault.clone(),
        stop.clone(),
        commands.clone(),
        last_force.clone(),
    );
    let handle = std::thread::spawn(move || {
        let mut reader = FrameReader::new();
        let mut buf = [0u8; 256];
        let mut out = [0u8; MAX_FRAME];
        let mut homed = false;
        let mut home_at: Option<Instant> = None;
        let t0 = Instant::now();
        while !s2.load(Ordering::SeqCst) {
            if let Some(at) = home_at
                && at.elapsed() >= home_after
            {
                homed = true;
                home_at = None;
                let n = DeviceMsg::HomeDone { ok: true }.encode(&mut out).unwrap();
                let _ = master.write_all(&out[..n]);
            }
            let n = read_some(&mut master, &mut buf);
            for &b in &buf[..n] {
                let mut ev = Some(reader.push(b));
                while let Some(e) = ev {
                    if let FrameEvent::Frame { kind, .. } = e {
                        match HostMsg::decode(kind, reader.payload()) {
                            Ok(HostMsg::Hello { .. }) => {
                                let m = DeviceMsg::HelloAck {
                                    version: frame::VERSION,
                                    max_force_mn: 4000,
                                    workspace_radius_um: 100_000,
                                };
                                let n = m.encode(&mut out).unwrap();
                                let _ = master.write_all(&out[..n]);
                            }
                            Ok(HostMsg::Home) => home_at = Some(Instant::now()),
                            Ok(HostMsg::Force { force_mn, seq }) => {
                                c2.fetch_add(1, Ordering::SeqCst);
                                *l2.lock().unwrap() = force_mn;
                                let status = if homed {
                                    frame::status::HOMED | frame::status::MOTORS_ON
                                } else {
                                    0
                                };
                                let m = DeviceMsg::State {
                                    position_um: cartesian_position_um(t0.elapsed().as_secs_f64()),
                                    buttons: 1,
                                    seq,
                                    status,
                                };
                                let n = m.encode(&mut out).unwrap();
                                match f2.swap(fault::NONE, Ordering::SeqCst) {
                                    fault::GARBAGE => {
                                        let _ = master.write_all(b"\x00\x13garbage");
                                        let _ = master.write_all(&out[..n]);
                                    }
                                    fault::BAD_FRAME => {
                                        out[n - 1] ^= 0x5a; // corrupt the CRC
                                        let _ = master.write_all(&out[..n]);
                                    }
                                    fault::SHORT_FRAME => {
                                        let _ = master.write_all(&out[..5]);
                                        let _ = master.write_all(&out[..n]);
                                    }
                                    fault::CLOSE => return,
                                    _ => {
                                        let _ = master.write_all(&out[..n]);
                                    }
                                }
                            }
                            Err(_) => {}
                        }
                    }
                    ev = reader.drain();
                }
            }
        }
    });
    Sim {
        path,
        fault,
        stop,
        commands,
        homing_commands: Arc::new(AtomicU64::new(0)),
        nonzero_commands: Arc::new(AtomicU64::new(0)),
        last_force,
        handle: Some(handle),
    }
}

fn falcon_opts(firmware: Option<std::path::PathBuf>) -> FalconOptions {
    FalconOptions {
        firmware,
        baud_policy: BaudPolicy::Tolerant,
        homing_timeout: Duration::from_secs(5),
        handshake_timeout: Duration::from_millis(300),
        reply_wait: Duration::from_millis(3),
        stale_after: Duration::from_millis(500),
        ..FalconOptions::default()
    }
}

fn serial_opts() -> SerialArmOptions {
    SerialArmOptions {
        homing_timeout: Duration::from_secs(5),
        reply_wait: Duration::from_millis(3),
        stale_after: Duration::from_millis(500),
        ..SerialArmOptions::default()
    }
}

/// The longest a test waits for a condition before calling it failed. Only a failure waits
/// this long; a passing test moves on as soon as the condition holds, so no rate or schedule
/// is assumed.
const GIVE_UP: Duration = Duration::from_secs(30);

/// Waits until `cond` holds (giving up after [`GIVE_UP`]); returns whether it did.
fn eventually(mut cond: impl FnMut() -> bool) -> bool {
    let start = Instant::now();
    while start.elapsed() < GIVE_UP {
        if cond() {
            return true;
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    cond()
}

fn safety() -> SafetyConfig {
    SafetyConfig {
        soft_start_s: 0.0,
        slew_rate_n_per_s: 1.0e6,
        ..SafetyConfig::default()
    }
}

/// Runs the device at 1 kHz for `ticks` ticks with a constant requested force; returns
/// (fresh samples, errors, last state).
fn stream<D: HapticDevice>(
    dev: &mut D,
    ticks: u32,
    force: Vec3,
) -> (u32, u32, dynaclay_devices::DeviceState) {
    let mut fresh = 0;
    let mut errors = 0;
    let mut last_seq = 0;
    let mut last = dynaclay_devices::DeviceState::ZERO;
    let start = Instant::now();
    for k in 0..ticks {
        let deadline = start + Duration::from_micros(1000 * u64::from(k + 1));
        match dev.read() {
            Ok(s) => {
                if s.sequence > last_seq {
                    fresh += 1;
                    last_seq = s.sequence;
                }
                last = s;
            }
            Err(_) => errors += 1,
        }
        let _ = dev.write_force(force);
        while Instant::now() < deadline {
            std::hint::spin_loop();
        }
    }
    (fresh, errors, last)
}

/// Streams until `want` fresh samples arrive (giving up after [`GIVE_UP`]); returns (fresh,
/// errors).
fn stream_until<D: HapticDevice>(dev: &mut D, want: u32, force: Vec3) -> (u32, u32) {
    let (mut fresh, mut errors) = (0, 0);
    let start = Instant::now();
    while fresh < want && start.elapsed() < GIVE_UP {
        let (f, e, _) = stream(dev, 10, force);
        fresh += f;
        errors += e;
    }
    (fresh, errors)
}

#[test]
fn falcon_loads_firmware_homes_and_streams_at_1khz() {
    let image: Vec<u8> = (0..1000u32).map(|i| (i * 7 + 3) as u8).collect();
    let dir = tempfile::tempdir().unwrap();
    let fw = dir.path().join("falcon_firmware.bin");
    std::fs::write(&fw, &image).unwrap();
    let sim = spawn_falcon(image.len(), 30);
    let mut dev =
        SafetyFilter::with_config(Falcon::new(&sim.path, falcon_opts(Some(fw))), safety());
    dev.open().expect("open: firmware upload and homing");
    assert!(dev.device().status().all_homed());
    assert_eq!(dev.device().link_stats().firmware_attempts, 1);

    let (fresh, errors, last) = stream(&mut dev, 1200, Vec3::new(0.0, 0.0, 1.0));
    // However loaded the machine, the link keeps delivering fresh samples (how many arrive
    // within each tick is measured in bench/, not here).
    let (more, more_errors) = stream_until(
        &mut dev,
        600u32.saturating_sub(fresh),
        Vec3::new(0.0, 0.0, 1.0),
    );
    assert_eq!(more_errors, 0, "no faults on a clean link");
    assert_eq!(errors, 0, "no faults on a clean link");
    // Every tick's command reaches the firmware.
    assert!(
        eventually(|| sim.commands.load(Ordering::SeqCst) >= 1200),
        "one command per tick"
    );
    assert!(
        fresh + more >= 600,
        "fresh samples: {fresh} in 1200 ticks, then {more}"
    );
    // The driver's forward kinematics recovers the simulated tool position.
    let d = Delta::from_geometry(&DeviceProfile::built_in("falcon").unwrap().geometry).unwrap();
    let r = (last.position_m.as_dvec3() - d.home_guess_m).length();
    assert!(
        (0.005..0.02).contains(&r),
        "position {} is on the simulated circle (r = {r})",
        last.position_m
    );
    assert_ne!(
        sim.last_force(),
        [0; 3],
        "a pushing force reaches the motors"
    );
    dev.close().unwrap();
}

#[test]
fn falcon_homing_waits_for_the_homed_flags_of_all_three_motors() {
    // Motors 1 and 2 report homed well before motor 3: open must keep asking for homing until
    // the reply's byte 13 carries all three flags (bits 4, 5, 6).
    let sim = spawn_falcon(0, 90);
    let mut dev = Falcon::new(&sim.path, falcon_opts(None));
    dev.open().expect("homing completes");
    assert_eq!(dev.status().homed, 0x7);
    let asked = sim.homing_commands.load(Ordering::SeqCst);
    assert!(
        asked >= 90,
        "open returned after {asked} homing commands, before motor 3 was homed (90)"
    );
    // Once homed, commands stop asking for homing.
    let before = sim.homing_commands.load(Ordering::SeqCst);
    let (fresh, errors) = stream_until(&mut dev, 20, Vec3::ZERO);
    assert!(fresh >= 20 && errors == 0, "{fresh} fresh, {errors} errors");
    assert_eq!(sim.homing_commands.load(Ordering::SeqCst), before);
    dev.close().unwrap();
}

#[test]
fn falcon_firmware_loads_when_the_handshake_answer_comes_after_a_zero() {
    let image: Vec<u8> = (0..200u32).map(|i| (i * 13 + 1) as u8).collect();
    let dir = tempfile::tempdir().unwrap();
    let fw = dir.path().join("falcon_firmware.bin");
    std::fs::write(&fw, &image).unwrap();
    let sim = spawn_falcon_answering(image.len(), 3, HELLO_REPLY_AFTER_ZERO);
    let mut dev = Falcon::new(&sim.path, falcon_opts(Some(fw)));
    dev.open()
        .expect("firmware upload after a 00-prefixed handshake answer");
    assert_eq!(dev.link_stats().firmware_attempts, 1);
    dev.close().unwrap();
}

#[test]
fn falcon_sets_the_ftdi_latency_timer_to_1_ms_or_says_why_not() {
    use dynaclay_devices::ftdi_latency::{LatencyOutcome, LatencyUnset};
    // A pseudo-terminal is not a USB-serial port: the outcome says so, and the arm still runs.
    let sim = spawn_falcon(0, 3);
    let mut dev = Falcon::new(&sim.path, falcon_opts(None));
    dev.open().expect("open");
    assert!(
        matches!(
            dev.latency_timer(),
            LatencyOutcome::NotSet(LatencyUnset::NotUsbSerial { .. })
        ),
        "{}",
        dev.latency_timer()
    );
    dev.close().unwrap();
    // With a sysfs stand-in holding the pty's latency timer at 16 ms, open sets it to 1.
    let sysfs = tempfile::tempdir().unwrap();
    let name = std::path::Path::new(&sim.path)
        .file_name()
        .unwrap()
        .to_owned();
    let attr = sysfs.path().join(&name).join("latency_timer");
    std::fs::create_dir_all(attr.parent().unwrap()).unwrap();
    std::fs::write(&attr, "16\n").unwrap();
    let mut dev = Falcon::new(
        &sim.path,
        FalconOptions {
            usb_serial_sysfs: sysfs.path().to_path_buf(),
            ..falcon_opts(None)
        },
    );
    dev.open().expect("open");
    assert!(
        matches!(
            dev.latency_timer(),
            LatencyOutcome::Set {
                was_ms: 16,
                now_ms: 1,
                ..
            }
        ),
        "{}",
        dev.latency_timer()
    );
    assert_eq!(std::fs::read_to_string(&attr).unwrap().trim(), "1");
    dev.close().unwrap();
}

#[test]
fn the_doctor_streams_a_falcon_on_a_pseudo_terminal_and_sends_only_zero_force() {
    use dynaclay_devices::doctor::{self, DoctorConfig, WallClock};
    let sim = spawn_falcon(0, 3);
    let config = DoctorConfig {
        duration_us: 200_000,
        rate_hz: None,
    };
    let (report, falcon) = doctor::run(
        Falcon::new(&sim.path, falcon_opts(None)),
        config,
        &mut WallClock::new(),
    );
    let report = report.expect("the stand-in Falcon opens");
    // However fast this machine ran the loop: it ticked, every tick's command reached the
    // firmware, and none of them moved a motor.
    assert!(report.ticks > 0, "{report}");
    assert!(report.reads_ok > 0, "{report}");
    assert_eq!(report.force_errors, 0, "{report}");
    assert!(
        eventually(|| sim.commands.load(Ordering::SeqCst) >= report.ticks as u64),
        "one command per tick at least: {report}"
    );
    assert_eq!(sim.nonzero_commands.load(Ordering::SeqCst), 0, "{report}");
    assert!(!falcon.is_open(), "the doctor closes the port");
    assert!(report.to_string().contains("Novint Falcon"), "{report}");
}

#[test]
fn falcon_faults_are_reported_zero_force_follows_and_reconnect_works() {
    let sim = spawn_falcon(0, 5);
    let mut dev = SafetyFilter::with_config(Falcon::new(&sim.path, falcon_opts(None)), safety());
    dev.open().expect("firmware already running");
    let push = Vec3::new(1.0, 0.0, 0.0);
    stream(&mut dev, 50, push);
    assert_ne!(sim.last_force(), [0; 3]);

    for f in [fault::GARBAGE, fault::BAD_FRAME, fault::SHORT_FRAME] {
        sim.inject(f);
        let mut reported = None;
        for _ in 0..2000 {
            match dev.read() {
                Err(e) => {
                    reported = Some(e);
                    break;
                }
                Ok(_) => {
                    let _ = dev.write_force(push);
                }
            }
            std::thread::sleep(Duration::from_millis(1));
        }
        let e = reported.unwrap_or_else(|| panic!("fault {f} was not reported"));
        assert!(matches!(e, DeviceError::Protocol { .. }), "fault {f}: {e}");
        assert!(dev.fault_latched());
        assert!(
            eventually(|| sim.last_force() == [0; 3]),
            "the filter sent zero after fault {f}"
        );
        // The link recovers by itself: the next frames are good.
        let (fresh, _) = stream_until(&mut dev, 10, push);
        assert!(fresh >= 10, "recovered after fault {f}");
    }

    sim.inject(fault::CLOSE);
    let mut err = None;
    for _ in 0..3000 {
        if let Err(e) = dev.read()
            && e == DeviceError::Disconnected
        {
            err = Some(e);
            break;
        }
        let _ = dev.write_force(push);
        std::thread::sleep(Duration::from_millis(1));
    }
    assert_eq!(err, Some(DeviceError::Disconnected));
    assert!(
        dev.write_force(push).is_err(),
        "nothing is sent to a vanished device"
    );
    dev.close().unwrap();
    drop(sim);

    // The device comes back on a new node (as a USB serial device re-enumerates).
    let sim2 = spawn_falcon(0, 5);
    dev.device_mut().set_path(&sim2.path);
    dev.open().expect("reconnect");
    let (fresh, errors) = stream_until(&mut dev, 50, Vec3::ZERO);
    assert_eq!(errors, 0);
    assert!(fresh >= 50, "streaming after reconnect");
}

#[test]
fn falcon_open_without_firmware_or_answer_is_a_clear_error() {
    let sim = spawn_falcon(10, 5); // stuck in the bootloader
    let mut dev = Falcon::new(&sim.path, falcon_opts(None));
    match dev.open() {
        Err(DeviceError::Config { message, .. }) => {
            assert!(message.contains("firmware"), "{message}")
        }
        other => panic!("expected a configuration error, got {other:?}"),
    }
    assert!(!dev.is_open());
    let missing = Falcon::new("/dev/nonexistent-falcon", falcon_opts(None)).open();
    assert!(
        matches!(
            missing,
            Err(DeviceError::NotFound { .. } | DeviceError::Io { .. })
        ),
        "{missing:?}"
    );
}

#[test]
fn cartesian_serial_handshakes_homes_and_streams_at_1khz() {
    let sim = spawn_cartesian(Duration::from_millis(30));
    let profile = DeviceProfile::built_in("cartesian-serial").unwrap();
    let mut dev =
        SafetyFilter::with_config(SerialArm::new(&sim.path, profile, serial_opts()), safety());
    dev.open().expect("handshake and homing");
    assert!(dev.device().homed());
    assert!(
        (dev.info().max_force_n - 4.0).abs() < 1e-6,
        "device limit from HELLO_ACK"
    );
    let (fresh, errors, last) = stream(&mut dev, 1200, Vec3::new(1.0, -2.0, 0.5));
    // However loaded the machine, the link keeps delivering fresh samples (how many arrive
    // within each tick is measured in bench/, not here).
    let (more, more_errors) = stream_until(
        &mut dev,
        600u32.saturating_sub(fresh),
        Vec3::new(1.0, -2.0, 0.5),
    );
    assert_eq!(more_errors, 0, "no faults on a clean link");
    assert_eq!(errors, 0);
    // Every tick's command reaches the firmware.
    assert!(
        eventually(|| sim.commands.load(Ordering::SeqCst) >= 1200),
        "one command per tick"
    );
    assert!(
        fresh + more >= 600,
        "fresh samples: {fresh} in 1200 ticks, then {more}"
    );
    assert_eq!(sim.last_force(), [1000, -2000, 500]);
    assert!(
        last.position_m.x.abs() <= 0.0201 && (last.position_m.z + 0.005).abs() < 1e-6,
        "{}",
        last.position_m
    );
    assert_eq!(last.buttons, 1);
}

#[test]
fn cartesian_serial_faults_are_reported_zero_force_follows_and_reconnect_works() {
    let sim = spawn_cartesian(Duration::from_millis(1));
    let profile = DeviceProfile::built_in("cartesian-serial").unwrap();
    let mut dev = SafetyFilter::with_config(
        SerialArm::new(&sim.path, profile.clone(), serial_opts()),
        safety(),
    );
    dev.open().unwrap();
    let push = Vec3::new(0.0, 1.0, 0.0);
    stream(&mut dev, 50, push);
    assert_eq!(sim.last_force(), [0, 1000, 0]);
    for (f, what) in [
        (fault::GARBAGE, "byte outside a frame"),
        (fault::BAD_FRAME, "frame CRC mismatch"),
        (fault::SHORT_FRAME, ""),
    ] {
        sim.inject(f);
        let mut reported = None;
        for _ in 0..2000 {
            if let Err(e) = dev.read() {
                reported = Some(e);
                break;
            }
            let _ = dev.write_force(push);
            std::thread::sleep(Duration::from_millis(1));
        }
        match reported {
            Some(DeviceError::Protocol { what: w, .. }) => {
                assert!(what.is_empty() || w == what, "fault {f}: {w}")
            }
            other => panic!("fault {f} not reported as a protocol error: {other:?}"),
        }
        assert!(
            eventually(|| sim.last_force() == [0; 3]),
            "the filter sent zero after fault {f}"
        );
        let (fresh, _) = stream_until(&mut dev, 10, push);
        assert!(fresh >= 10, "recovered after fault {f}");
    }
    sim.inject(fault::CLOSE);
    let mut disconnected = false;
    for _ in 0..3000 {
        if dev.read() == Err(DeviceError::Disconnected) {
            disconnected = true;
            break;
        }
        let _ = dev.write_force(push);
        std::thread::sleep(Duration::from_millis(1));
    }
    assert!(disconnected, "peer hang-up is reported as Disconnected");
    dev.close().unwrap();
    drop(sim);
    let sim2 = spawn_cartesian(Duration::from_millis(1));
    dev.device_mut().set_path(&sim2.path);
    dev.open().expect("reconnect");
    let (fresh, errors) = stream_until(&mut dev, 50, Vec3::ZERO);
    assert_eq!(errors, 0);
    assert!(fresh >= 50, "streaming after reconnect");
}
