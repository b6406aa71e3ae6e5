//! The set-up every streaming arm driver shares, so each driver states only its wire protocol,
//! its handshake and its kinematics: the link counters ([`LinkStats`]), one session's host-side
//! bookkeeping (`ArmSession`: session clock, velocity filter, last state, keep-alive rule),
//! the serial port with its health, counters and byte offsets (`SerialStream`), where a
//! sample's time stamp comes from ([`SampleClock`]), and the
//! small rules the drivers agree on (building the arm model, clamping a Cartesian force,
//! what closing reports).
//!
//! After `open`, nothing here allocates, and with a real-time reply wait nothing blocks:
//! `SerialStream` reads only what is queued (spinning at most the wait it is given; a wait over
//! [`crate::serial_link::SPIN_WAIT_LIMIT`], a lockstep run's, sleeps in the kernel instead) and
//! writes wait at most the port's write timeout.
//! The session clock and the link health take the time as an argument, so their rules are
//! tested on an injected clock.

use std::num::NonZeroU32;
use std::time::{Duration, Instant};

use glam::Vec3;

use crate::device::{DeviceError, DeviceState};
use crate::kinematics::ArmModel;
use crate::link_health::LinkHealth;
use crate::profile::DeviceProfile;
use crate::serial_link::{BaudPolicy, READ_BUF, SerialLink};
use crate::velocity::VelocityEstimator;

/// Longest wait for the OS to accept a write on a streaming serial link.
pub const SERIAL_WRITE_TIMEOUT: Duration = Duration::from_millis(5);

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

/// Where a streaming arm's samples take their time stamps (the device time the safety
/// filter's soft start, the velocity filter and the haptic renderer run on) when the firmware's
/// frames carry no clock of their own.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SampleClock {
    /// The host's monotonic clock when the reply was decoded, counted from the end of `open`:
    /// the time the sample really arrived, for real-time runs.
    #[default]
    Host,
    /// The `k`-th reply after `open` is stamped `k × period_us`: the device's clock when the
    /// firmware answers each command with exactly one frame and the engine sends one command
    /// per tick (a lockstep run), so the stamps, and everything computed from them, depend on
    /// the exchanges and never on how fast the machine ran them.
    PerReply {
        /// The time between two replies, microseconds (never zero, so time moves on).
        period_us: NonZeroU32,
    },
}

impl SampleClock {
    /// One reply per millisecond: the clock of a lockstep run at the 1 kHz haptic rate.
    pub const LOCKSTEP_1KHZ: Self = Self::PerReply {
        period_us: NonZeroU32::new(1000).expect("1000 is not zero"),
    };

    /// The time stamp of the `reply`-th reply of a session (counting from 1), decoded
    /// `since_start` after the session started, microseconds on this clock.
    #[must_use]
    pub fn stamp_us(self, reply: u64, since_start: Duration) -> u64 {
        match self {
            Self::Host => u64::try_from(since_start.as_micros()).unwrap_or(u64::MAX),
            Self::PerReply { period_us } => reply.saturating_mul(u64::from(period_us.get())),
        }
    }
}

/// The arm model a profile describes.
///
/// # Errors
/// [`DeviceError::Config`], naming the profile, when it has no arm kinematics.
pub(crate) fn arm_model(profile: &DeviceProfile) -> Result<ArmModel, DeviceError> {
    ArmModel::from_profile(profile).map_err(|e| DeviceError::Config {
        origin: profile.name.clone(),
        message: e.to_string(),
    })
}

/// The force an arm is asked for, made safe to encode: a non-finite force is zero, a finite
/// one is clamped to `max_force_n` in length.
#[must_use]
pub(crate) fn limited_force_n(force_n: Vec3, max_force_n: f32) -> Vec3 {
    if force_n.is_finite() {
        force_n.clamp_length_max(max_force_n)
    } else {
        Vec3::ZERO
    }
}

