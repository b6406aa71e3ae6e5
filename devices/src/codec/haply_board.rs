//! The Haply board's serial protocol (the 2DIY's Arduino board, as Haply's hAPI 2 library
//! speaks it). Every host message is one header byte (the message type), the device id, then
//! the type's bytes and little-endian IEEE-754 `f32`s:
//!
//! | type | name  | after the device id                                                    |
//! |------|-------|-------------------------------------------------------------------------|
//! | 0    | reset | nothing (the device id is 0)                                            |
//! | 1    | setup | motor mask, one direction byte per active motor; encoder mask, one      |
//! |      |       | direction byte per active encoder; analog sensor count (0 here); then   |
//! |      |       | `f32` offset (degrees) and `f32` resolution (steps per turn) per active |
//! |      |       | encoder                                                                 |
//! | 2    | data  | one `f32` torque (newton-metres) per active motor                       |
//!
//! A mask has bit `i` set when board port `i + 1` is in use; everything per port comes in port
//! order. The board answers each data message with the device id and one `f32` angle
//! (degrees) per active encoder, in port order: `1 + 4n` bytes. Directions are 0 for
//! clockwise, 1 for counter-clockwise.
//!
//! Pure functions over byte slices: no I/O, no allocation, no panic on any input.

use super::CodecError;

/// Message types (the header byte).
pub mod kind {
    /// Software reset of the board.
    pub const RESET: u8 = 0;
    /// Motor and encoder set-up.
    pub const SETUP: u8 = 1;
    /// Torques out, angles back.
    pub const DATA: u8 = 2;
}

/// Number of motor/encoder ports on the board.
pub const PORTS: usize = 4;

/// Longest host message: a set-up with every port in use.
pub const MAX_HOST_MESSAGE: usize = 2 + (1 + PORTS) * 2 + 1 + 8 * PORTS;

/// Longest board reply: the device id and one angle per port.
pub const MAX_REPLY: usize = 1 + 4 * PORTS;

/// Clockwise, as a direction byte.
pub const CW: u8 = 0;
/// Counter-clockwise, as a direction byte.
pub const CCW: u8 = 1;

const WHAT: &str = "Haply board";

/// One board port's motor and encoder.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PortSetup {
    /// Board port, 1 to 4.
    pub port: u8,
    /// Positive direction of the motor ([`CW`] or [`CCW`]).
    pub motor_direction: u8,
    /// Positive direction of the encoder.
    pub encoder_direction: u8,
    /// Encoder angle at the index position, degrees.
    pub encoder_offset_deg: f32,
    /// Encoder steps per turn.
    pub encoder_steps_per_turn: f32,
}

fn mask(ports: &[PortSetup]) -> Result<u8, CodecError> {
    let mut m = 0u8;
    for (i, p) in ports.iter().enumerate() {
        if !(1..=PORTS as u8).contains(&p.port) || m & (1 << (p.port - 1)) != 0 {
            return Err(CodecError::BadByte {
                what: WHAT,
                field: "port number (1 to 4, each once)",
                offset: i,
                value: p.port,
            });
        }
        m |= 1 << (p.port - 1);
    }
    Ok(m)
}

fn put_f32(out: &mut [u8], at: usize, v: f32) {
    out[at..at + 4].copy_from_slice(&v.to_le_bytes());
}

/// Writes the reset message; returns its length (2).
///
/// # Errors
/// [`CodecError::TooShort`] when `out` is shorter.
pub fn encode_reset(out: &mut [u8]) -> Result<usize, CodecError> {
    if out.len() < 2 {
        return Err(CodecError::TooShort {
            what: WHAT,
            needed: 2,
            got: out.len(),
        });
    }
    out[0] = kind::RESET;
    out[1] = 0;
    Ok(2)
}

/// Writes the set-up message for `ports` (given in port order or not: the message is in port
/// order); returns its length.
///
/// # Errors
/// [`CodecError::BadByte`] for a port outside 1–4 or given twice; [`CodecError::TooShort`]
/// when `out` is too small.
pub fn encode_setup(
    device_id: u8,
    ports: &[PortSetup],
    out: &mut [u8],
) -> Result<usize, CodecError> {
    if ports.len() > PORTS {
        return Err(CodecError::TooLong {
            what: WHAT,
            max: PORTS,
            got: ports.len(),
        });
    }
    let m = mask(ports)?;
    let n = ports.len();
    let len = 2 + (1 + n) * 2 + 1 + 8 * n;
    if out.len() < len {
        return Err(CodecError::TooShort {
            what: WHAT,
            needed: len,
            got: out.len(),
        });
    }
    let mut by_port = [None; PORTS];
    for p in ports {
        by_port[usize::from(p.port - 1)] = Some(*p);
    }
    let in_order = || by_port.iter().flatten();
    out[0] = kind::SETUP;
    out[1] = device_id;
    let mut at = 2;
    out[at] = m;
    at += 1;
    for p in in_order() {
        out[at] = p.motor_direction;
        at += 1;
    }
    out[at] = m;
    at += 1;
    for p in in_order() {
        out[at] = p.encoder_direction;
        at += 1;
    }
    out[at] = 0; // no analog sensors
    at += 1;
    for p in in_order() {
        put_f32(out, at, p.encoder_offset_deg);
        put_f32(out, at + 4, p.encoder_steps_per_turn);
        at += 8;
    }
    debug_assert_eq!(at, len);
    Ok(len)
}

