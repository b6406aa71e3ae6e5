//! Atomic outputs: a temporary file beside the target, flushed, fsynced and renamed over it.

use std::fs::{self, File, OpenOptions};
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// Why an output file was not written. In every case the file that was at the path before is
/// untouched and no temporary file is left behind.
#[derive(Debug, thiserror::Error)]
pub enum WriteError {
    /// Something other than a regular file is at the path (a symbolic link, a directory, a
    /// device, a FIFO or a socket); it is never written through or replaced.
    #[error(
        "{}: refusing to write over {what}; only a regular file is replaced",
        path.display()
    )]
    NotRegular {
        /// The target.
        path: PathBuf,
        /// What is there instead ("a symbolic link", "a character device", ...).
        what: &'static str,
    },
    /// The operating system refused a step.
    #[error("{}: cannot {op}: {source}", path.display())]
    Io {
        /// The target (the step may have been on the temporary file beside it).
        path: PathBuf,
        /// The step: "create a temporary file beside it", "write", "fsync", "rename over", ...
        op: &'static str,
        /// The operating system's error.
        #[source]
        source: io::Error,
    },
}

impl WriteError {
    /// The path the error is about.
    #[must_use]
    pub fn path(&self) -> &Path {
        match self {
            Self::NotRegular { path, .. } | Self::Io { path, .. } => path,
        }
    }

    /// The I/O error kind (`InvalidInput` for a refused target).
    #[must_use]
    pub fn kind(&self) -> io::ErrorKind {
        match self {
            Self::NotRegular { .. } => io::ErrorKind::InvalidInput,
            Self::Io { source, .. } => source.kind(),
        }
    }

    /// The operating system's error code, when there is one.
    #[must_use]
    pub fn raw_os_error(&self) -> Option<i32> {
        match self {
            Self::NotRegular { .. } => None,
            Self::Io { source, .. } => source.raw_os_error(),
        }
    }

    /// This error as an [`io::Error`] of the same kind, its message kept.
    #[must_use]
    pub fn into_io(self) -> io::Error {
        io::Error::new(self.kind(), self.to_string())
    }
}

/// Whether an output may be written at `path`: nothing is there yet, or a regular file is.
///
/// # Errors
/// [`WriteError::NotRegular`] for a link, directory, device, FIFO or socket;
/// [`WriteError::Io`] when the path cannot be inspected (its folder is missing or is a file).
pub fn check_target(path: &Path) -> Result<(), WriteError> {
    match fs::symlink_metadata(path) {
        Ok(meta) if meta.file_type().is_file() => Ok(()),
        Ok(meta) => Err(WriteError::NotRegular {
            path: path.to_path_buf(),
            what: if meta.file_type().is_symlink() {
                "a symbolic link"
            } else {
                crate::bounded_read::kind_of(&meta)
            },
        }),
        Err(e) if e.kind() == io::ErrorKind::NotFound => {
            // The folder must exist for the temporary file; say so now rather than at create.
            let dir = parent_dir(path);
            match fs::metadata(&dir) {
                Ok(m) if m.is_dir() => Ok(()),
                Ok(_) => Err(WriteError::Io {
                    path: path.to_path_buf(),
                    op: "write into its folder",
                    source: io::Error::new(
                        io::ErrorKind::NotADirectory,
                        format!("{} is not a directory", dir.display()),
                    ),
                }),
                Err(source) => Err(WriteError::Io {
                    path: path.to_path_buf(),
                    op: "write into its folder",
                    source,
                }),
            }
        }
        Err(source) => Err(WriteError::Io {
            path: path.to_path_buf(),
            op: "inspect it before writing",
            source,
        }),
    }
}

/// Writes `bytes` to `path` atomically.
///
/// # Errors
/// As [`AtomicFile::create`] and [`AtomicFile::commit`]; the previous file is untouched.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), WriteError> {
    write_atomic_with(path, |out| out.write_all(bytes))
}

/// Writes what `fill` produces to `path` atomically. An error from `fill` is reported as a
/// failed write of the temporary file.
///
/// # Errors
/// As [`write_atomic`].
pub fn write_atomic_with(
    path: &Path,
    fill: impl FnOnce(&mut dyn Write) -> io::Result<()>,
) -> Result<(), WriteError> {
    let mut file = AtomicFile::create(path)?;
    if let Err(source) = fill(&mut file) {
        return Err(WriteError::Io {
            path: file.target.clone(),
            op: "write",
            source,
        });
    }
    file.commit()
}

