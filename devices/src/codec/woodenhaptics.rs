//! WoodenHaptics / Polhem USB HID reports: pure encode and decode over byte slices.
//!
//! The open-hardware firmware (WoodenHaptics 1.5+, Polhem) exchanges 14-byte vendor reports
//! without report IDs, every field a little-endian `i16`:
//!
//! | offset | host → device (`OUTPUT_LEN` incl. report ID 0) | device → host (`INPUT_LEN`) |
//! | --- | --- | --- |
//! | 0..6 | motor currents a, b, c in mA | encoder counts a, b, c |
//! | 6..8 | command word (0 = drive, 1 = set encoders) | encoder count d |
//! | 8..14 | three command attributes | encoder counts e, f, then the info word |
//!
//! Command 1 sets encoders a–c from the attributes and d–f from the current fields, and clears the
//! calibration flag (info bit 0, latched when the calibration switch closes). The firmware cuts
//! motor power when no report arrives for 0.5 s, so a host must keep reports flowing.
//! Nothing here allocates.

use super::CodecError;

/// Bytes of a host → device report as written through hidapi: report ID 0, then 14 bytes.
pub const OUTPUT_LEN: usize = 15;
/// Bytes of a device → host report.
pub const INPUT_LEN: usize = 14;
/// The firmware's watchdog: motor power is cut after this long without a report.
pub const WATCHDOG_US: u64 = 500_000;

/// The command word of a host → device report.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WhCommand {
    /// Drive the motors with the given currents (command word 0).
    Drive {
        /// Motor currents in mA, axes a, b, c.
        currents_ma: [i16; 3],
    },
    /// Set the six encoder counters (command word 1); motors are not driven by this report.
    SetEncoders {
        /// New encoder counts a..f.
        counts: [i16; 6],
    },
    /// Any other command word, kept verbatim so unknown firmware extensions round-trip.
    Raw {
        /// The three current fields in mA.
        currents_ma: [i16; 3],
        /// The command word.
        command: i16,
        /// The three attribute words.
        attrs: [i16; 3],
    },
}

/// A decoded device → host report.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct WhStatus {
    /// Encoder counts a..f (a–c drive the arm, d–f a gimbal where fitted).
    pub encoders: [i16; 6],
    /// The info word; bit 0 is the latched calibration-switch flag.
    pub info: i16,
}

impl WhStatus {
    /// Whether the calibration switch has closed since the encoders were last set.
    #[must_use]
    pub fn calibration_switch(&self) -> bool {
        self.info & 1 != 0
    }
}

/// Encodes a host → device report, report ID 0 first, ready for `hid_write`.
#[must_use]
pub fn encode_command(cmd: &WhCommand) -> [u8; OUTPUT_LEN] {
    let (currents, command, attrs) = match *cmd {
        WhCommand::Drive { currents_ma } => (currents_ma, 0, [0; 3]),
        WhCommand::SetEncoders { counts } => (
            [counts[3], counts[4], counts[5]],
            1,
            [counts[0], counts[1], counts[2]],
        ),
        WhCommand::Raw {
            currents_ma,
            command,
            attrs,
        } => (currents_ma, command, attrs),
    };
    let words = [
        currents[0],
        currents[1],
        currents[2],
        command,
        attrs[0],
        attrs[1],
        attrs[2],
    ];
    let mut out = [0u8; OUTPUT_LEN];
    for (i, w) in words.iter().enumerate() {
        out[1 + 2 * i..3 + 2 * i].copy_from_slice(&w.to_le_bytes());
    }
    out
}

/// Decodes a host → device report (with or without its leading report ID 0), as the firmware
/// sees it. Used by tests and by simulated firmware.
///
/// # Errors
/// [`CodecError::TooShort`]/[`CodecError::TooLong`] when the length is neither 14 nor 15, and
/// [`CodecError::BadByte`] when a 15-byte report does not start with report ID 0.
pub fn decode_command(bytes: &[u8]) -> Result<WhCommand, CodecError> {
    const WHAT: &str = "WoodenHaptics output report";
    let body = match bytes.len() {
        OUTPUT_LEN => {
            if bytes[0] != 0 {
                return Err(CodecError::BadByte {
                    what: WHAT,
                    field: "report ID (must be 0)",
                    offset: 0,
                    value: bytes[0],
                });
            }
            &bytes[1..]
        }
        INPUT_LEN => bytes,
        n if n < INPUT_LEN => {
            return Err(CodecError::TooShort {
                what: WHAT,
                needed: INPUT_LEN,
                got: n,
            });
        }
        n => {
            return Err(CodecError::TooLong {
                what: WHAT,
                max: OUTPUT_LEN,
                got: n,
            });
        }
    };
    let w = |i: usize| i16::from_le_bytes([body[2 * i], body[2 * i + 1]]);
    let currents_ma = [w(0), w(1), w(2)];
    let command = w(3);
    let attrs = [w(4), w(5), w(6)];
    Ok(match command {
        0 if attrs == [0; 3] => WhCommand::Drive { currents_ma },
        1 => WhCommand::SetEncoders {
            counts: [
                attrs[0],
                attrs[1],
                attrs[2],
                currents_ma[0],
                currents_ma[1],
                currents_ma[2],
            ],
        },
        _ => WhCommand::Raw {
            currents_ma,
            command,
            attrs,
        },
    })
}

