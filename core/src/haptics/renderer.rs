//! The force the hand feels, one tick at a time: touch, the sculpting reaction, blending,
//! passivity and shaping, in that order.
//!
//! Guarantee: after [`ForceRenderer::new`], [`ForceRenderer::render`] allocates nothing, takes
//! no lock and does bounded work: one proxy update ([`super::MAX_PROXY_PROBES`] field
//! evaluations), at most one sculpting reaction ([`super::SculptReaction`]'s bound) and
//! constant work besides. It reads device time and device positions only, so a replay renders
//! the same forces bit for bit.
//!
//! Per tick:
//! 1. **Touch.** The proxy ([`super::SurfaceProxy`]) is moved; while it is on the surface the
//!    touch force is a spring from the tip to the proxy, `k (proxy − tip)` at the device's
//!    stiffness, plus a damper on the tip's normal velocity that fades in over the first
//!    millimetre of depth.
//! 2. **Sculpting.** During a stroke, the push tool feels eq. (6) along the vector from the
//!    surface to the tip along the tool's axis (the outward normal where the tip first touched
//!    the clay in this stroke; the surface is searched a bounded reach above the tip, and a
//!    deeper tip feels the force of that reach: it saturates, never drops); a force tool feels
//!    the weighted sum over its vectors
//!    ([`super::SculptReaction`]). Field units become newtons through the calibrated scale
//!    times the haptic gain, and saturate smoothly (`F_max · tanh(|F| / F_max)`) at the
//!    device's force limit instead of dropping.
//! 3. **Blend.** Touch renders between strokes, sculpting during them; each cross-fades over
//!    the shaping stage's `blend_s` when a stroke starts or ends or the tool changes. A stroke
//!    that ends with the tool inside the clay leaves it buried (no touch until it comes out):
//!    the sculpting force fades out and nothing kicks the hand.
//! 4. **Shaping.** The sum passes the rate limit ([`super::ForceShaper`]).
//! 5. **Passivity.** The observer's damper is added whenever the hand has put in less energy
//!    than the rendering stores ([`super::PassivityController`]). It is viscous (`−c · v`), its
//!    coefficient rising to the observer's at once and let go by at most the fade rule's share
//!    per millisecond, so a spent deficit or a contact's end fades it out instead of dropping
//!    it. It is added to the shaped force (not to its target, where the first rate limit would
//!    hold it back half an oscillation), and the sum passes the rate limit once more, so no
//!    step the hand feels exceeds the stated rate; the safety filter's slew limit after it is
//!    the backstop.

use glam::{Quat, Vec3};

use super::passivity::{PassivityConfig, PassivityController};
use super::proxy::{ProxyConfig, SurfaceProxy, Touch};
use super::sculpt::{FeltTool, SculptReaction, StrokeGeometry};
use super::shaping::{Blend, FadeOut, ForceShaper, ShapingConfig};
use super::shell::{ShapeProxy, ToolShell, press_fraction};
use crate::dynamics::{force_integral, reaction_force, surface_point_on_ray};
use crate::field::MultiPatchField;
use crate::tools::ForceTool;

/// Depth over which the touch damper fades in, metres: short, because a light touch (1 N on a
/// 3 kN/m wall is 0.3 mm deep) needs the damper's full share to stay passive on a late
/// position; long enough that entering at hand speed is no step.
const DAMPING_FADE_M: f32 = 2e-4;
/// The touch damper's share of the device's stable damping. The passivity sweep (grips
/// 100–1000 N/m, 1 and 4 kHz, a one-tick-late position with 1–8 µm of noise) is passive within
/// 1% from about 0.6; more damping driven by a noisy velocity starts to inject energy itself.
const TOUCH_DAMPING_SHARE: f32 = 0.6;

/// How the clay feels.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct HapticConfig {
    /// Friction of the touched surface.
    pub proxy: ProxyConfig,
    /// Rate limit and cross-fades.
    pub shaping: ShapingConfig,
    /// Passivity observer and damper.
    pub passivity: PassivityConfig,
    /// Stiffness of touch, newtons per metre.
    pub touch_stiffness_n_per_m: f32,
    /// Damping of touch along the normal, newton-seconds per metre.
    pub touch_damping_n_s_per_m: f32,
    /// Multiplies the calibrated sculpting force (1: pressing 5 mm into the fresh clay feels
    /// [`CALIBRATION_FORCE_N`]).
    pub haptic_gain: f32,
    /// How a geometric tool resting on the clay answers the hand's press.
    #[serde(default)]
    pub tool_press: ToolPressConfig,
    /// Whether a geometric tool on a device that renders force is felt with its whole shape
    /// and acts where it rests, at a rate the hand's press sets (tool-shaped contact); off, it
    /// acts at the tip and renders no force during its strokes (a script's strokes, whose path
    /// says where the tool acts).
    #[serde(default = "tool_contact_on")]
    pub tool_contact: bool,
}