/// A streaming output that appears at its path only when [`AtomicFile::commit`] succeeds:
/// until then the bytes go to a buffered temporary file beside it, which is removed if the
/// value is dropped uncommitted.
#[derive(Debug)]
pub struct AtomicFile {
    target: PathBuf,
    temp: PathBuf,
    out: Option<BufWriter<File>>,
}

impl AtomicFile {
    /// Checks the target (see [`check_target`]) and creates the temporary file beside it.
    ///
    /// # Errors
    /// [`WriteError::NotRegular`] when the target is not a regular file; [`WriteError::Io`]
    /// when its folder is missing or refuses a new file.
    pub fn create(path: &Path) -> Result<Self, WriteError> {
        if path.file_name().is_none() {
            return Err(WriteError::Io {
                path: path.to_path_buf(),
                op: "name the file",
                source: io::Error::new(io::ErrorKind::InvalidInput, "the path has no file name"),
            });
        }
        check_target(path)?;
        let temp = temp_path(path);
        let file = OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&temp)
            .map_err(|source| WriteError::Io {
                path: path.to_path_buf(),
                op: "create a temporary file beside it",
                source,
            })?;
        Ok(Self {
            target: path.to_path_buf(),
            temp,
            out: Some(BufWriter::with_capacity(1 << 16, file)),
        })
    }

    /// The path the file will have once committed.
    #[must_use]
    pub fn target(&self) -> &Path {
        &self.target
    }

    /// The temporary file's path.
    #[must_use]
    pub fn temp_path(&self) -> &Path {
        &self.temp
    }

    /// Flushes and fsyncs the temporary file, checks the target once more and renames the
    /// temporary file over it, then fsyncs the folder (best effort: the file is complete and
    /// in place either way).
    ///
    /// # Errors
    /// [`WriteError`] naming the failing step; the temporary file is removed and the target
    /// is untouched.
    pub fn commit(mut self) -> Result<(), WriteError> {
        let Some(out) = self.out.take() else {
            return Ok(());
        };
        let temp_err = |op, source| WriteError::Io {
            path: self.target.clone(),
            op,
            source,
        };
        let file = out
            .into_inner()
            .map_err(|e| temp_err("write", e.into_error()))?;
        file.sync_all().map_err(|e| temp_err("fsync", e))?;
        drop(file);
        // Something may have been placed at the target while the file was being written.
        check_target(&self.target)?;
        fs::rename(&self.temp, &self.target).map_err(|source| WriteError::Io {
            path: self.target.clone(),
            op: "rename the temporary file over it",
            source,
        })?;
        // Renamed: nothing left for `drop` to remove.
        self.temp = PathBuf::new();
        if let Ok(d) = File::open(parent_dir(&self.target)) {
            let _ = d.sync_all();
        }
        Ok(())
    }
}

impl Write for AtomicFile {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        match &mut self.out {
            Some(out) => out.write(buf),
            None => Err(io::Error::other("the file is already committed")),
        }
    }

    fn write_all(&mut self, buf: &[u8]) -> io::Result<()> {
        match &mut self.out {
            Some(out) => out.write_all(buf),
            None => Err(io::Error::other("the file is already committed")),
        }
    }

    fn flush(&mut self) -> io::Result<()> {
        self.out.as_mut().map_or(Ok(()), BufWriter::flush)
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        // Uncommitted (or a failed commit): the target keeps its previous file.
        drop(self.out.take());
        if !self.temp.as_os_str().is_empty() {
            let _ = fs::remove_file(&self.temp);
        }
    }
}

