// The mesh pass: the clay's brick meshes, lit by two directional lights (Blinn-Phong), with an
// optional sphere-mapped environment layer (opaque, transparent, or angle-dependent clear coat,
// Ferley et al. §5) and per-vertex paint.

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
@group(0) @binding(1) var env_texture: texture_2d<f32>;
@group(0) @binding(2) var env_sampler: sampler;

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

// Unit vector, or `fallback` for a (near) zero input, so no NaN reaches the output.
fn safe_normalize(x: vec3<f32>, fallback: vec3<f32>) -> vec3<f32> {
    let len2 = dot(x, x);
    if (len2 < 1e-20) {
        return fallback;
    }
    return x * inverseSqrt(len2);
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

    var lit = albedo * frame.material.a;
    for (var i = 0u; i < 2u; i = i + 1u) {
        let l = frame.light_dir[i].xyz;
        let n_dot_l = max(dot(n, l), 0.0);
        let h = safe_normalize(l + v, n);
        var spec = 0.0;
        if (n_dot_l > 0.0) {
            spec = frame.params.x * pow(max(dot(n, h), 0.0), frame.params.y);
        }
        lit = lit + frame.light_color[i].rgb * (albedo * n_dot_l + vec3<f32>(spec));
    }

    let mode = frame.flags.x;
    if (mode == 0u) {
        return vec4<f32>(lit, 1.0);
    }

    // Classic sphere mapping of the view-space reflection vector.
    let r_world = reflect(-v, n);
    let r = (frame.view * vec4<f32>(r_world, 0.0)).xyz;
    let m = 2.0 * sqrt(r.x * r.x + r.y * r.y + (r.z + 1.0) * (r.z + 1.0));
    var uv = vec2<f32>(0.5, 0.5);
    if (m > 1e-6) {
        uv = vec2<f32>(r.x / m + 0.5, 0.5 - r.y / m);
    }
    // Explicit level: this runs in non-uniform control flow, where derivatives are undefined.
    let env = textureSampleLevel(env_texture, env_sampler, uv, 0.0).rgb;

    let opacity = clamp(frame.params.z, 0.0, 1.0);
    var alpha = 1.0;
    if (mode == 2u) {
        alpha = opacity;
    } else if (mode == 3u) {
        // Schlick's Fresnel curve: the coat reflects more toward grazing angles.
        let grazing = 1.0 - clamp(dot(n, v), 0.0, 1.0);
        alpha = opacity + (1.0 - opacity) * pow(grazing, 5.0);
    }
    return vec4<f32>(mix(lit, env, alpha), 1.0);
}
