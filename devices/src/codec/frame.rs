//! The dynaclay Cartesian serial protocol: length-prefixed, CRC-32 checked frames.
//!
//! For custom firmware that does its own kinematics: the device reports its tool position in
//! micrometres and takes a force in millinewtons. Frame layout (all integers little-endian;
//! the full specification, with examples, is in `devices/PROTOCOL.md`):
//!
//! | offset | size | field |
//! | --- | --- | --- |
//! | 0 | 1 | sync `0xA5` |
//! | 1 | 1 | payload length `n` (0..=[`MAX_PAYLOAD`]) |
//! | 2 | 1 | message type |
//! | 3 | n | payload |
//! | 3+n | 4 | CRC-32 (IEEE 802.3, as `crc32fast`) over bytes 1..3+n |
//!
//! Encoding writes into a caller's buffer and [`FrameReader`] keeps a fixed buffer, so nothing
//! here allocates.

use super::CodecError;

/// Sync byte opening every frame.
pub const SYNC: u8 = 0xA5;
/// Largest payload.
pub const MAX_PAYLOAD: usize = 32;
/// Bytes of framing around a payload (sync, length, type, CRC).
pub const OVERHEAD: usize = 7;
/// Largest frame.
pub const MAX_FRAME: usize = MAX_PAYLOAD + OVERHEAD;
/// Protocol version carried in the handshake.
pub const VERSION: u8 = 1;

const WHAT: &str = "Cartesian frame";

/// Message types, host → device below 0x80, device → host from 0x80.
pub mod kind {
    /// Host asks for the device's identity; payload: protocol version.
    pub const HELLO: u8 = 0x01;
    /// Host asks the device to home (find its reference position).
    pub const HOME: u8 = 0x02;
    /// Host commands a force; payload: fx, fy, fz (i16 mN), sequence (u16).
    pub const FORCE: u8 = 0x03;
    /// Device identity.
    pub const HELLO_ACK: u8 = 0x81;
    /// Homing finished; payload: 1 on success, 0 on failure.
    pub const HOME_DONE: u8 = 0x82;
    /// Device state; payload: x, y, z (i32 µm), buttons (u16), echoed sequence (u16), status (u8).
    pub const STATE: u8 = 0x83;
}

/// Status bits of a [`DeviceMsg::State`].
pub mod status {
    /// The device is homed: positions are absolute.
    pub const HOMED: u8 = 0x1;
    /// Motor power is on.
    pub const MOTORS_ON: u8 = 0x2;
    /// The firmware saw a fault (over-current, watchdog); motors are off.
    pub const FAULT: u8 = 0x4;
}

/// Messages from host to device.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HostMsg {
    /// Handshake request.
    Hello {
        /// The host's protocol version.
        version: u8,
    },
    /// Homing request.
    Home,
    /// Force command.
    Force {
        /// Force in millinewtons, device frame.
        force_mn: [i16; 3],
        /// Sequence number, echoed in the next state.
        seq: u16,
    },
}

/// Messages from device to host.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DeviceMsg {
    /// Handshake answer.
    HelloAck {
        /// The device's protocol version.
        version: u8,
        /// Largest force the device can render, millinewtons.
        max_force_mn: u16,
        /// Radius of the reachable workspace, micrometres.
        workspace_radius_um: u32,
    },
    /// Homing answer.
    HomeDone {
        /// Whether homing succeeded.
        ok: bool,
    },
    /// Tool state.
    State {
        /// Tool position in micrometres, device frame.
        position_um: [i32; 3],
        /// Button bits.
        buttons: u16,
        /// Sequence number of the last force command applied.
        seq: u16,
        /// [`status`] bits.
        status: u8,
    },
}

