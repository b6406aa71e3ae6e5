//! The removal guard on the stage (see [`RemovalGuard`]): each geometric stroke's removal is
//! estimated application by application against the clay's volume when it began, and each
//! tool or CSG step's before it is applied; a step over [`MOST_REMOVED_UNASKED`] is held
//! until the user answers (`Ask`) or applied and reported (`Warn`). The estimates are bounded
//! by the tool's reach (a stroke's applications) or the patch (a CSG, a stroke's start).

use crossbeam::channel::Sender;

use super::super::command::{Command, ToolChoice};
use super::super::error::CommandError;
use crate::{MOST_REMOVED_UNASKED, RemovalGuard, RemovalQuestion, StrokeRemoval};
use dynaclay_core::tools::{
    Clay, GeometricTool, ToolPose, VolumeChange, clay_volume_fu3, removed_fraction,
    tool_volume_change,
};

/// The guard's state on the stage.
#[derive(Debug, Default)]
pub(super) struct RemovalState {
    /// The clay's volume when the held stroke began (`None`: no stroke, or one whose tool
    /// removes nothing).
    stroke_volume_fu3: Option<f32>,
    /// What the held stroke's applications removed so far (estimated).
    stroke_removed_fu3: f32,
    stroke_started_us: u64,
    stroke_what: &'static str,
    /// The held stroke's applications are withheld until the user answers.
    withheld: bool,
    /// The user said yes: the next step over the limit goes ahead (a held stroke resumes).
    allowed: bool,
    /// The held stroke saw the yes (it is spent when the stroke ends).
    allowance_seen: bool,
    /// The question published to observers.
    pub(super) question: Option<RemovalQuestion>,
    /// The tool or CSG step held for the answer, with the refusal it gets on a no.
    held_step: Option<(Command, CommandError)>,
    /// Where strokes over the limit are reported in `Warn` mode.
    reports: Option<Sender<StrokeRemoval>>,
}

impl RemovalState {
    /// A stroke began holding `choice` at device time `now_us`: notes the clay's volume if the
    /// tool can remove clay.
    pub(super) fn stroke_started(&mut self, choice: &ToolChoice, clay: &Clay, now_us: u64) {
        self.stroke_volume_fu3 = None;
        self.stroke_removed_fu3 = 0.0;
        self.withheld = false;
        self.allowance_seen = self.allowed;
        let ToolChoice::Geometric(tool) = choice else {
            return;
        };
        if tool.action.paints() {
            return;
        }
        self.stroke_what = tool.action.name();
        self.stroke_started_us = now_us;
        self.stroke_volume_fu3 = Some(clay_volume_fu3(clay));
    }

    /// The held stroke ended: reports it when it removed more than the limit (`Warn`), and
    /// spends the user's yes it saw.
    pub(super) fn stroke_ended(&mut self, guard: RemovalGuard) {
        let Some(volume) = self.stroke_volume_fu3.take() else {
            return;
        };
        let share = removed_fraction(self.stroke_removed_fu3, volume);
        if guard == RemovalGuard::Warn
            && share > MOST_REMOVED_UNASKED
            && let Some(to) = &self.reports
        {
            let _ = to.try_send(StrokeRemoval {
                what: self.stroke_what,
                percent: 100.0 * share,
                started_us: self.stroke_started_us,
            });
        }
        if self.allowance_seen {
            self.allowed = false;
        }
        self.allowance_seen = false;
        self.withheld = false;
    }

    /// Whether the held stroke may apply `tool` at `pose` for `dwell_s` on `clay`: counts the
    /// estimated removal, and in `Ask` mode withholds the application (and every later one of
    /// the stroke, until the user answers yes) that would take the stroke past the limit.
    pub(super) fn admits(
        &mut self,
        guard: RemovalGuard,
        clay: &Clay,
        tool: &GeometricTool,
        pose: &ToolPose,
        dwell_s: f32,
    ) -> bool {
        let Some(volume) = self.stroke_volume_fu3 else {
            return true;
        };
        let ask = guard == RemovalGuard::Ask;
        if ask && self.withheld && !self.allowed {
            return false;
        }
        let change = tool_volume_change(clay, tool, std::slice::from_ref(pose), dwell_s, 0);
        let total = self.stroke_removed_fu3 + change.net_removed_fu3();
        let share = removed_fraction(total, volume);
        if ask && share > MOST_REMOVED_UNASKED && !self.allowed {
            self.withheld = true;
            self.question = Some(RemovalQuestion {
                what: self.stroke_what,
                percent: 100.0 * share,
                stroke: true,
            });
            return false;
        }
        self.stroke_removed_fu3 = total;
        true
    }

    /// Whether a tool or CSG step (`what`) of estimated `change` may be applied to `clay`:
    /// its removed share of the clay when it may. In `Ask` mode a step over the limit without
    /// the user's yes may not (the caller holds it, see [`RemovalState::hold`]) and the
    /// question is published; a yes is spent by the step it lets through.
    ///
    /// # Errors
    /// [`CommandError::WouldRemoveMost`] for a step to hold for the user's answer.
    pub(super) fn admits_step(
        &mut self,
        guard: RemovalGuard,
        clay: &Clay,
        what: &'static str,
        change: VolumeChange,
    ) -> Result<f32, CommandError> {
        let share = removed_fraction(change.net_removed_fu3(), clay_volume_fu3(clay));
        if guard == RemovalGuard::Ask && share > MOST_REMOVED_UNASKED {
            if !self.allowed {
                self.question = Some(RemovalQuestion {
                    what,
                    percent: 100.0 * share,
                    stroke: false,
                });
                return Err(CommandError::WouldRemoveMost {
                    what: what.to_owned(),
                    percent: 100.0 * share,
                });
            }
            self.allowed = false;
        }
        Ok(share)
    }

    /// Holds `step` (refused with `refused`) for the user's answer; a step held before it is
    /// answered with its refusal (the newer step's question replaces its own).
    pub(super) fn hold(&mut self, step: Command, refused: CommandError) {
        if let Some((older, why)) = self.held_step.replace((step, refused)) {
            refuse(older, why);
        }
    }

    /// The user's answer to the published question (see [`Command::AnswerRemoval`]): the
    /// held tool or CSG step to apply now on a yes (the yes lets it through); on a no, the
    /// held step is answered with its refusal and dropped.
    pub(super) fn answer(&mut self, yes: bool) -> Option<Command> {
        self.question = None;
        self.allowed = yes;
        if yes && self.stroke_volume_fu3.is_some() {
            self.allowance_seen = true;
        }
        let (step, refused) = self.held_step.take()?;
        if yes {
            Some(step)
        } else {
            refuse(step, refused);
            None
        }
    }

    /// Reports strokes over the limit on `to` from now on (`Warn` mode).
    pub(super) fn report_to(&mut self, to: Sender<StrokeRemoval>) {
        self.reports = Some(to);
    }
}

/// Answers a held tool or CSG step with `refused`: it applied nothing.
pub(super) fn refuse(step: Command, refused: CommandError) {
    if let Command::ApplyTool { reply: Some(r), .. } | Command::Csg { reply: Some(r), .. } = step {
        let _ = r.send(Err(refused));
    }
}
