//! What the simulation publishes about itself for observers (the GUI, tests): undo and redo
//! depth, the material in effect, the simulated region, how many sessions were loaded, and
//! a step waiting for the user's yes.
//!
//! Guarantee: plain `Copy` data published once per simulation step through a triple buffer
//! (wait-free, no allocation after set-up); observers read the newest copy without ever
//! holding up the simulation.

use glam::Vec3;

use dynaclay_core::dynamics::Material;
use dynaclay_core::field::DenseBudgetError;

/// The simulation's state as observers see it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SimStatus {
    /// Steps that undo can take.
    pub undo_steps: usize,
    /// Steps that redo can take.
    pub redo_steps: usize,
    /// The material of new regions.
    pub material: Material,
    /// The simulated region's coefficient nodes as a world box (min, max corners), if a
    /// region is active.
    pub region: Option<(Vec3, Vec3)>,
    /// Sessions loaded into the running engine so far.
    pub sessions_loaded: u64,
    /// Simulation steps taken.
    pub sim_step: u64,
    /// Simulated time, seconds.
    pub sim_time_s: f64,
    /// Bumped whenever the clay's pins may have changed (pin, unpin, undo, redo, load): an
    /// observer showing the pins asks for the list again ([`super::Command::ListPins`]).
    pub pins_revision: u64,
    /// The compact RBF clay: on or off, its centre count, the last re-interpolation's time.
    pub compact: super::CompactStatus,
    /// A step held until the user says it may remove more than half the clay
    /// ([`super::RemovalGuard::Ask`]).
    pub removal_question: Option<super::RemovalQuestion>,
    /// Dense bricks the clay holds, of [`dynaclay_core::field::MAX_DENSE_BRICKS`].
    pub dense_bricks: usize,
    /// The newest edit (a stroke, a tool command, a simulated region) refused because it
    /// could pass the clay's dense-brick budget: what and where. The clay was left as it was.
    pub budget_refusal: Option<DenseBudgetError>,
}
