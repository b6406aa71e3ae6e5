//! CPU geometry for the overlays: box edges, mirror planes, the force arrow and the tool
//! sphere.
//!
//! Rebuilt every frame into reused vectors (no allocation once they have grown). Lines are
//! vertex pairs for a line list; the transparent tool is a triangle list with normals. Overlays
//! with non-finite or degenerate input are skipped rather than drawn wrong.

use glam::Vec3;

use super::options::{BoxOverlay, ForceOverlay, QuadOverlay, SceneOptions, ToolOverlay, ToolStyle};

/// One overlay vertex. A zero normal means "unlit" (lines).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct OverlayVertex {
    pub position: [f32; 3],
    pub normal: [f32; 3],
    pub color: [f32; 4],
}

/// Overlay vertices for one frame.
#[derive(Clone, Debug, Default)]
pub struct OverlayGeometry {
    /// Line list (pairs of vertices).
    pub lines: Vec<OverlayVertex>,
    /// Triangle list of see-through surfaces.
    pub triangles: Vec<OverlayVertex>,
}

/// Segments around a circle of the wire and shaded tool spheres.
const SPHERE_SEGMENTS: usize = 32;
/// Rings of latitude of the shaded tool sphere.
const SPHERE_RINGS: usize = 16;

impl OverlayGeometry {
    /// Refills the vertex lists from `options`.
    pub fn rebuild(&mut self, options: &SceneOptions) {
        self.lines.clear();
        self.triangles.clear();
        for b in [options.workspace_box, options.region_box]
            .into_iter()
            .flatten()
        {
            self.push_box(&b);
        }
        for q in options.mirror_planes.iter().flatten() {
            self.push_quad(q);
        }
        if let Some(f) = options.force {
            self.push_arrow(&f);
        }
        if let Some(t) = options.tool {
            match t.style {
                ToolStyle::Hidden => {}
                ToolStyle::Wireframe => self.push_wire_sphere(&t),
                ToolStyle::Transparent => self.push_shaded_sphere(&t),
                ToolStyle::TipAndReach => {
                    let [r, g, b, _] = t.color;
                    self.push_wire_sphere(&ToolOverlay {
                        color: [r, g, b, 0.5],
                        ..t
                    });
                    self.push_shaded_sphere(&ToolOverlay {
                        radius: t.radius * ToolStyle::TIP_FRACTION,
                        color: [r, g, b, 1.0],
                        ..t
                    });
                }
            }
        }
    }

    fn line(&mut self, a: Vec3, b: Vec3, color: [f32; 4]) {
        for p in [a, b] {
            self.lines.push(OverlayVertex {
                position: p.into(),
                normal: [0.0; 3],
                color,
            });
        }
    }

    fn push_box(&mut self, b: &BoxOverlay) {
        if !(b.min.is_finite() && b.max.is_finite()) {
            return;
        }
        let corner = |i: usize| {
            Vec3::new(
                if i & 1 == 0 { b.min.x } else { b.max.x },
                if i & 2 == 0 { b.min.y } else { b.max.y },
                if i & 4 == 0 { b.min.z } else { b.max.z },
            )
        };
        // The twelve edges join corners whose indices differ in exactly one bit.
        for i in 0..8 {
            for bit in [1, 2, 4] {
                if i & bit == 0 {
                    self.line(corner(i), corner(i | bit), b.color);
                }
            }
        }
    }

    /// A see-through quad (both windings, so the culled pipeline shows it from either side)
    /// and its outline, unlit.
    fn push_quad(&mut self, q: &QuadOverlay) {
        if !q.corners.iter().all(|c| c.is_finite()) {
            return;
        }
        let [r, g, b, _] = q.color;
        for i in 0..4 {
            self.line(q.corners[i], q.corners[(i + 1) % 4], [r, g, b, 1.0]);
        }
        let [a, b2, c, d] = q.corners;
        for triangle in [[a, b2, c], [a, c, d], [a, c, b2], [a, d, c]] {
            for p in triangle {
                self.triangles.push(OverlayVertex {
                    position: p.into(),
                    normal: [0.0; 3],
                    color: q.color,
                });
            }
        }
    }

