//! What a frame may cost on this adapter: the render profile, chosen once per adapter.
//!
//! A software rasterizer (an adapter whose `wgpu::AdapterInfo::device_type` is `Cpu`: Mesa's
//! lavapipe or llvmpipe, WARP) pays for every sample and every fragment-shader instruction on
//! the same CPU cores the engine needs. On such an adapter the window draws
//! [`RenderProfile::Software`]:
//! - one sample per pixel (no MSAA), and
//! - [`MeshShading::VertexLit`]: ambient plus the diffuse term of the key light (the first of
//!   [`super::Shading::lights`]), evaluated once per vertex and interpolated across the
//!   triangle. No specular highlight, no fill light, no environment layer. Paint still shows.
//! - back faces culled: the mesher winds every triangle counter-clockwise seen from outside, so
//!   on a closed clay only the far side goes. Where a sculpt is cut open at the lattice's border
//!   its inside is not drawn (the opening shows what lies behind it).
//! - far bricks coarse: a brick whose mean edge projects to fewer than
//!   [`COARSE_BELOW_EDGE_PX`] pixels is drawn with its coarse index list (interior vertices
//!   clustered on a grid of two edges, the border kept, `super::lod`), so a dense sculpt seen
//!   whole costs about a third of its triangles; the coarse surface lies within a few pixels'
//!   worth of the fine one, and bricks meet without cracks.
//!
//! Every other adapter draws [`RenderProfile::Full`]: 4× MSAA where the formats allow it,
//! [`MeshShading::PerPixel`] (Blinn-Phong with both lights, and the environment layer), and
//! both faces (an opening shows the clay's inside, lit as if it faced the viewer).
//! The renderer has no shadows or ambient occlusion in either profile. `bench/frame_time.rs`
//! measures both profiles on lavapipe in one run; the figures are in `bench/RESULTS.md`.
//!
//! [`RENDER_PROFILE_ENV`] overrides the detection (`full`, `software` or `auto`), to try the
//! software path on a real GPU or the full one on a software adapter.

use std::fmt;
use std::str::FromStr;

/// In the software profile, a brick whose mean edge projects to fewer pixels than this is
/// drawn coarse (its coarse triangles then span about twice as many).
pub const COARSE_BELOW_EDGE_PX: f32 = 3.0;

/// Samples per pixel when the adapter allows it.
pub const PREFERRED_SAMPLES: u32 = 4;

/// Environment variable that forces a profile: `full`, `software`, or `auto` (the default).
pub const RENDER_PROFILE_ENV: &str = "DYNACLAY_RENDER_PROFILE";

/// How much a frame may cost.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum RenderProfile {
    /// MSAA where supported, per-pixel Blinn-Phong with both lights and the environment, both
    /// faces drawn.
    Full,
    /// One sample per pixel, vertex-lit shading, back faces culled (see the module docs).
    Software,
}

impl RenderProfile {
    /// The profile for an adapter of this kind: [`Self::Software`] for a CPU adapter, else
    /// [`Self::Full`].
    #[must_use]
    pub fn detect(device_type: wgpu::DeviceType) -> Self {
        if device_type == wgpu::DeviceType::Cpu {
            Self::Software
        } else {
            Self::Full
        }
    }

    /// The renderer settings of this profile, given the sample count the adapter supports
    /// (see [`super::supported_sample_count`]).
    #[must_use]
    pub fn settings(self, supported_samples: u32) -> FrameSettings {
        match self {
            Self::Full => FrameSettings {
                sample_count: if supported_samples > 1 {
                    PREFERRED_SAMPLES
                } else {
                    1
                },
                shading: MeshShading::PerPixel,
                cull_back_faces: false,
                coarse_far_bricks: false,
            },
            Self::Software => FrameSettings::SOFTWARE,
        }
    }

    /// `full` or `software`, as [`RENDER_PROFILE_ENV`] spells it.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Full => "full",
            Self::Software => "software",
        }
    }
}

/// How the mesh pass lights the clay.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum MeshShading {
    /// Blinn-Phong per pixel with both lights, plus the environment layer (`shaders/mesh.wgsl`).
    PerPixel,
    /// Ambient plus the key light's diffuse term per vertex, interpolated
    /// (`shaders/mesh_vertex_lit.wgsl`).
    VertexLit,
}

/// What [`super::SceneRenderer::with_settings`] builds its pipelines for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct FrameSettings {
    /// Samples per pixel: 1, or [`PREFERRED_SAMPLES`].
    pub sample_count: u32,
    pub shading: MeshShading,
    /// Whether the mesh pass skips triangles facing away from the viewer (clockwise on
    /// screen). On lavapipe this cuts the 500k-triangle sculpt's scene pass by about 2.5×
    /// (`bench/frame_time.rs`); the cost is that an opening in the clay shows no inside.
    pub cull_back_faces: bool,
    /// Whether bricks far enough that their edges span under [`COARSE_BELOW_EDGE_PX`] pixels
    /// are drawn with their coarse index lists.
    pub coarse_far_bricks: bool,
}

