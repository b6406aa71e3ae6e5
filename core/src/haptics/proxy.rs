//! Touch: a proxy (god object) held on the clay's iso-surface while the tip is inside it.
//!
//! Guarantee: [`SurfaceProxy::update`] does bounded work — at most [`MAX_PROXY_PROBES`] field
//! evaluations (values, or values with gradients) — allocates nothing and takes no lock, so it
//! runs on the haptic path.
//!
//! The rule, after Zilles & Salisbury's god object and Salisbury & Tarr's proxy on implicit
//! surfaces, in field coordinates:
//! - Outside the clay the proxy is the tip.
//! - When the tip enters, the proxy stops where the segment from its last position to the tip
//!   crosses the surface (found by bisection), so it never passes through `s = iso`.
//! - While the tip stays inside, the proxy is first re-seated on the surface as it is now (the
//!   clay may have moved under it: it moves toward the tip until it meets the surface, or out
//!   along the normal if the surface grew over it), then slides toward the tip's projection on
//!   the tangent plane, with Coulomb friction (a cone, below). A few Newton steps along the
//!   gradient put the slid proxy back on the surface.
//! - **Friction cone.** A resting proxy sticks while the tip's tangential offset is within
//!   `static_friction` times the depth. When the tip leaves the cone the proxy slips to the
//!   cone's *edge* (it trails the tip's projection by `kinetic_friction` times the depth), never
//!   to the frictionless point, and stays sliding — held to the kinetic cone — until the tip
//!   comes back inside that cone. (A proxy that was held to the static cone again right after
//!   each slip stuck, then slipped all the way down to the kinetic trail, again and again: a
//!   ratchet felt as a buzz.) With the two coefficients equal, the default, stick and slip join
//!   without a step; a kinetic coefficient below the static one drops the tangential force by
//!   their difference once, when a slide starts.
//! - A tip that is inside the clay without having entered through the surface (a run that
//!   starts inside, a stroke released deep in the clay) is "buried": nothing is rendered until
//!   it leaves, so the hand is never kicked out of the clay.

use glam::Vec3;

use crate::field::MultiPatchField;

/// Bisection steps when the proxy meets the surface.
const BISECT_STEPS: usize = 12;
/// Outward marching steps when the surface grew over the proxy (one knot span in all).
const OUTWARD_STEPS: usize = 6;
/// Newton steps that put a sliding proxy back on the surface.
const NEWTON_STEPS: usize = 3;
/// Upper bound on field evaluations in one [`SurfaceProxy::update`].
pub const MAX_PROXY_PROBES: usize =
    2 + BISECT_STEPS + (OUTWARD_STEPS + BISECT_STEPS) + 1 + NEWTON_STEPS + 2 + BISECT_STEPS;

/// Friction of the touched surface.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ProxyConfig {
    /// Static friction coefficient: the proxy sticks while the tangential offset is at most
    /// this times the depth.
    pub static_friction: f32,
    /// Kinetic friction coefficient: a sliding proxy trails the tip's projection by this
    /// times the depth.
    pub kinetic_friction: f32,
}

impl Default for ProxyConfig {
    fn default() -> Self {
        // Clay-like: a light grip that lets the tool glide. One coefficient, so that sliding
        // starts and stops without a step in the force.
        Self {
            static_friction: 0.2,
            kinetic_friction: 0.2,
        }
    }
}

/// What a proxy found this tick (field coordinates): this surface proxy, or the held tool's
/// shape resting on the clay ([`super::ShapeProxy`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Touch {
    /// Whether the proxy is held off the tip by the clay.
    pub touching: bool,
    /// The proxy (a point on the surface, or the resting tool's centre) while touching, else
    /// the tip.
    pub proxy: Vec3,
    /// Unit vector from the tip's side out toward the proxy: the outward normal at a surface
    /// proxy (zero when not touching).
    pub normal: Vec3,
    /// Depth of the tip below the proxy along the normal, field units (≥ 0).
    pub depth: f32,
}

