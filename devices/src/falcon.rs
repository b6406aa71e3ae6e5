//! Novint Falcon driver over its FTDI serial link: firmware upload, homing, 1 kHz streaming.
//!
//! `open` does the slow work: it opens the port at 1,456,312 baud, checks whether firmware
//! answers, and if not (and a firmware file was given) runs the bootloader: 9600 baud
//! handshake (`0A 43 0D` → 4 bytes), DTR low, 140,000 baud, `'A'` → 2 bytes, then the image in
//! 62-byte chunks, each of which the bootloader echoes and we compare, retrying the whole load
//! up to `firmware_retries` times. Then it homes (homing bit set, red LED, until all three
//! homed flags are up) and turns the LED green. After that `read`/`write_force` are bounded and
//! allocation-free: one 16-byte command out per tick (a keep-alive if the engine only reads),
//! replies decoded by [`FalconReader`], encoders through the delta kinematics.
//!
//! Baud changes: a pseudo-terminal has no real line rate and some refuse unusual rates, so
//! [`BaudPolicy::Tolerant`] lets tests run the whole bootloader sequence over a PTY; real ports
//! use [`BaudPolicy::Strict`].

use std::path::PathBuf;
use std::time::{Duration, Instant};

use glam::{DVec3, Vec3};

use crate::codec::falcon::{
    self as fc, BOOT_BAUD, FIRMWARE_BAUD, FalconCommand, FalconReader, FalconStatus, LED_GREEN,
    LED_RED, ReadEvent, STREAM_BAUD,
};
use crate::device::{DeviceError, DeviceInfo, DeviceState, HapticDevice};
use crate::kinematics::ArmModel;
use crate::link_health::LinkHealth;
use crate::profile::DeviceProfile;
use crate::serial_link::{BaudPolicy, SerialLink};
use crate::velocity::VelocityEstimator;

/// Bootloader handshake sent at [`BOOT_BAUD`].
pub const BOOT_HELLO: [u8; 3] = [0x0a, 0x43, 0x0d];
/// Bytes the bootloader answers to [`BOOT_HELLO`].
pub const BOOT_HELLO_REPLY_LEN: usize = 4;
/// Byte sent at [`FIRMWARE_BAUD`] to start the upload.
pub const BOOT_START: u8 = b'A';
/// Bytes the bootloader answers to [`BOOT_START`].
pub const BOOT_START_REPLY_LEN: usize = 2;
/// Upload chunk: a full-speed USB packet (64) minus the FTDI's two status bytes.
pub const FIRMWARE_CHUNK: usize = 62;

/// Settings of a [`Falcon`].
#[derive(Clone, Debug, PartialEq)]
pub struct FalconOptions {
    /// Firmware image to upload when none answers (the user's own copy of the Novint firmware).
    pub firmware: Option<PathBuf>,
    /// Whole-upload attempts before giving up.
    pub firmware_retries: u32,
    /// How to treat refused baud-rate changes.
    pub baud_policy: BaudPolicy,
    /// Run the homing routine in `open`.
    pub homing: bool,
    /// Longest time homing may take (the user moves the grip through its range).
    pub homing_timeout: Duration,
    /// Longest wait for a bootloader or firmware answer during `open`.
    pub handshake_timeout: Duration,
    /// Longest `read` waits for the reply to the outstanding command (0: never wait).
    pub reply_wait: Duration,
    /// No valid frame for this long makes `read` fail with a timeout.
    pub stale_after: Duration,
}

impl Default for FalconOptions {
    fn default() -> Self {
        Self {
            firmware: None,
            firmware_retries: 3,
            baud_policy: BaudPolicy::Strict,
            homing: true,
            homing_timeout: Duration::from_secs(30),
            handshake_timeout: Duration::from_millis(500),
            reply_wait: Duration::from_micros(400),
            stale_after: Duration::from_millis(50),
        }
    }
}

