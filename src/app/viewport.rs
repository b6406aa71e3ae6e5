//! The 3D view inside egui: a [`SceneRenderer`] drawing into its own texture on eframe's wgpu
//! device, copied into the window by a paint callback ([`ViewImage`]: egui's own image shader
//! is several times dearer per pixel on a software adapter), with the camera driven by the
//! pointer on that image.
//!
//! The scene is re-rendered only when the meshes, the camera, the overlays or the size
//! changed. Its command buffer is submitted before egui's own, so the image shows this frame's
//! render. Without a wgpu device (headless tests) the view still takes camera input and says
//! that nothing is drawn.
//!
//! Every GPU allocation of the view (its textures on a resize, the mesh buffers on a new mesh,
//! the overlay buffers of a frame) runs inside wgpu's error scopes: a size or a mesh the GPU
//! refuses becomes a [`SceneView::problem`] shown over the view, never a panic, and the
//! engine, the sculpt and the rest of the window carry on. A refused size keeps the last
//! size's image; a refused mesh is not retried until the engine publishes a new one.

use glam::Vec2;

use crate::render::{
    Camera, Disc, MeshChunk, OFFSCREEN_FORMAT, ProfileChoice, ProfileRequest, RenderError,
    SceneOptions, SceneRenderer, Trackball, guarded_on,
};

use super::camera_input::{drag_pan, drag_rotate, scroll_zoom};
use super::view_image::{ViewBlit, ViewImage};

/// What was last rendered, to skip identical frames.
#[derive(Clone, Copy, Debug, PartialEq)]
struct RenderedKey {
    camera: Camera,
    options: SceneOptions,
    mesh_version: u64,
    discs: DiscKey,
    size: (u32, u32),
}

/// Which discs are on the GPU: the particles' and the point set's publication versions (0:
/// none of that kind).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DiscKey {
    pub particles: u64,
    pub points: u64,
}

/// The GPU side of the view.
pub struct SceneView {
    renderer: SceneRenderer,
    /// The render profile chosen for eframe's adapter (no MSAA, vertex-lit on a software one).
    profile: ProfileChoice,
    /// The pipeline copying the target into the window.
    blit: ViewBlit,
    /// The target's image, as painted into the window (rebuilt when the target is).
    image: ViewImage,
    last: Option<RenderedKey>,
    /// The mesh version whose chunks are on the GPU.
    synced: Option<u64>,
    /// A size the GPU refused, with why (not retried until the size changes).
    size_refused: Option<((u32, u32), RenderError)>,
    /// A mesh version the GPU could not take, with why (not retried until a new version).
    mesh_refused: Option<(u64, RenderError)>,
    /// Why the last frame could not be recorded.
    frame_failed: Option<RenderError>,
    /// Why the GPU refused the last discs (none are drawn then).
    discs_refused: Option<RenderError>,
    /// The key whose discs are on the GPU.
    discs: DiscKey,
}

impl SceneView {
    /// Chooses the render profile for eframe's adapter (`request` may force one), builds the
    /// renderer for it on eframe's device and the copy of its target into the window (inside
    /// error scopes).
    ///
    /// # Errors
    /// [`RenderError::OutOfMemory`] or [`RenderError::Gpu`] when the GPU refuses the pipelines
    /// or a `width × height` target.
    pub fn new(
        rs: &egui_wgpu::RenderState,
        request: ProfileRequest,
        width: u32,
        height: u32,
    ) -> Result<Self, RenderError> {
        let profile = ProfileChoice::for_adapter(&rs.adapter, OFFSCREEN_FORMAT, request);
        let renderer = guarded_on(&rs.device, "the 3D view's textures", || {
            SceneRenderer::with_settings(
                &rs.device,
                &rs.queue,
                OFFSCREEN_FORMAT,
                profile.settings,
                width,
                height,
            )
        })?;
        let blit = ViewBlit::new(&rs.device, rs.target_format)?;
        let image = blit.image(&rs.device, renderer.target_view());
        Ok(Self {
            renderer,
            profile,
            blit,
            image,
            last: None,
            synced: None,
            size_refused: None,
            mesh_refused: None,
            frame_failed: None,
            discs_refused: None,
            discs: DiscKey::default(),
        })
    }

    /// Puts the discs (particles, point-set splats) under `key` on the GPU, unless that key
    /// is already there. A buffer the GPU refuses leaves no discs and becomes the frame's
    /// problem.
    pub fn set_discs(&mut self, rs: &egui_wgpu::RenderState, key: DiscKey, discs: &[Disc]) {
        if key == self.discs {
            return;
        }
        self.discs = key;
        let renderer = &mut self.renderer;
        if let Err(e) = guarded_on(&rs.device, "the discs", || {
            renderer.set_discs(&rs.device, &rs.queue, discs);
        }) {
            self.renderer.set_discs(&rs.device, &rs.queue, &[]);
            self.discs_refused = Some(e);
        } else {
            self.discs_refused = None;
        }
    }

