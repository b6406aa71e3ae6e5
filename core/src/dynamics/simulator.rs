//! One step of the dynamic implicit solid (Hua & Qin eq. 5–8, §6, §7.3) as a flat sequence of
//! named stages: `gather_forces`, `spring_forces`, `solve_accel`, `integrate`, `publish`.
//!
//! The [`Simulator`] owns scratch buffers only; the state it advances ([`RegionState`] and the
//! lattice) is passed in. After the first step on a region of a given size a step allocates
//! nothing. A step never lets a NaN or an infinity into the state: it checks the acceleration
//! and bounds the new coefficients before writing anything, and returns an error value
//! instead. Only the coefficients of the region are written; every other coefficient of the
//! lattice stays bit-identical.

use std::time::Instant;

use crate::field::ImplicitField;
use crate::field::{BSplineLattice, KronScratch, OtherPatches, RegionSnapshot};
use glam::Vec3;

use super::coarse::CoarseScratch;
use super::coast::{COAST_REACH_SPANS, CoastField, RegionVelocity, coast_time_s, start_on_coast};
use super::constraint_solver::ConstraintSolver;
use super::counters::{StageTimes, StepCounters};
use super::force::{ToolBody, ToolForce, force_integral};
use super::material::{AccelSolver, Neighbourhood, StepParams};
use super::passes::{self, ChainScratch, Densities, Plastic, SpringFields, max_abs, plastic_drift};
use super::region::{RegionState, scratch_len};
use super::springs::{add_spring_forces, padded_row};
use super::team::Team;

/// Why a step was refused. The region state is unchanged except for its (halved) time step.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum StepError {
    /// A stage produced a NaN or an infinity.
    #[error("step refused: non-finite values in {stage}")]
    NonFinite {
        /// The stage that produced it.
        stage: &'static str,
    },
    /// The step would push a coefficient beyond `max_abs_coeff`.
    #[error("step refused: coefficients would reach {bound}")]
    Diverged {
        /// The bound the new coefficients would have reached.
        bound: f32,
    },
    /// The region does not fit the lattice passed in.
    #[error("step refused: region does not fit the lattice")]
    RegionMismatch,
}

/// What a successful step did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepReport {
    /// Time step used, seconds.
    pub dt_s: f32,
    /// Largest `|p̈|`.
    pub max_accel: f32,
    /// Halvings in this step.
    pub halvings: u32,
    /// Conjugate-gradient iterations (0 on the Kronecker path).
    pub cg_iterations: u32,
    /// Version published.
    pub version: u64,
}

/// The stepping object: parameters, counters, scratch and (with `params.threads == 2`) the
/// helper thread the passes are split with.
#[derive(Debug, Default)]
pub struct Simulator {
    /// Step parameters.
    pub params: StepParams,
    /// Running counters and the last step's stage timings.
    pub counters: StepCounters,
    /// External forces gathered from the tools, per mass point.
    external: Vec<f32>,
    /// The part of `external` that may be non-zero.
    external_dirty: std::ops::Range<usize>,
    /// Total force per mass point (external, springs, damping).
    force: Vec<f32>,
    /// The distribution weights of one tool force over its box of mass points.
    weights: Vec<f32>,
    /// One plane of total forces per thread (the springs fused into the projection).
    plane_buf: Vec<f32>,
    e: Vec<f32>,
    e_pad: Vec<f32>,
    k_pad: Vec<f32>,
    zeros: Vec<f32>,
    tmp: Vec<f32>,
    rhs: Vec<f32>,
    accel: Vec<f32>,
    cg_r: Vec<f32>,
    cg_z: Vec<f32>,
    cg_dir: Vec<f32>,
    cg_q: Vec<f32>,
    kron: KronScratch,
    t1: Vec<f32>,
    t2: Vec<f32>,
    team: Team,
    /// One thread or two for the next step.
    choice: ThreadChoice,
    /// Split every step over the helper when there is one, whatever the size (tests).
    always_split: bool,
    /// The force integral below which a force vector moves nothing (see
    /// [`Simulator::set_force_yield`]).
    force_yield: f32,
    /// One force vector's share per column of its box (see `TargetBound`), NaN until read.
    column_room: Vec<f32>,
    /// The tool bodies each step keeps the clay out of (see [`Simulator::set_tool_bodies`]).
    bodies: Vec<ToolBody>,
    /// The coarse springs' scratch (a detail patch's region, see `dynamics::coarse`).
    coarse: CoarseScratch,
}

/// Shortest lever of a force vector's integral in the simulation, knot spans (see
/// `gather_forces_over`).
const MIN_LEVER_SPANS: f32 = 1.0;

/// Regions smaller than this many mass points always step on one thread: the hand-offs
/// between passes cost more than the second core gives (32³ mass points: 330 µs on two
/// threads against 202 µs on one, measured quietly).
const MIN_POINTS_FOR_TWO: usize = 40_000;
/// Steps timed when choosing: a block on one thread, then a block on two.
const PROBE_STEPS: u32 = 16;
/// Steps at the start of each probe block that are not counted. Right after a switch a
/// step runs on caches the other count left (one thread finds half the region in the other
/// core's cache, two threads find it all in one), so it tells little about the count it
/// tries; blocks of steady steps time what the region will then run. (Same session, 32³/63³
/// on two threads, three runs of 300 steps each: 270–273 µs chosen by blocks, 278–316 µs
/// chosen by alternating steps.)
const PROBE_WARMUP: u32 = 2;
/// Steps between two choices for the same region size.
const REPROBE_EVERY: u32 = 4096;
/// Two threads are chosen only when their fastest probe step is at least this much faster
/// than one thread's (5%): where the two are about even, the timing noise of a few steps
/// would otherwise pick the slower count about half the time, and one thread also leaves
/// the other core to the rest of the engine. (In one window on the 2-core VM, while the
/// second core handed work over slowly, 32³/63³ ran at 479 µs on two threads against
/// 463 µs on one.)
const TWO_THREADS_GAIN: f64 = 0.95;

/// Whether the next step runs on one thread or two, chosen per region size by timing: the
/// fastest of a block of steps on each, once warm (see [`PROBE_WARMUP`]), with two threads
/// only when clearly faster (see [`TWO_THREADS_GAIN`]); re-checked every
/// [`REPROBE_EVERY`] steps. Both give
/// bit-identical results, so the choice changes only the time.
#[derive(Debug, Default)]
struct ThreadChoice {
    /// Mass points of the region the choice is for.
    points: usize,
    /// Fastest step seen on one and on two threads during the current probe.
    best_ns: [u64; 2],
    /// Probe steps still to time.
    probe_left: u32,
    /// The choice (or, while probing, the thread count of the step being timed).
    two: bool,
    steps_since_probe: u32,
}

impl ThreadChoice {
    /// Whether the next step on a region of `points` mass points runs on one thread.
    fn solo(&mut self, points: usize, has_helper: bool, always_split: bool) -> bool {
        if !has_helper {
            return true;
        }
        if always_split {
            return false;
        }
        if points < MIN_POINTS_FOR_TWO {
            self.points = points;
            self.probe_left = 0;
            return true;
        }
        if points != self.points
            || (self.probe_left == 0 && self.steps_since_probe >= REPROBE_EVERY)
        {
            self.points = points;
            self.best_ns = [u64::MAX; 2];
            self.probe_left = PROBE_STEPS;
            self.steps_since_probe = 0;
        }
        if self.probe_left > 0 {
            self.two = self.probe_left <= PROBE_STEPS / 2;
        }
        !self.two
    }

    /// Record how long the step chosen by [`ThreadChoice::solo`] took.
    fn record(&mut self, ns: u64) {
        if self.points < MIN_POINTS_FOR_TWO {
            return;
        }
        if self.probe_left == 0 {
            self.steps_since_probe = self.steps_since_probe.saturating_add(1);
            return;
        }
        let into_block = (PROBE_STEPS - self.probe_left) % (PROBE_STEPS / 2);
        if into_block >= PROBE_WARMUP {
            let best = &mut self.best_ns[usize::from(self.two)];
            *best = (*best).min(ns);
        }
        self.probe_left -= 1;
        if self.probe_left == 0 {
            self.two = (self.best_ns[1] as f64) < TWO_THREADS_GAIN * self.best_ns[0] as f64;
        }
    }
}

fn fit(v: &mut Vec<f32>, len: usize) {
    if v.len() != len {
        v.resize(len, 0.0);
    }
}

fn elapsed_ns(t: Instant) -> u64 {
    t.elapsed().as_nanos() as u64
}

impl Simulator {
    /// A simulator with the given parameters and empty scratch.
    #[must_use]
    pub fn new(params: StepParams) -> Self {
        Self {
            params,
            ..Self::default()
        }
    }

    /// Sets the clay's yield under the tool forces: each vector's eq. (6) integral (field
    /// units) gives way only by what exceeds `integral` (`sign(I) · max(|I| − y, 0)`), so the
    /// clay comes to rest where the integral has fallen to `y`, short of the vector's end, and
    /// the hand that keeps pressing feels `y` at the felt scale. Zero (the default, and any
    /// negative or non-finite value): the clay goes all the way to the vector's end.
    pub fn set_force_yield(&mut self, integral: f32) {
        self.force_yield = if integral.is_finite() {
            integral.max(0.0)
        } else {
            0.0
        };
    }

    /// The tool bodies the following steps keep the clay out of, replacing the last ones
    /// (none at first): each step pushes out the clay that lies in a body's shaft, on top of
    /// its force vectors (see [`ToolBody`]). Allocates only when given more bodies than ever
    /// before.
    pub fn set_tool_bodies(&mut self, bodies: &[ToolBody]) {
        self.bodies.clear();
        self.bodies.extend_from_slice(bodies);
    }

    fn ensure_scratch(&mut self, state: &RegionState) {
        let (n, m) = (state.p.len(), state.d.len());
        if self.external.len() != m {
            self.external_dirty = 0..m;
        }
        for v in [
            &mut self.external,
            &mut self.force,
            &mut self.weights,
            &mut self.e,
            &mut self.tmp,
        ] {
            fit(v, m);
        }
        for v in [
            &mut self.rhs,
            &mut self.accel,
            &mut self.cg_r,
            &mut self.cg_z,
            &mut self.cg_dir,
            &mut self.cg_q,
        ] {
            fit(v, n);
        }
        let [mx, my, mz] = state.grid.dims;
        let padded = padded_row(mx) * my * mz;
        fit(&mut self.e_pad, padded);
        fit(&mut self.k_pad, padded);
        fit(&mut self.zeros, mx);
        fit(&mut self.plane_buf, 2 * mx * my);
        let need = scratch_len(&state.basis);
        fit(&mut self.t1, need);
        fit(&mut self.t2, need);
        if self.kron.len() < need {
            self.kron = KronScratch::for_basis(&state.basis);
        }
        self.team.resize(self.params.threads);
    }

