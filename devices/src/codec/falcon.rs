//! Novint Falcon frames (Novint SDK firmware): pure encode/decode and a resynchronising reader.
//!
//! A frame is 16 bytes: `'<'`, 14 payload bytes, `'>'`. Every payload byte carries one 4-bit
//! nibble plus 0x41, so payload bytes are always `'A'..='P'`. Bytes 1..13 hold three `i16`
//! words, least significant nibble first:
//!
//! | frame bytes | host → device | device → host |
//! | --- | --- | --- |
//! | 1..5, 5..9, 9..13 | motor commands 1, 2, 3 | encoder counts 1, 2, 3 |
//! | 13 | LED bits (green 0x2, blue 0x4, red 0x8) OR homing-mode bit 0x1 | grip buttons (bits 0..3) OR homed flags (bits 4..6) |
//! | 14 | 0 | unused (not read) |
//!
//! The layout is libnifalcon's reverse-engineered reading of the Novint SDK firmware
//! (`FalconFirmwareNovintSDK`: the reply's byte 13 minus 0x41 carries the grip bits in its low
//! nibble and the homed flags of motors 1, 2, 3 as bits 4, 5, 6, so that one byte ranges
//! `0x41..=0xC0`; byte 14 of a reply is not read). The USB link is an FTDI bridge at
//! [`STREAM_BAUD`]; firmware is loaded at [`FIRMWARE_BAUD`] (see
//! [`crate::falcon`]). Nothing here allocates.

use super::CodecError;

/// Bytes in one frame.
pub const FRAME_LEN: usize = 16;
/// Baud rate of the streaming link.
pub const STREAM_BAUD: u32 = 1_456_312;
/// Baud rate of the bootloader while firmware is loaded.
pub const FIRMWARE_BAUD: u32 = 140_000;
/// Baud rate of the bootloader's first handshake.
pub const BOOT_BAUD: u32 = 9_600;
/// Frame start byte.
pub const START: u8 = b'<';
/// Frame end byte.
pub const END: u8 = b'>';
/// Offset added to each payload nibble.
pub const NIBBLE_BASE: u8 = 0x41;
/// Shift of the homed flags in a reply's byte 13 (after removing [`NIBBLE_BASE`]).
pub const HOMED_SHIFT: u32 = 4;
/// Frame offset of the byte carrying LEDs and homing (commands) or grip and homed (replies).
pub const STATUS_BYTE: usize = 13;

/// Homing-mode bit in command byte 13.
pub const HOMING_MODE: u8 = 0x1;
/// Green LED bit.
pub const LED_GREEN: u8 = 0x2;
/// Blue LED bit.
pub const LED_BLUE: u8 = 0x4;
/// Red LED bit.
pub const LED_RED: u8 = 0x8;

const WHAT: &str = "Falcon frame";

/// What the host sends each tick.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FalconCommand {
    /// Raw motor commands (firmware units, proportional to motor current).
    pub motor: [i16; 3],
    /// LED bits ([`LED_GREEN`], [`LED_BLUE`], [`LED_RED`]).
    pub leds: u8,
    /// Ask the firmware to run its homing routine (drive each arm to its stop).
    pub homing: bool,
}

/// What the device answers each tick.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FalconStatus {
    /// Encoder counts of motors 1..3 (quadrature counts, 1280 per motor turn).
    pub encoders: [i16; 3],
    /// Grip button bits (low nibble).
    pub buttons: u8,
    /// Homed flags, bit i set once motor i+1 has been homed (reply byte 13, bits 4..6).
    pub homed: u8,
}

impl FalconStatus {
    /// Whether all three motors report homed.
    #[must_use]
    pub fn all_homed(&self) -> bool {
        self.homed & 0x7 == 0x7
    }
}

fn put_word(frame: &mut [u8; FRAME_LEN], at: usize, w: i16) {
    let w = w as u16;
    for k in 0..4 {
        frame[at + k] = ((w >> (4 * k)) & 0xf) as u8 + NIBBLE_BASE;
    }
}

/// A frame with three words, `b13` (up to 0x7f) in byte 13 and 0 in byte 14.
fn frame_with(words: [i16; 3], b13: u8) -> [u8; FRAME_LEN] {
    let mut f = [0u8; FRAME_LEN];
    f[0] = START;
    f[FRAME_LEN - 1] = END;
    for (i, w) in words.iter().enumerate() {
        put_word(&mut f, 1 + 4 * i, *w);
    }
    f[STATUS_BYTE] = (b13 & 0x7f) + NIBBLE_BASE;
    f[14] = NIBBLE_BASE;
    f
}

/// Which way a frame travels: replies carry a wider byte 13 and an unread byte 14.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Direction {
    Command,
    Reply,
}