    fn push_arrow(&mut self, f: &ForceOverlay) {
        let v = f.force_n * f.length_per_newton;
        let len = v.length();
        if !(f.origin.is_finite() && len.is_finite()) || len < 1.0e-9 {
            return;
        }
        let tip = f.origin + v;
        let dir = v / len;
        let head_len = 0.25 * len;
        let head_radius = 0.08 * len;
        let base = tip - dir * head_len;
        let (u, w) = dir.any_orthonormal_pair();
        self.line(f.origin, tip, f.color);
        const SPOKES: usize = 8;
        let ring = |k: usize| {
            let a = std::f32::consts::TAU * k as f32 / SPOKES as f32;
            base + (u * a.cos() + w * a.sin()) * head_radius
        };
        for k in 0..SPOKES {
            self.line(tip, ring(k), f.color);
            self.line(ring(k), ring(k + 1), f.color);
        }
    }

    fn push_wire_sphere(&mut self, t: &ToolOverlay) {
        if !valid_sphere(t) {
            return;
        }
        let point = |theta: f32, phi: f32| {
            t.centre
                + t.radius
                    * Vec3::new(
                        theta.sin() * phi.cos(),
                        theta.cos(),
                        theta.sin() * phi.sin(),
                    )
        };
        let step = std::f32::consts::TAU / SPHERE_SEGMENTS as f32;
        // Wire lines are thin: draw them opaque, whatever the see-through opacity is.
        let color = [t.color[0], t.color[1], t.color[2], 1.0];
        // Three latitudes and four meridians read as a sphere without clutter.
        for lat in 1..4 {
            let theta = std::f32::consts::PI * lat as f32 / 4.0;
            for s in 0..SPHERE_SEGMENTS {
                self.line(
                    point(theta, s as f32 * step),
                    point(theta, (s + 1) as f32 * step),
                    color,
                );
            }
        }
        for m in 0..4 {
            let phi = std::f32::consts::PI * m as f32 / 4.0;
            for s in 0..SPHERE_SEGMENTS {
                self.line(
                    point(s as f32 * step, phi),
                    point((s + 1) as f32 * step, phi),
                    color,
                );
            }
        }
    }

    fn push_shaded_sphere(&mut self, t: &ToolOverlay) {
        if !valid_sphere(t) {
            return;
        }
        let normal = |ring: usize, seg: usize| {
            let theta = std::f32::consts::PI * ring as f32 / SPHERE_RINGS as f32;
            let phi = std::f32::consts::TAU * seg as f32 / SPHERE_SEGMENTS as f32;
            Vec3::new(
                theta.sin() * phi.cos(),
                theta.cos(),
                theta.sin() * phi.sin(),
            )
        };
        let vertex = |n: Vec3| OverlayVertex {
            position: (t.centre + n * t.radius).into(),
            normal: n.into(),
            color: t.color,
        };
        for ring in 0..SPHERE_RINGS {
            for seg in 0..SPHERE_SEGMENTS {
                let a = normal(ring, seg);
                let b = normal(ring + 1, seg);
                let c = normal(ring + 1, seg + 1);
                let d = normal(ring, seg + 1);
                // Counter-clockwise seen from outside.
                for n in [a, d, b, b, d, c] {
                    self.triangles.push(vertex(n));
                }
            }
        }
    }
}

