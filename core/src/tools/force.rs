//! Force-based tools (Hua & Qin §7.2): each turns the user's input for one tick into force
//! vectors ([`ToolForce`]) that the dynamics integrates (eq. 6) and spreads over mass points.
//!
//! Every vector ends where the tool wants the surface (the cursor, a track's end, a chisel's
//! target) and the simulation drives the surface there and stops it there (a closed loop on
//! the surface position: `dynamics::coast` and `Simulator::gather_forces`). A grab, pull or
//! area tool whose cursor is pressed into the clay (as the window's pointer presses) brings
//! the surface down to the cursor along the clay's normal where the stroke took hold; held
//! outside the clay, it draws the surface out toward the cursor.
//!
//! Real-time contract: [`ForceTool::forces`] allocates nothing, takes no lock and does bounded
//! work (at most `out.len()` force vectors, each found with a bounded ray search), so the
//! engine may call it on the haptic or the simulation thread every tick. Paths and curves are
//! plain slices the engine owns. One stroke (button down to up) is one undo step: the engine
//! touches the region in a [`super::StepRecorder`] before the first step of the stroke.

use glam::Vec3;

use crate::dynamics::{Distribution, ToolForce};
use crate::field::MultiPatchField;

/// Which force tool, with its parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ForceTool {
    /// Grab the nearest mass point in the solid and drag it toward the cursor (or, with the
    /// cursor pressed into the clay, bring the surface down to it).
    PointGrab { gain: f32 },
    /// Grab a patch of mass points: parallel tracks over a disc of `radius_fu` around the
    /// grabbed point, across the clay's normal there, each weighted by `distribution`'s
    /// profile at its offset; every track ends at the cursor's offset, so the patch comes to
    /// the cursor's level (drawn out, or pressed down) and the surface stays a height field
    /// over the disc.
    Area {
        distribution: Distribution,
        radius_fu: f32,
        /// Tracks per disc diameter (the disc holds about `π/4 · tracks²` of them).
        tracks: u32,
        gain: f32,
    },
    /// A force along a user curve: every curve sample moves with the cursor's displacement.
    Curve { radius_fu: f32, gain: f32 },
    /// Fixed shallow penetration `depth_fu` along the inward surface normal at every path
    /// sample (plan the stroke's targets with [`plan_penetration`]).
    Chisel {
        depth_fu: f32,
        radius_fu: f32,
        gain: f32,
    },
    /// The chisel's opposite: material raised `depth_fu` along the outward normal.
    Squirt {
        depth_fu: f32,
        radius_fu: f32,
        gain: f32,
    },
    /// Pull a region with the spread `distribution` (Hua & Qin Fig. 10).
    Pull {
        distribution: Distribution,
        radius_fu: f32,
        gain: f32,
    },
    /// Bend about `pivot`: samples along pivot → grab point rotate with the cursor, so their
    /// displacement grows linearly with the distance from the pivot.
    Bend {
        samples: u32,
        radius_fu: f32,
        gain: f32,
    },
}

/// The user's input for one tick.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ForceInput<'a> {
    /// Where the stroke grabbed the clay (from [`nearest_solid_point`] at button down).
    pub grab: Vec3,
    /// The cursor now.
    pub cursor: Vec3,
    /// The pivot of a bend.
    pub pivot: Vec3,
    /// The user curve (curve tool), world points.
    pub path: &'a [Vec3],
    /// The fixed targets of a chisel or squirt stroke, from [`plan_penetration`].
    pub targets: &'a [PenetrationTarget],
    /// Outward unit normal of the clay where the stroke took hold ([`anchor_normal`] at the
    /// grab); zero when unknown. The grab, pull and area tools use it when the cursor is
    /// pressed into the clay: the surface then comes down to the cursor along it.
    pub normal: Vec3,
}

/// How far above a cursor pressed into the clay the grab, pull and area tools look for the
/// surface that must come down to it, knot spans.
pub const PRESS_REACH_SPANS: f32 = 6.0;