/// The force a Cartesian firmware is sent, in mN: a non-finite force is zero, a finite one is
/// clamped to `max_force_n` in length, and each axis saturates to the `i16` range.
#[must_use]
pub(crate) fn cartesian_force_mn(force_n: Vec3, max_force_n: f32) -> [i16; 3] {
    (limited_force_n(force_n, max_force_n) * 1000.0)
        .round()
        .to_array()
        .map(|v| v.clamp(f32::from(i16::MIN), f32::from(i16::MAX)) as i16)
}

/// What `close` reports after its zero-force send: a device that is already gone has closed
/// cleanly; any other failure is reported.
///
/// # Errors
/// The zero-force send's error, unless it is [`DeviceError::Disconnected`].
pub(crate) fn close_result(zero_force: Result<(), DeviceError>) -> Result<(), DeviceError> {
    match zero_force {
        Err(DeviceError::Disconnected) => Ok(()),
        other => other,
    }
}

/// The host side of one streaming session: when it started, how its samples are stamped
/// ([`SampleClock`]) and how many replies it has stamped, the velocity filter, the last state
/// handed out and whether the engine has written since the last read (when it has not, `read`
/// sends a keep-alive so the firmware keeps streaming and its watchdog stays fed).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct ArmSession {
    started: Instant,
    clock: SampleClock,
    replies: u64,
    velocity: VelocityEstimator,
    state: DeviceState,
    written_since_read: bool,
}

impl ArmSession {
    /// A session that has not streamed yet, its clock starting at `now`, stamping samples on
    /// the host's clock.
    #[must_use]
    pub(crate) fn new(now: Instant) -> Self {
        Self::with_clock(now, SampleClock::Host)
    }

    /// A session that has not streamed yet, its clock starting at `now`, stamping samples on
    /// `clock`.
    #[must_use]
    pub(crate) fn with_clock(now: Instant, clock: SampleClock) -> Self {
        Self {
            started: now,
            clock,
            replies: 0,
            velocity: VelocityEstimator::default(),
            state: DeviceState::ZERO,
            written_since_read: false,
        }
    }

    /// Starts a fresh session at `now` (the end of a successful `open`): the clock restarts,
    /// the velocity filter forgets, the state is [`DeviceState::ZERO`] and the first read sends
    /// a keep-alive.
    pub(crate) fn start(&mut self, now: Instant) {
        self.started = now;
        self.replies = 0;
        self.velocity.reset();
        self.state = DeviceState::ZERO;
        self.written_since_read = false;
    }

    /// Microseconds from the session's start to `now` (zero for an earlier `now`).
    #[must_use]
    pub(crate) fn elapsed_us(&self, now: Instant) -> u64 {
        now.duration_since(self.started).as_micros() as u64
    }

    /// Counts one reply decoded at `now` and returns its time stamp on the session's
    /// [`SampleClock`], microseconds since the session started.
    pub(crate) fn reply_time_us(&mut self, now: Instant) -> u64 {
        self.replies += 1;
        self.clock
            .stamp_us(self.replies, now.saturating_duration_since(self.started))
    }

    /// Takes a fresh sample at `t_us` on the session clock: the velocity comes from the filter
    /// and the sequence counts on. Returns the new state.
    pub(crate) fn sample(&mut self, position_m: Vec3, buttons: u32, t_us: u64) -> DeviceState {
        self.state = DeviceState {
            position_m,
            orientation: None,
            velocity_m_per_s: self.velocity.update(position_m, t_us),
            buttons,
            timestamp_us: t_us,
            sequence: self.state.sequence + 1,
        };
        self.state
    }

    /// The last state (the previous sample again when nothing new has arrived).
    #[must_use]
    pub(crate) fn state(&self) -> DeviceState {
        self.state
    }

    /// The engine wrote a force: the next read needs no keep-alive.
    pub(crate) fn force_written(&mut self) {
        self.written_since_read = true;
    }

    /// Whether this read must send a keep-alive (nothing written since the previous read);
    /// starts the next read's count.
    pub(crate) fn keep_alive_due(&mut self) -> bool {
        !std::mem::replace(&mut self.written_since_read, false)
    }
}

