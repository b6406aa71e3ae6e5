//! The guard against a step that removes most of the clay: what the simulation does when one
//! stroke, tool step or CSG would remove more than [`MOST_REMOVED_UNASKED`] of the clay's
//! volume (estimated before it is applied, see [`dynaclay_core::tools::tool_volume_change`]).
//!
//! Plain `Copy` values: the question travels in the simulation's published status, a stroke's
//! report on a channel a script driver hands the simulation.

pub use dynaclay_core::tools::MOST_REMOVED_UNASKED;

/// What the simulation does with a step over the limit.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum RemovalGuard {
    /// Apply it, and report it (a script prints a warning naming the step and its line).
    #[default]
    Warn,
    /// Hold it until the user answers (the window): a stroke's applications are withheld
    /// from the one that would pass the limit on, a tool or CSG step waits unapplied (and
    /// unanswered); the question is published in [`super::SimStatus::removal_question`] and
    /// [`super::Command::AnswerRemoval`] answers it.
    Ask,
}

/// A step held until the user says whether it may remove that much.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RemovalQuestion {
    /// The tool or operation (`"remove"`, `"intersection"`, …).
    pub what: &'static str,
    /// The share of the clay's volume it would remove, percent.
    pub percent: f32,
    /// Whether it is a stroke (its applications withheld; a yes lets it go on) rather than a
    /// tool or CSG step (waiting unapplied; a yes applies it).
    pub stroke: bool,
}

/// A stroke that removed more than the limit, reported in [`RemovalGuard::Warn`] mode when it
/// ends.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StrokeRemoval {
    /// The stroke's tool.
    pub what: &'static str,
    /// The share of the clay's volume it removed, percent.
    pub percent: f32,
    /// Device time of the stroke's first sample, microseconds (a script finds its step by it).
    pub started_us: u64,
}
