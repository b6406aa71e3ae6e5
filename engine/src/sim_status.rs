//! What the simulation publishes about itself for observers (the GUI, tests): undo and redo
//! depth, the material in effect, the simulated region, how many sessions were loaded, and
//! a step waiting for the user's yes.
//!
//! Guarantee: plain `Copy` data published once per simulation step through a triple buffer
//! (wait-free, no allocation after set-up); observers read the newest copy without ever
//! holding up the simulation.

use glam::Vec3;

use dynaclay_core::dynamics::Material;
use dynaclay_core::field::{DenseBudgetError, MAX_CLAY_BOX_COEFFS};

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
    /// The newest edit (a stroke, a tool command, a simulated region) that one of the clay's
    /// budgets refused or clipped: what and where.
    pub budget_refusal: Option<BudgetRefusal>,
}

/// An edit the clay's budgets stopped, as observers are told of it (plain `Copy` data, so
/// that the status stays allocation-free to publish).
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum BudgetRefusal {
    /// The edit could have made more bricks dense than the clay may hold; the clay was left
    /// as it was.
    #[error("{0}")]
    DenseBricks(#[from] DenseBudgetError),
    /// The edit reached past the clay's box, and growing the base to take it would have made
    /// the clay span more than [`MAX_CLAY_BOX_COEFFS`] coefficients of box: the edit was
    /// clipped to the box (growth is symmetric about the lattice's centre, so the box's sides
    /// grow in pairs).
    #[error(
        "the clay could not grow to take the edit: a base of {dims:?} coefficients would make {total} coefficients of box in all, more than {MAX_CLAY_BOX_COEFFS}; the edit was clipped to the clay's box"
    )]
    ClayBox {
        /// The grown base's dimensions the edit needed (saturated when they overflow).
        dims: [usize; 3],
        /// Coefficients of box the grown clay would span, every lattice together.
        total: usize,
    },
}