impl Touch {
    /// Not touching, proxy at `tip`.
    #[must_use]
    pub fn free(tip: Vec3) -> Self {
        Self {
            touching: false,
            proxy: tip,
            normal: Vec3::ZERO,
            depth: 0.0,
        }
    }
}

/// The proxy's state from tick to tick.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceProxy {
    config: ProxyConfig,
    /// The proxy (the tip's last outside position while free).
    proxy: Option<Vec3>,
    touching: bool,
    /// The tip is inside without having entered through the surface.
    buried: bool,
    /// The proxy slipped at the last update and is held to the kinetic cone.
    sliding: bool,
}

impl SurfaceProxy {
    /// A proxy not touching anything.
    #[must_use]
    pub fn new(config: ProxyConfig) -> Self {
        Self {
            config,
            proxy: None,
            touching: false,
            buried: false,
            sliding: false,
        }
    }

    /// Forgets the contact (device fault, device switch, a stroke released inside the clay):
    /// a tip inside the clay counts as buried until it leaves.
    pub fn release(&mut self) {
        self.proxy = None;
        self.touching = false;
        self.sliding = false;
    }

    /// Buries a tip that is inside the clay now (a stroke ended with the tool in the clay:
    /// sculpting moved the surface to the tool, and a rigid surface there would kick the hand
    /// out). Nothing happens to a tip outside.
    pub fn bury_if_inside(&mut self, field: &MultiPatchField, tip: Vec3) {
        if tip.is_finite() && field.value(tip) > field.iso() {
            self.release();
            self.buried = true;
        }
    }

    /// Whether the proxy is on the surface.
    #[must_use]
    pub fn is_touching(&self) -> bool {
        self.touching
    }

    /// Moves the proxy for the tip at `tip` on `field` and returns the touch.
    pub fn update(&mut self, field: &MultiPatchField, tip: Vec3) -> Touch {
        if !tip.is_finite() {
            self.release();
            return Touch::free(tip);
        }
        let inside = |x: Vec3| field.value(x) > field.iso();
        if !inside(tip) {
            self.proxy = Some(tip);
            self.touching = false;
            self.buried = false;
            self.sliding = false;
            return Touch::free(tip);
        }
        if self.buried {
            return Touch::free(tip);
        }
        let Some(last) = self.proxy else {
            self.buried = true;
            return Touch::free(tip);
        };
        let seated = if inside(last) {
            if self.touching {
                // The surface grew over the proxy: step out along the normal to meet it.
                push_out(field, last)
            } else {
                None
            }
        } else {
            // Entering, or the surface moved away: go toward the tip until the surface.
            Some(crossing(field, last, tip))
        };
        let Some(seated) = seated else {
            self.release();
            self.buried = true;
            return Touch::free(tip);
        };
        let normal = outward_normal(field, seated);
        let proxy = if normal == Vec3::ZERO {
            seated
        } else {
            self.slide(field, seated, normal, tip)
        };
        let normal = if normal == Vec3::ZERO {
            (proxy - tip).normalize_or_zero()
        } else {
            normal
        };
        self.proxy = Some(proxy);
        self.touching = true;
        Touch {
            touching: true,
            proxy,
            normal,
            depth: (proxy - tip).dot(normal).max(0.0),
        }
    }

