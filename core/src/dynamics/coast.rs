//! Where the clay is going: the coast field `s + τ ṡ`, the surface the simulated region would
//! come to rest on if every force stopped now, and the closed loop that makes force tools
//! stop where the surface reaches their target (Hua & Qin §7.2.2).
//!
//! Guarantee: pure functions over borrowed state; no allocation, no lock, bounded work (a
//! field evaluation costs one lattice evaluation plus one 4×4×4 tap sum over the region's
//! velocities), so the simulation may call them for every force vector of every step.
//!
//! Why the coast field. Eq. (6) drives the densities toward the cursor and vanishes when the
//! surface reaches it, but the densities have mass: a surface that arrives with speed passes
//! the cursor (the push groove ended a tenth of the block below the tip, a chisel cut 1.8
//! times its depth). The damping of every mass point is proportional to its mass here
//! (`D = M / τ`, `τ = μ / γ`), so eq. (7) reads `τ p̈ + ṗ = τ (AᵀMA)⁻¹ Aᵀ (f − K d)`, and
//! the coast coefficients `p + τ ṗ` obey a first-order law,
//! `d/dt (p + τ ṗ) = (AᵀMA)⁻¹ Aᵀ (f − K d) · τ`: no inertia. The simulation therefore takes
//! eq. (6) on the coast field (the start of each force vector re-found on the coast surface,
//! the integral along it), so each force falls to zero as the coast surface reaches its
//! target and reverses when the coast surface has passed it; the coast surface, being
//! first order, does not overshoot; and the clay itself, `p(t)` a running average of past
//! coast coefficients (`p + τ ṗ = p_coast`), never passes a target the coast surface has not
//! passed. This is a proportional–derivative loop on the surface position whose derivative
//! gain is exactly the material's own coast time; with it the linearised loop is at least
//! critically damped for any gain. The springs and the plastic drift act on top; they
//! resist the motion, they do not carry it past.
//!
//! The springs also brake a moving point sooner than its damping alone, so the coast time
//! used is the first peak of the point's damped oscillation ([`coast_time_s`]): 9 ms for the
//! default clay against `μ/γ` = 25 ms. With `μ/γ` the loop over-predicted how far a narrow
//! dent coasts, reversed its force and stalled it (a 0.12 press on a detail patch left a
//! 0.003 dent); with the oscillator's peak it lands (0.115).

use glam::Vec3;

use crate::field::ImplicitField;
use crate::field::{CoeffBox, cubic_weights, cubic_weights_and_derivatives};

use super::force::first_change;

/// Longest coast time used, seconds. A material with (almost) no damping would coast for
/// ever; its braking still uses at most this horizon.
pub const MAX_COAST_S: f32 = 0.25;

/// How far beyond a force vector's end the coast surface is searched for when it has passed
/// the end, knot spans of the simulated patch (at least the vector's own length).
pub const COAST_REACH_SPANS: f32 = 4.0;

/// The springs that hold a lone mass point, as multiples of its spring stiffness `ρ`: its six
/// face neighbours (the larger stencils share the same resistance out among more springs).
pub const SPRINGS_PER_POINT: f32 = 6.0;

/// The coast time of a region's mass points, seconds: how far a mass point moving at unit
/// speed goes before it turns, if every tool force stopped now — the first peak of a damped
/// oscillator of the region's mean mass `μ`, damping `γ` and springs `k = 6ρ` (see
/// [`SPRINGS_PER_POINT`]). Without springs it is `μ/γ`; the springs brake the point sooner
/// (the default clay, `μ = 1`, `γ = 40`, `ρ = 1000`, is underdamped, `ζ = 0.26`, and coasts
/// 9.1 ms against `μ/γ` = 25 ms). It never exceeds `μ/γ` or [`MAX_COAST_S`] (the cap
/// also stands for no damping). Zero for no mass or a non-finite material.
#[must_use]
pub fn coast_time_s(mass: &[f32], damping: &[f32], stiffness: &[f32]) -> f32 {
    let n = mass.len().max(1) as f64;
    let mean = |v: &[f32]| lane_sum(v) / n;
    let (m, g) = (mean(mass), mean(damping));
    let k = f64::from(SPRINGS_PER_POINT) * mean(stiffness);
    if !(m.is_finite() && g.is_finite() && k.is_finite() && m > 0.0) {
        return 0.0;
    }
    let damped = if g > 0.0 { m / g } else { f64::INFINITY };
    let sprung = if k > 0.0 {
        first_peak_per_unit_speed(m, g.max(0.0), k)
    } else {
        f64::INFINITY
    };
    damped.min(sprung).min(f64::from(MAX_COAST_S)) as f32
}

