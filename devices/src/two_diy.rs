//! Haply 2DIY: a planar two-motor pantograph on Haply's Arduino board, over its USB serial
//! port, speaking the board protocol of [`crate::codec::haply_board`] and moving by the
//! kinematics of [`crate::pantograph`].
//!
//! Who ticks: the haptic loop, as with every serial arm here. The board answers each data
//! message (two torques) with one reply (two encoder angles), so `write_force` sends one data
//! message with the torques `Jᵀ F` for the newest pose, and `read` waits at most
//! [`TwoDiyOptions::reply_wait`] for the replies to what was sent, decodes the newest and runs
//! the forward kinematics. A `read` with no write since the previous one first sends the last
//! torques again, so the board is asked once per tick either way. Both are allocation-free:
//! fixed buffers, bounded reads ([`SerialLink::read_available`]).
//!
//! How a planar device sculpts in 3-D: the pantograph's plane is the device frame's x–y plane
//! at z = 0, turned so the handle moves as a pen on a page seen from the user: moving it right
//! moves the tool right (+x) and pushing it away from you (toward the motors) moves the tool up
//! (+y). The tool never leaves that plane, so it carves the clay's cross-section at the
//! workspace's middle depth; the z part of the force is dropped (the device cannot render it)
//! and the x–y part goes to the motors. The workspace box is the reachable rectangle of the
//! linkage, with a z extent as deep as the rectangle's shorter half-side so the workspace map
//! scales by the plane.
//!
//! Safety: `open` resets the board, sets up motors and encoders, then sends zero torques and
//! takes the reply as the first sample; `close` sends zero torques and waits (at most
//! `reply_wait`) for the board's reply before it lets the port go. A reply that breaks the
//! protocol is reported once as [`DeviceError::Protocol`] (its bytes are skipped until the
//! stream realigns); silence longer than [`TwoDiyOptions::stale_after`] is
//! [`DeviceError::Timeout`]; a port that goes away is [`DeviceError::Disconnected`]. The safety
//! filter then sends zero.
//!
//! Time: the board's replies carry no clock, so each sample is stamped on the host's clock
//! when its reply is decoded ([`SampleClock::Host`]); a lockstep run counts the replies instead
//! ([`SampleClock::LOCKSTEP_1KHZ`]: the board answers each data message with one reply, one
//! message per tick), so its soft start, velocities and forces do not depend on the machine.

use std::time::{Duration, Instant};

use glam::{DVec2, Vec3};

pub use crate::arm_link::SampleClock;
use crate::codec::CodecError;
use crate::codec::haply_board::{self as board, CCW, CW, MAX_HOST_MESSAGE, PortSetup};
use crate::device::{DeviceError, DeviceInfo, DeviceState, HapticDevice};
use crate::pantograph::{Pantograph, PantographPose};
use crate::serial_link::{BaudPolicy, SerialLink};
use crate::velocity::VelocityEstimator;

/// The device id the driver gives the board (Haply's examples use small ids; any byte works).
pub const DEVICE_ID: u8 = 5;

/// Which 2DIY: the generations differ in motor spacing and encoders.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum TwoDiyVersion {
    /// Second generation: motors on one axis, 10752-step encoders.
    V2,
    /// Third generation (the current one): motors 38 mm apart, 4880-step encoders.
    #[default]
    V3,
}

impl TwoDiyVersion {
    /// The linkage.
    #[must_use]
    pub fn pantograph(self) -> Pantograph {
        match self {
            Self::V2 => Pantograph::TWO_DIY_V2,
            Self::V3 => Pantograph::TWO_DIY_V3,
        }
    }

