// The mesh pass of the software profile: the clay lit once per vertex by
// shaders/clay_shading.wgsl's key-light shading (placed before this file), the colour
// interpolated across each triangle (Gouraud). No specular, no fill light, no environment
// layer: a software rasterizer pays for every fragment-shader instruction, and this leaves the
// fragment stage a single select.

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
    let n = safe_normalize(v.normal, vec3<f32>(0.0, 0.0, 0.0));
    let albedo = mix(frame.material.rgb, v.color.rgb, clamp(v.color.a, 0.0, 1.0));
    out.front = shade_clay_key_light(albedo, n);
    // Open brick borders can show the inside: lit as if it faced us, as the full pass does.
    out.back = shade_clay_key_light(albedo, -n);
    return out;
}

@fragment
fn fs_main(in: VertexOut, @builtin(front_facing) front: bool) -> @location(0) vec4<f32> {
    return vec4<f32>(select(in.back, in.front, front), 1.0);
}
