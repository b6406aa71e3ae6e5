//! Per-stage timings and counters of the simulation step, so a profile reads like eq. (5)–(8).

/// Nanoseconds spent in each stage of the last step.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StageTimes {
    /// External forces from the tool's force vectors.
    pub gather_forces_ns: u64,
    /// Density springs and damping.
    pub spring_forces_ns: u64,
    /// `p̈ = (AᵀMA)⁻¹ Aᵀ f`.
    pub solve_accel_ns: u64,
    /// Geometric constraints on `p̈` (§7.3; zero without constraints).
    pub constrain_ns: u64,
    /// Adaptive forward Euler, densities, plasticity.
    pub integrate_ns: u64,
    /// Coefficients into the lattice and the region snapshot.
    pub publish_ns: u64,
}

impl StageTimes {
    /// Sum over the stages.
    #[must_use]
    pub fn total_ns(&self) -> u64 {
        self.gather_forces_ns
            + self.spring_forces_ns
            + self.solve_accel_ns
            + self.constrain_ns
            + self.integrate_ns
            + self.publish_ns
    }
}

/// Running counters of a simulator.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StepCounters {
    /// Successful steps.
    pub steps: u64,
    /// Steps refused (non-finite or diverging state).
    pub failed_steps: u64,
    /// Times the step was halved.
    pub halvings: u64,
    /// Times the step grew back.
    pub growths: u64,
    /// Tool forces ignored because they were not finite or had a bad radius.
    pub rejected_forces: u64,
    /// Conjugate-gradient iterations in the last step (0 on the Kronecker path).
    pub cg_iterations_last: u32,
    /// Largest `|p̈|` of the last step.
    pub max_accel_last: f32,
    /// Stage timings of the last step.
    pub last: StageTimes,
}
