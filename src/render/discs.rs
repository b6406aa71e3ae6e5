//! Oriented discs drawn over (or instead of) the clay: one instanced quad per [`Disc`], drawn
//! by `shaders/discs.wgsl`, which lays each quad in the plane its normal defines and cuts it
//! to a disc. Two kinds of points use it, each with its own colour, rim, lift and shading:
//!
//! - particles on the clay ([`particle_discs`]): small unlit green discs with a dark rim,
//!   lifted a little off the surface so the clay does not hide them;
//! - point-set splats ([`splat_discs`]): discs in each point's own colour, lit by the
//!   scene's lights, sitting on the surface and large enough to cover it without holes.
//!   Each splat carries its normal's gradient ([`NormalGradient`]); the shader lights every
//!   pixel of the disc with the normal the surface has there to first order,
//!   `normalize(n + W·(x − centre))` (ambient plus Lambert, as before), so overlapping
//!   splats agree where they meet and a curved surface shades smoothly instead of showing
//!   one flat-lit facet per disc (Phong splatting, Botsch et al. 2004).

use glam::Vec3;

use crate::pointset::NormalGradient;

/// The particles' disc colour (linear RGB), a green that neither the clay nor the overlays
/// use.
pub const PARTICLE_DISC_COLOR: [f32; 3] = [0.02, 0.60, 0.08];

/// Disc radius as a fraction of the particle's radius: particles sit about one radius apart,
/// so half-radius discs show each one without covering the clay.
pub const DISC_SCALE: f32 = 0.5;

/// How far a particle's disc sits off the surface along its normal, as a fraction of its
/// radius, so the clay does not hide it.
pub const DISC_LIFT: f32 = 0.25;

/// Where a particle disc's darker rim starts, as a fraction of the squared radius.
pub const PARTICLE_RIM: f32 = 0.72;

/// One disc (the instance layout of `shaders/discs.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Disc {
    /// Centre, world units.
    pub centre: [f32; 3],
    /// Unit normal (the disc's orientation).
    pub normal: [f32; 3],
    /// Radius, world units.
    pub radius: f32,
    /// Offset along the normal, as a fraction of the radius.
    pub lift: f32,
    /// Linear RGB.
    pub colour: [f32; 3],
    /// Squared-radius fraction beyond which the disc is drawn darker (1 or more: no rim).
    pub rim: f32,
    /// 0: unlit (the colour as is); 1: lit by the scene's lights like the clay.
    pub shade: f32,
    /// The normal's gradient `W` (per world unit), diagonal `(Wxx, Wyy, Wzz)`; zero: one
    /// normal over the whole disc.
    pub normal_gradient_diagonal: [f32; 3],
    /// Its entries above the diagonal, `(Wxy, Wxz, Wyz)`.
    pub normal_gradient_off_diagonal: [f32; 3],
    /// How far behind its plane, away from the eye, the disc's rim is taken to lie for the
    /// depth test, as a fraction of its radius; the depth grows with the squared distance
    /// from the centre, so where discs overlap the one whose centre is nearest wins
    /// ([`SPLAT_RIM_DEPTH`]); 0: the plane's depth.
    pub rim_depth: f32,
    /// 1: the disc is drawn only from the side its normal points to ([`splat_discs`]); 0:
    /// from both sides.
    pub one_sided: u32,
}

pub(crate) const DISC_ATTRIBUTES: [wgpu::VertexAttribute; 11] = wgpu::vertex_attr_array![
    0 => Float32x3, 1 => Float32x3, 2 => Float32, 3 => Float32, 4 => Float32x3,
    5 => Float32, 6 => Float32, 7 => Float32x3, 8 => Float32x3, 9 => Float32, 10 => Uint32
];

/// A splat's [`Disc::rim_depth`]. Overlapping splats of a convex surface (a groove's rounded
/// rim) all stand above it, and with their planes' depths the farthest one's rim is
/// nearest the eye and wins: a flat-top splat reaching over the rim paints its flat shading
/// there, with a sharp step where it ends. Pushing each pixel back by `rim_depth · r · (d/r)²`
/// (`d` its distance from the centre) lets the splat centred nearest win instead: a disc of
/// radius `r` on a surface of curvature `κ` stands `κ d² / 2` above it at `d`, under the push
/// wherever `κ r ≤ 2 · rim_depth`; the follower keeps `κ r` to 0.5 where coverage allows
/// (`dynaclay_import`'s `DISC_CURVATURE_RADII`). The cost: a surface less than `rim_depth · r` behind a splat's rim may show through
/// it (the visibility splatting tolerance of Botsch et al. 2004). That surface is the clay's
/// far side wherever a wall is thinner than the push (a groove's end beside the block's
/// side), so splats are one-sided ([`Disc::one_sided`]): the points follow a closed clay,
/// and a splat seen from behind is always on its far side (back-face culling, as surface
/// splatting does).
pub const SPLAT_RIM_DEPTH: f32 = 0.5;

fn usable(p: Vec3, n: Vec3, r: f32) -> bool {
    p.is_finite() && n.is_finite() && r.is_finite() && r > 0.0
}

