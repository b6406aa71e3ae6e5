// The mesh pass: the clay's brick meshes, lit per pixel by shaders/clay_shading.wgsl (placed
// before this file): two directional lights (Blinn-Phong), with an optional sphere-mapped
// environment layer (opaque, transparent, or angle-dependent clear coat, Ferley et al. §5)
// and per-vertex paint.

struct VertexIn {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) color: vec4<f32>,
}

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) color: vec4<f32>,
}

@vertex
fn vs_main(v: VertexIn) -> VertexOut {
    var out: VertexOut;
    out.clip = frame.view_proj * vec4<f32>(v.position, 1.0);
    out.world = v.position;
    out.normal = v.normal;
    out.color = v.color;
    return out;
}

@fragment
fn fs_main(in: VertexOut, @builtin(front_facing) front: bool) -> @location(0) vec4<f32> {
    let v = safe_normalize(frame.eye.xyz - in.world, vec3<f32>(0.0, 0.0, 1.0));
    var n = safe_normalize(in.normal, v);
    // Open brick borders can show the inside: light the back face as if it faced us.
    if (!front) {
        n = -n;
    }
    let albedo = mix(frame.material.rgb, in.color.rgb, clamp(in.color.a, 0.0, 1.0));
    return vec4<f32>(shade_clay(albedo, n, v), 1.0);
}