fn tool_contact_on() -> bool {
    true
}

/// How a geometric tool resting on the clay answers the hand's press (tool-shaped contact):
/// below `rest_n` it rests and changes nothing; from there its cut runs ahead of it toward the
/// tip ever faster (and a rate action's dwell grows), at the full rate from `firm_n`.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ToolPressConfig {
    /// The force up to which the tool only rests on the clay, newtons.
    pub rest_n: f32,
    /// The force from which the tool acts at its full rate, newtons.
    pub firm_n: f32,
    /// The clay's yield under the push and the force tools, newtons: the clay gives way to
    /// them only while the hand presses harder than this, so a held press is felt at this
    /// force and the clay stops where the sculpting force has fallen to it (the press's
    /// elastic part, short of the tip).
    #[serde(default = "default_yield_n")]
    pub yield_n: f32,
}

fn default_yield_n() -> f32 {
    ToolPressConfig::default().yield_n
}

impl Default for ToolPressConfig {
    fn default() -> Self {
        // A hand resting on a desktop arm leans with up to about half a newton, and setting
        // the tool down at a few centimetres a second adds as much again for a moment; 4 N is
        // a firm press that such an arm holds for minutes.
        // Half a newton of yield: a held press is felt clearly above the hand's own lean, and
        // the clay stops some 2 mm of device travel short of the tip at the calibrated scale.
        Self {
            rest_n: 1.0,
            firm_n: 4.0,
            yield_n: 0.5,
        }
    }
}

/// The sculpting force that a 5 mm press into the fresh clay gives at haptic gain 1, newtons:
/// firm clay on a Touch-class arm.
pub const CALIBRATION_FORCE_N: f32 = 2.0;
/// The press depth of the calibration, metres.
pub const CALIBRATION_DEPTH_M: f32 = 0.005;

impl HapticConfig {
    /// Settings for a device that renders `max_stiffness_n_per_m` and `max_damping_n_s_per_m`
    /// stably: touch as stiff as the device allows, [`TOUCH_DAMPING_SHARE`] of its damping on
    /// the normal, the passivity damper capped at its damping.
    #[must_use]
    pub fn for_device(max_stiffness_n_per_m: f32, max_damping_n_s_per_m: f32) -> Self {
        let damping = if max_damping_n_s_per_m > 0.0 {
            max_damping_n_s_per_m
        } else {
            PassivityConfig::default().max_damping_n_s_per_m
        };
        Self {
            proxy: ProxyConfig::default(),
            shaping: ShapingConfig::default(),
            passivity: PassivityConfig {
                max_damping_n_s_per_m: damping,
                ..PassivityConfig::default()
            },
            touch_stiffness_n_per_m: max_stiffness_n_per_m.max(0.0),
            touch_damping_n_s_per_m: TOUCH_DAMPING_SHARE * damping,
            haptic_gain: 1.0,
            tool_press: ToolPressConfig::default(),
            tool_contact: true,
        }
    }
}

/// Newtons per unit of reaction (field units) such that pressing [`CALIBRATION_DEPTH_M`] into
/// `field` from its top gives [`CALIBRATION_FORCE_N`], with `field_per_m` field units per
/// device metre. The press is measured where a ray from the centre of the lattice straight up
/// leaves the clay; `None` when it does not (no clay above the centre).
#[must_use]
pub fn calibrated_force_scale(field: &MultiPatchField, field_per_m: f32) -> Option<f32> {
    let (lo, hi) = field.support();
    let centre = (lo + hi) * 0.5;
    let top = surface_point_on_ray(
        field,
        centre,
        Vec3::Y,
        hi.y - centre.y,
        0.25 * field.finest_spacing(),
    )?;
    let depth = CALIBRATION_DEPTH_M * field_per_m;
    let f = force_integral(field, top, top - Vec3::Y * depth).abs();
    (f.is_finite() && f > 0.0).then(|| CALIBRATION_FORCE_N / f)
}

