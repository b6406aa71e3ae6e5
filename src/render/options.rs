//! What a frame shows besides the clay: shading settings and the overlays (tool, force, boxes,
//! mirror planes).
//!
//! Plain data, filled in by the app or the CLI each frame; the renderer never keeps a copy.
//! Colours are linear RGBA; positions and lengths are in world units.

use glam::Vec3;

/// How the environment texture is layered over the lit surface (Ferley et al. §5).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum EnvironmentMode {
    /// Blinn-Phong only.
    #[default]
    Off,
    /// The sphere-mapped texture replaces the surface colour: a metallic look.
    Opaque,
    /// The texture is blended over the lit surface with constant opacity
    /// [`Shading::environment_opacity`].
    Transparent,
    /// A clear coat: the texture's opacity rises from `environment_opacity` facing the viewer to
    /// 1 at grazing angles (Schlick's Fresnel curve), like a varnish layer over paint.
    ClearCoat,
}

/// One directional light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Light {
    /// Direction *toward* the light; need not be unit length.
    pub direction: Vec3,
    pub color: [f32; 3],
}

/// Surface shading parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Shading {
    /// Clay colour where no paint covers it (linear RGB).
    pub material_color: [f32; 3],
    pub ambient: f32,
    pub specular: f32,
    /// Blinn-Phong exponent.
    pub shininess: f32,
    pub lights: [Light; 2],
    /// When true the light directions are in view space and move with the viewpoint; when
    /// false they are in world space and stay fixed relative to the sculpture.
    pub lights_follow_camera: bool,
    pub environment: EnvironmentMode,
    /// Opacity of the environment layer in `Transparent` mode, and its opacity at normal
    /// incidence in `ClearCoat` mode, in `[0, 1]`.
    pub environment_opacity: f32,
}

impl Default for Shading {
    fn default() -> Self {
        Self {
            material_color: [0.72, 0.45, 0.32],
            ambient: 0.12,
            specular: 0.35,
            shininess: 48.0,
            lights: [
                Light {
                    direction: Vec3::new(-0.4, 0.6, 1.0),
                    color: [0.9, 0.88, 0.85],
                },
                Light {
                    direction: Vec3::new(0.7, -0.2, 0.4),
                    color: [0.25, 0.27, 0.32],
                },
            ],
            lights_follow_camera: true,
            environment: EnvironmentMode::Off,
            environment_opacity: 0.35,
        }
    }
}

/// How the tool is drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum ToolStyle {
    Hidden,
    /// A see-through shaded sphere.
    #[default]
    Transparent,
    /// Latitude and longitude circles.
    Wireframe,
    /// A small opaque tip at the centre and the reach (the area of influence) as faint
    /// circles, so the work under the tool stays visible.
    TipAndReach,
}

impl ToolStyle {
    /// The tip's radius in [`ToolStyle::TipAndReach`], as a fraction of the reach.
    pub const TIP_FRACTION: f32 = 0.12;
}

/// The tool's bounding sphere as the user sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ToolOverlay {
    pub centre: Vec3,
    pub radius: f32,
    pub style: ToolStyle,
    /// Linear RGBA; alpha is the transparent style's opacity (wireframe lines are opaque).
    pub color: [f32; 4],
}

/// The force on the tool, drawn as an arrow from `origin` along `force_n * length_per_newton`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ForceOverlay {
    pub origin: Vec3,
    pub force_n: Vec3,
    /// World units of arrow per newton.
    pub length_per_newton: f32,
    pub color: [f32; 4],
}

/// An axis-aligned box drawn as its twelve edges.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoxOverlay {
    pub min: Vec3,
    pub max: Vec3,
    pub color: [f32; 4],
}

/// A flat quadrilateral drawn see-through with its outline (a mirror plane across the clay).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QuadOverlay {
    /// The corners in order around the quad.
    pub corners: [Vec3; 4],
    /// Linear RGBA of the fill; the outline takes the same colour opaque.
    pub color: [f32; 4],
}

/// Everything a frame needs besides the meshes and the camera.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SceneOptions {
    /// Clear colour, linear RGBA.
    pub background: [f32; 4],
    pub shading: Shading,
    pub tool: Option<ToolOverlay>,
    pub force: Option<ForceOverlay>,
    /// The sculpting workspace.
    pub workspace_box: Option<BoxOverlay>,
    /// The locally simulated region (Hua & Qin §7.3).
    pub region_box: Option<BoxOverlay>,
    /// The mirror planes of strokes that are on (x, y, z), each across the clay's box.
    pub mirror_planes: [Option<QuadOverlay>; 3],
}

impl Default for SceneOptions {
    fn default() -> Self {
        Self {
            background: [0.02, 0.025, 0.035, 1.0],
            shading: Shading::default(),
            tool: None,
            force: None,
            workspace_box: None,
            region_box: None,
            mirror_planes: [None; 3],
        }
    }
}
