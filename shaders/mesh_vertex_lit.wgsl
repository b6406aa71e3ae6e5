// The mesh pass of the software profile: the clay lit once per vertex by ambient light and the
// key light's diffuse term, the colour interpolated across each triangle (Gouraud). No
// specular, no fill light, no environment layer: a software rasterizer pays for every
// fragment-shader instruction, and this leaves the fragment stage a single select.

struct Frame {
    view_proj: mat4x4<f32>,
    view: mat4x4<f32>,
    // xyz: eye position in world units.
    eye: vec4<f32>,
    // xyz: world-space unit direction toward each light; only the first (key) light is used.
    light_dir: array<vec4<f32>, 2>,
    light_color: array<vec4<f32>, 2>,
    // rgb: unpainted clay colour; a: ambient factor.
    material: vec4<f32>,
    params: vec4<f32>,
    flags: vec4<u32>,
}

@group(0) @binding(0) var<uniform> frame: Frame;

struct VertexIn {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) color: vec4<f32>,
}

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    // The colour seen on the side the normal points to, and on the other side.
    @location(0) front: vec3<f32>,
    @location(1) back: vec3<f32>,
}

@vertex
fn vs_main(v: VertexIn) -> VertexOut {
    var out: VertexOut;
    out.clip = frame.view_proj * vec4<f32>(v.position, 1.0);
    let len2 = dot(v.normal, v.normal);
    var n = vec3<f32>(0.0, 0.0, 0.0);
    if (len2 > 1e-20) {
        n = v.normal * inverseSqrt(len2);
    }
    let albedo = mix(frame.material.rgb, v.color.rgb, clamp(v.color.a, 0.0, 1.0));
    let ambient = albedo * frame.material.a;
    let key = frame.light_color[0].rgb * albedo;
    let n_dot_l = dot(n, frame.light_dir[0].xyz);
    out.front = ambient + key * max(n_dot_l, 0.0);
    // Open brick borders can show the inside: lit as if it faced us, as the full pass does.
    out.back = ambient + key * max(-n_dot_l, 0.0);
    return out;
}

@fragment
fn fs_main(in: VertexOut, @builtin(front_facing) front: bool) -> @location(0) vec4<f32> {
    return vec4<f32>(select(in.back, in.front, front), 1.0);
}