/// Writes a data message carrying `torques_n_m` (one per active motor, port order); returns
/// its length.
///
/// # Errors
/// [`CodecError::TooLong`] for more than four torques, [`CodecError::TooShort`] when `out` is
/// too small.
pub fn encode_torques(
    device_id: u8,
    torques_n_m: &[f32],
    out: &mut [u8],
) -> Result<usize, CodecError> {
    if torques_n_m.len() > PORTS {
        return Err(CodecError::TooLong {
            what: WHAT,
            max: PORTS,
            got: torques_n_m.len(),
        });
    }
    let len = 2 + 4 * torques_n_m.len();
    if out.len() < len {
        return Err(CodecError::TooShort {
            what: WHAT,
            needed: len,
            got: out.len(),
        });
    }
    out[0] = kind::DATA;
    out[1] = device_id;
    for (i, t) in torques_n_m.iter().enumerate() {
        put_f32(out, 2 + 4 * i, if t.is_finite() { *t } else { 0.0 });
    }
    Ok(len)
}

/// Length of the board's reply for `encoders` active encoders.
#[must_use]
pub const fn reply_len(encoders: usize) -> usize {
    1 + 4 * encoders
}

/// Decodes a reply of exactly `angles_deg.len()` angles from `device_id` into `angles_deg`.
///
/// # Errors
/// [`CodecError::TooShort`]/[`CodecError::TooLong`] for a reply of the wrong length,
/// [`CodecError::BadByte`] when it comes from another device id or carries a non-finite angle
/// (the offset is the angle's first byte).
pub fn decode_angles(
    device_id: u8,
    reply: &[u8],
    angles_deg: &mut [f32],
) -> Result<(), CodecError> {
    let want = reply_len(angles_deg.len());
    if angles_deg.len() > PORTS || reply.len() > want {
        return Err(CodecError::TooLong {
            what: WHAT,
            max: want.min(MAX_REPLY),
            got: reply.len(),
        });
    }
    if reply.len() < want {
        return Err(CodecError::TooShort {
            what: WHAT,
            needed: want,
            got: reply.len(),
        });
    }
    if reply[0] != device_id {
        return Err(CodecError::BadByte {
            what: WHAT,
            field: "device id of the reply",
            offset: 0,
            value: reply[0],
        });
    }
    for (i, a) in angles_deg.iter_mut().enumerate() {
        let at = 1 + 4 * i;
        let v = f32::from_le_bytes([reply[at], reply[at + 1], reply[at + 2], reply[at + 3]]);
        if !v.is_finite() {
            return Err(CodecError::BadByte {
                what: WHAT,
                field: "angle (not a finite number)",
                offset: at,
                value: reply[at + 3],
            });
        }
        *a = v;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ports() -> [PortSetup; 2] {
        [
            PortSetup {
                port: 2,
                motor_direction: CCW,
                encoder_direction: CCW,
                encoder_offset_deg: 168.0,
                encoder_steps_per_turn: 4880.0,
            },
            PortSetup {
                port: 1,
                motor_direction: CW,
                encoder_direction: CCW,
                encoder_offset_deg: 12.0,
                encoder_steps_per_turn: 4880.0,
            },
        ]
    }

    #[test]
    fn setup_is_in_port_order_with_masks_and_little_endian_floats() {
        let mut out = [0u8; MAX_HOST_MESSAGE];
        let n = encode_setup(5, &ports(), &mut out).unwrap();
        assert_eq!(n, 25);
        assert_eq!(&out[..9], &[1, 5, 0b11, CW, CCW, 0b11, CCW, CCW, 0]);
        let f = |at: usize| f32::from_le_bytes(out[at..at + 4].try_into().unwrap());
        assert_eq!([f(9), f(13), f(17), f(21)], [12.0, 4880.0, 168.0, 4880.0]);
        let mut bad = ports();
        bad[1].port = 2;
        assert!(matches!(
            encode_setup(5, &bad, &mut out),
            Err(CodecError::BadByte {
                offset: 1,
                value: 2,
                ..
            })
        ));
        bad[1].port = 0;
        assert!(encode_setup(5, &bad, &mut out).is_err());
        assert!(encode_setup(5, &ports(), &mut out[..24]).is_err());
    }

    #[test]
    fn torques_and_reset() {
        let mut out = [0u8; MAX_HOST_MESSAGE];
        assert_eq!(encode_reset(&mut out).unwrap(), 2);
        assert_eq!(&out[..2], &[0, 0]);
        let n = encode_torques(5, &[0.5, f32::NAN], &mut out).unwrap();
        assert_eq!(n, 10);
        assert_eq!(&out[..2], &[2, 5]);
        assert_eq!(&out[2..6], &0.5f32.to_le_bytes());
        assert_eq!(&out[6..10], &0.0f32.to_le_bytes());
        assert!(encode_torques(5, &[0.0; 5], &mut out).is_err());
    }

    #[test]
    fn replies_are_checked_for_length_id_and_finite_angles() {
        let mut reply = [0u8; 9];
        reply[0] = 5;
        reply[1..5].copy_from_slice(&12.5f32.to_le_bytes());
        reply[5..9].copy_from_slice(&(-3.0f32).to_le_bytes());
        let mut a = [0.0; 2];
        decode_angles(5, &reply, &mut a).unwrap();
        assert_eq!(a, [12.5, -3.0]);
        assert!(matches!(
            decode_angles(4, &reply, &mut a),
            Err(CodecError::BadByte {
                offset: 0,
                value: 5,
                ..
            })
        ));
        assert!(matches!(
            decode_angles(5, &reply[..8], &mut a),
            Err(CodecError::TooShort {
                needed: 9,
                got: 8,
                ..
            })
        ));
        reply[5..9].copy_from_slice(&f32::INFINITY.to_le_bytes());
        assert!(matches!(
            decode_angles(5, &reply, &mut a),
            Err(CodecError::BadByte { offset: 5, .. })
        ));
        let mut many = [0.0; 5];
        assert!(decode_angles(5, &[0; 21], &mut many).is_err());
    }
}
