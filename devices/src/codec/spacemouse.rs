//! 3Dconnexion SpaceMouse HID input reports: pure decoding over byte slices.
//!
//! Forms (first byte is the report ID; integers little-endian `i16`, raw range about ±350):
//!
//! | report | bytes | content |
//! | --- | --- | --- |
//! | ID 1, 7 bytes | 1 + 6 | translation x, y, z (older devices: SpaceNavigator, SpaceExplorer) |
//! | ID 2, 7 bytes | 1 + 6 | rotation rx, ry, rz (older devices, sent after ID 1) |
//! | ID 1, 13 bytes | 1 + 12 | translation then rotation in one report (newer devices, 0x256f) |
//! | ID 3, 2..=9 bytes | 1 + n | button bits, little-endian, bit i = button i |
//!
//! Device axes: x right, y toward the user, z down; rotations about those axes. Mapping them to
//! the tool frame is [`crate::spacemouse::AxisMap`]'s job, not the codec's. Nothing here
//! allocates.

use super::CodecError;

const WHAT: &str = "SpaceMouse report";

/// Report ID of translation (and of the combined report).
pub const ID_TRANSLATION: u8 = 1;
/// Report ID of rotation.
pub const ID_ROTATION: u8 = 2;
/// Report ID of buttons.
pub const ID_BUTTONS: u8 = 3;
/// Longest button report (report ID plus 8 bytes of bits).
pub const MAX_BUTTON_REPORT: usize = 9;

/// A decoded SpaceMouse report.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SpaceMouseReport {
    /// Translation only (ID 1, 7 bytes).
    Translation([i16; 3]),
    /// Rotation only (ID 2, 7 bytes).
    Rotation([i16; 3]),
    /// Translation and rotation together (ID 1, 13 bytes).
    Combined {
        /// x, y, z.
        translation: [i16; 3],
        /// rx, ry, rz.
        rotation: [i16; 3],
    },
    /// Button bits (ID 3).
    Buttons(u64),
}

fn triple(b: &[u8]) -> [i16; 3] {
    [
        i16::from_le_bytes([b[0], b[1]]),
        i16::from_le_bytes([b[2], b[3]]),
        i16::from_le_bytes([b[4], b[5]]),
    ]
}

/// Decodes one input report as hidapi returns it (report ID first).
///
/// # Errors
/// [`CodecError::TooShort`] for an empty report, [`CodecError::BadByte`] for an unknown report
/// ID (offset 0), [`CodecError::BadLength`] when a known ID has a length none of its forms has.
pub fn decode_report(bytes: &[u8]) -> Result<SpaceMouseReport, CodecError> {
    let Some(&id) = bytes.first() else {
        return Err(CodecError::TooShort {
            what: WHAT,
            needed: 1,
            got: 0,
        });
    };
    let body = &bytes[1..];
    match (id, body.len()) {
        (ID_TRANSLATION, 6) => Ok(SpaceMouseReport::Translation(triple(body))),
        (ID_TRANSLATION, 12) => Ok(SpaceMouseReport::Combined {
            translation: triple(&body[..6]),
            rotation: triple(&body[6..]),
        }),
        (ID_ROTATION, 6) => Ok(SpaceMouseReport::Rotation(triple(body))),
        (ID_BUTTONS, 1..=8) => {
            let mut bits = [0u8; 8];
            bits[..body.len()].copy_from_slice(body);
            Ok(SpaceMouseReport::Buttons(u64::from_le_bytes(bits)))
        }
        (ID_TRANSLATION, n) => Err(CodecError::BadLength {
            what: "SpaceMouse translation report",
            offset: 0,
            announced: n + 1,
            expected: 7,
        }),
        (ID_ROTATION, n) => Err(CodecError::BadLength {
            what: "SpaceMouse rotation report",
            offset: 0,
            announced: n + 1,
            expected: 7,
        }),
        (ID_BUTTONS, n) => Err(CodecError::BadLength {
            what: "SpaceMouse button report",
            offset: 0,
            announced: n + 1,
            expected: MAX_BUTTON_REPORT,
        }),
        (other, _) => Err(CodecError::BadByte {
            what: WHAT,
            field: "report ID (1, 2 or 3)",
            offset: 0,
            value: other,
        }),
    }
}

