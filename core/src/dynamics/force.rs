//! Force mapping (Hua & Qin eq. 6, §7.2): the scalar sculpting force along a force vector, its
//! spread over mass points, and the reaction force the user feels.
//!
//! Everything here is a pure function over `&BSplineLattice` and two points: no allocation, no
//! locks, bounded work (four field evaluations), so it is safe on the 1 kHz haptic thread.
//!
//! Sign convention (checked against Hua & Qin Fig. 3). The paper's field is zero on the
//! surface and negative outside; ours is a density with the surface at `iso`, so the integrand
//! is `s − iso`: `f = −l ∫₀¹ (s(x0 + t(x1 − x0)) − iso) dt`. A force vector from a surface point
//! `x0` outward to the cursor `x1` crosses empty space (`s < iso`), so `f > 0` raises
//! densities and the solid grows toward the cursor; the reversed vector (cursor inside) gives
//! `f < 0` and the solid shrinks. As `x0` — re-found on the surface each tick, see
//! [`surface_point_on_ray`] — reaches the cursor, `l → 0` and `s − iso → 0`, so the force
//! falls smoothly to zero (§7.2.2). The user feels the opposite force along the vector.

use glam::Vec3;

use crate::field::ImplicitField;

/// Gauss–Legendre nodes on `[−1, 1]`, ascending.
pub const GAUSS_NODES: [f32; 4] = [-0.861_136_3, -0.339_981_04, 0.339_981_04, 0.861_136_3];
/// Gauss–Legendre weights on `[−1, 1]`, matching [`GAUSS_NODES`].
pub const GAUSS_WEIGHTS: [f32; 4] = [0.347_854_85, 0.652_145_15, 0.652_145_15, 0.347_854_85];

/// `∫₀¹ g(t) dt` by 4-point Gauss–Legendre: exact for polynomials of degree up to 7.
#[inline]
#[must_use]
pub fn gauss_legendre_unit(g: impl Fn(f32) -> f32) -> f32 {
    let mut sum = 0.0;
    for (xi, w) in GAUSS_NODES.iter().zip(GAUSS_WEIGHTS) {
        sum += w * g(0.5 * (1.0 + xi));
    }
    0.5 * sum
}

/// The scalar sculpting force of the force vector `x0 → x1`:
/// `f = −l ∫₀¹ (s(x0 + t(x1 − x0)) − iso) dt`. Positive raises densities. Zero for a
/// degenerate or non-finite vector.
#[inline]
#[must_use]
pub fn force_integral<F: ImplicitField + ?Sized>(lattice: &F, x0: Vec3, x1: Vec3) -> f32 {
    let v = x1 - x0;
    let l = v.length();
    if !(l.is_finite() && l > 0.0) {
        return 0.0;
    }
    let mean = gauss_legendre_unit(|t| lattice.value(x0 + v * t) - lattice.iso());
    -l * mean
}

/// The reaction on the cursor at `x1` for the force vector `x0 → x1`, in field units
/// (density × length): equal and opposite to the sculpting force, `|f| · (x0 − x1)/l`. The
/// cursor is drawn back toward the surface point whichever way the density moves: pulling
/// outward (`f > 0`) is resisted inward and pushing in (`f < 0`) is pushed back out. Zero for
/// a degenerate or non-finite vector. The haptic loop scales it to newtons
/// ([`crate::haptics`]).
#[inline]
#[must_use]
pub fn reaction_force<F: ImplicitField + ?Sized>(lattice: &F, x0: Vec3, x1: Vec3) -> Vec3 {
    let v = x1 - x0;
    let l = v.length();
    if !(l.is_finite() && l > 0.0) {
        return Vec3::ZERO;
    }
    let f = force_integral(lattice, x0, x1);
    let r = v * (-f.abs() / l);
    if r.is_finite() { r } else { Vec3::ZERO }
}

/// Marching steps of [`start_on_surface`].
/// Whether `x` is inside the solid of `field`.
#[inline]
fn is_inside<F: ImplicitField + ?Sized>(field: &F, x: Vec3) -> bool {
    field.value(x) > field.iso()
}

