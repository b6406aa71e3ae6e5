//! The one error type of every protocol codec: what was wrong, and at which byte.
//!
//! Codecs never panic on input; a malformed report or frame is a [`CodecError`] value that names
//! the protocol, the field and the byte offset, so a log line says exactly where a stream broke.

use std::fmt;

/// Why a report or frame could not be decoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CodecError {
    /// The input was shorter than the form needs.
    TooShort {
        /// Protocol or report name.
        what: &'static str,
        /// Bytes the form needs.
        needed: usize,
        /// Bytes that were given.
        got: usize,
    },
    /// The input was longer than the form allows.
    TooLong {
        /// Protocol or report name.
        what: &'static str,
        /// Largest length allowed.
        max: usize,
        /// Bytes that were given.
        got: usize,
    },
    /// A byte had a value the protocol does not allow there.
    BadByte {
        /// Protocol or report name.
        what: &'static str,
        /// The field the byte belongs to.
        field: &'static str,
        /// Offset of the byte in the input.
        offset: usize,
        /// The byte found.
        value: u8,
    },
    /// The checksum did not match the bytes it covers.
    BadCrc {
        /// Protocol or frame name.
        what: &'static str,
        /// Offset of the checksum field in the frame.
        offset: usize,
        /// Checksum carried by the frame.
        expected: u32,
        /// Checksum computed over the frame's bytes.
        computed: u32,
    },
    /// A length field disagreed with the form it announces.
    BadLength {
        /// Protocol or frame name.
        what: &'static str,
        /// Offset of the length field.
        offset: usize,
        /// The length announced.
        announced: usize,
        /// The length the announced type requires (or the largest allowed).
        expected: usize,
    },
}

impl fmt::Display for CodecError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::TooShort { what, needed, got } => {
                write!(
                    f,
                    "{what}: short input, {got} bytes where {needed} are needed"
                )
            }
            Self::TooLong { what, max, got } => {
                write!(
                    f,
                    "{what}: input of {got} bytes is longer than the {max} allowed"
                )
            }
            Self::BadByte {
                what,
                field,
                offset,
                value,
            } => {
                write!(
                    f,
                    "{what}: byte 0x{value:02x} at offset {offset} is not a valid {field}"
                )
            }
            Self::BadCrc {
                what,
                offset,
                expected,
                computed,
            } => write!(
                f,
                "{what}: CRC at offset {offset} is 0x{expected:08x} but the bytes give 0x{computed:08x}"
            ),
            Self::BadLength {
                what,
                offset,
                announced,
                expected,
            } => write!(
                f,
                "{what}: length field at offset {offset} says {announced}, expected {expected}"
            ),
        }
    }
}

impl std::error::Error for CodecError {}