/// Where a chunk read by [`SerialStream::read_chunk`] sits in the session's byte stream.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Chunk {
    /// Bytes read into the buffer.
    pub len: usize,
    /// Offset of the chunk's first byte since `open` (protocol errors name it).
    pub first_offset: usize,
}

/// A serial port as a streaming arm holds it: open or not, its [`LinkHealth`], the
/// [`LinkStats`] and the byte offset since `open`. Every link error passes through the health,
/// so a hang-up leaves the link dead until it is opened again.
pub(crate) struct SerialStream {
    link: Option<SerialLink>,
    health: LinkHealth,
    /// Counters since `open`.
    pub stats: LinkStats,
    rx_bytes: u64,
}

impl SerialStream {
    /// A stream not opened yet, silent after `stale_after` without a frame.
    #[must_use]
    pub(crate) fn new(stale_after: Duration, now: Instant) -> Self {
        Self {
            link: None,
            health: LinkHealth::new(stale_after, now),
            stats: LinkStats::default(),
            rx_bytes: 0,
        }
    }

    /// Opens `path` at `baud`, 8N1, with [`SERIAL_WRITE_TIMEOUT`], and starts a session on it
    /// (see [`SerialStream::attach`]).
    ///
    /// # Errors
    /// [`DeviceError::NotFound`], [`DeviceError::PermissionDenied`], [`DeviceError::Config`] or
    /// [`DeviceError::Io`] from opening the port.
    pub(crate) fn open(
        &mut self,
        path: &str,
        baud: u32,
        policy: BaudPolicy,
        now: Instant,
    ) -> Result<(), DeviceError> {
        let link = SerialLink::open(path, baud, policy, SERIAL_WRITE_TIMEOUT)?;
        self.attach(link, now);
        Ok(())
    }

    /// Starts a session on an open link: queued input is dropped, counters and offsets are
    /// zero, and the link is live at `now`.
    pub(crate) fn attach(&mut self, mut link: SerialLink, now: Instant) {
        link.clear_input();
        self.link = Some(link);
        self.health.restart(now);
        self.stats = LinkStats::default();
        self.rx_bytes = 0;
    }

    /// Whether a link is held (it may be dead).
    #[must_use]
    pub(crate) fn is_open(&self) -> bool {
        self.link.is_some()
    }

    /// Whether a link is held and the other side has not hung up: `open` has nothing to do
    /// and `close` sends its zero force.
    #[must_use]
    pub(crate) fn is_live(&self) -> bool {
        self.link.is_some() && !self.health.is_dead()
    }

    /// What an `open` that ran its set-up reports: on failure the half-open link is dropped,
    /// so the next `open` starts over.
    ///
    /// # Errors
    /// `set_up`'s error, unchanged.
    pub(crate) fn opened(&mut self, set_up: Result<(), DeviceError>) -> Result<(), DeviceError> {
        if set_up.is_err() {
            self.link = None;
        }
        set_up
    }

    /// Drops the link after `close`'s zero-force send and reports it (see [`close_result`]);
    /// the health starts over at `now`.
    ///
    /// # Errors
    /// The zero-force send's error, unless it is [`DeviceError::Disconnected`].
    pub(crate) fn close(
        &mut self,
        zero_force: Result<(), DeviceError>,
        now: Instant,
    ) -> Result<(), DeviceError> {
        self.link = None;
        self.health.restart(now);
        close_result(zero_force)
    }

    /// Whether `read` and `write_force` may use the link.
    ///
    /// # Errors
    /// [`DeviceError::NotOpen`] without a link, [`DeviceError::Disconnected`] on a dead one.
    pub(crate) fn ready(&self) -> Result<(), DeviceError> {
        if self.link.is_none() {
            return Err(DeviceError::NotOpen);
        }
        self.health.alive()
    }

