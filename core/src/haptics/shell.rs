//! Tool-shaped contact: the held geometric tool rests on the clay with its whole shape.
//!
//! Guarantee: [`ShapeProxy::update`] does bounded work — at most [`MAX_SHAPE_PROBES`] field
//! evaluations — allocates nothing and takes no lock, so it runs on the haptic path. A
//! [`ToolShell`] is plain data of fixed size, built once per tool on the simulation thread.
//!
//! The model, after McNeely, Puterbaugh & Troy's voxmap point-shell and Zilles & Salisbury's
//! god object, in field coordinates:
//! - The tool's surface is sampled by a point shell of [`SHELL_POINTS`] points in its local
//!   frame ([`ToolShell::of`]): the six axis extremes, the directions of the eight corners of
//!   its bounding box (a box's corners) and the rest spread over the directions (a Fibonacci
//!   sphere stretched to the box), each where the ray from the tool's centre leaves its shape.
//! - While the shell placed at the tip meets no clay, the proxy is the tip.
//! - Otherwise the proxy (the tool's centre where it rests) moves from where it was toward the
//!   tip in a few bounded steps; after each, every shell point the clay reaches (or nearly
//!   reaches) is a constraint `Δ · n ≥ d` on the proxy's correction `Δ` (`n` the clay's
//!   outward normal there, `d` the point's depth to first order, `(s − iso) / |∇s|`), solved
//!   by two Gauss–Seidel sweeps. The tool slides without friction around the clay (a carving
//!   tool glides) and never enters it by more than the linearisation's error, which the next
//!   step removes.
//! - A tool that reaches clay without having come to it from outside (a tool switched to
//!   inside the clay) is "buried": nothing is rendered until the shell at the tip is clear.
//! - The hand feels a spring from the tip to the proxy (the renderer's touch force). The tool
//!   acts on the clay only from where it rests, at a rate set by how hard the hand presses
//!   ([`press_fraction`]; the simulation runs the cut ahead of the resting tool toward the
//!   tip).

use glam::{Quat, Vec3};

use super::proxy::Touch;
use crate::field::MultiPatchField;
use crate::tools::ToolShape;

/// Points in a tool's shell.
pub const SHELL_POINTS: usize = 48;
/// Steps toward the tip per tick.
const SHAPE_STEPS: usize = 3;
/// Longest step toward the tip, knot spans of the finest patch.
const STEP_SPANS: f32 = 0.25;
/// Gauss–Seidel sweeps over the shell's constraints per step.
const SWEEPS: usize = 2;
/// Shell points within this many knot spans of the surface take part in a step's constraints
/// (so that a correction does not push a neighbour in).
const NEAR_SPANS: f32 = 0.25;
/// Shell points whose density is this far below the iso-value are more than a knot span from
/// the surface (the clay's ramp rises 1/2 over two spans; a tool's edit makes it no
/// shallower than half that): their gradient is not needed.
const FAR_BELOW_ISO: f32 = 0.25;
/// Upper bound on field evaluations in one [`ShapeProxy::update`]: the clear test at the tip,
/// then every shell point's value at each step, and its gradient where it is near the clay.
pub const MAX_SHAPE_PROBES: usize = SHELL_POINTS * (1 + 2 * SHAPE_STEPS);

/// A tool's surface as a point shell in its local frame (field units). Plain data.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ToolShell {
    points: [Vec3; SHELL_POINTS],
}

