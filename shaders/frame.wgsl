// The per-frame uniforms every scene pass reads (binding 0 of group 0); its layout matches
// `FrameUniforms` in src/render/renderer.rs. Placed before the clay's shading and the overlay
// pass (src/render/renderer.rs joins them), so the layout is written once.

struct Frame {
    view_proj: mat4x4<f32>,
    view: mat4x4<f32>,
    // xyz: eye position in world units.
    eye: vec4<f32>,
    // xyz: world-space unit direction toward each light.
    light_dir: array<vec4<f32>, 2>,
    light_color: array<vec4<f32>, 2>,
    // rgb: unpainted clay colour; a: ambient factor.
    material: vec4<f32>,
    // x: specular strength, y: shininess, z: environment opacity.
    params: vec4<f32>,
    // x: environment mode (0 off, 1 opaque, 2 transparent, 3 clear coat).
    flags: vec4<u32>,
}

@group(0) @binding(0) var<uniform> frame: Frame;