/// Counters of what the link has seen since `open`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LinkStats {
    /// Frames sent.
    pub sent: u64,
    /// Valid frames received.
    pub received: u64,
    /// Malformed frames received.
    pub bad_frames: u64,
    /// Bytes skipped outside frames.
    pub skipped_bytes: u64,
    /// Firmware upload attempts in the last `open`.
    pub firmware_attempts: u32,
}

/// A Novint Falcon on a serial port.
pub struct Falcon {
    path: String,
    profile: DeviceProfile,
    model: ArmModel,
    opts: FalconOptions,
    link: Option<SerialLink>,
    health: LinkHealth,
    reader: FalconReader,
    cmd: FalconCommand,
    sent_since_read: bool,
    status: FalconStatus,
    state: DeviceState,
    velocity: VelocityEstimator,
    t0: Instant,
    rx_bytes: u64,
    stats: LinkStats,
}

/// Uploads a firmware image through the Falcon bootloader once (no retries).
///
/// # Errors
/// [`DeviceError::Timeout`] when the bootloader does not answer, [`DeviceError::Protocol`] when
/// an echoed byte differs (offset into the image), or a link error.
pub fn upload_firmware(
    link: &mut SerialLink,
    image: &[u8],
    timeout: Duration,
) -> Result<(), DeviceError> {
    link.set_baud(BOOT_BAUD)?;
    link.set_lines(false, false)?;
    link.set_lines(true, false)?;
    link.clear_input();
    link.write_all(&BOOT_HELLO)?;
    let mut reply = [0u8; BOOT_HELLO_REPLY_LEN];
    link.read_exact_within(&mut reply, timeout)?;
    link.set_lines(false, false)?;
    link.set_baud(FIRMWARE_BAUD)?;
    link.write_all(&[BOOT_START])?;
    let mut reply = [0u8; BOOT_START_REPLY_LEN];
    link.read_exact_within(&mut reply, timeout)?;
    let mut echo = [0u8; FIRMWARE_CHUNK];
    for (k, chunk) in image.chunks(FIRMWARE_CHUNK).enumerate() {
        link.write_all(chunk)?;
        let echo = &mut echo[..chunk.len()];
        link.read_exact_within(echo, timeout)?;
        if let Some(i) = chunk.iter().zip(echo.iter()).position(|(a, b)| a != b) {
            return Err(DeviceError::Protocol {
                what: "firmware echo differs from the image",
                offset: k * FIRMWARE_CHUNK + i,
            });
        }
    }
    link.set_baud(STREAM_BAUD)
}

fn codec_fault(e: &crate::codec::CodecError) -> &'static str {
    match e {
        crate::codec::CodecError::TooShort { .. } => "Falcon frame cut short",
        crate::codec::CodecError::BadByte { field, .. } => field,
        _ => "malformed Falcon frame",
    }
}

impl Falcon {
    /// A Falcon on `path` (not opened yet) with the built-in `falcon` profile.
    #[must_use]
    pub fn new(path: &str, opts: FalconOptions) -> Self {
        let profile =
            DeviceProfile::built_in("falcon").expect("the built-in falcon profile is valid");
        Self::with_profile(path, profile, opts)
            .expect("the built-in falcon profile has delta kinematics")
    }

    /// A Falcon-protocol arm with a custom profile (a recalibrated or modified Falcon).
    ///
    /// # Errors
    /// [`DeviceError::Config`] when the profile has no arm kinematics.
    pub fn with_profile(
        path: &str,
        profile: DeviceProfile,
        opts: FalconOptions,
    ) -> Result<Self, DeviceError> {
        let model = ArmModel::from_profile(&profile).map_err(|e| DeviceError::Config {
            origin: profile.name.clone(),
            message: e.to_string(),
        })?;
        let now = Instant::now();
        let health = LinkHealth::new(opts.stale_after, now);
        Ok(Self {
            path: path.to_string(),
            profile,
            model,
            opts,
            link: None,
            health,
            reader: FalconReader::new(),
            cmd: FalconCommand::default(),
            sent_since_read: false,
            status: FalconStatus::default(),
            state: DeviceState::ZERO,
            velocity: VelocityEstimator::default(),
            t0: now,
            rx_bytes: 0,
            stats: LinkStats::default(),
        })
    }