/// Everything a tick reads.
#[derive(Clone, Copy, Debug)]
pub struct FeltInput<'a> {
    /// The haptic loop's field.
    pub field: &'a MultiPatchField,
    /// The tip, field coordinates.
    pub tip: Vec3,
    /// The tip's device position, metres.
    pub position_m: Vec3,
    /// The tip's device velocity, metres per second.
    pub velocity_m_per_s: Vec3,
    /// Device time of the sample, microseconds.
    pub time_us: u64,
    /// Field units per device metre.
    pub field_per_m: f32,
    /// Newtons per unit of reaction at haptic gain 1.
    pub force_n_per_reaction: f32,
    /// Whether a stroke is held.
    pub stroke_active: bool,
    /// The held tool.
    pub tool: FeltTool,
    /// The stroke as the simulation fixed it.
    pub stroke: &'a StrokeGeometry,
    /// Fade from the field's age (1 fresh, 0 stale).
    pub fade: f32,
    /// Where the sculpting force saturates, newtons (the device's force limit).
    pub saturation_n: f32,
    /// The force sent to the device over the interval that ends now, newtons.
    pub sent_n: Vec3,
    /// The tool's orientation, field coordinates.
    pub rotation: Quat,
    /// Whether the device renders force: a geometric tool is then felt with its whole shape
    /// and acts where it rests as the hand presses; without force it acts at the tip.
    pub tool_contact: bool,
}

/// What a tick rendered.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Felt {
    /// The shaped force to send (before the safety filter), newtons.
    pub force_n: Vec3,
    /// The touch proxy.
    pub touch: Touch,
    /// The sculpting force vector (push: proxy → tip; a force tool: its first vector).
    pub vector: Option<(Vec3, Vec3)>,
    /// Whether a stroke's tool is acting on the clay.
    pub sculpting: bool,
    /// The passivity observer's energy, joules.
    pub energy_j: f32,
    /// With tool-shaped contact, the held geometric tool's centre where it rests on the clay.
    pub resting_at: Option<Vec3>,
    /// How hard the hand presses the resting tool, 0 (resting, or touching nothing: the tool
    /// does nothing) to 1 (firmly: full rate); 1 without tool-shaped contact (the tool acts at
    /// the tip).
    pub press: f32,
    /// With force rendered, the force integral (field units, as eq. (6) gives it) below which
    /// the push and the force tools do not move the clay: [`ToolPressConfig::yield_n`] over
    /// the felt scale. Zero without force (a script's or a pointer's path says where the clay
    /// goes, and it goes there).
    pub force_yield: f32,
}

/// The haptic renderer's state (see the module docs).
#[derive(Clone, Debug)]
pub struct ForceRenderer {
    config: HapticConfig,
    proxy: SurfaceProxy,
    /// The held geometric tool, resting on the clay with its shape.
    shape_proxy: ShapeProxy,
    /// The shell the last tick touched with (`None`: at a point).
    touch_shell: Option<ToolShell>,
    /// The touch force of the contact model left behind by a tool switch, fading out.
    touch_fade: FadeOut,
    /// The touch force sent on the last tick (blended), newtons.
    last_touch_n: Vec3,
    sculpt: SculptReaction,
    shaper: ForceShaper,
    /// The rate limit on the sum sent (shaped force plus passivity damper).
    output_limit: ForceShaper,
    passivity: PassivityController,
    touch_blend: Blend,
    sculpt_blend: Blend,
    /// The sculpting force after its source stopped (stroke end, tool switch), fading out.
    sculpt_fade: FadeOut,
    /// The sculpting force sent on the last tick its source was on, newtons.
    last_sculpt_n: Vec3,
    /// Whether the sculpting source was on at the last tick.
    sculpt_was_on: bool,
    last_tool: FeltTool,
    /// A tool switch fades the sculpting force out before the new tool fades in.
    switching: bool,
    /// The passivity damper's coefficient as applied, newton-seconds per metre: it rises to
    /// the observer's at once and falls by at most the fade rule's share per millisecond.
    damping_n_s_per_m: f32,
    /// Whether the previous tick held a stroke.
    was_stroke: bool,
    /// The push's direction for the held stroke: the outward normal where the tip first
    /// touched the clay during it (the tool's axis, as Hua & Qin's push vector runs along it).
    push_axis: Option<Vec3>,
    /// Device faults since the last rendered tick.
    faults_in_a_row: u32,
    /// A short fault came in the middle of a contact and the contact has not been seen to
    /// go on or to end since: the passivity account is kept until then (see
    /// [`Self::device_fault`]).
    resuming_contact: bool,
}

/// Faulted ticks in a row through which a contact is taken to go on, so the passivity
/// observer keeps its account: 5 ms at 1 kHz, in which a hand at a brisk 0.2 m/s moves 1 mm,
/// too little to leave the clay and come back into another contact unseen. A longer fault
/// ends the contact (its credit is dropped, a deficit kept).
pub const FAULT_TICKS_IN_ONE_CONTACT: u32 = 5;

