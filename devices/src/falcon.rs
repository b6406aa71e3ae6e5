//! Novint Falcon driver over its FTDI serial link: firmware upload, homing, 1 kHz streaming.
//!
//! `open` does the slow work: it opens the port at 1,456,312 baud, sets the FTDI latency timer
//! to 1 ms ([`crate::ftdi_latency`]; at the default 16 ms a reply waits up to 16 ms and 1 kHz
//! is out of reach), checks whether firmware answers, and if not (and a firmware file was
//! given) runs the bootloader with the timer at 16 ms: 9600 baud handshake (`0A 43 0D` →
//! `0A 44 2C 0D`, sometimes after a `00`), DTR low, 140,000 baud, `'A'` → `'A'`, then the
//! image in 62-byte chunks, each of which the bootloader echoes and we compare, retrying the
//! whole load up to `firmware_retries` times. Then it homes (homing bit set, red LED, until the
//! homed flags of all three motors are up) and turns the LED green. After that
//! `read`/`write_force` are bounded and allocation-free: one 16-byte command out per tick (a
//! keep-alive if the engine only reads), replies decoded by [`FalconReader`], encoders through
//! the delta kinematics.
//!
//! The handshake bytes, the latency timer settings and the homing bits follow libnifalcon's
//! reverse-engineered protocol (`FalconCommLibUSB`, `FalconFirmwareNovintSDK`); see
//! [`crate::codec::falcon`] for the frame layout.
//!
//! Time: the status frame carries no clock, so each sample is stamped on the host's clock when
//! its reply is decoded ([`SampleClock::Host`]); a lockstep run counts the replies instead
//! ([`SampleClock::LOCKSTEP_1KHZ`]: the firmware answers each command with one frame, one
//! command per tick), so its soft start, velocities and forces do not depend on the machine.
//!
//! Baud changes: a pseudo-terminal has no real line rate and some refuse unusual rates, so
//! [`BaudPolicy::Tolerant`] lets tests run the whole bootloader sequence over a PTY; real ports
//! use [`BaudPolicy::Strict`].

use std::path::PathBuf;
use std::time::{Duration, Instant};

use glam::{DVec3, Vec3};

use crate::arm_link::{ArmSession, SerialStream, arm_model};
pub use crate::arm_link::{LinkStats, SampleClock};
use crate::codec::CodecError;
use crate::codec::falcon::{
    self as fc, BOOT_BAUD, FIRMWARE_BAUD, FalconCommand, FalconReader, FalconStatus, LED_GREEN,
    LED_RED, ReadEvent, STREAM_BAUD,
};
use crate::device::{DeviceError, DeviceInfo, DeviceState, HapticDevice};
use crate::ftdi_latency::{self, LatencyOutcome};
use crate::kinematics::{ArmModel, Linkage};
use crate::profile::DeviceProfile;
use crate::serial_link::{BaudPolicy, READ_BUF, SerialLink};

/// Bootloader handshake sent at [`BOOT_BAUD`].
pub const BOOT_HELLO: [u8; 3] = [0x0a, 0x43, 0x0d];
/// The bootloader's answer to [`BOOT_HELLO`]; some hosts see a `00` before it.
pub const BOOT_HELLO_REPLY: [u8; 4] = [0x0a, 0x44, 0x2c, 0x0d];
/// Byte sent at [`FIRMWARE_BAUD`] to start the upload.
pub const BOOT_START: u8 = b'A';
/// The bootloader's one-byte answer to [`BOOT_START`].
pub const BOOT_START_REPLY: u8 = b'A';
/// Upload chunk: a full-speed USB packet (64) minus the FTDI's two status bytes.
pub const FIRMWARE_CHUNK: usize = 62;

/// Longest wait for each homing reply in real time; a lockstep run's longer
/// [`FalconOptions::reply_wait`] wins (see [`Falcon::open_reply_wait`]).
const HOMING_REPLY_WAIT: Duration = Duration::from_millis(20);

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
    /// Where the port's FTDI latency timer is found (`/sys/bus/usb-serial/devices`; a test
    /// points it at a stand-in folder).
    pub usb_serial_sysfs: PathBuf,
    /// Where the samples' time stamps come from (the status frame carries no time): the
    /// host's clock in real time; [`SampleClock::LOCKSTEP_1KHZ`] in a lockstep run, where the
    /// firmware's one reply per command is the device's clock.
    pub sample_clock: SampleClock,
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
            usb_serial_sysfs: PathBuf::from(ftdi_latency::USB_SERIAL_SYSFS),
            sample_clock: SampleClock::Host,
        }
    }
}

