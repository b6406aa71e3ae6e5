//! Constrained particles on the clay's surface (Witkin & Heckbert, as Zhang et al. §4–§5.5 use
//! them), and the particle division structure (PDS) that finds their neighbours.
//!
//! Particles are held on the zero set of `value − iso` by the constraint velocity, repel one
//! another with a Gaussian energy of adaptive radius `σᵢ`, split where the surface around them
//! is sparse and die where it is crowded; the count follows the user's `N` through the feedback
//! `S` of §5.5. Work per step is bounded: the neighbour search is the PDS, and births per step
//! are at most half the population. Nothing here runs on the haptic thread.

mod follow;
mod pds;
mod surface;
mod system;

pub use follow::{ParticleFollower, ParticleView};
pub use pds::{MAX_LEVEL, Pds};
pub use surface::ImplicitSurface;
pub use system::{
    NeighbourSearch, ParticleError, ParticleParams, ParticleSystem, SWAP_RATIO, StepReport,
    nearest_neighbour_distances,
};
