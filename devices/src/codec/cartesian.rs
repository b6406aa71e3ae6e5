//! The dynaclay Cartesian HID reports: tool position in µm in, force in mN out.
//!
//! For custom firmware on a USB HID arm that does its own kinematics (see `devices/PROTOCOL.md`,
//! "Cartesian HID profile"). All integers little-endian; no report IDs.
//!
//! Device → host, [`INPUT_LEN`] bytes: x, y, z (`i32` µm), buttons (`u16`), status (`u8`, the
//! bits of [`super::frame::status`]), sequence echo (`u8`).
//!
//! Host → device, [`OUTPUT_LEN`] bytes as written through hidapi: report ID 0, fx, fy, fz
//! (`i16` mN), flags (`u8`: [`FLAG_ENABLE`], [`FLAG_HOME`]), sequence (`u8`), 6 reserved zero
//! bytes — 14 bytes after the report ID, like the WoodenHaptics reports, so one firmware USB
//! descriptor serves both. Nothing here allocates.

use super::CodecError;

/// Bytes of a device → host report.
pub const INPUT_LEN: usize = 16;
/// Bytes of a host → device report, report ID 0 included.
pub const OUTPUT_LEN: usize = 15;
/// Output flag: motors may be powered.
pub const FLAG_ENABLE: u8 = 0x1;
/// Output flag: start homing.
pub const FLAG_HOME: u8 = 0x2;

/// A decoded device → host report.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CartesianState {
    /// Tool position in micrometres, device frame.
    pub position_um: [i32; 3],
    /// Button bits.
    pub buttons: u16,
    /// Status bits (homed, motors on, fault).
    pub status: u8,
    /// Sequence number of the last command applied.
    pub seq: u8,
}

/// A host → device command.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CartesianCommand {
    /// Force in millinewtons, device frame.
    pub force_mn: [i16; 3],
    /// [`FLAG_ENABLE`] and [`FLAG_HOME`] bits.
    pub flags: u8,
    /// Sequence number.
    pub seq: u8,
}

/// Encodes a device → host report (simulated firmware side).
#[must_use]
pub fn encode_state(s: &CartesianState) -> [u8; INPUT_LEN] {
    let mut out = [0u8; INPUT_LEN];
    for (i, x) in s.position_um.iter().enumerate() {
        out[4 * i..4 * i + 4].copy_from_slice(&x.to_le_bytes());
    }
    out[12..14].copy_from_slice(&s.buttons.to_le_bytes());
    out[14] = s.status;
    out[15] = s.seq;
    out
}

/// Decodes a device → host report.
///
/// # Errors
/// [`CodecError::TooShort`]/[`CodecError::TooLong`] when `bytes` is not [`INPUT_LEN`] long.
pub fn decode_state(bytes: &[u8]) -> Result<CartesianState, CodecError> {
    const WHAT: &str = "Cartesian input report";
    CodecError::check_exact_len(WHAT, bytes, INPUT_LEN)?;
    let i = |k: usize| {
        i32::from_le_bytes([
            bytes[4 * k],
            bytes[4 * k + 1],
            bytes[4 * k + 2],
            bytes[4 * k + 3],
        ])
    };
    Ok(CartesianState {
        position_um: [i(0), i(1), i(2)],
        buttons: u16::from_le_bytes([bytes[12], bytes[13]]),
        status: bytes[14],
        seq: bytes[15],
    })
}

/// Encodes a host → device report, report ID 0 first.
#[must_use]
pub fn encode_command(c: &CartesianCommand) -> [u8; OUTPUT_LEN] {
    let mut out = [0u8; OUTPUT_LEN];
    for (i, f) in c.force_mn.iter().enumerate() {
        out[1 + 2 * i..3 + 2 * i].copy_from_slice(&f.to_le_bytes());
    }
    out[7] = c.flags;
    out[8] = c.seq;
    out
}

/// Decodes a host → device report with its report ID (simulated firmware side).
///
/// # Errors
/// [`CodecError`] for a wrong length, a non-zero report ID, unknown flag bits or non-zero
/// reserved bytes (with their offset).
pub fn decode_command(bytes: &[u8]) -> Result<CartesianCommand, CodecError> {
    const WHAT: &str = "Cartesian output report";
    CodecError::check_exact_len(WHAT, bytes, OUTPUT_LEN)?;
    if bytes[0] != 0 {
        return Err(CodecError::BadByte {
            what: WHAT,
            field: "report ID (must be 0)",
            offset: 0,
            value: bytes[0],
        });
    }
    if bytes[7] & !(FLAG_ENABLE | FLAG_HOME) != 0 {
        return Err(CodecError::BadByte {
            what: WHAT,
            field: "flags",
            offset: 7,
            value: bytes[7],
        });
    }
    if let Some(k) = (9..OUTPUT_LEN).find(|&k| bytes[k] != 0) {
        return Err(CodecError::BadByte {
            what: WHAT,
            field: "reserved (must be 0)",
            offset: k,
            value: bytes[k],
        });
    }
    let w = |k: usize| i16::from_le_bytes([bytes[1 + 2 * k], bytes[2 + 2 * k]]);
    Ok(CartesianCommand {
        force_mn: [w(0), w(1), w(2)],
        flags: bytes[7],
        seq: bytes[8],
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reports_round_trip() {
        let s = CartesianState {
            position_um: [-150_000, 0, 2_000_000],
            buttons: 0x8001,
            status: 3,
            seq: 200,
        };
        assert_eq!(decode_state(&encode_state(&s)), Ok(s));
        let c = CartesianCommand {
            force_mn: [3000, -3000, 1],
            flags: FLAG_ENABLE,
            seq: 9,
        };
        assert_eq!(decode_command(&encode_command(&c)), Ok(c));
    }

    #[test]
    fn recorded_state_report_decodes() {
        // x = 1000 µm, y = -1 µm, z = 0, buttons = 1, status = homed|motors, seq = 5.
        let bytes = [
            0xe8, 0x03, 0, 0, 0xff, 0xff, 0xff, 0xff, 0, 0, 0, 0, 1, 0, 3, 5,
        ];
        let s = decode_state(&bytes).unwrap();
        assert_eq!(s.position_um, [1000, -1, 0]);
        assert_eq!((s.buttons, s.status, s.seq), (1, 3, 5));
    }

    #[test]
    fn malformed_reports_are_rejected() {
        assert!(matches!(
            decode_state(&[0; 15]),
            Err(CodecError::TooShort { got: 15, .. })
        ));
        let mut c = encode_command(&CartesianCommand::default());
        c[12] = 1;
        assert!(matches!(
            decode_command(&c),
            Err(CodecError::BadByte { offset: 12, .. })
        ));
        let mut c = encode_command(&CartesianCommand::default());
        c[7] = 0x80;
        assert!(matches!(
            decode_command(&c),
            Err(CodecError::BadByte {
                offset: 7,
                field: "flags",
                ..
            })
        ));
    }
}
