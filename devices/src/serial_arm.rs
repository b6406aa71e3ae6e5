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

use crate::codec::CodecError;
use crate::codec::frame::{self, DeviceMsg, FrameEvent, FrameReader, HostMsg, MAX_FRAME, VERSION};
use crate::device::{DeviceError, DeviceInfo, DeviceState, HapticDevice};
use crate::falcon::LinkStats;
use crate::link_health::LinkHealth;
use crate::profile::DeviceProfile;
use crate::serial_link::{BaudPolicy, SerialLink};
use crate::velocity::VelocityEstimator;

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
    link: Option<SerialLink>,
    health: LinkHealth,
    reader: FrameReader,
    force_mn: [i16; 3],
    seq: u16,
    sent_since_read: bool,
    state: DeviceState,
    device_max_force_n: f32,
    velocity: VelocityEstimator,
    t0: Instant,
    rx_bytes: u64,
    stats: LinkStats,
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
        let health = LinkHealth::new(opts.stale_after, now);
        let device_max_force_n = profile.max_force_n;
        Self {
            path: path.to_string(),
            profile,
            opts,
            link: None,
            health,
            reader: FrameReader::new(),
            force_mn: [0; 3],
            seq: 0,
            sent_since_read: false,
            state: DeviceState::ZERO,
            device_max_force_n,
            velocity: VelocityEstimator::default(),
            t0: now,
            rx_bytes: 0,
            stats: LinkStats::default(),
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
        self.stats
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
        let link = self.link.as_mut().ok_or(DeviceError::NotOpen)?;
        match link.write_all(&buf[..n]) {
            Ok(()) => {
                self.stats.sent += 1;
                Ok(())
            }
            Err(e) => Err(self.health.note(e)),
        }
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
        let mut chunk = [0u8; crate::serial_link::READ_BUF];
        let n = {
            let link = self.link.as_mut().ok_or(DeviceError::NotOpen)?;
            match link.read_available(wait) {
                Ok(b) => {
                    chunk[..b.len()].copy_from_slice(b);
                    b.len()
                }
                Err(e) => return Err(self.health.note(e)),
            }
        };
        let mut fault = None;
        for (i, &b) in chunk[..n].iter().enumerate() {
            let offset = (self.rx_bytes as usize).wrapping_add(i);
            let mut ev = Some(self.reader.push(b));
            while let Some(e) = ev {
                match e {
                    FrameEvent::Pending => {}
                    FrameEvent::Skipped(_) => {
                        self.stats.skipped_bytes += 1;
                        fault.get_or_insert(DeviceError::Protocol {
                            what: "byte outside a frame",
                            offset,
                        });
                    }
                    FrameEvent::Bad(err) => {
                        self.stats.bad_frames += 1;
                        fault.get_or_insert(DeviceError::Protocol {
                            what: fault_name(&err),
                            offset,
                        });
                    }
                    FrameEvent::Frame { kind, .. } => {
                        match DeviceMsg::decode(kind, self.reader.payload()) {
                            Ok(m) => {
                                self.stats.received += 1;
                                on_msg(self, m);
                            }
                            Err(err) => {
                                self.stats.bad_frames += 1;
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
        self.rx_bytes += n as u64;
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
        let mut link = SerialLink::open(
            &self.path,
            self.opts.baud,
            self.opts.baud_policy,
            Duration::from_millis(5),
        )?;
        link.clear_input();
        self.link = Some(link);
        self.health.restart(Instant::now());
        self.reader.reset();
        self.stats = LinkStats::default();
        self.rx_bytes = 0;
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
        self.velocity.reset();
        self.t0 = Instant::now();
        self.health.restart(self.t0);
        self.state = DeviceState::ZERO;
        self.sent_since_read = false;
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
            let t_us = now.duration_since(self.t0).as_micros() as u64;
            let p = Vec3::new(
                position_um[0] as f32,
                position_um[1] as f32,
                position_um[2] as f32,
            ) * 1e-6;
            self.homed = status & frame::status::HOMED != 0;
            self.health.frame(now);
            self.state = DeviceState {
                position_m: p,
                orientation: None,
                velocity_m_per_s: self.velocity.update(p, t_us),
                buttons: u32::from(buttons),
                timestamp_us: t_us,
                sequence: self.state.sequence + 1,
            };
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
        if self.link.is_some() && !self.health.is_dead() {
            return Ok(());
        }
        let r = self.open_inner();
        if r.is_err() {
            self.link = None;
        }
        r
    }

    fn close(&mut self) -> Result<(), DeviceError> {
        let r = if self.link.is_some() && !self.health.is_dead() {
            self.force_mn = [0; 3];
            self.send_force()
        } else {
            Ok(())
        };
        self.link = None;
        self.health.restart(Instant::now());
        match r {
            Err(DeviceError::Disconnected) => Ok(()),
            other => other,
        }
    }

    fn is_open(&self) -> bool {
        self.link.is_some()
    }

    fn read(&mut self) -> Result<DeviceState, DeviceError> {
        if self.link.is_none() {
            return Err(DeviceError::NotOpen);
        }
        self.health.alive()?;
        if !self.sent_since_read {
            self.send_force()?;
        }
        self.sent_since_read = false;
        let fault = self.pump(self.opts.reply_wait, &mut |s, m| s.on_state(m))?;
        if let Some(f) = fault {
            return Err(f);
        }
        let link = &mut self.link;
        self.health.check(Instant::now(), || {
            link.as_mut().is_some_and(|l| l.probe_hangup().is_err())
        })?;
        Ok(self.state)
    }

    fn write_force(&mut self, force_n: Vec3) -> Result<(), DeviceError> {
        if self.link.is_none() {
            return Err(DeviceError::NotOpen);
        }
        self.health.alive()?;
        let f = if force_n.is_finite() {
            force_n.clamp_length_max(self.device_max_force_n)
        } else {
            Vec3::ZERO
        };
        self.force_mn = (f * 1000.0)
            .round()
            .to_array()
            .map(|v| v.clamp(f32::from(i16::MIN), f32::from(i16::MAX)) as i16);
        self.sent_since_read = true;
        self.send_force()
    }
}