impl ForceRenderer {
    /// A renderer at rest.
    #[must_use]
    pub fn new(config: HapticConfig) -> Self {
        Self {
            proxy: SurfaceProxy::new(config.proxy),
            shape_proxy: ShapeProxy::default(),
            touch_shell: None,
            touch_fade: FadeOut::default(),
            last_touch_n: Vec3::ZERO,
            sculpt: SculptReaction::default(),
            shaper: ForceShaper::new(config.shaping),
            output_limit: ForceShaper::new(config.shaping),
            passivity: PassivityController::new(config.passivity),
            touch_blend: Blend::default(),
            sculpt_blend: Blend::default(),
            sculpt_fade: FadeOut::default(),
            last_sculpt_n: Vec3::ZERO,
            sculpt_was_on: false,
            last_tool: FeltTool::default(),
            switching: false,
            damping_n_s_per_m: 0.0,
            was_stroke: false,
            push_axis: None,
            faults_in_a_row: 0,
            resuming_contact: false,
            config,
        }
    }

    /// The settings.
    #[must_use]
    pub fn config(&self) -> &HapticConfig {
        &self.config
    }

    /// Sets the haptic gain (finite, ≥ 0; others are ignored).
    pub fn set_haptic_gain(&mut self, gain: f32) {
        if gain.is_finite() && gain >= 0.0 {
            self.config.haptic_gain = gain;
        }
    }

    /// Zero force at once, no contact and nothing observed (a new device: the safety filter
    /// sent zero already).
    pub fn reset(&mut self) {
        self.zero_force();
        self.passivity.reset();
        self.faults_in_a_row = 0;
        self.resuming_contact = false;
    }

    /// Zero force at once after a device fault (a failed read or write: the safety filter
    /// sent zero already), every source starting again from zero when the samples come back.
    ///
    /// Unlike [`Self::reset`], a fault of at most [`FAULT_TICKS_IN_ONE_CONTACT`] ticks does
    /// not end the contact: the passivity observer loses its track (position, velocity) but
    /// keeps its energy account ([`PassivityController::lose_track`]), so after the soft
    /// start the hand feels what the same contact without the fault would feel. Should the
    /// first sample after it find the contact over (nothing touched, nothing sculpted), the
    /// account's credit is dropped as between any two contacts. A longer fault ends the
    /// contact at once. A deficit is never forgiven.
    pub fn device_fault(&mut self) {
        self.zero_force();
        self.passivity.lose_track();
        self.faults_in_a_row = self.faults_in_a_row.saturating_add(1);
        self.resuming_contact = self.faults_in_a_row <= FAULT_TICKS_IN_ONE_CONTACT;
        if !self.resuming_contact {
            self.passivity.between_contacts();
        }
    }

    /// Every force source to zero at once, the contact released.
    fn zero_force(&mut self) {
        self.proxy.release();
        self.shape_proxy.release();
        self.touch_fade.reset();
        self.last_touch_n = Vec3::ZERO;
        self.shaper.reset();
        self.output_limit.reset();
        self.touch_blend.reset();
        self.sculpt_blend.reset();
        self.sculpt_fade.reset();
        self.last_sculpt_n = Vec3::ZERO;
        self.sculpt_was_on = false;
        self.damping_n_s_per_m = 0.0;
    }