    /// Advance the region by one adaptive step under the tool forces, write the region's
    /// coefficients into `lattice` and publish them into `snapshot`. With
    /// `params.threads == 2` the passes are split with a helper thread; the result is
    /// bit-identical to one thread.
    ///
    /// # Errors
    /// [`StepError`] when the step would let a non-finite or diverging value into the state;
    /// nothing is written then (the region's time step is halved for the next attempt).
    pub fn step(
        &mut self,
        state: &mut RegionState,
        lattice: &mut BSplineLattice,
        forces: &[ToolForce],
        snapshot: &mut RegionSnapshot,
    ) -> Result<StepReport, StepError> {
        self.step_constrained(state, lattice, forces, None, snapshot)
    }

    /// [`Simulator::step`] with the geometric constraints of `constraints` held (§7.3): a
    /// `constrain` stage between `solve_accel` and `integrate` makes `p̈` keep every
    /// constraint row and removes any drift in the same Euler update.
    ///
    /// # Errors
    /// As [`Simulator::step`].
    pub fn step_constrained(
        &mut self,
        state: &mut RegionState,
        lattice: &mut BSplineLattice,
        forces: &[ToolForce],
        constraints: Option<&mut ConstraintSolver>,
        snapshot: &mut RegionSnapshot,
    ) -> Result<StepReport, StepError> {
        self.step_layered(
            state,
            lattice,
            OtherPatches::NONE,
            forces,
            constraints,
            snapshot,
        )
    }

    /// [`Simulator::step_constrained`] on one patch of a multi-patch clay (Hua & Qin eq. (3)):
    /// `lattice` is the patch simulated, `others` the fixed patches around it. The forces'
    /// line integrals are taken on the whole clay's density; only `lattice` moves.
    ///
    /// # Errors
    /// As [`Simulator::step`].
    pub fn step_layered(
        &mut self,
        state: &mut RegionState,
        lattice: &mut BSplineLattice,
        others: OtherPatches<'_>,
        forces: &[ToolForce],
        constraints: Option<&mut ConstraintSolver>,
        snapshot: &mut RegionSnapshot,
    ) -> Result<StepReport, StepError> {
        if !state.coeff_box().fits(lattice.dims) {
            self.counters.failed_steps += 1;
            return Err(StepError::RegionMismatch);
        }
        self.ensure_scratch(state);
        let started = Instant::now();
        let solo = self
            .choice
            .solo(state.d.len(), self.team.has_helper(), self.always_split);
        self.team.set_solo(solo);
        let result = self.step_on_team(state, lattice, others, forces, constraints, snapshot);
        self.choice.record(elapsed_ns(started));
        result
    }

    /// [`Simulator::step_constrained`] on the team as chosen.
    fn step_on_team(
        &mut self,
        state: &mut RegionState,
        lattice: &mut BSplineLattice,
        others: OtherPatches<'_>,
        forces: &[ToolForce],
        mut constraints: Option<&mut ConstraintSolver>,
        snapshot: &mut RegionSnapshot,
    ) -> Result<StepReport, StepError> {
        let mut times = StageTimes::default();

        let t = Instant::now();
        self.gather_forces_over(state, lattice, others, forces);
        times.gather_forces_ns = elapsed_ns(t);
        let t = Instant::now();
        self.coarse_spring_forces(state);
        let coarse_ns = elapsed_ns(t);

        let fused = state.neighbourhood == Neighbourhood::Six
            && self.params.solver == AccelSolver::Auto
            && state.mass_is_uniform();
        let solved = if fused {
            // The springs are made inside the projection; their time is in `solve_accel`.
            let t = Instant::now();
            let solved = self.springs_and_solve(state);
            times.solve_accel_ns = elapsed_ns(t);
            times.spring_forces_ns = coarse_ns;
            solved
        } else {
            let t = Instant::now();
            self.spring_forces(state);
            times.spring_forces_ns = elapsed_ns(t) + coarse_ns;
            let t = Instant::now();
            let solved = self.solve_accel(state);
            times.solve_accel_ns = elapsed_ns(t);
            solved
        };
        let (max_accel, cg_iterations) = match solved {
            Ok(v) => v,
            Err(e) => {
                self.counters.failed_steps += 1;
                self.counters.last = times;
                return Err(e);
            }
        };

        let (mut max_accel, mut constrain_ns) = (max_accel, 0);
        if let Some(c) = constraints.as_deref_mut().filter(|c| !c.is_empty()) {
            let t = Instant::now();
            c.project_accel(&mut self.accel);
            max_accel = max_abs(&self.accel).0;
            constrain_ns = elapsed_ns(t);
        }

        let t = Instant::now();
        let (dt_s, halvings) = self.choose_dt(state, max_accel);
        let mut drift_ns = 0;
        if let Some(c) = constraints.filter(|c| !c.is_empty()) {
            let tc = Instant::now();
            c.enforce_with_drift(
                &state.p,
                &state.p_dot,
                &mut self.accel,
                dt_s,
                self.params.integrator,
            );
            max_accel = max_abs(&self.accel).0;
            drift_ns = elapsed_ns(tc);
        }
        times.constrain_ns = constrain_ns + drift_ns;
        // What the freeze mask holds takes its share of the acceleration only; a fully held
        // coefficient stands still (bit for bit: zero velocity, zero acceleration).
        if state.held.len() == state.p.len() {
            hold_masked(&state.held, &mut self.accel, &mut state.p_dot);
        }
        let integrated = self
            .integrate_with_dt(state, dt_s, max_accel)
            .map(|()| (dt_s, halvings));
        times.integrate_ns = elapsed_ns(t).saturating_sub(drift_ns);
        let (dt_s, halvings) = match integrated {
            Ok(v) => v,
            Err(e) => {
                self.counters.failed_steps += 1;
                self.counters.last = times;
                return Err(e);
            }
        };

        let t = Instant::now();
        Self::publish(state, lattice, snapshot);
        times.publish_ns = elapsed_ns(t);

        self.counters.steps += 1;
        self.counters.cg_iterations_last = cg_iterations;
        self.counters.max_accel_last = max_accel;
        self.counters.last = times;
        Ok(StepReport {
            dt_s,
            max_accel,
            halvings,
            cg_iterations,
            version: state.version,
        })
    }

    /// Stage 1: `f_ext` at the mass points from the force vectors, each spread by its `β`.
    /// It replaces the external forces of the previous step.
    ///
    /// Each vector is a closed loop on the surface's position, so the clay comes to rest
    /// where the surface reaches the vector's end and does not pass it:
    /// - eq. (6) is taken on the coast field `s + τ ṡ` (where the clay would stop if every
    ///   force ended now; `dynamics::coast`), the start re-found on its surface, so the force
    ///   vanishes as that surface reaches the end and reverses once it has passed;
    /// - below one knot span the integral's lever `l` is held at one span, so the force falls
    ///   to zero linearly, not quadratically, and still moves the last stretch against the
    ///   clay's elastic stress;
    /// - a mass point's share is gated by how far its column (the line through it along the
    ///   vector) still is from the plane through the end (`TargetBound`), so the spread does
    ///   not keep carving or raising places already at the target;
    /// - a vector's share on its most loaded point moves that point's coast density by at
    ///   most `StepParams::max_coast_step_spans` of surface travel per step, whatever the gain
    ///   (sized for the region's mean mass, at most its material's unpainted mass: clay painted
    ///   heavier moves less than that per step).
    pub fn gather_forces(
        &mut self,
        state: &RegionState,
        lattice: &BSplineLattice,
        forces: &[ToolForce],
    ) {
        self.gather_forces_over(state, lattice, OtherPatches::NONE, forces);
    }

