//! The scene renderer: draws the brick meshes and overlays into its own colour texture.
//!
//! `new` / `resize` / `render`, given the device and queue and nothing else. It renders to a
//! texture it owns (multisampled when the format allows, resolved into [`SceneRenderer::target`]),
//! so the same code serves offscreen PNGs (copy the target out) and the GUI (register the target
//! view as an egui texture). Rendering never blocks: it records into the caller's encoder.
//!
//! In an egui-wgpu app: create it with [`crate::render::OFFSCREEN_FORMAT`] (sRGB, as egui
//! expects of user textures) and the settings [`crate::render::ProfileChoice::for_adapter`]
//! gives for the app's adapter (no MSAA and vertex-lit shading on a software adapter); call
//! `sync_chunks` and `render` from a paint callback's `prepare` (it gets the device, queue and
//! egui's encoder); register [`SceneRenderer::target_view`] once with
//! `egui_wgpu::Renderer::register_native_texture` and show it as an image; after a `resize`
//! that changed the size, point the same id at the new view with
//! `update_egui_texture_from_wgpu_texture`.

use glam::Mat4;

use super::camera::Camera;
use super::chunk::{ChunkError, MeshChunk};
use super::discs::{DISC_ATTRIBUTES, Disc};
use super::environment::EnvironmentMap;
use super::error::RenderError;
use super::faults::guarded_on;
use super::gpu_chunks::{
    ChunkBuffers, DrawReport, DrawView, LevelOfDetail, MeshVertex, SyncReport, UploadStats,
};
use super::options::{EnvironmentMode, SceneOptions};
use super::overlay::{OverlayGeometry, OverlayVertex};
use super::profile::{COARSE_BELOW_EDGE_PX, FrameSettings, MeshShading, PREFERRED_SAMPLES};

/// Depth buffer format of every pass.
pub const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// A shader of `shaders/` with `shaders/frame.wgsl` (the per-frame uniforms) placed before
/// it: every scene pass reads that one layout.
macro_rules! framed {
    ($file:literal) => {
        concat!(
            include_str!("../../shaders/frame.wgsl"),
            "\n",
            include_str!(concat!("../../shaders/", $file))
        )
    };
}

/// A shader of `shaders/` with `shaders/frame.wgsl` and `shaders/clay_shading.wgsl` placed
/// before it: the passes that draw the clay's surface (the mesh, the point-set splats) share
/// that one lighting code.
macro_rules! clay_shaded {
    ($file:literal) => {
        concat!(
            include_str!("../../shaders/frame.wgsl"),
            "\n",
            include_str!("../../shaders/clay_shading.wgsl"),
            "\n",
            include_str!(concat!("../../shaders/", $file))
        )
    };
}

/// Edge length of the built-in environment sphere map.
const ENVIRONMENT_SIZE_PX: u32 = 256;

/// The sample count to pass to [`SceneRenderer::new`]: 4 when both `format` and the depth
/// format support 4× multisampling (and resolving) on this adapter, else 1.
#[must_use]
pub fn supported_sample_count(adapter: &wgpu::Adapter, format: wgpu::TextureFormat) -> u32 {
    let color = adapter.get_texture_format_features(format).flags;
    let depth = adapter.get_texture_format_features(DEPTH_FORMAT).flags;
    let ok = color.sample_count_supported(PREFERRED_SAMPLES)
        && color.contains(wgpu::TextureFormatFeatureFlags::MULTISAMPLE_RESOLVE)
        && depth.sample_count_supported(PREFERRED_SAMPLES);
    if ok { PREFERRED_SAMPLES } else { 1 }
}

/// Per-frame uniforms; the layout matches `Frame` in `shaders/frame.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
struct FrameUniforms {
    view_proj: [[f32; 4]; 4],
    view: [[f32; 4]; 4],
    eye: [f32; 4],
    light_dir: [[f32; 4]; 2],
    light_color: [[f32; 4]; 2],
    material: [f32; 4],
    params: [f32; 4],
    flags: [u32; 4],
}

