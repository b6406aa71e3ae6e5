//! The 3D view's image drawn into egui's render pass by a pipeline of its own (an egui-wgpu
//! paint callback) rather than as an egui image.
//!
//! Why: egui's fragment shader (its texture-filtering paths and colour handling) costs several
//! times a plain texel copy per pixel on a software adapter, and the view is the largest thing
//! in the window. On lavapipe the default view's 764×821 pixels took about 140 ms through egui's
//! shader against 11–25 ms for a plain copy of the same image (see `bench/RESULTS.md`,
//! `frame_time`).
//!
//! The copy gives the bytes egui's image gave: the scene's sRGB target is read decoded (linear
//! values) and, like egui's image, stored as they are in the window, whatever its format (to an
//! sRGB window egui treats them as gamma-encoded, so this copy decodes them once more before
//! the window's own encoding). Texels are fetched, not filtered: the scene target is
//! sized to the view in pixels, so each pixel takes the texel under it. Blending is egui's
//! (premultiplied alpha), so an image with alpha below one shows the window behind as before.
//!
//! The pipeline matches eframe's window pass as the app opens it: one sample, no depth buffer.

use crate::render::RenderError;
use crate::render::guarded_on;

const SHADER: &str = r"
@group(0) @binding(0) var scene: texture_2d<f32>;

struct Corner {
    @builtin(position) position: vec4<f32>,
    @location(0) uv: vec2<f32>,
};

// A quad over the whole viewport (egui sets the viewport to the callback's rectangle) as a
// four-vertex strip: uv (0,0) at the top left.
@vertex
fn vs_main(@builtin(vertex_index) index: u32) -> Corner {
    let uv = vec2<f32>(f32(index & 1u), f32((index >> 1u) & 1u));
    var out: Corner;
    out.uv = uv;
    out.position = vec4<f32>(2.0 * uv.x - 1.0, 1.0 - 2.0 * uv.y, 0.0, 1.0);
    return out;
}

fn texel(uv: vec2<f32>) -> vec4<f32> {
    let size = textureDimensions(scene, 0);
    let at = min(vec2<u32>(uv * vec2<f32>(size)), size - vec2<u32>(1u, 1u));
    return textureLoad(scene, at, 0);
}

@fragment
fn fs_unorm_window(in: Corner) -> @location(0) vec4<f32> {
    return texel(in.uv);
}

// sRGB decoding (IEC 61966-2-1), for a window whose format encodes on write.
fn decoded(encoded: vec3<f32>) -> vec3<f32> {
    let low = encoded / 12.92;
    let high = pow((encoded + 0.055) / 1.055, vec3<f32>(2.4));
    return select(high, low, encoded <= vec3<f32>(0.04045));
}

@fragment
fn fs_srgb_window(in: Corner) -> @location(0) vec4<f32> {
    let c = texel(in.uv);
    return vec4<f32>(decoded(c.rgb), c.a);
}
";

/// The pipeline that copies the view's image into the window, for one window format.
pub struct ViewBlit {
    pipeline: wgpu::RenderPipeline,
    layout: wgpu::BindGroupLayout,
}

impl ViewBlit {
    /// Builds the pipeline for a window of `window_format` (inside error scopes).
    ///
    /// # Errors
    /// [`RenderError::OutOfMemory`] or [`RenderError::Gpu`] when the GPU refuses it.
    pub fn new(
        device: &wgpu::Device,
        window_format: wgpu::TextureFormat,
    ) -> Result<Self, RenderError> {
        guarded_on(device, "the 3D view's copy into the window", || {
            let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("dynaclay view image"),
                source: wgpu::ShaderSource::Wgsl(SHADER.into()),
            });
            let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("dynaclay view image"),
                entries: &[wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Float { filterable: false },
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                    count: None,
                }],
            });
            let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some("dynaclay view image"),
                bind_group_layouts: &[Some(&layout)],
                immediate_size: 0,
            });
            let premultiplied_over = wgpu::BlendState {
                color: wgpu::BlendComponent {
                    src_factor: wgpu::BlendFactor::One,
                    dst_factor: wgpu::BlendFactor::OneMinusSrcAlpha,
                    operation: wgpu::BlendOperation::Add,
                },
                alpha: wgpu::BlendComponent {
                    src_factor: wgpu::BlendFactor::OneMinusDstAlpha,
                    dst_factor: wgpu::BlendFactor::One,
                    operation: wgpu::BlendOperation::Add,
                },
            };
            let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some("dynaclay view image"),
                layout: Some(&pipeline_layout),
                vertex: wgpu::VertexState {
                    module: &module,
                    entry_point: Some("vs_main"),
                    buffers: &[],
                    compilation_options: wgpu::PipelineCompilationOptions::default(),
                },
                primitive: wgpu::PrimitiveState {
                    topology: wgpu::PrimitiveTopology::TriangleStrip,
                    ..Default::default()
                },
                depth_stencil: None,
                multisample: wgpu::MultisampleState::default(),
                fragment: Some(wgpu::FragmentState {
                    module: &module,
                    entry_point: Some(if window_format.is_srgb() {
                        "fs_srgb_window"
                    } else {
                        "fs_unorm_window"
                    }),
                    targets: &[Some(wgpu::ColorTargetState {
                        format: window_format,
                        blend: Some(premultiplied_over),
                        write_mask: wgpu::ColorWrites::ALL,
                    })],
                    compilation_options: wgpu::PipelineCompilationOptions::default(),
                }),
                multiview_mask: None,
                cache: None,
            });
            Self { pipeline, layout }
        })
    }

    /// The image of `scene` (the scene target's view) ready to paint, for as long as that
    /// view lives.
    #[must_use]
    pub fn image(&self, device: &wgpu::Device, scene: &wgpu::TextureView) -> ViewImage {
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("dynaclay view image"),
            layout: &self.layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: wgpu::BindingResource::TextureView(scene),
            }],
        });
        ViewImage {
            pipeline: self.pipeline.clone(),
            bind_group,
        }
    }
}

