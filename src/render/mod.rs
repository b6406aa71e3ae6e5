//! The wgpu renderer: brick meshes, Blinn-Phong and environment shading (vertex-lit on software
//! adapters), overlays, offscreen PNGs.

mod camera;
mod chunk;
mod context;
mod discs;
mod environment;
mod error;
mod faults;
mod from_mesh;
mod gpu_chunks;
mod image;
mod lod;
mod offscreen;
mod options;
mod overlay;
mod profile;
mod renderer;
mod trackball;

pub use camera::{Camera, NamedView, UnknownView};
pub use chunk::{ChunkError, MeshChunk, bounds_of};
pub use context::{AdapterSummary, GpuContext, REQUIRE_GPU_ENV, gpu_required};
pub use discs::{
    DISC_LIFT, DISC_SCALE, Disc, PARTICLE_DISC_COLOR, PARTICLE_RIM, SPLAT_RIM_DEPTH,
    particle_discs, splat_discs, srgb8_to_linear,
};
pub use environment::{EnvironmentMap, EnvironmentSizeError, linear_to_srgb8};
pub use error::RenderError;
pub use faults::{GpuFaultLog, PRINTED_ERRORS, guarded_on};
pub use from_mesh::{
    ChunkMesh, MASK_TINT_OPACITY, MASK_TINT_RGB, MIN_PAINT_COVERAGE, brick_id, chunk_views,
    octree_chunks, paint_colors, surface_colors, tinted,
};
pub use gpu_chunks::{
    COARSE_CLUSTER_EDGES, COARSE_MIN_TRIANGLES, ChunkBuffers, DrawReport, DrawView, LevelOfDetail,
    MeshVertex, SyncReport, UploadStats,
};
pub use image::Image;
pub use lod::{coarse_indices, mean_edge_length};
pub use offscreen::{
    OFFSCREEN_FORMAT, OffscreenRenderer, RenderOutcome, render_to_png, scene_camera,
};
pub use options::{
    BoxOverlay, EnvironmentMode, ForceOverlay, Light, QuadOverlay, SceneOptions, Shading,
    ToolOverlay, ToolStyle,
};
pub use overlay::{OverlayGeometry, OverlayVertex};
pub use profile::{
    COARSE_BELOW_EDGE_PX, FrameSettings, MeshShading, PREFERRED_SAMPLES, ProfileChoice,
    ProfileRequest, RENDER_PROFILE_ENV, RenderProfile, UnknownProfile,
};
pub use renderer::{DEPTH_FORMAT, SceneRenderer, supported_sample_count};
pub use trackball::Trackball;

#[cfg(test)]
mod render_tests;
