//! Stand-ins for Haply's devices, speaking their real protocols, for tests: a local WebSocket
//! server that answers as the Inverse Service does (a snapshot on connect, then one state
//! message per message received) and a Haply board on a pseudo-terminal (reset, set-up, one
//! angle reply per torque message).
//!
//! Each answers exchange `k` (counting from 0) with the hand at `hand(k)` (device frame,
//! metres), so what the driver sees depends on how many commands it sent, never on time. A
//! fault is injected on the reply to exchange `fault_at` (or the next one). Shared by `#[path]`
//! with the workspace's root tests.

#![allow(dead_code)]

use std::io::{Read, Write};
use std::net::TcpListener;
use std::sync::atomic::{AtomicBool, AtomicU8, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use dynaclay_devices::codec::haply_board as hb;
use dynaclay_devices::codec::haply_service as hs;
use dynaclay_devices::pantograph::Pantograph;
use dynaclay_devices::two_diy::{DEVICE_ID, TwoDiyVersion};
use glam::{DVec2, Vec3};
use serialport::{SerialPort, TTYPort};

/// A fault the stand-in puts in place of a reply.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum Fault {
    /// No fault.
    None = 0,
    /// Bytes that are not a reply (not JSON; a stray byte before the board's reply).
    Garbage = 1,
    /// A state message whose `cursor_position.y` is a string (Inverse3 only).
    WrongType = 2,
    /// A binary WebSocket message (Inverse3 only).
    Binary = 3,
    /// A message longer than the driver accepts (Inverse3 only).
    Oversize = 4,
    /// The connection or port goes away.
    Close = 5,
    /// The board takes commands and never answers again (2DIY only).
    Silent = 6,
}

impl Fault {
    fn from_u8(v: u8) -> Self {
        match v {
            1 => Self::Garbage,
            2 => Self::WrongType,
            3 => Self::Binary,
            4 => Self::Oversize,
            5 => Self::Close,
            6 => Self::Silent,
            _ => Self::None,
        }
    }
}

/// What the stand-in received.
#[derive(Clone, Debug, Default)]
pub struct Log {
    /// Every force command, device frame, newtons (Inverse3).
    pub forces_n: Vec<Vec3>,
    /// Every torque message, joint order (τ₁, τ₂), newton-metres (2DIY).
    pub torques_n_m: Vec<[f32; 2]>,
    /// The set-up message, as received (2DIY).
    pub setup: Vec<u8>,
    /// Reset messages received (2DIY).
    pub resets: u32,
    /// Commands that came after a fault reply (the driver's last zero force).
    pub after_fault: Vec<Vec3>,
}

/// A running stand-in.
pub struct Standin {
    /// `ws://127.0.0.1:PORT` or the pseudo-terminal's path.
    pub address: String,
    fault: Arc<AtomicU8>,
    fault_at: Arc<AtomicU64>,
    exchanges: Arc<AtomicU64>,
    log: Arc<Mutex<Log>>,
    stop: Arc<AtomicBool>,
    handle: Option<JoinHandle<()>>,
}

impl Standin {
    /// Puts `fault` in place of the reply to exchange `at` (0 = the next one).
    pub fn inject_at(&self, at: u64, fault: Fault) {
        self.fault_at.store(at, Ordering::SeqCst);
        self.fault.store(fault as u8, Ordering::SeqCst);
    }

    /// Puts `fault` in place of the next reply.
    pub fn inject(&self, fault: Fault) {
        self.inject_at(0, fault);
    }

    /// Commands answered so far (the opening exchange included).
    pub fn exchanges(&self) -> u64 {
        self.exchanges.load(Ordering::SeqCst)
    }

    /// A copy of what was received.
    pub fn log(&self) -> Log {
        self.log.lock().unwrap().clone()
    }

    /// Waits (bounded by `limit`) until `done` holds for the log.
    pub fn wait_for(&self, limit: Duration, done: impl Fn(&Log) -> bool) -> bool {
        let start = std::time::Instant::now();
        while start.elapsed() < limit {
            if done(&self.log()) {
                return true;
            }
            std::thread::sleep(Duration::from_millis(1));
        }
        false
    }

    /// Takes the fault due at exchange `k`, if any.
    fn due(fault: &AtomicU8, fault_at: &AtomicU64, k: u64) -> Fault {
        if fault.load(Ordering::SeqCst) != 0 && k >= fault_at.load(Ordering::SeqCst) {
            Fault::from_u8(fault.swap(0, Ordering::SeqCst))
        } else {
            Fault::None
        }
    }
}

