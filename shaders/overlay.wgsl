// The overlay pass: workspace and region boxes, the force arrow and the tool wireframe as lines
// (unlit, zero normal), and the see-through tool sphere as alpha-blended triangles.

// `Frame` and `frame` (binding 0) come from shaders/frame.wgsl, placed before this file.

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
fn fs_main(in: VertexOut) -> @location(0) vec4<f32> {
    let len2 = dot(in.normal, in.normal);
    if (len2 < 0.25) {
        return in.color;
    }
    let n = in.normal * inverseSqrt(len2);
    let to_eye = frame.eye.xyz - in.world;
    let v = to_eye * inverseSqrt(max(dot(to_eye, to_eye), 1e-20));
    let facing = abs(dot(n, v));
    // Brighter facing the viewer, more opaque at the rim: the sphere's outline stays readable.
    let rgb = in.color.rgb * (0.45 + 0.55 * facing);
    let alpha = clamp(in.color.a * (1.0 + 1.5 * (1.0 - facing)), 0.0, 1.0);
    return vec4<f32>(rgb, alpha);
}
