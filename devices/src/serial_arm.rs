//! Cartesian arm over a serial port: the dynaclay framed protocol (`devices/PROTOCOL.md`).
//!
//! `open` opens the port, exchanges HELLO / HELLO_ACK (checking the protocol version and
//! taking the device's force limit), and optionally homes (HOME → HOME_DONE). Streaming is one
//! FORCE frame out per tick (a keep-alive with the last force when the engine only reads) and
//! STATE frames in, decoded by [`FrameReader`]; positions arrive in micrometres in the dynaclay
//! device frame, so there is no kinematics on the host. `read`/`write_force` are bounded and
//! allocation-free; a bad CRC, a bad length, noise or silence is reported as a value.

use std::time::{Duration, Instant};

use glam::Vec3;

use crate::arm_link::{ArmSession, LinkStats, SerialStream, cartesian_force_mn};
use crate::codec::CodecError;
use crate::codec::frame::{self, DeviceMsg, FrameEvent, FrameReader, HostMsg, MAX_FRAME, VERSION};
use crate::device::{DeviceError, DeviceInfo, DeviceState, HapticDevice};
use crate::profile::DeviceProfile;
use crate::serial_link::{BaudPolicy, READ_BUF};

/// Default line rate (USB CDC ports ignore it).
pub const DEFAULT_BAUD: u32 = 1_000_000;

/// Settings of a [`SerialArm`].
#[derive(Clone, Debug, PartialEq)]
pub struct SerialArmOptions {
    /// Line rate.
    pub baud: u32,
    /// How to treat refused baud-rate changes.
    pub baud_policy: BaudPolicy,
    /// Ask the device to home in `open`.
    pub homing: bool,
    /// Longest wait for HELLO_ACK (per attempt) during `open`.
    pub handshake_timeout: Duration,
    /// Longest wait for HOME_DONE.
    pub homing_timeout: Duration,
    /// Longest `read` waits for the reply to the outstanding command (0: never wait).
    pub reply_wait: Duration,
    /// No valid STATE for this long makes `read` fail with a timeout.
    pub stale_after: Duration,
}

impl Default for SerialArmOptions {
    fn default() -> Self {
        Self {
            baud: DEFAULT_BAUD,
            baud_policy: BaudPolicy::Tolerant,
            homing: true,
            handshake_timeout: Duration::from_millis(300),
            homing_timeout: Duration::from_secs(30),
            reply_wait: Duration::from_micros(400),
            stale_after: Duration::from_millis(50),
        }
    }
}

/// A Cartesian arm on a serial port.
pub struct SerialArm {
    path: String,
    profile: DeviceProfile,
    opts: SerialArmOptions,
    stream: SerialStream,
    session: ArmSession,
    reader: FrameReader,
    force_mn: [i16; 3],
    seq: u16,
    device_max_force_n: f32,
    homed: bool,
}

fn fault_name(e: &CodecError) -> &'static str {
    match e {
        CodecError::BadCrc { .. } => "frame CRC mismatch",
        CodecError::BadLength { .. } => "frame length out of range",
        CodecError::BadByte { field, .. } => field,
        CodecError::TooShort { .. } | CodecError::TooLong { .. } => "frame of the wrong size",
    }
}

impl SerialArm {
    /// A Cartesian serial arm on `path` (not opened yet).
    #[must_use]
    pub fn new(path: &str, profile: DeviceProfile, opts: SerialArmOptions) -> Self {
        let now = Instant::now();
        let device_max_force_n = profile.max_force_n;
        Self {
            path: path.to_string(),
            profile,
            stream: SerialStream::new(opts.stale_after, now),
            session: ArmSession::new(now),
            opts,
            reader: FrameReader::new(),
            force_mn: [0; 3],
            seq: 0,
            device_max_force_n,
            homed: false,
        }
    }

    /// Points the driver at another port node; takes effect at the next `open`.
    pub fn set_path(&mut self, path: &str) {
        self.path = path.to_string();
    }

    /// Link counters since `open`.
    #[must_use]
    pub fn link_stats(&self) -> LinkStats {
        self.stream.stats
    }

    /// Whether the device reported homed in its last state (or HOME_DONE succeeded).
    #[must_use]
    pub fn homed(&self) -> bool {
        self.homed
    }

    fn send(&mut self, msg: HostMsg) -> Result<(), DeviceError> {
        let mut buf = [0u8; MAX_FRAME];
        let n = msg.encode(&mut buf).map_err(|_| DeviceError::Protocol {
            what: "frame encoding",
            offset: 0,
        })?;
        self.stream.write_frame(&buf[..n])
    }

    fn send_force(&mut self) -> Result<(), DeviceError> {
        self.seq = self.seq.wrapping_add(1);
        self.send(HostMsg::Force {
            force_mn: self.force_mn,
            seq: self.seq,
        })
    }