pub const REFIND_MARCH_STEPS: u32 = 8;
/// Bisection steps of [`start_on_surface`].
pub const REFIND_BISECT_STEPS: u32 = 8;

/// The start of the force vector `start → end` found again on the current surface (Hua &
/// Qin §7.2.2): the iso-surface crossing on the segment nearest `end`. Because `x0` is a
/// surface point, a surface that follows the cursor shortens the vector, so the force falls
/// to zero as the surface reaches the cursor; a fixed `x0` would stall the surface where
/// `∫(s − iso)` vanishes, half-way.
///
/// When the segment does not cross the surface:
/// - both ends inside: the surface has reached (or passed) the cursor. The start is the exit
///   crossing just beyond `end`, within one segment length along the vector, so the vector
///   turns into a short push back and the force passes smoothly through zero; with no exit
///   within that reach (the cursor deep in the clay), `start`;
/// - both ends outside: `start` (the vector acts in open air, as eq. 6 gives).
///
/// The same rule serves the simulation (which force vectors act on the clay) and the haptic
/// loop (what the hand feels), so both integrate the same vectors. Bounded work: at most
/// `2 · (`[`REFIND_MARCH_STEPS`]` + `[`REFIND_BISECT_STEPS`]`) + 1` field evaluations;
/// allocates nothing.
#[must_use]
pub fn start_on_surface<F: ImplicitField + ?Sized>(lattice: &F, start: Vec3, end: Vec3) -> Vec3 {
    if !(start.is_finite() && end.is_finite()) {
        return start;
    }
    let end_inside = is_inside(lattice, end);
    if let Some(x) = first_change(lattice, end, start - end, end_inside) {
        return x;
    }
    if end_inside && let Some(x) = first_change(lattice, end, end - start, true) {
        return x;
    }
    start
}

/// [`start_on_surface`] for a vector ending at a fixed target that the surface is moved to (a
/// chisel's or squirt's): the surface crossing on the vector's line nearest `end`, on either
/// side of it. Where `end` is outside and the surface has passed it (a cut gone past its
/// target, under a skin of clay that still closes it above), the nearest crossing is the one
/// just past `end`, not the clay above: the vector shrinks to zero and reverses as the surface
/// moves through the target, where the crossing toward `start` would jump from the surface
/// just short of `end` to the skin (felt as a force stepping on and off each time the surface
/// crosses the target). Bounded work: [`start_on_surface`]'s and one more march and bisection.
#[must_use]
pub fn start_on_surface_near_target<F: ImplicitField + ?Sized>(
    lattice: &F,
    start: Vec3,
    end: Vec3,
) -> Vec3 {
    let found = start_on_surface(lattice, start, end);
    if !(start.is_finite() && end.is_finite()) || is_inside(lattice, end) || found == start {
        return found;
    }
    // `end` outside and a crossing toward `start`: a nearer one past `end`, within as far.
    first_change(lattice, end, end - found, false).unwrap_or(found)
}

/// The first point along `from + t · span`, `t ∈ (0, 1]`, whose inside-ness differs from
/// `from_inside`, refined by bisection; `None` when there is none at the march's resolution.
/// At most [`REFIND_MARCH_STEPS`]` + `[`REFIND_BISECT_STEPS`] evaluations.
pub(super) fn first_change<F: ImplicitField + ?Sized>(
    lattice: &F,
    from: Vec3,
    span: Vec3,
    from_inside: bool,
) -> Option<Vec3> {
    let mut near = 0.0_f32;
    for i in 1..=REFIND_MARCH_STEPS {
        let t = i as f32 / REFIND_MARCH_STEPS as f32;
        if is_inside(lattice, from + span * t) != from_inside {
            let mut far = t;
            for _ in 0..REFIND_BISECT_STEPS {
                let mid = 0.5 * (near + far);
                if is_inside(lattice, from + span * mid) == from_inside {
                    near = mid;
                } else {
                    far = mid;
                }
            }
            return Some(from + span * (0.5 * (near + far)));
        }
        near = t;
    }
    None
}