impl FrameUniforms {
    fn new(camera: &Camera, aspect: f32, options: &SceneOptions) -> Self {
        let view = camera.view();
        let shading = &options.shading;
        // Lights that follow the camera are given in view space: rotate them into the world.
        let to_world = if shading.lights_follow_camera {
            view.inverse()
        } else {
            Mat4::IDENTITY
        };
        let mut light_dir = [[0.0; 4]; 2];
        let mut light_color = [[0.0; 4]; 2];
        for (i, light) in shading.lights.iter().enumerate() {
            let dir = to_world
                .transform_vector3(light.direction)
                .normalize_or_zero();
            light_dir[i] = dir.extend(0.0).into();
            let c = light
                .color
                .map(|x| if x.is_finite() { x.max(0.0) } else { 0.0 });
            light_color[i] = [c[0], c[1], c[2], 0.0];
        }
        let mode = match shading.environment {
            EnvironmentMode::Off => 0,
            EnvironmentMode::Opaque => 1,
            EnvironmentMode::Transparent => 2,
            EnvironmentMode::ClearCoat => 3,
        };
        let m = shading.material_color;
        Self {
            view_proj: camera.view_projection(aspect).to_cols_array_2d(),
            view: view.to_cols_array_2d(),
            eye: camera.eye().extend(1.0).into(),
            light_dir,
            light_color,
            material: [m[0], m[1], m[2], shading.ambient],
            params: [
                shading.specular,
                shading.shininess.max(1.0),
                shading.environment_opacity.clamp(0.0, 1.0),
                0.0,
            ],
            flags: [mode, 0, 0, 0],
        }
    }
}

/// A growable GPU vertex buffer rewritten each frame (overlay geometry, disc instances): it
/// grows to twice the need when the data does not fit, and is otherwise reused.
struct DynamicBuffer {
    label: &'static str,
    buffer: Option<wgpu::Buffer>,
    count: u32,
}

impl DynamicBuffer {
    const fn new(label: &'static str) -> Self {
        Self {
            label,
            buffer: None,
            count: 0,
        }
    }

    fn write<T: bytemuck::Pod>(&mut self, device: &wgpu::Device, queue: &wgpu::Queue, data: &[T]) {
        self.count = u32::try_from(data.len()).unwrap_or(0);
        if data.is_empty() {
            return;
        }
        let bytes: &[u8] = bytemuck::cast_slice(data);
        let fits = self
            .buffer
            .as_ref()
            .is_some_and(|b| b.size() >= bytes.len() as u64);
        if !fits {
            self.buffer = Some(device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(self.label),
                size: (bytes.len() as u64 * 2).next_multiple_of(4),
                usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }));
        }
        if let Some(b) = &self.buffer {
            queue.write_buffer(b, 0, bytes);
        }
    }
}

/// Size-dependent textures.
struct Targets {
    width: u32,
    height: u32,
    color: wgpu::Texture,
    color_view: wgpu::TextureView,
    msaa_view: Option<wgpu::TextureView>,
    depth_view: wgpu::TextureView,
}

impl Targets {
    fn new(
        device: &wgpu::Device,
        format: wgpu::TextureFormat,
        samples: u32,
        width: u32,
        height: u32,
    ) -> Self {
        let (width, height) = (width.max(1), height.max(1));
        let size = wgpu::Extent3d {
            width,
            height,
            depth_or_array_layers: 1,
        };
        let texture = |label, sample_count, format, usage| {
            device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size,
                mip_level_count: 1,
                sample_count,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage,
                view_formats: &[],
            })
        };
        let color = texture(
            "scene colour",
            1,
            format,
            wgpu::TextureUsages::RENDER_ATTACHMENT
                | wgpu::TextureUsages::TEXTURE_BINDING
                | wgpu::TextureUsages::COPY_SRC,
        );
        let msaa_view = (samples > 1).then(|| {
            texture(
                "scene colour (multisampled)",
                samples,
                format,
                wgpu::TextureUsages::RENDER_ATTACHMENT,
            )
            .create_view(&wgpu::TextureViewDescriptor::default())
        });
        let depth_view = texture(
            "scene depth",
            samples,
            DEPTH_FORMAT,
            wgpu::TextureUsages::RENDER_ATTACHMENT,
        )
        .create_view(&wgpu::TextureViewDescriptor::default());
        Self {
            width,
            height,
            color_view: color.create_view(&wgpu::TextureViewDescriptor::default()),
            color,
            msaa_view,
            depth_view,
        }
    }
}