/// Encodes a device → host report (what the firmware sends). Used by simulated firmware.
#[must_use]
pub fn encode_status(status: &WhStatus) -> [u8; INPUT_LEN] {
    let mut out = [0u8; INPUT_LEN];
    for (i, e) in status.encoders.iter().enumerate() {
        out[2 * i..2 * i + 2].copy_from_slice(&e.to_le_bytes());
    }
    out[12..14].copy_from_slice(&status.info.to_le_bytes());
    out
}

/// Decodes a device → host report.
///
/// hidapi returns exactly the report's 14 bytes for a device without report IDs; anything else
/// is rejected rather than guessed at.
///
/// # Errors
/// [`CodecError::TooShort`] or [`CodecError::TooLong`] when `bytes` is not 14 bytes long.
pub fn decode_status(bytes: &[u8]) -> Result<WhStatus, CodecError> {
    const WHAT: &str = "WoodenHaptics input report";
    CodecError::check_exact_len(WHAT, bytes, INPUT_LEN)?;
    let w = |i: usize| i16::from_le_bytes([bytes[2 * i], bytes[2 * i + 1]]);
    Ok(WhStatus {
        encoders: [w(0), w(1), w(2), w(3), w(4), w(5)],
        info: w(6),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn drive_report_layout_is_little_endian_after_report_id() {
        let out = encode_command(&WhCommand::Drive {
            currents_ma: [1000, -2, 0x1234],
        });
        assert_eq!(out[0], 0, "report ID");
        assert_eq!(&out[1..3], &1000i16.to_le_bytes());
        assert_eq!(&out[3..5], &[0xfe, 0xff]);
        assert_eq!(&out[5..7], &[0x34, 0x12]);
        assert_eq!(&out[7..15], &[0u8; 8], "command 0 and zero attributes");
    }

    #[test]
    fn commands_round_trip() {
        let cases = [
            WhCommand::Drive {
                currents_ma: [i16::MIN, 0, i16::MAX],
            },
            WhCommand::SetEncoders {
                counts: [1, -2, 3, -4, 5, -6],
            },
            WhCommand::Raw {
                currents_ma: [7, 8, 9],
                command: 42,
                attrs: [-1, -2, -3],
            },
        ];
        for c in cases {
            assert_eq!(decode_command(&encode_command(&c)), Ok(c));
            // The firmware sees the 14 bytes without the report ID.
            assert_eq!(decode_command(&encode_command(&c)[1..]), Ok(c));
        }
    }

    #[test]
    fn status_round_trips_and_reads_the_switch_flag() {
        let s = WhStatus {
            encoders: [100, -100, 32767, -32768, 0, 1],
            info: 1,
        };
        let bytes = encode_status(&s);
        // Recorded form: encoder a = 100 = 0x0064 little-endian.
        assert_eq!(&bytes[0..2], &[0x64, 0x00]);
        let back = decode_status(&bytes).unwrap();
        assert_eq!(back, s);
        assert!(back.calibration_switch());
    }

    #[test]
    fn malformed_reports_are_rejected_with_the_offending_length_or_byte() {
        assert_eq!(
            decode_status(&[0u8; 13]),
            Err(CodecError::TooShort {
                what: "WoodenHaptics input report",
                needed: 14,
                got: 13
            })
        );
        assert!(matches!(
            decode_status(&[0u8; 15]),
            Err(CodecError::TooLong { got: 15, .. })
        ));
        let mut bad = encode_command(&WhCommand::Drive {
            currents_ma: [0; 3],
        });
        bad[0] = 2;
        assert!(matches!(
            decode_command(&bad),
            Err(CodecError::BadByte {
                offset: 0,
                value: 2,
                ..
            })
        ));
        assert!(matches!(
            decode_command(&[]),
            Err(CodecError::TooShort { got: 0, .. })
        ));
    }
}
