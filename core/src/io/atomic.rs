//! Durable saves: a session is written through the one atomic writer
//! ([`dynaclay_files::write_atomic`]: a temporary file in the target's directory, flushed to
//! disk, renamed over the target and the directory entry flushed), so a crash at any point
//! leaves either the previous file or the new one, never a mix. Loading reads the whole file
//! through a size cap and validates it before returning anything.

use std::fs;
use std::path::{Path, PathBuf};

use super::error::SessionError;
use super::format::{decode, encode};
use super::session::Session;

/// Saves `session` to `path` atomically.
///
/// # Errors
/// [`SessionError::Invalid`] when the session cannot be encoded, [`SessionError::Io`] naming
/// the failing operation; in either case the file at `path` is unchanged.
pub fn save_session(path: &Path, session: &Session) -> Result<(), SessionError> {
    let bytes = encode(session)?;
    write_atomic(path, &bytes)
}

/// The largest session file read, bytes (sixteen 96³ patches with paint fit well inside).
pub const MAX_SESSION_BYTES: u64 = 1 << 30;

/// Loads and validates the session at `path`. Only a regular file of at most
/// [`MAX_SESSION_BYTES`] is read (a FIFO or a device such as `/dev/zero` is refused at once).
///
/// # Errors
/// [`SessionError::Io`] when it cannot be read; the format errors of
/// [`decode`](super::format::decode) otherwise.
pub fn load_session(path: &Path) -> Result<Session, SessionError> {
    let bytes = dynaclay_files::read_regular_file(path, MAX_SESSION_BYTES).map_err(|e| {
        SessionError::Io {
            path: path.to_path_buf(),
            op: "read",
            source: e.into_io(),
        }
    })?;
    decode(&bytes, path)
}

/// Writes `bytes` to `path` atomically (see [`dynaclay_files::write_atomic`]).
///
/// # Errors
/// [`SessionError::Write`] naming the failing step; the previous file at `path` is untouched
/// and the temporary file is removed.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), SessionError> {
    Ok(dynaclay_files::write_atomic(path, bytes)?)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::BSplineLattice;
    use crate::tools::Clay;
    use glam::Vec3;

    fn session(value: f32) -> Session {
        let mut l = BSplineLattice::zeros([6, 6, 6], 0.1, Vec3::ZERO).unwrap();
        l.coeffs.update_each(|_, c| *c = value);
        Session {
            clay: Clay::single(l),
            ..Session::default()
        }
    }

    #[test]
    fn save_then_load_round_trips() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.dclay");
        save_session(&path, &session(0.25)).unwrap();
        assert_eq!(load_session(&path).unwrap(), session(0.25));
        save_session(&path, &session(0.5)).unwrap();
        assert_eq!(load_session(&path).unwrap(), session(0.5));
        // No temporary files left behind.
        assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn a_write_failure_mid_save_leaves_the_previous_file_intact() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.dclay");
        save_session(&path, &session(0.25)).unwrap();
        let before = fs::read(&path).unwrap();
        let bytes = encode(&session(0.75)).unwrap();
        let err = dynaclay_files::write_atomic_with(&path, |file| {
            // Half the file reaches the disk, then the device fails.
            file.write_all(&bytes[..bytes.len() / 2])?;
            Err(std::io::Error::other("injected: disk full"))
        })
        .unwrap_err();
        assert!(err.to_string().contains("injected: disk full"), "{err}");
        assert_eq!(fs::read(&path).unwrap(), before);
        assert_eq!(load_session(&path).unwrap(), session(0.25));
        assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 1, "temp removed");
    }

    #[test]
    fn a_crash_before_the_rename_leaves_the_previous_file_loadable() {
        // A kill during the write leaves a partial temporary file and the old target.
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.dclay");
        save_session(&path, &session(0.25)).unwrap();
        let bytes = encode(&session(0.75)).unwrap();
        fs::write(
            dir.path().join(".a.dclay.tmp.1.0"),
            &bytes[..bytes.len() / 3],
        )
        .unwrap();
        assert_eq!(load_session(&path).unwrap(), session(0.25));
    }

    #[test]
    fn loading_a_missing_or_corrupt_file_names_it() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("none.dclay");
        let err = load_session(&path).unwrap_err();
        assert!(matches!(err, SessionError::Io { op: "read", .. }));
        assert!(err.to_string().contains("none.dclay"));
        let path = dir.path().join("bad.dclay");
        let mut bytes = encode(&session(0.25)).unwrap();
        let n = bytes.len();
        bytes[n / 2] ^= 0xff;
        fs::write(&path, &bytes).unwrap();
        let err = load_session(&path).unwrap_err();
        assert!(matches!(err, SessionError::Checksum { .. }), "{err}");
    }
}