    /// Renders the scene at `width × height` if anything changed; returns the image to paint,
    /// or `None` when no frame could be recorded. Whatever the GPU refused is kept in
    /// [`Self::problem`].
    pub fn draw(
        &mut self,
        rs: &egui_wgpu::RenderState,
        size: (u32, u32),
        chunks: &[MeshChunk<'_>],
        mesh_version: u64,
        camera: &Camera,
        options: &SceneOptions,
    ) -> Option<ViewImage> {
        self.resize(rs, size);
        let key = RenderedKey {
            camera: *camera,
            options: *options,
            mesh_version,
            discs: self.discs,
            size: self.renderer.size(),
        };
        if self.last == Some(key) {
            return self.frame_failed.is_none().then(|| self.image.clone());
        }
        self.sync(rs, chunks, mesh_version);
        let renderer = &mut self.renderer;
        let recorded = guarded_on(&rs.device, "the 3D view's frame", || {
            let mut encoder = rs
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("dynaclay scene"),
                });
            renderer.render(&rs.device, &rs.queue, &mut encoder, camera, options);
            rs.queue.submit([encoder.finish()]);
        });
        // Kept even on failure: the same frame is not retried until something changes.
        self.last = Some(key);
        self.frame_failed = recorded.err();
        self.frame_failed.is_none().then(|| self.image.clone())
    }

    /// Resizes the target unless the GPU refuses; a refused size is remembered and the old
    /// target (and its image) stays.
    fn resize(&mut self, rs: &egui_wgpu::RenderState, size: (u32, u32)) {
        let size = (size.0.max(1), size.1.max(1));
        if self.size_refused.as_ref().is_some_and(|(s, _)| *s == size) {
            return;
        }
        match self.renderer.try_resize(&rs.device, size.0, size.1) {
            Ok(changed) => {
                self.size_refused = None;
                if changed {
                    self.image = self.blit.image(&rs.device, self.renderer.target_view());
                }
            }
            Err(e) => self.size_refused = Some((size, e)),
        }
    }

    /// Uploads a new mesh version; one the GPU cannot take (or a malformed one) leaves no
    /// chunk on the GPU and is not retried.
    fn sync(&mut self, rs: &egui_wgpu::RenderState, chunks: &[MeshChunk<'_>], version: u64) {
        if self.synced == Some(version)
            || self
                .mesh_refused
                .as_ref()
                .is_some_and(|(v, _)| *v == version)
        {
            return;
        }
        let renderer = &mut self.renderer;
        let synced = guarded_on(&rs.device, "the mesh buffers", || {
            renderer.sync_chunks(&rs.device, &rs.queue, chunks)
        })
        .and_then(|r| r.map_err(RenderError::from));
        match synced {
            Ok(_) => {
                self.synced = Some(version);
                self.mesh_refused = None;
            }
            Err(e) => {
                // Buffers made in a failed scope are invalid: drop them all.
                self.renderer.clear_chunks();
                self.synced = None;
                self.mesh_refused = Some((version, e));
            }
        }
    }

    /// Why the view is not showing everything: a refused size (the last size's image is
    /// shown), a mesh the GPU could not take (the clay is missing), or a frame that could not
    /// be recorded.
    #[must_use]
    pub fn problem(&self) -> Option<String> {
        if let Some(e) = &self.frame_failed {
            return Some(format!("cannot draw the 3D view: {e}"));
        }
        if let Some(e) = &self.discs_refused {
            return Some(format!("cannot show the particles or points: {e}"));
        }
        if let Some((_, e)) = &self.mesh_refused {
            return Some(format!(
                "cannot show the clay: {e}; the sculpt is kept, save it as usual"
            ));
        }
        self.size_refused.as_ref().map(|((w, h), e)| {
            format!("cannot draw the view at {w}×{h}: {e}; make the window smaller")
        })
    }

    /// The render profile this view draws with.
    #[must_use]
    pub fn profile(&self) -> &ProfileChoice {
        &self.profile
    }

    /// Triangles drawn per frame.
    #[must_use]
    pub fn triangle_count(&self) -> usize {
        self.renderer.triangle_count()
    }

    /// Upload totals of the view's mesh buffers (only changed bricks are uploaded).
    #[must_use]
    pub fn upload_stats(&self) -> crate::render::UploadStats {
        self.renderer.upload_stats()
    }

    /// The target's size in pixels (the last size the GPU accepted).
    #[must_use]
    pub fn size(&self) -> (u32, u32) {
        self.renderer.size()
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
