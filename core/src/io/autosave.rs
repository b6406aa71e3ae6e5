//! Autosave to a recovery file every N seconds or N strokes, and detection of a recovery file
//! left by a crash, to offer at the next start. The engine calls [`Autosave::note_stroke`]
//! after each committed step and [`Autosave::save_if_due`] between simulation steps (saving
//! encodes and writes the session: never on the haptic path).

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant, SystemTime};

use super::atomic::save_session;
use super::error::SessionError;
use super::session::Session;

/// When to autosave: whichever of the two limits is reached first (0 disables a limit).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AutosavePolicy {
    pub every_s: f32,
    pub every_strokes: u32,
}

impl Default for AutosavePolicy {
    fn default() -> Self {
        Self {
            every_s: 60.0,
            every_strokes: 20,
        }
    }
}

/// The recovery file's path for a session saved at `session_path`: `<name>.recovery`.
#[must_use]
pub fn recovery_path_for(session_path: &Path) -> PathBuf {
    let mut name = session_path
        .file_name()
        .map_or_else(|| "untitled.dclay".into(), |n| n.to_os_string());
    name.push(".recovery");
    session_path.with_file_name(name)
}

/// A recovery file found at start-up.
#[derive(Clone, Debug, PartialEq)]
pub struct Recovery {
    pub path: PathBuf,
    pub modified: SystemTime,
}

/// The recovery file for `session_path`, if one exists and is newer than the session file
/// (or the session file is missing): the work it holds was never saved.
#[must_use]
pub fn find_recovery(session_path: &Path) -> Option<Recovery> {
    let path = recovery_path_for(session_path);
    let modified = std::fs::metadata(&path).ok()?.modified().ok()?;
    let session_modified = std::fs::metadata(session_path).and_then(|m| m.modified());
    match session_modified {
        Ok(saved) if saved >= modified => None,
        _ => Some(Recovery { path, modified }),
    }
}

/// Why a start-up may not go on as asked about a recovery file.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum RecoveryRefused {
    /// A recovery file newer than the session exists and `--recover` was not given.
    #[error(
        "recovery file {} is newer than session {}{}; pass --recover to start from it \
         (or remove it to start afresh)",
        recovery.display(),
        session.display(),
        if *never_saved { " (never saved)" } else { "" }
    )]
    Unseen {
        /// The recovery file.
        recovery: PathBuf,
        /// The session it belongs to.
        session: PathBuf,
        /// Whether the session file does not exist.
        never_saved: bool,
    },
    /// `--recover` was given and there is no recovery file newer than the session.
    #[error(
        "--recover: no recovery file newer than {} (looked for {})",
        session.display(),
        looked_for.display()
    )]
    NoneToRecover {
        /// The session.
        session: PathBuf,
        /// Where the recovery file would be.
        looked_for: PathBuf,
    },
}

/// What a start-up does about the recovery file of `session_path`. With `recover`, the recovery
/// file to start from; without, `None`.
///
/// # Errors
/// A recovery file newer than the session exists and `recover` was not given (so unsaved work
/// is never overwritten unseen), or `recover` was given and there is none.
pub fn recovery_to_use(
    session_path: &Path,
    recover: bool,
) -> Result<Option<Recovery>, RecoveryRefused> {
    match (find_recovery(session_path), recover) {
        (Some(r), true) => Ok(Some(r)),
        (Some(r), false) => Err(RecoveryRefused::Unseen {
            recovery: r.path,
            session: session_path.to_path_buf(),
            never_saved: !session_path.exists(),
        }),
        (None, true) => Err(RecoveryRefused::NoneToRecover {
            session: session_path.to_path_buf(),
            looked_for: recovery_path_for(session_path),
        }),
        (None, false) => Ok(None),
    }
}

/// Autosave state: the recovery path, the policy and the counters since the last save.
#[derive(Debug)]
pub struct Autosave {
    pub recovery_path: PathBuf,
    pub policy: AutosavePolicy,
    last_save: Instant,
    strokes: u32,
}

impl Autosave {
    /// Autosave for the session at `session_path`, counting from `now`.
    #[must_use]
    pub fn new(session_path: &Path, policy: AutosavePolicy, now: Instant) -> Self {
        Self {
            recovery_path: recovery_path_for(session_path),
            policy,
            last_save: now,
            strokes: 0,
        }
    }

