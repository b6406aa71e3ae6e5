//! Errors from reading and writing session files, each naming the file and, for bad content,
//! the section and byte offset.

use std::path::PathBuf;

/// Why a session could not be saved or loaded.
#[derive(Debug, thiserror::Error)]
pub enum SessionError {
    /// The operating system refused an operation on `path`.
    #[error("{}: cannot {op}: {source}", path.display())]
    Io {
        path: PathBuf,
        op: &'static str,
        source: std::io::Error,
    },
    /// The file holds no bytes at all.
    #[error("{}: the file is empty (0 bytes), not a dynaclay session", path.display())]
    Empty { path: PathBuf },
    /// The file does not start with the session magic: not a dynaclay session.
    #[error(
        "{}: not a dynaclay session (starts with {:?}, expected \"DYNACLAY\")",
        path.display(),
        String::from_utf8_lossy(found)
    )]
    NotASession { path: PathBuf, found: [u8; 8] },
    /// The file was written by a newer, incompatible format version (or names version 0).
    #[error(
        "{}: format version {found} at byte 8 {}",
        path.display(),
        version_problem(*found, *supported)
    )]
    UnsupportedVersion {
        path: PathBuf,
        found: u32,
        supported: u32,
    },
    /// The file ends before `section` is complete.
    #[error(
        "{}: truncated in section {section} at byte {offset}: needs {needed} bytes, {available} left",
        path.display()
    )]
    Truncated {
        path: PathBuf,
        section: String,
        offset: u64,
        needed: u64,
        available: u64,
    },
    /// A section's stored checksum does not match its bytes.
    #[error(
        "{}: checksum mismatch in section {section} (starting at byte {offset}): stored {stored:08x}, computed {computed:08x}",
        path.display()
    )]
    Checksum {
        path: PathBuf,
        section: String,
        offset: u64,
        stored: u32,
        computed: u32,
    },
    /// A section's content is inconsistent.
    #[error("{}: malformed section {section} at byte {offset}: {detail}", path.display())]
    Malformed {
        path: PathBuf,
        section: String,
        offset: u64,
        detail: String,
    },
    /// The session itself cannot be written (e.g. a lattice whose length mismatches its dims).
    #[error("cannot save session: {detail}")]
    Invalid { detail: String },
    /// The file could not be written (the previous file at the path is untouched).
    #[error(transparent)]
    Write(#[from] dynaclay_files::WriteError),
}

/// What is wrong with format version `found`: version 0 is never valid; others are newer.
fn version_problem(found: u32, supported: u32) -> String {
    if found == 0 {
        format!("is not a valid version (this build reads versions 1 to {supported})")
    } else {
        format!("is newer than the supported version {supported}")
    }
}