    /// [`Simulator::gather_forces`] on one patch of a multi-patch clay: the forces' integrals
    /// are taken on `lattice` plus `others`.
    pub fn gather_forces_over(
        &mut self,
        state: &RegionState,
        lattice: &BSplineLattice,
        others: OtherPatches<'_>,
        forces: &[ToolForce],
    ) {
        self.ensure_scratch(state);
        // The forces are sparse: clear only what the previous step wrote.
        let dirty = self.external_dirty.start.min(self.external.len())
            ..self.external_dirty.end.min(self.external.len());
        self.external[dirty].fill(0.0);
        self.external_dirty = 0..0;
        let grid = &state.grid;
        if forces.is_empty() && self.bodies.is_empty() {
            return;
        }
        // Eq. (6) on the coast field (see `coast.rs`): each vector's start re-found on the
        // surface the clay is coasting to, so the force vanishes as that surface reaches the
        // vector's end and reverses once it has passed.
        let velocity = RegionVelocity {
            origin: lattice.origin,
            spacing: lattice.spacing,
            coeffs: state.coeff_box(),
            p_dot: &state.p_dot,
        };
        let tau_s = coast_time_s(&state.mass, &state.damping, &state.stiffness);
        let reach = COAST_REACH_SPANS * lattice.spacing;
        // Force on one mass point that moves its coast density by one unit of density in one
        // step (`Δ(d + τ ḋ) ≈ (τ + Δt) Δt F / μ`), times the largest surface travel per step.
        let dt = if state.dt_s > 0.0 {
            state.dt_s
        } else {
            self.params.dt_max_s
        };
        // The cap is sized for the region's own mass, but never for more than its material's
        // unpainted mass: a region painted heavier then takes the unpainted clay's largest
        // force, and so lags as its mass asks, where a cap that grew with the painted mass
        // moved heavy clay as fast as light clay at any large gain.
        // (A mean within rounding of the material's mass is kept as it is: unpainted clay's cap
        // is the same to the bit as before the cap knew the material.)
        let mean_mass = state.mass.iter().sum::<f32>() / state.mass.len().max(1) as f32;
        let cap_mass = if mean_mass > state.material_mass * (1.0 + 1e-4) {
            state.material_mass
        } else {
            mean_mass
        };
        // The travel is in the base's knot spans (the patch's times its ratio) where the
        // region's material is two-level: it resists a dent as the base does, so a force
        // tool may move the clay there as far a step as on the base.
        let travel =
            self.params.max_coast_step_spans * lattice.spacing * state.spacing_ratio.max(1) as f32;
        let coast_cap = travel * cap_mass / ((tau_s + dt) * dt);
        let among = PatchAmongOthers { lattice, others };
        let coast_alone = CoastField {
            field: lattice,
            velocity,
            tau_s,
        };
        let coast_among = CoastField {
            field: &among,
            velocity,
            tau_s,
        };
        let coast: &dyn ImplicitField = if others.is_empty() {
            &coast_alone
        } else {
            &coast_among
        };
        for tf in forces {
            let start = start_on_coast(coast, tf.start, tf.end, reach);
            let tf = &ToolForce { start, ..*tf };
            // Eq. (6)'s `l · ∫(s − iso)` vanishes quadratically as the surface reaches the
            // end, too weakly to move the last stretch against the clay's elastic stress
            // (the plastic preset keeps up to its yield density of it): below one knot span
            // the lever `l` is held at one span, so the force falls to zero linearly there.
            let l = (tf.end - start).length();
            let lever = if l > 0.0 {
                (MIN_LEVER_SPANS * lattice.spacing / l).max(1.0)
            } else {
                1.0
            };
            // The clay yields only to what exceeds its yield (see `set_force_yield`).
            let integral = force_integral(coast, start, tf.end);
            let yielded = (integral.abs() - self.force_yield)
                .max(0.0)
                .copysign(integral);
            let f = yielded * lever * tf.gain;
            let bound = TargetBound::new(coast, tf, f, lattice.spacing);
            let ok = f.is_finite() && tf.radius.is_finite() && tf.radius > 0.0;
            if !ok {
                self.counters.rejected_forces += 1;
                continue;
            }
            if f == 0.0 {
                continue;
            }
            let Some(range) = mass_range(grid, lattice, tf.start, tf.end, tf.radius) else {
                continue;
            };
            // Two passes over the box: the weights and their total, then the scaled forces
            // from the weights kept in the first (the box has at most one weight per point).
            // Each weight is gated by the room its point has left (see `TargetBound`), and the
            // force goes to the points that can still move the surface.
            let mut total = 0.0_f32;
            let mut peak = 0.0_f32;
            let mut at_weight = 0;
            // Each column's share is read once (one coast evaluation per grid line through
            // the box, not per mass point: 121 instead of 1331 for the default push).
            let axis = bound.column_axis();
            let (across_a, across_b) = match axis {
                Some(0) => (1, 2),
                Some(1) => (0, 2),
                _ => (0, 1),
            };
            let width_a = range[across_a].1 - range[across_a].0 + 1;
            let columns = width_a * (range[across_b].1 - range[across_b].0 + 1);
            self.column_room.clear();
            self.column_room.resize(columns, f32::NAN);
            for k in range[2].0..=range[2].1 {
                for j in range[1].0..=range[1].1 {
                    for i in range[0].0..=range[0].1 {
                        let x = grid.position(lattice, i, j, k);
                        let mut w = tf.distribution.weight(x, tf.start, tf.end, tf.radius);
                        if w != 0.0 {
                            // The total is of the ungated weights: a gate only takes force
                            // away from a column, never piles it onto the others.
                            total += w;
                            if let Some(axis) = axis {
                                let at = [i, j, k];
                                let column = (at[across_a] - range[across_a].0)
                                    + width_a * (at[across_b] - range[across_b].0);
                                let room = &mut self.column_room[column];
                                if room.is_nan() {
                                    *room = bound.room(coast, x, axis);
                                }
                                w *= *room;
                            }
                            peak = peak.max(w.abs());
                        }
                        self.weights[at_weight] = w;
                        at_weight += 1;
                    }
                }
            }
            if total <= 0.0 {
                continue;
            }
            // The step's share of the force on its most loaded point moves that point's coast
            // density by at most `max_coast_step_spans` knot spans of surface travel: no
            // gain carries the coast surface past a target in one step, and the step keeps
            // its size instead of halving down to nothing under a huge gain.
            // A force planned far ahead on a detail patch may cover what is left of it at the
            // base's pace (see `RegionState::set_planned_travel_ratio`).
            let far =
                far_travel_factor(state, l, self.params.max_coast_step_spans * lattice.spacing);
            let most = coast_cap * far * bound.slope;
            let scale = if (f / total).abs() * peak > most {
                most / peak * f.signum()
            } else {
                f / total
            };
            self.add_weighted_external(state, range, scale);
        }
        for n in 0..self.bodies.len() {
            let body = self.bodies[n];
            self.add_body_force(state, lattice, coast, &body, coast_cap);
        }
    }

    /// Adds `f` to the external force on mass point `at`, noting it among the points written.
    #[inline]
    fn add_external(&mut self, at: usize, f: f32) {
        self.external[at] += f;
        let d = &mut self.external_dirty;
        (d.start, d.end) = if d.start >= d.end {
            (at, at + 1)
        } else {
            (d.start.min(at), d.end.max(at + 1))
        };
    }

    /// The force of a tool's body ([`ToolBody`]) on the clay in its shaft, added to the
    /// external forces. The coast density's excess over the iso-level is read at
    /// [`BODY_STATIONS`] points along the shaft; where there is any, the densities are pushed
    /// down there, spread across the shaft by the body's `β` and along it by the excess
    /// itself. The body is rigid: its most loaded mass point is driven at the step's cap
    /// (`max_coast_step_spans` of surface travel a step, as under a force vector) once the
    /// clay stands a fiftieth of a knot span into the shaft, fading below that. Nothing
    /// where the shaft is open (the hole the tool made, or open air); on the coast field the
    /// body acts as the walls are about to close, and falls silent as they are about to
    /// clear.
    fn add_body_force(
        &mut self,
        state: &RegionState,
        lattice: &BSplineLattice,
        coast: &dyn ImplicitField,
        body: &ToolBody,
        coast_cap: f32,
    ) {
        let axis = body.outer - body.inner;
        let len = axis.length();
        let valid = len.is_finite() && len > 0.0 && body.radius.is_finite() && body.radius > 0.0;
        if !valid {
            return;
        }
        let iso = coast.iso();
        let mut excess = [0.0_f32; BODY_STATIONS];
        let (mut most, mut most_at) = (0.0_f32, 0);
        for (k, e) in excess.iter_mut().enumerate() {
            let x = body.inner + axis * ((k as f32 + 0.5) / BODY_STATIONS as f32);
            *e = (coast.value(x) - iso).max(0.0);
            if *e > most {
                (most, most_at) = (*e, k);
            }
        }
        // An open shaft (or a non-finite read): nothing to push out.
        if most <= 0.0 || !most.is_finite() {
            return;
        }
        // The density ramp across the surface, as `TargetBound` reads it, where the shaft
        // holds the most clay: it turns the cap's travel into density, and the fade's.
        let at = body.inner + axis * ((most_at as f32 + 0.5) / BODY_STATIONS as f32);
        let floor = iso / (2.0 * lattice.spacing);
        let measured = coast.value_and_gradient(at).1.length();
        let slope = if measured.is_finite() {
            measured.max(floor)
        } else {
            floor
        };
        let fade = (most / (BODY_FADE_SPANS * lattice.spacing * slope)).min(1.0);
        let grid = &state.grid;
        let Some(range) = mass_range(grid, lattice, body.inner, body.outer, body.radius) else {
            return;
        };
        // The excess along the shaft at the mass point's projection on it, linear between
        // the stations.
        let excess_at = |x: Vec3| {
            let t = ((x - body.inner).dot(axis) / (len * len)).clamp(0.0, 1.0);
            let u = (t * BODY_STATIONS as f32 - 0.5).clamp(0.0, (BODY_STATIONS - 1) as f32);
            let k = (u as usize).min(BODY_STATIONS - 2);
            let frac = u - k as f32;
            excess[k] * (1.0 - frac) + excess[k + 1] * frac
        };
        let (mut peak, mut at_weight) = (0.0_f32, 0);
        for k in range[2].0..=range[2].1 {
            for j in range[1].0..=range[1].1 {
                for i in range[0].0..=range[0].1 {
                    let x = grid.position(lattice, i, j, k);
                    let mut w = body
                        .distribution
                        .weight(x, body.inner, body.outer, body.radius);
                    if w != 0.0 {
                        w *= excess_at(x);
                        peak = peak.max(w);
                    }
                    self.weights[at_weight] = w;
                    at_weight += 1;
                }
            }
        }
        if peak <= 0.0 || !peak.is_finite() {
            return;
        }
        let scale = -coast_cap * slope * fade / peak;
        self.add_weighted_external(state, range, scale);
    }

    /// Adds `scale` times the weights of the mass points in `range` (in `self.weights`, x
    /// fastest, as the range is walked) to their external forces.
    fn add_weighted_external(
        &mut self,
        state: &RegionState,
        range: [(usize, usize); 3],
        scale: f32,
    ) {
        let mut at_weight = 0;
        for k in range[2].0..=range[2].1 {
            for j in range[1].0..=range[1].1 {
                for i in range[0].0..=range[0].1 {
                    let w = self.weights[at_weight];
                    at_weight += 1;
                    if w != 0.0 {
                        self.add_external(state.point_index(i, j, k), scale * w);
                    }
                }
            }
        }
    }

    /// The coarse springs of a detail patch's region with a two-level material
    /// ([`RegionState::set_coarse_springs`]; see `dynamics::coarse`), added to the external
    /// forces of stage 1 so both spring kernels take them as they are. Nothing otherwise.
    pub fn coarse_spring_forces(&mut self, state: &RegionState) {
        if state.coarse_stride < 2 || state.spacing_ratio < 2 {
            return;
        }
        self.ensure_scratch(state);
        self.coarse.add_forces(
            state.grid.dims,
            (state.coarse_stride, state.spacing_ratio),
            &state.d,
            &state.rest,
            &state.stiffness,
            &mut self.e,
            &mut self.external,
        );
        // Every point may hold a coarse share now: the next step clears them all.
        self.external_dirty = 0..state.d.len();
    }

    /// Stage 2: the total force per mass point: the external forces of stage 1, density
    /// springs toward the rest densities, and damping `−γ ḋ`.
    pub fn spring_forces(&mut self, state: &RegionState) {
        self.ensure_scratch(state);
        if state.neighbourhood == Neighbourhood::Six {
            let fields = SpringFields {
                dims: state.grid.dims,
                d: &state.d,
                rest: &state.rest,
                stiffness: &state.stiffness,
                damping: &state.damping,
                d_dot: &state.d_dot,
                external: &self.external,
                zeros: &self.zeros,
            };
            passes::springs_six(
                &mut self.team,
                &fields,
                &mut self.e_pad,
                &mut self.k_pad,
                &mut self.force,
            );
            return;
        }
        self.force.copy_from_slice(&self.external);
        add_spring_forces(
            state.grid.dims,
            &state.d,
            &state.rest,
            &state.stiffness,
            state.neighbourhood,
            &mut self.e,
            &mut self.force,
        );
        for ((f, &g), &v) in self.force.iter_mut().zip(&state.damping).zip(&state.d_dot) {
            *f -= g * v;
        }
    }

