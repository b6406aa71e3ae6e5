//! Ferley et al.'s stamp deformation function `def(v)` (Fig. 11–12) and Zhang et al.'s contact
//! deformation `h = f + β·g` (§3, after Cani-Gascuel). Pure scalar functions: no allocation.
//!
//! Both take the tool's potential as a density `t` in `[0, 1]` with the surface at one half.
//! Ferley's `v` grows away from the tool's centre, so here `v = 1 − t`: `v = 0` at the core,
//! `v = s = 1/2` on the tool's surface, `v = 1` beyond the tool's influence, and the sum
//! `s + m + r` must stay within that range (`maxVal − minVal` in the paper).

use serde::{Deserialize, Serialize};

/// The five tunable parameters of Ferley's deformation function (Fig. 12).
///
/// `def(v)` runs from −1 at `v = 0` (remove everything at the tool's core) up to 0 at `v = s`
/// with slope `−k`, on to a bulge of height `n` at `v = s + m` (slope 0), and back down to 0
/// at `v = s + m + r` (slope 0), C¹ throughout. The formula is Ferley's as printed, whose
/// slope at `s` is `−k`: a wall rising out of the print has `k < 0` (the default is −2), and
/// `−k ≤ 3/s` keeps the first piece monotone.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct StampParams {
    /// Value of `v` where the deformation crosses zero (Ferley sets it to the iso-value).
    pub s: f32,
    /// Width of the rising part of the bulge.
    pub m: f32,
    /// Width of the falling part of the bulge.
    pub r: f32,
    /// Minus the slope at `v = s` (negative for a wall rising out of the print).
    pub k: f32,
    /// Bulge height (material pushed aside).
    pub n: f32,
    /// Whole stamps per second of dwell: a held stamp deepens with time, and holding twice as
    /// long does what two stamps do. Sessions saved before the rate existed read
    /// [`DEFAULT_DEFORM_RATE_PER_S`].
    #[serde(default = "default_deform_rate")]
    pub rate_per_s: f32,
}

/// Default rate of the stamp and contact tools: one whole application per 10 ms of dwell, what
/// one application of a live stroke gave before they scaled with dwell time.
pub const DEFAULT_DEFORM_RATE_PER_S: f32 = 100.0;

fn default_deform_rate() -> f32 {
    DEFAULT_DEFORM_RATE_PER_S
}

impl Default for StampParams {
    fn default() -> Self {
        Self {
            s: 0.5,
            m: 0.15,
            r: 0.25,
            k: -2.0,
            n: 0.3,
            rate_per_s: DEFAULT_DEFORM_RATE_PER_S,
        }
    }
}

/// Why stamp parameters were rejected.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("invalid stamp parameters: {0}")]
pub struct StampParamsError(pub String);

impl StampParams {
    /// Checks `s, m, r > 0`, `n ≥ 0`, all finite, and `s + m + r ≤ 1` (so the function is not
    /// truncated by the potential's range, as Ferley requires).
    ///
    /// # Errors
    /// Names the parameter that is out of range.
    pub fn validate(&self) -> Result<(), StampParamsError> {
        // (name, value, lower bound rule): "positive", "non-negative" or "any".
        for (name, v, rule) in [
            ("s", self.s, "positive"),
            ("m", self.m, "positive"),
            ("r", self.r, "positive"),
            ("k", self.k, "any"),
            ("n", self.n, "non-negative"),
            ("rate_per_s", self.rate_per_s, "positive"),
        ] {
            let ok = v.is_finite()
                && match rule {
                    "positive" => v > 0.0,
                    "non-negative" => v >= 0.0,
                    _ => true,
                };
            if !ok {
                let bound = if rule == "any" {
                    String::new()
                } else {
                    format!(" and {rule}")
                };
                return Err(StampParamsError(format!(
                    "{name} = {v} must be finite{bound}"
                )));
            }
        }
        let span = self.s + self.m + self.r;
        if span > 1.0 + 1e-6 {
            return Err(StampParamsError(format!(
                "s + m + r = {span} exceeds the potential's range 1"
            )));
        }
        Ok(())
    }

