//! The window's sculpt edits that need something read or built before the engine applies them
//! — a tool made from the sculpt for the library, CSG with a session file or a solid, an
//! embossed image — turned into the engine's commands on the bridge thread (files are read
//! here, never on a loop), and their answers forwarded to the app's log.

use crossbeam::channel::{Receiver, TryRecvError, bounded};

use super::command::{CsgOperand, EngineCommand, EngineEvent};
use crate::engine::{Command, CommandError, EditOutcome};
use crate::io::load_session;
use crate::tools::{GeometricTool, solid_clay};

/// Where an edit's answer will come: a tool for the library or an emboss answers a line, a
/// CSG the step's outcome.
#[derive(Debug)]
pub enum PendingReply {
    /// [`Command::AddTool`]'s or [`Command::Emboss`]'s answer.
    Line(Receiver<Result<String, CommandError>>),
    /// [`Command::Csg`]'s answer.
    Edit(Receiver<Result<EditOutcome, CommandError>>),
}

impl PendingReply {
    /// The answer if it came: `Some(Ok(line))`, `Some(Err(why))`, or `None` while waiting;
    /// a hung-up channel is an error.
    pub fn try_answer(&self) -> Option<Result<String, String>> {
        fn take<T>(
            rx: &Receiver<Result<T, CommandError>>,
            line: impl Fn(T) -> String,
        ) -> Option<Result<String, String>> {
            match rx.try_recv() {
                Ok(Ok(answer)) => Some(Ok(line(answer))),
                Ok(Err(error)) => Some(Err(error.to_string())),
                Err(TryRecvError::Empty) => None,
                Err(TryRecvError::Disconnected) => {
                    Some(Err("the engine stopped before answering".into()))
                }
            }
        }
        match self {
            Self::Line(rx) => take(rx, |line| line),
            Self::Edit(rx) => take(rx, |outcome| outcome.note),
        }
    }
}

/// Answers still to come: (what, where).
pub type PendingEdits = Vec<(&'static str, PendingReply)>;

/// The engine command for an edit request and where its answer will come; `None` when
/// `request` is not one of the edits here ([`EngineCommand::AddTool`], [`EngineCommand::Csg`],
/// [`EngineCommand::Emboss`]). A solid operand becomes a clay of its own
/// ([`solid_clay`]), so CSG with a solid is CSG with another clay, intersection included.
///
/// # Errors
/// (inside the `Some`) Why the request could not become a command: a session or image that
/// does not read, named with its path; a solid too large to make into a clay.
pub fn edit_command(request: EngineCommand) -> Option<Result<(Command, PendingReply), String>> {
    let (line_tx, line_rx) = bounded(1);
    let (edit_tx, edit_rx) = bounded(1);
    let edit = |cmd: Command| (cmd, PendingReply::Edit(edit_rx));
    Some(match request {
        EngineCommand::AddTool(preset) => Ok((
            Command::AddTool {
                preset,
                reply: Some(line_tx),
            },
            PendingReply::Line(line_rx),
        )),
        EngineCommand::Csg { op, operand } => {
            let other = match operand {
                CsgOperand::Session(path) => load_session(&path)
                    .map(|session| session.clay)
                    .map_err(|e| format!("{}: {e}", path.display())),
                CsgOperand::Solid {
                    shape,
                    pose,
                    falloff_fu,
                } => {
                    let solid = GeometricTool {
                        shape: *shape,
                        action: op,
                        falloff_fu,
                    };
                    solid_clay(&solid, &pose).map_err(|e| e.to_string())
                }
            };
            other.map(|other| {
                edit(Command::Csg {
                    op,
                    other: Box::new(other),
                    patch: 0,
                    reply: Some(edit_tx),
                })
            })
        }
        EngineCommand::Emboss { image, params } => crate::io::load_relief(&image)
            .map(|relief| {
                (
                    Command::Emboss {
                        relief: std::sync::Arc::new(relief),
                        params,
                        patch: 0,
                        reply: Some(line_tx),
                    },
                    PendingReply::Line(line_rx),
                )
            })
            .map_err(|e| e.to_string()),
        _ => return None,
    })
}

/// Forwards each answer that arrived as an event named by its edit, and forgets the channels
/// that answered or hung up.
pub fn forward_edits(pending: &mut PendingEdits, events: &super::link::EventSender) {
    pending.retain(|(what, reply)| {
        let event = match reply.try_answer() {
            None => return true,
            Some(Ok(detail)) => EngineEvent::Done {
                what: (*what).into(),
                detail,
            },
            Some(Err(error)) => EngineEvent::Failed {
                what: (*what).into(),
                error,
            },
        };
        let _ = events.send(event);
        false
    });
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tools::{ToolAction, ToolPose, ToolShape};
    use glam::Vec3;

    #[test]
    fn edits_become_engine_commands_and_unreadable_files_are_named() {
        let solid = EngineCommand::Csg {
            op: ToolAction::Intersection,
            operand: CsgOperand::Solid {
                shape: Box::new(ToolShape::Sphere { radius_fu: 0.2 }),
                pose: ToolPose::at(Vec3::ONE),
                falloff_fu: 0.05,
            },
        };
        let Some(Ok((Command::Csg { op, other, .. }, PendingReply::Edit(_)))) = edit_command(solid)
        else {
            panic!("a solid operand is CSG with the solid's clay");
        };
        assert_eq!(op, ToolAction::Intersection);
        assert!((other.base().value(Vec3::ONE) - 1.0).abs() < 0.02);
        assert!((other.base().value(Vec3::ONE + Vec3::X * 0.2) - 0.5).abs() < 0.02);
        let missing = EngineCommand::Csg {
            op: ToolAction::Union,
            operand: CsgOperand::Session("/nonexistent/other.dclay".into()),
        };
        let Some(Err(e)) = edit_command(missing) else {
            panic!("a missing session is refused");
        };
        assert!(e.contains("/nonexistent/other.dclay"), "{e}");
        let image = EngineCommand::Emboss {
            image: "/nonexistent/logo.png".into(),
            params: crate::tools::EmbossParams {
                projection: crate::tools::Projection::Spherical {
                    centre: Vec3::ONE,
                    up: Vec3::Y,
                },
                depth_fu: 0.05,
                engrave: false,
            },
        };
        let Some(Err(e)) = edit_command(image) else {
            panic!("a missing image is refused");
        };
        assert!(e.contains("logo.png"), "{e}");
        assert!(edit_command(EngineCommand::Undo).is_none());
    }
}