    /// Stages 2 and 3 fused, for the six-neighbour springs and a uniform mass: the total
    /// force is made plane by plane inside the projection `p̈ = (AᵀA)⁻¹ Aᵀ f / μ` and never
    /// stored whole. Bit-identical to [`Simulator::spring_forces`] then
    /// [`Simulator::solve_accel`]. Returns `max|p̈|` and 0 CG iterations.
    ///
    /// # Errors
    /// When `p̈` is not finite.
    fn springs_and_solve(&mut self, state: &RegionState) -> Result<(f32, u32), StepError> {
        self.ensure_scratch(state);
        let fields = SpringFields {
            dims: state.grid.dims,
            d: &state.d,
            rest: &state.rest,
            stiffness: &state.stiffness,
            damping: &state.damping,
            d_dot: &state.d_dot,
            external: &self.external,
            zeros: &self.zeros,
        };
        let mu = state.mass.first().copied().unwrap_or(1.0);
        let (max, finite) = passes::springs_project(
            &mut self.team,
            &fields,
            (&mut self.e_pad, &mut self.k_pad),
            &mut self.plane_buf,
            &state.basis,
            1.0 / mu,
            ChainScratch {
                t1: &mut self.t1,
                t2: &mut self.t2,
            },
            &mut self.accel,
        );
        if !finite {
            return Err(StepError::NonFinite {
                stage: "solve_accel",
            });
        }
        Ok((max, 0))
    }

    /// Stage 3: `p̈ = (AᵀMA)⁻¹ Aᵀ f`. Returns `max|p̈|` and the CG iteration count. With a
    /// uniform mass this is one fused projection `(AᵀA)⁻¹ Aᵀ f / μ`.
    ///
    /// # Errors
    /// When `p̈` is not finite.
    pub fn solve_accel(&mut self, state: &RegionState) -> Result<(f32, u32), StepError> {
        self.ensure_scratch(state);
        let basis = &state.basis;
        let uniform = self.params.solver == AccelSolver::Auto && state.mass_is_uniform();
        let (max, finite, iterations) = if uniform {
            let mu = state.mass.first().copied().unwrap_or(1.0);
            let scratch = ChainScratch {
                t1: &mut self.t1,
                t2: &mut self.t2,
            };
            let (max, finite) = passes::project(
                &mut self.team,
                basis,
                &self.force,
                1.0 / mu,
                scratch,
                &mut self.accel,
            );
            (max, finite, 0)
        } else {
            basis.apply_transpose(&self.force, &mut self.rhs, &mut self.kron);
            let it = self.conjugate_gradient(state);
            let (max, finite) = max_abs(&self.accel);
            (max, finite, it)
        };
        if !finite {
            return Err(StepError::NonFinite {
                stage: "solve_accel",
            });
        }
        Ok((max, iterations))
    }

    /// Solve `(AᵀMA) x = rhs` into `accel` by conjugate gradients preconditioned with
    /// `(μ̄ AᵀA)⁻¹`, warm-started from the previous acceleration.
    fn conjugate_gradient(&mut self, state: &RegionState) -> u32 {
        let basis = &state.basis;
        let mean_mass = (state.mass.iter().map(|&m| f64::from(m)).sum::<f64>()
            / state.mass.len() as f64) as f32;
        let inv_mean = if mean_mass > 0.0 {
            1.0 / mean_mass
        } else {
            1.0
        };
        if !self.accel.iter().all(|v| v.is_finite()) {
            self.accel.fill(0.0);
        }
        // q = H accel; r = rhs − q
        Self::apply_h(
            basis,
            &state.mass,
            &self.accel,
            &mut self.cg_q,
            &mut self.tmp,
            &mut self.kron,
        );
        for ((r, &b), &q) in self.cg_r.iter_mut().zip(&self.rhs).zip(&self.cg_q) {
            *r = b - q;
        }
        let b_norm = dot(&self.rhs, &self.rhs).sqrt();
        let target = f64::from(self.params.cg_tolerance) * b_norm;
        if b_norm == 0.0 {
            self.accel.fill(0.0);
            return 0;
        }
        basis.solve_gram_into(&self.cg_r, &mut self.cg_z, &mut self.kron);
        self.cg_z.iter_mut().for_each(|z| *z *= inv_mean);
        self.cg_dir.copy_from_slice(&self.cg_z);
        let mut rz = dot(&self.cg_r, &self.cg_z);
        let mut it = 0;
        while it < self.params.cg_max_iterations {
            if dot(&self.cg_r, &self.cg_r).sqrt() <= target {
                break;
            }
            it += 1;
            Self::apply_h(
                basis,
                &state.mass,
                &self.cg_dir,
                &mut self.cg_q,
                &mut self.tmp,
                &mut self.kron,
            );
            let dq = dot(&self.cg_dir, &self.cg_q);
            if dq.is_nan() || dq <= 0.0 {
                break;
            }
            let alpha = (rz / dq) as f32;
            for ((x, r), (&p, &q)) in self
                .accel
                .iter_mut()
                .zip(self.cg_r.iter_mut())
                .zip(self.cg_dir.iter().zip(&self.cg_q))
            {
                *x += alpha * p;
                *r -= alpha * q;
            }
            basis.solve_gram_into(&self.cg_r, &mut self.cg_z, &mut self.kron);
            self.cg_z.iter_mut().for_each(|z| *z *= inv_mean);
            let rz_new = dot(&self.cg_r, &self.cg_z);
            let beta = (rz_new / rz) as f32;
            rz = rz_new;
            for (p, &z) in self.cg_dir.iter_mut().zip(&self.cg_z) {
                *p = z + beta * *p;
            }
        }
        it
    }

    /// `out = Aᵀ M A v`.
    fn apply_h(
        basis: &crate::field::KroneckerBasis,
        mass: &[f32],
        v: &[f32],
        out: &mut [f32],
        tmp: &mut [f32],
        kron: &mut KronScratch,
    ) {
        basis.apply(v, tmp, kron);
        for (t, &m) in tmp.iter_mut().zip(mass) {
            *t *= m;
        }
        basis.apply_transpose(tmp, out, kron);
    }

    /// Stage 4: choose the adaptive step, then forward Euler on `ṗ` and `p`, the densities
    /// (`ḋ = A ṗ`, `d` advanced by linearity and recomputed every `resync_every` steps) and the
    /// plastic drift of the rest densities. Returns the step used and the halvings.
    ///
    /// # Errors
    /// When the new coefficients would exceed `max_abs_coeff` or not be finite; nothing but
    /// the time step is written then.
    pub fn integrate(
        &mut self,
        state: &mut RegionState,
        max_accel: f32,
    ) -> Result<(f32, u32), StepError> {
        let (dt, halvings) = self.choose_dt(state, max_accel);
        self.integrate_with_dt(state, dt, max_accel)?;
        Ok((dt, halvings))
    }

    /// The adaptive step (§6): halved while `max_accel · Δt` exceeds the velocity-change
    /// bound, grown back after calm steps. Stored in `state.dt_s`; returns it and the halvings.
    fn choose_dt(&mut self, state: &mut RegionState, max_accel: f32) -> (f32, u32) {
        let p = &self.params;
        let mut dt = if state.dt_s > 0.0 {
            state.dt_s.clamp(p.dt_min_s, p.dt_max_s)
        } else {
            p.dt_max_s
        };
        let mut halvings = 0;
        // A region whose threshold is the base's (a two-level one, see `gather_forces_over`,
        // or one set with `set_base_step_threshold`) may move its coefficients as far a step
        // as the base's in the world: `ratio` of its own knot spans.
        let vmax = p.max_velocity_change * state.threshold_ratio.max(1) as f32;
        while max_accel * dt > vmax && dt > p.dt_min_s {
            dt = (0.5 * dt).max(p.dt_min_s);
            halvings += 1;
        }
        if halvings > 0 {
            state.calm_steps = 0;
        } else if max_accel * dt < 0.25 * vmax {
            state.calm_steps += 1;
            if state.calm_steps >= p.calm_steps_to_grow && dt < p.dt_max_s {
                dt = (dt * p.growth).min(p.dt_max_s);
                state.calm_steps = 0;
                self.counters.growths += 1;
            }
        } else {
            state.calm_steps = 0;
        }
        self.counters.halvings += u64::from(halvings);
        state.dt_s = dt;
        (dt, halvings)
    }

    /// Forward Euler with the step `dt` (see [`Simulator::integrate`]).
    fn integrate_with_dt(
        &mut self,
        state: &mut RegionState,
        dt: f32,
        max_accel: f32,
    ) -> Result<(), StepError> {
        let p = &self.params;
        // Bound the new state before writing any of it.
        let (p_max, v_max, finite) =
            passes::coefficient_bounds(&mut self.team, &state.p, &state.p_dot);
        let v_new = v_max + dt * max_accel;
        let bound = p_max + dt * v_new.max(v_max);
        if !(finite && bound.is_finite() && bound <= p.max_abs_coeff) {
            return Err(StepError::Diverged { bound });
        }

        state.steps_since_resync += 1;
        let resync = state.steps_since_resync >= p.resync_every;
        // Mass points painted with no drift leave the rest densities as they are; a region with
        // none that drifts skips the drift altogether.
        let drifts = state.plasticity_per_s.iter().any(|&r| r > 0.0);
        let yield_density = state.yield_density.max(0.0);
        let plastic = (drifts && !resync).then_some(Plastic {
            rate_per_s: &state.plasticity_per_s,
            dt_s: dt,
            yield_density,
        });
        passes::integrate(
            &mut self.team,
            &state.basis,
            dt,
            p.integrator,
            // On a resync step the drift waits for the recomputed densities.
            plastic,
            (&mut state.p, &mut state.p_dot, &self.accel),
            ChainScratch {
                t1: &mut self.t1,
                t2: &mut self.t2,
            },
            Densities {
                d_dot: &mut state.d_dot,
                d: &mut state.d,
                rest: &mut state.rest,
            },
        );
        if resync {
            state.resync_densities_with(&mut self.kron);
            if drifts {
                let pl = Plastic {
                    rate_per_s: &state.plasticity_per_s,
                    dt_s: dt,
                    yield_density,
                };
                plastic_drift(&state.d, &mut state.rest, pl.rate_per_s, &pl);
            }
        }
        state.time_s += f64::from(dt);
        state.version += 1;
        Ok(())
    }

    /// Stage 5: the region's coefficients into the lattice, and a snapshot of them.
    pub fn publish(
        state: &RegionState,
        lattice: &mut BSplineLattice,
        snapshot: &mut RegionSnapshot,
    ) {
        let b = state.coeff_box();
        lattice.coeffs.write_box(b.min, b.dims(), &state.p);
        // Rows written with the values a uniform brick holds leave it uniform; a brick the
        // step moved and brought back to one value is freed again.
        lattice.coeffs.compact_within(b.min, b.max);
        // The lattice now holds `state.p` over the box: the snapshot copies them as they are.
        snapshot.capture_written(lattice, b, &state.p, state.version);
    }

    /// The acceleration computed by the last step (for diagnostics and tests).
    #[must_use]
    pub fn last_accel(&self) -> &[f32] {
        &self.accel
    }
}