    /// Reads what is queued; hands each decoded message to `on_msg`; returns the first fault.
    fn pump(
        &mut self,
        wait: Duration,
        on_msg: &mut dyn FnMut(&mut Self, DeviceMsg),
    ) -> Result<Option<DeviceError>, DeviceError> {
        let mut chunk = [0u8; READ_BUF];
        let received = self.stream.read_chunk(wait, &mut chunk)?;
        let mut fault = None;
        for (i, &b) in chunk[..received.len].iter().enumerate() {
            let offset = received.first_offset.wrapping_add(i);
            let mut ev = Some(self.reader.push(b));
            while let Some(e) = ev {
                match e {
                    FrameEvent::Pending => {}
                    FrameEvent::Skipped(_) => {
                        self.stream.stats.skipped_bytes += 1;
                        fault.get_or_insert(DeviceError::Protocol {
                            what: "byte outside a frame",
                            offset,
                        });
                    }
                    FrameEvent::Bad(err) => {
                        self.stream.stats.bad_frames += 1;
                        fault.get_or_insert(DeviceError::Protocol {
                            what: fault_name(&err),
                            offset,
                        });
                    }
                    FrameEvent::Frame { kind, .. } => {
                        match DeviceMsg::decode(kind, self.reader.payload()) {
                            Ok(m) => {
                                self.stream.stats.received += 1;
                                on_msg(self, m);
                            }
                            Err(err) => {
                                self.stream.stats.bad_frames += 1;
                                fault.get_or_insert(DeviceError::Protocol {
                                    what: fault_name(&err),
                                    offset,
                                });
                            }
                        }
                    }
                }
                ev = self.reader.drain();
            }
        }
        Ok(fault)
    }

    fn await_msg(
        &mut self,
        timeout: Duration,
        want: &mut dyn FnMut(&mut Self, DeviceMsg) -> bool,
    ) -> Result<bool, DeviceError> {
        let start = Instant::now();
        let mut got = false;
        while !got && start.elapsed() < timeout {
            self.pump(Duration::from_millis(1), &mut |s, m| got |= want(s, m))?;
        }
        Ok(got)
    }

    fn open_inner(&mut self) -> Result<(), DeviceError> {
        self.stream.open(
            &self.path,
            self.opts.baud,
            self.opts.baud_policy,
            Instant::now(),
        )?;
        self.reader.reset();
        self.force_mn = [0; 3];
        let mut version = None;
        for _ in 0..3 {
            self.send(HostMsg::Hello { version: VERSION })?;
            let mut max_mn = 0u16;
            let ok = self.await_msg(self.opts.handshake_timeout, &mut |_, m| match m {
                DeviceMsg::HelloAck {
                    version: v,
                    max_force_mn,
                    ..
                } => {
                    version = Some(v);
                    max_mn = max_force_mn;
                    true
                }
                _ => false,
            })?;
            if ok {
                if max_mn > 0 {
                    self.device_max_force_n =
                        self.profile.max_force_n.min(f32::from(max_mn) * 1e-3);
                }
                break;
            }
        }
        match version {
            None => {
                return Err(DeviceError::Timeout {
                    waited_us: 3 * self.opts.handshake_timeout.as_micros() as u64,
                });
            }
            Some(v) if v != VERSION => {
                return Err(DeviceError::Config {
                    origin: format!("serial:{}", self.path),
                    message: format!(
                        "device speaks Cartesian protocol version {v}, dynaclay speaks {VERSION}"
                    ),
                });
            }
            Some(_) => {}
        }
        if self.opts.homing {
            self.send(HostMsg::Home)?;
            let mut ok = None;
            self.await_msg(self.opts.homing_timeout, &mut |_, m| match m {
                DeviceMsg::HomeDone { ok: k } => {
                    ok = Some(k);
                    true
                }
                _ => false,
            })?;
            match ok {
                Some(true) => self.homed = true,
                Some(false) => {
                    return Err(DeviceError::Config {
                        origin: format!("serial:{}", self.path),
                        message: "the device reported that homing failed".into(),
                    });
                }
                None => {
                    return Err(DeviceError::Timeout {
                        waited_us: self.opts.homing_timeout.as_micros() as u64,
                    });
                }
            }
        }
        let now = Instant::now();
        self.session.start(now);
        self.stream.live_from(now);
        Ok(())
    }

    fn on_state(&mut self, m: DeviceMsg) {
        if let DeviceMsg::State {
            position_um,
            buttons,
            status,
            ..
        } = m
        {
            let now = Instant::now();
            let t_us = self.session.elapsed_us(now);
            let p = Vec3::new(
                position_um[0] as f32,
                position_um[1] as f32,
                position_um[2] as f32,
            ) * 1e-6;
            self.homed = status & frame::status::HOMED != 0;
            self.stream.frame_received(now);
            self.session.sample(p, u32::from(buttons), t_us);
        }
    }
}

impl HapticDevice for SerialArm {
    fn info(&self) -> DeviceInfo {
        let mut info = self.profile.device_info(Vec3::ZERO, 16, 1000.0);
        info.max_force_n = self.device_max_force_n;
        info
    }

    fn open(&mut self) -> Result<(), DeviceError> {
        if self.stream.is_live() {
            return Ok(());
        }
        let set_up = self.open_inner();
        self.stream.opened(set_up)
    }

    fn close(&mut self) -> Result<(), DeviceError> {
        let zero_force = if self.stream.is_live() {
            self.force_mn = [0; 3];
            self.send_force()
        } else {
            Ok(())
        };
        self.stream.close(zero_force, Instant::now())
    }

    fn is_open(&self) -> bool {
        self.stream.is_open()
    }

    fn read(&mut self) -> Result<DeviceState, DeviceError> {
        self.stream.ready()?;
        if self.session.keep_alive_due() {
            self.send_force()?;
        }
        let fault = self.pump(self.opts.reply_wait, &mut |s, m| s.on_state(m))?;
        if let Some(f) = fault {
            return Err(f);
        }
        self.stream.check(Instant::now())?;
        Ok(self.session.state())
    }

    fn write_force(&mut self, force_n: Vec3) -> Result<(), DeviceError> {
        self.stream.ready()?;
        self.force_mn = cartesian_force_mn(force_n, self.device_max_force_n);
        self.session.force_written();
        self.send_force()
    }
}