impl ToolShell {
    /// The shell of `shape` (local frame): along each direction, a point where the ray from
    /// the tool's centre crosses its surface, found by bisection between the centre and a
    /// point beyond the shape (for a shape that is star-shaped about its centre, its surface
    /// point in that direction; for another, one of the crossings). `None` when the shape has
    /// no extent or its centre is not inside it (a freeform tool hollow there).
    #[must_use]
    pub fn of(shape: &ToolShape) -> Option<Self> {
        let reach = 1.5 * shape.half_extents().length();
        if !(reach.is_finite() && reach > 0.0) {
            return None;
        }
        // A thin band: the shape's own surface, not the falloff around it.
        let falloff = 1e-3 * reach;
        let inside = |p: Vec3| shape.density(p, falloff) >= 0.5;
        if !inside(Vec3::ZERO) {
            return None;
        }
        let mut points = [Vec3::ZERO; SHELL_POINTS];
        for (i, point) in points.iter_mut().enumerate() {
            let dir = shell_direction(i, shape.half_extents());
            // Bisection between the centre (inside) and the reach (outside).
            let (mut lo, mut hi) = (0.0_f32, reach);
            for _ in 0..24 {
                let mid = 0.5 * (lo + hi);
                if inside(dir * mid) {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            *point = dir * lo;
        }
        Some(Self { points })
    }

    /// The shell's points, local frame.
    #[must_use]
    pub fn points(&self) -> &[Vec3; SHELL_POINTS] {
        &self.points
    }

    /// The farthest shell point from the tool's centre, field units.
    #[must_use]
    pub fn radius_fu(&self) -> f32 {
        self.points.iter().map(|p| p.length()).fold(0.0, f32::max)
    }
}

/// The `i`-th shell direction for a shape of `half_extents`: axis extremes, then the
/// directions of its bounding box's corners, then a Fibonacci sphere stretched to the box (so
/// an elongated tool's ends get their share of points).
fn shell_direction(i: usize, half_extents: Vec3) -> Vec3 {
    const AXES: [Vec3; 6] = [
        Vec3::X,
        Vec3::NEG_X,
        Vec3::Y,
        Vec3::NEG_Y,
        Vec3::Z,
        Vec3::NEG_Z,
    ];
    if i < 6 {
        return AXES[i];
    }
    if i < 14 {
        let k = i - 6;
        let s = |bit: usize| if k & bit == 0 { 1.0 } else { -1.0 };
        return (Vec3::new(s(1), s(2), s(4)) * half_extents).normalize();
    }
    let n = (SHELL_POINTS - 14) as f32;
    let k = (i - 14) as f32 + 0.5;
    let z = 1.0 - 2.0 * k / n;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = k * std::f32::consts::PI * (3.0 - 5.0_f32.sqrt());
    (Vec3::new(r * phi.cos(), r * phi.sin(), z) * half_extents).normalize()
}

/// The tool-shaped proxy's state from tick to tick (see the module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ShapeProxy {
    /// The tool's centre where it last rested or was free.
    centre: Option<Vec3>,
    /// The shell reached clay without having come from outside.
    buried: bool,
}

impl ShapeProxy {
    /// Forgets the contact: a tool in the clay now counts as buried until it is clear.
    pub fn release(&mut self) {
        self.centre = None;
    }

