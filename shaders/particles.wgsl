// Particles on the clay as small discs: one instanced quad per particle, lying in the plane
// the particle's normal defines, cut to a disc in the fragment shader. Unlit, in a fixed
// colour (`PARTICLE_DISC_COLOR` in src/render/particles.rs) with a darker rim, lifted a little
// off the surface along the normal so the clay does not hide it.

struct Frame {
    view_proj: mat4x4<f32>,
    view: mat4x4<f32>,
    eye: vec4<f32>,
    light_dir: array<vec4<f32>, 2>,
    light_color: array<vec4<f32>, 2>,
    material: vec4<f32>,
    params: vec4<f32>,
    flags: vec4<u32>,
}

@group(0) @binding(0) var<uniform> frame: Frame;

const DISC_COLOR: vec3<f32> = vec3<f32>(0.02, 0.60, 0.08);
const RIM_COLOR: vec3<f32> = vec3<f32>(0.005, 0.15, 0.02);
// Lift off the surface, as a fraction of the disc radius.
const LIFT: f32 = 0.25;

struct DiscIn {
    @location(0) centre: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) radius: f32,
}

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) uv: vec2<f32>,
}

@vertex
fn vs_main(@builtin(vertex_index) corner: u32, d: DiscIn) -> VertexOut {
    var corners = array<vec2<f32>, 6>(
        vec2<f32>(-1.0, -1.0), vec2<f32>(1.0, -1.0), vec2<f32>(1.0, 1.0),
        vec2<f32>(-1.0, -1.0), vec2<f32>(1.0, 1.0), vec2<f32>(-1.0, 1.0),
    );
    let uv = corners[corner % 6u];
    var n = d.normal;
    if dot(n, n) < 1e-12 {
        n = vec3<f32>(0.0, 0.0, 1.0);
    }
    n = normalize(n);
    var a = vec3<f32>(1.0, 0.0, 0.0);
    if abs(n.x) > 0.9 {
        a = vec3<f32>(0.0, 1.0, 0.0);
    }
    let t = normalize(cross(n, a));
    let b = cross(n, t);
    let world = d.centre + n * (LIFT * d.radius) + (t * uv.x + b * uv.y) * d.radius;
    var out: VertexOut;
    out.clip = frame.view_proj * vec4<f32>(world, 1.0);
    out.uv = uv;
    return out;
}

@fragment
fn fs_main(v: VertexOut) -> @location(0) vec4<f32> {
    let r2 = dot(v.uv, v.uv);
    if r2 > 1.0 {
        discard;
    }
    if r2 > 0.72 {
        return vec4<f32>(RIM_COLOR, 1.0);
    }
    return vec4<f32>(DISC_COLOR, 1.0);
}