/// Draws the clay, the tool, the force arrow and the boxes.
pub struct SceneRenderer {
    format: wgpu::TextureFormat,
    samples: u32,
    shading: MeshShading,
    targets: Targets,
    uniforms: wgpu::Buffer,
    bind_group_layout: wgpu::BindGroupLayout,
    bind_group: wgpu::BindGroup,
    sampler: wgpu::Sampler,
    mesh_pipeline: wgpu::RenderPipeline,
    line_pipeline: wgpu::RenderPipeline,
    tool_pipeline: wgpu::RenderPipeline,
    disc_pipeline: wgpu::RenderPipeline,
    discs: DynamicBuffer,
    chunks: ChunkBuffers,
    /// Far bricks' coarse lists, when the settings ask for them.
    level_of_detail: Option<LevelOfDetail>,
    /// What the last [`Self::render`] drew.
    last_draw: DrawReport,
    overlay: OverlayGeometry,
    overlay_lines: DynamicBuffer,
    overlay_triangles: DynamicBuffer,
}

const MESH_ATTRIBUTES: [wgpu::VertexAttribute; 3] =
    wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3, 2 => Float32x4];

impl SceneRenderer {
    /// Builds pipelines and a `width × height` target (each clamped to at least 1) in `format`
    /// with `sample_count` samples per pixel (use [`supported_sample_count`]; any value other
    /// than 1 is treated as 4), shaded per pixel ([`MeshShading::PerPixel`]).
    #[must_use]
    pub fn new(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        format: wgpu::TextureFormat,
        sample_count: u32,
        width: u32,
        height: u32,
    ) -> Self {
        let settings = FrameSettings {
            sample_count,
            shading: MeshShading::PerPixel,
            cull_back_faces: false,
            coarse_far_bricks: false,
        };
        Self::with_settings(device, queue, format, settings, width, height)
    }

