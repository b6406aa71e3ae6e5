// The clay's lighting, one formula for every pass that draws the clay's surface: the mesh
// passes (shaders/mesh.wgsl, shaders/mesh_vertex_lit.wgsl) and the point-set splats
// (shaders/discs.wgsl) are each this file followed by their own stages (src/render/
// renderer.rs joins them), so a splat and the triangle under it are lit alike: the same
// ambient, lights, specular and environment layer, never two copies that drift apart.

// `Frame` and `frame` (binding 0) come from shaders/frame.wgsl, placed before this file.
@group(0) @binding(1) var env_texture: texture_2d<f32>;
@group(0) @binding(2) var env_sampler: sampler;

// Unit vector, or `fallback` for a (near) zero input, so no NaN reaches the output.
fn safe_normalize(x: vec3<f32>, fallback: vec3<f32>) -> vec3<f32> {
    let len2 = dot(x, x);
    if (len2 < 1e-20) {
        return fallback;
    }
    return x * inverseSqrt(len2);
}

// The full shading (the full profile): ambient, both lights' Lambert and Blinn-Phong terms,
// then the environment layer (Ferley et al. §5), for the unit normal `n` facing the viewer
// and the unit direction `v` toward the eye.
fn shade_clay(albedo: vec3<f32>, n: vec3<f32>, v: vec3<f32>) -> vec3<f32> {
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
        return lit;
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
    return mix(lit, env, alpha);
}

// The software profile's shading: ambient plus the key light's diffuse term, no specular,
// no fill light, no environment layer, for the unit (or zero) normal `n`.
fn shade_clay_key_light(albedo: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    let key = frame.light_color[0].rgb * albedo;
    return albedo * frame.material.a + key * max(dot(n, frame.light_dir[0].xyz), 0.0);
}
