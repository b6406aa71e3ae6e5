//! The one error type of every protocol codec: what was wrong, and at which byte.
//!
//! Codecs never panic on input; a malformed report or frame is a [`CodecError`] value that names
//! the protocol, the field and the byte offset, so a log line says exactly where a stream broke.

/// Why a report or frame could not be decoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum CodecError {
    /// The input was shorter than the form needs.
    #[error("{what}: short input, {got} bytes where {needed} are needed")]
    TooShort {
        /// Protocol or report name.
        what: &'static str,
        /// Bytes the form needs.
        needed: usize,
        /// Bytes that were given.
        got: usize,
    },
    /// The input was longer than the form allows.
    #[error("{what}: input of {got} bytes is longer than the {max} allowed")]
    TooLong {
        /// Protocol or report name.
        what: &'static str,
        /// Largest length allowed.
        max: usize,
        /// Bytes that were given.
        got: usize,
    },
    /// A byte had a value the protocol does not allow there.
    #[error("{what}: byte 0x{value:02x} at offset {offset} is not a valid {field}")]
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
    #[error(
        "{what}: CRC at offset {offset} is 0x{expected:08x} but the bytes give 0x{computed:08x}"
    )]
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
    #[error("{what}: length field at offset {offset} says {announced}, expected {expected}")]
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

impl CodecError {
    /// `Ok` when `bytes` is exactly `len` bytes long, else [`CodecError::TooShort`] or
    /// [`CodecError::TooLong`] naming `what`: for fixed-size reports and frames.
    ///
    /// # Errors
    /// As above.
    pub fn check_exact_len(what: &'static str, bytes: &[u8], len: usize) -> Result<(), Self> {
        let got = bytes.len();
        if got < len {
            return Err(Self::TooShort {
                what,
                needed: len,
                got,
            });
        }
        if got > len {
            return Err(Self::TooLong {
                what,
                max: len,
                got,
            });
        }
        Ok(())
    }
}
