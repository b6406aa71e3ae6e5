//! Errors from reading and writing session files, each naming the file and, for bad content,
//! the section and byte offset.

use std::path::PathBuf;

/// Why a session could not be saved or loaded.
#[derive(Debug)]
pub enum SessionError {
    /// The operating system refused an operation on `path`.
    Io {
        path: PathBuf,
        op: &'static str,
        source: std::io::Error,
    },
    /// The file holds no bytes at all.
    Empty { path: PathBuf },
    /// The file does not start with the session magic: not a dynaclay session.
    NotASession { path: PathBuf, found: [u8; 8] },
    /// The file was written by a newer, incompatible format version.
    UnsupportedVersion {
        path: PathBuf,
        found: u32,
        supported: u32,
    },
    /// The file ends before `section` is complete.
    Truncated {
        path: PathBuf,
        section: String,
        offset: u64,
        needed: u64,
        available: u64,
    },
    /// A section's stored checksum does not match its bytes.
    Checksum {
        path: PathBuf,
        section: String,
        offset: u64,
        stored: u32,
        computed: u32,
    },
    /// A section's content is inconsistent.
    Malformed {
        path: PathBuf,
        section: String,
        offset: u64,
        detail: String,
    },
    /// The session itself cannot be written (e.g. a lattice whose length mismatches its dims).
    Invalid { detail: String },
    /// The file could not be written (the previous file at the path is untouched).
    Write(dynaclay_files::WriteError),
}

impl From<dynaclay_files::WriteError> for SessionError {
    fn from(e: dynaclay_files::WriteError) -> Self {
        Self::Write(e)
    }
}

impl std::fmt::Display for SessionError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Io { path, op, source } => {
                write!(f, "{}: cannot {op}: {source}", path.display())
            }
            Self::Empty { path } => write!(
                f,
                "{}: the file is empty (0 bytes), not a dynaclay session",
                path.display()
            ),
            Self::NotASession { path, found } => write!(
                f,
                "{}: not a dynaclay session (starts with {:?}, expected \"DYNACLAY\")",
                path.display(),
                String::from_utf8_lossy(found)
            ),
            Self::UnsupportedVersion {
                path,
                found,
                supported,
            } if *found == 0 => write!(
                f,
                "{}: format version 0 at byte 8 is not a valid version (this build reads versions 1 to {supported})",
                path.display()
            ),
            Self::UnsupportedVersion {
                path,
                found,
                supported,
            } => write!(
                f,
                "{}: format version {found} at byte 8 is newer than the supported version {supported}",
                path.display()
            ),
            Self::Truncated {
                path,
                section,
                offset,
                needed,
                available,
            } => write!(
                f,
                "{}: truncated in section {section} at byte {offset}: needs {needed} bytes, {available} left",
                path.display()
            ),
            Self::Checksum {
                path,
                section,
                offset,
                stored,
                computed,
            } => write!(
                f,
                "{}: checksum mismatch in section {section} (starting at byte {offset}): stored {stored:08x}, computed {computed:08x}",
                path.display()
            ),
            Self::Malformed {
                path,
                section,
                offset,
                detail,
            } => write!(
                f,
                "{}: malformed section {section} at byte {offset}: {detail}",
                path.display()
            ),
            Self::Invalid { detail } => write!(f, "cannot save session: {detail}"),
            Self::Write(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for SessionError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Self::Io { source, .. } => Some(source),
            Self::Write(e) => e.source(),
            _ => None,
        }
    }
}