    /// As [`Self::new`], with the sample count, the mesh shading and the face culling of
    /// `settings` (a [`super::ProfileChoice`]'s, in the window).
    #[must_use]
    pub fn with_settings(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        format: wgpu::TextureFormat,
        settings: FrameSettings,
        width: u32,
        height: u32,
    ) -> Self {
        let FrameSettings {
            sample_count,
            shading,
            cull_back_faces,
            coarse_far_bricks,
        } = settings;
        let samples = if sample_count > 1 {
            PREFERRED_SAMPLES
        } else {
            1
        };
        let uniforms = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("frame uniforms"),
            size: size_of::<FrameUniforms>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let visible = wgpu::ShaderStages::VERTEX_FRAGMENT;
        let bind_group_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("scene bindings"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: visible,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: wgpu::BufferSize::new(size_of::<FrameUniforms>() as u64),
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 1,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Float { filterable: true },
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 2,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
                    count: None,
                },
            ],
        });
        let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("environment sampler"),
            address_mode_u: wgpu::AddressMode::ClampToEdge,
            address_mode_v: wgpu::AddressMode::ClampToEdge,
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            ..Default::default()
        });
        let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("scene pipeline layout"),
            bind_group_layouts: &[Some(&bind_group_layout)],
            immediate_size: 0,
        });
        let mesh_shader = device.create_shader_module(match shading {
            MeshShading::PerPixel => wgpu::ShaderModuleDescriptor {
                label: Some("mesh.wgsl"),
                source: wgpu::ShaderSource::Wgsl(clay_shaded!("mesh.wgsl").into()),
            },
            MeshShading::VertexLit => wgpu::ShaderModuleDescriptor {
                label: Some("mesh_vertex_lit.wgsl"),
                source: wgpu::ShaderSource::Wgsl(clay_shaded!("mesh_vertex_lit.wgsl").into()),
            },
        });
        let overlay_shader = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("overlay.wgsl"),
            source: wgpu::ShaderSource::Wgsl(framed!("overlay.wgsl").into()),
        });
        let pipeline = |label: &str,
                        module: &wgpu::ShaderModule,
                        stride: usize,
                        topology: wgpu::PrimitiveTopology,
                        cull_mode: Option<wgpu::Face>,
                        depth_write: bool,
                        blend: Option<wgpu::BlendState>| {
            device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some(label),
                layout: Some(&layout),
                vertex: wgpu::VertexState {
                    module,
                    entry_point: Some("vs_main"),
                    compilation_options: wgpu::PipelineCompilationOptions::default(),
                    buffers: &[Some(wgpu::VertexBufferLayout {
                        array_stride: stride as u64,
                        step_mode: wgpu::VertexStepMode::Vertex,
                        attributes: &MESH_ATTRIBUTES,
                    })],
                },
                primitive: wgpu::PrimitiveState {
                    topology,
                    cull_mode,
                    front_face: wgpu::FrontFace::Ccw,
                    ..Default::default()
                },
                depth_stencil: Some(wgpu::DepthStencilState {
                    format: DEPTH_FORMAT,
                    depth_write_enabled: Some(depth_write),
                    depth_compare: Some(wgpu::CompareFunction::LessEqual),
                    stencil: wgpu::StencilState::default(),
                    bias: wgpu::DepthBiasState::default(),
                }),
                multisample: wgpu::MultisampleState {
                    count: samples,
                    ..Default::default()
                },
                fragment: Some(wgpu::FragmentState {
                    module,
                    entry_point: Some("fs_main"),
                    compilation_options: wgpu::PipelineCompilationOptions::default(),
                    targets: &[Some(wgpu::ColorTargetState {
                        format,
                        blend,
                        write_mask: wgpu::ColorWrites::ALL,
                    })],
                }),
                multiview_mask: None,
                cache: None,
            })
        };
        // Same attribute layout for both vertex types (position, normal, colour).
        const _: () = assert!(size_of::<MeshVertex>() == size_of::<OverlayVertex>());
        let mesh_pipeline = pipeline(
            "mesh pass",
            &mesh_shader,
            size_of::<MeshVertex>(),
            wgpu::PrimitiveTopology::TriangleList,
            cull_back_faces.then_some(wgpu::Face::Back),
            true,
            None,
        );
        let line_pipeline = pipeline(
            "overlay lines",
            &overlay_shader,
            size_of::<OverlayVertex>(),
            wgpu::PrimitiveTopology::LineList,
            None,
            true,
            Some(wgpu::BlendState::ALPHA_BLENDING),
        );
        let tool_pipeline = pipeline(
            "overlay see-through tool",
            &overlay_shader,
            size_of::<OverlayVertex>(),
            wgpu::PrimitiveTopology::TriangleList,
            Some(wgpu::Face::Back),
            false,
            Some(wgpu::BlendState::ALPHA_BLENDING),
        );
        let disc_shader = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("discs.wgsl"),
            source: wgpu::ShaderSource::Wgsl(clay_shaded!("discs.wgsl").into()),
        });
        // Splats are lit as the mesh pass lights the clay (`shaders/discs.wgsl`).
        let disc_constants = [(
            "KEY_LIGHT_ONLY",
            if shading == MeshShading::VertexLit {
                1.0
            } else {
                0.0
            },
        )];
        let disc_pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("discs"),
            layout: Some(&layout),
            vertex: wgpu::VertexState {
                module: &disc_shader,
                entry_point: Some("vs_main"),
                compilation_options: wgpu::PipelineCompilationOptions::default(),
                buffers: &[Some(wgpu::VertexBufferLayout {
                    array_stride: size_of::<Disc>() as u64,
                    step_mode: wgpu::VertexStepMode::Instance,
                    attributes: &DISC_ATTRIBUTES,
                })],
            },
            primitive: wgpu::PrimitiveState {
                topology: wgpu::PrimitiveTopology::TriangleList,
                cull_mode: None,
                ..Default::default()
            },
            depth_stencil: Some(wgpu::DepthStencilState {
                format: DEPTH_FORMAT,
                depth_write_enabled: Some(true),
                depth_compare: Some(wgpu::CompareFunction::LessEqual),
                stencil: wgpu::StencilState::default(),
                bias: wgpu::DepthBiasState::default(),
            }),
            multisample: wgpu::MultisampleState {
                count: samples,
                ..Default::default()
            },
            fragment: Some(wgpu::FragmentState {
                module: &disc_shader,
                entry_point: Some("fs_main"),
                compilation_options: wgpu::PipelineCompilationOptions {
                    constants: &disc_constants,
                    ..Default::default()
                },
                targets: &[Some(wgpu::ColorTargetState {
                    format,
                    blend: None,
                    write_mask: wgpu::ColorWrites::ALL,
                })],
            }),
            multiview_mask: None,
            cache: None,
        });
        let env_view =
            upload_environment(device, queue, &EnvironmentMap::studio(ENVIRONMENT_SIZE_PX));
        let bind_group =
            make_bind_group(device, &bind_group_layout, &uniforms, &env_view, &sampler);
        Self {
            format,
            samples,
            shading,
            targets: Targets::new(device, format, samples, width, height),
            uniforms,
            bind_group_layout,
            bind_group,
            sampler,
            mesh_pipeline,
            line_pipeline,
            tool_pipeline,
            disc_pipeline,
            discs: DynamicBuffer::new("discs"),
            chunks: {
                let mut chunks = ChunkBuffers::default();
                chunks.set_build_coarse(coarse_far_bricks);
                chunks
            },
            level_of_detail: coarse_far_bricks.then_some(LevelOfDetail {
                coarse_below_edge_px: COARSE_BELOW_EDGE_PX,
            }),
            last_draw: DrawReport::default(),
            overlay: OverlayGeometry::default(),
            overlay_lines: DynamicBuffer::new("overlay lines"),
            overlay_triangles: DynamicBuffer::new("overlay triangles"),
        }
    }

    /// Resizes the target (each side clamped to at least 1). A no-op when the size is
    /// unchanged; otherwise [`Self::target_view`] is a new view, to be re-registered by a GUI.
    pub fn resize(&mut self, device: &wgpu::Device, width: u32, height: u32) {
        let (width, height) = (width.max(1), height.max(1));
        if (width, height) != (self.targets.width, self.targets.height) {
            self.targets = Targets::new(device, self.format, self.samples, width, height);
        }
    }

    /// As [`Self::resize`], with the new textures made inside wgpu's error scopes: they replace
    /// the old ones only when the GPU made them. Returns whether the size changed.
    ///
    /// # Errors
    /// [`RenderError::OutOfMemory`] or [`RenderError::Gpu`] (a side over the device's texture
    /// limit, say); the renderer keeps its previous size and targets then.
    pub fn try_resize(
        &mut self,
        device: &wgpu::Device,
        width: u32,
        height: u32,
    ) -> Result<bool, RenderError> {
        let (width, height) = (width.max(1), height.max(1));
        if (width, height) == (self.targets.width, self.targets.height) {
            return Ok(false);
        }
        let (format, samples) = (self.format, self.samples);
        self.targets = guarded_on(device, "the view's textures", || {
            Targets::new(device, format, samples, width, height)
        })?;
        Ok(true)
    }

    /// Drops every uploaded chunk; the next [`Self::sync_chunks`] uploads them all again.
    pub fn clear_chunks(&mut self) {
        self.chunks.clear();
    }

    /// Replaces the environment sphere map (for example with a loaded matcap).
    pub fn set_environment(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        map: &EnvironmentMap,
    ) {
        let view = upload_environment(device, queue, map);
        self.bind_group = make_bind_group(
            device,
            &self.bind_group_layout,
            &self.uniforms,
            &view,
            &self.sampler,
        );
    }

    /// Brings the GPU meshes in line with `chunks` (the full current set), uploading only the
    /// chunks whose version changed and dropping those no longer listed.
    ///
    /// # Errors
    /// A malformed chunk or a repeated id; see [`ChunkBuffers::sync`].
    pub fn sync_chunks(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        chunks: &[MeshChunk<'_>],
    ) -> Result<SyncReport, ChunkError> {
        self.chunks.sync(device, queue, chunks)
    }

    /// Replaces the discs (particles, point-set splats) drawn with the clay (empty: none, and
    /// no draw call).
    pub fn set_discs(&mut self, device: &wgpu::Device, queue: &wgpu::Queue, discs: &[Disc]) {
        self.discs.write(device, queue, discs);
    }

    /// Discs drawn per frame.
    #[must_use]
    pub fn disc_count(&self) -> usize {
        self.discs.count as usize
    }

    /// Records one frame into `encoder`: clear, the clay, the discs, overlay lines,
    /// then the see-through tool, all into [`Self::target`]. The caller submits the encoder.
    pub fn render(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        camera: &Camera,
        options: &SceneOptions,
    ) {
        let aspect = self.targets.width as f32 / self.targets.height as f32;
        let uniforms = FrameUniforms::new(camera, aspect, options);
        queue.write_buffer(&self.uniforms, 0, bytemuck::bytes_of(&uniforms));
        self.overlay.rebuild(options);
        self.overlay_lines.write(device, queue, &self.overlay.lines);
        self.overlay_triangles
            .write(device, queue, &self.overlay.triangles);
        let b = options
            .background
            .map(|x| if x.is_finite() { f64::from(x) } else { 0.0 });
        let clear = wgpu::Color {
            r: b[0],
            g: b[1],
            b: b[2],
            a: b[3],
        };

        let t = &self.targets;
        let (view, resolve_target) = match &t.msaa_view {
            Some(msaa) => (msaa, Some(&t.color_view)),
            None => (&t.color_view, None),
        };
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("scene"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view,
                depth_slice: None,
                resolve_target,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(clear),
                    // The multisampled image is only needed until it is resolved.
                    store: if resolve_target.is_some() {
                        wgpu::StoreOp::Discard
                    } else {
                        wgpu::StoreOp::Store
                    },
                },
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &t.depth_view,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(1.0),
                    store: wgpu::StoreOp::Discard,
                }),
                stencil_ops: None,
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_bind_group(0, &self.bind_group, &[]);
        pass.set_pipeline(&self.mesh_pipeline);
        let view = DrawView {
            eye: camera.eye().to_array(),
            pixels_per_unit_at_unit_distance: self.targets.height as f32
                / (2.0 * (0.5 * camera.fov_y_rad).tan()),
        };
        self.last_draw = self.chunks.draw(&mut pass, &view, self.level_of_detail);
        if let (Some(buffer), count @ 1..) = (&self.discs.buffer, self.discs.count) {
            pass.set_pipeline(&self.disc_pipeline);
            pass.set_vertex_buffer(0, buffer.slice(..));
            pass.draw(0..6, 0..count);
        }
        for (pipeline, geometry) in [
            (&self.line_pipeline, &self.overlay_lines),
            (&self.tool_pipeline, &self.overlay_triangles),
        ] {
            if let (Some(buffer), count @ 1..) = (&geometry.buffer, geometry.count) {
                pass.set_pipeline(pipeline);
                pass.set_vertex_buffer(0, buffer.slice(..));
                pass.draw(0..count, 0..1);
            }
        }
    }

    /// What the last [`Self::render`] drew: the triangles its draw calls named and how many
    /// bricks were drawn coarse.
    #[must_use]
    pub fn last_draw(&self) -> DrawReport {
        self.last_draw
    }

    /// The resolved colour texture (`RENDER_ATTACHMENT | TEXTURE_BINDING | COPY_SRC`).
    #[must_use]
    pub fn target(&self) -> &wgpu::Texture {
        &self.targets.color
    }

    /// A view of [`Self::target`], for `egui_wgpu::Renderer::register_native_texture`.
    #[must_use]
    pub fn target_view(&self) -> &wgpu::TextureView {
        &self.targets.color_view
    }

    /// Target size in pixels (never zero).
    #[must_use]
    pub fn size(&self) -> (u32, u32) {
        (self.targets.width, self.targets.height)
    }

    #[must_use]
    pub fn format(&self) -> wgpu::TextureFormat {
        self.format
    }

    /// Samples per pixel in use (1 or 4).
    #[must_use]
    pub fn sample_count(&self) -> u32 {
        self.samples
    }

    /// How the mesh pass lights the clay.
    #[must_use]
    pub fn shading(&self) -> MeshShading {
        self.shading
    }

    /// Upload totals of the chunk store.
    #[must_use]
    pub fn upload_stats(&self) -> UploadStats {
        self.chunks.stats()
    }

    /// Triangles drawn per frame.
    #[must_use]
    pub fn triangle_count(&self) -> usize {
        self.chunks.triangle_count()
    }
}