    /// Ferley's `def(v)` (Fig. 11).
    ///
    /// NOTE: the third piece is printed as `−2n/r³·v₀³ − 3n/m²·v₀² + n`, which neither reaches 0
    /// at `v₀ = r` nor joins with slope 0; the C¹ cubic the figure draws is
    /// `2n/r³·v₀³ − 3n/r²·v₀² + n`, used here.
    #[inline]
    #[must_use]
    pub fn def(&self, v: f32) -> f32 {
        let Self { s, m, r, k, n, .. } = *self;
        if v <= s {
            let v = v.max(0.0);
            -(s * k + 2.0) / (s * s * s) * v * v * v + (s * k + 3.0) / (s * s) * v * v - 1.0
        } else if v <= s + m {
            let v0 = v - s;
            -(k * m + 2.0 * n) / (m * m * m) * v0 * v0 * v0
                + (2.0 * k * m + 3.0 * n) / (m * m) * v0 * v0
                - k * v0
        } else if v <= s + m + r {
            let v0 = v - s - m;
            2.0 * n / (r * r * r) * v0 * v0 * v0 - 3.0 * n / (r * r) * v0 * v0 + n
        } else {
            0.0
        }
    }

    /// The stamped clay density at a point after a dwell of `dt_s`: `f + rate · dt · def(1 − t)`,
    /// kept within `[0, 1]`, with `t = tool` the potential over the user's band. Only the
    /// stamp's own change is limited: a density the fit left a little outside the range is not
    /// pulled back where the stamp does nothing, so two short applications do what one long
    /// one does. The bulge pushes clay aside and creates none: a rise is weighted by the
    /// clay's [`presence`] at the point (iso-level `iso`), so it grows from the surface and
    /// never in the air over the tool.
    ///
    /// `print` is the tool's potential over the band the lattice can hold (the carving tools'
    /// floor, [`crate::tools::MIN_FALLOFF_SPANS`] knot spans; equal to `tool` when the user's
    /// band is wider). The print tends to what removing the tool over that band leaves,
    /// `min(f, 1 − print)`, inside the tool and out: each whole application wears the clay
    /// down to it (inside, on top of `def`'s carve), and the bulge rises no higher than it.
    /// The print's wall is then as smooth as the clay's own, not a step of one half at the
    /// tool's surface, which the refit shrank the print on (a sphere of one knot span's
    /// radius printed 28% small, `tests/geometric_size.rs`). Where the lattice's band is the
    /// wider, a rise is also scaled by how much of the lattice's band remains outside the
    /// point against the user's, `(1 − 2·print) / (1 − 2·t)`: the bulge moves out of the
    /// print's wall instead of ringing in it.
    #[inline]
    #[must_use]
    pub fn apply(&self, clay: f32, tool: f32, print: f32, iso: f32, dt_s: f32) -> f32 {
        let v = 1.0 - tool;
        let applications = self.rate_per_s * dt_s.max(0.0);
        let change = applications * self.def(v);
        let in_tool = v <= self.s;
        let wear = |d: f32| applications.min(1.0) * (d - d.min(1.0 - print)).max(0.0);
        let change = if in_tool {
            change.min(-wear(clay))
        } else if change > 0.0 {
            change * ((1.0 - 2.0 * print) / (1.0 - 2.0 * tool)).clamp(0.0, 1.0)
        } else {
            change
        };
        let new = limited_change(clay, pushed_aside(change, clay, iso, in_tool));
        let new = if in_tool { new } else { new - wear(new) };
        no_sharper_than_the_tool(new, clay, print, in_tool)
    }
}

/// Zhang et al.'s contact deformation (§3): `h = f + β·g` with `g = α (f_tool − c)`.
///
/// With `t` the tool's potential and `c` the iso-level: inside the tool (`t ≥ c`, the contact
/// region) `β = 1`; outside, `β = t / c`, which meets the inside with matching value (0) and
/// slope (`α`), so the surface is C¹ across the tool boundary; it fades to zero with the
/// tool's potential. α < 0 dents the clay and raises a rim around the dent; α > 0 bulges it.
/// The deformation moves the surface and neither creates nor cuts clay away from the tool:
/// inside it a dent goes no deeper and a bulge no higher than the tool's own shape; outside
/// it a rise (a dent's rim) is weighted by the clay's [`presence`], so material grows only
/// from the surface outward, never as a speck in the air where the fit's density is a little
/// above zero, and a fall (a bulge's moat) by the clay's [`exposure`], so it wears the surface
/// in and never cuts a shell that would set the bulge loose (one connected clay at every α).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ContactParams {
    /// Strength and sign: negative dents, positive bulges.
    pub alpha: f32,
    /// Whole applications per second of dwell (see [`StampParams::rate_per_s`]).
    #[serde(default = "default_deform_rate")]
    pub rate_per_s: f32,
}