    /// Motor and encoder set-up, as Haply's examples configure each generation: joint 1 on
    /// board port 2, joint 2 on port 1.
    #[must_use]
    pub fn ports(self) -> [PortSetup; 2] {
        match self {
            Self::V2 => [
                PortSetup {
                    port: 2,
                    motor_direction: CCW,
                    encoder_direction: CCW,
                    encoder_offset_deg: 241.0,
                    encoder_steps_per_turn: 10752.0,
                },
                PortSetup {
                    port: 1,
                    motor_direction: CW,
                    encoder_direction: CW,
                    encoder_offset_deg: -61.0,
                    encoder_steps_per_turn: 10752.0,
                },
            ],
            Self::V3 => [
                PortSetup {
                    port: 2,
                    motor_direction: CCW,
                    encoder_direction: CCW,
                    encoder_offset_deg: 168.0,
                    encoder_steps_per_turn: 4880.0,
                },
                PortSetup {
                    port: 1,
                    motor_direction: CCW,
                    encoder_direction: CCW,
                    encoder_offset_deg: 12.0,
                    encoder_steps_per_turn: 4880.0,
                },
            ],
        }
    }

    /// The spec suffix (`v2`, `v3`).
    #[must_use]
    pub fn label(self) -> &'static str {
        match self {
            Self::V2 => "v2",
            Self::V3 => "v3",
        }
    }
}

/// Board frame (metres) to the device frame: a half turn in the plane, z = 0.
#[must_use]
pub fn board_to_device(p: DVec2) -> Vec3 {
    Vec3::new(-p.x as f32, -p.y as f32, 0.0)
}

/// The device frame's x–y force to the board frame's (z dropped).
#[must_use]
pub fn device_to_board_force(f: Vec3) -> DVec2 {
    DVec2::new(-f64::from(f.x), -f64::from(f.y))
}

/// Settings of a [`TwoDiy`].
#[derive(Clone, Debug, PartialEq)]
pub struct TwoDiyOptions {
    /// Which generation.
    pub version: TwoDiyVersion,
    /// Line rate (the board's native USB port ignores it).
    pub baud: u32,
    /// How to treat refused baud changes.
    pub baud_policy: BaudPolicy,
    /// Longest wait for the first reply during `open`.
    pub handshake_timeout: Duration,
    /// Longest `read` waits for the replies to what was sent (0: never wait).
    pub reply_wait: Duration,
    /// No reply for this long makes `read` fail with a timeout.
    pub stale_after: Duration,
    /// Where the samples' time stamps come from (the replies carry no time): the host's
    /// clock in real time; [`SampleClock::LOCKSTEP_1KHZ`] in a lockstep run, where the board's
    /// one reply per data message is the device's clock.
    pub sample_clock: SampleClock,
}

impl Default for TwoDiyOptions {
    fn default() -> Self {
        Self {
            version: TwoDiyVersion::V3,
            baud: 115_200,
            baud_policy: BaudPolicy::Tolerant,
            handshake_timeout: Duration::from_secs(2),
            reply_wait: Duration::from_micros(800),
            stale_after: Duration::from_millis(50),
            sample_clock: SampleClock::Host,
        }
    }
}

/// Bytes kept between reads while a reply is incomplete.
const PENDING: usize = 4 * board::MAX_REPLY;
/// Bytes of one reply (two angles).
const REPLY: usize = board::reply_len(2);

/// An open port and what the stream has carried.
struct Link {
    port: SerialLink,
    pending: [u8; PENDING],
    pending_len: usize,
    /// Bytes read since open (for fault offsets).
    stream_offset: usize,
    /// Data messages sent and replies decoded.
    commands: u64,
    replies: u64,
    last_reply: Instant,
    started: Instant,
    /// The port went away: every call reports it until the device is opened again.
    dead: bool,
}

/// A Haply 2DIY on a serial port.
pub struct TwoDiy {
    path: String,
    opts: TwoDiyOptions,
    pantograph: Pantograph,
    link: Option<Link>,
    pose: Option<PantographPose>,
    state: DeviceState,
    velocity: VelocityEstimator,
    torques_n_m: [f32; 2],
    written_since_read: bool,
}

fn codec_fault(e: &CodecError, at: usize) -> DeviceError {
    let what = match e {
        CodecError::BadByte { field, .. } => field,
        _ => "2DIY reply of the wrong size",
    };
    DeviceError::Protocol { what, offset: at }
}