/// Scales each coefficient's acceleration by `1 − hold` and stops the fully held ones (their
/// velocity zeroed), so a masked coefficient keeps its value and a half-held one moves about
/// half as far from rest. Allocates nothing.
fn hold_masked(held: &[f32], accel: &mut [f32], p_dot: &mut [f32]) {
    for ((&m, a), v) in held.iter().zip(accel.iter_mut()).zip(p_dot.iter_mut()) {
        if m >= 1.0 {
            *a = 0.0;
            *v = 0.0;
        } else if m > 0.0 {
            *a *= 1.0 - m;
        }
    }
}

fn dot(a: &[f32], b: &[f32]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(&x, &y)| f64::from(x) * f64::from(y))
        .sum()
}

/// The bound a force vector sets on the mass points it spreads over: the surface must not
/// pass the plane through the vector's end perpendicular to it. A mass point's share is
/// scaled by how far the coast surface of its column (the grid line through it nearest the vector, below)
/// still is from that plane, read as the coast density where the column meets the plane:
/// while that point is on the near side of the surface the column may still move, and its
/// share fades to zero over the last tenth of a knot span of travel. Without it the spread
/// `β` keeps carving (or raising) columns whose own target is already reached: a push groove
/// sank below the tip's path behind the tip, a chisel cut where its neighbours' spread
/// reached. A whole column shares one factor, so the gated force stays as smooth as `β` and
/// its projection onto the spline does not spill past the plane. The columns are the mass
/// grid's lines along the axis nearest the vector (exactly the vector's own lines for a push
/// along an axis), so each is read once per step.
#[derive(Clone, Copy, Debug)]
struct TargetBound {
    end: Vec3,
    /// Unit vector along the force vector; zero for no bound.
    dir: Vec3,
    sign: f32,
    iso: f32,
    /// Density over which a column's share fades.
    band: f32,
    /// The density ramp across the surface, per world unit.
    slope: f32,
}

impl TargetBound {
    fn new(field: &dyn ImplicitField, tf: &ToolForce, f: f32, spacing: f32) -> Self {
        let dir = (tf.end - tf.start).normalize_or_zero();
        // The density ramp across the surface: as measured where the vector starts, and never
        // flatter than the iso-level over two knot spans.
        let floor = field.iso() / (2.0 * spacing);
        let measured = field.value_and_gradient(tf.start).1.length();
        let slope = if measured.is_finite() {
            measured.max(floor)
        } else {
            floor
        };
        Self {
            end: tf.end,
            dir: if f.is_finite() && f != 0.0 {
                dir
            } else {
                Vec3::ZERO
            },
            sign: f.signum(),
            iso: field.iso(),
            band: 0.02 * spacing * slope,
            slope,
        }
    }

    /// The mass grid's axis nearest the vector's direction: its columns are the grid lines
    /// along it (`None` for no bound).
    fn column_axis(&self) -> Option<usize> {
        if self.dir == Vec3::ZERO {
            return None;
        }
        let a = self.dir.abs();
        Some(if a.x >= a.y && a.x >= a.z {
            0
        } else if a.y >= a.z {
            1
        } else {
            2
        })
    }

    /// The share (0 to 1) the column through the mass point at `x` along the grid axis `axis`
    /// ([`TargetBound::column_axis`]) may still take, on the coast field `field`: read where
    /// that grid line meets the plane.
    #[inline]
    fn room(&self, field: &dyn ImplicitField, x: Vec3, axis: usize) -> f32 {
        let along = Vec3::AXES[axis];
        let on_plane = x - along * ((x - self.end).dot(self.dir) / self.dir[axis]);
        let room = -self.sign * (field.value(on_plane) - self.iso);
        (room / self.band).clamp(0.0, 1.0)
    }
}

/// Knot spans the clay must stand into a tool body's shaft for the body to push it out at
/// the step's full cap (as `TargetBound` fades a column's share).
const BODY_FADE_SPANS: f32 = 0.02;

/// Stations along a tool body's shaft at which [`Simulator::add_body_force`] reads the clay
/// in it (a 0.12-long shaft is read every 0.004, a third of a mass step two levels down).
const BODY_STATIONS: usize = 32;

/// The mass-index range of `grid` in the bounding box of the segment `a → b` grown by
/// `radius`, per axis (first, last); `None` when the box misses the grid.
fn mass_range(
    grid: &crate::field::MassGrid,
    lattice: &BSplineLattice,
    a: Vec3,
    b: Vec3,
    radius: f32,
) -> Option<[(usize, usize); 3]> {
    let lo = lattice.to_lattice(a.min(b) - radius);
    let hi = lattice.to_lattice(a.max(b) + radius);
    let mut range = [(0_usize, 0_usize); 3];
    for axis in 0..3 {
        let step = grid.step(axis) as f32;
        let c0 = grid.coeffs.min[axis] as f32;
        let (first, last) = if step > 0.0 {
            (
                ((lo[axis] - c0) / step).ceil(),
                ((hi[axis] - c0) / step).floor(),
            )
        } else {
            (0.0, 0.0)
        };
        let first = first.max(0.0);
        let last = last.min((grid.dims[axis] - 1) as f32);
        if first.is_nan() || last.is_nan() || first > last {
            return None;
        }
        range[axis] = (first as usize, last as usize);
    }
    Some(range)
}

/// One patch's lattice with the fixed patches around it: the clay's density as the force
/// integrals read it while the patch is simulated.
struct PatchAmongOthers<'a> {
    lattice: &'a BSplineLattice,
    others: OtherPatches<'a>,
}

impl ImplicitField for PatchAmongOthers<'_> {
    fn iso(&self) -> f32 {
        self.lattice.iso
    }

    fn value(&self, p: Vec3) -> f32 {
        self.lattice.value(p) + self.others.value(p)
    }

    fn value_and_gradient(&self, p: Vec3) -> (f32, Vec3) {
        let (v, g) = self.lattice.value_and_gradient(p);
        let (ov, og) = self.others.value_and_gradient(p);
        (v + ov, g + og)
    }
}