/// The first point where the solid ends along the ray from `anchor` in direction `toward`
/// (normalised here), searched up to `max_len` world units: a step search at `step` followed by
/// bisection. `None` when `anchor` is outside the solid or the solid does not end within
/// `max_len`. Bounded work: at most `max_len / step + 24` field evaluations; allocates nothing.
#[must_use]
pub fn surface_point_on_ray<F: ImplicitField + ?Sized>(
    lattice: &F,
    anchor: Vec3,
    toward: Vec3,
    max_len: f32,
    step: f32,
) -> Option<Vec3> {
    let dir = toward.normalize_or_zero();
    if dir == Vec3::ZERO
        || step.is_nan()
        || step <= 0.0
        || !max_len.is_finite()
        || !is_inside(lattice, anchor)
    {
        return None;
    }
    let steps = (max_len / step).ceil().min(100_000.0) as u32;
    let mut a = 0.0_f32;
    for s in 1..=steps {
        let b = (s as f32 * step).min(max_len);
        if !is_inside(lattice, anchor + dir * b) {
            let (mut lo, mut hi) = (a, b);
            for _ in 0..24 {
                let m = 0.5 * (lo + hi);
                if is_inside(lattice, anchor + dir * m) {
                    lo = m;
                } else {
                    hi = m;
                }
            }
            return Some(anchor + dir * (0.5 * (lo + hi)));
        }
        a = b;
    }
    None
}

/// Shape of the spread `β` of a sculpting force over mass points near the force vector.
/// `ρ` is the distance to the segment divided by the radius.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Distribution {
    /// `β = 1` within the radius of the segment (a capsule).
    #[default]
    Constant,
    /// `β = exp(−4.5 ρ²)` (σ = radius / 3), cut at the radius.
    Gaussian,
    /// `β = √(1 − ρ²)`: a hemispherical profile.
    Spherical,
    /// `β = 1` inside the flat-ended cylinder of the radius around the segment.
    Cylindrical,
    /// `β = 1 − ρ`: a conical profile.
    Conical,
}

impl Distribution {
    /// Weight of a mass point at `x` for the segment `a → b` and `radius`.
    #[inline]
    #[must_use]
    pub fn weight(self, x: Vec3, a: Vec3, b: Vec3, radius: f32) -> f32 {
        let ab = b - a;
        let len2 = ab.length_squared();
        let t_raw = if len2 > 0.0 {
            (x - a).dot(ab) / len2
        } else {
            0.0
        };
        let t = t_raw.clamp(0.0, 1.0);
        let rho = (x - (a + ab * t)).length() / radius;
        if rho.is_nan() || rho > 1.0 {
            return 0.0;
        }
        match self {
            Self::Constant => 1.0,
            Self::Gaussian => (-4.5 * rho * rho).exp(),
            Self::Spherical => (1.0 - rho * rho).max(0.0).sqrt(),
            Self::Conical => 1.0 - rho,
            Self::Cylindrical => {
                if (0.0..=1.0).contains(&t_raw) || len2 == 0.0 {
                    1.0
                } else {
                    0.0
                }
            }
        }
    }
}

/// One force vector applied by a tool: the integral along `start → end`, times `gain`, spread
/// over the mass points within `radius` of the segment by `distribution` (weights normalised
/// so the mass-point forces sum to `gain · f`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ToolForce {
    /// Start of the force vector (a surface point, `x0`).
    pub start: Vec3,
    /// End of the force vector (the cursor, `x1`).
    pub end: Vec3,
    /// Spread shape.
    pub distribution: Distribution,
    /// Spread radius, world units.
    pub radius: f32,
    /// Density force per unit of force integral.
    pub gain: f32,
}

