//! Device benchmarks: protocol codec encode/decode times, kinematics, the serial round trip
//! over a real pseudo-terminal pair at 1 kHz (p50/p99), and the device doctor's loop on a
//! Falcon over a pseudo-terminal (the rate its read/write cycle achieves, and its jitter).
//!
//! Run: `cargo bench --bench devices` (short: `cargo bench --bench devices -- --warm-up-time 0.5
//! --measurement-time 1`; `cargo bench --bench devices -- doctor` runs the doctor part alone).
//! The PTY parts run after criterion and print their own percentiles; they are optimistic
//! compared with real USB (no FTDI latency timer, no USB frame scheduling) and pessimistic on a
//! loaded machine (the firmware thread competes for a core).

use std::hint::black_box;
use std::io::{Read, Write};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use criterion::{Criterion, Throughput};
use dynaclay_devices::HapticDevice;
use dynaclay_devices::codec::frame::{self, DeviceMsg, FrameEvent, FrameReader, HostMsg};
use dynaclay_devices::codec::{cartesian, falcon, spacemouse, woodenhaptics};
use dynaclay_devices::delta::Delta;
use dynaclay_devices::doctor::{self, DoctorConfig, WallClock};
use dynaclay_devices::falcon::{Falcon, FalconOptions};
use dynaclay_devices::kinematics::ArmModel;
use dynaclay_devices::profile::DeviceProfile;
use dynaclay_devices::serial_arm::{SerialArm, SerialArmOptions};
use dynaclay_devices::serial_link::BaudPolicy;
use glam::{DVec3, Vec3};
use serialport::{SerialPort, TTYPort};

fn codecs(c: &mut Criterion) {
    let mut g = c.benchmark_group("codec");
    g.throughput(Throughput::Elements(1));
    let fcmd = falcon::FalconCommand {
        motor: [1200, -800, 33],
        leds: falcon::LED_GREEN,
        homing: false,
    };
    let fstat = falcon::encode_status(&falcon::FalconStatus {
        encoders: [-500, 20, 3000],
        buttons: 1,
        homed: 7,
    });
    g.bench_function("falcon/encode_command", |b| {
        b.iter(|| falcon::encode_command(black_box(&fcmd)))
    });
    g.bench_function("falcon/decode_status", |b| {
        b.iter(|| falcon::decode_status(black_box(&fstat)))
    });
    g.bench_function("falcon/reader_16_bytes", |b| {
        let mut r = falcon::FalconReader::new();
        b.iter(|| {
            let mut out = None;
            for &x in black_box(&fstat) {
                out = Some(r.push(x));
            }
            out
        })
    });
    let wcmd = woodenhaptics::WhCommand::Drive {
        currents_ma: [100, -200, 300],
    };
    let wstat = woodenhaptics::encode_status(&woodenhaptics::WhStatus {
        encoders: [1, 2, 3, 4, 5, 6],
        info: 0,
    });
    g.bench_function("woodenhaptics/encode_command", |b| {
        b.iter(|| woodenhaptics::encode_command(black_box(&wcmd)))
    });
    g.bench_function("woodenhaptics/decode_status", |b| {
        b.iter(|| woodenhaptics::decode_status(black_box(&wstat)))
    });
    let cstat = cartesian::encode_state(&cartesian::CartesianState {
        position_um: [1, 2, 3],
        buttons: 0,
        status: 1,
        seq: 2,
    });
    g.bench_function("cartesian_hid/decode_state", |b| {
        b.iter(|| cartesian::decode_state(black_box(&cstat)))
    });
    let (sm, n) = spacemouse::encode_report(&spacemouse::SpaceMouseReport::Combined {
        translation: [1, 2, 3],
        rotation: [4, 5, 6],
    });
    g.bench_function("spacemouse/decode_combined", |b| {
        b.iter(|| spacemouse::decode_report(black_box(&sm[..n])))
    });
    let mut buf = [0u8; frame::MAX_FRAME];
    g.bench_function("frame/encode_force", |b| {
        b.iter(|| {
            HostMsg::Force {
                force_mn: [1000, -1000, 0],
                seq: 7,
            }
            .encode(black_box(&mut buf))
        })
    });
    let st = DeviceMsg::State {
        position_um: [10, 20, 30],
        buttons: 0,
        seq: 1,
        status: 1,
    };
    let mut sbuf = [0u8; frame::MAX_FRAME];
    let sn = st.encode(&mut sbuf).unwrap();
    g.bench_function("frame/decode_state", |b| {
        b.iter(|| {
            let (k, p) = frame::decode_frame(black_box(&sbuf[..sn])).unwrap();
            DeviceMsg::decode(k, p)
        })
    });
    g.bench_function("frame/reader_state_frame", |b| {
        let mut r = FrameReader::new();
        b.iter(|| {
            let mut got = None;
            for &x in black_box(&sbuf[..sn]) {
                if let FrameEvent::Frame { kind, .. } = r.push(x) {
                    got = DeviceMsg::decode(kind, r.payload()).ok();
                }
            }
            got
        })
    });
    g.finish();
}

