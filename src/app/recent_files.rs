//! The window's list of recently opened and saved files: newest first, at most
//! [`MAX_RECENT`] entries, kept in the user's settings folder (one path a line in
//! [`RECENT_FILE_NAME`]), and pruned of files that no longer exist each time it is shown.
//!
//! The list is small and written only when it changes (an Open, a Save or a prune), never
//! from a loop thread.

use std::path::{Path, PathBuf};

/// The most files the list keeps; an older one falls off the end.
pub const MAX_RECENT: usize = 10;

/// The longest list file read back, bytes: [`MAX_RECENT`] paths of 4 KiB each and room to
/// spare; a longer file is refused rather than read.
pub const MAX_RECENT_FILE_BYTES: u64 = 64 * 1024;

/// The list's file name in the settings folder.
pub const RECENT_FILE_NAME: &str = "recent-files.txt";

/// Why the recent-files list could not be read or written (the window then keeps the list in
/// memory only and says so in the log).
#[derive(Debug, thiserror::Error)]
pub enum RecentFilesError {
    /// The list file could not be read (too large, not a regular file, unreadable).
    #[error("recent files: cannot read {}: {source}", path.display())]
    Read {
        /// The list file.
        path: PathBuf,
        /// Why.
        source: dynaclay_files::BoundedReadError,
    },
    /// The list file is not UTF-8 text.
    #[error("recent files: {} is not UTF-8 text", path.display())]
    NotText {
        /// The list file.
        path: PathBuf,
    },
    /// The settings folder could not be made.
    #[error("recent files: cannot make the settings folder {}: {source}", dir.display())]
    Folder {
        /// The folder.
        dir: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The list file could not be written.
    #[error("recent files: cannot write {}: {source}", path.display())]
    Write {
        /// The list file.
        path: PathBuf,
        /// Why.
        source: dynaclay_files::WriteError,
    },
}

/// The user's settings folder for dynaclay: `$XDG_CONFIG_HOME/dynaclay`, else
/// `$HOME/.config/dynaclay` (`%APPDATA%\dynaclay` on Windows); `None` when the environment
/// names none (the list is then kept in memory only).
#[must_use]
pub fn settings_dir() -> Option<PathBuf> {
    let non_empty = |name: &str| std::env::var_os(name).filter(|v| !v.is_empty());
    if cfg!(windows) {
        return non_empty("APPDATA").map(|d| PathBuf::from(d).join("dynaclay"));
    }
    non_empty("XDG_CONFIG_HOME")
        .map(PathBuf::from)
        .or_else(|| non_empty("HOME").map(|h| PathBuf::from(h).join(".config")))
        .map(|d| d.join("dynaclay"))
}

/// Recently opened and saved files, newest first.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RecentFiles {
    paths: Vec<PathBuf>,
    /// The list file (`None`: in memory only).
    store: Option<PathBuf>,
}

impl RecentFiles {
    /// An empty list kept in memory only.
    #[must_use]
    pub fn in_memory() -> Self {
        Self::default()
    }

    /// The list kept in `dir`/[`RECENT_FILE_NAME`], read from it if it exists. Blank lines
    /// are skipped and only the first [`MAX_RECENT`] paths are kept.
    ///
    /// # Errors
    /// The file exists but cannot be read, is larger than [`MAX_RECENT_FILE_BYTES`] or is
    /// not UTF-8; the list is then empty but still kept in `dir`.
    pub fn load_from(dir: &Path) -> (Self, Option<RecentFilesError>) {
        let path = dir.join(RECENT_FILE_NAME);
        let mut list = Self {
            paths: Vec::new(),
            store: Some(path.clone()),
        };
        if !path.exists() {
            return (list, None);
        }
        let bytes = match dynaclay_files::read_regular_file(&path, MAX_RECENT_FILE_BYTES) {
            Ok(b) => b,
            Err(source) => return (list, Some(RecentFilesError::Read { path, source })),
        };
        let Ok(text) = String::from_utf8(bytes) else {
            return (list, Some(RecentFilesError::NotText { path }));
        };
        list.paths = text
            .lines()
            .map(str::trim)
            .filter(|l| !l.is_empty())
            .take(MAX_RECENT)
            .map(PathBuf::from)
            .collect();
        (list, None)
    }