/// Why a save may not write its path; nothing was written.
#[derive(Debug, thiserror::Error)]
pub enum ReplaceRefused {
    /// What is at the path could not be inspected.
    #[error("{}: cannot inspect before saving: {source}", path.display())]
    Inspect {
        /// The path to save to.
        path: PathBuf,
        /// The inspection's error.
        source: std::io::Error,
    },
    /// A link, device, FIFO or directory is at the path.
    #[error(
        "{}: refusing to replace something that is not a regular file (a link, device, FIFO or directory)",
        path.display()
    )]
    NotRegularFile {
        /// The path to save to.
        path: PathBuf,
    },
    /// A regular file that is not a dynaclay session is at the path.
    #[error("{}: refusing to replace a file that is not a dynaclay session", path.display())]
    NotSession {
        /// The path to save to.
        path: PathBuf,
    },
}

/// Whether a save may write `path`: nothing is there yet, or a regular file that is a dynaclay
/// session (it starts with [`MAGIC`](super::format::MAGIC)). A symlink, a device, a FIFO, a
/// directory or any other file is never replaced.
///
/// # Errors
/// What is there, naming `path`.
pub fn check_replaceable(path: &Path) -> Result<(), ReplaceRefused> {
    use std::io::Read;
    let meta = match fs::symlink_metadata(path) {
        Ok(m) => m,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(source) => {
            return Err(ReplaceRefused::Inspect {
                path: path.to_path_buf(),
                source,
            });
        }
    };
    if !meta.file_type().is_file() {
        return Err(ReplaceRefused::NotRegularFile {
            path: path.to_path_buf(),
        });
    }
    let mut head = [0u8; 8];
    let read = fs::File::open(path).and_then(|mut f| f.read_exact(&mut head));
    if read.is_err() || head != super::format::MAGIC {
        return Err(ReplaceRefused::NotSession {
            path: path.to_path_buf(),
        });
    }
    Ok(())
}

#[cfg(test)]
mod replace_tests {
    use super::*;

    #[test]
    fn only_absent_paths_and_sessions_may_be_replaced() {
        let dir = tempfile::tempdir().unwrap();
        let absent = dir.path().join("new.dclay");
        assert!(check_replaceable(&absent).is_ok());
        save_session(&absent, &Session::default()).unwrap();
        assert!(
            check_replaceable(&absent).is_ok(),
            "a session may be replaced"
        );
        let text = dir.path().join("notes.txt");
        fs::write(&text, "precious").unwrap();
        let err = check_replaceable(&text).unwrap_err();
        assert!(matches!(err, ReplaceRefused::NotSession { .. }), "{err}");
        assert!(err.to_string().contains("not a dynaclay session"), "{err}");
        let link = dir.path().join("link.dclay");
        std::os::unix::fs::symlink(&absent, &link).unwrap();
        assert!(
            check_replaceable(&link)
                .unwrap_err()
                .to_string()
                .contains("not a regular file")
        );
        assert!(check_replaceable(Path::new("/dev/null")).is_err());
        assert!(check_replaceable(dir.path()).is_err());
    }
}