    /// The open link, for set-up steps that drive the port directly (a firmware upload).
    ///
    /// # Errors
    /// [`DeviceError::NotOpen`] without a link.
    pub(crate) fn link_mut(&mut self) -> Result<&mut SerialLink, DeviceError> {
        self.link.as_mut().ok_or(DeviceError::NotOpen)
    }

    /// Drops whatever input is queued (nothing without a link).
    pub(crate) fn clear_input(&mut self) {
        if let Some(link) = self.link.as_mut() {
            link.clear_input();
        }
    }

    /// Writes one encoded frame and counts it.
    ///
    /// # Errors
    /// [`DeviceError::NotOpen`], or the link's error ([`DeviceError::Disconnected`] makes the
    /// link dead).
    pub(crate) fn write_frame(&mut self, frame: &[u8]) -> Result<(), DeviceError> {
        let link = self.link.as_mut().ok_or(DeviceError::NotOpen)?;
        match link.write_all(frame) {
            Ok(()) => {
                self.stats.sent += 1;
                Ok(())
            }
            Err(e) => Err(self.health.note(e)),
        }
    }

    /// Copies the bytes queued now into `buf`, waiting (by spinning) up to `wait` for the
    /// first one, and says where they sit in the byte stream.
    ///
    /// # Errors
    /// [`DeviceError::NotOpen`], or the link's error ([`DeviceError::Disconnected`] makes the
    /// link dead).
    pub(crate) fn read_chunk(
        &mut self,
        wait: Duration,
        buf: &mut [u8; READ_BUF],
    ) -> Result<Chunk, DeviceError> {
        let link = self.link.as_mut().ok_or(DeviceError::NotOpen)?;
        let len = match link.read_available(wait) {
            Ok(bytes) => {
                buf[..bytes.len()].copy_from_slice(bytes);
                bytes.len()
            }
            Err(e) => return Err(self.health.note(e)),
        };
        let chunk = Chunk {
            len,
            first_offset: self.rx_bytes as usize,
        };
        self.rx_bytes += len as u64;
        Ok(chunk)
    }

    /// The set-up is done: the link is live from `now`.
    pub(crate) fn live_from(&mut self, now: Instant) {
        self.health.restart(now);
    }

    /// A good frame arrived at `now`.
    pub(crate) fn frame_received(&mut self, now: Instant) {
        self.health.frame(now);
    }

    /// What a read at `now` reports about the link: after a silence the port is probed for a
    /// hang-up (see [`LinkHealth::check`]).
    ///
    /// # Errors
    /// [`DeviceError::Disconnected`] on a dead link, [`DeviceError::Timeout`] on a silent one.
    pub(crate) fn check(&mut self, now: Instant) -> Result<(), DeviceError> {
        let link = &mut self.link;
        self.health.check(now, || {
            link.as_mut().is_some_and(|l| l.probe_hangup().is_err())
        })
    }
}

#[cfg(test)]
mod tests {
    use std::io::{Read, Write};

    use serialport::{SerialPort, TTYPort};

    use super::*;

    const MS: Duration = Duration::from_millis(1);

    #[test]
    fn a_session_samples_on_its_own_clock_and_starts_over_clean() {
        let t0 = Instant::now();
        let mut s = ArmSession::new(t0);
        assert_eq!(s.elapsed_us(t0 + 3 * MS), 3000);
        assert_eq!(s.elapsed_us(t0 - MS), 0, "an earlier instant is time zero");
        s.sample(Vec3::ZERO, 0, 0);
        let mut last = s.state();
        for k in 1..=200u64 {
            last = s.sample(Vec3::new(0.1e-3 * k as f32, 0.0, 0.0), 5, k * 1000);
        }
        assert_eq!(last, s.state());
        assert_eq!(last.sequence, 201);
        assert_eq!((last.buttons, last.timestamp_us), (5, 200_000));
        assert!((last.velocity_m_per_s.x - 0.1).abs() < 1e-2, "{last:?}");

        s.force_written();
        s.start(t0 + 500 * MS);
        assert_eq!(s.state(), DeviceState::ZERO);
        assert_eq!(s.elapsed_us(t0 + 501 * MS), 1000);
        assert!(
            s.keep_alive_due(),
            "a new session's first read sends a keep-alive"
        );
        // The velocity filter forgot the old session: one sample gives no velocity.
        assert_eq!(s.sample(Vec3::ONE, 0, 10).velocity_m_per_s, Vec3::ZERO);
        assert_eq!(s.state().sequence, 1);
    }