/// The body of a tool pressed into the clay: its shaft, the capsule of `radius` around the
/// segment from `inner` (where the tool's force vector starts, the surface above its tip) out
/// to `outer` (where the tool entered the clay, on the plane it entered through). A real
/// stylus keeps the clay out of the hole it has made; the tool's force vector acts only at its
/// tip, so without the body the walls of a hole narrow against its depth close over the tip
/// (the clay's springs smooth a narrow hole away faster than its plastic flow sets it) and the
/// tip carves a pocket under a shut top. The simulation pushes out whatever clay lies along
/// the shaft, as the tool's force vector pushes the clay under the tip (see
/// `Simulator::set_tool_bodies`); an open hole holds none, so the body adds nothing there.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ToolBody {
    /// The shaft's inner end: the start of the tool's force vector, on the surface above the
    /// tip.
    pub inner: Vec3,
    /// The shaft's outer end: above the tip, on the plane where the tool entered the clay.
    pub outer: Vec3,
    /// Spread shape across the shaft.
    pub distribution: Distribution,
    /// Radius of the shaft, world units.
    pub radius: f32,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::BSplineLattice;

    #[test]
    fn gauss_legendre_is_exact_up_to_degree_seven() {
        for k in 0..=7 {
            let got = gauss_legendre_unit(|t| t.powi(k));
            let want = 1.0 / (k as f32 + 1.0);
            assert!((got - want).abs() < 2e-7, "t^{k}: {got} vs {want}");
        }
        // Degree 8 is not integrated exactly (the rule is exactly of order 7).
        let err8 = (gauss_legendre_unit(|t| t.powi(8)) - 1.0 / 9.0).abs();
        assert!(err8 > 1e-5, "degree 8 error {err8}");
    }

    #[test]
    fn force_integral_is_exact_for_a_cubic_along_a_segment() {
        // Along a segment parallel to x inside one knot span the field is a cubic in t.
        let mut lattice = BSplineLattice::zeros([8, 8, 8], 0.5, Vec3::ZERO).unwrap();
        lattice.coeffs.update_each(|n, c| {
            *c = ((n * 37) % 11) as f32 / 11.0;
        });
        let (x0, x1) = (Vec3::new(1.55, 1.7, 2.2), Vec3::new(1.95, 1.7, 2.2));
        let got = force_integral(&lattice, x0, x1);
        // Reference: composite Simpson in f64 on a fine grid.
        let n = 2000;
        let mut sum = 0.0_f64;
        for i in 0..=n {
            let t = i as f32 / n as f32;
            let w = if i == 0 || i == n {
                1.0
            } else if i % 2 == 1 {
                4.0
            } else {
                2.0
            };
            sum += w * f64::from(lattice.value(x0 + (x1 - x0) * t) - lattice.iso);
        }
        let want = -0.4 * sum / (3.0 * n as f64);
        assert!((f64::from(got) - want).abs() < 1e-6, "{got} vs {want}");
    }

    fn slab() -> BSplineLattice {
        // Density 1 for x < 1.0, 0 beyond: surface near x = 1 (values are the linear ramp).
        let mut lattice = BSplineLattice::zeros([12, 6, 6], 0.2, Vec3::ZERO).unwrap();
        for k in 0..6 {
            for j in 0..6 {
                for i in 0..12 {
                    let idx = lattice.index(i, j, k);
                    lattice
                        .coeffs
                        .set_flat(idx, (0.5 - (i as f32 * 0.2 - 1.0) / 0.8).clamp(0.0, 1.0));
                }
            }
        }
        lattice
    }

    #[test]
    fn outward_vector_grows_and_inward_vector_shrinks() {
        let lattice = slab();
        let centre = Vec3::new(0.0, 0.5, 0.5);
        let x0 =
            surface_point_on_ray(&lattice, centre + Vec3::X * 0.6, Vec3::X, 1.0, 0.05).unwrap();
        assert!((x0.x - 1.0).abs() < 0.05, "surface at {x0}");
        let out = x0 + Vec3::X * 0.3;
        assert!(force_integral(&lattice, x0, out) > 0.0);
        let r = reaction_force(&lattice, x0, out);
        assert!(r.x < 0.0, "user pulled back toward the surface: {r}");
        let inside = x0 - Vec3::X * 0.3;
        assert!(force_integral(&lattice, x0, inside) < 0.0);
        let r = reaction_force(&lattice, x0, inside);
        assert!(r.x > 0.0, "user pushed back out: {r}");
        // Vanishes as the vector shrinks to the surface.
        let near = force_integral(&lattice, x0, x0 + Vec3::X * 1e-3).abs();
        assert!(near < 1e-5, "{near}");
        assert_eq!(force_integral(&lattice, x0, x0), 0.0);
        assert_eq!(reaction_force(&lattice, Vec3::NAN, x0), Vec3::ZERO);
    }

    #[test]
    fn distributions_are_bounded_and_vanish_beyond_the_radius() {
        let (a, b) = (Vec3::ZERO, Vec3::X);
        for d in [
            Distribution::Constant,
            Distribution::Gaussian,
            Distribution::Spherical,
            Distribution::Cylindrical,
            Distribution::Conical,
        ] {
            assert!((d.weight(Vec3::new(0.5, 0.0, 0.0), a, b, 0.2) - 1.0).abs() < 1e-6);
            assert_eq!(d.weight(Vec3::new(0.5, 0.3, 0.0), a, b, 0.2), 0.0);
            let w = d.weight(Vec3::new(0.5, 0.1, 0.0), a, b, 0.2);
            assert!((0.0..=1.0).contains(&w));
        }
        assert_eq!(
            Distribution::Cylindrical.weight(Vec3::new(-0.1, 0.0, 0.0), a, b, 0.2),
            0.0
        );
        assert_eq!(
            Distribution::Constant.weight(Vec3::new(-0.1, 0.0, 0.0), a, b, 0.2),
            1.0
        );
    }

    /// A cut under a skin, along y: clay below the floor at `floor_y` and in the skin from
    /// y = 1.0 to 1.1, a hole between (positive inside, iso 0).
    struct SkinOverCut {
        floor_y: f32,
    }

    impl crate::field::ImplicitField for SkinOverCut {
        fn iso(&self) -> f32 {
            0.0
        }
        fn value(&self, p: Vec3) -> f32 {
            (self.floor_y - p.y).max((p.y - 1.0).min(1.1 - p.y))
        }
        fn value_and_gradient(&self, p: Vec3) -> (f32, Vec3) {
            let floor = self.floor_y - p.y;
            let skin = (p.y - 1.0).min(1.1 - p.y);
            let skin_gradient = if p.y < 1.05 { Vec3::Y } else { -Vec3::Y };
            if floor >= skin {
                (floor, -Vec3::Y)
            } else {
                (skin, skin_gradient)
            }
        }
    }

    #[test]
    fn a_target_vector_starts_at_the_surface_nearest_its_target_on_either_side() {
        let (top, target) = (Vec3::new(0.0, 1.1, 0.0), Vec3::new(0.0, 0.6, 0.0));
        // The floor moving down through the target: the start follows it, so the vector
        // shrinks to nothing and grows again the other way.
        for floor_y in [0.7, 0.65, 0.61, 0.59, 0.55, 0.5] {
            let field = SkinOverCut { floor_y };
            let start = start_on_surface_near_target(&field, top, target);
            assert!(
                (start.y - floor_y).abs() < 2e-3,
                "floor at {floor_y}: start {start}"
            );
        }
        // The plain rule finds the skin's underside once the floor is past the target.
        let past = SkinOverCut { floor_y: 0.59 };
        assert!((start_on_surface(&past, top, target).y - 1.0).abs() < 2e-3);
        // Nothing nearer past the target: the crossing toward the start.
        let open = SkinOverCut { floor_y: -1.0 };
        let start = start_on_surface_near_target(&open, top, target);
        assert!((start.y - 1.0).abs() < 2e-3, "{start}");
    }
}