/// The sum of `v`, in eight f32 lanes (which the compiler keeps in one vector register; a
/// region holds tens of thousands of mass points and the simulation reads this every step)
/// added up in f64 at the end.
fn lane_sum(v: &[f32]) -> f64 {
    let mut lanes = [0.0_f32; 8];
    let chunks = v.chunks_exact(8);
    let tail: f64 = chunks.remainder().iter().map(|&x| f64::from(x)).sum();
    for chunk in chunks {
        for (lane, &x) in lanes.iter_mut().zip(chunk) {
            *lane += x;
        }
    }
    lanes.iter().map(|&x| f64::from(x)).sum::<f64>() + tail
}

/// The first peak of `x(t)` for `m ẍ + g ẋ + k x = 0`, `x(0) = 0`, `ẋ(0) = 1` (`m, k > 0`,
/// `g ≥ 0`): seconds of unit speed.
fn first_peak_per_unit_speed(m: f64, g: f64, k: f64) -> f64 {
    let w0 = (k / m).sqrt();
    let zeta = g / (2.0 * (k * m).sqrt());
    if (zeta - 1.0).abs() < 1e-6 {
        // Critical: x = t e^{−ω₀t}, peak at t = 1/ω₀.
        return (-1.0_f64).exp() / w0;
    }
    if zeta < 1.0 {
        // x = e^{−ζω₀t} sin(ω_d t) / ω_d, first peak where tan(ω_d t) = ω_d / (ζω₀).
        let wd = w0 * (1.0 - zeta * zeta).sqrt();
        let t = wd.atan2(zeta * w0) / wd;
        return (-zeta * w0 * t).exp() * (wd * t).sin() / wd;
    }
    // Overdamped: x = (e^{r₁t} − e^{r₂t}) / (r₁ − r₂) with r₂ < r₁ < 0, peak where
    // r₁ e^{r₁t} = r₂ e^{r₂t}.
    let root = w0 * (zeta * zeta - 1.0).sqrt();
    let (r1, r2) = (-zeta * w0 + root, -zeta * w0 - root);
    let t = (r2 / r1).ln() / (r1 - r2);
    ((r1 * t).exp() - (r2 * t).exp()) / (r1 - r2)
}

/// The velocity field `ṡ(x) = Σ ṗ B(x)` of a simulated region: the region's coefficient
/// velocities laid on its box of the patch's lattice, zero elsewhere (those coefficients are
/// fixed).
#[derive(Clone, Copy, Debug)]
pub struct RegionVelocity<'a> {
    /// The patch lattice's origin, world units.
    pub origin: Vec3,
    /// The patch lattice's knot spacing, world units.
    pub spacing: f32,
    /// The region's coefficient box.
    pub coeffs: CoeffBox,
    /// `ṗ` over the box, x fastest.
    pub p_dot: &'a [f32],
}

