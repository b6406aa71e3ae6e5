// Oriented discs (src/render/discs.rs): one instanced quad per disc, lying in the plane the
// disc's normal defines, cut to a disc in the fragment shader; shaders/clay_shading.wgsl is
// placed before this file. Each disc brings its colour, its lift off the surface (a fraction
// of its radius), where its darker rim starts, and whether the scene's lights shade it:
// particles are unlit green with a rim and lifted so the clay does not hide them; point-set
// splats sit on the surface and are lit as the clay's mesh is (the same shading, chosen by
// KEY_LIGHT_ONLY as the mesh pass is), each pixel with the normal the surface has there to
// first order (n + W·offset, W the normal's gradient the splat carries), each pixel's
// depth pushed back with its squared distance from the centre, so where splats overlap the
// one centred nearest is seen, and only from the side their normal points to.

// The rim's colour as a fraction of the disc's.
const RIM_DARKEN: f32 = 0.25;

// Set by the pipeline: true where the mesh pass is the software profile's
// (shaders/mesh_vertex_lit.wgsl), so splats get its key-light shading rather than the full
// one.
override KEY_LIGHT_ONLY: bool = false;

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
    // How far behind its plane the rim is for the depth test, a fraction of the radius.
    @location(9) rim_depth: f32,
    // 1: drawn only from the side the normal points to (splats of the closed clay).
    @location(10) one_sided: u32,
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
    // rim_depth × radius: the push away from the eye at the rim, world units.
    @location(6) @interpolate(flat) rim_push: f32,
    @location(7) @interpolate(flat) one_sided: u32,
}

struct FragmentOut {
    @location(0) colour: vec4<f32>,
    @builtin(frag_depth) depth: f32,
}

@vertex
fn vs_main(@builtin(vertex_index) corner: u32, d: DiscIn) -> VertexOut {
    var corners = array<vec2<f32>, 6>(
        vec2<f32>(-1.0, -1.0), vec2<f32>(1.0, -1.0), vec2<f32>(1.0, 1.0),
        vec2<f32>(-1.0, -1.0), vec2<f32>(1.0, 1.0), vec2<f32>(-1.0, 1.0),
    );
    let uv = corners[corner % 6u];
    let n = safe_normalize(d.normal, vec3<f32>(0.0, 0.0, 1.0));
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
    out.rim_push = max(d.rim_depth, 0.0) * d.radius;
    out.one_sided = d.one_sided;
    return out;
}

@fragment
fn fs_main(v: VertexOut, @builtin(front_facing) front: bool) -> FragmentOut {
    let r2 = dot(v.uv, v.uv);
    if r2 > 1.0 {
        discard;
    }
    // A one-sided disc seen from behind lies on the clay's far side, behind a wall: not drawn,
    // so where the wall is thinner than the near splats' rim push it does not show through.
    if !front && v.one_sided != 0u {
        discard;
    }
    let to_eye = safe_normalize(frame.eye.xyz - v.world, vec3<f32>(0.0, 0.0, 1.0));
    // The depth of the point pushed back along the ray through this pixel by rim_push times
    // the squared distance from the centre (in radii): where discs overlap, the one centred
    // nearest wins (src/render/discs.rs, SPLAT_RIM_DEPTH).
    let behind = frame.view_proj * vec4<f32>(v.world - to_eye * (v.rim_push * r2), 1.0);
    var out: FragmentOut;
    out.depth = clamp(behind.z / behind.w, 0.0, 1.0);
    var colour = v.colour;
    if v.shade > 0.0 {
        // The surface's normal at this pixel to first order.
        var m = safe_normalize(v.turned_normal, to_eye);
        // A two-sided disc, as the mesh: seen from behind, it is lit as if it faced the viewer.
        // The disc's side decides, not the turned normal's, so a pixel whose normal turns a
        // little past the silhouette is lit as the mesh's pixel there is, not flipped over.
        if !front {
            m = -m;
        }
        var lit: vec3<f32>;
        if KEY_LIGHT_ONLY {
            lit = shade_clay_key_light(colour, m);
        } else {
            lit = shade_clay(colour, m, to_eye);
        }
        colour = mix(colour, lit, v.shade);
    }
    if r2 > v.rim {
        colour = colour * RIM_DARKEN;
    }
    out.colour = vec4<f32>(colour, 1.0);
    return out;
}
