//! Choosing a file for Open, Save As, Import and Export: the desktop's own file dialog (`rfd`;
//! on Linux the XDG desktop portal over D-Bus, or zenity where no portal answers), or, where
//! there is no dialog to show (no D-Bus session and no zenity, a headless run, or
//! `DYNACLAY_FILE_DIALOG=typed`), a path typed into the window.
//!
//! A native dialog runs on a thread of its own and its answer comes back over a channel that
//! the window polls once a frame, so the window never waits for the user to pick.

use std::path::{Path, PathBuf};

use crossbeam::channel::{Receiver, TryRecvError, bounded};

/// The environment variable that forces the typed-path fallback (`typed`) or the native
/// dialog (`native`); anything else, or unset, detects.
pub const DIALOG_ENV: &str = "DYNACLAY_FILE_DIALOG";

/// What the chosen file is for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum FilePurpose {
    /// A session to open (`.dclay`).
    Open,
    /// Where to save the session under a new name.
    SaveAs,
    /// A point cloud, mesh or volume to fit into a new clay.
    Import,
    /// Where to write the surface mesh.
    Export,
}

impl FilePurpose {
    /// The dialog's title.
    #[must_use]
    pub fn title(self) -> &'static str {
        match self {
            Self::Open => "Open session",
            Self::SaveAs => "Save session as",
            Self::Import => "Import point cloud, mesh or volume",
            Self::Export => "Export mesh",
        }
    }

    /// Whether the dialog names a file to write (a save dialog) rather than one to read.
    #[must_use]
    pub fn writes(self) -> bool {
        matches!(self, Self::SaveAs | Self::Export)
    }

    /// The dialog's filters: a name and the extensions it shows.
    #[must_use]
    pub fn filters(self) -> &'static [(&'static str, &'static [&'static str])] {
        match self {
            Self::Open | Self::SaveAs => &[("dynaclay session", &["dclay"])],
            Self::Import => &[
                ("point cloud", &["ply", "xyz", "txt", "pts"]),
                ("mesh", &["obj", "stl"]),
                ("volume", &["nrrd", "raw"]),
            ],
            Self::Export => &[("mesh", &["obj", "ply", "stl"])],
        }
    }

    /// The typed path's hint: the extensions this purpose takes.
    #[must_use]
    pub fn hint(self) -> &'static str {
        match self {
            Self::Open | Self::SaveAs => "a .dclay session",
            Self::Import => {
                "a .ply, .xyz, .txt or .pts cloud, an .obj or .stl mesh, a .nrrd volume"
            }
            Self::Export => "an .obj, .ply or .stl mesh",
        }
    }
}

/// How files are chosen in this window.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum DialogBackend {
    /// The desktop's file dialog.
    Native,
    /// A path typed in the window; `why` says why there is no dialog.
    Typed {
        /// Why no native dialog is used, for the message beside the text box.
        why: String,
    },
}

impl DialogBackend {
    /// The typed-path fallback, for `why`.
    #[must_use]
    pub fn typed(why: impl Into<String>) -> Self {
        Self::Typed { why: why.into() }
    }

    /// Detects whether a native dialog can be shown here: [`DIALOG_ENV`] decides when set;
    /// otherwise on Linux and the BSDs a D-Bus session bus (for the portal) or a `zenity` on
    /// the `PATH` is needed; on macOS and Windows the system's dialog is always there.
    #[must_use]
    pub fn detect() -> Self {
        match std::env::var(DIALOG_ENV).as_deref() {
            Ok("typed") => return Self::typed(format!("{DIALOG_ENV}=typed")),
            Ok("native") => return Self::Native,
            _ => {}
        }
        if cfg!(any(target_os = "macos", target_os = "windows")) {
            return Self::Native;
        }
        let bus = std::env::var_os("DBUS_SESSION_BUS_ADDRESS").is_some_and(|a| !a.is_empty())
            || std::env::var_os("XDG_RUNTIME_DIR")
                .is_some_and(|d| Path::new(&d).join("bus").exists());
        let zenity = std::env::var_os("PATH")
            .is_some_and(|p| std::env::split_paths(&p).any(|d| d.join("zenity").is_file()));
        if bus || zenity {
            Self::Native
        } else {
            Self::typed("no desktop file dialog here (no D-Bus session for a portal, no zenity)")
        }
    }
}

/// A native dialog open on its own thread.
pub struct NativePick {
    answer: Receiver<Option<PathBuf>>,
}

/// What a native dialog said so far.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum PickState {
    /// Still open.
    Open,
    /// The user chose this file.
    Chosen(PathBuf),
    /// The user cancelled, or the dialog could not be shown.
    Cancelled,
}

impl NativePick {
    /// Shows the desktop's dialog for `purpose` on a new thread, starting in `folder` and
    /// suggesting `file_name` for a save.
    ///
    /// # Errors
    /// The thread could not be started.
    pub fn start(
        purpose: FilePurpose,
        folder: Option<&Path>,
        file_name: Option<&str>,
    ) -> std::io::Result<Self> {
        let mut dialog = rfd::FileDialog::new().set_title(purpose.title());
        for (name, extensions) in purpose.filters() {
            dialog = dialog.add_filter(*name, extensions);
        }
        if let Some(folder) = folder {
            dialog = dialog.set_directory(folder);
        }
        if let Some(name) = file_name {
            dialog = dialog.set_file_name(name);
        }
        let (tx, answer) = bounded(1);
        std::thread::Builder::new()
            .name("dynaclay-file-dialog".into())
            .spawn(move || {
                let chosen = if purpose.writes() {
                    dialog.save_file()
                } else {
                    dialog.pick_file()
                };
                let _ = tx.send(chosen);
            })?;
        Ok(Self { answer })
    }

    /// What the dialog said, without waiting.
    #[must_use]
    pub fn poll(&self) -> PickState {
        match self.answer.try_recv() {
            Ok(Some(path)) => PickState::Chosen(path),
            Ok(None) | Err(TryRecvError::Disconnected) => PickState::Cancelled,
            Err(TryRecvError::Empty) => PickState::Open,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_purpose_filters_the_extensions_its_reader_or_writer_takes() {
        let import: Vec<&str> = FilePurpose::Import
            .filters()
            .iter()
            .flat_map(|(_, e)| e.iter().copied())
            .collect();
        let mut readable = crate::fit::IMPORT_EXTENSIONS.to_vec();
        readable.sort_unstable();
        let mut offered = import.clone();
        offered.sort_unstable();
        assert_eq!(offered, readable, "the import crate's extensions, no more");
        for (_, extensions) in FilePurpose::Export.filters() {
            for ext in *extensions {
                let path = PathBuf::from(format!("a.{ext}"));
                assert!(crate::mesh::MeshFormat::from_path(&path).is_some(), "{ext}");
            }
        }
        assert!(FilePurpose::SaveAs.writes() && FilePurpose::Export.writes());
        assert!(!FilePurpose::Open.writes() && !FilePurpose::Import.writes());
    }
}