/// Writes a frame around `payload` into `out`, returning the frame length.
///
/// # Errors
/// [`CodecError::TooLong`] when the payload exceeds [`MAX_PAYLOAD`] or `out` is too small.
pub fn encode_frame(kind: u8, payload: &[u8], out: &mut [u8]) -> Result<usize, CodecError> {
    if payload.len() > MAX_PAYLOAD {
        return Err(CodecError::TooLong {
            what: WHAT,
            max: MAX_PAYLOAD,
            got: payload.len(),
        });
    }
    let n = payload.len() + OVERHEAD;
    if out.len() < n {
        return Err(CodecError::TooShort {
            what: "frame output buffer",
            needed: n,
            got: out.len(),
        });
    }
    out[0] = SYNC;
    out[1] = payload.len() as u8;
    out[2] = kind;
    out[3..3 + payload.len()].copy_from_slice(payload);
    let crc = crc32fast::hash(&out[1..3 + payload.len()]);
    out[3 + payload.len()..n].copy_from_slice(&crc.to_le_bytes());
    Ok(n)
}

/// Checks one whole frame and returns its type and payload.
///
/// # Errors
/// [`CodecError`] naming the sync byte, the length field or the CRC that was wrong.
pub fn decode_frame(frame: &[u8]) -> Result<(u8, &[u8]), CodecError> {
    if frame.len() < OVERHEAD {
        return Err(CodecError::TooShort {
            what: WHAT,
            needed: OVERHEAD,
            got: frame.len(),
        });
    }
    if frame[0] != SYNC {
        return Err(CodecError::BadByte {
            what: WHAT,
            field: "sync 0xA5",
            offset: 0,
            value: frame[0],
        });
    }
    let n = usize::from(frame[1]);
    if n > MAX_PAYLOAD {
        return Err(CodecError::BadLength {
            what: WHAT,
            offset: 1,
            announced: n,
            expected: MAX_PAYLOAD,
        });
    }
    if frame.len() != n + OVERHEAD {
        return Err(CodecError::BadLength {
            what: WHAT,
            offset: 1,
            announced: n,
            expected: frame.len().saturating_sub(OVERHEAD),
        });
    }
    let at = 3 + n;
    let expected = u32::from_le_bytes([frame[at], frame[at + 1], frame[at + 2], frame[at + 3]]);
    let computed = crc32fast::hash(&frame[1..at]);
    if expected != computed {
        return Err(CodecError::BadCrc {
            what: WHAT,
            offset: at,
            expected,
            computed,
        });
    }
    Ok((frame[2], &frame[3..at]))
}

fn need(kind_name: &'static str, payload: &[u8], n: usize) -> Result<(), CodecError> {
    if payload.len() == n {
        Ok(())
    } else {
        Err(CodecError::BadLength {
            what: kind_name,
            offset: 1,
            announced: payload.len(),
            expected: n,
        })
    }
}

fn i16_at(p: &[u8], at: usize) -> i16 {
    i16::from_le_bytes([p[at], p[at + 1]])
}

fn u16_at(p: &[u8], at: usize) -> u16 {
    u16::from_le_bytes([p[at], p[at + 1]])
}

fn i32_at(p: &[u8], at: usize) -> i32 {
    i32::from_le_bytes([p[at], p[at + 1], p[at + 2], p[at + 3]])
}

impl HostMsg {
    /// Encodes the message as a whole frame into `out`; returns the frame length.
    ///
    /// # Errors
    /// [`CodecError::TooShort`] when `out` holds fewer than [`MAX_FRAME`] bytes' worth.
    pub fn encode(&self, out: &mut [u8]) -> Result<usize, CodecError> {
        let mut p = [0u8; 8];
        let (k, len) = match *self {
            Self::Hello { version } => {
                p[0] = version;
                (kind::HELLO, 1)
            }
            Self::Home => (kind::HOME, 0),
            Self::Force { force_mn, seq } => {
                for (i, f) in force_mn.iter().enumerate() {
                    p[2 * i..2 * i + 2].copy_from_slice(&f.to_le_bytes());
                }
                p[6..8].copy_from_slice(&seq.to_le_bytes());
                (kind::FORCE, 8)
            }
        };
        encode_frame(k, &p[..len], out)
    }