/// The view's image as a paint callback: copies the scene target into the rectangle it is
/// painted at.
#[derive(Clone, Debug)]
pub struct ViewImage {
    pipeline: wgpu::RenderPipeline,
    bind_group: wgpu::BindGroup,
}

impl ViewImage {
    /// Adds the image to `ui`'s painter over `rect` (points), in paint order with the shapes
    /// before and after it.
    pub fn paint_at(&self, ui: &egui::Ui, rect: egui::Rect) {
        ui.painter()
            .add(egui_wgpu::Callback::new_paint_callback(rect, self.clone()));
    }
}

impl egui_wgpu::CallbackTrait for ViewImage {
    fn paint(
        &self,
        _info: egui::PaintCallbackInfo,
        render_pass: &mut wgpu::RenderPass<'static>,
        _resources: &egui_wgpu::CallbackResources,
    ) {
        render_pass.set_pipeline(&self.pipeline);
        render_pass.set_bind_group(0, &self.bind_group, &[]);
        render_pass.draw(0..4, 0..1);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::{GpuContext, OFFSCREEN_FORMAT, REQUIRE_GPU_ENV, gpu_required};

    const SOURCE: [u32; 2] = [20, 10];
    const WINDOW: [u32; 2] = [32, 16];
    /// Where the image goes in the window, pixels (left, top).
    const AT: [u32; 2] = [5, 3];
    const CLEAR: [u8; 4] = [30, 60, 90, 255];

    fn texture(gpu: &GpuContext, format: wgpu::TextureFormat, size: [u32; 2]) -> wgpu::Texture {
        gpu.device.create_texture(&wgpu::TextureDescriptor {
            label: None,
            size: wgpu::Extent3d {
                width: size[0],
                height: size[1],
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT
                | wgpu::TextureUsages::TEXTURE_BINDING
                | wgpu::TextureUsages::COPY_SRC
                | wgpu::TextureUsages::COPY_DST,
            view_formats: &[],
        })
    }

    /// The texture's bytes, four per pixel, rows top to bottom.
    fn read(gpu: &GpuContext, texture: &wgpu::Texture) -> Vec<[u8; 4]> {
        let (w, h) = (texture.width(), texture.height());
        let row = (4 * w).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
        let buffer = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: None,
            size: u64::from(row * h),
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        encoder.copy_texture_to_buffer(
            texture.as_image_copy(),
            wgpu::TexelCopyBufferInfo {
                buffer: &buffer,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(row),
                    rows_per_image: Some(h),
                },
            },
            texture.size(),
        );
        gpu.queue.submit([encoder.finish()]);
        let slice = buffer.slice(..);
        slice.map_async(wgpu::MapMode::Read, |r| r.expect("mapped"));
        gpu.device
            .poll(wgpu::PollType::wait_indefinitely())
            .expect("the GPU finished");
        let data = slice.get_mapped_range().expect("mapped range");
        (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .map(|(x, y)| {
                let at = (y * row + 4 * x) as usize;
                [data[at], data[at + 1], data[at + 2], data[at + 3]]
            })
            .collect()
    }

    /// The source image: every texel different, opaque.
    fn source_texel(x: u32, y: u32) -> [u8; 4] {
        [
            (12 * x + 3) as u8,
            (25 * y + 7) as u8,
            (7 * x + 11 * y) as u8,
            255,
        ]
    }

    fn srgb_decoded(byte: u8) -> f64 {
        let c = f64::from(byte) / 255.0;
        if c <= 0.04045 {
            c / 12.92
        } else {
            ((c + 0.055) / 1.055).powf(2.4)
        }
    }

    /// Copies the source into a window of `format` at [`AT`] and returns the window's bytes.
    fn blit_into(gpu: &GpuContext, format: wgpu::TextureFormat) -> Vec<[u8; 4]> {
        let source = texture(gpu, OFFSCREEN_FORMAT, SOURCE);
        let texels: Vec<u8> = (0..SOURCE[1])
            .flat_map(|y| (0..SOURCE[0]).flat_map(move |x| source_texel(x, y)))
            .collect();
        gpu.queue.write_texture(
            source.as_image_copy(),
            &texels,
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(4 * SOURCE[0]),
                rows_per_image: Some(SOURCE[1]),
            },
            source.size(),
        );
        let window = texture(gpu, format, WINDOW);
        let blit = ViewBlit::new(&gpu.device, format).expect("the pipeline");
        let image = blit.image(
            &gpu.device,
            &source.create_view(&wgpu::TextureViewDescriptor::default()),
        );
        let clear = CLEAR.map(|c| {
            if format.is_srgb() {
                srgb_decoded(c)
            } else {
                f64::from(c) / 255.0
            }
        });
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder
                .begin_render_pass(&wgpu::RenderPassDescriptor {
                    label: None,
                    color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                        view: &window.create_view(&wgpu::TextureViewDescriptor::default()),
                        depth_slice: None,
                        resolve_target: None,
                        ops: wgpu::Operations {
                            load: wgpu::LoadOp::Clear(wgpu::Color {
                                r: clear[0],
                                g: clear[1],
                                b: clear[2],
                                a: 1.0,
                            }),
                            store: wgpu::StoreOp::Store,
                        },
                    })],
                    depth_stencil_attachment: None,
                    timestamp_writes: None,
                    occlusion_query_set: None,
                    multiview_mask: None,
                })
                .forget_lifetime();
            // As egui-wgpu does before a paint callback: the viewport is its rectangle.
            pass.set_viewport(
                AT[0] as f32,
                AT[1] as f32,
                SOURCE[0] as f32,
                SOURCE[1] as f32,
                0.0,
                1.0,
            );
            let rect = egui::Rect::from_min_size(
                egui::pos2(AT[0] as f32, AT[1] as f32),
                egui::vec2(SOURCE[0] as f32, SOURCE[1] as f32),
            );
            let info = egui::PaintCallbackInfo {
                viewport: rect,
                clip_rect: rect,
                pixels_per_point: 1.0,
                screen_size_px: WINDOW,
            };
            egui_wgpu::CallbackTrait::paint(&image, info, &mut pass, &Default::default());
        }
        gpu.queue.submit([encoder.finish()]);
        read(gpu, &window)
    }

    #[test]
    fn the_view_image_copies_each_texel_once_with_egui_images_colours() {
        let gpu = match GpuContext::headless() {
            Ok(g) => g,
            Err(e) if e.is_no_adapter() && !gpu_required() => {
                println!("skipped: {e}");
                return;
            }
            Err(e) => panic!("{e} ({REQUIRE_GPU_ENV} is set, so a missing adapter fails)"),
        };
        for format in [
            wgpu::TextureFormat::Rgba8Unorm,
            wgpu::TextureFormat::Rgba8UnormSrgb,
        ] {
            let window = blit_into(&gpu, format);
            for y in 0..WINDOW[1] {
                for x in 0..WINDOW[0] {
                    let got = window[(y * WINDOW[0] + x) as usize];
                    let inside = (AT[0]..AT[0] + SOURCE[0]).contains(&x)
                        && (AT[1]..AT[1] + SOURCE[1]).contains(&y);
                    let want = if !inside {
                        CLEAR
                    } else {
                        // egui's image on either window: the decoded (linear) values
                        // stored as they are.
                        let s = source_texel(x - AT[0], y - AT[1]);
                        let d = |c: u8| (srgb_decoded(c) * 255.0).round() as u8;
                        [d(s[0]), d(s[1]), d(s[2]), s[3]]
                    };
                    let off = got.iter().zip(want).map(|(&g, w)| g.abs_diff(w)).max();
                    assert!(
                        off <= Some(1),
                        "{format:?} pixel ({x}, {y}): {got:?}, expected {want:?}"
                    );
                }
            }
        }
        gpu.check_faults("the test").expect("no GPU faults");
    }
}