/// Checks framing and payload ranges; returns the 14 payload values (byte minus 0x41; a
/// reply's byte 13 up to 0x7f, its byte 14 always 0).
fn payload(frame: &[u8], direction: Direction) -> Result<[u8; 14], CodecError> {
    CodecError::check_exact_len(WHAT, frame, FRAME_LEN)?;
    if frame[0] != START {
        return Err(CodecError::BadByte {
            what: WHAT,
            field: "start '<'",
            offset: 0,
            value: frame[0],
        });
    }
    if frame[FRAME_LEN - 1] != END {
        return Err(CodecError::BadByte {
            what: WHAT,
            field: "end '>'",
            offset: FRAME_LEN - 1,
            value: frame[FRAME_LEN - 1],
        });
    }
    let mut n = [0u8; 14];
    for (i, slot) in n.iter_mut().enumerate() {
        let offset = 1 + i;
        let b = frame[offset];
        let (span, field) = match (direction, offset) {
            (Direction::Reply, STATUS_BYTE) => (0x80, "grip and homed byte (0x41..=0xC0)"),
            (Direction::Reply, 14) => continue,
            _ => (16, "payload nibble ('A'..='P')"),
        };
        if !(NIBBLE_BASE..NIBBLE_BASE + span).contains(&b) {
            return Err(CodecError::BadByte {
                what: WHAT,
                field,
                offset,
                value: b,
            });
        }
        *slot = b - NIBBLE_BASE;
    }
    Ok(n)
}

fn word(n: &[u8; 14], first: usize) -> i16 {
    let mut w = 0u16;
    for k in 0..4 {
        w |= u16::from(n[first + k]) << (4 * k);
    }
    w as i16
}

/// Encodes a host → device frame.
#[must_use]
pub fn encode_command(cmd: &FalconCommand) -> [u8; FRAME_LEN] {
    let b13 = (cmd.leds & (LED_GREEN | LED_BLUE | LED_RED)) | u8::from(cmd.homing);
    frame_with(cmd.motor, b13)
}

/// Decodes a host → device frame (what simulated firmware reads).
///
/// # Errors
/// [`CodecError`] naming the offset of a bad start, end or payload byte, or a wrong length.
pub fn decode_command(frame: &[u8]) -> Result<FalconCommand, CodecError> {
    let n = payload(frame, Direction::Command)?;
    Ok(FalconCommand {
        motor: [word(&n, 0), word(&n, 4), word(&n, 8)],
        leds: n[12] & (LED_GREEN | LED_BLUE | LED_RED),
        homing: n[12] & HOMING_MODE != 0,
    })
}

/// Encodes a device → host frame (what simulated firmware sends).
#[must_use]
pub fn encode_status(status: &FalconStatus) -> [u8; FRAME_LEN] {
    frame_with(
        status.encoders,
        (status.buttons & 0xf) | ((status.homed & 0x7) << HOMED_SHIFT),
    )
}

/// Decodes a device → host frame.
///
/// # Errors
/// [`CodecError`] naming the offset of a bad start, end or payload byte, or a wrong length.
pub fn decode_status(frame: &[u8]) -> Result<FalconStatus, CodecError> {
    let n = payload(frame, Direction::Reply)?;
    Ok(FalconStatus {
        encoders: [word(&n, 0), word(&n, 4), word(&n, 8)],
        buttons: n[12] & 0xf,
        homed: (n[12] >> HOMED_SHIFT) & 0x7,
    })
}

/// What one byte pushed into a [`FalconReader`] produced.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ReadEvent {
    /// Nothing complete yet.
    Pending,
    /// A byte outside any frame was skipped (line noise, a torn frame's tail).
    Skipped(u8),
    /// A whole frame decoded.
    Frame(FalconStatus),
    /// A frame was started but was malformed; reading resynchronises at the next `'<'`.
    Bad(CodecError),
}

/// Streaming reader: finds frames in a byte stream, resynchronising after noise or a torn frame.
/// Fixed-size state; never allocates.
#[derive(Clone, Debug, Default)]
pub struct FalconReader {
    buf: [u8; FRAME_LEN],
    len: usize,
}

impl FalconReader {
    /// A reader waiting for a frame start.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// Forgets a partly read frame.
    pub fn reset(&mut self) {
        self.len = 0;
    }

    /// Whether a frame has started and not ended: its remaining bytes are on their way (a
    /// reply can reach the port in more than one piece).
    #[must_use]
    pub fn is_mid_frame(&self) -> bool {
        self.len > 0
    }

