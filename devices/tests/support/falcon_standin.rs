//! A Novint Falcon stand-in for tests: the Novint firmware's framing (libnifalcon's reading of
//! it) on a pseudo-terminal, already running (no bootloader), answering each 16-byte command
//! frame with one status frame. Homing follows the same reading: a command with the homing bit
//! (byte 13, bit 0) homes the three motors, and the status reports them homed in bits 4..6 of
//! byte 13 from then on.
//!
//! Exchange `k` (counting from 0, homing commands included) is answered with the hand at
//! `hand(k)` (device frame, metres), turned into encoder counts through the profile's delta
//! kinematics and motor table, so what the driver sees depends on how many commands it sent,
//! never on time. Faults are scheduled by exchange: a stray byte before one reply, and the
//! port going away (no reply, the terminal hung up) at another. Shared by `#[path]` with the
//! workspace's root tests.

#![allow(dead_code)]

use std::io::{Read, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use dynaclay_devices::codec::falcon::{self as fc};
use dynaclay_devices::delta::Delta;
use dynaclay_devices::kinematics::JointMap;
use dynaclay_devices::profile::DeviceProfile;
use glam::Vec3;
use serialport::{SerialPort, TTYPort};

/// Where the hand is at exchange `k` (device frame, metres).
pub type Hand = Box<dyn Fn(u64) -> Vec3 + Send>;

/// When the stand-in breaks the link, by exchange.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FalconFaults {
    /// A stray byte goes out before this exchange's reply.
    pub stray_byte_at: Option<u64>,
    /// This exchange gets no reply: the stand-in hangs up the terminal.
    pub hang_up_at: Option<u64>,
}

/// What the stand-in received.
#[derive(Clone, Debug, Default)]
pub struct FalconLog {
    /// The motor commands of every frame answered, in order (homing ones included).
    pub motor_commands: Vec<[i16; 3]>,
    /// Whether each of those frames asked for homing.
    pub homing: Vec<bool>,
    /// When each of those frames was decoded (a failure message shows where the link paused).
    pub decoded_at: Vec<Instant>,
    /// When the reply to each of them was written.
    pub replied_at: Vec<Instant>,
    /// Replies the terminal did not take whole (exchange, error): a silent loss would leave
    /// the driver waiting for a reply that was never sent.
    pub reply_write_errors: Vec<(u64, String)>,
}

/// A running Falcon stand-in.
pub struct FalconStandin {
    /// The pseudo-terminal's path, for `Falcon::new`.
    pub path: String,
    log: Arc<Mutex<FalconLog>>,
    stop: Arc<AtomicBool>,
    handle: Option<JoinHandle<()>>,
}

impl FalconStandin {
    /// A copy of what was received.
    pub fn log(&self) -> FalconLog {
        self.log.lock().unwrap().clone()
    }
}

impl Drop for FalconStandin {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(h) = self.handle.take() {
            let _ = h.join();
        }
    }
}

/// Starts a Falcon stand-in on a new pseudo-terminal, its hand at `hand(k)` for exchange `k`.
pub fn falcon_board(hand: Hand, faults: FalconFaults) -> FalconStandin {
    let (mut master, slave) = TTYPort::pair().expect("pseudo-terminal pair");
    let path = slave.name().expect("slave path");
    drop(slave); // the driver opens the node itself
    master.set_timeout(Duration::from_millis(1)).unwrap();
    let profile = DeviceProfile::built_in("falcon").unwrap();
    let delta = Delta::from_geometry(&profile.geometry).unwrap();
    let joints = JointMap {
        motors: profile.motors.unwrap(),
    };
    let log = Arc::new(Mutex::new(FalconLog::default()));
    let stop = Arc::new(AtomicBool::new(false));
    let (l2, s2) = (log.clone(), stop.clone());
    let handle = std::thread::spawn(move || {
        let mut window: Vec<u8> = Vec::new();
        let mut buf = [0u8; 256];
        let mut homed = false;
        let mut k = 0u64;
        while !s2.load(Ordering::SeqCst) {
            let n = master.read(&mut buf).unwrap_or(0);
            for &b in &buf[..n] {
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
                window.clear();
                {
                    let mut l = l2.lock().unwrap();
                    l.motor_commands.push(cmd.motor);
                    l.homing.push(cmd.homing);
                    l.decoded_at.push(Instant::now());
                }
                homed |= cmd.homing;
                if faults.hang_up_at == Some(k) {
                    return; // drops the master: the terminal hangs up
                }
                let p = hand(k).as_dvec3();
                let q = delta
                    .inverse(p)
                    .expect("the hand stays in the Falcon's reach");
                let counts = joints.counts(q).map(|c| c.round() as i16);
                let mut frame = fc::encode_status(&fc::FalconStatus {
                    encoders: counts,
                    buttons: 0,
                    homed: 0,
                });
                // The homed flags of motors 1..3 in bits 4..6 of byte 13 (nibble base 0x41),
                // written by hand rather than through the codec the driver decodes with.
                frame[13] = 0x41 + if homed { 0x7 << 4 } else { 0 };
                let mut reply = Vec::with_capacity(1 + fc::FRAME_LEN);
                if faults.stray_byte_at == Some(k) {
                    reply.push(0xee);
                }
                reply.extend_from_slice(&frame);
                let written = master.write_all(&reply);
                {
                    let mut l = l2.lock().unwrap();
                    l.replied_at.push(Instant::now());
                    if let Err(e) = written {
                        l.reply_write_errors.push((k, e.to_string()));
                    }
                }
                k += 1;
            }
        }
    });
    FalconStandin {
        path,
        log,
        stop,
        handle: Some(handle),
    }
}