fn parent_dir(path: &Path) -> PathBuf {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// A fresh temporary name beside `path`: `.<name>.tmp.<pid>.<n>`.
fn temp_path(path: &Path) -> PathBuf {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    // NOTE: Relaxed: the counter only has to be unique, not ordered with anything.
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let name = path
        .file_name()
        .map_or_else(|| "out".into(), |n| n.to_string_lossy().into_owned());
    path.with_file_name(format!(".{name}.tmp.{}.{n}", std::process::id()))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn writes_replace_a_regular_file_and_leave_no_temporary() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.txt");
        write_atomic(&path, b"one").unwrap();
        write_atomic(&path, b"two").unwrap();
        assert_eq!(fs::read(&path).unwrap(), b"two");
        assert_eq!(names(dir.path()), ["a.txt"]);
    }

    #[test]
    fn a_failed_write_keeps_the_previous_file_and_names_the_step() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.txt");
        write_atomic(&path, b"previous").unwrap();
        let err = write_atomic_with(&path, |out| {
            out.write_all(b"half")?;
            Err(io::Error::new(
                io::ErrorKind::StorageFull,
                "injected: disk full",
            ))
        })
        .unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::StorageFull);
        assert!(err.to_string().contains("cannot write"), "{err}");
        assert_eq!(fs::read(&path).unwrap(), b"previous");
        assert_eq!(names(dir.path()), ["a.txt"]);
    }

    #[test]
    fn a_streaming_file_appears_only_when_committed() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("rec.bin");
        write_atomic(&path, b"old recording").unwrap();
        let mut f = AtomicFile::create(&path).unwrap();
        f.write_all(&[7; 100_000]).unwrap();
        assert_eq!(fs::read(&path).unwrap(), b"old recording");
        drop(f);
        assert_eq!(fs::read(&path).unwrap(), b"old recording");
        assert_eq!(names(dir.path()), ["rec.bin"], "temporary removed on drop");
        let mut f = AtomicFile::create(&path).unwrap();
        f.write_all(&[7; 100_000]).unwrap();
        f.commit().unwrap();
        assert_eq!(fs::read(&path).unwrap().len(), 100_000);
    }

    #[test]
    fn links_devices_fifos_and_folders_are_never_written_or_replaced() {
        let dir = tempfile::tempdir().unwrap();
        let victim = dir.path().join("victim");
        fs::write(&victim, b"keep").unwrap();
        let link = dir.path().join("link");
        std::os::unix::fs::symlink(&victim, &link).unwrap();
        let err = write_atomic(&link, b"x").unwrap_err();
        assert!(err.to_string().contains("symbolic link"), "{err}");
        assert!(
            fs::symlink_metadata(&link)
                .unwrap()
                .file_type()
                .is_symlink()
        );
        assert_eq!(fs::read(&victim).unwrap(), b"keep");
        for p in ["/dev/full", "/dev/null"] {
            let err = write_atomic(Path::new(p), b"x").unwrap_err();
            assert!(matches!(err, WriteError::NotRegular { .. }), "{p}: {err}");
            assert!(err.to_string().contains("character device"), "{err}");
        }
        let sub = dir.path().join("sub");
        fs::create_dir(&sub).unwrap();
        assert!(matches!(
            write_atomic(&sub, b"x").unwrap_err(),
            WriteError::NotRegular { .. }
        ));
        assert_eq!(names(dir.path()), ["link", "sub", "victim"]);
    }

    #[test]
    fn a_parent_that_is_a_file_or_missing_is_an_error_naming_the_path() {
        let dir = tempfile::tempdir().unwrap();
        let blocker = dir.path().join("blocker");
        fs::write(&blocker, b"keep").unwrap();
        let err = write_atomic(&blocker.join("out.obj"), b"x").unwrap_err();
        assert!(err.to_string().contains("blocker"), "{err}");
        assert!(
            err.to_string().to_lowercase().contains("not a directory"),
            "{err}"
        );
        let err = write_atomic(&dir.path().join("none").join("out.obj"), b"x").unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::NotFound, "{err}");
        assert_eq!(fs::read(&blocker).unwrap(), b"keep");
    }

    #[test]
    fn a_link_placed_while_writing_is_not_replaced() {
        let dir = tempfile::tempdir().unwrap();
        let victim = dir.path().join("victim");
        fs::write(&victim, b"keep").unwrap();
        let path = dir.path().join("out");
        let mut f = AtomicFile::create(&path).unwrap();
        f.write_all(b"new").unwrap();
        std::os::unix::fs::symlink(&victim, &path).unwrap();
        assert!(f.commit().is_err());
        assert_eq!(fs::read(&victim).unwrap(), b"keep");
        assert_eq!(names(dir.path()), ["out", "victim"]);
    }
}
