//! The window's files, as a desktop app has them: New, Open, Save, Save As, Import, Export and
//! the recent files, in the top bar. Each file is chosen in the desktop's dialog, or typed
//! where there is none ([`super::file_dialog`]); New opens a dialog of its own
//! ([`super::new_clay`]). What the user chose comes back as a [`FileRequest`] for the app to
//! carry out; nothing here talks to the engine.

use std::path::{Path, PathBuf};

use super::file_dialog::{DialogBackend, FilePurpose, NativePick, PickState};
use super::new_clay::NewClay;
use super::recent_files::RecentFiles;

/// What the user asked of the File controls.
#[derive(Clone, Debug, PartialEq)]
pub enum FileRequest {
    /// Replace the clay with a new one.
    New(NewClay),
    /// Open this session.
    Open(PathBuf),
    /// Save the session under its current name.
    Save,
    /// Save the session under this name (it becomes the current one).
    SaveAs(PathBuf),
    /// Fit this point cloud, mesh or volume into a new clay.
    Import(PathBuf),
    /// Write the surface mesh here.
    Export(PathBuf),
}

impl FileRequest {
    fn for_purpose(purpose: FilePurpose, path: PathBuf) -> Self {
        match purpose {
            FilePurpose::Open => Self::Open(path),
            FilePurpose::SaveAs => Self::SaveAs(path),
            FilePurpose::Import => Self::Import(path),
            FilePurpose::Export => Self::Export(path),
        }
    }
}

/// A file being chosen.
enum Picking {
    /// In the desktop's dialog.
    Native {
        purpose: FilePurpose,
        pick: NativePick,
    },
    /// In the window's typed-path box.
    Typed {
        purpose: FilePurpose,
        text: String,
        /// Not yet shown (its box takes the keyboard focus when it shows).
        fresh: bool,
    },
}

/// The File controls' state.
pub struct FileMenu {
    /// How files are chosen (`run_gui` detects it; the typed box otherwise).
    pub backend: DialogBackend,
    /// The recent files (in memory only unless `run_gui` gives it the settings folder).
    pub recent: RecentFiles,
    picking: Option<Picking>,
    /// The New dialog's choices while it is open.
    new_clay: Option<NewClay>,
    /// The New dialog's last choices, offered again next time.
    last_new: NewClay,
}

impl Default for FileMenu {
    fn default() -> Self {
        Self {
            backend: DialogBackend::typed("the desktop's file dialog is used only in the window"),
            recent: RecentFiles::in_memory(),
            picking: None,
            new_clay: None,
            last_new: NewClay::default(),
        }
    }
}

impl FileMenu {
    /// Whether a native dialog is open (the window polls for its answer).
    #[must_use]
    pub fn dialog_open(&self) -> bool {
        matches!(self.picking, Some(Picking::Native { .. }))
    }

    /// Opens the New dialog with the last choices.
    pub fn open_new_dialog(&mut self) {
        self.new_clay = Some(self.last_new);
    }

    /// The New dialog's choices while it is open (`None` when closed).
    pub fn new_dialog_mut(&mut self) -> Option<&mut NewClay> {
        self.new_clay.as_mut()
    }

    /// Whether a file is being chosen (in a dialog or the typed box).
    #[must_use]
    pub fn is_picking(&self) -> bool {
        self.picking.is_some()
    }

    /// Starts choosing a file for `purpose`, next to `near` (the current session) when
    /// given. A native dialog that cannot start falls back to the typed box, saying why in
    /// the returned note.
    pub fn pick(&mut self, purpose: FilePurpose, near: Option<&Path>) -> Option<String> {
        let mut note = None;
        if self.backend == DialogBackend::Native {
            let folder = near
                .and_then(Path::parent)
                .filter(|d| !d.as_os_str().is_empty());
            let name = near
                .filter(|_| purpose == FilePurpose::SaveAs)
                .and_then(Path::file_name)
                .and_then(|n| n.to_str());
            match NativePick::start(purpose, folder, name) {
                Ok(pick) => {
                    self.picking = Some(Picking::Native { purpose, pick });
                    return None;
                }
                Err(e) => {
                    let why = format!("the file dialog could not start ({e})");
                    note = Some(format!("{}: {why}; type the path instead", purpose.title()));
                    self.backend = DialogBackend::typed(why);
                }
            }
        }
        let text = match purpose {
            FilePurpose::SaveAs => near.map(|p| p.display().to_string()).unwrap_or_default(),
            _ => String::new(),
        };
        self.picking = Some(Picking::Typed {
            purpose,
            text,
            fresh: true,
        });
        note
    }