    /// Renders one tick.
    pub fn render(&mut self, input: &FeltInput) -> Felt {
        let dt = self.shaper.elapsed_s(input.time_us);
        self.passivity.observe(input.position_m, input.sent_n, dt);
        self.faults_in_a_row = 0;
        let shell = match input.tool {
            FeltTool::Geometric(Some(shell)) if input.tool_contact && self.config.tool_contact => {
                Some(shell)
            }
            _ => None,
        };
        if self.was_stroke && !input.stroke_active && shell.is_none() {
            self.proxy.bury_if_inside(input.field, input.tip);
        }
        self.was_stroke = input.stroke_active;
        // One proxy at a time; the other forgets its contact, so switching tools inside the
        // clay buries the new one instead of kicking the hand out.
        if shell.is_some() && shell != self.touch_shell {
            // Another shape: its contact starts afresh.
            self.shape_proxy.release();
        }
        let touch = match &shell {
            Some(shell) => {
                self.proxy.release();
                self.shape_touch(input, shell)
            }
            None => {
                self.shape_proxy.release();
                self.proxy.update(input.field, input.tip)
            }
        };
        if !input.stroke_active {
            self.push_axis = None;
            self.sculpt.end_stroke();
        } else if self.push_axis.is_none() && touch.touching {
            self.push_axis = Some(touch.normal);
        }
        let per_m = input.field_per_m.max(f32::MIN_POSITIVE);

        // Sculpting reaction, field units.
        let (reaction, vector, sculpting) = if input.stroke_active {
            match input.tool {
                FeltTool::Push if input.field.is_inside(input.tip) => match self.push_axis {
                    Some(axis) => {
                        let from = surface_along(input.field, input.tip, axis);
                        (
                            reaction_force(input.field, from, input.tip),
                            Some((from, input.tip)),
                            true,
                        )
                    }
                    None => (Vec3::ZERO, None, false),
                },
                FeltTool::Force(tool) => {
                    let f = self.sculpt.compute(
                        &tool,
                        input.field,
                        input.tip,
                        input.stroke,
                        (input.time_us, self.config.shaping.blend_s),
                    );
                    (f.reaction, f.first, f.vectors > 0)
                }
                _ => (Vec3::ZERO, None, false),
            }
        } else {
            (Vec3::ZERO, None, false)
        };
        let scale = input.force_n_per_reaction * self.config.haptic_gain;
        let sculpt_n = saturate(reaction * scale, input.saturation_n);

        // Touch, newtons.
        let touch_n = if touch.touching {
            let spring = (touch.proxy - input.tip) / per_m * self.config.touch_stiffness_n_per_m;
            let depth_m = touch.depth / per_m;
            let fade_in = (depth_m / DAMPING_FADE_M).min(1.0);
            let normal_speed = input.velocity_m_per_s.dot(touch.normal);
            let damper =
                -touch.normal * (normal_speed * self.config.touch_damping_n_s_per_m * fade_in);
            saturate(spring + damper, input.saturation_n)
        } else {
            Vec3::ZERO
        };

        // Blend the sources.
        if input.tool != self.last_tool {
            self.last_tool = input.tool;
            self.switching = true;
        }
        let blend_s = self.config.shaping.blend_s;
        let sculpt_on =
            input.stroke_active && !self.switching && !matches!(input.tool, FeltTool::Geometric(_));
        let ws = self.sculpt_blend.advance(sculpt_on, dt, blend_s);
        if self.switching && ws == 0.0 {
            self.switching = false;
        }
        // A tool felt with its shape rests on the clay during its strokes too.
        let wt = self
            .touch_blend
            .advance(!input.stroke_active || shell.is_some(), dt, blend_s);
        let fade = if input.fade.is_finite() {
            input.fade.clamp(0.0, 1.0)
        } else {
            0.0
        };
        // The sculpting source: cross-faded in over `blend_s`; when it stops, the force it last
        // gave is let go through the fade-out (from wherever it was, never in one tick).
        let sculpt_part = if sculpt_on {
            let residue = self.sculpt_fade.advance(dt);
            let part = residue * (1.0 - ws) + sculpt_n * ws;
            self.last_sculpt_n = part;
            part
        } else {
            if self.sculpt_was_on {
                self.sculpt_fade.hold(self.last_sculpt_n);
            }
            self.sculpt_fade.advance(dt)
        };
        self.sculpt_was_on = sculpt_on;
        // A tool switch that changes how the clay is touched (at a point, or with another
        // shape) started the new contact afresh (buried while in the clay, see above); the old
        // one's force is let go through the fade-out, not dropped.
        if shell != self.touch_shell {
            self.touch_shell = shell;
            self.touch_fade.hold(self.last_touch_n);
        }
        let touch_part = touch_n * wt + self.touch_fade.advance(dt);
        self.last_touch_n = touch_part;
        let target = (touch_part + sculpt_part) * fade;

        // Shaping, then passivity: the damper while in deficit, in contact only (free space
        // stays free). The damper is added to the shaped force, not to its target: it answers
        // an oscillation within the tick instead of queueing behind the source's rate limit.
        let shaped = self.shaper.shape(target, dt);
        // After a short fault every source starts again from zero, so the first ticks render
        // nothing while the contact goes on: the contact has ended only if nothing is touched
        // or sculpted; once something is rendered it has gone on.
        let acting = touch.touching || sculpting;
        let resumed = target != Vec3::ZERO || shaped != Vec3::ZERO;
        if self.resuming_contact && (resumed || !acting) {
            self.resuming_contact = false;
        }
        let wanted_n_s_per_m = if !resumed {
            if !self.resuming_contact {
                self.passivity.between_contacts();
            }
            0.0
        } else {
            // What the touch spring stores and will give back on the way out: the work to
            // press it to its depth, `∫ F_max tanh(k x / F_max) dx`.
            let stored_j = if touch.touching {
                spring_energy_j(
                    self.config.touch_stiffness_n_per_m,
                    touch.depth / per_m,
                    input.saturation_n,
                ) * wt
                    * fade
            } else {
                0.0
            };
            self.passivity.damping_n_s_per_m(dt, stored_j)
        };
        // The damper is viscous, `−c · v` on the port's velocity now, so whatever its
        // coefficient it only takes energy. The coefficient rises to what the observer asks at
        // once (an oscillation is answered within the tick) and is let go by at most the fade
        // rule's share per millisecond, so neither a spent deficit nor the end of a contact
        // drops the force in one tick (the hand leaving the clay feels the drag fade out over
        // some 50 ms).
        let let_go = (1.0 - FadeOut::RELATIVE_PER_MS * dt * 1e3).max(0.0);
        self.damping_n_s_per_m = wanted_n_s_per_m.max(self.damping_n_s_per_m * let_go);
        let velocity = self.passivity.damped_velocity_m_per_s();
        if self.damping_n_s_per_m * velocity.length() < FadeOut::ABSOLUTE_N_PER_MS {
            // Under the rule's floor: let go of what is left.
            self.damping_n_s_per_m = wanted_n_s_per_m;
        }
        let damper = -velocity * self.damping_n_s_per_m;
        let force_n = shaped + damper.clamp_length_max(input.saturation_n.max(0.0));
        // The damper's share passes the same rate limit as the rest, on the sum: no step the
        // hand feels is larger than the stated rate, whatever its source.
        let force_n = self.output_limit.shape(force_n, dt);
        // The tool acts only where it rests on the clay, at a rate that grows with how hard the
        // hand presses past the surface; a tool felt with its shape that touches nothing acts
        // nowhere.
        let (resting_at, press) = match shell {
            Some(_) if touch.touching => {
                let press_n = touch.depth / per_m * self.config.touch_stiffness_n_per_m;
                let press = press_fraction(
                    press_n,
                    self.config.tool_press.rest_n,
                    self.config.tool_press.firm_n,
                );
                (Some(touch.proxy), press)
            }
            Some(_) => (None, 0.0),
            None => (None, 1.0),
        };
        let force_yield = if input.tool_contact
            && self.config.tool_contact
            && yields_to_the_press(&input.tool)
            && scale > 0.0
        {
            let y = self.config.tool_press.yield_n / scale;
            if y.is_finite() { y.max(0.0) } else { 0.0 }
        } else {
            0.0
        };
        Felt {
            force_n,
            touch,
            vector,
            sculpting,
            energy_j: self.passivity.energy_j(),
            resting_at,
            press,
            force_yield,
        }
    }