    /// Pushes one byte.
    pub fn push(&mut self, byte: u8) -> ReadEvent {
        if self.len == 0 {
            if byte != START {
                return ReadEvent::Skipped(byte);
            }
            self.buf[0] = byte;
            self.len = 1;
            return ReadEvent::Pending;
        }
        if byte == START {
            // '<' never occurs inside a frame (payload is 'A'..='P'): the previous one was torn. Report it and restart here.
            let got = self.len;
            self.buf[0] = byte;
            self.len = 1;
            return ReadEvent::Bad(CodecError::TooShort {
                what: WHAT,
                needed: FRAME_LEN,
                got,
            });
        }
        self.buf[self.len] = byte;
        self.len += 1;
        if self.len < FRAME_LEN {
            return ReadEvent::Pending;
        }
        self.len = 0;
        match decode_status(&self.buf) {
            Ok(s) => ReadEvent::Frame(s),
            Err(e) => ReadEvent::Bad(e),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn command_frame_has_nibbles_lsb_first_plus_0x41() {
        let f = encode_command(&FalconCommand {
            motor: [0x1234, -1, 0],
            leds: LED_RED,
            homing: true,
        });
        assert_eq!(f[0], b'<');
        assert_eq!(f[15], b'>');
        // 0x1234 -> nibbles 4, 3, 2, 1 -> 'E', 'D', 'C', 'B'.
        assert_eq!(&f[1..5], b"EDCB");
        assert_eq!(&f[5..9], b"PPPP", "-1 is all ones");
        assert_eq!(&f[9..13], b"AAAA");
        assert_eq!(f[13], b'A' + 0x9, "red LED plus homing bit");
        assert_eq!(f[14], b'A');
    }

    #[test]
    fn reply_byte_13_carries_grip_bits_low_and_homed_flags_in_bits_4_to_6() {
        // libnifalcon: homing status = ((byte13 - 0x41) >> 4) & 7, grip = (byte13 - 0x41) & 0xf.
        let mut f = encode_status(&FalconStatus::default());
        f[13] = 0x41 + 0x70 + 0x5; // all three homed, grip buttons 0b0101
        f[14] = b'z'; // not read
        let s = decode_status(&f).unwrap();
        assert_eq!(s.homed, 0x7);
        assert_eq!(s.buttons, 0x5);
        assert!(s.all_homed());
        f[13] = 0x41 + 0x30; // motors 1 and 2 homed, no button
        let s = decode_status(&f).unwrap();
        assert_eq!((s.homed, s.buttons), (0x3, 0));
        assert!(!s.all_homed());
        let e = encode_status(&FalconStatus {
            encoders: [0; 3],
            buttons: 0x2,
            homed: 0x4,
        });
        assert_eq!(e[13], 0x41 + 0x40 + 0x2);
        assert_eq!(e[14], b'A');
    }

    #[test]
    fn frames_round_trip() {
        let c = FalconCommand {
            motor: [i16::MIN, 77, i16::MAX],
            leds: LED_GREEN | LED_BLUE,
            homing: false,
        };
        assert_eq!(decode_command(&encode_command(&c)), Ok(c));
        let s = FalconStatus {
            encoders: [-3000, 0, 4095],
            buttons: 0b1010,
            homed: 0b101,
        };
        assert_eq!(decode_status(&encode_status(&s)), Ok(s));
        assert!(!s.all_homed());
    }

    #[test]
    fn malformed_frames_name_the_offset() {
        let mut f = encode_status(&FalconStatus::default());
        f[7] = b'z';
        assert!(matches!(
            decode_status(&f),
            Err(CodecError::BadByte {
                offset: 7,
                value: b'z',
                ..
            })
        ));
        let mut f = encode_status(&FalconStatus::default());
        f[13] = 0xC1;
        assert!(matches!(
            decode_status(&f),
            Err(CodecError::BadByte {
                offset: 13,
                value: 0xC1,
                ..
            })
        ));
        let mut f = encode_command(&FalconCommand::default());
        f[13] = b'Q';
        assert!(
            matches!(
                decode_command(&f),
                Err(CodecError::BadByte { offset: 13, .. })
            ),
            "a command's byte 13 is a nibble"
        );
        let mut f = encode_status(&FalconStatus::default());
        f[15] = b'A';
        assert!(matches!(
            decode_status(&f),
            Err(CodecError::BadByte { offset: 15, .. })
        ));
        assert!(matches!(
            decode_status(&f[..10]),
            Err(CodecError::TooShort { got: 10, .. })
        ));
    }

    #[test]
    fn reader_resynchronises_after_noise_and_torn_frames() {
        let good = FalconStatus {
            encoders: [1, 2, 3],
            buttons: 1,
            homed: 7,
        };
        let frame = encode_status(&good);
        let mut stream = Vec::new();
        stream.extend_from_slice(b"xx>");
        stream.extend_from_slice(&frame[..6]); // torn frame
        stream.extend_from_slice(&frame);
        let mut r = FalconReader::new();
        let events: Vec<ReadEvent> = stream.iter().map(|b| r.push(*b)).collect();
        let frames: Vec<_> = events
            .iter()
            .filter_map(|e| {
                if let ReadEvent::Frame(s) = e {
                    Some(*s)
                } else {
                    None
                }
            })
            .collect();
        assert_eq!(frames, vec![good]);
        assert_eq!(
            events
                .iter()
                .filter(|e| matches!(e, ReadEvent::Skipped(_)))
                .count(),
            3
        );
        assert!(
            events
                .iter()
                .any(|e| matches!(e, ReadEvent::Bad(CodecError::TooShort { got: 6, .. })))
        );
    }
}