fn kinematics(c: &mut Criterion) {
    let mut g = c.benchmark_group("kinematics");
    let fp = DeviceProfile::built_in("falcon").unwrap();
    let d = Delta::from_geometry(&fp.geometry).unwrap();
    let p = d.home_guess_m + DVec3::new(0.01, -0.01, 0.005);
    let q = d.inverse(p).unwrap();
    g.bench_function("delta/inverse", |b| b.iter(|| d.inverse(black_box(p))));
    g.bench_function("delta/forward_warm", |b| {
        b.iter(|| d.forward(black_box(q), p + DVec3::splat(1e-4)))
    });
    g.bench_function("delta/forward_cold", |b| {
        b.iter(|| d.forward(black_box(q), d.home_guess_m))
    });
    let mut m = ArmModel::from_profile(&DeviceProfile::built_in("woodenhaptics").unwrap()).unwrap();
    m.update([100, 200, 300]).unwrap();
    g.bench_function("serial_arm/update_and_force", |b| {
        b.iter(|| {
            let pos = m.update(black_box([101, 199, 300])).unwrap();
            (pos, m.commands_for_force(DVec3::new(1.0, 0.0, -1.0)))
        })
    });
    g.finish();
}

/// Simulated firmware on the PTY master: answers every Falcon command (or Cartesian FORCE) at once.
fn spawn_echo_firmware(
    mut master: TTYPort,
    cartesian_protocol: bool,
    stop: Arc<AtomicBool>,
) -> std::thread::JoinHandle<()> {
    std::thread::spawn(move || {
        let _ = master.set_timeout(Duration::from_millis(1));
        let mut buf = [0u8; 256];
        let mut window = Vec::new();
        let mut reader = FrameReader::new();
        let mut out = [0u8; frame::MAX_FRAME];
        let status = falcon::encode_status(&falcon::FalconStatus {
            encoders: [-550, -550, -550],
            buttons: 0,
            homed: 7,
        });
        while !stop.load(Ordering::Relaxed) {
            let n = master.read(&mut buf).unwrap_or(0);
            for &b in &buf[..n] {
                if cartesian_protocol {
                    let mut ev = Some(reader.push(b));
                    while let Some(e) = ev {
                        if let FrameEvent::Frame { kind, .. } = e {
                            let reply = match HostMsg::decode(kind, reader.payload()) {
                                Ok(HostMsg::Hello { .. }) => Some(DeviceMsg::HelloAck {
                                    version: frame::VERSION,
                                    max_force_mn: 5000,
                                    workspace_radius_um: 100_000,
                                }),
                                Ok(HostMsg::Home) => Some(DeviceMsg::HomeDone { ok: true }),
                                Ok(HostMsg::Force { seq, .. }) => Some(DeviceMsg::State {
                                    position_um: [0, 0, 0],
                                    buttons: 0,
                                    seq,
                                    status: 1,
                                }),
                                Err(_) => None,
                            };
                            if let Some(m) = reply {
                                let k = m.encode(&mut out).unwrap();
                                let _ = master.write_all(&out[..k]);
                            }
                        }
                        ev = reader.drain();
                    }
                } else {
                    if b == falcon::START {
                        window.clear();
                    }
                    window.push(b);
                    if window.len() == falcon::FRAME_LEN {
                        if falcon::decode_command(&window).is_ok() {
                            let _ = master.write_all(&status);
                        }
                        window.clear();
                    }
                }
            }
        }
    })
}

fn percentile(sorted: &[f64], q: f64) -> f64 {
    sorted[((sorted.len() - 1) as f64 * q).round() as usize]
}