    /// Moves the proxy of `shell`, turned by `rotation`, for the tip at `tip`.
    pub fn update(
        &mut self,
        field: &MultiPatchField,
        shell: &ToolShell,
        rotation: Quat,
        tip: Vec3,
    ) -> Touch {
        let rotation = if rotation.is_finite() && rotation.length_squared() > 0.5 {
            rotation.normalize()
        } else {
            Quat::IDENTITY
        };
        if !tip.is_finite() {
            self.release();
            return Touch::free(tip);
        }
        let iso = field.iso();
        let clear = shell
            .points
            .iter()
            .all(|q| field.value(tip + rotation * *q) <= iso);
        if clear {
            self.centre = Some(tip);
            self.buried = false;
            return Touch::free(tip);
        }
        if self.buried {
            return Touch::free(tip);
        }
        let Some(mut centre) = self.centre else {
            self.buried = true;
            return Touch::free(tip);
        };
        let spacing = field.finest_spacing();
        let max_step = STEP_SPANS * spacing;
        let near = NEAR_SPANS * spacing;
        let mut constraints = [(Vec3::ZERO, 0.0_f32); SHELL_POINTS];
        let mut at_tip = 0;
        for _ in 0..SHAPE_STEPS {
            let reach = tip - centre;
            let target = centre + reach.clamp_length_max(max_step);
            let mut count = 0;
            for q in &shell.points {
                let p = target + rotation * *q;
                if field.value(p) < iso - FAR_BELOW_ISO {
                    continue;
                }
                let (s, g) = field.value_and_gradient(p);
                let g_len = g.length();
                if !(g_len > 1e-6 && s.is_finite()) {
                    continue;
                }
                let depth = (s - iso) / g_len;
                if depth > -near {
                    constraints[count] = (-g / g_len, depth);
                    count += 1;
                }
            }
            let mut correction = Vec3::ZERO;
            for _ in 0..SWEEPS {
                for &(normal, depth) in &constraints[..count] {
                    let need = depth - correction.dot(normal);
                    if need > 0.0 {
                        correction += normal * need;
                    }
                }
            }
            let next = target + correction.clamp_length_max(4.0 * max_step);
            if !next.is_finite() {
                break;
            }
            centre = next;
            // Once a step could reach the tip, one more step re-linearises there and a third
            // would repeat it.
            if reach.length() <= max_step {
                at_tip += 1;
                if at_tip == 2 {
                    break;
                }
            }
        }
        self.centre = Some(centre);
        let offset = centre - tip;
        let depth = offset.length();
        Touch {
            touching: depth > 0.0,
            proxy: centre,
            normal: if depth > 0.0 {
                offset / depth
            } else {
                Vec3::ZERO
            },
            depth,
        }
    }
}

/// How far toward the tip the tool acts, from the force the hand presses with: nothing below
/// `rest_n` (the tool rests on the clay), all the way at `firm_n` and beyond, linear between.
#[must_use]
pub fn press_fraction(force_n: f32, rest_n: f32, firm_n: f32) -> f32 {
    if !force_n.is_finite() {
        return 0.0;
    }
    let span = (firm_n - rest_n).max(f32::EPSILON);
    ((force_n - rest_n) / span).clamp(0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::{Primitive, lattice_from_primitive};
    use crate::haptics::test_clay::slab;

    fn lowest_point(shell: &ToolShell, rotation: Quat, at: Vec3) -> f32 {
        shell
            .points()
            .iter()
            .map(|q| (at + rotation * *q).y)
            .fold(f32::INFINITY, f32::min)
    }

    #[test]
    fn every_shell_point_lies_on_its_shape() {
        let shapes = [
            ToolShape::Sphere { radius_fu: 0.25 },
            ToolShape::Ellipsoid {
                radii_fu: Vec3::new(0.3, 0.1, 0.2),
            },
            ToolShape::Box {
                half_extents_fu: Vec3::new(0.3, 0.05, 0.1),
            },
            ToolShape::Cylinder {
                radius_fu: 0.1,
                half_height_fu: 0.3,
            },
            ToolShape::Capsule {
                radius_fu: 0.1,
                half_height_fu: 0.2,
            },
        ];
        for shape in &shapes {
            let shell = ToolShell::of(shape).unwrap();
            for p in shell.points() {
                let d = shape.signed_distance(*p).unwrap();
                assert!(d.abs() < 1e-3, "{shape:?}: {p} is {d} off");
            }
        }
        // The box's corners are in the shell.
        let shell = ToolShell::of(&shapes[2]).unwrap();
        assert!((shell.radius_fu() - Vec3::new(0.3, 0.05, 0.1).length()).abs() < 1e-3);
    }

    /// A freeform tool (a sculpt scaled two to one) is sampled where its own surface is: an
    /// ellipsoid of radii (2r, r, r) within a tenth of a knot span of the sculpt.
    #[test]
    fn a_freeform_shell_lies_on_the_sculpt_it_was_made_from() {
        let (h, r) = (0.05_f32, 0.2_f32);
        let sculpt = lattice_from_primitive(
            [16, 16, 16],
            h,
            Vec3::ZERO,
            &Primitive::Sphere {
                centre: Vec3::splat(7.5 * h),
                radius: r,
            },
            2.0 * h,
            2,
        )
        .unwrap();
        let shape = ToolShape::Freeform(crate::tools::FreeformTool {
            lattice: sculpt,
            scale: Vec3::new(2.0, 1.0, 1.0),
        });
        let shell = ToolShell::of(&shape).unwrap();
        for p in shell.points() {
            let on_ellipsoid = (*p / Vec3::new(2.0 * r, r, r)).length();
            assert!(
                (on_ellipsoid - 1.0).abs() < 0.1 * h / r,
                "{p}: {on_ellipsoid}"
            );
        }
        assert!(
            (shell.radius_fu() - 2.0 * r).abs() < 0.1 * h,
            "{}",
            shell.radius_fu()
        );
    }

    #[test]
    fn a_sphere_rests_on_the_clay_by_its_radius_and_the_tip_goes_on() {
        let field = slab();
        let shell = ToolShell::of(&ToolShape::Sphere { radius_fu: 0.25 }).unwrap();
        let mut p = ShapeProxy::default();
        let x = Vec3::new(1.3, 0.0, 1.3);
        assert!(
            !p.update(&field, &shell, Quat::IDENTITY, x + Vec3::Y * 1.5)
                .touching
        );
        let mut last = Touch::free(x);
        // Down at 0.01 a tick to 0.2 below where the sphere first meets the clay.
        for i in 0..=45 {
            let tip = x + Vec3::Y * (1.5 - 0.01 * i as f32);
            last = p.update(&field, &shell, Quat::IDENTITY, tip);
        }
        let tip_y = 1.5 - 0.45;
        assert!(last.touching);
        // The sphere's bottom rests on y = 1 (the fitted surface is within a few thousandths).
        let bottom = lowest_point(&shell, Quat::IDENTITY, last.proxy);
        assert!((bottom - 1.0).abs() < 0.01, "bottom at {bottom}");
        assert!(
            (last.depth - (1.25 - tip_y)).abs() < 0.01,
            "depth {}",
            last.depth
        );
        assert!(last.normal.y > 0.99, "{}", last.normal);
        for q in shell.points() {
            assert!(
                field.value(last.proxy + *q) <= field.iso() + 0.02,
                "shell in clay"
            );
        }
        // Lifting clear frees it at once.
        assert!(
            !p.update(&field, &shell, Quat::IDENTITY, x + Vec3::Y * 1.4)
                .touching
        );
    }

    #[test]
    fn a_turned_box_rests_on_its_corner() {
        let field = slab();
        let half = Vec3::new(0.2, 0.2, 0.2);
        let shell = ToolShell::of(&ToolShape::Box {
            half_extents_fu: half,
        })
        .unwrap();
        // Turned so that a corner points straight down.
        let corner_down = Quat::from_rotation_arc(-half.normalize(), Vec3::NEG_Y);
        for (rotation, low) in [(Quat::IDENTITY, 0.2), (corner_down, half.length())] {
            let mut p = ShapeProxy::default();
            let x = Vec3::new(1.3, 0.0, 1.3);
            let mut last = Touch::free(x);
            for i in 0..=60 {
                let tip = x + Vec3::Y * (1.8 - 0.01 * i as f32);
                last = p.update(&field, &shell, rotation, tip);
            }
            assert!(last.touching);
            let centre_above = last.proxy.y - 1.0;
            assert!(
                (centre_above - low).abs() < 0.015,
                "centre {centre_above} above the clay, expected {low}"
            );
        }
    }

    #[test]
    fn the_tool_slides_along_the_clay_without_sticking() {
        let field = slab();
        let shell = ToolShell::of(&ToolShape::Sphere { radius_fu: 0.2 }).unwrap();
        let mut p = ShapeProxy::default();
        let start = Vec3::new(0.8, 1.4, 1.3);
        p.update(&field, &shell, Quat::IDENTITY, start);
        let mut tip = start;
        for _ in 0..40 {
            tip.y -= 0.01;
            p.update(&field, &shell, Quat::IDENTITY, tip);
        }
        // Slide sideways 0.5 at 0.005 a tick, 0.2 deep: the proxy follows over the tip.
        let mut last = Touch::free(tip);
        for _ in 0..100 {
            tip.x += 0.005;
            last = p.update(&field, &shell, Quat::IDENTITY, tip);
        }
        assert!(last.touching);
        assert!(
            (last.proxy.x - tip.x).abs() < 0.01,
            "{} vs {}",
            last.proxy,
            tip
        );
        assert!((last.proxy.y - 1.2).abs() < 0.01, "{}", last.proxy);
    }

    #[test]
    fn a_tool_switched_to_inside_the_clay_is_buried_until_clear() {
        let field = slab();
        let shell = ToolShell::of(&ToolShape::Sphere { radius_fu: 0.2 }).unwrap();
        let mut p = ShapeProxy::default();
        let x = Vec3::new(1.3, 0.0, 1.3);
        assert!(
            !p.update(&field, &shell, Quat::IDENTITY, x + Vec3::Y * 0.9)
                .touching
        );
        assert!(
            !p.update(&field, &shell, Quat::IDENTITY, x + Vec3::Y * 1.1)
                .touching
        );
        assert!(
            !p.update(&field, &shell, Quat::IDENTITY, x + Vec3::Y * 1.3)
                .touching
        );
        assert!(
            p.update(&field, &shell, Quat::IDENTITY, x + Vec3::Y * 1.15)
                .touching
        );
    }

    #[test]
    fn pressing_past_the_rest_force_acts_more() {
        assert_eq!(press_fraction(0.2, 0.3, 3.0), 0.0);
        assert!((press_fraction(1.65, 0.3, 3.0) - 0.5).abs() < 1e-6);
        assert_eq!(press_fraction(10.0, 0.3, 3.0), 1.0);
        assert_eq!(press_fraction(f32::NAN, 0.3, 3.0), 0.0);
    }
}