    /// Decodes a host message from a checked frame's type and payload.
    ///
    /// # Errors
    /// [`CodecError::BadByte`] for an unknown type, [`CodecError::BadLength`] for a payload of
    /// the wrong size.
    pub fn decode(k: u8, p: &[u8]) -> Result<Self, CodecError> {
        match k {
            kind::HELLO => {
                need("HELLO payload", p, 1)?;
                Ok(Self::Hello { version: p[0] })
            }
            kind::HOME => {
                need("HOME payload", p, 0)?;
                Ok(Self::Home)
            }
            kind::FORCE => {
                need("FORCE payload", p, 8)?;
                Ok(Self::Force {
                    force_mn: [i16_at(p, 0), i16_at(p, 2), i16_at(p, 4)],
                    seq: u16_at(p, 6),
                })
            }
            other => Err(CodecError::BadByte {
                what: WHAT,
                field: "host message type",
                offset: 2,
                value: other,
            }),
        }
    }
}

impl DeviceMsg {
    /// Encodes the message as a whole frame into `out`; returns the frame length.
    ///
    /// # Errors
    /// [`CodecError::TooShort`] when `out` is too small for the frame.
    pub fn encode(&self, out: &mut [u8]) -> Result<usize, CodecError> {
        let mut p = [0u8; 17];
        let (k, len) = match *self {
            Self::HelloAck {
                version,
                max_force_mn,
                workspace_radius_um,
            } => {
                p[0] = version;
                p[1..3].copy_from_slice(&max_force_mn.to_le_bytes());
                p[3..7].copy_from_slice(&workspace_radius_um.to_le_bytes());
                (kind::HELLO_ACK, 7)
            }
            Self::HomeDone { ok } => {
                p[0] = u8::from(ok);
                (kind::HOME_DONE, 1)
            }
            Self::State {
                position_um,
                buttons,
                seq,
                status,
            } => {
                for (i, x) in position_um.iter().enumerate() {
                    p[4 * i..4 * i + 4].copy_from_slice(&x.to_le_bytes());
                }
                p[12..14].copy_from_slice(&buttons.to_le_bytes());
                p[14..16].copy_from_slice(&seq.to_le_bytes());
                p[16] = status;
                (kind::STATE, 17)
            }
        };
        encode_frame(k, &p[..len], out)
    }

    /// Decodes a device message from a checked frame's type and payload.
    ///
    /// # Errors
    /// [`CodecError::BadByte`] for an unknown type or a bad flag byte, [`CodecError::BadLength`]
    /// for a payload of the wrong size.
    pub fn decode(k: u8, p: &[u8]) -> Result<Self, CodecError> {
        match k {
            kind::HELLO_ACK => {
                need("HELLO_ACK payload", p, 7)?;
                Ok(Self::HelloAck {
                    version: p[0],
                    max_force_mn: u16_at(p, 1),
                    workspace_radius_um: u32::from_le_bytes([p[3], p[4], p[5], p[6]]),
                })
            }
            kind::HOME_DONE => {
                need("HOME_DONE payload", p, 1)?;
                match p[0] {
                    0 | 1 => Ok(Self::HomeDone { ok: p[0] == 1 }),
                    v => Err(CodecError::BadByte {
                        what: WHAT,
                        field: "HOME_DONE flag (0 or 1)",
                        offset: 3,
                        value: v,
                    }),
                }
            }
            kind::STATE => {
                need("STATE payload", p, 17)?;
                Ok(Self::State {
                    position_um: [i32_at(p, 0), i32_at(p, 4), i32_at(p, 8)],
                    buttons: u16_at(p, 12),
                    seq: u16_at(p, 14),
                    status: p[16],
                })
            }
            other => Err(CodecError::BadByte {
                what: WHAT,
                field: "device message type",
                offset: 2,
                value: other,
            }),
        }
    }
}

/// What one byte pushed into a [`FrameReader`] produced.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrameEvent {
    /// Nothing complete yet.
    Pending,
    /// A byte outside any frame was skipped.
    Skipped(u8),
    /// A whole, CRC-checked frame: its type and payload length; read the payload with
    /// [`FrameReader::payload`].
    Frame {
        /// Message type.
        kind: u8,
        /// Payload length.
        len: usize,
    },
    /// A frame failed its checks; reading resynchronises on the next sync byte after its start.
    Bad(CodecError),
}