    /// The proxy after sliding from `seated` toward the tip's projection on the tangent plane,
    /// with friction, put back on the surface.
    fn slide(&mut self, field: &MultiPatchField, seated: Vec3, normal: Vec3, tip: Vec3) -> Vec3 {
        let offset = tip - seated;
        let along = offset.dot(normal);
        let depth = (-along).max(0.0);
        let tangential = offset - normal * along;
        let reach = tangential.length();
        let kinetic = self.config.kinetic_friction;
        // Resting: held by the static cone; sliding: by the kinetic one.
        let holds = if self.sliding {
            kinetic
        } else {
            self.config.static_friction.max(kinetic)
        };
        if reach <= holds * depth || reach <= 0.0 {
            self.sliding = false;
            return seated;
        }
        let travel = reach - kinetic * depth;
        if travel <= 0.0 {
            self.sliding = false;
            return seated;
        }
        self.sliding = true;
        let candidate = seated + tangential * (travel / reach);
        let projected = newton_to_surface(field, candidate, field.finest_spacing());
        if !projected.is_finite() {
            return seated;
        }
        if field.value(projected) <= field.iso() {
            return projected;
        }
        // Newton stopped a hair inside: step out along the normal there. Failing that, the way
        // to the tip's projection is blocked (a wall ahead): go as far as the surface along
        // the straight line, as a god object does.
        push_out(field, projected).unwrap_or_else(|| crossing(field, seated, projected))
    }
}

/// The outward unit normal at `x` (the density falls outward), or zero.
fn outward_normal(field: &MultiPatchField, x: Vec3) -> Vec3 {
    (-field.value_and_gradient(x).1).normalize_or_zero()
}