    /// Points the driver at another port node (the device re-enumerated); takes effect at the
    /// next `open`.
    pub fn set_path(&mut self, path: &str) {
        self.path = path.to_string();
    }

    /// Link counters since `open`.
    #[must_use]
    pub fn link_stats(&self) -> LinkStats {
        self.stats
    }

    /// The last decoded status (encoders, buttons, homed flags).
    #[must_use]
    pub fn status(&self) -> FalconStatus {
        self.status
    }

    fn send(&mut self) -> Result<(), DeviceError> {
        let frame = fc::encode_command(&self.cmd);
        let link = self.link.as_mut().ok_or(DeviceError::NotOpen)?;
        match link.write_all(&frame) {
            Ok(()) => {
                self.stats.sent += 1;
                Ok(())
            }
            Err(e) => Err(self.health.note(e)),
        }
    }

    /// Reads what is queued (waiting up to `wait` for the first byte); returns whether a valid
    /// frame arrived and the first fault seen.
    fn pump(&mut self, wait: Duration) -> Result<(bool, Option<DeviceError>), DeviceError> {
        let link = self.link.as_mut().ok_or(DeviceError::NotOpen)?;
        let bytes = match link.read_available(wait) {
            Ok(b) => b,
            Err(e) => return Err(self.health.note(e)),
        };
        let mut fresh = false;
        let mut fault = None;
        for (i, &b) in bytes.iter().enumerate() {
            let offset = (self.rx_bytes as usize).wrapping_add(i);
            match self.reader.push(b) {
                ReadEvent::Pending => {}
                ReadEvent::Frame(s) => {
                    self.status = s;
                    fresh = true;
                    self.stats.received += 1;
                }
                ReadEvent::Skipped(_) => {
                    self.stats.skipped_bytes += 1;
                    fault.get_or_insert(DeviceError::Protocol {
                        what: "byte outside a Falcon frame",
                        offset,
                    });
                }
                ReadEvent::Bad(e) => {
                    self.stats.bad_frames += 1;
                    fault.get_or_insert(DeviceError::Protocol {
                        what: codec_fault(&e),
                        offset,
                    });
                }
            }
        }
        self.rx_bytes += bytes.len() as u64;
        Ok((fresh, fault))
    }

    /// Sends the current command and waits up to `timeout` for any valid reply.
    fn exchange(&mut self, timeout: Duration) -> Result<bool, DeviceError> {
        self.send()?;
        let start = Instant::now();
        while start.elapsed() < timeout {
            if self.pump(Duration::from_millis(1))?.0 {
                return Ok(true);
            }
        }
        Ok(false)
    }

    fn firmware_answers(&mut self) -> Result<bool, DeviceError> {
        for _ in 0..3 {
            if self.exchange(self.opts.handshake_timeout / 3)? {
                return Ok(true);
            }
        }
        Ok(false)
    }

    fn load_firmware(&mut self) -> Result<(), DeviceError> {
        let Some(file) = self.opts.firmware.clone() else {
            return Err(DeviceError::Config {
                origin: format!("falcon:{}", self.path),
                message: "no firmware answers on this port; give the Falcon firmware file (DYNACLAY_FALCON_FIRMWARE)".into(),
            });
        };
        // Falcon firmware images are tens of kilobytes; a FIFO or a device is refused at once.
        let image = dynaclay_files::read_regular_file(&file, 16 << 20).map_err(|e| {
            DeviceError::Config {
                origin: file.display().to_string(),
                message: format!("cannot read the Falcon firmware file: {e}"),
            }
        })?;
        if image.is_empty() {
            return Err(DeviceError::Config {
                origin: file.display().to_string(),
                message: "the firmware file is empty".into(),
            });
        }
        let mut last = DeviceError::Timeout { waited_us: 0 };
        for attempt in 1..=self.opts.firmware_retries.max(1) {
            self.stats.firmware_attempts = attempt;
            let link = self.link.as_mut().ok_or(DeviceError::NotOpen)?;
            match upload_firmware(link, &image, self.opts.handshake_timeout) {
                Ok(()) => {
                    self.reader.reset();
                    if let Some(l) = self.link.as_mut() {
                        l.clear_input();
                    }
                    if self.firmware_answers()? {
                        return Ok(());
                    }
                    last = DeviceError::Timeout {
                        waited_us: self.opts.handshake_timeout.as_micros() as u64,
                    };
                }
                Err(DeviceError::Disconnected) => return Err(DeviceError::Disconnected),
                Err(e) => last = e,
            }
        }
        Err(last)
    }