    /// Autosaves beside the session now at `session_path` (after it was saved under a new
    /// name), so the recovery file always belongs to the session being worked on; the count
    /// and the clock carry on.
    pub fn follow(&mut self, session_path: &Path) {
        self.recovery_path = recovery_path_for(session_path);
    }

    /// Counts a committed stroke or tool action.
    pub fn note_stroke(&mut self) {
        self.strokes = self.strokes.saturating_add(1);
    }

    /// Whether a save is due at `now` (only when something changed since the last one).
    #[must_use]
    pub fn is_due(&self, now: Instant) -> bool {
        if self.strokes == 0 {
            return false;
        }
        let by_strokes = self.policy.every_strokes > 0 && self.strokes >= self.policy.every_strokes;
        let by_time = self.policy.every_s > 0.0
            && now.saturating_duration_since(self.last_save)
                >= Duration::from_secs_f32(self.policy.every_s);
        by_strokes || by_time
    }

    /// Writes the recovery file if due; returns whether it did.
    ///
    /// # Errors
    /// As [`save_session`]; the counters are kept so the next call retries.
    pub fn save_if_due(&mut self, session: &Session, now: Instant) -> Result<bool, SessionError> {
        if !self.is_due(now) {
            return Ok(false);
        }
        save_session(&self.recovery_path, session)?;
        self.last_save = now;
        self.strokes = 0;
        Ok(true)
    }

    /// Removes the recovery file after a normal save (a missing file is fine).
    ///
    /// # Errors
    /// [`SessionError::Io`] when it exists but cannot be removed.
    pub fn discard(&mut self, now: Instant) -> Result<(), SessionError> {
        self.last_save = now;
        self.strokes = 0;
        match std::fs::remove_file(&self.recovery_path) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(SessionError::Io {
                path: self.recovery_path.clone(),
                op: "remove recovery file",
                source: e,
            }),
            _ => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::load_session;

    #[test]
    fn a_start_uses_a_recovery_file_only_when_asked_and_never_ignores_one() {
        let dir = tempfile::tempdir().unwrap();
        let session_path = dir.path().join("bust.dclay");
        assert_eq!(recovery_to_use(&session_path, false), Ok(None));
        let e = recovery_to_use(&session_path, true).unwrap_err();
        assert!(matches!(e, RecoveryRefused::NoneToRecover { .. }));
        assert!(e.to_string().contains("no recovery file newer than"), "{e}");

        std::fs::write(recovery_path_for(&session_path), b"unsaved work").unwrap();
        let e = recovery_to_use(&session_path, false)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("pass --recover") && e.contains("never saved"),
            "{e}"
        );
        let found = recovery_to_use(&session_path, true).unwrap().unwrap();
        assert_eq!(found.path, recovery_path_for(&session_path));

        // A session saved after the recovery file holds that work: nothing to offer.
        std::thread::sleep(Duration::from_millis(20));
        std::fs::write(&session_path, b"saved").unwrap();
        assert_eq!(recovery_to_use(&session_path, false), Ok(None));
    }

    #[test]
    fn saves_after_n_strokes_or_n_seconds_and_is_offered_at_start() {
        let dir = tempfile::tempdir().unwrap();
        let session_path = dir.path().join("pot.dclay");
        let t0 = Instant::now();
        let mut auto = Autosave::new(
            &session_path,
            AutosavePolicy {
                every_s: 30.0,
                every_strokes: 3,
            },
            t0,
        );
        let s = Session::default();
        assert!(
            !auto.save_if_due(&s, t0 + Duration::from_secs(100)).unwrap(),
            "nothing changed"
        );
        auto.note_stroke();
        auto.note_stroke();
        assert!(!auto.save_if_due(&s, t0).unwrap());
        auto.note_stroke();
        assert!(auto.save_if_due(&s, t0).unwrap());
        auto.note_stroke();
        assert!(!auto.is_due(t0 + Duration::from_secs(29)));
        assert!(auto.is_due(t0 + Duration::from_secs(31)));

        // No session file yet: the recovery file is offered and loads.
        let found = find_recovery(&session_path).unwrap();
        assert_eq!(found.path, dir.path().join("pot.dclay.recovery"));
        assert_eq!(load_session(&found.path).unwrap(), s);
        auto.discard(t0).unwrap();
        assert!(find_recovery(&session_path).is_none());
    }
}