    /// The held geometric tool's contact, as a touch: the spring runs from the tip to the
    /// tool's centre where it rests on the clay.
    fn shape_touch(&mut self, input: &FeltInput, shell: &ToolShell) -> Touch {
        self.shape_proxy
            .update(input.field, shell, input.rotation, input.tip)
    }
}

/// Whether the clay yields to `tool` only under the hand's press (with force rendered): the
/// push and the force tools that bring the surface to the cursor. A chisel or squirt is not:
/// its depth is set by its control, so the clay goes to it whatever the press.
fn yields_to_the_press(tool: &FeltTool) -> bool {
    match tool {
        FeltTool::Push => true,
        FeltTool::Force(tool) => {
            !matches!(tool, ForceTool::Chisel { .. } | ForceTool::Squirt { .. })
        }
        FeltTool::Geometric(_) => false,
    }
}

/// Marching steps of [`surface_along`].
const PUSH_MARCH_STEPS: usize = 16;
/// Bisection steps of [`surface_along`].
const PUSH_BISECT_STEPS: usize = 10;
/// How far the push looks for the surface above the tip, knot spans.
const PUSH_REACH_SPANS: f32 = 6.0;

/// The start of the push's force vector: the first point outside the clay from `tip` along
/// `axis`, within [`PUSH_REACH_SPANS`] knot spans (bisected), or the end of that reach when the
/// tip is deeper still, so the force saturates there instead of dropping. Bounded: at most
/// [`PUSH_MARCH_STEPS`] + [`PUSH_BISECT_STEPS`] field evaluations.
fn surface_along(field: &MultiPatchField, tip: Vec3, axis: Vec3) -> Vec3 {
    let reach = PUSH_REACH_SPANS * field.finest_spacing();
    let step = reach / PUSH_MARCH_STEPS as f32;
    let mut inner = 0.0_f32;
    for i in 1..=PUSH_MARCH_STEPS {
        let t = step * i as f32;
        if field.value(tip + axis * t) <= field.iso() {
            let mut outer = t;
            for _ in 0..PUSH_BISECT_STEPS {
                let mid = 0.5 * (inner + outer);
                if field.value(tip + axis * mid) > field.iso() {
                    inner = mid;
                } else {
                    outer = mid;
                }
            }
            return tip + axis * outer;
        }
        inner = t;
    }
    tip + axis * reach
}