/// The outward unit normal of the clay at `x` for a stroke that takes hold there: the
/// direction the density falls fastest, or — where the density is flat (deep inside) — the
/// axis direction along which the clay ends soonest (within [`PRESS_REACH_SPANS`] knot spans);
/// zero when neither is found. Bounded: at most `1 + 6 · 12` field evaluations.
#[must_use]
pub fn anchor_normal(field: &MultiPatchField, x: Vec3) -> Vec3 {
    let (_, g) = field.value_and_gradient(x);
    // A gradient worth trusting: at least a tenth of the iso-level per knot span.
    let spacing = field.finest_spacing();
    if g.is_finite() && g.length() * spacing > 0.1 * field.iso() {
        return (-g).normalize_or_zero();
    }
    const STEPS: u32 = 12;
    let reach = PRESS_REACH_SPANS * spacing;
    let mut best: Option<(u32, Vec3)> = None;
    for dir in [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z] {
        let exit =
            (1..=STEPS).find(|&i| !field.is_inside(x + dir * (reach * i as f32 / STEPS as f32)));
        if let Some(i) = exit
            && best.is_none_or(|(b, _)| i < b)
        {
            best = Some((i, dir));
        }
    }
    best.map_or(Vec3::ZERO, |(_, d)| d)
}

/// Where a chisel or squirt stroke wants the surface: `depth` along the normal from where the
/// path met the surface at the stroke's start.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PenetrationTarget {
    pub target: Vec3,
    /// Outward unit normal of the surface at the path sample when planned.
    pub normal: Vec3,
    /// The set depth, field units.
    pub depth_fu: f32,
}

/// Plans a chisel (`squirt == false`: inward) or squirt (outward) stroke over `path`: each
/// sample is moved onto the surface and its target set `depth_fu` along the normal. Called once
/// per stroke (it allocates); samples where the field has no gradient are skipped.
#[must_use]
pub fn plan_penetration(
    field: &MultiPatchField,
    path: &[Vec3],
    depth_fu: f32,
    squirt: bool,
) -> Vec<PenetrationTarget> {
    plan_penetration_along(field, path, depth_fu, squirt, Vec3::ZERO)
}

/// [`plan_penetration`] for a stroke that took hold with the outward normal `along` (zero:
/// unknown): each sample is moved onto the surface along that line first — a tip pressed
/// deep into the clay, where the density is flat and has no gradient to follow, still finds
/// the surface above it — and by the gradient where the line meets no surface within
/// [`PRESS_REACH_SPANS`] knot spans.
#[must_use]
pub fn plan_penetration_along(
    field: &MultiPatchField,
    path: &[Vec3],
    depth_fu: f32,
    squirt: bool,
    along: Vec3,
) -> Vec<PenetrationTarget> {
    let sign = if squirt { 1.0 } else { -1.0 };
    path.iter()
        .filter_map(|&p| {
            let x0 =
                surface_on_line(field, p, along).unwrap_or_else(|| project_to_surface(field, p));
            let normal = outward_normal(field, x0);
            (normal != Vec3::ZERO).then_some(PenetrationTarget {
                target: x0 + sign * depth_fu * normal,
                normal,
                depth_fu,
            })
        })
        .collect()
}

/// The surface crossing on the line through `p` along the unit vector `n`, within
/// [`PRESS_REACH_SPANS`] knot spans: outward from a point inside the clay, inward from one
/// outside. `None` for a zero `n` or no crossing. Bounded: 24 + 20 evaluations.
fn surface_on_line(field: &MultiPatchField, p: Vec3, n: Vec3) -> Option<Vec3> {
    if n == Vec3::ZERO || !p.is_finite() {
        return None;
    }
    let reach = PRESS_REACH_SPANS * field.finest_spacing();
    let inside = field.is_inside(p);
    let dir = if inside { n } else { -n };
    const STEPS: u32 = 24;
    let mut near = 0.0_f32;
    for i in 1..=STEPS {
        let t = reach * i as f32 / STEPS as f32;
        if field.is_inside(p + dir * t) != inside {
            let mut far = t;
            for _ in 0..20 {
                let mid = 0.5 * (near + far);
                if field.is_inside(p + dir * mid) == inside {
                    near = mid;
                } else {
                    far = mid;
                }
            }
            return Some(p + dir * (0.5 * (near + far)));
        }
        near = t;
    }
    None
}

