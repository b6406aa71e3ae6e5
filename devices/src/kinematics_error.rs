//! Why a kinematic solve failed: the one error type of the arm kinematics, shared by the
//! linkage solvers ([`crate::delta`]) and the arm model built on them ([`crate::kinematics`]).

/// Why a kinematic solve failed.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum KinematicsError {
    /// No joint angles reach this position.
    #[error(
        "position ({:.4}, {:.4}, {:.4}) m is outside the arm's reach",
        position_m[0],
        position_m[1],
        position_m[2]
    )]
    Unreachable {
        /// The position asked for, m.
        position_m: [f64; 3],
    },
    /// The forward solve did not converge within its iteration budget.
    #[error(
        "forward kinematics did not converge in {iterations} iterations (residual {residual_rad:.2e} rad)"
    )]
    NoConvergence {
        /// Iterations spent.
        iterations: u32,
        /// Largest joint-angle residual left, rad.
        residual_rad: f64,
    },
    /// The profile has no joint kinematics (a Cartesian device).
    #[error("profile has no joint kinematics (Cartesian device)")]
    NotAnArm,
}