impl Drop for Standin {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(h) = self.handle.take() {
            let _ = h.join();
        }
    }
}

/// The hand's path: device-frame position for exchange `k`.
pub type Hand = Box<dyn Fn(u64) -> Vec3 + Send>;

fn state_message(hand: Vec3, velocity: Vec3, with_config: bool) -> String {
    let p = hs::device_to_haply(hand);
    let v = hs::device_to_haply(velocity);
    let config = if with_config {
        r#""config": {"handedness": "right", "basis": {"permutation": "XYZ"}},"#
    } else {
        ""
    };
    format!(
        r#"{{"session_id": 1, "inverse3": [{{"device_id": "049D", {config} "state": {{"cursor_position": {{"x": {}, "y": {}, "z": {}}}, "cursor_velocity": {{"x": {}, "y": {}, "z": {}}}}}}}], "wireless_verse_grip": [{{"device_id": "0A1", "state": {{"buttons": {{"a": false, "b": true, "c": false}}}}}}]}}"#,
        p[0], p[1], p[2], v[0], v[1], v[2]
    )
}

/// Starts an Inverse Service stand-in on an ephemeral port of 127.0.0.1; it serves one client.
/// The velocity it reports is the hand's displacement per exchange over 1 ms.
pub fn inverse3_service(hand: Hand) -> Standin {
    let listener = TcpListener::bind("127.0.0.1:0").expect("bind a local port");
    let address = format!("ws://{}", listener.local_addr().unwrap());
    let fault = Arc::new(AtomicU8::new(0));
    let fault_at = Arc::new(AtomicU64::new(0));
    let exchanges = Arc::new(AtomicU64::new(0));
    let log = Arc::new(Mutex::new(Log::default()));
    let stop = Arc::new(AtomicBool::new(false));
    let (f2, fa2, x2, l2, s2) = (
        fault.clone(),
        fault_at.clone(),
        exchanges.clone(),
        log.clone(),
        stop.clone(),
    );
    listener.set_nonblocking(true).unwrap();
    let handle = std::thread::spawn(move || {
        let stream = loop {
            if s2.load(Ordering::SeqCst) {
                return;
            }
            match listener.accept() {
                Ok((s, _)) => break s,
                Err(_) => std::thread::sleep(Duration::from_millis(1)),
            }
        };
        stream.set_nonblocking(false).unwrap();
        let mut ws = tungstenite::accept(stream).expect("WebSocket handshake");
        ws.get_mut()
            .set_read_timeout(Some(Duration::from_millis(5)))
            .unwrap();
        let velocity = |k: u64| (hand(k + 1) - hand(k)) * 1000.0;
        ws.send(tungstenite::Message::text(state_message(
            hand(0),
            Vec3::ZERO,
            true,
        )))
        .unwrap();
        let mut faulted = false;
        while !s2.load(Ordering::SeqCst) {
            let msg = match ws.read() {
                Ok(m) => m,
                Err(tungstenite::Error::Io(e))
                    if matches!(
                        e.kind(),
                        std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                    ) =>
                {
                    continue;
                }
                Err(_) => return,
            };
            let tungstenite::Message::Text(text) = msg else {
                continue;
            };
            let v: serde_json::Value = serde_json::from_str(text.as_str()).expect("JSON command");
            let cmd = &v["inverse3"][0];
            assert_eq!(cmd["device_id"], "049D", "the command names the arm");
            let values = &cmd["commands"]["set_cursor_force"]["values"];
            let f = [
                values["x"].as_f64().unwrap(),
                values["y"].as_f64().unwrap(),
                values["z"].as_f64().unwrap(),
            ];
            let force = hs::haply_to_device(f);
            {
                let mut l = l2.lock().unwrap();
                l.forces_n.push(force);
                if faulted {
                    l.after_fault.push(force);
                }
            }
            let k = x2.fetch_add(1, Ordering::SeqCst);
            let due = Standin::due(&f2, &fa2, k);
            let reply = match due {
                Fault::None => {
                    tungstenite::Message::text(state_message(hand(k), velocity(k), false))
                }
                Fault::Garbage => tungstenite::Message::text("{\"inverse3\": [oops"),
                Fault::WrongType => {
                    tungstenite::Message::text(state_message(hand(k), Vec3::ZERO, false).replacen(
                        "\"y\": ",
                        "\"y\": \"up\", \"w\": ",
                        1,
                    ))
                }
                Fault::Binary => tungstenite::Message::binary(vec![1u8, 2, 3]),
                Fault::Oversize => {
                    tungstenite::Message::text(" ".repeat(hs::MAX_MESSAGE_BYTES + 16))
                }
                Fault::Close | Fault::Silent => return,
            };
            faulted |= due != Fault::None;
            if ws.send(reply).is_err() {
                return;
            }
        }
    });
    Standin {
        address,
        fault,
        fault_at,
        exchanges,
        log,
        stop,
        handle: Some(handle),
    }
}