/// The surface crossing on the line `target + λ·normal`, `λ ∈ [−2·depth, 2·depth]`, nearest
/// the outside end; the window's end when the line does not cross. Bounded: 16 + 20
/// evaluations.
fn crossing_on_line(field: &MultiPatchField, t: &PenetrationTarget) -> Vec3 {
    let reach = 2.0 * t.depth_fu;
    let at = |l: f32| t.target + l * t.normal;
    let inside = |l: f32| field.is_inside(at(l));
    const STEPS: u32 = 16;
    let step = 2.0 * reach / STEPS as f32;
    // Walk inward from the outside end to the first inside sample.
    let mut outer = reach;
    if inside(outer) {
        return at(outer);
    }
    for s in 1..=STEPS {
        let l = reach - s as f32 * step;
        if inside(l) {
            let (mut lo, mut hi) = (l, outer);
            for _ in 0..20 {
                let m = 0.5 * (lo + hi);
                if inside(m) {
                    lo = m;
                } else {
                    hi = m;
                }
            }
            return at(0.5 * (lo + hi));
        }
        outer = l;
    }
    at(-reach)
}

/// The point closest to `cursor` inside the solid among the points of a grid of pitch
/// `step_fu` within `search_fu` of the cursor (the nearest mass point when `step_fu` is the mass
/// spacing). Bounded work: at most `(2·search_fu/step_fu + 1)³` evaluations (capped at 33³).
#[must_use]
pub fn nearest_solid_point(
    field: &MultiPatchField,
    cursor: Vec3,
    search_fu: f32,
    step_fu: f32,
) -> Option<Vec3> {
    if !(step_fu > 0.0 && search_fu >= 0.0 && cursor.is_finite()) {
        return None;
    }
    let n = ((search_fu / step_fu).ceil() as i32).min(16);
    // Snap to the grid the mass points lie on (through the field origin).
    let base = field.base().origin + ((cursor - field.base().origin) / step_fu).round() * step_fu;
    let mut best: Option<(f32, Vec3)> = None;
    for k in -n..=n {
        for j in -n..=n {
            for i in -n..=n {
                let x = base + Vec3::new(i as f32, j as f32, k as f32) * step_fu;
                let d = x.distance_squared(cursor);
                if d <= search_fu * search_fu + 1e-12
                    && best.is_none_or(|(b, _)| d < b)
                    && field.is_inside(x)
                {
                    best = Some((d, x));
                }
            }
        }
    }
    best.map(|(_, x)| x)
}

/// Density above the iso-level at which a track's start counts as fully held.
const HOLD_BAND: f32 = 0.25;

/// How firmly the clay holds a point: 0 at or outside the surface, rising linearly to 1 at
/// [`HOLD_BAND`] of density above the iso-level.
#[must_use]
pub fn hold_weight(field: &MultiPatchField, x: Vec3) -> f32 {
    ((field.value(x) - field.iso()) / HOLD_BAND).clamp(0.0, 1.0)
}

/// The outward unit normal of the solid at `x` (the density falls outward), or zero.
#[must_use]
pub fn outward_normal(field: &MultiPatchField, x: Vec3) -> Vec3 {
    (-field.value_and_gradient(x).1).normalize_or_zero()
}

/// Moves `x` onto the iso-surface by a few Newton steps along the gradient (bounded work).
#[must_use]
pub fn project_to_surface(field: &MultiPatchField, mut x: Vec3) -> Vec3 {
    for _ in 0..6 {
        let (v, g) = field.value_and_gradient(x);
        let g2 = g.length_squared();
        // Also stops on NaN.
        if g2.is_nan() || g2 <= 1e-12 {
            break;
        }
        let step = (v - field.iso()) * g / g2;
        // Keep each step within a knot span so a flat region cannot throw the point away.
        x -= step.clamp_length_max(field.finest_spacing());
    }
    x
}

/// Why a force tool's parameters were rejected.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("invalid force tool: {0}")]
pub struct ForceToolError(pub String);