    /// The top bar's file buttons: New, Open, Save, Save As, Import, Export and Recent.
    /// `session` is the session worked on (`None` before the first Save As); `busy` greys
    /// out what would replace the clay while a load runs.
    pub fn bar_ui(
        &mut self,
        ui: &mut egui::Ui,
        session: Option<&Path>,
        busy: bool,
    ) -> Option<FileRequest> {
        let mut request = None;
        let free = !busy && !self.is_picking();
        if ui
            .add_enabled(free, egui::Button::new("New…"))
            .on_hover_text("A new clay: shape, size, resolution and material")
            .clicked()
        {
            self.open_new_dialog();
        }
        if ui
            .add_enabled(free, egui::Button::new("Open…"))
            .on_hover_text("Open a session (.dclay)")
            .clicked()
        {
            self.pick(FilePurpose::Open, session);
        }
        let save_tip = match session {
            Some(p) => format!("Save to {}", p.display()),
            None => "Save under a name of your choice".to_owned(),
        };
        if ui
            .add_enabled(!self.is_picking(), egui::Button::new("Save"))
            .on_hover_text(save_tip)
            .clicked()
        {
            match session {
                Some(_) => request = Some(FileRequest::Save),
                None => {
                    self.pick(FilePurpose::SaveAs, None);
                }
            }
        }
        if ui
            .add_enabled(!self.is_picking(), egui::Button::new("Save As…"))
            .clicked()
        {
            self.pick(FilePurpose::SaveAs, session);
        }
        if ui
            .add_enabled(free, egui::Button::new("Import…"))
            .on_hover_text("Fit a point cloud, mesh or volume into a new clay")
            .clicked()
        {
            self.pick(FilePurpose::Import, session);
        }
        if ui
            .add_enabled(!self.is_picking(), egui::Button::new("Export…"))
            .on_hover_text("Write the surface mesh (.obj, .ply or .stl)")
            .clicked()
        {
            self.pick(FilePurpose::Export, session);
        }
        ui.add_enabled_ui(free, |ui| {
            ui.menu_button("Recent", |ui| {
                if let Some(r) = self.recent_ui(ui) {
                    request = Some(r);
                    ui.close();
                }
            });
        });
        request
    }

    /// The recent files, pruned of files gone; a session opens, anything else imports.
    fn recent_ui(&mut self, ui: &mut egui::Ui) -> Option<FileRequest> {
        let (paths, _) = self.recent.shown();
        if paths.is_empty() {
            ui.weak("no recent files");
            return None;
        }
        let mut chosen = None;
        for path in paths {
            let name = path.file_name().map_or_else(
                || path.display().to_string(),
                |n| n.to_string_lossy().into(),
            );
            if ui
                .button(name)
                .on_hover_text(path.display().to_string())
                .clicked()
            {
                chosen = Some(path.clone());
            }
        }
        chosen.map(|path| {
            if super::replace_dialog::is_session_path(&path) {
                FileRequest::Open(path)
            } else {
                FileRequest::Import(path)
            }
        })
    }

    /// The native dialog's answer, if it came; polled each frame without waiting.
    pub fn poll(&mut self) -> Option<FileRequest> {
        let Some(Picking::Native { purpose, pick }) = &self.picking else {
            return None;
        };
        let purpose = *purpose;
        match pick.poll() {
            PickState::Open => None,
            PickState::Cancelled => {
                self.picking = None;
                None
            }
            PickState::Chosen(path) => {
                self.picking = None;
                Some(FileRequest::for_purpose(purpose, path))
            }
        }
    }

    /// The windows over the view: the typed-path box and the New dialog.
    pub fn windows(&mut self, ctx: &egui::Context) -> Option<FileRequest> {
        let mut request = self.typed_window(ctx);
        if let Some(spec) = self.new_clay.as_mut() {
            let mut create = false;
            let mut cancel = false;
            egui::Window::new("New clay")
                .collapsible(false)
                .resizable(false)
                .show(ctx, |ui| {
                    spec.ui(ui);
                    ui.horizontal(|ui| {
                        create = ui.button("Create").clicked();
                        cancel = ui.button("Cancel").clicked();
                    });
                });
            if create {
                self.last_new = *spec;
                request = Some(FileRequest::New(*spec));
            }
            if create || cancel {
                self.new_clay = None;
            }
        }
        request
    }

    fn typed_window(&mut self, ctx: &egui::Context) -> Option<FileRequest> {
        let Some(Picking::Typed {
            purpose,
            text,
            fresh,
        }) = self.picking.as_mut()
        else {
            return None;
        };
        let purpose = *purpose;
        let why = match &self.backend {
            DialogBackend::Typed { why } => why.clone(),
            DialogBackend::Native => "the file dialog is not available".to_owned(),
        };
        let (mut ok, mut cancel) = (false, false);
        egui::Window::new(purpose.title())
            .collapsible(false)
            .resizable(false)
            .show(ctx, |ui| {
                ui.label(format!(
                    "No file dialog: {why}. Type the path of {}.",
                    purpose.hint()
                ));
                let label = ui.label("Path");
                let edit = ui
                    .add(egui::TextEdit::singleline(text).desired_width(360.0))
                    .labelled_by(label.id);
                if *fresh {
                    // Typing goes to the box as soon as it shows.
                    edit.request_focus();
                    *fresh = false;
                }
                let entered = edit.lost_focus() && ui.input(|i| i.key_pressed(egui::Key::Enter));
                ui.horizontal(|ui| {
                    ok = ui.button("OK").clicked() || entered;
                    cancel = ui.button("Cancel").clicked();
                });
            });
        let typed = text.trim().to_owned();
        if cancel {
            self.picking = None;
            return None;
        }
        if ok && !typed.is_empty() {
            self.picking = None;
            return Some(FileRequest::for_purpose(purpose, PathBuf::from(typed)));
        }
        None
    }
}
