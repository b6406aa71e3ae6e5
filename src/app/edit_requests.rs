//! The window's sculpt edits that need something read or built before the engine applies them
//! — a tool made from the sculpt for the library, CSG with a session file or a solid, an
//! embossed image — turned into the engine's commands on the bridge thread (files are read
//! here, never on a loop), and their answers forwarded to the app's log.

use crossbeam::channel::{Receiver, Sender, TryRecvError};

use super::command::{CsgOperand, EngineCommand, EngineEvent};
use crate::engine::{Command, CommandError, Reply};
use crate::io::load_session;
use crate::tools::{GeometricTool, Relief};

/// Answers still to come: (what, receiver).
pub type PendingEdits = Vec<(&'static str, Receiver<Result<String, CommandError>>)>;

/// The engine command for an edit request, answering on `reply`; `None` when `request` is not
/// one of the edits here ([`EngineCommand::AddTool`], [`EngineCommand::Csg`],
/// [`EngineCommand::Emboss`]).
///
/// # Errors
/// (inside the `Some`) Why the request could not become a command: a session or image that
/// does not read, named with its path.
pub fn edit_command(request: EngineCommand, reply: Reply) -> Option<Result<Command, String>> {
    Some(match request {
        EngineCommand::AddTool(preset) => Ok(Command::AddTool {
            preset,
            reply: Some(reply),
        }),
        EngineCommand::Csg { op, operand } => match operand {
            CsgOperand::Session(path) => load_session(&path)
                .map(|session| Command::Csg {
                    op,
                    other: Box::new(session.clay),
                    patch: 0,
                    reply: Some(reply),
                })
                .map_err(|e| format!("{}: {e}", path.display())),
            CsgOperand::Solid {
                shape,
                pose,
                falloff_fu,
            } => Ok(Command::ApplyTool {
                tool: GeometricTool {
                    shape,
                    action: op,
                    falloff_fu,
                },
                poses: vec![pose],
                duration_s: 0.0,
                patch: 0,
                reply: Some(reply),
            }),
        },
        EngineCommand::Emboss { image, params } => Relief::load(&image)
            .map(|relief| Command::Emboss {
                relief: std::sync::Arc::new(relief),
                params,
                patch: 0,
                reply: Some(reply),
            })
            .map_err(|e| e.to_string()),
        _ => return None,
    })
}

/// Forwards each answer that arrived as an event named by its edit, and forgets the channels
/// that answered or hung up.
pub fn forward_edits(pending: &mut PendingEdits, events: &Sender<EngineEvent>) {
    pending.retain(|(what, rx)| {
        let event = match rx.try_recv() {
            Ok(Ok(detail)) => EngineEvent::Done {
                what: (*what).into(),
                detail,
            },
            Ok(Err(error)) => EngineEvent::Failed {
                what: (*what).into(),
                error: error.to_string(),
            },
            Err(TryRecvError::Empty) => return true,
            Err(TryRecvError::Disconnected) => EngineEvent::Failed {
                what: (*what).into(),
                error: "the engine stopped before answering".into(),
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
    use crossbeam::channel::bounded;
    use glam::Vec3;

    #[test]
    fn edits_become_engine_commands_and_unreadable_files_are_named() {
        let (tx, _rx) = bounded(1);
        let solid = EngineCommand::Csg {
            op: ToolAction::Difference,
            operand: CsgOperand::Solid {
                shape: ToolShape::Sphere { radius_fu: 0.2 },
                pose: ToolPose::at(Vec3::ONE),
                falloff_fu: 0.05,
            },
        };
        let Some(Ok(Command::ApplyTool { tool, poses, .. })) = edit_command(solid, tx.clone())
        else {
            panic!("a solid operand is a tool application");
        };
        assert_eq!(tool.action, ToolAction::Difference);
        assert_eq!(poses, vec![ToolPose::at(Vec3::ONE)]);
        let missing = EngineCommand::Csg {
            op: ToolAction::Union,
            operand: CsgOperand::Session("/nonexistent/other.dclay".into()),
        };
        let Some(Err(e)) = edit_command(missing, tx.clone()) else {
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
                depth: 0.05,
                engrave: false,
            },
        };
        let Some(Err(e)) = edit_command(image, tx.clone()) else {
            panic!("a missing image is refused");
        };
        assert!(e.contains("logo.png"), "{e}");
        assert!(edit_command(EngineCommand::Undo, tx).is_none());
    }
}