impl RegionVelocity<'_> {
    /// The taps of `x`: for each axis the first coefficient index and the fractional
    /// position; `None` off the lattice grid.
    #[inline]
    fn taps(&self, x: Vec3) -> Option<([i64; 3], Vec3)> {
        let u = (x - self.origin) / self.spacing;
        if !u.is_finite() {
            return None;
        }
        let base = u.floor();
        Some((
            [base.x as i64 - 1, base.y as i64 - 1, base.z as i64 - 1],
            u - base,
        ))
    }

    /// `ṡ(x)` and its gradient (per world unit).
    #[must_use]
    pub fn value_and_gradient(&self, x: Vec3) -> (f32, Vec3) {
        let Some((first, t)) = self.taps(x) else {
            return (0.0, Vec3::ZERO);
        };
        let (wx, dx) = cubic_weights_and_derivatives(t.x);
        let (wy, dy) = cubic_weights_and_derivatives(t.y);
        let (wz, dz) = cubic_weights_and_derivatives(t.z);
        let n = self.coeffs.dims();
        let (mut v, mut g) = (0.0, Vec3::ZERO);
        for c in 0..4 {
            let Some(k) = self.local(2, first[2] + c as i64) else {
                continue;
            };
            for b in 0..4 {
                let Some(j) = self.local(1, first[1] + b as i64) else {
                    continue;
                };
                for a in 0..4 {
                    let Some(i) = self.local(0, first[0] + a as i64) else {
                        continue;
                    };
                    let p = self.p_dot[i + n[0] * (j + n[1] * k)];
                    v += p * wx[a] * wy[b] * wz[c];
                    g += p * Vec3::new(
                        dx[a] * wy[b] * wz[c],
                        wx[a] * dy[b] * wz[c],
                        wx[a] * wy[b] * dz[c],
                    );
                }
            }
        }
        (v, g / self.spacing)
    }

    /// `ṡ(x)`.
    #[must_use]
    pub fn value(&self, x: Vec3) -> f32 {
        let Some((first, t)) = self.taps(x) else {
            return 0.0;
        };
        let (wx, wy, wz) = (cubic_weights(t.x), cubic_weights(t.y), cubic_weights(t.z));
        let n = self.coeffs.dims();
        let mut v = 0.0;
        for (c, w_z) in wz.iter().enumerate() {
            let Some(k) = self.local(2, first[2] + c as i64) else {
                continue;
            };
            for (b, w_y) in wy.iter().enumerate() {
                let Some(j) = self.local(1, first[1] + b as i64) else {
                    continue;
                };
                let row = n[0] * (j + n[1] * k);
                let mut s = 0.0;
                for (a, w) in wx.iter().enumerate() {
                    if let Some(i) = self.local(0, first[0] + a as i64) {
                        s += w * self.p_dot[row + i];
                    }
                }
                v += s * w_y * w_z;
            }
        }
        v
    }

    /// The index along `axis` within the box of lattice index `i`, if the box holds it.
    #[inline]
    fn local(&self, axis: usize, i: i64) -> Option<usize> {
        let (lo, hi) = (self.coeffs.min[axis] as i64, self.coeffs.max[axis] as i64);
        (lo <= i && i <= hi && self.p_dot.len() == self.coeffs.count()).then(|| (i - lo) as usize)
    }
}

/// The coast field `s(x) + τ ṡ(x)`: where the densities go if every force stopped now.
#[derive(Clone, Copy, Debug)]
pub struct CoastField<'a, F: ?Sized> {
    /// The clay's density as it is.
    pub field: &'a F,
    /// The simulated region's velocities.
    pub velocity: RegionVelocity<'a>,
    /// The coast time, seconds ([`coast_time_s`]).
    pub tau_s: f32,
}

impl<F: ImplicitField + ?Sized> ImplicitField for CoastField<'_, F> {
    fn iso(&self) -> f32 {
        self.field.iso()
    }

    fn value(&self, p: Vec3) -> f32 {
        self.field.value(p) + self.tau_s * self.velocity.value(p)
    }

    fn value_and_gradient(&self, p: Vec3) -> (f32, Vec3) {
        let (v, g) = self.field.value_and_gradient(p);
        let (dv, dg) = self.velocity.value_and_gradient(p);
        (v + self.tau_s * dv, g + self.tau_s * dg)
    }
}

