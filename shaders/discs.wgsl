// Oriented discs (src/render/discs.rs): one instanced quad per disc, lying in the plane the
// disc's normal defines, cut to a disc in the fragment shader. Each disc brings its colour,
// its lift off the surface (a fraction of its radius), where its darker rim starts, and
// whether the scene's lights shade it: particles are unlit green with a rim and lifted so the
// clay does not hide them; point-set splats are lit in their own colour and sit on the surface,
// each pixel with the normal the surface has there to first order (n + W·offset, W the
// normal's gradient the splat carries), ambient plus Lambert.

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

// The rim's colour as a fraction of the disc's.
const RIM_DARKEN: f32 = 0.25;

struct DiscIn {
    @location(0) centre: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) radius: f32,
    @location(3) lift: f32,
    @location(4) colour: vec3<f32>,
    @location(5) rim: f32,
    @location(6) shade: f32,
    // The normal's gradient W (symmetric): diagonal, and (xy, xz, yz) above it.
    @location(7) grad_diag: vec3<f32>,
    @location(8) grad_off: vec3<f32>,
}

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) uv: vec2<f32>,
    @location(1) @interpolate(flat) colour: vec3<f32>,
    @location(2) @interpolate(flat) rim: f32,
    // The world position on the disc.
    @location(3) world: vec3<f32>,
    // n + W·offset, unnormalised: linear in the offset, so its interpolation across the
    // (planar) quad is exact; normalised per pixel.
    @location(4) turned_normal: vec3<f32>,
    @location(5) @interpolate(flat) shade: f32,
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
    let offset = (t * uv.x + b * uv.y) * d.radius;
    let world = d.centre + n * (d.lift * d.radius) + offset;
    var out: VertexOut;
    out.clip = frame.view_proj * vec4<f32>(world, 1.0);
    out.uv = uv;
    out.colour = d.colour;
    out.rim = d.rim;
    out.world = world;
    // W·offset, W symmetric from its diagonal and the entries above it.
    let g = d.grad_diag;
    let o = d.grad_off;
    out.turned_normal = n + vec3<f32>(
        dot(vec3<f32>(g.x, o.x, o.y), offset),
        dot(vec3<f32>(o.x, g.y, o.z), offset),
        dot(vec3<f32>(o.y, o.z, g.z), offset),
    );
    out.shade = d.shade;
    return out;
}

// Ambient plus two-light Lambert on the normal `m`: the clay's diffuse terms, no specular
// (as the software profile's mesh, shaders/mesh_vertex_lit.wgsl, is lit).
fn lambert(albedo: vec3<f32>, m: vec3<f32>) -> vec3<f32> {
    var lit = albedo * frame.material.a;
    for (var i = 0u; i < 2u; i = i + 1u) {
        let l = frame.light_dir[i].xyz;
        lit = lit + frame.light_color[i].rgb * albedo * max(dot(m, l), 0.0);
    }
    return lit;
}

@fragment
fn fs_main(v: VertexOut) -> @location(0) vec4<f32> {
    let r2 = dot(v.uv, v.uv);
    if r2 > 1.0 {
        discard;
    }
    var colour = v.colour;
    if v.shade > 0.0 {
        // The surface's normal at this pixel to first order.
        var m = v.turned_normal;
        if dot(m, m) < 1e-12 {
            m = vec3<f32>(0.0, 0.0, 1.0);
        }
        m = normalize(m);
        // Two-sided: a splat seen from behind is lit as if it faced the viewer.
        if dot(m, frame.eye.xyz - v.world) < 0.0 {
            m = -m;
        }
        colour = mix(colour, lambert(colour, m), v.shade);
    }
    if r2 > v.rim {
        return vec4<f32>(colour * RIM_DARKEN, 1.0);
    }
    return vec4<f32>(colour, 1.0);
}