impl ContactParams {
    /// The strongest contact a tool takes, either way: at `|α| = 3` one whole application
    /// already moves a density by up to 1.5, more than its whole range, so a stronger α only
    /// makes the tool faster than its rate says.
    pub const MAX_ALPHA: f32 = 3.0;

    /// Contact deformation of strength `alpha` at the default rate.
    #[must_use]
    pub fn with_alpha(alpha: f32) -> Self {
        Self {
            alpha,
            rate_per_s: DEFAULT_DEFORM_RATE_PER_S,
        }
    }

    /// The deformed clay density `h = f + rate · dt · β·g` after a dwell of `dt_s`, kept within
    /// `[0, 1]` as [`StampParams::apply`] keeps it.
    #[inline]
    #[must_use]
    pub fn apply(&self, clay: f32, tool: f32, iso: f32, dt_s: f32) -> f32 {
        if tool <= 0.0 {
            return clay;
        }
        let g = self.alpha * (tool - iso);
        let beta = if tool >= iso { 1.0 } else { tool / iso };
        let change = self.rate_per_s * dt_s.max(0.0) * beta * g;
        let in_tool = tool >= iso;
        let new = limited_change(clay, pushed_aside(change, clay, iso, in_tool));
        no_sharper_than_the_tool(new, clay, tool, in_tool)
    }
}

/// How much clay is at a point of density `clay` for a deformation to push aside, in
/// `[0, 1]`: 1 from the iso-level on (the clay), 0 below an eighth of it (air, and the fit's
/// small density around the clay, which never grows however long a tool dwells), and between
/// the smooth step `3x² − 2x³` of `x = clay / iso`, lowered to meet 0 at the floor. Only the
/// band just outside the surface lies between, and every point of it is next to the clay, so
/// a rise weighted by it grows the surface outward and cannot start an island. The step spans
/// the whole band so that the weighted change is as smooth across it as the clay.
#[inline]
#[must_use]
pub fn presence(clay: f32, iso: f32) -> f32 {
    floored_smoothstep(clay / iso.max(f32::EPSILON))
}

/// How open a point of density `clay` is to the outside, in `[0, 1]`: 1 up to the
/// iso-level, 0 from seven eighths of the way to full density on (deep in the clay), and
/// between the mirror of [`presence`]'s step. A fall weighted by it wears the surface in from
/// outside and cannot cut a shell through the inside of the clay.
#[inline]
#[must_use]
pub fn exposure(clay: f32, iso: f32) -> f32 {
    floored_smoothstep((1.0 - clay) / (1.0 - iso).max(f32::EPSILON))
}

/// Below this fraction of the iso-level a deformation creates no clay (and above the same
/// fraction of the way down from full density it cuts none): the fit's ripple around a
/// solid stays under it.
const PUSH_FLOOR: f32 = 0.125;

/// `(s(x) − s(PUSH_FLOOR)) / (1 − s(PUSH_FLOOR))`, kept to `[0, 1]`, with `s` the smooth step
/// `3x² − 2x³` of `x` clamped to `[0, 1]`: 0 up to the floor, 1 from `x = 1`.
#[inline]
fn floored_smoothstep(x: f32) -> f32 {
    let s = |x: f32| {
        let x = x.clamp(0.0, 1.0);
        x * x * (3.0 - 2.0 * x)
    };
    let floor = s(PUSH_FLOOR);
    ((s(x) - floor) / (1.0 - floor)).max(0.0)
}

/// A deformation's `change` at a point of density `clay`. Inside the tool (`in_tool`: the
/// print, the dent, the bulge) as it is: there [`no_sharper_than_the_tool`] bounds it by the
/// tool's own shape, and that shape touches the clay it deforms. Outside the tool (the skirt:
/// a dent's rim, a bulge's moat, a stamp's dip and rise) a rise is weighted by the clay's
/// [`presence`] (deformations push clay aside; they do not create it in the air) and a fall
/// by its [`exposure`], so the skirt moves the surface and never cuts the clay under it loose.
///
/// A rise inside the tool weighted by presence too made a bulge depend on the clay's slope
/// across its surface, which earlier strokes change: a compact RBF of the clay (re-interpolated
/// as a signed distance after each action, Zhang §5.4) then ended 1.0% of the sphere's
/// diagonal from the lattice after fifty contacts instead of 0.7% (`tests/rbf_sculpt.rs`).
#[inline]
fn pushed_aside(change: f32, clay: f32, iso: f32, in_tool: bool) -> f32 {
    if in_tool {
        change
    } else if change > 0.0 {
        change * presence(clay, iso)
    } else {
        change * exposure(clay, iso)
    }
}