/// Streaming frame reader with a fixed buffer. After a bad frame it rescans the bytes that
/// followed the false sync byte, so a sync value inside noise cannot hide a real frame for long.
#[derive(Clone, Debug)]
pub struct FrameReader {
    buf: [u8; MAX_FRAME],
    len: usize,
    /// Bytes to replay after a bad frame (those after its sync byte).
    pending: [u8; MAX_FRAME],
    pending_len: usize,
    pending_at: usize,
}

impl Default for FrameReader {
    fn default() -> Self {
        Self {
            buf: [0; MAX_FRAME],
            len: 0,
            pending: [0; MAX_FRAME],
            pending_len: 0,
            pending_at: 0,
        }
    }
}

impl FrameReader {
    /// A reader waiting for a sync byte.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// Forgets any partly read frame.
    pub fn reset(&mut self) {
        self.len = 0;
        self.pending_len = 0;
        self.pending_at = 0;
    }

    /// The payload of the frame last reported by [`FrameEvent::Frame`].
    #[must_use]
    pub fn payload(&self) -> &[u8] {
        let n = usize::from(self.buf[1]).min(MAX_PAYLOAD);
        &self.buf[3..3 + n]
    }

    /// Pushes one byte from the wire; call [`FrameReader::drain`] until it returns `None` after
    /// a [`FrameEvent::Bad`] to rescan what followed the bad frame's sync byte.
    pub fn push(&mut self, byte: u8) -> FrameEvent {
        self.step(byte)
    }

    /// Replays one byte held back after a bad frame, if any.
    pub fn drain(&mut self) -> Option<FrameEvent> {
        if self.pending_at < self.pending_len {
            let b = self.pending[self.pending_at];
            self.pending_at += 1;
            Some(self.step(b))
        } else {
            self.pending_len = 0;
            self.pending_at = 0;
            None
        }
    }

    fn step(&mut self, byte: u8) -> FrameEvent {
        if self.len == 0 {
            if byte != SYNC {
                return FrameEvent::Skipped(byte);
            }
            self.buf[0] = byte;
            self.len = 1;
            return FrameEvent::Pending;
        }
        self.buf[self.len] = byte;
        self.len += 1;
        if self.len == 2 && usize::from(byte) > MAX_PAYLOAD {
            return self.fail(CodecError::BadLength {
                what: WHAT,
                offset: 1,
                announced: usize::from(byte),
                expected: MAX_PAYLOAD,
            });
        }
        if self.len < 2 || self.len < usize::from(self.buf[1]) + OVERHEAD {
            return FrameEvent::Pending;
        }
        let n = self.len;
        match decode_frame(&self.buf[..n]) {
            Ok((kind, payload)) => {
                let len = payload.len();
                self.len = 0;
                FrameEvent::Frame { kind, len }
            }
            Err(e) => self.fail(e),
        }
    }