impl TwoDiy {
    /// A 2DIY on `path` (not opened yet).
    #[must_use]
    pub fn new(path: &str, opts: TwoDiyOptions) -> Self {
        Self {
            path: path.to_string(),
            pantograph: opts.version.pantograph(),
            opts,
            link: None,
            pose: None,
            state: DeviceState::ZERO,
            velocity: VelocityEstimator::default(),
            torques_n_m: [0.0; 2],
            written_since_read: false,
        }
    }

    /// The figures of this generation: a workspace box inside the linkage's reach (14 cm
    /// across, 9 cm from 4 cm to 13 cm in front of the motors), 2 N and 500 N/m. Haply
    /// publishes no force or stiffness figures for the 2DIY; these are conservative bounds
    /// for its small DC motors, to be raised only after measuring an arm. Two joints sensed:
    /// 2 degrees of freedom.
    #[must_use]
    pub fn info_for(version: TwoDiyVersion) -> DeviceInfo {
        let d = version.pantograph().motor_spacing_m;
        let near = board_to_device(DVec2::new(d * 0.5 + 0.07, 0.04));
        let far = board_to_device(DVec2::new(d * 0.5 - 0.07, 0.13));
        let depth = 0.045;
        DeviceInfo {
            name: format!("Haply 2DIY {} (serial)", version.label()),
            dof: 2,
            max_force_n: 2.0,
            max_stiffness_n_per_m: 500.0,
            max_damping_n_s_per_m: 0.0,
            workspace_min_m: near.min(far) - Vec3::Z * depth,
            workspace_max_m: near.max(far) + Vec3::Z * depth,
            has_orientation: false,
            has_force: true,
            button_count: 0,
            sample_rate_hz: 1000.0,
        }
    }

    /// Data messages sent and replies decoded since `open`.
    #[must_use]
    pub fn exchanges(&self) -> (u64, u64) {
        self.link
            .as_ref()
            .map_or((0, 0), |l| (l.commands, l.replies))
    }

    fn send_torques(&mut self) -> Result<(), DeviceError> {
        let link = self.link.as_mut().ok_or(DeviceError::NotOpen)?;
        if link.dead {
            return Err(DeviceError::Disconnected);
        }
        let mut buf = [0u8; MAX_HOST_MESSAGE];
        // Board order is port order: port 1 drives joint 2, port 2 joint 1.
        let n = board::encode_torques(
            DEVICE_ID,
            &[self.torques_n_m[1], self.torques_n_m[0]],
            &mut buf,
        )
        .map_err(|e| codec_fault(&e, 0))?;
        if let Err(e) = link.port.write_all(&buf[..n]) {
            link.dead |= e == DeviceError::Disconnected;
            return Err(e);
        }
        link.commands += 1;
        Ok(())
    }