/// Inside the tool (`in_tool`), a deformation's `new` density kept between what removing the
/// tool's shape and adding it would leave: never below `min(clay, 1 − tool)` nor above
/// `max(clay, tool)`. Held or dragged, a print or a dent tends to the tool's own shape, whose
/// potential falls over the whole falloff band, instead of a step the refit would ring on.
#[inline]
fn no_sharper_than_the_tool(new: f32, clay: f32, tool: f32, in_tool: bool) -> f32 {
    if !in_tool || new == clay {
        new
    } else if new < clay {
        new.max(clay.min(1.0 - tool))
    } else {
        new.min(clay.max(tool))
    }
}

/// `clay + change`, with the change cut so that the result stays in `[0, 1]` when the clay
/// was; the clay itself is not clamped (zero change leaves it bit-identical).
#[inline]
fn limited_change(clay: f32, change: f32) -> f32 {
    if change == 0.0 {
        return clay;
    }
    let from = clay.clamp(0.0, 1.0);
    clay + ((from + change).clamp(0.0, 1.0) - from)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn derivative(p: &StampParams, v: f32) -> f32 {
        let h = 1e-3;
        (p.def(v + h) - p.def(v - h)) / (2.0 * h)
    }

    #[test]
    fn def_hits_the_control_values_of_fig_12() {
        let p = StampParams::default();
        p.validate().unwrap();
        assert!((p.def(0.0) + 1.0).abs() < 1e-6);
        assert!(p.def(p.s).abs() < 1e-5);
        assert!((p.def(p.s + p.m) - p.n).abs() < 1e-5);
        assert!(p.def(p.s + p.m + p.r).abs() < 1e-5);
        assert_eq!(p.def(0.99), 0.0);
        assert!((derivative(&p, p.s) + p.k).abs() < 1e-2);
        assert!(derivative(&p, p.s + p.m).abs() < 1e-2);
        assert!(derivative(&p, 1e-3).abs() < 5e-2);
    }

    /// Inside the tool the stamp carves; just outside it raises the clay that is there into a
    /// rim, and nothing where there is no clay (a shell around the tool in empty space).
    #[test]
    fn the_stamp_raises_a_rim_only_where_there_is_clay() {
        let p = StampParams::default();
        let (iso, dt) = (0.5, 0.01);
        assert!(
            p.apply(0.9, 0.9, 0.9, iso, dt) < 0.9,
            "carves inside the tool"
        );
        // Outside the tool's surface, in the bulge: def > 0. (The rim rises no higher than
        // `1 − print` there, the print's own wall: 0.8.)
        let t = 0.2;
        assert!(p.def(1.0 - t) > 0.0);
        assert!(p.apply(0.6, t, t, iso, dt) > 0.6, "a rim in the clay");
        assert_eq!(p.apply(0.0, t, t, iso, dt), 0.0, "nothing in empty space");
        assert_eq!(
            p.apply(0.01, t, t, iso, 100.0),
            0.01,
            "nor in the fit's ripple"
        );
        assert!(
            p.apply(0.3, t, t, iso, dt) > 0.3,
            "the clay's outer band rises"
        );
        assert_eq!(presence(0.06, iso), 0.0);
        assert_eq!(presence(0.5, iso), 1.0);
        assert!((presence(0.25, iso) - (0.5 - 0.043) / (1.0 - 0.043)).abs() < 1e-3);
    }

    #[test]
    fn def_is_continuous_at_every_joint() {
        let p = StampParams {
            s: 0.4,
            m: 0.2,
            r: 0.3,
            k: -3.0,
            n: 0.5,
            ..StampParams::default()
        };
        for joint in [p.s, p.s + p.m, p.s + p.m + p.r] {
            let e = 1e-4;
            assert!(
                (p.def(joint - e) - p.def(joint + e)).abs() < 1e-2,
                "jump at {joint}"
            );
            let h = 1e-3;
            let left = (p.def(joint) - p.def(joint - h)) / h;
            let right = (p.def(joint + h) - p.def(joint)) / h;
            assert!(
                (left - right).abs() < 0.1,
                "kink at {joint}: {left} vs {right}"
            );
        }
    }

    #[test]
    fn bad_stamp_parameters_are_named() {
        let e = StampParams {
            s: 0.5,
            m: 0.4,
            r: 0.3,
            ..StampParams::default()
        }
        .validate()
        .unwrap_err();
        assert!(e.0.contains("s + m + r"));
        let e = StampParams {
            k: f32::NAN,
            ..StampParams::default()
        }
        .validate()
        .unwrap_err();
        assert!(e.0.starts_with("k ="));
    }

    #[test]
    fn deformations_push_clay_aside_and_never_grow_it_in_the_air() {
        let iso = 0.5;
        let dent = ContactParams::with_alpha(-ContactParams::MAX_ALPHA);
        let bulge = ContactParams::with_alpha(ContactParams::MAX_ALPHA);
        let stamp = StampParams::default();
        // Where the stamp's bulge peaks (v = s + m).
        let t_bulge = 1.0 - (stamp.s + stamp.m);
        // Air and the fit's small density around the clay, held for ten seconds in the rim of
        // a dent and in a stamp's bulge (both outside the tool): nothing grows. Inside a
        // bulging tool the clay grows to the tool's own shape and no further.
        for f in [0.0, 0.01, 0.05, 0.0625] {
            assert_eq!(dent.apply(f, 0.25, iso, 10.0), f, "rim at {f}");
            assert_eq!(
                stamp.apply(f, t_bulge, t_bulge, iso, 10.0),
                f,
                "stamp at {f}"
            );
            assert_eq!(bulge.apply(f, 0.9, iso, 10.0), 0.9, "bulge at {f}");
        }
        // The moat around a bulge wears the surface in and never cuts deep inside the clay.
        for f in [0.9375, 0.97, 1.0] {
            assert_eq!(bulge.apply(f, 0.25, iso, 10.0), f, "moat at {f}");
        }
        assert!(bulge.apply(0.55, 0.25, iso, 0.01) < 0.55);
        // A dent inside the tool goes as deep as the tool, and no sharper: held for ten
        // seconds it leaves what removing the tool's shape leaves, and a bulge what adding it
        // leaves.
        assert_eq!(dent.apply(1.0, 0.9, iso, 10.0), 1.0 - 0.9);
        assert_eq!(dent.apply(1.0, 0.55, iso, 10.0), 1.0 - 0.55);
        assert_eq!(bulge.apply(0.45, 0.8, iso, 10.0), 0.8);
        assert_eq!(stamp.apply(1.0, 0.9, 0.9, iso, 10.0), 1.0 - 0.9);
        // At the surface they rise as before.
        assert!(dent.apply(0.45, 0.25, iso, 0.01) > 0.45);
        assert!(bulge.apply(0.45, 0.9, iso, 0.01) > 0.45);
        assert!(stamp.apply(0.45, t_bulge, t_bulge, iso, 0.01) > 0.45);
        assert_eq!(presence(0.0625, iso), 0.0);
        assert_eq!(exposure(0.9375, iso), 0.0);
        assert_eq!(exposure(0.5, iso), 1.0);
        assert_eq!(presence(0.5, iso), 1.0);
        assert!(presence(0.4, iso) > presence(0.3, iso));
    }

    #[test]
    fn contact_dents_inside_raises_a_rim_and_is_c1_at_the_tool_surface() {
        let dent = ContactParams::with_alpha(-2.0);
        let iso = 0.5;
        assert!(
            dent.apply(0.8, 0.9, iso, 0.01) < 0.8,
            "dent inside the tool"
        );
        assert!(dent.apply(0.4, 0.3, iso, 0.01) > 0.4, "rim just outside");
        assert_eq!(
            dent.apply(0.4, 0.0, iso, 0.01),
            0.4,
            "untouched beyond the tool"
        );
        assert_eq!(
            dent.apply(0.0, 0.9, iso, 0.01),
            0.0,
            "no clay created in air"
        );
        let e = 1e-3;
        let slope = |t: f32| {
            (dent.apply(0.6, t + e, iso, 0.01) - dent.apply(0.6, t - e, iso, 0.01)) / (2.0 * e)
        };
        assert!((slope(iso - 0.01) - slope(iso + 0.01)).abs() < 0.1);
        let bulge = ContactParams::with_alpha(2.0);
        assert!(bulge.apply(0.6, 0.9, iso, 0.01) > 0.6);
    }
}