impl ForceTool {
    /// Short name for menus and undo labels.
    #[must_use]
    pub fn name(&self) -> &'static str {
        match self {
            Self::PointGrab { .. } => "grab",
            Self::Area { .. } => "area",
            Self::Curve { .. } => "curve",
            Self::Chisel { .. } => "chisel",
            Self::Squirt { .. } => "squirt",
            Self::Pull { .. } => "pull",
            Self::Bend { .. } => "bend",
        }
    }

    /// The tool's gain (density force per unit of force integral).
    #[must_use]
    pub fn gain(&self) -> f32 {
        match *self {
            Self::PointGrab { gain }
            | Self::Area { gain, .. }
            | Self::Curve { gain, .. }
            | Self::Chisel { gain, .. }
            | Self::Squirt { gain, .. }
            | Self::Pull { gain, .. }
            | Self::Bend { gain, .. } => gain,
        }
    }

    /// The tool's spread radius, field units (`None` for the point grab, which has none).
    #[must_use]
    pub fn radius_fu(&self) -> Option<f32> {
        match *self {
            Self::PointGrab { .. } => None,
            Self::Area { radius_fu, .. }
            | Self::Curve { radius_fu, .. }
            | Self::Chisel { radius_fu, .. }
            | Self::Squirt { radius_fu, .. }
            | Self::Pull { radius_fu, .. }
            | Self::Bend { radius_fu, .. } => Some(radius_fu),
        }
    }

    /// Checks that radii, depths and gains are positive and finite.
    ///
    /// # Errors
    /// Names the parameter.
    pub fn validate(&self) -> Result<(), ForceToolError> {
        let check = |name: &str, v: f32| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(ForceToolError(format!(
                    "{name} must be positive and finite, got {v}"
                )))
            }
        };
        match *self {
            Self::PointGrab { gain } => check("gain", gain),
            Self::Area {
                radius_fu,
                tracks,
                gain,
                ..
            } => {
                check("radius_fu", radius_fu)?;
                check("gain", gain)?;
                if tracks == 0 {
                    return Err(ForceToolError("tracks must be at least 1".into()));
                }
                Ok(())
            }
            Self::Curve { radius_fu, gain }
            | Self::Pull {
                radius_fu, gain, ..
            }
            | Self::Bend {
                radius_fu, gain, ..
            } => {
                check("radius_fu", radius_fu)?;
                check("gain", gain)
            }
            Self::Chisel {
                depth_fu,
                radius_fu,
                gain,
            }
            | Self::Squirt {
                depth_fu,
                radius_fu,
                gain,
            } => {
                check("depth_fu", depth_fu)?;
                check("radius_fu", radius_fu)?;
                check("gain", gain)
            }
        }
    }

    /// Writes this tick's force vectors into `out` and returns how many (never more than
    /// `out.len()`; extra tracks or path samples are dropped). Allocates nothing.
    pub fn forces(
        &self,
        field: &MultiPatchField,
        input: &ForceInput,
        out: &mut [ToolForce],
    ) -> usize {
        let spacing = field.finest_spacing();
        let mut n = 0;
        let mut push = |f: ToolForce| {
            if n < out.len() && f.start.is_finite() && f.end.is_finite() {
                out[n] = f;
                n += 1;
            }
        };
        let drag = input.cursor - input.grab;
        let reach = PRESS_REACH_SPANS * spacing;
        // A vector's start for a cursor (or a track's end) `end` held from `from`: with the
        // cursor pressed into the clay the surface comes down to it along the stroke's normal
        // (the vector starts above it, a push); otherwise from the grab toward the cursor.
        let pressed = |from: Vec3, end: Vec3| {
            if input.normal != Vec3::ZERO && field.is_inside(end) {
                end + input.normal * reach
            } else {
                from
            }
        };
        match *self {
            Self::PointGrab { gain } => {
                // Half a knot span: the spread reaches the grabbed mass point only.
                push(ToolForce {
                    start: pressed(input.grab, input.cursor),
                    end: input.cursor,
                    distribution: Distribution::Constant,
                    radius: 0.5 * spacing,
                    gain,
                });
            }
            Self::Pull {
                distribution,
                radius_fu,
                gain,
            } => push(ToolForce {
                start: pressed(input.grab, input.cursor),
                end: input.cursor,
                distribution,
                radius: radius_fu,
                gain,
            }),
            Self::Area {
                distribution,
                radius_fu,
                tracks,
                gain,
            } => {
                // A disc of track offsets across the stroke's normal (the clay's tangent plane
                // where it took hold), or across the drag when the normal is unknown. Across
                // the normal every track ends at the cursor's depth: a drag along the clay
                // moves a patch of surface to the cursor's level, never a wall of tracks
                // reaching under the surface (which hollowed it into an overhang).
                let axis = if input.normal == Vec3::ZERO {
                    drag.normalize_or(Vec3::Z)
                } else {
                    input.normal
                };
                // Where a track is held: a knot span below its start along the normal, so a
                // patch carved down to the grab's depth still holds its tracks.
                let hold_depth = if input.normal == Vec3::ZERO {
                    Vec3::ZERO
                } else {
                    input.normal * spacing
                };
                let (u, v) = axis.any_orthonormal_pair();
                let t = tracks.max(1) as i32;
                let pitch = 2.0 * radius_fu / t as f32;
                for b in 0..t {
                    for a in 0..t {
                        let o = (a as f32 + 0.5 - 0.5 * t as f32) * pitch * u
                            + (b as f32 + 0.5 - 0.5 * t as f32) * pitch * v;
                        // The track's weight is the β profile at its offset, times how firmly
                        // its start is held in the clay: a track whose start the clay has
                        // left holds nothing, and fades out instead of dropping (its vector
                        // would otherwise jump from the short re-found one to the whole
                        // segment in open air).
                        let w = distribution.weight(o, Vec3::ZERO, Vec3::ZERO, radius_fu)
                            * hold_weight(field, input.grab + o - hold_depth);
                        if w <= 0.0 {
                            continue;
                        }
                        push(ToolForce {
                            start: pressed(input.grab + o, input.cursor + o),
                            end: input.cursor + o,
                            distribution: Distribution::Constant,
                            radius: 0.5 * pitch.max(spacing),
                            gain: gain * w,
                        });
                    }
                }
            }
            Self::Curve { radius_fu, gain } => {
                for &p in input.path {
                    push(ToolForce {
                        start: p,
                        end: p + drag,
                        distribution: Distribution::Gaussian,
                        radius: radius_fu,
                        gain,
                    });
                }
            }
            Self::Chisel {
                radius_fu, gain, ..
            }
            | Self::Squirt {
                radius_fu, gain, ..
            } => {
                // From the surface as it is now to the fixed target: the integral vanishes as
                // the surface reaches the set depth, and reverses if it overshoots.
                for t in input.targets {
                    push(ToolForce {
                        start: crossing_on_line(field, t),
                        end: t.target,
                        distribution: Distribution::Gaussian,
                        radius: radius_fu,
                        gain,
                    });
                }
            }
            Self::Bend {
                samples,
                radius_fu,
                gain,
            } => {
                let arm = input.grab - input.pivot;
                let len = arm.length();
                if len > 0.0 {
                    let rotation = glam::Quat::from_rotation_arc(
                        arm / len,
                        (input.cursor - input.pivot).normalize_or(arm / len),
                    );
                    let s = samples.max(1);
                    for i in 1..=s {
                        let p = input.pivot + arm * (i as f32 / s as f32);
                        let q = input.pivot + rotation * (p - input.pivot);
                        push(ToolForce {
                            start: p,
                            end: q,
                            distribution: Distribution::Gaussian,
                            radius: radius_fu,
                            gain,
                        });
                    }
                }
            }
        }
        n
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dynamics::{Material, RegionState, Simulator, StepParams, surface_point_on_ray};
    use crate::field::BSplineLattice;
    use crate::field::MultiPatchField;
    use crate::field::{CoeffBox, Primitive, RegionSnapshot, lattice_from_primitive};
    use crate::tools::{Clay, FieldId, History, StepRecorder};

    const CENTRE: Vec3 = Vec3::new(0.95, 0.95, 0.95);
    const RADIUS: f32 = 0.4;

    fn sphere() -> BSplineLattice {
        let s = Primitive::Sphere {
            centre: CENTRE,
            radius: RADIUS,
        };
        lattice_from_primitive([20, 20, 20], 0.1, Vec3::ZERO, &s, 0.2, 2).unwrap()
    }

    fn radius_along(lattice: &BSplineLattice, dir: Vec3) -> f32 {
        surface_point_on_ray(lattice, CENTRE, dir, 0.9, 0.005)
            .map_or(0.0, |p| (p - CENTRE).length())
    }

    fn input<'a>(grab: Vec3, cursor: Vec3, targets: &'a [PenetrationTarget]) -> ForceInput<'a> {
        ForceInput {
            grab,
            cursor,
            pivot: Vec3::ZERO,
            path: &[],
            targets,
            normal: Vec3::ZERO,
        }
    }

    /// Runs a chisel or squirt stroke at the +x pole through the dynamics; returns the pole's
    /// radius before and after, and checks the stroke undoes bit for bit.
    fn penetrate(squirt: bool, depth_fu: f32) -> (f32, f32) {
        let mut clay = Clay::single(sphere());
        let before_bits = clay.clone();
        let r0 = radius_along(&clay.density.patches[0].lattice, Vec3::X);
        let region = CoeffBox {
            min: [10, 6, 6],
            max: [17, 13, 13],
        };
        let material = Material {
            yield_density: 0.0,
            ..Material::PLASTIC
        };
        let mut state = RegionState::new(
            &clay.density.patches[0].lattice,
            region,
            [15, 15, 15],
            material,
        )
        .unwrap();
        let mut sim = Simulator::new(StepParams::default());
        let mut snap = RegionSnapshot::default();
        let tool = if squirt {
            ForceTool::Squirt {
                depth_fu,
                radius_fu: 0.12,
                gain: 1e6,
            }
        } else {
            ForceTool::Chisel {
                depth_fu,
                radius_fu: 0.12,
                gain: 1e6,
            }
        };
        tool.validate().unwrap();
        // A short path across the pole.
        let path: Vec<Vec3> = (-1..=1)
            .map(|s| CENTRE + Vec3::new(RADIUS, s as f32 * 0.03, 0.0))
            .collect();
        let targets = plan_penetration(&clay.density, &path, depth_fu, squirt);
        assert_eq!(targets.len(), 3);
        let mut recorder = StepRecorder::new(tool.name());
        recorder.touch(&clay, FieldId::Density(0), region);
        let mut out = [ToolForce {
            start: Vec3::ZERO,
            end: Vec3::ZERO,
            distribution: Distribution::Constant,
            radius: 1.0,
            gain: 0.0,
        }; 8];
        for _ in 0..3000 {
            let n = tool.forces(
                &clay.density,
                &input(Vec3::ZERO, Vec3::ZERO, &targets),
                &mut out,
            );
            assert_eq!(n, 3);
            sim.step(
                &mut state,
                &mut clay.density.patches[0].lattice,
                &out[..n],
                &mut snap,
            )
            .unwrap();
        }
        let r1 = radius_along(&clay.density.patches[0].lattice, Vec3::X);
        // One stroke is one undo step and restores the field bit for bit.
        let mut history = History::default();
        assert!(history.commit(recorder, &clay));
        history.undo(&mut clay).unwrap();
        assert_eq!(clay, before_bits);
        (r0, r1)
    }

    #[test]
    fn the_chisel_cuts_to_about_the_set_depth() {
        let depth = 0.08;
        let (r0, r1) = penetrate(false, depth);
        let cut = r0 - r1;
        assert!(
            (cut - depth).abs() < 0.25 * depth,
            "cut {cut} for depth {depth}"
        );
    }

    #[test]
    fn the_squirt_raises_about_the_set_height() {
        let depth = 0.08;
        let (r0, r1) = penetrate(true, depth);
        let raised = r1 - r0;
        assert!(
            (raised - depth).abs() < 0.25 * depth,
            "raised {raised} for {depth}"
        );
    }

    #[test]
    fn grab_finds_the_nearest_mass_point_inside_the_solid() {
        let l = MultiPatchField::new(sphere());
        let cursor = CENTRE + Vec3::X * (RADIUS + 0.12);
        let p = nearest_solid_point(&l, cursor, 0.3, 0.05).unwrap();
        assert!(l.is_inside(p));
        assert!((p - cursor).length() < 0.2);
        // Nothing solid within reach far away.
        assert!(nearest_solid_point(&l, Vec3::splat(10.0), 0.3, 0.05).is_none());
        let mut out = [ToolForce {
            start: Vec3::ZERO,
            end: Vec3::ZERO,
            distribution: Distribution::Constant,
            radius: 1.0,
            gain: 0.0,
        }; 4];
        let n = ForceTool::PointGrab { gain: 2.0 }.forces(&l, &input(p, cursor, &[]), &mut out);
        assert_eq!(n, 1);
        assert_eq!((out[0].start, out[0].end, out[0].gain), (p, cursor, 2.0));
        assert!(
            crate::dynamics::force_integral(&l, out[0].start, out[0].end) > 0.0,
            "pull grows"
        );
    }

    #[test]
    fn area_tracks_follow_the_beta_profile_and_respect_the_buffer() {
        let l = MultiPatchField::new(sphere());
        // Held well inside the clay, where every track's start is fully held.
        let grab = CENTRE + Vec3::X * (RADIUS - 0.15);
        let cursor = grab + Vec3::X * 0.1;
        let mut out = [ToolForce {
            start: Vec3::ZERO,
            end: Vec3::ZERO,
            distribution: Distribution::Constant,
            radius: 1.0,
            gain: 0.0,
        }; 64];
        let tool = ForceTool::Area {
            distribution: Distribution::Conical,
            radius_fu: 0.1,
            tracks: 6,
            gain: 1.0,
        };
        let n = tool.forces(&l, &input(grab, cursor, &[]), &mut out);
        assert!(n > 20 && n <= 36, "{n} tracks");
        for f in &out[..n] {
            let offset = (f.start - grab).length();
            // Conical: weight 1 − ρ, every track parallel to the drag.
            assert!((f.gain - (1.0 - offset / 0.1)).abs() < 1e-4);
            assert!(((f.end - f.start) - (cursor - grab)).length() < 1e-5);
        }
        // A short buffer truncates rather than overflows.
        assert_eq!(tool.forces(&l, &input(grab, cursor, &[]), &mut out[..5]), 5);
        // Held outside the clay, no track holds anything.
        let outside = CENTRE + Vec3::X * (RADIUS + 0.1);
        assert_eq!(
            tool.forces(&l, &input(outside, outside + Vec3::X * 0.1, &[]), &mut out),
            0
        );
    }

    #[test]
    fn curve_and_bend_move_their_samples_as_designed() {
        let l = MultiPatchField::new(sphere());
        let curve = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let mut out = [ToolForce {
            start: Vec3::ZERO,
            end: Vec3::ZERO,
            distribution: Distribution::Constant,
            radius: 1.0,
            gain: 0.0,
        }; 8];
        let tool = ForceTool::Curve {
            radius_fu: 0.05,
            gain: 1.0,
        };
        let drag = Vec3::new(0.0, 0.0, 0.2);
        let i = ForceInput {
            grab: Vec3::ONE,
            cursor: Vec3::ONE + drag,
            pivot: Vec3::ZERO,
            path: &curve,
            targets: &[],
            normal: Vec3::ZERO,
        };
        assert_eq!(tool.forces(&l, &i, &mut out), 3);
        for (f, p) in out.iter().zip(curve) {
            assert_eq!(f.start, p);
            assert!((f.end - (p + drag)).length() < 1e-6);
        }
        // Bend: a quarter turn about the pivot; displacement grows with distance from it.
        let bend = ForceTool::Bend {
            samples: 4,
            radius_fu: 0.05,
            gain: 1.0,
        };
        let i = ForceInput {
            grab: Vec3::X,
            cursor: Vec3::Y,
            pivot: Vec3::ZERO,
            path: &[],
            targets: &[],
            normal: Vec3::ZERO,
        };
        assert_eq!(bend.forces(&l, &i, &mut out), 4);
        for (k, f) in out[..4].iter().enumerate() {
            let d = (k + 1) as f32 / 4.0;
            assert!((f.start - Vec3::X * d).length() < 1e-5);
            assert!((f.end - Vec3::Y * d).length() < 1e-5);
        }
        assert!(
            ForceTool::Chisel {
                depth_fu: 0.0,
                radius_fu: 0.1,
                gain: 1.0
            }
            .validate()
            .is_err()
        );
    }
}