    /// Reads what is queued (waiting up to `wait` while replies are outstanding) and decodes
    /// every whole reply; returns the first fault. Bytes that do not decode are skipped one at
    /// a time until a reply does.
    fn pump(&mut self, wait: Duration) -> Result<Option<DeviceError>, DeviceError> {
        let start = Instant::now();
        let mut fault = None;
        loop {
            let link = self.link.as_mut().ok_or(DeviceError::NotOpen)?;
            let outstanding = link.commands > link.replies;
            let left = if outstanding {
                wait.saturating_sub(start.elapsed())
            } else {
                Duration::ZERO
            };
            let bytes = match link.port.read_available(left) {
                Ok(b) => b,
                // The port opened and worked, so a port that now refuses even to say how
                // much is queued (a pseudo-terminal whose other end closed, a board that
                // reset) is gone.
                Err(DeviceError::Config { .. } | DeviceError::Disconnected) => {
                    link.dead = true;
                    return Err(DeviceError::Disconnected);
                }
                Err(e) => return Err(e),
            };
            if bytes.is_empty() {
                return Ok(fault);
            }
            for &b in bytes {
                if link.pending_len == PENDING {
                    // Noise filled the buffer: drop the oldest byte.
                    link.pending.copy_within(1.., 0);
                    link.pending_len -= 1;
                    fault.get_or_insert(DeviceError::Protocol {
                        what: "2DIY reply stream overflow",
                        offset: link.stream_offset,
                    });
                }
                link.pending[link.pending_len] = b;
                link.pending_len += 1;
                link.stream_offset += 1;
            }
            let mut angles_deg = [0.0f32; 2];
            let mut newest = None;
            while link.pending_len >= REPLY {
                let at = link.stream_offset - link.pending_len;
                match board::decode_angles(DEVICE_ID, &link.pending[..REPLY], &mut angles_deg) {
                    Ok(()) => {
                        newest = Some(angles_deg);
                        link.replies += 1;
                        link.pending.copy_within(REPLY..link.pending_len, 0);
                        link.pending_len -= REPLY;
                    }
                    Err(e) => {
                        fault.get_or_insert(codec_fault(&e, at));
                        link.pending.copy_within(1..link.pending_len, 0);
                        link.pending_len -= 1;
                    }
                }
            }
            if let Some(a) = newest {
                let now = Instant::now();
                link.last_reply = now;
                let replies = link.replies;
                // The reply to `open`'s zero-torque message is the first.
                let t_us = self
                    .opts
                    .sample_clock
                    .stamp_us(replies, now.saturating_duration_since(link.started));
                // Port order: port 1 is joint 2, port 2 joint 1.
                let (theta1, theta2) = (f64::from(a[1]).to_radians(), f64::from(a[0]).to_radians());
                match self.pantograph.forward(theta1, theta2) {
                    Some(pose) => {
                        let p = board_to_device(pose.handle_m);
                        self.pose = Some(pose);
                        self.state = DeviceState {
                            position_m: p,
                            orientation: None,
                            velocity_m_per_s: self.velocity.update(p, t_us),
                            buttons: 0,
                            timestamp_us: t_us,
                            sequence: replies,
                        };
                    }
                    None => {
                        fault.get_or_insert(DeviceError::Protocol {
                            what: "2DIY joint angles the linkage cannot take",
                            offset: self.link.as_ref().map_or(0, |l| l.stream_offset),
                        });
                    }
                }
            }
            let link = self.link.as_ref().ok_or(DeviceError::NotOpen)?;
            if link.commands <= link.replies || start.elapsed() >= wait {
                return Ok(fault);
            }
        }
    }

    fn open_inner(&mut self) -> Result<(), DeviceError> {
        let mut port = SerialLink::open(
            &self.path,
            self.opts.baud,
            self.opts.baud_policy,
            Duration::from_millis(100),
        )?;
        port.clear_input();
        let mut buf = [0u8; MAX_HOST_MESSAGE];
        let n = board::encode_reset(&mut buf).map_err(|e| codec_fault(&e, 0))?;
        port.write_all(&buf[..n])?;
        let n = board::encode_setup(DEVICE_ID, &self.opts.version.ports(), &mut buf)
            .map_err(|e| codec_fault(&e, 0))?;
        port.write_all(&buf[..n])?;
        let now = Instant::now();
        self.link = Some(Link {
            port,
            pending: [0; PENDING],
            pending_len: 0,
            stream_offset: 0,
            commands: 0,
            replies: 0,
            last_reply: now,
            started: now,
            dead: false,
        });
        self.torques_n_m = [0.0; 2];
        self.velocity.reset();
        self.pose = None;
        self.send_torques()?;
        let fault = self.pump(self.opts.handshake_timeout)?;
        if self.pose.is_none() {
            return Err(match fault {
                Some(e) => DeviceError::Config {
                    origin: format!("2diy:{}", self.path),
                    message: format!("the board's first reply is not a 2DIY's ({e})"),
                },
                None => DeviceError::NotFound {
                    what: format!(
                        "a Haply 2DIY on {}: no reply within {:?} to a zero-torque command; is \
                         Haply's firmware loaded on the board and is this its port?",
                        self.path, self.opts.handshake_timeout
                    ),
                },
            });
        }
        Ok(())
    }
}