/// Starts a Haply board stand-in for a 2DIY of `version` on a pseudo-terminal.
pub fn two_diy_board(version: TwoDiyVersion, hand: Hand) -> Standin {
    let (mut master, slave) = TTYPort::pair().expect("pseudo-terminal pair");
    let address = slave.name().expect("slave path");
    drop(slave); // the driver opens the node itself
    master.set_timeout(Duration::from_millis(1)).unwrap();
    let pantograph: Pantograph = version.pantograph();
    let fault = Arc::new(AtomicU8::new(0));
    let fault_at = Arc::new(AtomicU64::new(0));
    let exchanges = Arc::new(AtomicU64::new(0));
    let log = Arc::new(Mutex::new(Log::default()));
    let stop = Arc::new(AtomicBool::new(false));
    let (f2, fa2, x2, l2, s2) = (
        fault.clone(),
        fault_at.clone(),
        exchanges.clone(),
        log.clone(),
        stop.clone(),
    );
    let handle = std::thread::spawn(move || {
        let mut input: Vec<u8> = Vec::new();
        let mut buf = [0u8; 256];
        let mut motors = 0usize;
        let mut faulted = false;
        let mut silent = false;
        while !s2.load(Ordering::SeqCst) {
            let n = master.read(&mut buf).unwrap_or(0);
            input.extend_from_slice(&buf[..n]);
            while let Some(&kind) = input.first() {
                let len = match kind {
                    hb::kind::RESET => 2,
                    hb::kind::SETUP => {
                        // type, id, motor mask + dirs, encoder mask + dirs, sensors, floats.
                        if input.len() < 3 {
                            break;
                        }
                        let m = (input[2] & 0x0f).count_ones() as usize;
                        if input.len() < 4 + m {
                            break;
                        }
                        let e = (input[3 + m] & 0x0f).count_ones() as usize;
                        motors = m;
                        2 + (1 + m) + (1 + e) + 1 + 8 * e
                    }
                    hb::kind::DATA => 2 + 4 * motors,
                    other => panic!("the driver sent message type {other}"),
                };
                if input.len() < len {
                    break;
                }
                let msg: Vec<u8> = input.drain(..len).collect();
                match kind {
                    hb::kind::RESET => l2.lock().unwrap().resets += 1,
                    hb::kind::SETUP => l2.lock().unwrap().setup = msg,
                    _ => {
                        assert_eq!(msg[1], DEVICE_ID, "the torques name the board");
                        let f = |at: usize| f32::from_le_bytes(msg[at..at + 4].try_into().unwrap());
                        // Port order: port 1 drives joint 2, port 2 joint 1.
                        let tau = [f(6), f(2)];
                        {
                            let mut l = l2.lock().unwrap();
                            l.torques_n_m.push(tau);
                            if faulted {
                                l.after_fault.push(Vec3::new(tau[0], tau[1], 0.0));
                            }
                        }
                        let k = x2.fetch_add(1, Ordering::SeqCst);
                        let p = hand(k);
                        let (t1, t2) = pantograph
                            .inverse(DVec2::new(-f64::from(p.x), -f64::from(p.y)))
                            .expect("the hand stays in the linkage's reach");
                        let mut reply = [0u8; hb::MAX_REPLY];
                        reply[0] = DEVICE_ID;
                        reply[1..5].copy_from_slice(&(t2.to_degrees() as f32).to_le_bytes());
                        reply[5..9].copy_from_slice(&(t1.to_degrees() as f32).to_le_bytes());
                        match Standin::due(&f2, &fa2, k) {
                            Fault::Close => return,
                            Fault::Silent => silent = true,
                            _ if silent => {}
                            Fault::None => {
                                let _ = master.write_all(&reply[..9]);
                            }
                            _ => {
                                faulted = true;
                                // A stray byte, then the reply: the driver must report the
                                // byte and realign on the reply.
                                let _ = master.write_all(&[0xee]);
                                let _ = master.write_all(&reply[..9]);
                            }
                        }
                    }
                }
            }
        }
    });
    Standin {
        address,
        fault,
        fault_at,
        exchanges,
        log,
        stop,
        handle: Some(handle),
    }
}