/// A Novint Falcon on a serial port.
pub struct Falcon {
    path: String,
    profile: DeviceProfile,
    model: ArmModel,
    opts: FalconOptions,
    stream: SerialStream,
    session: ArmSession,
    reader: FalconReader,
    cmd: FalconCommand,
    status: FalconStatus,
    latency: LatencyOutcome,
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
    let mut reply = [0u8; BOOT_HELLO_REPLY.len()];
    link.read_exact_within(&mut reply, timeout)?;
    if reply[0] == 0x00 {
        // The answer came after a 00: drop it and read the answer's last byte.
        reply.copy_within(1.., 0);
        link.read_exact_within(&mut reply[BOOT_HELLO_REPLY.len() - 1..], timeout)?;
    }
    if let Some(i) = reply
        .iter()
        .zip(BOOT_HELLO_REPLY)
        .position(|(a, b)| *a != b)
    {
        return Err(DeviceError::Protocol {
            what: "bootloader's handshake answer is not 0A 44 2C 0D",
            offset: i,
        });
    }
    link.set_lines(false, false)?;
    link.set_baud(FIRMWARE_BAUD)?;
    link.write_all(&[BOOT_START])?;
    let mut reply = [0u8; 1];
    link.read_exact_within(&mut reply, timeout)?;
    if reply[0] != BOOT_START_REPLY {
        return Err(DeviceError::Protocol {
            what: "bootloader's answer to 'A' is not 'A'",
            offset: 0,
        });
    }
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

fn codec_fault(e: &CodecError) -> &'static str {
    match e {
        CodecError::TooShort { .. } => "Falcon frame cut short",
        CodecError::BadByte { field, .. } => field,
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
        let model = arm_model(&profile)?;
        let now = Instant::now();
        Ok(Self {
            path: path.to_string(),
            profile,
            model,
            stream: SerialStream::new(opts.stale_after, now),
            session: ArmSession::with_clock(now, opts.sample_clock),
            opts,
            reader: FalconReader::new(),
            cmd: FalconCommand::default(),
            status: FalconStatus::default(),
            latency: LatencyOutcome::NotTried,
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
        self.stream.stats
    }

    /// The last decoded status (encoders, buttons, homed flags).
    #[must_use]
    pub fn status(&self) -> FalconStatus {
        self.status
    }

    /// What the last `open` did to the port's FTDI latency timer (set to 1 ms, or why not).
    #[must_use]
    pub fn latency_timer(&self) -> &LatencyOutcome {
        &self.latency
    }

    fn set_latency(&mut self, ms: u8) {
        self.latency = ftdi_latency::set_latency_timer(
            &self.opts.usb_serial_sysfs,
            std::path::Path::new(&self.path),
            ms,
        );
    }

    fn send(&mut self) -> Result<(), DeviceError> {
        self.stream.write_frame(&fc::encode_command(&self.cmd))
    }

    /// Reads what is queued (waiting up to `wait` for the first byte); returns whether a valid
    /// frame arrived and the first fault seen.
    fn pump(&mut self, wait: Duration) -> Result<(bool, Option<DeviceError>), DeviceError> {
        let mut chunk = [0u8; READ_BUF];
        let received = self.stream.read_chunk(wait, &mut chunk)?;
        let mut fresh = false;
        let mut fault = None;
        for (i, &b) in chunk[..received.len].iter().enumerate() {
            let offset = received.first_offset.wrapping_add(i);
            match self.reader.push(b) {
                ReadEvent::Pending => {}
                ReadEvent::Frame(s) => {
                    self.status = s;
                    fresh = true;
                    self.stream.stats.received += 1;
                }
                ReadEvent::Skipped(_) => {
                    self.stream.stats.skipped_bytes += 1;
                    fault.get_or_insert(DeviceError::Protocol {
                        what: "byte outside a Falcon frame",
                        offset,
                    });
                }
                ReadEvent::Bad(e) => {
                    self.stream.stats.bad_frames += 1;
                    fault.get_or_insert(DeviceError::Protocol {
                        what: codec_fault(&e),
                        offset,
                    });
                }
            }
        }
        Ok((fresh, fault))
    }

    /// Reads the reply to the outstanding command within [`FalconOptions::reply_wait`]: the
    /// first bytes, then, while a frame is started but not whole, the rest of it. A reply can
    /// reach the port in pieces (a loaded machine runs the other side's write in between);
    /// stopping at the first piece would report the previous sample again and take this
    /// reply on the next read, one tick late, so a lockstep run would depend on the load.
    fn pump_reply(&mut self) -> Result<(bool, Option<DeviceError>), DeviceError> {
        let start = Instant::now();
        let (mut fresh, mut fault) = self.pump(self.opts.reply_wait)?;
        while !fresh && fault.is_none() && self.reader.is_mid_frame() {
            let left = self.opts.reply_wait.saturating_sub(start.elapsed());
            if left.is_zero() {
                break;
            }
            (fresh, fault) = self.pump(left)?;
        }
        Ok((fresh, fault))
    }

    /// Sends the current command and waits up to `timeout` for any valid reply (asleep while
    /// nothing comes: `open` is off the real-time path).
    fn exchange(&mut self, timeout: Duration) -> Result<bool, DeviceError> {
        self.send()?;
        let start = Instant::now();
        loop {
            let left = timeout.saturating_sub(start.elapsed());
            if left.is_zero() {
                return Ok(false);
            }
            if self.pump(left)?.0 {
                return Ok(true);
            }
        }
    }

    /// How long one exchange of `open` waits for its reply, at least `floor`: never less than
    /// the streaming reply wait. A reply that comes after its exchange gave up stays in flight
    /// while the next command is sent, so the stream would start one reply ahead of the
    /// commands; a lockstep run (reply wait 1 s) counts replies as its clock and must start
    /// with none in flight, however loaded the machine.
    fn open_reply_wait(&self, floor: Duration) -> Duration {
        floor.max(self.opts.reply_wait)
    }

    fn firmware_answers(&mut self) -> Result<bool, DeviceError> {
        let wait = self.open_reply_wait(self.opts.handshake_timeout / 3);
        for _ in 0..3 {
            if self.exchange(wait)? {
                return Ok(true);
            }
        }
        Ok(false)
    }

    fn load_firmware(&mut self) -> Result<(), DeviceError> {
        let Some(file) = self.opts.firmware.clone() else {
            return Err(DeviceError::Config {
                origin: format!("falcon:{}", self.path),
                message: "firmware not loaded: no firmware answers on this port; name the Novint firmware file with --falcon-firmware FILE, DYNACLAY_FALCON_FIRMWARE or the profile's `firmware`".into(),
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
        // libnifalcon loads firmware with the timer at 16 ms ("firmware checks tend to fail"
        // at 1 ms) and streams at 1 ms; the outcome kept is the streaming one.
        self.set_latency(ftdi_latency::BOOTLOADER_LATENCY_MS);
        let loaded = self.upload_with_retries(&image);
        self.set_latency(ftdi_latency::STREAM_LATENCY_MS);
        loaded
    }

    fn upload_with_retries(&mut self, image: &[u8]) -> Result<(), DeviceError> {
        let mut last = DeviceError::Timeout { waited_us: 0 };
        for attempt in 1..=self.opts.firmware_retries.max(1) {
            self.stream.stats.firmware_attempts = attempt;
            let link = self.stream.link_mut()?;
            match upload_firmware(link, image, self.opts.handshake_timeout) {
                Ok(()) => {
                    self.reader.reset();
                    self.stream.clear_input();
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
        let wait = self.open_reply_wait(HOMING_REPLY_WAIT);
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
            self.exchange(wait)?;
        }
        self.cmd = FalconCommand {
            motor: [0; 3],
            leds: LED_GREEN,
            homing: false,
        };
        self.exchange(wait)?;
        Ok(())
    }

    fn open_inner(&mut self) -> Result<(), DeviceError> {
        self.stream.open(
            &self.path,
            STREAM_BAUD,
            self.opts.baud_policy,
            Instant::now(),
        )?;
        self.set_latency(ftdi_latency::STREAM_LATENCY_MS);
        self.reader.reset();
        self.cmd = FalconCommand {
            motor: [0; 3],
            leds: LED_GREEN,
            homing: false,
        };
        if !self.firmware_answers()? {
            self.load_firmware()?;
        }
        if self.opts.homing {
            self.home()?;
        }
        self.model.reset();
        let now = Instant::now();
        self.session.start(now);
        self.stream.live_from(now);
        Ok(())
    }
}

impl HapticDevice for Falcon {
    fn info(&self) -> DeviceInfo {
        let center = match self.model.linkage {
            Linkage::Delta(d) => d.home_guess_m.as_vec3(),
            Linkage::Serial(_) => Vec3::ZERO,
        };
        self.profile.device_info(center, 4, 1000.0)
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
            self.cmd = FalconCommand {
                motor: [0; 3],
                leds: 0,
                homing: false,
            };
            self.send()
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
            // Keep the stream flowing: the firmware answers one frame per command.
            self.send()?;
        }
        let (fresh, fault) = self.pump_reply()?;
        let now = Instant::now();
        if fresh {
            self.stream.frame_received(now);
            // Stamped whether or not the solve succeeds: a reply is a tick of the device's
            // clock either way.
            let t_us = self.session.reply_time_us(now);
            // Keep the last good position if the solve fails (a glitch near a singularity).
            if let Ok(p) = self.model.update(self.status.encoders) {
                self.session
                    .sample(p.as_vec3(), u32::from(self.status.buttons), t_us);
            }
        }
        if let Some(f) = fault {
            return Err(f);
        }
        self.stream.check(now)?;
        Ok(self.session.state())
    }

    fn write_force(&mut self, force_n: Vec3) -> Result<(), DeviceError> {
        self.stream.ready()?;
        let f = if force_n.is_finite() {
            force_n.as_dvec3()
        } else {
            DVec3::ZERO
        };
        self.cmd.motor = self.model.commands_for_force(f);
        self.session.force_written();
        self.send()
    }
}