impl HapticDevice for TwoDiy {
    fn info(&self) -> DeviceInfo {
        Self::info_for(self.opts.version)
    }

    fn open(&mut self) -> Result<(), DeviceError> {
        if self.link.is_some() {
            return Ok(());
        }
        let r = self.open_inner();
        if r.is_err() {
            self.link = None;
        }
        r
    }

    fn close(&mut self) -> Result<(), DeviceError> {
        if self.link.is_none() {
            return Ok(());
        }
        self.torques_n_m = [0.0; 2];
        let r = self.send_torques();
        if r.is_ok() {
            // The board's reply says it took the zero before the port is let go (closing a
            // port may drop what it has not sent yet).
            let _ = self.pump(self.opts.reply_wait);
        }
        self.link = None;
        match r {
            Err(DeviceError::Disconnected) => Ok(()),
            other => other,
        }
    }

    fn is_open(&self) -> bool {
        self.link.is_some()
    }

    fn read(&mut self) -> Result<DeviceState, DeviceError> {
        match &self.link {
            None => return Err(DeviceError::NotOpen),
            Some(l) if l.dead => return Err(DeviceError::Disconnected),
            Some(_) => {}
        }
        if !self.written_since_read {
            self.send_torques()?;
        }
        self.written_since_read = false;
        if let Some(f) = self.pump(self.opts.reply_wait)? {
            return Err(f);
        }
        let link = self.link.as_ref().ok_or(DeviceError::NotOpen)?;
        let silent = link.last_reply.elapsed();
        if silent > self.opts.stale_after {
            return Err(DeviceError::Timeout {
                waited_us: silent.as_micros() as u64,
            });
        }
        Ok(self.state)
    }

    /// Sends the torques that put `force_n`'s x–y part on the handle at the newest pose.
    fn write_force(&mut self, force_n: Vec3) -> Result<(), DeviceError> {
        if self.link.is_none() {
            return Err(DeviceError::NotOpen);
        }
        let f = if force_n.is_finite() {
            device_to_board_force(force_n)
        } else {
            DVec2::ZERO
        };
        let tau = self.pose.map_or([0.0; 2], |p| p.torques_n_m(f));
        self.torques_n_m = [tau[0] as f32, tau[1] as f32];
        self.written_since_read = true;
        self.send_torques()
    }
}

impl Drop for TwoDiy {
    fn drop(&mut self) {
        let _ = self.close();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_workspace_box_is_reachable_and_maps_by_the_plane() {
        for version in [TwoDiyVersion::V2, TwoDiyVersion::V3] {
            let info = TwoDiy::info_for(version);
            let pg = version.pantograph();
            let (lo, hi) = (info.workspace_min_m, info.workspace_max_m);
            for (x, y) in [(lo.x, lo.y), (lo.x, hi.y), (hi.x, lo.y), (hi.x, hi.y)] {
                // Device (x, y) back to the board frame: the half turn is its own inverse.
                let p = DVec2::new(-f64::from(x), -f64::from(y));
                assert!(
                    pg.inverse(p).is_some(),
                    "{version:?}: corner {p} out of reach"
                );
            }
            let size = info.workspace_size_m();
            assert!(size.z <= size.x.min(size.y) + 1e-6, "{size}");
            assert_eq!(info.dof, 2);
        }
    }

    #[test]
    fn the_plane_is_a_half_turn_so_right_stays_right_and_away_is_up() {
        // Board +x is the user's left (Haply draws it mirrored); board +y comes toward the user.
        assert_eq!(board_to_device(DVec2::new(-0.01, 0.0)).x, 0.01);
        assert_eq!(board_to_device(DVec2::new(0.0, 0.05)).y, -0.05);
        let f = Vec3::new(0.3, -0.2, 5.0);
        let b = device_to_board_force(f);
        assert_eq!(board_to_device(b), Vec3::new(0.3, -0.2, 0.0));
    }
}