/// Appends one disc per particle (radius [`DISC_SCALE`] times the particle's), skipping
/// particles with a non-finite position or radius; the three slices are read up to the
/// shortest.
pub fn particle_discs(out: &mut Vec<Disc>, positions: &[Vec3], normals: &[Vec3], radii: &[f32]) {
    out.extend(
        positions
            .iter()
            .zip(normals)
            .zip(radii)
            .filter(|((p, n), r)| usable(**p, **n, **r))
            .map(|((p, n), r)| Disc {
                centre: p.to_array(),
                normal: n.to_array(),
                radius: r * DISC_SCALE,
                lift: DISC_LIFT,
                colour: PARTICLE_DISC_COLOR,
                rim: PARTICLE_RIM,
                shade: 0.0,
                normal_gradient_diagonal: [0.0; 3],
                normal_gradient_off_diagonal: [0.0; 3],
                rim_depth: 0.0,
                one_sided: 0,
            }),
    );
}

/// An 8-bit sRGB channel in linear light.
#[must_use]
pub fn srgb8_to_linear(c: u8) -> f32 {
    let c = f32::from(c) / 255.0;
    if c <= 0.040_45 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// Appends one splat per point: its colour (8-bit sRGB), its normal, its radius and how its
/// normal turns across it, lit, no rim, on the surface, one-sided; points with a non-finite position or
/// radius are skipped. The first four slices are read up to the shortest; a point past the
/// end of `normal_gradients`, or with a non-finite one, is lit with its one normal.
pub fn splat_discs(
    out: &mut Vec<Disc>,
    positions: &[Vec3],
    normals: &[Vec3],
    colours: &[[u8; 3]],
    radii: &[f32],
    normal_gradients: &[NormalGradient],
) {
    out.extend(
        positions
            .iter()
            .zip(normals)
            .zip(colours)
            .zip(radii)
            .enumerate()
            .filter(|(_, (((p, n), _), r))| usable(**p, **n, **r))
            .map(|(i, (((p, n), c), r))| {
                let w = normal_gradients
                    .get(i)
                    .filter(|w| w.is_finite())
                    .copied()
                    .unwrap_or(NormalGradient::FLAT);
                Disc {
                    centre: p.to_array(),
                    normal: n.to_array(),
                    radius: *r,
                    lift: 0.0,
                    colour: c.map(srgb8_to_linear),
                    rim: 2.0,
                    shade: 1.0,
                    normal_gradient_diagonal: w.diagonal_per_fu.to_array(),
                    normal_gradient_off_diagonal: w.off_diagonal_per_fu.to_array(),
                    rim_depth: SPLAT_RIM_DEPTH,
                    one_sided: 1,
                }
            }),
    );
}

#[cfg(test)]
mod tests {
    use super::*;
    use bytemuck::Zeroable;

    #[test]
    fn discs_take_half_the_radius_and_skip_bad_particles() {
        let mut out = Vec::new();
        particle_discs(
            &mut out,
            &[Vec3::X, Vec3::splat(f32::NAN), Vec3::Y],
            &[Vec3::Z, Vec3::Z, Vec3::Z],
            &[0.2, 0.2, 0.4],
        );
        assert_eq!(out.len(), 2);
        assert_eq!(out[0].centre, [1.0, 0.0, 0.0]);
        assert!((out[1].radius - 0.4 * DISC_SCALE).abs() < 1e-7);
        assert_eq!(out[0].colour, PARTICLE_DISC_COLOR);
        assert_eq!(
            out[0].rim_depth, 0.0,
            "particles are drawn at their plane's depth"
        );
        assert_eq!(out[0].one_sided, 0, "particles are seen from both sides");
    }

    #[test]
    fn splats_keep_their_colour_radius_and_normal_and_append() {
        let mut out = vec![Disc::zeroed()];
        splat_discs(
            &mut out,
            &[Vec3::X, Vec3::Y, Vec3::splat(f32::INFINITY)],
            &[Vec3::Z, Vec3::X, Vec3::Z],
            &[[255, 0, 0], [0, 128, 255], [1, 2, 3]],
            &[0.1, 0.2, 0.3],
            &[NormalGradient {
                diagonal_per_fu: Vec3::new(1.0, 2.0, 3.0),
                off_diagonal_per_fu: Vec3::new(4.0, 5.0, 6.0),
            }],
        );
        assert_eq!(
            out.len(),
            3,
            "appended after the one there, the bad one skipped"
        );
        assert_eq!(out[1].colour, [1.0, 0.0, 0.0]);
        assert!(
            (out[2].colour[1] - 0.2158).abs() < 1e-3,
            "{:?}",
            out[2].colour
        );
        assert_eq!(out[2].normal, [1.0, 0.0, 0.0]);
        assert_eq!(out[2].radius, 0.2);
        assert!(out[1].rim > 1.0 && out[1].shade == 1.0 && out[1].lift == 0.0);
        assert_eq!(out[1].rim_depth, SPLAT_RIM_DEPTH);
        assert_eq!(
            out[1].one_sided, 1,
            "splats are seen from their normal's side only"
        );
        assert_eq!(out[1].normal_gradient_diagonal, [1.0, 2.0, 3.0]);
        assert_eq!(out[1].normal_gradient_off_diagonal, [4.0, 5.0, 6.0]);
        assert_eq!(
            out[2].normal_gradient_diagonal, [0.0; 3],
            "past the gradients' end: one normal"
        );
    }
}