    #[test]
    fn replies_are_stamped_by_the_host_clock_or_counted_one_period_apart() {
        let t0 = Instant::now();
        let mut host = ArmSession::new(t0);
        assert_eq!(host.reply_time_us(t0 + 7 * MS), 7000);
        assert_eq!(
            host.reply_time_us(t0 + 7 * MS),
            7000,
            "the time, not the count"
        );

        let mut counted = ArmSession::with_clock(t0, SampleClock::LOCKSTEP_1KHZ);
        // However late or early the replies are decoded, the k-th is k ms after the start.
        assert_eq!(counted.reply_time_us(t0 + 40 * MS), 1000);
        assert_eq!(counted.reply_time_us(t0), 2000);
        assert_eq!(counted.reply_time_us(t0 + 3 * MS), 3000);
        // A new session counts from zero again.
        counted.start(t0 + 500 * MS);
        assert_eq!(counted.reply_time_us(t0 + 900 * MS), 1000);
        let slow = SampleClock::PerReply {
            period_us: NonZeroU32::new(250).unwrap(),
        };
        let mut s = ArmSession::with_clock(t0, slow);
        s.reply_time_us(t0);
        assert_eq!(s.reply_time_us(t0), 500);
    }

    #[test]
    fn a_keep_alive_is_due_only_on_reads_without_a_write_before_them() {
        let mut s = ArmSession::new(Instant::now());
        assert!(s.keep_alive_due());
        assert!(s.keep_alive_due());
        s.force_written();
        s.force_written();
        assert!(!s.keep_alive_due());
        assert!(s.keep_alive_due(), "the write counted for one read only");
    }

    #[test]
    fn cartesian_forces_are_clamped_in_length_and_saturate_per_axis() {
        assert_eq!(
            cartesian_force_mn(Vec3::new(100.0, 0.0, 0.0), 5.0),
            [5000, 0, 0]
        );
        assert_eq!(
            cartesian_force_mn(Vec3::new(0.0012, -0.0016, 2.0), 5.0),
            [1, -2, 2000]
        );
        assert_eq!(
            cartesian_force_mn(Vec3::new(-50.0, 50.0, 0.0), 1000.0),
            [i16::MIN, i16::MAX, 0]
        );
        assert_eq!(cartesian_force_mn(Vec3::NAN, 5.0), [0; 3]);
        assert_eq!(
            cartesian_force_mn(Vec3::new(f32::INFINITY, 0.0, 0.0), 5.0),
            [0; 3]
        );
    }

    #[test]
    fn closing_a_device_that_is_gone_is_clean() {
        assert_eq!(close_result(Ok(())), Ok(()));
        assert_eq!(close_result(Err(DeviceError::Disconnected)), Ok(()));
        assert_eq!(
            close_result(Err(DeviceError::NotOpen)),
            Err(DeviceError::NotOpen)
        );
    }

    #[test]
    fn a_profile_without_arm_kinematics_is_a_config_error_naming_it() {
        let falcon = DeviceProfile::built_in("falcon").unwrap();
        assert!(arm_model(&falcon).is_ok());
        let cartesian = DeviceProfile::built_in("cartesian-hid").unwrap();
        match arm_model(&cartesian) {
            Err(DeviceError::Config { origin, .. }) => assert_eq!(origin, cartesian.name),
            other => panic!("unexpected {other:?}"),
        }
    }