/// Round trip at 1 kHz: write a force, then read until the reply's sample arrives.
fn pty_round_trip(name: &str, dev: &mut dyn HapticDevice, ticks: usize) {
    let mut lat_us = Vec::with_capacity(ticks);
    let mut last_seq = dev.read().map(|s| s.sequence).unwrap_or(0);
    let mut missed = 0;
    let start = Instant::now();
    for k in 0..ticks {
        let t = Instant::now();
        let _ = dev.write_force(Vec3::new(0.0, 0.0, 0.5));
        loop {
            if let Ok(s) = dev.read()
                && s.sequence > last_seq
            {
                last_seq = s.sequence;
                lat_us.push(t.elapsed().as_secs_f64() * 1e6);
                break;
            }
            if t.elapsed() > Duration::from_millis(20) {
                missed += 1;
                break;
            }
        }
        let deadline = start + Duration::from_micros(1000 * (k as u64 + 1));
        while Instant::now() < deadline {
            std::hint::spin_loop();
        }
    }
    lat_us.sort_by(f64::total_cmp);
    println!(
        "pty_round_trip/{name}: {} ticks at 1 kHz, p50 {:.1} µs, p99 {:.1} µs, max {:.1} µs, missed {missed}",
        lat_us.len(),
        percentile(&lat_us, 0.5),
        percentile(&lat_us, 0.99),
        lat_us.last().copied().unwrap_or(0.0)
    );
}

fn pty_latency() {
    let ticks = std::env::var("DEVICES_BENCH_TICKS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(2000);
    for cartesian_protocol in [false, true] {
        let (master, slave) = TTYPort::pair().expect("pseudo-terminal pair");
        let path = slave.name().unwrap();
        drop(slave);
        let stop = Arc::new(AtomicBool::new(false));
        let fw = spawn_echo_firmware(master, cartesian_protocol, stop.clone());
        if cartesian_protocol {
            let opts = SerialArmOptions {
                reply_wait: Duration::from_micros(0),
                stale_after: Duration::from_secs(1),
                ..SerialArmOptions::default()
            };
            let mut dev = SerialArm::new(
                &path,
                DeviceProfile::built_in("cartesian-serial").unwrap(),
                opts,
            );
            dev.open().expect("open cartesian serial");
            pty_round_trip("cartesian_serial", &mut dev, ticks);
            let _ = dev.close();
        } else {
            let opts = FalconOptions {
                baud_policy: BaudPolicy::Tolerant,
                reply_wait: Duration::from_micros(0),
                stale_after: Duration::from_secs(1),
                ..FalconOptions::default()
            };
            let mut dev = Falcon::new(&path, opts);
            dev.open().expect("open falcon");
            pty_round_trip("falcon", &mut dev, ticks);
            let _ = dev.close();
        }
        stop.store(true, Ordering::Relaxed);
        let _ = fw.join();
    }
}

/// The device doctor's zero-force loop (`dynaclay devices --doctor falcon:PATH`, in process:
/// the same `doctor::run`, the same wall clock, the driver's default options, as the command
/// builds them without a firmware file) on a Falcon whose firmware is the echo thread on a
/// pseudo-terminal. Each tick reads the reply to the previous tick's command and sends the
/// next, so the fresh-sample rate is the rate the driver's read/write cycle sustains; the load
/// average is printed before and after, since a second core's load shows in the tail.
fn falcon_doctor() {
    let seconds: f64 = std::env::var("DEVICES_DOCTOR_SECONDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .filter(|s: &f64| (0.05..=60.0).contains(s))
        .unwrap_or(5.0);
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    println!("falcon_doctor: load average {}", load.trim());
    let (master, slave) = TTYPort::pair().expect("pseudo-terminal pair");
    let path = slave.name().unwrap();
    drop(slave);
    let stop = Arc::new(AtomicBool::new(false));
    let fw = spawn_echo_firmware(master, false, stop.clone());
    let config = DoctorConfig {
        duration_us: (seconds * 1e6).round() as u64,
        rate_hz: None,
    };
    let falcon = Falcon::new(&path, FalconOptions::default());
    let (outcome, falcon) = doctor::run(falcon, config, &mut WallClock::new());
    match outcome {
        Ok(report) => print!("falcon_doctor: {report}"),
        Err(e) => println!("falcon_doctor: cannot open the Falcon on {path}: {e}"),
    }
    println!("falcon_doctor: {}", falcon.latency_timer());
    let stats = falcon.link_stats();
    println!(
        "falcon_doctor: link {} frames sent, {} received, {} malformed, {} stray bytes",
        stats.sent, stats.received, stats.bad_frames, stats.skipped_bytes
    );
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    println!("falcon_doctor: load average after {}", load.trim());
    stop.store(true, Ordering::Relaxed);
    let _ = fw.join();
}

fn main() {
    if std::env::args().any(|a| a == "doctor") {
        falcon_doctor();
        return;
    }
    let mut c = Criterion::default().configure_from_args();
    codecs(&mut c);
    kinematics(&mut c);
    c.final_summary();
    pty_latency();
    falcon_doctor();
}
