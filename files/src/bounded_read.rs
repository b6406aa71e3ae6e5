//! Reading an input file with a size cap: only regular files are read (a FIFO would block and
//! a device such as `/dev/zero` never ends), and a file longer than the cap is refused before
//! any of it is read into memory.

use std::fs::File;
use std::io::{self, Read};
use std::path::Path;

/// Why a file was not read.
#[derive(Debug, thiserror::Error)]
pub enum BoundedReadError {
    /// The path is not a regular file (a FIFO, a device, a directory, a socket).
    #[error("not a regular file ({kind}); only regular files are read")]
    NotRegular {
        /// What the path is instead.
        kind: &'static str,
    },
    /// The file holds more bytes than the reader accepts.
    #[error("the file is {len} bytes, more than the {cap} bytes accepted")]
    TooLarge {
        /// The file's length (or the bytes seen before stopping), bytes.
        len: u64,
        /// The cap, bytes.
        cap: u64,
    },
    /// The operating system refused.
    #[error("{0}")]
    Io(#[from] io::Error),
}

impl BoundedReadError {
    /// The underlying I/O error kind, for callers that keep `io::Error`s.
    #[must_use]
    pub fn into_io(self) -> io::Error {
        match self {
            Self::Io(e) => e,
            other => io::Error::new(io::ErrorKind::InvalidInput, other.to_string()),
        }
    }
}

pub(crate) fn kind_of(meta: &std::fs::Metadata) -> &'static str {
    use std::os::unix::fs::FileTypeExt;
    let t = meta.file_type();
    if t.is_dir() {
        "a directory"
    } else if t.is_fifo() {
        "a FIFO"
    } else if t.is_char_device() {
        "a character device"
    } else if t.is_block_device() {
        "a block device"
    } else if t.is_socket() {
        "a socket"
    } else {
        "not a plain file"
    }
}

/// Reads the whole of the regular file at `path`, at most `cap_bytes` bytes.
///
/// The file type is checked before opening (so a FIFO is never opened, which would block) and
/// again on the open file; the length is checked before reading, and the read itself stops
/// one byte past the cap in case the file grew meanwhile.
///
/// # Errors
/// [`BoundedReadError`] saying why.
pub fn read_regular_file(path: &Path, cap_bytes: u64) -> Result<Vec<u8>, BoundedReadError> {
    let meta = std::fs::metadata(path)?;
    if !meta.is_file() {
        return Err(BoundedReadError::NotRegular {
            kind: kind_of(&meta),
        });
    }
    let file = File::open(path)?;
    let meta = file.metadata()?;
    if !meta.is_file() {
        return Err(BoundedReadError::NotRegular {
            kind: kind_of(&meta),
        });
    }
    if meta.len() > cap_bytes {
        return Err(BoundedReadError::TooLarge {
            len: meta.len(),
            cap: cap_bytes,
        });
    }
    // The length is bounded by the cap, so this reserve is bounded too.
    let mut bytes = Vec::with_capacity(usize::try_from(meta.len()).unwrap_or(0));
    file.take(cap_bytes + 1).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > cap_bytes {
        return Err(BoundedReadError::TooLarge {
            len: bytes.len() as u64,
            cap: cap_bytes,
        });
    }
    Ok(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn devices_directories_and_fifos_are_refused_without_reading() {
        for path in ["/dev/zero", "/dev/null", "/tmp"] {
            let err = read_regular_file(Path::new(path), 1 << 20).unwrap_err();
            assert!(
                matches!(err, BoundedReadError::NotRegular { .. }),
                "{path}: {err}"
            );
        }
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("fifo");
        let made = std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap();
        assert!(made.success());
        // Opening a FIFO with no writer would block forever; it is refused before opening.
        let err = read_regular_file(&fifo, 1 << 20).unwrap_err();
        assert!(err.to_string().contains("FIFO"), "{err}");
    }

    #[test]
    fn a_file_over_the_cap_is_refused_and_one_at_the_cap_is_read() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("f");
        std::fs::write(&path, vec![7u8; 100]).unwrap();
        assert_eq!(read_regular_file(&path, 100).unwrap().len(), 100);
        let err = read_regular_file(&path, 99).unwrap_err();
        assert!(
            matches!(err, BoundedReadError::TooLarge { len: 100, cap: 99 }),
            "{err}"
        );
    }
}
