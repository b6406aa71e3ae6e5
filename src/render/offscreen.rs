//! Offscreen rendering: frames to CPU images and PNG files, without a window.
//!
//! [`OffscreenRenderer`] keeps a headless GPU and a [`SceneRenderer`] for many frames (tests,
//! benchmarks, turntables); [`render_to_png`] is the one-call form for `dynaclay render` and
//! `dynaclay run --png`. Both block until the frame is back in memory.

use std::path::{Path, PathBuf};
use std::sync::mpsc;

use glam::Vec3;

use super::camera::{Camera, NamedView};
use super::chunk::{MeshChunk, bounds_of};
use super::context::{AdapterSummary, GpuContext};
use super::discs::Disc;
use super::error::RenderError;
use super::gpu_chunks::SyncReport;
use super::image::Image;
use super::options::SceneOptions;
use super::profile::{FrameSettings, MeshShading};
use super::renderer::{SceneRenderer, supported_sample_count};

/// Colour format of offscreen frames: 8-bit sRGB, what PNG viewers expect.
pub const OFFSCREEN_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;

/// What [`render_to_png`] produced.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RenderOutcome {
    pub path: PathBuf,
    pub width: u32,
    pub height: u32,
    pub adapter: AdapterSummary,
    pub sample_count: u32,
    pub triangles: usize,
}

/// A headless GPU with a scene renderer and a readback buffer.
pub struct OffscreenRenderer {
    gpu: GpuContext,
    renderer: SceneRenderer,
    readback: Option<wgpu::Buffer>,
}

impl OffscreenRenderer {
    /// Opens a headless GPU ([`GpuContext::headless`]) with a `width × height` target
    /// (clamped to at least 1 and to the adapter's texture limit).
    ///
    /// # Errors
    /// [`RenderError::NoAdapter`] or [`RenderError::Device`]; [`RenderError::OutOfMemory`]
    /// when the GPU cannot hold the target.
    pub fn new(width: u32, height: u32) -> Result<Self, RenderError> {
        Self::with_context(GpuContext::headless()?, width, height)
    }

    /// Uses an existing context.
    ///
    /// # Errors
    /// [`RenderError::OutOfMemory`] (or another caught GPU error) when the target's textures
    /// cannot be made.
    pub fn with_context(gpu: GpuContext, width: u32, height: u32) -> Result<Self, RenderError> {
        let settings = FrameSettings {
            sample_count: supported_sample_count(&gpu.adapter, OFFSCREEN_FORMAT),
            shading: MeshShading::PerPixel,
            cull_back_faces: false,
            coarse_far_bricks: false,
        };
        Self::with_settings(gpu, settings, width, height)
    }

    /// Uses an existing context and draws with `settings` (a render profile's, say).
    ///
    /// # Errors
    /// As [`Self::with_context`].
    pub fn with_settings(
        gpu: GpuContext,
        settings: FrameSettings,
        width: u32,
        height: u32,
    ) -> Result<Self, RenderError> {
        let max = gpu.device.limits().max_texture_dimension_2d.max(1);
        let renderer = gpu.guarded("the frame's textures", |device, queue| {
            SceneRenderer::with_settings(
                device,
                queue,
                OFFSCREEN_FORMAT,
                settings,
                width.clamp(1, max),
                height.clamp(1, max),
            )
        })?;
        Ok(Self {
            gpu,
            renderer,
            readback: None,
        })
    }

    /// Changes the frame size (clamped as in [`Self::new`]).
    ///
    /// # Errors
    /// As [`Self::with_context`].
    pub fn resize(&mut self, width: u32, height: u32) -> Result<(), RenderError> {
        let max = self.gpu.device.limits().max_texture_dimension_2d.max(1);
        self.renderer
            .try_resize(&self.gpu.device, width.clamp(1, max), height.clamp(1, max))?;
        self.gpu.check_faults("the frame's textures")
    }