/// How many times `patch_travel` (the patch's largest surface travel per step) a force with
/// `remaining` left to its end may move `state`'s clay in a step: as far as what is left, at
/// least the patch's travel and at most [`RegionState::planned_travel_ratio`] times it (a
/// two-level region's travel is the base's already).
fn far_travel_factor(state: &RegionState, remaining: f32, patch_travel: f32) -> f32 {
    let ratio = state.planned_travel_ratio.max(1);
    if ratio <= 1
        || state.spacing_ratio > 1
        || remaining.is_nan()
        || patch_travel.is_nan()
        || patch_travel <= 0.0
    {
        return 1.0;
    }
    (remaining / patch_travel).clamp(1.0, ratio as f32)
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;
    use crate::dynamics::{
        Distribution, Integrator, Material, ToolBody, reaction_force, surface_point_on_ray,
    };
    use crate::field::{CoeffBox, Primitive, lattice_from_primitive};

    const CENTRE: Vec3 = Vec3::new(0.95, 0.95, 0.95);
    const RADIUS: f32 = 0.4;
    const GAIN: f32 = 1e6;
    /// Fully plastic creep (no yield threshold): the springs give way until the force is spent.
    const CREEP: Material = Material {
        yield_density: 0.0,
        ..Material::PLASTIC
    };

    fn sphere() -> BSplineLattice {
        let s = Primitive::Sphere {
            centre: CENTRE,
            radius: RADIUS,
        };
        lattice_from_primitive([20, 20, 20], 0.1, Vec3::ZERO, &s, 0.2, 2).unwrap()
    }

    /// Region around the +x pole of the sphere (x = 1.35, lattice coordinate 13.5).
    fn region(lattice: &BSplineLattice, material: Material) -> RegionState {
        let b = CoeffBox {
            min: [10, 6, 6],
            max: [17, 13, 13],
        };
        RegionState::new(lattice, b, [15, 15, 15], material).unwrap()
    }

    fn surface_radius(lattice: &BSplineLattice, dir: Vec3) -> f32 {
        surface_point_on_ray(lattice, CENTRE, dir, 0.9, 0.01).map_or(0.0, |p| (p - CENTRE).length())
    }

    fn grab(lattice: &BSplineLattice, cursor: Vec3, gain: f32) -> Option<ToolForce> {
        let dir = cursor - CENTRE;
        let x0 = surface_point_on_ray(lattice, CENTRE, dir, 0.9, 0.01)?;
        Some(ToolForce {
            start: x0,
            end: cursor,
            distribution: Distribution::Constant,
            radius: 0.12,
            gain,
        })
    }

    /// A tool body along the x axis through the +x pole: from inside the sphere out past
    /// its surface, or wholly in the open air beyond it.
    fn body_along_x(from: f32, to: f32) -> ToolBody {
        ToolBody {
            inner: CENTRE + Vec3::X * from,
            outer: CENTRE + Vec3::X * to,
            distribution: Distribution::Gaussian,
            radius: 0.12,
        }
    }

    #[test]
    fn a_tool_body_pushes_out_the_clay_in_its_shaft_and_adds_nothing_where_the_shaft_is_open() {
        let mut lattice = sphere();
        let mut state = region(&lattice, CREEP);
        let mut sim = Simulator::new(StepParams::default());
        // Open air beyond the pole: no force at all.
        sim.set_tool_bodies(&[body_along_x(RADIUS + 0.05, RADIUS + 0.3)]);
        sim.gather_forces(&state, &lattice, &[]);
        assert!(sim.external.iter().all(|&f| f == 0.0), "an open shaft");
        // A shaft from 0.1 inside the pole out past it: the clay in it is pushed down, and
        // only there.
        let body = body_along_x(RADIUS - 0.1, RADIUS + 0.2);
        sim.set_tool_bodies(&[body]);
        sim.gather_forces(&state, &lattice, &[]);
        assert!(
            sim.external.iter().all(|&f| f <= 0.0),
            "the body only removes clay"
        );
        let pushed: Vec<usize> = (0..sim.external.len())
            .filter(|&n| sim.external[n] < 0.0)
            .collect();
        assert!(!pushed.is_empty(), "the clay in the shaft is pushed");
        let m = state.grid.dims;
        for &n in &pushed {
            let (i, j, k) = (n % m[0], (n / m[0]) % m[1], n / (m[0] * m[1]));
            let x = state.grid.position(&lattice, i, j, k);
            assert!(
                Distribution::Gaussian.weight(x, body.inner, body.outer, body.radius) > 0.0,
                "pushed outside the shaft at {x}"
            );
        }
        // Stepped, the pole gives way along the shaft: its surface sinks toward the shaft's
        // inner end.
        let mut snap = RegionSnapshot::default();
        let before = surface_radius(&lattice, Vec3::X);
        for _ in 0..300 {
            sim.step(&mut state, &mut lattice, &[], &mut snap).unwrap();
        }
        let after = surface_radius(&lattice, Vec3::X);
        assert!(
            after < before - 0.05,
            "the shaft is cleared: surface {before} -> {after}"
        );
        assert!(
            after > RADIUS - 0.1 - 0.02,
            "no deeper than the shaft's inner end: {after}"
        );
    }

    #[test]
    fn fig3_outward_force_grows_the_solid_to_the_cursor_and_the_reaction_decays() {
        let mut lattice = sphere();
        let mut state = region(&lattice, CREEP);
        let mut sim = Simulator::new(StepParams::default());
        let mut snap = RegionSnapshot::default();
        let cursor = CENTRE + Vec3::X * (RADIUS + 0.15);
        let between = CENTRE + Vec3::X * (RADIUS + 0.075);
        assert!(lattice.value(between) < lattice.iso);
        let mut peak = 0.0_f32;
        let mut last = 0.0_f32;
        for _ in 0..4000 {
            let Some(tf) = grab(&lattice, cursor, GAIN) else {
                break;
            };
            last = reaction_force(&lattice, tf.start, tf.end).length();
            peak = peak.max(last);
            sim.step(&mut state, &mut lattice, &[tf], &mut snap)
                .unwrap();
        }
        let r = surface_radius(&lattice, Vec3::X);
        assert!(r > RADIUS + 0.15 - 0.015, "surface reached {r}");
        assert!(lattice.value(between) > lattice.iso);
        assert!(
            peak > 0.0 && last < 0.1 * peak,
            "reaction {last} of peak {peak}"
        );
        assert_eq!(snap.version, state.version);
    }

    #[test]
    fn fig3_reversed_force_shrinks_the_solid() {
        let mut lattice = sphere();
        let mut state = region(&lattice, CREEP);
        let mut sim = Simulator::new(StepParams::default());
        let mut snap = RegionSnapshot::default();
        let cursor = CENTRE + Vec3::X * (RADIUS - 0.12);
        for _ in 0..4000 {
            let Some(tf) = grab(&lattice, cursor, GAIN) else {
                break;
            };
            assert!(force_integral(&lattice, tf.start, tf.end) <= 0.0);
            sim.step(&mut state, &mut lattice, &[tf], &mut snap)
                .unwrap();
        }
        let r = surface_radius(&lattice, Vec3::X);
        assert!((r - (RADIUS - 0.12)).abs() < 0.02, "surface at {r}");
    }

    #[test]
    fn elastic_perturbation_returns_to_rest_and_energy_decays() {
        let mut lattice = sphere();
        let mut state = region(&lattice, Material::ELASTIC);
        let rest_p = state.p.clone();
        // Perturb the coefficients (rest densities stay where they were).
        for (n, p) in state.p.iter_mut().enumerate() {
            *p += 0.2 * ((n * 13 % 7) as f32 / 7.0 - 0.5);
        }
        let mut sim = Simulator::new(StepParams::default());
        state.resync_densities_with(&mut KronScratch::for_basis(&state.basis));
        let mut snap = RegionSnapshot::default();
        let e0 = state.energy();
        let mut previous = e0;
        for s in 0..3000 {
            sim.step(&mut state, &mut lattice, &[], &mut snap).unwrap();
            if s % 50 == 49 {
                // Monotone decay while above the f32 noise floor of the densities.
                let e = state.energy();
                if previous > 1e-3 * e0 {
                    assert!(e <= previous, "energy grew at {s}: {previous} -> {e}");
                }
                previous = e;
            }
        }
        assert!(previous < 1e-4 * e0, "energy {previous} of {e0}");
        let err = state
            .p
            .iter()
            .zip(&rest_p)
            .fold(0.0_f32, |m, (a, b)| m.max((a - b).abs()));
        assert!(err < 2e-3, "coefficients off rest by {err}");
    }

    #[test]
    fn plastic_dent_persists_and_elastic_dent_springs_back() {
        let probe = CENTRE + Vec3::X * (RADIUS - 0.05);
        let mut dents = Vec::new();
        for material in [Material::PLASTIC, Material::ELASTIC] {
            let mut lattice = sphere();
            let before = lattice.value(probe);
            let mut state = region(&lattice, material);
            let mut sim = Simulator::new(StepParams::default());
            let mut snap = RegionSnapshot::default();
            let cursor = CENTRE + Vec3::X * (RADIUS - 0.1);
            for _ in 0..800 {
                let Some(tf) = grab(&lattice, cursor, GAIN) else {
                    break;
                };
                sim.step(&mut state, &mut lattice, &[tf], &mut snap)
                    .unwrap();
            }
            for _ in 0..3000 {
                sim.step(&mut state, &mut lattice, &[], &mut snap).unwrap();
            }
            dents.push(before - lattice.value(probe));
        }
        assert!(dents[0] > 0.1, "plastic dent {}", dents[0]);
        assert!(dents[1].abs() < 0.01, "elastic dent {}", dents[1]);
    }

    #[test]
    fn coefficients_outside_the_region_stay_bit_identical() {
        let mut lattice = sphere();
        let before = lattice.clone();
        let mut state = region(&lattice, Material::PLASTIC);
        let b = state.coeff_box();
        let mut sim = Simulator::new(StepParams::default());
        let mut snap = RegionSnapshot::default();
        let cursor = CENTRE + Vec3::new(0.6, 0.1, 0.0);
        for _ in 0..300 {
            let tf = grab(&lattice, cursor, GAIN).unwrap();
            sim.step(&mut state, &mut lattice, &[tf], &mut snap)
                .unwrap();
        }
        let mut moved = 0;
        for k in 0..20 {
            for j in 0..20 {
                for i in 0..20 {
                    let idx = lattice.index(i, j, k);
                    if b.contains(i, j, k) {
                        moved += usize::from(lattice.coeffs[idx] != before.coeffs[idx]);
                    } else {
                        assert_eq!(lattice.coeffs[idx].to_bits(), before.coeffs[idx].to_bits());
                    }
                }
            }
        }
        assert!(moved > 0);
        // The snapshot carries exactly the region.
        let mut copy = before.clone();
        snap.apply_to(&mut copy).unwrap();
        assert_eq!(copy, lattice);
    }

    #[test]
    fn huge_force_halves_the_step_and_the_state_stays_finite() {
        let mut lattice = sphere();
        let mut state = region(&lattice, Material::ELASTIC);
        // With the coast cap off, so the force really is huge (the cap's own test is below).
        let params = StepParams {
            max_coast_step_spans: f32::INFINITY,
            ..StepParams::default()
        };
        let mut sim = Simulator::new(params);
        let mut snap = RegionSnapshot::default();
        let cursor = CENTRE + Vec3::X * (RADIUS + 0.2);
        let mut refused = 0;
        for _ in 0..50 {
            let tf = grab(&lattice, cursor, 1e30).unwrap_or(ToolForce {
                start: CENTRE,
                end: cursor,
                distribution: Distribution::Gaussian,
                radius: 0.12,
                gain: 1e30,
            });
            match sim.step(&mut state, &mut lattice, &[tf], &mut snap) {
                Ok(_) => {}
                Err(StepError::Diverged { .. } | StepError::NonFinite { .. }) => refused += 1,
                Err(e) => panic!("{e}"),
            }
            for v in state
                .p
                .iter()
                .chain(&state.p_dot)
                .chain(&state.d)
                .chain(&state.d_dot)
            {
                assert!(v.is_finite());
            }
            assert!(lattice.coeffs.iter().all(|v| v.is_finite()));
        }
        assert!(state.dt_s < params.dt_max_s, "step {}", state.dt_s);
        assert!(sim.counters.halvings > 0);
        assert_eq!(sim.counters.failed_steps, refused);
        // A NaN force vector is rejected, not propagated.
        let bad = ToolForce {
            start: Vec3::NAN,
            end: cursor,
            distribution: Distribution::Constant,
            radius: 0.1,
            gain: 1.0,
        };
        let _ = sim.step(&mut state, &mut lattice, &[bad], &mut snap);
        assert!(state.p.iter().all(|v| v.is_finite()));
    }

    #[test]
    fn a_huge_gain_is_capped_to_a_bounded_travel_per_step_and_the_step_keeps_its_size() {
        let mut lattice = sphere();
        let mut state = region(&lattice, CREEP);
        let params = StepParams::default();
        let mut sim = Simulator::new(params);
        let mut snap = RegionSnapshot::default();
        let cursor = CENTRE + Vec3::X * (RADIUS + 0.15);
        let mut last = surface_radius(&lattice, Vec3::X);
        let mut most = 0.0_f32;
        for _ in 0..300 {
            let tf = grab(&lattice, cursor, 1e15).unwrap();
            sim.step(&mut state, &mut lattice, &[tf], &mut snap)
                .unwrap();
            let r = surface_radius(&lattice, Vec3::X);
            most = most.max((r - last).abs());
            last = r;
        }
        assert_eq!(sim.counters.halvings, 0, "the step halved");
        assert_eq!(state.dt_s, params.dt_max_s);
        // The surface moves at most a few times the cap's travel in one step (the cap bounds
        // the coast surface; the clay follows it), and it reaches the cursor, not past it.
        assert!(
            most <= 4.0 * params.max_coast_step_spans * lattice.spacing,
            "moved {most} in one step"
        );
        let reached = last - RADIUS;
        assert!(
            (reached - 0.15).abs() < 0.015,
            "surface at {reached} for 0.15"
        );
    }

    /// The cap is sized for the material's unpainted mass: a region painted ten times heavier
    /// under the same huge gain moves under a tenth as far in its first 20 steps (0.004
    /// against 0.083; a cap that grew with the painted mass let it move 0.023, 0.28 of the
    /// unpainted clay), and still reaches the cursor.
    #[test]
    fn under_a_huge_gain_clay_painted_heavier_lags_as_its_mass_asks() {
        let cursor = CENTRE + Vec3::X * (RADIUS + 0.15);
        let run = |mass_scale: f32, steps: usize| {
            let mut lattice = sphere();
            let mut state = region(&lattice, CREEP);
            for m in &mut state.mass {
                *m *= mass_scale;
            }
            let mut sim = Simulator::new(StepParams::default());
            let mut snap = RegionSnapshot::default();
            for _ in 0..steps {
                let tf = grab(&lattice, cursor, 1e15).unwrap();
                sim.step(&mut state, &mut lattice, &[tf], &mut snap)
                    .unwrap();
            }
            surface_radius(&lattice, Vec3::X) - RADIUS
        };
        let (light, heavy) = (run(1.0, 20), run(10.0, 20));
        println!("20 steps: unpainted {light}, ten times heavier {heavy}");
        assert!(light > 0.01, "the unpainted clay moved {light} in 20 steps");
        assert!(
            heavy < 0.1 * light,
            "painted ten times heavier it moved {heavy} against {light}"
        );
        let reached = run(10.0, 1500);
        assert!(
            (reached - 0.15).abs() < 0.015,
            "the heavy clay's surface at {reached} for 0.15"
        );
    }

    #[test]
    fn a_yield_stops_the_clay_where_the_integral_has_fallen_to_it() {
        let cursor = CENTRE + Vec3::X * (RADIUS + 0.15);
        let run = |yield_integral: f32| {
            let mut lattice = sphere();
            let mut state = region(&lattice, CREEP);
            let mut sim = Simulator::new(StepParams::default());
            sim.set_force_yield(yield_integral);
            let mut snap = RegionSnapshot::default();
            for _ in 0..1500 {
                let tf = grab(&lattice, cursor, GAIN).unwrap();
                sim.step(&mut state, &mut lattice, &[tf], &mut snap)
                    .unwrap();
            }
            lattice
        };
        let free = run(0.0);
        let reached = surface_radius(&free, Vec3::X) - RADIUS;
        assert!((reached - 0.15).abs() < 0.015, "without a yield: {reached}");
        // A yield of a quarter of the starting integral: the pull stops where what is left of
        // its integral has fallen to it, short of the cursor.
        let start = sphere();
        let x0 = surface_point_on_ray(&start, CENTRE, Vec3::X, 0.9, 0.01).unwrap();
        let y = 0.25 * force_integral(&start, x0, cursor).abs();
        let held = run(y);
        let stopped = surface_radius(&held, Vec3::X);
        let left = force_integral(&held, CENTRE + Vec3::X * stopped, cursor).abs();
        assert!(
            stopped - RADIUS > 0.02 && stopped - RADIUS < reached - 0.02,
            "with a yield the surface stopped {} out (free: {reached})",
            stopped - RADIUS
        );
        assert!(
            (left - y).abs() < 0.25 * y,
            "the integral left, {left}, is not the yield, {y}"
        );
        // Negative and non-finite yields mean none.
        let mut sim = Simulator::new(StepParams::default());
        sim.set_force_yield(-1.0);
        assert_eq!(sim.force_yield, 0.0);
        sim.set_force_yield(f32::NAN);
        assert_eq!(sim.force_yield, 0.0);
    }

    #[test]
    fn conjugate_gradient_agrees_with_the_kronecker_inverse_for_uniform_mass() {
        let lattice = sphere();
        let mut state = region(&lattice, Material::ELASTIC);
        for (n, d) in state.d.iter_mut().enumerate() {
            *d += 0.05 * ((n * 7 % 11) as f32 / 11.0 - 0.5);
        }
        let mut kron = Simulator::new(StepParams::default());
        let mut cg = Simulator::new(StepParams {
            solver: AccelSolver::ConjugateGradient,
            cg_tolerance: 1e-6,
            ..StepParams::default()
        });
        for sim in [&mut kron, &mut cg] {
            sim.ensure_scratch(&state);
            sim.gather_forces(&state, &lattice, &[]);
            sim.spring_forces(&state);
            sim.solve_accel(&state).unwrap();
        }
        let scale = kron
            .last_accel()
            .iter()
            .fold(0.0_f32, |m, v| m.max(v.abs()));
        for (a, b) in kron.last_accel().iter().zip(cg.last_accel()) {
            assert!((a - b).abs() < 1e-4 * scale, "{a} vs {b}");
        }
        assert!(
            cg.counters.cg_iterations_last <= 3,
            "{}",
            cg.counters.cg_iterations_last
        );

        // Non-uniform mass: CG converges to AᵀMA x = Aᵀ f.
        for (n, m) in state.mass.iter_mut().enumerate() {
            *m = 1.0 + (n % 5) as f32;
        }
        let mut auto = Simulator::new(StepParams {
            cg_tolerance: 1e-6,
            ..StepParams::default()
        });
        auto.ensure_scratch(&state);
        auto.gather_forces(&state, &lattice, &[]);
        auto.spring_forces(&state);
        let (_, iterations) = auto.solve_accel(&state).unwrap();
        assert!(iterations > 0);
        let x = auto.last_accel().to_vec();
        let mut hx = vec![0.0; x.len()];
        let mut tmp = vec![0.0; state.d.len()];
        let mut ks = KronScratch::for_basis(&state.basis);
        Simulator::apply_h(&state.basis, &state.mass, &x, &mut hx, &mut tmp, &mut ks);
        let mut rhs = vec![0.0; x.len()];
        state.basis.apply_transpose(&auto.force, &mut rhs, &mut ks);
        let norm = dot(&rhs, &rhs).sqrt();
        let res: f64 = hx
            .iter()
            .zip(&rhs)
            .map(|(a, b)| f64::from(a - b).powi(2))
            .sum::<f64>()
            .sqrt();
        assert!(res < 1e-4 * norm, "residual {res} of {norm}");
    }

    /// Gaussian elimination with partial pivoting on a dense `n × n` system (row-major).
    fn dense_solve(mut a: Vec<f64>, mut b: Vec<f64>, n: usize) -> Vec<f64> {
        for c in 0..n {
            let p = (c..n)
                .max_by(|&x, &y| a[x * n + c].abs().total_cmp(&a[y * n + c].abs()))
                .unwrap();
            for k in 0..n {
                a.swap(c * n + k, p * n + k);
            }
            b.swap(c, p);
            for r in c + 1..n {
                let f = a[r * n + c] / a[c * n + c];
                for k in c..n {
                    a[r * n + k] -= f * a[c * n + k];
                }
                b[r] -= f * b[c];
            }
        }
        let mut x = vec![0.0; n];
        for r in (0..n).rev() {
            let s: f64 = (r + 1..n).map(|k| a[r * n + k] * x[k]).sum();
            x[r] = (b[r] - s) / a[r * n + r];
        }
        x
    }

    /// A force on a patch granted the base's pace travels as far a step as what is left of
    /// its vector, between the patch's own travel and `ratio` times it; without the grant, or
    /// on a two-level region (whose travel is the base's already), the patch's own.
    #[test]
    fn a_planned_force_travels_at_most_what_is_left_and_the_bases_pace() {
        let lattice = sphere();
        let b = CoeffBox {
            min: [10, 6, 6],
            max: [13, 9, 9],
        };
        let mut state = RegionState::new(&lattice, b, [7, 7, 7], Material::PLASTIC).unwrap();
        let patch_travel = 0.01;
        assert_eq!(
            far_travel_factor(&state, 1.0, patch_travel),
            1.0,
            "no grant"
        );
        state.set_planned_travel_ratio(4);
        assert_eq!(
            far_travel_factor(&state, 1.0, patch_travel),
            4.0,
            "far: the base's"
        );
        assert_eq!(
            far_travel_factor(&state, 0.025, patch_travel),
            2.5,
            "what is left"
        );
        assert_eq!(
            far_travel_factor(&state, 0.002, patch_travel),
            1.0,
            "near: the patch's"
        );
        assert_eq!(far_travel_factor(&state, f32::NAN, patch_travel), 1.0);
        assert_eq!(far_travel_factor(&state, 1.0, 0.0), 1.0);
        state.set_coarse_springs(4, 4);
        assert_eq!(
            far_travel_factor(&state, 1.0, patch_travel),
            1.0,
            "two-level"
        );
    }

    /// A painted mass (a heavy half ten times the light one) makes `AᵀMA` non-Kronecker: the
    /// conjugate gradients preconditioned by the mean-mass Kronecker inverse converge, within
    /// the default tolerance and iteration cap, to the direct dense solve.
    #[test]
    fn conjugate_gradient_converges_to_the_direct_solve_for_a_painted_mass() {
        let lattice = sphere();
        let b = CoeffBox {
            min: [10, 6, 6],
            max: [13, 9, 9],
        };
        let mut state = RegionState::new(&lattice, b, [7, 7, 7], Material::ELASTIC).unwrap();
        for k in 0..7 {
            for j in 0..7 {
                for i in 0..7 {
                    let n = state.point_index(i, j, k);
                    state.mass[n] = if i < 3 { 10.0 } else { 1.0 };
                }
            }
        }
        for (n, d) in state.d.iter_mut().enumerate() {
            *d += 0.05 * ((n * 7 % 11) as f32 / 11.0 - 0.5);
        }
        let params = StepParams::default();
        let mut sim = Simulator::new(params);
        sim.ensure_scratch(&state);
        let force = grab(&lattice, CENTRE + Vec3::new(0.3, -0.1, -0.1), GAIN);
        sim.gather_forces(&state, &lattice, force.as_slice());
        sim.spring_forces(&state);
        let (_, iterations) = sim.solve_accel(&state).unwrap();
        assert!(
            iterations > 0 && iterations < params.cg_max_iterations,
            "{iterations} iterations"
        );
        let cg = sim.last_accel().to_vec();

        // The dense system, column by column from the same operators, solved in f64.
        let n = state.p.len();
        let mut ks = KronScratch::for_basis(&state.basis);
        let mut tmp = vec![0.0; state.d.len()];
        let (mut unit, mut col) = (vec![0.0_f32; n], vec![0.0_f32; n]);
        let mut h = vec![0.0_f64; n * n];
        for c in 0..n {
            unit.fill(0.0);
            unit[c] = 1.0;
            Simulator::apply_h(
                &state.basis,
                &state.mass,
                &unit,
                &mut col,
                &mut tmp,
                &mut ks,
            );
            for r in 0..n {
                h[r * n + c] = f64::from(col[r]);
            }
        }
        let mut rhs = vec![0.0_f32; n];
        state.basis.apply_transpose(&sim.force, &mut rhs, &mut ks);
        let direct = dense_solve(h, rhs.iter().map(|&v| f64::from(v)).collect(), n);
        let scale = direct.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
        let worst = cg
            .iter()
            .zip(&direct)
            .fold(0.0_f64, |m, (&a, &b)| m.max((f64::from(a) - b).abs()));
        assert!(scale > 0.0);
        assert!(
            worst < 1e-3 * scale,
            "CG off the direct solve by {worst} of {scale} after {iterations} iterations"
        );
    }

    #[test]
    fn small_regions_step_on_one_thread_and_large_ones_on_the_faster_count() {
        let mut c = ThreadChoice::default();
        assert!(c.solo(1000, true, false), "a small region runs alone");
        assert!(!c.solo(1000, true, true), "unless splitting is forced");
        assert!(c.solo(1_000_000, false, false), "no helper, one thread");
        // A large region: a block on each count while probing, then keep the faster.
        for fast_two in [true, false] {
            let mut c = ThreadChoice::default();
            let mut seen = [0, 0];
            for _ in 0..PROBE_STEPS {
                let solo = c.solo(100_000, true, false);
                seen[usize::from(!solo)] += 1;
                c.record(if solo == fast_two { 2_000 } else { 1_000 });
            }
            assert_eq!(seen, [PROBE_STEPS / 2; 2]);
            for _ in 0..10 {
                assert_eq!(c.solo(100_000, true, false), !fast_two);
                c.record(5_000);
            }
        }
        // About even (two threads 3% faster): one thread.
        let mut c = ThreadChoice::default();
        for _ in 0..PROBE_STEPS {
            let solo = c.solo(100_000, true, false);
            c.record(if solo { 1_000 } else { 970 });
        }
        assert!(
            c.solo(100_000, true, false),
            "two threads must be clearly faster"
        );
        // The first steps of each block (cold from the other count) are not counted.
        let mut c = ThreadChoice::default();
        for i in 0..PROBE_STEPS {
            let solo = c.solo(100_000, true, false);
            let warm = i % (PROBE_STEPS / 2) >= PROBE_WARMUP;
            c.record(match (solo, warm) {
                (true, false) => 5_000,
                (true, true) => 1_000,
                (false, false) => 500,
                (false, true) => 2_000,
            });
        }
        assert!(
            c.solo(100_000, true, false),
            "a cold first step must not decide"
        );
        // The choice is timed again after REPROBE_EVERY steps.
        let mut c = ThreadChoice::default();
        let mut counts = [0, 0];
        for _ in 0..(PROBE_STEPS + REPROBE_EVERY + PROBE_STEPS) {
            let solo = c.solo(100_000, true, false);
            counts[usize::from(!solo)] += 1;
            c.record(if solo { 2_000 } else { 1_000 });
        }
        assert_eq!(counts[0], PROBE_STEPS, "one thread only while probing");
    }

    #[test]
    fn springs_fused_into_the_projection_give_bit_identical_accelerations() {
        let lattice = sphere();
        for (mass_dims, uniform_k) in [([15, 15, 15], true), ([15, 11, 9], false)] {
            let b = CoeffBox {
                min: [10, 6, 6],
                max: [17, 13, 13],
            };
            let mut state = RegionState::new(&lattice, b, mass_dims, Material::PLASTIC).unwrap();
            for (n, d) in state.d.iter_mut().enumerate() {
                *d += 0.05 * ((n * 7 % 11) as f32 / 11.0 - 0.5);
            }
            for (n, v) in state.d_dot.iter_mut().enumerate() {
                *v = 0.01 * ((n * 5 % 7) as f32 - 3.0);
            }
            if !uniform_k {
                for (n, k) in state.stiffness.iter_mut().enumerate() {
                    *k *= 1.0 + 0.1 * (n % 3) as f32;
                }
            }
            let force = grab(&lattice, CENTRE + Vec3::new(0.6, 0.1, 0.0), GAIN).unwrap();
            let mut accels = Vec::new();
            for threads in [1, 2] {
                let mut sim = Simulator::new(StepParams {
                    threads,
                    ..StepParams::default()
                });
                sim.always_split = true;
                sim.ensure_scratch(&state);
                sim.gather_forces(&state, &lattice, &[force]);
                sim.spring_forces(&state);
                let apart = sim.solve_accel(&state).unwrap();
                let want = sim.last_accel().to_vec();
                sim.accel.fill(f32::NAN);
                let fused = sim.springs_and_solve(&state).unwrap();
                assert_eq!(apart.0.to_bits(), fused.0.to_bits());
                let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(&want), bits(sim.last_accel()), "{mass_dims:?}");
                accels.push(bits(&want));
            }
            assert_eq!(accels[0], accels[1]);
        }
    }

    #[test]
    fn two_threads_give_bit_identical_steps() {
        // `painted`: mass, damping and stiffness vary over the region (a painted material).
        for (mass_dims, integrator, neighbourhood, painted) in [
            (
                [15, 15, 15],
                Integrator::SemiImplicit,
                Neighbourhood::Six,
                false,
            ),
            (
                [8, 8, 8],
                Integrator::SemiImplicit,
                Neighbourhood::Six,
                false,
            ),
            (
                [11, 9, 13],
                Integrator::Explicit,
                Neighbourhood::Eighteen,
                false,
            ),
            (
                [11, 9, 13],
                Integrator::SemiImplicit,
                Neighbourhood::TwentySix,
                false,
            ),
            (
                [15, 15, 15],
                Integrator::SemiImplicit,
                Neighbourhood::Six,
                true,
            ),
            (
                [11, 9, 13],
                Integrator::SemiImplicit,
                Neighbourhood::TwentySix,
                true,
            ),
        ] {
            let mut runs = Vec::new();
            for threads in [1, 2] {
                let mut lattice = sphere();
                let b = CoeffBox {
                    min: [10, 6, 6],
                    max: [17, 13, 13],
                };
                let material = Material {
                    neighbourhood,
                    ..Material::PLASTIC
                };
                let mut state = RegionState::new(&lattice, b, mass_dims, material).unwrap();
                if painted {
                    for n in 0..state.mass.len() {
                        let f = 1.0 + (n % 7) as f32 / 7.0;
                        state.mass[n] *= f;
                        state.damping[n] *= 2.0 - f;
                        state.stiffness[n] *= f * f;
                    }
                }
                let mut sim = Simulator::new(StepParams {
                    threads,
                    integrator,
                    resync_every: 7,
                    ..StepParams::default()
                });
                // These regions are below the size where a step chooses two threads.
                sim.always_split = true;
                let mut snap = RegionSnapshot::default();
                let cursor = CENTRE + Vec3::new(0.6, 0.1, 0.0);
                for _ in 0..40 {
                    let tf = grab(&lattice, cursor, GAIN).unwrap();
                    sim.step(&mut state, &mut lattice, &[tf], &mut snap)
                        .unwrap();
                }
                let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                runs.push((
                    bits(&state.p),
                    bits(&state.p_dot),
                    bits(&state.d),
                    bits(&state.d_dot),
                    bits(&state.rest),
                    bits(&lattice.coeffs.to_vec()),
                ));
            }
            assert!(
                runs[0] == runs[1],
                "{mass_dims:?}: one and two threads differ"
            );
        }
    }

    #[test]
    fn non_finite_state_is_refused_without_writing() {
        let mut lattice = sphere();
        let mut state = region(&lattice, Material::ELASTIC);
        state.p_dot[3] = f32::NAN;
        let before = lattice.clone();
        let mut sim = Simulator::new(StepParams::default());
        let mut snap = RegionSnapshot::default();
        assert!(sim.step(&mut state, &mut lattice, &[], &mut snap).is_err());
        assert_eq!(lattice, before);
        assert_eq!(snap.version, 0);
    }

    /// Two threads writing disjoint ranges of one step's buffers (the passes' `SharedOut`)
    /// under Miri (`cargo +nightly miri test -p dynaclay-core --lib miri_`): a tiny region,
    /// two mass points per knot span, two steps, bit-identical to one thread.
    #[test]
    fn miri_two_threads_step_a_tiny_region_as_one() {
        // A ball written straight into the coefficients (a fit would cost Miri minutes).
        let centre = Vec3::splat(0.45);
        let mut start = BSplineLattice::zeros([10, 10, 10], 0.1, Vec3::ZERO).unwrap();
        for k in 0..10 {
            for j in 0..10 {
                for i in 0..10 {
                    let d = 0.3 - (start.node_position(i, j, k) - centre).length();
                    let at = start.index(i, j, k);
                    start.coeffs.set_flat(at, (0.5 + d / 0.6).clamp(0.0, 1.0));
                }
            }
        }
        let b = CoeffBox {
            min: [6, 3, 3],
            max: [8, 5, 5],
        };
        let mut runs = Vec::new();
        for threads in [1, 2] {
            let mut lattice = start.clone();
            let mut state = RegionState::new(&lattice, b, [5, 5, 5], Material::PLASTIC).unwrap();
            let mut sim = Simulator::new(StepParams {
                threads,
                ..StepParams::default()
            });
            sim.always_split = true;
            let mut snap = RegionSnapshot::default();
            let tool = ToolForce {
                start: centre + Vec3::X * 0.3,
                end: centre + Vec3::new(0.45, 0.02, 0.0),
                distribution: Distribution::Constant,
                radius: 0.12,
                gain: GAIN,
            };
            for _ in 0..2 {
                sim.step(&mut state, &mut lattice, &[tool], &mut snap)
                    .unwrap();
            }
            let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            runs.push((
                bits(&state.p),
                bits(&state.d),
                bits(&lattice.coeffs.to_vec()),
            ));
        }
        assert!(runs[0] == runs[1], "one and two threads differ");
        assert!(runs[0].2 != bits_of(&start), "the pull moved nothing");
    }

    fn bits_of(lattice: &BSplineLattice) -> Vec<u32> {
        lattice.coeffs.iter().map(|x| x.to_bits()).collect()
    }

    /// Pulls the elastic sphere's +x pole out for `pull_steps` steps in region `first`, then
    /// sets up `second` (a box shifted by one coefficient along y, sharing most of the dent)
    /// with or without `first`'s elastic memory carried over, lets go and steps `rest_steps`
    /// more; returns the pole's radius when let go and at the end.
    fn pull_then_move_region(carry: bool, material: Material) -> (f32, f32, usize) {
        let mut lattice = sphere();
        let first = region(&lattice, material);
        let mut state = first;
        let mut sim = Simulator::new(StepParams::default());
        let mut snap = RegionSnapshot::default();
        let cursor = CENTRE + Vec3::X * (RADIUS + 0.15);
        for _ in 0..600 {
            let Some(tf) = grab(&lattice, cursor, GAIN) else {
                break;
            };
            sim.step(&mut state, &mut lattice, &[tf], &mut snap)
                .unwrap();
        }
        let pulled = surface_radius(&lattice, Vec3::X);
        let shifted = CoeffBox {
            min: [10, 7, 6],
            max: [17, 14, 13],
        };
        let mut moved = RegionState::new(&lattice, shifted, [15, 15, 15], material).unwrap();
        let carried = if carry {
            moved.carry_rest_from(&state)
        } else {
            0
        };
        let mut sim = Simulator::new(StepParams::default());
        for _ in 0..1500 {
            sim.step(&mut moved, &mut lattice, &[], &mut snap).unwrap();
        }
        (pulled, surface_radius(&lattice, Vec3::X), carried)
    }

    #[test]
    fn an_elastic_dent_springs_back_after_its_region_moves_on() {
        let (pulled, end, carried) = pull_then_move_region(true, Material::ELASTIC);
        // The two boxes share 8 x 7 x 8 coefficients: 15 x 13 x 15 mass points.
        assert_eq!(carried, 15 * 13 * 15);
        assert!(pulled > RADIUS + 0.05, "pulled to {pulled}");
        assert!(
            (end - RADIUS).abs() < 0.2 * (pulled - RADIUS),
            "sprang back to {end} from {pulled} (rest {RADIUS})"
        );
        // Without the memory the moved region takes the pulled pole as its rest shape.
        let (pulled, kept, _) = pull_then_move_region(false, Material::ELASTIC);
        eprintln!("pulled {pulled:.4}: {end:.4} carried, {kept:.4} not (rest {RADIUS})");
        assert!(
            kept - RADIUS > 0.5 * (pulled - RADIUS),
            "kept {kept} of {pulled} without the memory"
        );
        // A plastic point's rest follows the clay: nothing is carried.
        let (_, _, carried) = pull_then_move_region(true, Material::PLASTIC);
        assert_eq!(carried, 0);
    }
}
