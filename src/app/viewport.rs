//! The 3D view inside egui: a [`SceneRenderer`] drawing into its own texture on eframe's wgpu
//! device, shown as an image, with the camera driven by the pointer on that image.
//!
//! The scene is re-rendered only when the meshes, the camera, the overlays or the size
//! changed. Its command buffer is submitted before egui's own, so the image shows this frame's
//! render. Without a wgpu device (headless tests) the view still takes camera input and says
//! that nothing is drawn.

use glam::Vec2;

use crate::render::{
    Camera, ChunkError, MeshChunk, OFFSCREEN_FORMAT, SceneOptions, SceneRenderer, Trackball,
    supported_sample_count,
};

use super::camera_input::{drag_pan, drag_rotate, scroll_zoom};

/// What was last rendered, to skip identical frames.
#[derive(Clone, Copy, Debug, PartialEq)]
struct RenderedKey {
    camera: Camera,
    options: SceneOptions,
    mesh_version: u64,
    size: (u32, u32),
}

/// The GPU side of the view.
pub struct SceneView {
    renderer: SceneRenderer,
    texture: egui::TextureId,
    last: Option<RenderedKey>,
}

impl SceneView {
    /// Builds the renderer on eframe's device and registers its target with egui.
    #[must_use]
    pub fn new(rs: &egui_wgpu::RenderState, width: u32, height: u32) -> Self {
        // eframe makes the device; a lost one is said on stderr (the engine, its autosave and
        // the session live apart from the GPU and carry on).
        rs.device.set_device_lost_callback(|reason, message| {
            eprintln!(
                "dynaclay: the GPU device was lost ({reason:?}: {message}); the sculpt is \
                 kept and autosaved: save it and restart the window"
            );
        });
        let samples = supported_sample_count(&rs.adapter, OFFSCREEN_FORMAT);
        let renderer = SceneRenderer::new(
            &rs.device,
            &rs.queue,
            OFFSCREEN_FORMAT,
            samples,
            width,
            height,
        );
        let texture = rs.renderer.write().register_native_texture(
            &rs.device,
            renderer.target_view(),
            wgpu::FilterMode::Linear,
        );
        Self {
            renderer,
            texture,
            last: None,
        }
    }

    /// Renders the scene at `width × height` if anything changed; returns the texture to show.
    ///
    /// # Errors
    /// A malformed chunk (see [`SceneRenderer::sync_chunks`]); nothing is drawn then.
    pub fn draw(
        &mut self,
        rs: &egui_wgpu::RenderState,
        size: (u32, u32),
        chunks: &[MeshChunk<'_>],
        mesh_version: u64,
        camera: &Camera,
        options: &SceneOptions,
    ) -> Result<egui::TextureId, ChunkError> {
        let before = self.renderer.size();
        self.renderer.resize(&rs.device, size.0, size.1);
        let size = self.renderer.size();
        if size != before {
            rs.renderer.write().update_egui_texture_from_wgpu_texture(
                &rs.device,
                self.renderer.target_view(),
                wgpu::FilterMode::Linear,
                self.texture,
            );
        }
        let key = RenderedKey {
            camera: *camera,
            options: *options,
            mesh_version,
            size,
        };
        if self.last != Some(key) {
            self.last = None;
            self.renderer.sync_chunks(&rs.device, &rs.queue, chunks)?;
            let mut encoder = rs
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("dynaclay scene"),
                });
            self.renderer
                .render(&rs.device, &rs.queue, &mut encoder, camera, options);
            rs.queue.submit([encoder.finish()]);
            self.last = Some(key);
        }
        Ok(self.texture)
    }
}

/// Pointer handling on the view: left drag rotates (trackball) unless it `sculpts`, right or
/// middle drag (or Shift + left) pans, scrolling zooms (Ctrl and Shift with the wheel are the
/// brush's, see the pointer tool). Returns whether the camera changed.
pub fn camera_input(
    ui: &egui::Ui,
    response: &egui::Response,
    camera: &mut Camera,
    trackball: &Trackball,
    sculpts: bool,
) -> bool {
    let before = *camera;
    let rect = response.rect;
    let size = Vec2::new(rect.width(), rect.height());
    let shift = ui.input(|i| i.modifiers.shift);
    let delta = response.drag_delta();
    if delta != egui::Vec2::ZERO {
        let pan = response.dragged_by(egui::PointerButton::Secondary)
            || response.dragged_by(egui::PointerButton::Middle)
            || (shift && response.dragged_by(egui::PointerButton::Primary));
        if pan {
            drag_pan(camera, Vec2::new(delta.x, delta.y), size.y);
        } else if response.dragged_by(egui::PointerButton::Primary)
            && !sculpts
            && let Some(pos) = response.interact_pointer_pos()
        {
            let to = pos - rect.min;
            let from = to - delta;
            drag_rotate(
                camera,
                trackball,
                Vec2::new(from.x, from.y),
                Vec2::new(to.x, to.y),
                size,
            );
        }
    }
    let brush_wheel = ui.input(|i| i.modifiers.shift || i.modifiers.ctrl || i.modifiers.command);
    if response.hovered() && !brush_wheel {
        let scroll = ui.input(|i| i.smooth_scroll_delta.y);
        if scroll != 0.0 {
            scroll_zoom(camera, scroll);
        }
    }
    *camera != before
}
