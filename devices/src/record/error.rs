//! Errors from reading or writing a recording, naming the byte offset and block at fault.

use std::fmt;
use std::io;
use std::path::PathBuf;

/// Why a recording could not be written or loaded.
#[derive(Debug, thiserror::Error)]
pub enum RecordError {
    /// A file operation failed.
    #[error("cannot {action} {}: {source}", path.display())]
    Io {
        /// The file involved.
        path: PathBuf,
        /// What was being done, e.g. `"create"`.
        action: &'static str,
        /// The underlying error.
        source: io::Error,
    },
    /// The file does not start with the recording magic.
    #[error("not a dynaclay recording (bad magic at byte 0)")]
    BadMagic,
    /// The file is a recording of a format version this build cannot read.
    #[error(
        "recording format version {found} is not supported (this build reads versions {oldest} to {supported})"
    )]
    UnsupportedVersion {
        /// Version found in the header.
        found: u16,
        /// The oldest version this build reads.
        oldest: u16,
        /// Version this build reads and writes.
        supported: u16,
    },
    /// The file ends before a structure it announces is complete.
    #[error(
        "recording truncated at byte {offset}{}: {what} needs {needed} bytes, {available} remain",
        Where(*block)
    )]
    Truncated {
        /// Byte offset where the incomplete structure starts.
        offset: u64,
        /// Index of the block being read, if inside the block section.
        block: Option<u32>,
        /// What was being read.
        what: &'static str,
        /// Bytes it needs.
        needed: u64,
        /// Bytes that remain in the file from `offset`.
        available: u64,
    },
    /// A checksum does not match its data.
    #[error(
        "recording checksum mismatch at byte {offset}{}: stored {stored:#010x}, computed {computed:#010x}",
        Where(*block)
    )]
    Checksum {
        /// Byte offset of the checksummed structure.
        offset: u64,
        /// Index of the block, or `None` for the header or end marker.
        block: Option<u32>,
        /// CRC-32 stored in the file.
        stored: u32,
        /// CRC-32 computed over the data.
        computed: u32,
    },
    /// A field has a value the format does not allow.
    #[error("malformed recording at byte {offset}{}: {what}", Where(*block))]
    Malformed {
        /// Byte offset of the offending field or record.
        offset: u64,
        /// Index of the block, if inside the block section.
        block: Option<u32>,
        /// What is wrong.
        what: &'static str,
    },
    /// An error in the file at `path`.
    #[error("{}: {error}", path.display())]
    InFile {
        /// The recording file.
        path: PathBuf,
        /// What is wrong with it.
        #[source]
        error: Box<RecordError>,
    },
}

impl RecordError {
    /// The error without its file wrapper.
    #[must_use]
    pub fn root(&self) -> &RecordError {
        match self {
            Self::InFile { error, .. } => error.root(),
            other => other,
        }
    }

    /// The byte offset the error names, if any.
    #[must_use]
    pub fn offset(&self) -> Option<u64> {
        match self.root() {
            Self::BadMagic | Self::UnsupportedVersion { .. } => Some(0),
            Self::Truncated { offset, .. }
            | Self::Checksum { offset, .. }
            | Self::Malformed { offset, .. } => Some(*offset),
            Self::Io { .. } | Self::InFile { .. } => None,
        }
    }

    /// The block index the error names, if any.
    #[must_use]
    pub fn block(&self) -> Option<u32> {
        match self.root() {
            Self::Truncated { block, .. }
            | Self::Checksum { block, .. }
            | Self::Malformed { block, .. } => *block,
            _ => None,
        }
    }
}

struct Where(Option<u32>);

impl fmt::Display for Where {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.0 {
            Some(block) => write!(f, " in block {block}"),
            None => Ok(()),
        }
    }
}