    /// A serial stream on one end of a pseudo-terminal pair; the other end plays the device.
    fn stream_on_pty(now: Instant) -> (SerialStream, TTYPort) {
        let (mut device, host) = TTYPort::pair().expect("pseudo-terminal pair");
        device.set_timeout(Duration::from_secs(5)).unwrap();
        let mut stream = SerialStream::new(50 * MS, now);
        stream.attach(
            SerialLink::from_port(Box::new(host), BaudPolicy::Tolerant),
            now,
        );
        (stream, device)
    }

    /// Reads `want` bytes from the stream; the bound on the wait only guards a stalled
    /// machine, the bytes are already on their way.
    fn read_exactly(stream: &mut SerialStream, want: usize) -> (Vec<u8>, usize) {
        let mut got = Vec::new();
        let mut first = None;
        let mut buf = [0u8; READ_BUF];
        while got.len() < want {
            let c = stream.read_chunk(Duration::from_secs(5), &mut buf).unwrap();
            assert!(c.len > 0, "the device's bytes never arrived");
            first.get_or_insert(c.first_offset);
            got.extend_from_slice(&buf[..c.len]);
        }
        (got, first.unwrap())
    }

    #[test]
    fn a_serial_stream_counts_frames_and_byte_offsets_per_session() {
        let t0 = Instant::now();
        let mut stream = SerialStream::new(50 * MS, t0);
        assert!(!stream.is_open() && !stream.is_live());
        assert_eq!(stream.ready(), Err(DeviceError::NotOpen));
        assert_eq!(stream.write_frame(b"x"), Err(DeviceError::NotOpen));

        let (mut stream, mut device) = stream_on_pty(t0);
        assert!(stream.is_live());
        assert_eq!(stream.ready(), Ok(()));
        stream.write_frame(b"abc").unwrap();
        let mut out = [0u8; 3];
        device.read_exact(&mut out).unwrap();
        assert_eq!(&out, b"abc");
        assert_eq!(stream.stats.sent, 1);

        device.write_all(b"12345").unwrap();
        assert_eq!(read_exactly(&mut stream, 5), (b"12345".to_vec(), 0));
        device.write_all(b"67").unwrap();
        assert_eq!(read_exactly(&mut stream, 2), (b"67".to_vec(), 5));

        // Live within `stale_after` of the last frame, a timeout after it (the device is
        // still there, so the probe finds no hang-up).
        stream.frame_received(t0 + 10 * MS);
        assert_eq!(stream.check(t0 + 60 * MS), Ok(()));
        assert_eq!(
            stream.check(t0 + 100 * MS),
            Err(DeviceError::Timeout { waited_us: 90_000 })
        );

        // A new session on another link starts its counters and offsets at zero.
        let (host2, mut device2) = TTYPort::pair().expect("pseudo-terminal pair");
        stream.attach(
            SerialLink::from_port(Box::new(host2), BaudPolicy::Tolerant),
            t0,
        );
        assert_eq!(stream.stats, LinkStats::default());
        device2.write_all(b"z").unwrap();
        assert_eq!(read_exactly(&mut stream, 1), (b"z".to_vec(), 0));
    }

    #[test]
    fn a_hang_up_kills_the_stream_until_it_is_closed_and_a_failed_open_drops_the_link() {
        let t0 = Instant::now();
        let (mut stream, device) = stream_on_pty(t0);
        drop(device);
        assert_eq!(stream.write_frame(b"abc"), Err(DeviceError::Disconnected));
        assert!(stream.is_open() && !stream.is_live());
        assert_eq!(stream.ready(), Err(DeviceError::Disconnected));
        // Closing a dead link is clean and leaves the stream ready to open again.
        assert_eq!(stream.close(Err(DeviceError::Disconnected), t0), Ok(()));
        assert!(!stream.is_open());
        assert_eq!(stream.ready(), Err(DeviceError::NotOpen));

        let (mut stream, _device) = stream_on_pty(t0);
        let refused = Err(DeviceError::Timeout { waited_us: 7 });
        assert_eq!(stream.opened(refused.clone()), refused);
        assert!(
            !stream.is_open(),
            "a failed set-up leaves no half-open link"
        );
        assert_eq!(stream.opened(Ok(())), Ok(()));
    }
}