/// The work to press the saturating touch spring (`F = F_max · tanh(k x / F_max)`) to
/// `depth_m`, joules: `(F_max² / k) · ln cosh(k · depth / F_max)`.
#[must_use]
pub fn spring_energy_j(stiffness_n_per_m: f32, depth_m: f32, saturation_n: f32) -> f32 {
    if !(stiffness_n_per_m > 0.0 && saturation_n > 0.0 && depth_m > 0.0) {
        return 0.0;
    }
    let u = stiffness_n_per_m * depth_m / saturation_n;
    // ln cosh u; past u = 10, as u − ln 2 (cosh would lose nothing but may overflow later).
    let ln_cosh = if u < 10.0 {
        u.cosh().ln()
    } else {
        u - std::f32::consts::LN_2
    };
    saturation_n * saturation_n / stiffness_n_per_m * ln_cosh
}

/// `v` with its length passed through `limit · tanh(|v| / limit)`: linear for small forces,
/// smoothly saturating at `limit` (zero for a non-positive limit).
#[must_use]
pub fn saturate(v: Vec3, limit: f32) -> Vec3 {
    let len = v.length();
    if !(limit > 0.0 && len.is_finite()) {
        return Vec3::ZERO;
    }
    if len == 0.0 {
        return v;
    }
    v * (limit * (len / limit).tanh() / len)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::haptics::test_clay::slab;

    fn input<'a>(
        field: &'a MultiPatchField,
        stroke: &'a StrokeGeometry,
        y: f32,
        t_us: u64,
        active: bool,
    ) -> FeltInput<'a> {
        FeltInput {
            field,
            tip: Vec3::new(1.3, y, 1.3),
            position_m: Vec3::new(0.0, y / 10.0, 0.0),
            velocity_m_per_s: Vec3::ZERO,
            time_us: t_us,
            field_per_m: 10.0,
            force_n_per_reaction: 300.0,
            stroke_active: active,
            tool: FeltTool::Push,
            stroke,
            fade: 1.0,
            saturation_n: 8.0,
            sent_n: Vec3::ZERO,
            rotation: Quat::IDENTITY,
            tool_contact: true,
        }
    }

    #[test]
    fn touch_is_a_stiff_spring_to_the_proxy_and_zero_outside() {
        let field = slab();
        let stroke = StrokeGeometry::default();
        let mut r = ForceRenderer::new(HapticConfig::for_device(2000.0, 10.0));
        let mut t = 0;
        let mut run = |y: f32, r: &mut ForceRenderer| {
            let mut f = Vec3::ZERO;
            for _ in 0..200 {
                t += 1000;
                f = r.render(&input(&field, &stroke, y, t, false)).force_n;
            }
            f
        };
        assert_eq!(run(1.1, &mut r), Vec3::ZERO);
        // 1 mm deep (0.01 field units at 10 per metre): 2 N at 2 kN/m, before saturation
        // (the fitted surface is within a tenth of a millimetre of y = 1).
        let f = run(0.99, &mut r);
        assert!((1.8..2.2).contains(&f.y), "{f}");
        assert!(f.x.abs() < 1e-3 && f.z.abs() < 1e-3);
        assert_eq!(run(1.1, &mut r), Vec3::ZERO, "released");
    }

    #[test]
    fn a_push_stroke_cross_fades_from_touch_to_the_sculpting_reaction() {
        let field = slab();
        let stroke = StrokeGeometry::default();
        // The shaped force alone (the passivity damper comes after the rate limit).
        let mut config = HapticConfig::for_device(2000.0, 10.0);
        config.passivity.enabled = false;
        let mut r = ForceRenderer::new(config);
        let mut t = 0;
        for _ in 0..50 {
            t += 1000;
            r.render(&input(&field, &stroke, 1.1, t, false));
        }
        let mut last = Vec3::ZERO;
        let mut max_step = 0.0_f32;
        for i in 0..300 {
            t += 1000;
            // Touch down to 5 mm at 0.1 m/s, hold, then start the stroke.
            let y = (1.1 - 0.001 * i as f32).max(0.95);
            let f = r.render(&input(&field, &stroke, y, t, i >= 200));
            max_step = max_step.max((f.force_n - last).length());
            last = f.force_n;
            if i >= 230 {
                assert!(f.sculpting && f.vector.is_some());
            }
        }
        let sculpt = saturate(
            reaction_force(&field, Vec3::new(1.3, 1.0, 1.3), Vec3::new(1.3, 0.95, 1.3)) * 300.0,
            8.0,
        );
        assert!(
            (last - sculpt).length() < 0.05 * sculpt.length() + 1e-3,
            "{last} vs {sculpt}"
        );
        assert!(
            max_step <= 0.5 + 1e-5,
            "step {max_step} N over the rate limit"
        );
    }

    /// A renderer pressed 5 mm into the slab at 0.1 m/s and held in a push stroke for 100
    /// ticks, and the device time it reached.
    fn pressed_in_a_stroke(
        field: &MultiPatchField,
        stroke: &StrokeGeometry,
    ) -> (ForceRenderer, u64) {
        let mut r = ForceRenderer::new(HapticConfig::for_device(2000.0, 10.0));
        let mut t = 0;
        let mut sent = Vec3::ZERO;
        for i in 0..300 {
            t += 1000;
            let y = (1.1 - 0.001 * i as f32).max(0.95);
            // The observer pairs each move with the force sent before it.
            let f = r.render(&FeltInput {
                sent_n: sent,
                ..input(field, stroke, y, t, i >= 200)
            });
            sent = f.force_n;
            if i >= 230 {
                assert!(f.sculpting, "tick {i}");
            }
        }
        (r, t)
    }

    #[test]
    fn a_short_fault_in_a_stroke_keeps_the_energy_account_and_a_lost_contact_drops_its_credit() {
        let field = slab();
        let stroke = StrokeGeometry::default();
        let still = |r: &mut ForceRenderer, t: &mut u64, y: f32, ticks: usize| {
            let mut last = None;
            for _ in 0..ticks {
                *t += 1000;
                last = Some(r.render(&input(&field, &stroke, y, *t, true)));
            }
            last.expect("rendered")
        };
        // The press put energy in (the hand pushed the touch spring down): credit.
        let (mut r, mut t) = pressed_in_a_stroke(&field, &stroke);
        let credit = still(&mut r, &mut t, 0.95, 1).energy_j;
        assert!(credit > 1e-3, "{credit} J");

        // One failed read, then the hand still in the clay, in the stroke: the force starts
        // again from zero, and the account is what it was (the hand has not moved, so no work).
        r.device_fault();
        t += 1000;
        let first = r.render(&input(&field, &stroke, 0.95, t, true));
        assert_eq!(first.force_n, Vec3::ZERO, "every source starts from zero");
        assert_eq!(first.energy_j, credit);
        let later = still(&mut r, &mut t, 0.95, 50);
        assert_eq!(later.energy_j, credit, "kept through the blend back in");
        assert!(
            later.force_n.y > 0.1,
            "the press is felt again: {}",
            later.force_n
        );

        // A new device forgets the account.
        r.reset();
        assert_eq!(still(&mut r, &mut t, 0.95, 1).energy_j, 0.0);

        // A short fault after which the hand is out of the clay: the contact ended, so its
        // credit is dropped.
        let (mut r, mut t) = pressed_in_a_stroke(&field, &stroke);
        r.device_fault();
        assert_eq!(still(&mut r, &mut t, 1.1, 1).energy_j, 0.0);

        // A fault longer than a contact survives: the credit is dropped, in the clay or not.
        let (mut r, mut t) = pressed_in_a_stroke(&field, &stroke);
        for _ in 0..=FAULT_TICKS_IN_ONE_CONTACT {
            r.device_fault();
        }
        assert_eq!(still(&mut r, &mut t, 0.95, 1).energy_j, 0.0);
        // One tick shorter, it is kept.
        let (mut r, mut t) = pressed_in_a_stroke(&field, &stroke);
        for _ in 0..FAULT_TICKS_IN_ONE_CONTACT {
            r.device_fault();
        }
        assert!(still(&mut r, &mut t, 0.95, 1).energy_j > 1e-3);
    }

    #[test]
    fn the_stored_energy_is_the_work_to_press_the_saturating_spring() {
        // Well below saturation: ½ k d².
        let e = spring_energy_j(1000.0, 1e-3, 8.0);
        assert!((e - 0.5e-3).abs() < 5e-6, "{e}");
        // Deep in saturation: about F_max · d.
        let e = spring_energy_j(3000.0, 0.1, 8.0);
        assert!((e - 8.0 * 0.1).abs() < 0.02, "{e}");
        assert_eq!(spring_energy_j(1000.0, -1.0, 8.0), 0.0);
    }

    #[test]
    fn saturation_is_smooth_and_bounded() {
        let big = saturate(Vec3::new(0.0, 100.0, 0.0), 8.0);
        assert!(big.y <= 8.0 && big.y > 7.99);
        let small = saturate(Vec3::new(0.0, 0.1, 0.0), 8.0);
        assert!((small.y - 0.1).abs() < 1e-3);
        assert_eq!(saturate(Vec3::NAN, 8.0), Vec3::ZERO);
    }
}
