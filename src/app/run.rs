//! Opening the app's window: `dynaclay gui`.

use super::link::EngineLink;
use super::pointer_tool::PointerTool;
use super::state::SculptApp;

/// Window settings.
#[derive(Clone, Debug, PartialEq)]
pub struct GuiOptions {
    pub title: String,
    /// Initial inner size of the window, logical points.
    pub window_size_pt: [f32; 2],
    /// The session path the top bar starts with (Save and Load use it).
    pub session_path: String,
    /// The haptic loop's rate and priority, which the latency panel's probe imitates.
    pub probe_settings: super::probe_panel::ProbeSettings,
    /// The probe run at launch, before the engine started.
    pub probe_at_start: Option<super::probe_panel::ProbeOutcome>,
}

impl Default for GuiOptions {
    fn default() -> Self {
        Self {
            title: "dynaclay".into(),
            window_size_pt: [1400.0, 900.0],
            session_path: super::state::DEFAULT_SESSION.into(),
            probe_settings: super::probe_panel::ProbeSettings::default(),
            probe_at_start: None,
        }
    }
}

/// Why the window could not run.
#[derive(Debug, thiserror::Error)]
#[error("cannot run the GUI: {message}")]
pub struct GuiError {
    pub message: String,
}

/// Opens the window and runs the app until it is closed. The engine behind `link` keeps
/// running on its own threads (`pointer`, when given, aims the engine's pointer device); the app only sends commands and reads what it publishes.
///
/// # Errors
/// No display (no `DISPLAY` or `WAYLAND_DISPLAY`), no wgpu adapter for the window, or another
/// windowing failure, as a [`GuiError`] carrying eframe's message.
pub fn run_gui(
    options: GuiOptions,
    link: EngineLink,
    pointer: Option<PointerTool>,
) -> Result<(), GuiError> {
    let native = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default()
            .with_title(options.title.clone())
            .with_inner_size(options.window_size_pt),
        renderer: eframe::Renderer::Wgpu,
        ..Default::default()
    };
    let repaint = link.repaint_signal();
    let mut app = SculptApp::new(link);
    if let Some(pointer) = pointer {
        app.pointer = pointer;
    }
    app.files.session = Some(options.session_path.clone().into());
    app.file_menu.backend = super::file_dialog::DialogBackend::detect();
    if let Some(dir) = super::recent_files::settings_dir() {
        let (recent, error) = super::recent_files::RecentFiles::load_from(&dir);
        app.file_menu.recent = recent;
        if let Some(e) = error {
            app.note(e.to_string());
        }
    }
    app.probe =
        super::probe_panel::ProbePanel::new(options.probe_settings, options.probe_at_start.clone());
    eframe::run_native(
        &options.title,
        native,
        Box::new(move |cc| {
            // wgpu's default handler panics on an error outside an error scope (a validation
            // or out-of-memory error): count and report them instead, and say a lost device.
            if let Some(rs) = &cc.wgpu_render_state {
                app.gpu_faults = Some(crate::render::GpuFaultLog::install(&rs.device, true));
            }
            let ctx = cc.egui_ctx.clone();
            repaint.install(move || ctx.request_repaint());
            Ok(Box::new(app))
        }),
    )
    .map_err(|e| GuiError {
        message: e.to_string(),
    })
}