/// The start of the force vector `start → end` found on the surface of `field` (the coast
/// field, in the simulation): the crossing on the segment nearest `end`; when the segment
/// does not cross, the first crossing beyond `end` along the vector within
/// `max(|end − start|, reach)`, so a surface that has passed the end (or will) turns the
/// vector into a push back; otherwise `start`. Bounded work: at most
/// `2 · (`[`REFIND_MARCH_STEPS`](super::force::REFIND_MARCH_STEPS)` + `
/// [`REFIND_BISECT_STEPS`](super::force::REFIND_BISECT_STEPS)`) + 1` evaluations of `field`.
#[must_use]
pub fn start_on_coast<F: ImplicitField + ?Sized>(
    field: &F,
    start: Vec3,
    end: Vec3,
    reach: f32,
) -> Vec3 {
    if !(start.is_finite() && end.is_finite()) {
        return start;
    }
    let end_inside = field.value(end) > field.iso();
    if let Some(x) = first_change(field, end, start - end, end_inside) {
        return x;
    }
    let v = end - start;
    let l = v.length();
    if l > 0.0 && l.is_finite() {
        let far = v * (l.max(reach) / l);
        if let Some(x) = first_change(field, end, far, end_inside) {
            return x;
        }
    }
    start
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::BSplineLattice;

    #[test]
    fn the_region_velocity_is_the_spline_of_its_coefficients_inside_the_box() {
        // ṗ = 1 on a box reproduces 1 where all 64 taps are inside it.
        let lattice = BSplineLattice::zeros([12; 3], 0.1, Vec3::ZERO).unwrap();
        let b = CoeffBox {
            min: [2, 2, 2],
            max: [9, 9, 9],
        };
        let p_dot = vec![1.0; b.count()];
        let v = RegionVelocity {
            origin: lattice.origin,
            spacing: lattice.spacing,
            coeffs: b,
            p_dot: &p_dot,
        };
        let inner = Vec3::splat(0.55);
        assert!((v.value(inner) - 1.0).abs() < 1e-5);
        let (val, grad) = v.value_and_gradient(inner);
        assert!((val - 1.0).abs() < 1e-5 && grad.length() < 1e-4);
        // Beyond the box's support the velocity is zero.
        assert_eq!(v.value(Vec3::new(0.0, 0.55, 0.55)), 0.0);
        // Near the box's edge it falls off (fixed coefficients beyond).
        let edge = v.value(Vec3::splat(0.2));
        assert!(edge > 0.0 && edge < 1.0, "{edge}");
    }

    #[test]
    fn without_springs_the_coast_time_is_mass_over_damping_and_capped() {
        assert!((coast_time_s(&[1.0; 4], &[40.0; 4], &[0.0; 4]) - 0.025).abs() < 1e-7);
        assert_eq!(coast_time_s(&[1.0; 4], &[0.0; 4], &[0.0; 4]), MAX_COAST_S);
        assert_eq!(coast_time_s(&[], &[], &[]), 0.0);
        assert_eq!(coast_time_s(&[f32::NAN], &[40.0], &[1000.0]), 0.0);
    }

    /// The first peak of the damped oscillator, found by stepping it finely.
    fn stepped_peak(m: f64, g: f64, k: f64) -> f64 {
        let dt = 1e-7;
        let (mut x, mut v) = (0.0_f64, 1.0_f64);
        while v > 0.0 {
            v += dt * (-(g * v) - k * x) / m;
            x += dt * v;
        }
        x
    }

    #[test]
    fn with_springs_the_coast_time_is_the_first_peak_of_the_damped_oscillator() {
        // Underdamped (the default clay), critical and overdamped.
        for (m, g, rho) in [
            (1.0, 40.0, 1000.0),
            (1.0, 40.0, 400.0 / 6.0),
            (1.0, 400.0, 1000.0),
        ] {
            let got = f64::from(coast_time_s(&[m; 3], &[g; 3], &[rho; 3]));
            let want = stepped_peak(f64::from(m), f64::from(g), 6.0 * f64::from(rho));
            assert!(
                (got - want).abs() < 1e-3 * want,
                "{m} {g} {rho}: {got} vs {want}"
            );
            assert!(got <= f64::from(m / g), "{got} past μ/γ");
        }
        // The default clay coasts about 9 ms, well short of μ/γ = 25 ms.
        let t = coast_time_s(&[1.0], &[40.0], &[1000.0]);
        assert!((0.0085..0.0097).contains(&t), "{t}");
        // A detail patch's material (all three scaled by its volume) coasts alike.
        let fine = coast_time_s(&[1.0 / 64.0], &[40.0 / 64.0], &[1000.0 / 64.0]);
        assert!((fine - t).abs() < 1e-6 * t.max(1.0), "{fine} vs {t}");
    }
}