    fn home(&mut self) -> Result<(), DeviceError> {
        let start = Instant::now();
        self.cmd = FalconCommand {
            motor: [0; 3],
            leds: LED_RED,
            homing: true,
        };
        while !self.status.all_homed() {
            if start.elapsed() > self.opts.homing_timeout {
                return Err(DeviceError::Timeout {
                    waited_us: start.elapsed().as_micros() as u64,
                });
            }
            self.exchange(Duration::from_millis(20))?;
        }
        self.cmd = FalconCommand {
            motor: [0; 3],
            leds: LED_GREEN,
            homing: false,
        };
        self.exchange(Duration::from_millis(20))?;
        Ok(())
    }

    fn open_inner(&mut self) -> Result<(), DeviceError> {
        self.link = Some(SerialLink::open(
            &self.path,
            STREAM_BAUD,
            self.opts.baud_policy,
            Duration::from_millis(5),
        )?);
        self.health.restart(Instant::now());
        self.reader.reset();
        self.stats = LinkStats::default();
        self.rx_bytes = 0;
        self.cmd = FalconCommand {
            motor: [0; 3],
            leds: LED_GREEN,
            homing: false,
        };
        if let Some(l) = self.link.as_mut() {
            l.clear_input();
        }
        if !self.firmware_answers()? {
            self.load_firmware()?;
        }
        if self.opts.homing {
            self.home()?;
        }
        self.model.reset();
        self.velocity.reset();
        self.t0 = Instant::now();
        self.health.restart(self.t0);
        self.state = DeviceState::ZERO;
        self.sent_since_read = false;
        Ok(())
    }
}

impl HapticDevice for Falcon {
    fn info(&self) -> DeviceInfo {
        let center = match self.model.linkage {
            crate::kinematics::Linkage::Delta(d) => d.home_guess_m.as_vec3(),
            crate::kinematics::Linkage::Serial(_) => Vec3::ZERO,
        };
        self.profile.device_info(center, 4, 1000.0)
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
            self.cmd = FalconCommand {
                motor: [0; 3],
                leds: 0,
                homing: false,
            };
            self.send()
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
            // Keep the stream flowing: the firmware answers one frame per command.
            self.send()?;
        }
        self.sent_since_read = false;
        let (fresh, fault) = self.pump(self.opts.reply_wait)?;
        let now = Instant::now();
        if fresh {
            self.health.frame(now);
            // Keep the last good position if the solve fails (a glitch near a singularity).
            if let Ok(p) = self.model.update(self.status.encoders) {
                let t_us = now.duration_since(self.t0).as_micros() as u64;
                let p = p.as_vec3();
                self.state = DeviceState {
                    position_m: p,
                    orientation: None,
                    velocity_m_per_s: self.velocity.update(p, t_us),
                    buttons: u32::from(self.status.buttons),
                    timestamp_us: t_us,
                    sequence: self.state.sequence + 1,
                };
            }
        }
        if let Some(f) = fault {
            return Err(f);
        }
        let link = &mut self.link;
        self.health.check(now, || {
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
            force_n.as_dvec3()
        } else {
            DVec3::ZERO
        };
        self.cmd.motor = self.model.commands_for_force(f);
        self.sent_since_read = true;
        self.send()
    }
}