fn valid_sphere(t: &ToolOverlay) -> bool {
    t.centre.is_finite() && t.radius.is_finite() && t.radius > 0.0
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::options::SceneOptions;

    #[test]
    fn box_has_twelve_edges_of_the_right_lengths() {
        let mut g = OverlayGeometry::default();
        let opts = SceneOptions {
            workspace_box: Some(BoxOverlay {
                min: Vec3::ZERO,
                max: Vec3::new(1.0, 2.0, 3.0),
                color: [1.0; 4],
            }),
            ..SceneOptions::default()
        };
        g.rebuild(&opts);
        assert_eq!(g.lines.len(), 24);
        let mut total = 0.0;
        for pair in g.lines.chunks(2) {
            total += (Vec3::from(pair[0].position) - Vec3::from(pair[1].position)).length();
        }
        assert!((total - 4.0 * (1.0 + 2.0 + 3.0)).abs() < 1e-5);
        assert!(g.triangles.is_empty());
    }

    #[test]
    fn arrow_tip_is_at_origin_plus_scaled_force() {
        let mut g = OverlayGeometry::default();
        let f = ForceOverlay {
            origin: Vec3::new(1.0, 0.0, 0.0),
            force_n: Vec3::new(0.0, 4.0, 0.0),
            length_per_newton: 0.5,
            color: [1.0; 4],
        };
        g.rebuild(&SceneOptions {
            force: Some(f),
            ..SceneOptions::default()
        });
        assert_eq!(g.lines[1].position, [1.0, 2.0, 0.0]);
        let max_y = g
            .lines
            .iter()
            .map(|v| v.position[1])
            .fold(f32::MIN, f32::max);
        assert!((max_y - 2.0).abs() < 1e-6, "nothing overshoots the tip");
        g.rebuild(&SceneOptions {
            force: Some(ForceOverlay {
                force_n: Vec3::ZERO,
                ..f
            }),
            ..SceneOptions::default()
        });
        assert!(g.lines.is_empty(), "a zero force draws nothing");
    }

    #[test]
    fn tool_sphere_vertices_lie_on_the_sphere() {
        let mut g = OverlayGeometry::default();
        let mut tool = ToolOverlay {
            centre: Vec3::new(0.5, -1.0, 2.0),
            radius: 0.25,
            style: ToolStyle::Transparent,
            color: [0.2, 0.6, 1.0, 0.3],
        };
        for style in [ToolStyle::Transparent, ToolStyle::Wireframe] {
            tool.style = style;
            g.rebuild(&SceneOptions {
                tool: Some(tool),
                ..SceneOptions::default()
            });
            let verts = if style == ToolStyle::Transparent {
                &g.triangles
            } else {
                &g.lines
            };
            assert!(!verts.is_empty());
            for v in verts {
                let r = (Vec3::from(v.position) - tool.centre).length();
                assert!((r - tool.radius).abs() < 1e-5);
            }
        }
        tool.style = ToolStyle::Hidden;
        g.rebuild(&SceneOptions {
            tool: Some(tool),
            ..SceneOptions::default()
        });
        assert!(g.lines.is_empty() && g.triangles.is_empty());
        tool.style = ToolStyle::Transparent;
        tool.radius = f32::NAN;
        g.rebuild(&SceneOptions {
            tool: Some(tool),
            ..SceneOptions::default()
        });
        assert!(g.triangles.is_empty());
    }

    /// The tip-and-reach style: the reach as opaque-free circles on the full radius, and a
    /// small opaque tip at the centre, so the clay under the tool stays visible.
    #[test]
    fn tip_and_reach_draws_a_small_opaque_tip_inside_reach_circles() {
        let tool = ToolOverlay {
            centre: Vec3::new(0.5, -1.0, 2.0),
            radius: 0.25,
            style: ToolStyle::TipAndReach,
            color: [0.9, 0.35, 0.2, 0.3],
        };
        let mut g = OverlayGeometry::default();
        g.rebuild(&SceneOptions {
            tool: Some(tool),
            ..SceneOptions::default()
        });
        assert!(!g.lines.is_empty() && !g.triangles.is_empty());
        for v in &g.lines {
            let r = (Vec3::from(v.position) - tool.centre).length();
            assert!((r - tool.radius).abs() < 1e-5);
        }
        let tip = tool.radius * ToolStyle::TIP_FRACTION;
        for v in &g.triangles {
            let r = (Vec3::from(v.position) - tool.centre).length();
            assert!((r - tip).abs() < 1e-5);
            assert_eq!(v.color[3], 1.0, "the tip is opaque");
        }
    }

    #[test]
    fn a_mirror_plane_is_a_two_sided_unlit_quad_with_its_outline() {
        let corners = [
            Vec3::new(0.0, -1.0, -1.0),
            Vec3::new(0.0, 1.0, -1.0),
            Vec3::new(0.0, 1.0, 1.0),
            Vec3::new(0.0, -1.0, 1.0),
        ];
        let mut g = OverlayGeometry::default();
        g.rebuild(&SceneOptions {
            mirror_planes: [
                Some(QuadOverlay {
                    corners,
                    color: [0.4, 0.6, 1.0, 0.2],
                }),
                None,
                None,
            ],
            ..SceneOptions::default()
        });
        assert_eq!(g.lines.len(), 8, "four outline edges");
        assert!(g.lines.iter().all(|v| v.color[3] == 1.0));
        assert_eq!(g.triangles.len(), 12, "two triangles each way round");
        assert!(
            g.triangles
                .iter()
                .all(|v| v.normal == [0.0; 3] && v.position[0] == 0.0)
        );
        // Each winding covers the quad once: signed areas along +x sum to +4 and -4.
        let area = |t: &[OverlayVertex]| {
            let p = |i: usize| Vec3::from(t[i].position);
            0.5 * (p(1) - p(0)).cross(p(2) - p(0)).x
        };
        let areas: Vec<f32> = g.triangles.chunks(3).map(area).collect();
        assert_eq!(areas[0] + areas[1], 4.0);
        assert_eq!(areas[2] + areas[3], -4.0);
        g.rebuild(&SceneOptions::default());
        assert!(g.lines.is_empty() && g.triangles.is_empty());
    }
}