/// Encodes a report in the form a device sends it (for fixtures and simulated devices); returns
/// the bytes and their length. Buttons use the shortest form holding the highest set bit (at
/// least 2 bytes, like a SpaceNavigator).
#[must_use]
pub fn encode_report(r: &SpaceMouseReport) -> ([u8; 13], usize) {
    let mut out = [0u8; 13];
    let put = |out: &mut [u8; 13], at: usize, v: [i16; 3]| {
        for (i, x) in v.iter().enumerate() {
            out[at + 2 * i..at + 2 * i + 2].copy_from_slice(&x.to_le_bytes());
        }
    };
    match *r {
        SpaceMouseReport::Translation(t) => {
            out[0] = ID_TRANSLATION;
            put(&mut out, 1, t);
            (out, 7)
        }
        SpaceMouseReport::Rotation(t) => {
            out[0] = ID_ROTATION;
            put(&mut out, 1, t);
            (out, 7)
        }
        SpaceMouseReport::Combined {
            translation,
            rotation,
        } => {
            out[0] = ID_TRANSLATION;
            put(&mut out, 1, translation);
            put(&mut out, 7, rotation);
            (out, 13)
        }
        SpaceMouseReport::Buttons(bits) => {
            out[0] = ID_BUTTONS;
            let used = (64 - bits.leading_zeros() as usize).div_ceil(8).max(2);
            out[1..1 + used].copy_from_slice(&bits.to_le_bytes()[..used]);
            (out, 1 + used)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fixture_translation_report() {
        // SpaceNavigator pushed right and slightly toward the user: x = 100, y = -30, z = 0.
        let r = decode_report(&[0x01, 0x64, 0x00, 0xe2, 0xff, 0x00, 0x00]).unwrap();
        assert_eq!(r, SpaceMouseReport::Translation([100, -30, 0]));
    }

    #[test]
    fn fixture_rotation_report() {
        // Rotation about the second axis, as captured from a SpaceNavigator: 02 00 00 e2 ff 00 00.
        let r = decode_report(&[0x02, 0x00, 0x00, 0xe2, 0xff, 0x00, 0x00]).unwrap();
        assert_eq!(r, SpaceMouseReport::Rotation([0, -30, 0]));
    }

    #[test]
    fn fixture_combined_report() {
        let bytes = [
            0x01, 0x5e, 0x01, 0xa2, 0xfe, 0x01, 0x00, 0x0a, 0x00, 0xf6, 0xff, 0x00, 0x00,
        ];
        let r = decode_report(&bytes).unwrap();
        assert_eq!(
            r,
            SpaceMouseReport::Combined {
                translation: [350, -350, 1],
                rotation: [10, -10, 0]
            }
        );
    }

    #[test]
    fn fixture_button_reports() {
        assert_eq!(
            decode_report(&[0x03, 0x01, 0x00]).unwrap(),
            SpaceMouseReport::Buttons(1)
        );
        assert_eq!(
            decode_report(&[0x03, 0x03, 0x00]).unwrap(),
            SpaceMouseReport::Buttons(3)
        );
        // SpaceMouse Pro style: four bytes of bits.
        assert_eq!(
            decode_report(&[0x03, 0x00, 0x10, 0x00, 0x80]).unwrap(),
            SpaceMouseReport::Buttons(0x8000_1000)
        );
    }

    #[test]
    fn encode_then_decode_round_trips() {
        for r in [
            SpaceMouseReport::Translation([1, -2, 3]),
            SpaceMouseReport::Rotation([-350, 350, 0]),
            SpaceMouseReport::Combined {
                translation: [i16::MIN, 0, i16::MAX],
                rotation: [5, 6, 7],
            },
            SpaceMouseReport::Buttons(0),
            SpaceMouseReport::Buttons(1 << 40),
        ] {
            let (b, n) = encode_report(&r);
            assert_eq!(decode_report(&b[..n]), Ok(r));
        }
    }

    #[test]
    fn malformed_reports_are_rejected() {
        assert!(matches!(
            decode_report(&[]),
            Err(CodecError::TooShort { .. })
        ));
        assert!(matches!(
            decode_report(&[0x01, 0, 0, 0]),
            Err(CodecError::BadLength { announced: 4, .. })
        ));
        assert!(matches!(
            decode_report(&[0x02; 13]),
            Err(CodecError::BadLength { .. })
        ));
        assert!(matches!(
            decode_report(&[0x03]),
            Err(CodecError::BadLength { .. })
        ));
        assert!(matches!(
            decode_report(&[0x17, 0x64]),
            Err(CodecError::BadByte {
                offset: 0,
                value: 0x17,
                ..
            })
        ));
    }
}