/// The surface point on the segment `outside → inside` (the outside end of the last
/// bisection bracket, so it is never inside).
fn crossing(field: &MultiPatchField, outside: Vec3, inside: Vec3) -> Vec3 {
    let (mut lo, mut hi) = (0.0_f32, 1.0_f32);
    let d = inside - outside;
    for _ in 0..BISECT_STEPS {
        let mid = 0.5 * (lo + hi);
        if field.value(outside + d * mid) > field.iso() {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    outside + d * lo
}

/// From a point inside, the first surface point along the outward normal within one knot
/// span, or `None`.
fn push_out(field: &MultiPatchField, from: Vec3) -> Option<Vec3> {
    let normal = outward_normal(field, from);
    if normal == Vec3::ZERO {
        return None;
    }
    let step = field.finest_spacing() / OUTWARD_STEPS as f32;
    for i in 1..=OUTWARD_STEPS {
        let x = from + normal * (step * i as f32);
        if field.value(x) <= field.iso() {
            return Some(crossing(field, x, from));
        }
    }
    None
}

/// A few Newton steps along the gradient toward `s = iso`, each at most `max_step` long.
fn newton_to_surface(field: &MultiPatchField, mut x: Vec3, max_step: f32) -> Vec3 {
    for _ in 0..NEWTON_STEPS {
        let (v, g) = field.value_and_gradient(x);
        let g2 = g.length_squared();
        if g2.is_nan() || g2 <= 1e-12 {
            break;
        }
        x -= ((v - field.iso()) * g / g2).clamp_length_max(max_step);
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::{Primitive, lattice_from_primitive};
    use crate::haptics::test_clay::slab;

    #[test]
    fn the_proxy_stops_at_the_surface_and_the_tip_goes_on() {
        let field = slab();
        let mut p = SurfaceProxy::new(ProxyConfig::default());
        assert!(!p.update(&field, Vec3::new(1.3, 1.2, 1.3)).touching);
        for depth in [0.02, 0.05, 0.1, 0.3] {
            let tip = Vec3::new(1.3, 1.0 - depth, 1.3);
            let t = p.update(&field, tip);
            assert!(t.touching);
            assert!((t.proxy.y - 1.0).abs() < 0.01, "proxy at {}", t.proxy);
            assert!(field.value(t.proxy) <= field.iso() + 1e-6, "never inside");
            assert!(
                (t.depth - depth).abs() < 0.015,
                "depth {} vs {depth}",
                t.depth
            );
            assert!(t.normal.y > 0.99);
        }
        // Leaving frees it at once.
        assert!(!p.update(&field, Vec3::new(1.3, 1.1, 1.3)).touching);
    }

    #[test]
    fn friction_holds_small_tangential_offsets_and_a_slide_trails_the_tip() {
        let field = slab();
        let mut p = SurfaceProxy::new(ProxyConfig::default());
        p.update(&field, Vec3::new(1.3, 1.2, 1.3));
        let first = p.update(&field, Vec3::new(1.3, 0.9, 1.3)).proxy;
        // 0.1 deep, 0.015 sideways: within the friction cone (0.2 · 0.1).
        let held = p.update(&field, Vec3::new(1.315, 0.9, 1.3)).proxy;
        assert!(held.distance(first) < 1e-4, "stuck: {first} → {held}");
        // 0.2 sideways: slides to the cone's edge, trailing by 0.2 · depth.
        let slid = p.update(&field, Vec3::new(1.5, 0.9, 1.3)).proxy;
        let trail = 1.5 - slid.x;
        assert!((trail - 0.02).abs() < 0.006, "trail {trail}");
        assert!((slid.y - 1.0).abs() < 0.01, "stays on the surface: {slid}");
    }

    /// With a kinetic coefficient below the static one, a steady slide stays on the kinetic
    /// cone: the trail does not cycle between the two (the ratchet).
    #[test]
    fn a_steady_slide_trails_steadily_without_sticking_again() {
        let field = slab();
        let mut p = SurfaceProxy::new(ProxyConfig {
            static_friction: 0.25,
            kinetic_friction: 0.15,
        });
        p.update(&field, Vec3::new(1.0, 1.2, 1.3));
        p.update(&field, Vec3::new(1.0, 0.9, 1.3));
        let mut trails = Vec::new();
        for i in 1..=200 {
            let x = 1.0 + 0.002 * i as f32;
            let t = p.update(&field, Vec3::new(x, 0.9, 1.3));
            trails.push(x - t.proxy.x);
        }
        // Past the onset (the tip needs 0.025 to leave the static cone), the trail holds at
        // the kinetic 0.015 within the re-seating's noise.
        for (i, trail) in trails.iter().enumerate().skip(30) {
            assert!((trail - 0.015).abs() < 0.002, "tick {i}: trail {trail}");
        }
    }

    #[test]
    fn a_tip_that_starts_inside_is_buried_until_it_leaves() {
        let field = slab();
        let mut p = SurfaceProxy::new(ProxyConfig::default());
        assert!(!p.update(&field, Vec3::new(1.3, 0.5, 1.3)).touching);
        assert!(!p.update(&field, Vec3::new(1.3, 0.8, 1.3)).touching);
        assert!(!p.update(&field, Vec3::new(1.3, 1.1, 1.3)).touching);
        assert!(p.update(&field, Vec3::new(1.3, 0.95, 1.3)).touching);
    }

    #[test]
    fn a_surface_that_recedes_takes_the_proxy_with_it() {
        let field = slab();
        let mut p = SurfaceProxy::new(ProxyConfig::default());
        p.update(&field, Vec3::new(1.3, 1.2, 1.3));
        p.update(&field, Vec3::new(1.3, 0.8, 1.3));
        // The same slab, 0.1 lower: the proxy follows down toward the tip.
        let lower = MultiPatchField::new(
            lattice_from_primitive(
                [14, 14, 14],
                0.2,
                Vec3::ZERO,
                &Primitive::Box {
                    centre: Vec3::new(1.3, 0.4, 1.3),
                    half_extents: Vec3::new(2.0, 0.5, 2.0),
                },
                0.4,
                2,
            )
            .unwrap(),
        );
        let t = p.update(&lower, Vec3::new(1.3, 0.8, 1.3));
        assert!(t.touching && (t.proxy.y - 0.9).abs() < 0.01, "{}", t.proxy);
        // And grows back over it: the proxy steps out.
        let t = p.update(&field, Vec3::new(1.3, 0.8, 1.3));
        assert!(t.touching && (t.proxy.y - 1.0).abs() < 0.01, "{}", t.proxy);
    }
}
