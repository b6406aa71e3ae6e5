//! Density-spring dynamics of the implicit solid (Hua & Qin §4, §6, §7.2–§7.3): material,
//! force mapping, the simulated region, geometric constraints and the stepping pipeline.

mod coarse;
mod coast;
mod constraint_model;
mod constraint_solver;
#[cfg(test)]
mod constraint_tests;
mod counters;
mod force;
mod material;
mod material_grid;
mod passes;
mod region;
mod simulator;
mod springs;
mod team;

pub use coast::{
    COAST_REACH_SPANS, CoastField, MAX_COAST_S, RegionVelocity, coast_time_s, start_on_coast,
};
pub use constraint_model::{
    CURVE_SAMPLES_PER_SPAN, Constraint, ConstraintError, ConstraintRow, MAX_CONSTRAINTS,
    MAX_CURVE_POINTS, MAX_CURVE_SAMPLES, project_onto_surface,
};
pub use constraint_solver::{
    ConstraintPath, ConstraintReport, ConstraintSolver, RANK_TOLERANCE, REDUCED_MAX_SUPPORT,
};
pub use counters::{StageTimes, StepCounters};
pub use force::{
    Distribution, GAUSS_NODES, GAUSS_WEIGHTS, REFIND_BISECT_STEPS, REFIND_MARCH_STEPS, ToolBody,
    ToolForce, force_integral, gauss_legendre_unit, reaction_force, start_on_surface,
    start_on_surface_near_target, surface_point_on_ray,
};
pub use material::{AccelSolver, Integrator, Material, MaterialError, Neighbourhood, StepParams};
pub use material_grid::{
    MAX_GRID_SAMPLES, MaterialGrid, MaterialGridError, MaterialPaint, MaterialParam, PaintRegion,
    apply_grids, grid_dims_over, paint_grids,
};
pub use region::{RegionError, RegionState};
pub use simulator::{Simulator, StepError, StepReport};
