//! The simulated arm: a deterministic, closed-loop stand-in for a force-feedback arm, and the
//! reference driver a new [`crate::HapticDevice`] implementation is written from.
//!
//! A point-mass end effector is held by a simulated hand (a spring–damper) that follows a
//! scripted [`Trajectory`]; the force the engine writes pushes the effector back, so a haptic
//! loop over it runs closed-loop. It advances a fixed step of simulated time per `read`, never
//! wall time, so a run is reproducible for a given seed; faults are injected on a schedule.

mod arm;
mod fault;
mod rng;
mod trajectory;

pub use arm::{SimArmConfig, SimArmCounters, SimulatedArm};
pub use fault::{Fault, FaultKind};
pub use rng::SimRng;
pub use trajectory::{HandSample, Interpolation, Trajectory, TrajectoryError, Waypoint};