    fn fail(&mut self, e: CodecError) -> FrameEvent {
        // Hold back everything after the false sync byte for a rescan.
        let rest = self.len - 1;
        let mut tmp = [0u8; MAX_FRAME];
        tmp[..rest].copy_from_slice(&self.buf[1..self.len]);
        // Bytes not yet replayed from an earlier failure go after them.
        let left = self.pending_len - self.pending_at;
        let take = left.min(MAX_FRAME - rest);
        tmp[rest..rest + take]
            .copy_from_slice(&self.pending[self.pending_at..self.pending_at + take]);
        self.pending = tmp;
        self.pending_len = rest + take;
        self.pending_at = 0;
        self.len = 0;
        FrameEvent::Bad(e)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn feed(r: &mut FrameReader, bytes: &[u8]) -> (Vec<DeviceMsg>, usize) {
        let mut msgs = Vec::new();
        let mut bad = 0;
        let mut handle = |r: &mut FrameReader, ev: FrameEvent, msgs: &mut Vec<DeviceMsg>| match ev {
            FrameEvent::Frame { kind, .. } => {
                msgs.push(DeviceMsg::decode(kind, r.payload()).unwrap())
            }
            FrameEvent::Bad(_) => bad += 1,
            _ => {}
        };
        for &b in bytes {
            let ev = r.push(b);
            handle(r, ev, &mut msgs);
            while let Some(ev) = r.drain() {
                handle(r, ev, &mut msgs);
            }
        }
        (msgs, bad)
    }

    #[test]
    fn force_frame_layout_matches_the_spec_example() {
        let mut out = [0u8; MAX_FRAME];
        let n = HostMsg::Force {
            force_mn: [1000, -1000, 0],
            seq: 7,
        }
        .encode(&mut out)
        .unwrap();
        assert_eq!(n, 15);
        assert_eq!(
            &out[..11],
            &[0xA5, 8, 0x03, 0xe8, 0x03, 0x18, 0xfc, 0, 0, 7, 0]
        );
        let crc = crc32fast::hash(&out[1..11]);
        assert_eq!(&out[11..15], &crc.to_le_bytes());
    }

    #[test]
    fn messages_round_trip() {
        let mut out = [0u8; MAX_FRAME];
        for m in [
            HostMsg::Hello { version: VERSION },
            HostMsg::Home,
            HostMsg::Force {
                force_mn: [-1, 2, i16::MAX],
                seq: 65535,
            },
        ] {
            let n = m.encode(&mut out).unwrap();
            let (k, p) = decode_frame(&out[..n]).unwrap();
            assert_eq!(HostMsg::decode(k, p), Ok(m));
        }
        for m in [
            DeviceMsg::HelloAck {
                version: 1,
                max_force_mn: 8000,
                workspace_radius_um: 100_000,
            },
            DeviceMsg::HomeDone { ok: true },
            DeviceMsg::State {
                position_um: [i32::MIN, 0, 123_456],
                buttons: 3,
                seq: 9,
                status: status::HOMED,
            },
        ] {
            let n = m.encode(&mut out).unwrap();
            let (k, p) = decode_frame(&out[..n]).unwrap();
            assert_eq!(DeviceMsg::decode(k, p), Ok(m));
        }
    }

    #[test]
    fn bad_crc_and_length_are_reported_with_offsets() {
        let mut out = [0u8; MAX_FRAME];
        let n = DeviceMsg::HomeDone { ok: true }.encode(&mut out).unwrap();
        out[3] ^= 1;
        assert!(matches!(
            decode_frame(&out[..n]),
            Err(CodecError::BadCrc { offset: 4, .. })
        ));
        let mut long = [0u8; 8];
        long[0] = SYNC;
        long[1] = 200;
        assert!(matches!(
            decode_frame(&long),
            Err(CodecError::BadLength { announced: 200, .. })
        ));
        assert!(matches!(
            DeviceMsg::decode(kind::STATE, &[0; 3]),
            Err(CodecError::BadLength { .. })
        ));
        assert!(matches!(
            DeviceMsg::decode(0x99, &[]),
            Err(CodecError::BadByte { value: 0x99, .. })
        ));
    }

    #[test]
    fn reader_recovers_a_frame_hidden_behind_a_false_sync() {
        let mut out = [0u8; MAX_FRAME];
        let m = DeviceMsg::State {
            position_um: [1, 2, 3],
            buttons: 0,
            seq: 1,
            status: 0,
        };
        let n = m.encode(&mut out).unwrap();
        let mut stream = vec![0x00, SYNC, 3, 0x83];
        stream.extend_from_slice(&out[..n]);
        let mut r = FrameReader::new();
        let (msgs, bad) = feed(&mut r, &stream);
        assert_eq!(msgs, vec![m]);
        assert!(bad >= 1);
    }

    #[test]
    fn reader_rejects_a_corrupted_frame_then_reads_the_next() {
        let mut out = [0u8; MAX_FRAME];
        let m = DeviceMsg::HomeDone { ok: false };
        let n = m.encode(&mut out).unwrap();
        let mut stream = out[..n].to_vec();
        stream[4] ^= 0xff; // corrupt the CRC
        stream.extend_from_slice(&out[..n]);
        let mut r = FrameReader::new();
        let (msgs, bad) = feed(&mut r, &stream);
        assert_eq!(msgs, vec![m]);
        assert_eq!(bad, 1);
    }
}