    /// The paths, newest first, as last stored (see [`Self::shown`] for the pruned list).
    #[must_use]
    pub fn paths(&self) -> &[PathBuf] {
        &self.paths
    }

    /// Puts `path` first (moving it up if it was listed), drops what falls past
    /// [`MAX_RECENT`], and writes the list.
    ///
    /// # Errors
    /// The list could not be written (it is still updated in memory).
    pub fn add(&mut self, path: &Path) -> Result<(), RecentFilesError> {
        self.paths.retain(|p| p != path);
        self.paths.insert(0, path.to_path_buf());
        self.paths.truncate(MAX_RECENT);
        self.store()
    }

    /// The list with files that no longer exist removed (and the list written if any was):
    /// what the Recent menu shows.
    ///
    /// # Errors
    /// The pruned list could not be written (it is still pruned in memory).
    pub fn shown(&mut self) -> (&[PathBuf], Option<RecentFilesError>) {
        let before = self.paths.len();
        self.paths.retain(|p| p.is_file());
        let error = if self.paths.len() == before {
            None
        } else {
            self.store().err()
        };
        (&self.paths, error)
    }

    fn store(&self) -> Result<(), RecentFilesError> {
        let Some(path) = &self.store else {
            return Ok(());
        };
        if let Some(dir) = path.parent() {
            std::fs::create_dir_all(dir).map_err(|source| RecentFilesError::Folder {
                dir: dir.to_path_buf(),
                source,
            })?;
        }
        let mut text = String::new();
        for p in &self.paths {
            // A path with a line break cannot be listed one a line; it is left out.
            let s = p.to_string_lossy();
            if !s.contains(['\n', '\r']) {
                text.push_str(&s);
                text.push('\n');
            }
        }
        dynaclay_files::write_atomic(path, text.as_bytes()).map_err(|source| {
            RecentFilesError::Write {
                path: path.clone(),
                source,
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_list_is_bounded_newest_first_and_survives_a_restart() {
        let dir = tempfile::tempdir().unwrap();
        let (mut list, error) = RecentFiles::load_from(dir.path());
        assert!(error.is_none());
        let files: Vec<PathBuf> = (0..MAX_RECENT + 3)
            .map(|i| dir.path().join(format!("s{i}.dclay")))
            .collect();
        for f in &files {
            std::fs::write(f, b"x").unwrap();
            list.add(f).unwrap();
        }
        assert_eq!(list.paths().len(), MAX_RECENT);
        assert_eq!(list.paths()[0], files[MAX_RECENT + 2], "newest first");
        assert!(!list.paths().contains(&files[0]), "the oldest fell off");
        // Opening a listed file again moves it to the top without a duplicate.
        list.add(&files[5]).unwrap();
        assert_eq!(list.paths()[0], files[5]);
        assert_eq!(list.paths().iter().filter(|p| **p == files[5]).count(), 1);
        assert_eq!(list.paths().len(), MAX_RECENT);

        let (again, error) = RecentFiles::load_from(dir.path());
        assert!(error.is_none());
        assert_eq!(again.paths(), list.paths(), "read back as written");
    }

    #[test]
    fn files_gone_are_pruned_when_the_list_is_shown_and_the_file_rewritten() {
        let dir = tempfile::tempdir().unwrap();
        let (mut list, _) = RecentFiles::load_from(dir.path());
        let kept = dir.path().join("kept.dclay");
        let gone = dir.path().join("gone.dclay");
        std::fs::write(&kept, b"x").unwrap();
        std::fs::write(&gone, b"x").unwrap();
        list.add(&kept).unwrap();
        list.add(&gone).unwrap();
        std::fs::remove_file(&gone).unwrap();
        let (shown, error) = list.shown();
        assert!(error.is_none());
        assert_eq!(shown, std::slice::from_ref(&kept));
        let (again, _) = RecentFiles::load_from(dir.path());
        assert_eq!(again.paths(), [kept]);
    }

    #[test]
    fn an_oversized_list_file_is_refused_with_its_path() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(RECENT_FILE_NAME);
        std::fs::write(&path, vec![b'a'; MAX_RECENT_FILE_BYTES as usize + 1]).unwrap();
        let (list, error) = RecentFiles::load_from(dir.path());
        assert!(list.paths().is_empty());
        let message = error.unwrap().to_string();
        assert!(message.contains(RECENT_FILE_NAME), "{message}");
    }
}