fn upload_environment(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    map: &EnvironmentMap,
) -> wgpu::TextureView {
    let size = wgpu::Extent3d {
        width: map.size_px.max(1),
        height: map.size_px.max(1),
        depth_or_array_layers: 1,
    };
    let texture = device.create_texture(&wgpu::TextureDescriptor {
        label: Some("environment sphere map"),
        size,
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::Rgba8UnormSrgb,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    });
    queue.write_texture(
        wgpu::TexelCopyTextureInfo {
            texture: &texture,
            mip_level: 0,
            origin: wgpu::Origin3d::ZERO,
            aspect: wgpu::TextureAspect::All,
        },
        &map.rgba8_srgb,
        wgpu::TexelCopyBufferLayout {
            offset: 0,
            bytes_per_row: Some(4 * size.width),
            rows_per_image: Some(size.height),
        },
        size,
    );
    texture.create_view(&wgpu::TextureViewDescriptor::default())
}

fn make_bind_group(
    device: &wgpu::Device,
    layout: &wgpu::BindGroupLayout,
    uniforms: &wgpu::Buffer,
    env_view: &wgpu::TextureView,
    sampler: &wgpu::Sampler,
) -> wgpu::BindGroup {
    device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("scene bindings"),
        layout,
        entries: &[
            wgpu::BindGroupEntry {
                binding: 0,
                resource: uniforms.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 1,
                resource: wgpu::BindingResource::TextureView(env_view),
            },
            wgpu::BindGroupEntry {
                binding: 2,
                resource: wgpu::BindingResource::Sampler(sampler),
            },
        ],
    })
}