    /// Uploads changed chunks and drops absent ones; see [`SceneRenderer::sync_chunks`].
    ///
    /// # Errors
    /// [`RenderError::Chunk`] for a malformed chunk or a repeated id;
    /// [`RenderError::OutOfMemory`] when the GPU cannot hold the meshes.
    pub fn sync_chunks(&mut self, chunks: &[MeshChunk<'_>]) -> Result<SyncReport, RenderError> {
        let renderer = &mut self.renderer;
        Ok(self.gpu.guarded("the mesh buffers", |device, queue| {
            renderer.sync_chunks(device, queue, chunks)
        })??)
    }

    /// What the last frame drew; see [`SceneRenderer::last_draw`].
    #[must_use]
    pub fn last_draw(&self) -> super::DrawReport {
        self.renderer.last_draw()
    }

    /// Replaces the discs (particles, point-set splats) drawn with the clay.
    ///
    /// # Errors
    /// [`RenderError::OutOfMemory`] or [`RenderError::Gpu`] when the GPU refuses the buffer.
    pub fn set_discs(&mut self, discs: &[Disc]) -> Result<(), RenderError> {
        let renderer = &mut self.renderer;
        self.gpu.guarded("the discs", |device, queue| {
            renderer.set_discs(device, queue, discs);
        })
    }

    /// Renders the synced chunks and reads the frame back.
    ///
    /// # Errors
    /// [`RenderError::Readback`] when the GPU copy cannot be mapped.
    pub fn render(
        &mut self,
        camera: &Camera,
        options: &SceneOptions,
    ) -> Result<Image, RenderError> {
        let (width, height) = self.renderer.size();
        // Rows in a texture-to-buffer copy must be 256-byte aligned.
        let row_bytes = 4 * width;
        let padded_row = row_bytes.next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
        let needed = u64::from(padded_row) * u64::from(height);
        let renderer = &mut self.renderer;
        let slot = &mut self.readback;
        let readback = self.gpu.guarded("the frame", |device, queue| {
            let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("offscreen frame"),
            });
            renderer.render(device, queue, &mut encoder, camera, options);
            if slot.as_ref().is_none_or(|b| b.size() < needed) {
                *slot = Some(device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("offscreen readback"),
                    size: needed,
                    usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                    mapped_at_creation: false,
                }));
            }
            let readback = slot.clone().unwrap_or_else(|| unreachable!("just ensured"));
            copy_frame(
                &mut encoder,
                renderer.target(),
                &readback,
                padded_row,
                width,
                height,
            );
            queue.submit([encoder.finish()]);
            readback
        })?;
        let device = &self.gpu.device;

        let slice = readback.slice(..needed);
        let (tx, rx) = mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            // The receiver lives until after the poll below; a failed send cannot happen.
            let _ = tx.send(r);
        });
        let fail = |message: String| RenderError::Readback { message };
        dynaclay_loops::assert_not_in_tick("OffscreenRenderer::render waiting for the GPU");
        device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| fail(e.to_string()))?;
        rx.recv()
            .map_err(|_| fail("map callback never ran".to_owned()))?
            .map_err(|e| fail(e.to_string()))?;
        let mut rgba8 = Vec::with_capacity((row_bytes * height) as usize);
        {
            let view = slice.get_mapped_range().map_err(|e| fail(e.to_string()))?;
            for row in view.chunks(padded_row as usize).take(height as usize) {
                rgba8.extend_from_slice(&row[..row_bytes as usize]);
            }
        }
        readback.unmap();
        self.gpu.check_faults("the frame")?;
        Ok(Image {
            width,
            height,
            rgba8,
        })
    }

    /// The GPU this renderer runs on.
    #[must_use]
    pub fn gpu(&self) -> &GpuContext {
        &self.gpu
    }

    /// The scene renderer (upload counters, sample count, size).
    #[must_use]
    pub fn renderer(&self) -> &SceneRenderer {
        &self.renderer
    }
}

/// Records the copy of the frame `target` into `readback`, `padded_row` bytes per row.
fn copy_frame(
    encoder: &mut wgpu::CommandEncoder,
    target: &wgpu::Texture,
    readback: &wgpu::Buffer,
    padded_row: u32,
    width: u32,
    height: u32,
) {
    encoder.copy_texture_to_buffer(
        wgpu::TexelCopyTextureInfo {
            texture: target,
            mip_level: 0,
            origin: wgpu::Origin3d::ZERO,
            aspect: wgpu::TextureAspect::All,
        },
        wgpu::TexelCopyBufferInfo {
            buffer: readback,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(padded_row),
                rows_per_image: Some(height),
            },
        },
        wgpu::Extent3d {
            width,
            height,
            depth_or_array_layers: 1,
        },
    );
}

/// A camera that frames the chunks and the workspace box (when shown) from `view`, or the unit
/// cube around the origin when the scene is empty.
#[must_use]
pub fn scene_camera(view: NamedView, chunks: &[MeshChunk<'_>], options: &SceneOptions) -> Camera {
    let mut bounds = bounds_of(chunks);
    if let Some(b) = options
        .workspace_box
        .filter(|b| b.min.is_finite() && b.max.is_finite())
    {
        bounds = Some(match bounds {
            Some((lo, hi)) => (lo.min(b.min), hi.max(b.max)),
            None => (b.min, b.max),
        });
    }
    let (lo, hi) = bounds.unwrap_or((Vec3::splat(-1.0), Vec3::splat(1.0)));
    Camera::named(view, lo, hi)
}

/// Renders `chunks` once, `width × height` pixels seen by `camera`, and writes a PNG to `path`
/// atomically.
///
/// # Errors
/// [`RenderError::NoAdapter`] (message "no GPU adapter: …") when the machine has no GPU, which
/// callers should report and skip; otherwise a chunk, device, readback or file error.
pub fn render_to_png(
    chunks: &[MeshChunk<'_>],
    options: &SceneOptions,
    camera: &Camera,
    width: u32,
    height: u32,
    path: &Path,
) -> Result<RenderOutcome, RenderError> {
    let mut offscreen = OffscreenRenderer::new(width, height)?;
    let report = offscreen.sync_chunks(chunks)?;
    let image = offscreen.render(camera, options)?;
    image.write_png(path)?;
    Ok(RenderOutcome {
        path: path.to_path_buf(),
        width: image.width,
        height: image.height,
        adapter: offscreen.gpu().summary.clone(),
        sample_count: offscreen.renderer().sample_count(),
        triangles: report.triangles,
    })
}