impl FrameSettings {
    /// The software profile's settings: no MSAA, vertex-lit, back faces culled, far bricks
    /// coarse.
    pub const SOFTWARE: Self = Self {
        sample_count: 1,
        shading: MeshShading::VertexLit,
        cull_back_faces: true,
        coarse_far_bricks: true,
    };
}

/// Whether the profile follows the adapter or is forced.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum ProfileRequest {
    /// Detect from the adapter's device type.
    #[default]
    Auto,
    /// Use this profile whatever the adapter.
    Force(RenderProfile),
}

/// A value of [`RENDER_PROFILE_ENV`] that names no profile.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{RENDER_PROFILE_ENV}={value:?} names no render profile: use full, software or auto")]
pub struct UnknownProfile {
    pub value: String,
}

impl FromStr for ProfileRequest {
    type Err = UnknownProfile;

    /// `auto` (or empty), `full` or `software`, in any case, surrounding blanks ignored.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim().to_ascii_lowercase().as_str() {
            "" | "auto" => Ok(Self::Auto),
            "full" => Ok(Self::Force(RenderProfile::Full)),
            "software" => Ok(Self::Force(RenderProfile::Software)),
            _ => Err(UnknownProfile {
                value: s.to_owned(),
            }),
        }
    }
}

impl ProfileRequest {
    /// The request in [`RENDER_PROFILE_ENV`]; [`Self::Auto`] when it is unset.
    ///
    /// # Errors
    /// [`UnknownProfile`] when it is set to something else than `auto`, `full` or `software`.
    pub fn from_env() -> Result<Self, UnknownProfile> {
        std::env::var(RENDER_PROFILE_ENV).map_or(Ok(Self::Auto), |v| v.parse())
    }
}

/// The profile chosen for one adapter, with the facts behind the choice.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ProfileChoice {
    pub profile: RenderProfile,
    pub settings: FrameSettings,
    /// Whether [`RENDER_PROFILE_ENV`] (or a caller) forced the profile.
    pub forced: bool,
    /// The adapter's name as wgpu reports it.
    pub adapter_name: String,
    pub device_type: wgpu::DeviceType,
}

impl ProfileChoice {
    /// Chooses for `adapter` rendering into `format`.
    #[must_use]
    pub fn for_adapter(
        adapter: &wgpu::Adapter,
        format: wgpu::TextureFormat,
        request: ProfileRequest,
    ) -> Self {
        let samples = super::supported_sample_count(adapter, format);
        Self::from_info(&adapter.get_info(), samples, request)
    }

    /// Chooses from the adapter's description and the sample count it supports (a pure
    /// function, for tests without an adapter).
    #[must_use]
    pub fn from_info(
        info: &wgpu::AdapterInfo,
        supported_samples: u32,
        request: ProfileRequest,
    ) -> Self {
        let (profile, forced) = match request {
            ProfileRequest::Auto => (RenderProfile::detect(info.device_type), false),
            ProfileRequest::Force(p) => (p, true),
        };
        Self {
            profile,
            settings: profile.settings(supported_samples),
            forced,
            adapter_name: info.name.clone(),
            device_type: info.device_type,
        }
    }

    /// A few words for the status line: `software render: no MSAA, vertex-lit, back faces
    /// culled` or `MSAA 4×, per-pixel shading`.
    #[must_use]
    pub fn short(&self) -> String {
        let samples = match self.settings.sample_count {
            1 => "no MSAA".to_owned(),
            n => format!("MSAA {n}×"),
        };
        let shading = match self.settings.shading {
            MeshShading::PerPixel => "per-pixel shading",
            MeshShading::VertexLit => "vertex-lit",
        };
        let prefix = match self.profile {
            RenderProfile::Software => "software render: ",
            RenderProfile::Full => "",
        };
        let culling = if self.settings.cull_back_faces {
            ", back faces culled"
        } else {
            ""
        };
        let coarse = if self.settings.coarse_far_bricks {
            ", far bricks coarse"
        } else {
            ""
        };
        format!("{prefix}{samples}, {shading}{culling}{coarse}")
    }
}

impl fmt::Display for ProfileChoice {
    /// One line for the log: the profile, the adapter and why.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let why = if self.forced {
            format!("forced by {RENDER_PROFILE_ENV}")
        } else if self.device_type == wgpu::DeviceType::Cpu {
            "a software adapter".to_owned()
        } else {
            format!("a {:?} adapter", self.device_type)
        };
        write!(
            f,
            "render profile {} on {} ({why}): {}",
            self.profile.name(),
            self.adapter_name,
            self.short()
        )
    }
}
