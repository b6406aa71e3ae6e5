//! Density-spring dynamics of the implicit solid (Hua & Qin §4, §6, §7.2–§7.3): material,
//! force mapping, the simulated region and the stepping pipeline.

mod counters;
mod force;
mod material;
mod passes;
mod region;
mod simulator;
mod springs;
mod team;

pub use counters::{StageTimes, StepCounters};
pub use force::{
    Distribution, GAUSS_NODES, GAUSS_WEIGHTS, REFIND_BISECT_STEPS, REFIND_MARCH_STEPS, ToolForce,
    force_integral, gauss_legendre_unit, reaction_force, start_on_surface, surface_point_on_ray,
};
pub use material::{AccelSolver, Integrator, Material, Neighbourhood, StepParams};
pub use region::{RegionError, RegionState};
pub use simulator::{Simulator, StepError, StepReport};
