//! Runs the non-real-time steps of a script on a [`Session`]: geometric tools (and presets),
//! CSG with another session file, material changes, undo/redo and saves. Force strokes need
//! the dynamics and the loops, so they (and material changes, after they are stored) are
//! handed to the engine's callback. Every tool step is one undo step.

use std::path::Path;

use super::atomic::{load_session, save_session};
use super::script::{Script, ScriptError, ScriptStep, pin_request, poses};
use super::session::Session;
use crate::tools::{
    ApplyOptions, GeometricTool, History, PinRequest, StepRecorder, ToolReport, add_pins,
    apply_csg, apply_stroke, remove_pins,
};

/// What a run did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RunSummary {
    /// Steps executed (including those handed to the engine).
    pub steps_run: usize,
    /// One report per geometric tool or CSG step, in order.
    pub tool_reports: Vec<ToolReport>,
    /// Steps handed to the engine callback.
    pub handed_to_engine: usize,
    /// What `constrain` and `unconstrain` steps did (1-based step, message).
    pub notes: Vec<(usize, String)>,
}

/// Runs `script` on `session`; paths in the script are relative to `base_dir`. `engine` runs
/// `stroke` steps and is told about `material` steps (after the session's material was
/// updated); it returns an error message to stop the run.
///
/// # Errors
/// A [`ScriptError`] naming the failing step (1-based); steps before it stay applied.
pub fn run_script(
    script: &Script,
    session: &mut Session,
    history: &mut History,
    base_dir: &Path,
    engine: &mut dyn FnMut(&ScriptStep, &mut Session, &mut History) -> Result<(), String>,
) -> Result<RunSummary, ScriptError> {
    let mut summary = RunSummary::default();
    for (n, step) in script.steps.iter().enumerate() {
        let fail = |message: String| ScriptError {
            file: base_dir.display().to_string(),
            line: None,
            column: None,
            step: Some(n + 1),
            message,
        };
        match step {
            ScriptStep::Tool {
                shape,
                action,
                positions,
                falloff_m,
                rotation,
                duration_s,
                patch,
            } => {
                let shape = shape
                    .resolve(|name| session.tool(name).map(|t| &t.shape))
                    .map_err(fail)?;
                let tool = GeometricTool {
                    shape,
                    action: *action,
                    falloff_m: *falloff_m,
                };
                let options = ApplyOptions {
                    patch: *patch,
                    ..ApplyOptions::default()
                };
                let report = run_tool(
                    session,
                    history,
                    &tool,
                    &poses(positions, *rotation),
                    *duration_s,
                    &options,
                )
                .map_err(fail)?;
                summary.tool_reports.push(report);
            }
            ScriptStep::Preset {
                name,
                positions,
                duration_s,
            } => {
                let preset = session
                    .tool(name)
                    .ok_or_else(|| fail(format!("no tool preset named {name:?}")))?;
                let tool = GeometricTool {
                    shape: preset.shape.clone(),
                    action: preset.action,
                    falloff_m: preset.falloff_m,
                };
                let report = run_tool(
                    session,
                    history,
                    &tool,
                    &poses(positions, None),
                    *duration_s,
                    &ApplyOptions::default(),
                )
                .map_err(fail)?;
                summary.tool_reports.push(report);
            }
            ScriptStep::Csg { op, with, patch } => {
                let other = load_session(&base_dir.join(with)).map_err(|e| fail(e.to_string()))?;
                let mut recorder = StepRecorder::new(format!("csg {op:?}"));
                let options = ApplyOptions {
                    patch: *patch,
                    ..ApplyOptions::default()
                };
                let report = apply_csg(
                    &mut session.clay,
                    &other.clay,
                    (*op).into(),
                    &options,
                    Some(&mut recorder),
                )
                .map_err(|e| fail(e.to_string()))?;
                history.commit(recorder, &session.clay);
                summary.tool_reports.push(report);
            }
            ScriptStep::Undo { count } => {
                for _ in 0..*count {
                    history
                        .undo(&mut session.clay)
                        .map_err(|e| fail(e.to_string()))?;
                }
            }
            ScriptStep::Redo { count } => {
                for _ in 0..*count {
                    history
                        .redo(&mut session.clay)
                        .map_err(|e| fail(e.to_string()))?;
                }
            }
            ScriptStep::Save { path } => {
                save_session(&base_dir.join(path), session).map_err(|e| fail(e.to_string()))?;
            }
            ScriptStep::Constrain { kind, at, points } => {
                let request = pin_request(*kind, *at, points).map_err(fail)?;
                let note = pin_on_session(session, history, &request).map_err(fail)?;
                summary.notes.push((n + 1, note));
            }
            ScriptStep::Unconstrain { index } => {
                // Checked non-negative and bounded when the script was parsed.
                let index = index.map(|i| usize::try_from(i).unwrap_or(usize::MAX));
                let note = unpin_on_session(session, history, index).map_err(fail)?;
                summary.notes.push((n + 1, note));
            }
            ScriptStep::Material { .. } => {
                session.material.uniform = step.updated_material(session.material.uniform);
                engine(step, session, history).map_err(fail)?;
                summary.handed_to_engine += 1;
            }
            ScriptStep::Stroke { .. } => {
                engine(step, session, history).map_err(fail)?;
                summary.handed_to_engine += 1;
            }
        }
        summary.steps_run += 1;
    }
    Ok(summary)
}

/// Pins `request` on the session's clay as one undo step.
fn pin_on_session(
    session: &mut Session,
    history: &mut History,
    request: &PinRequest,
) -> Result<String, String> {
    let mut recorder = StepRecorder::new("pin");
    recorder.touch_constraints(&session.clay);
    let message = add_pins(&mut session.clay, request).map_err(|e| e.to_string())?;
    history.commit(recorder, &session.clay);
    Ok(message)
}

/// Removes pin `index` (or all) from the session's clay as one undo step.
fn unpin_on_session(
    session: &mut Session,
    history: &mut History,
    index: Option<usize>,
) -> Result<String, String> {
    let mut recorder = StepRecorder::new("unpin");
    recorder.touch_constraints(&session.clay);
    let message = remove_pins(&mut session.clay, index).map_err(|e| e.to_string())?;
    history.commit(recorder, &session.clay);
    Ok(message)
}

/// One geometric tool step as one undo step.
fn run_tool(
    session: &mut Session,
    history: &mut History,
    tool: &GeometricTool,
    poses: &[crate::tools::ToolPose],
    duration_s: f32,
    options: &ApplyOptions,
) -> Result<ToolReport, String> {
    let mut recorder = StepRecorder::new(tool.action.name());
    let result = apply_stroke(
        &mut session.clay,
        tool,
        poses,
        duration_s,
        options,
        Some(&mut recorder),
    );
    // Whatever was applied before a failure stays undoable.
    history.commit(recorder, &session.clay);
    result.map_err(|e| e.to_string())
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;
    use crate::field::BSplineLattice;
    use crate::io::parse_script;
    use crate::tools::Clay;

    #[test]
    fn a_script_sculpts_undoes_and_saves_and_hands_strokes_to_the_engine() {
        let dir = tempfile::tempdir().unwrap();
        let text = r#"
version = 1

[[step]]
do = "tool"
shape = { kind = "sphere", radius_m = 0.3 }
action = { kind = "add", deposit_rate_per_s = 2.0 }
positions = [[1.0, 1.0, 1.0]]
duration_s = 1.0
falloff_m = 0.12

[[step]]
do = "save"
path = "first.dclay"

[[step]]
do = "tool"
shape = { kind = "box", half_extents_m = [0.1, 0.1, 0.5] }
action = { kind = "remove" }
positions = [[1.0, 1.0, 1.0]]
falloff_m = 0.12

[[step]]
do = "stroke"
tool = { kind = "grab", gain = 1.0 }
path = [[1.3, 1.0, 1.0], [1.4, 1.0, 1.0]]
duration_s = 0.5

[[step]]
do = "material"
stiffness = 123.0

[[step]]
do = "undo"

[[step]]
do = "save"
path = "second.dclay"
"#;
        let script = parse_script(text, "t.toml").unwrap();
        let lattice = BSplineLattice::zeros([32; 3], 1.0 / 16.0, Vec3::ZERO).unwrap();
        let mut session = Session {
            clay: Clay::single(lattice),
            ..Session::default()
        };
        let mut history = History::default();
        let mut strokes = 0;
        let summary = run_script(
            &script,
            &mut session,
            &mut history,
            dir.path(),
            &mut |step, _, _| {
                if matches!(step, ScriptStep::Stroke { .. }) {
                    strokes += 1;
                }
                Ok(())
            },
        )
        .unwrap();
        assert_eq!(
            (summary.steps_run, summary.handed_to_engine, strokes),
            (7, 2, 1)
        );
        assert_eq!(summary.tool_reports.len(), 2);
        assert_eq!(session.material.uniform.stiffness, 123.0);
        // The undo removed the box cut: the state equals the first save, bit for bit.
        let first = load_session(&dir.path().join("first.dclay")).unwrap();
        let second = load_session(&dir.path().join("second.dclay")).unwrap();
        assert_eq!(first.clay, second.clay);
        assert!(second.clay.patches[0].is_inside(Vec3::ONE));
    }

    #[test]
    fn a_failing_step_is_named() {
        let script = parse_script(
            "version = 1\n[[step]]\ndo = \"undo\"\n[[step]]\ndo = \"preset\"\nname = \"nope\"\npositions = [[0, 0, 0]]\n",
            "t.toml",
        )
        .unwrap();
        let mut session = Session::default();
        let mut history = History::default();
        let e = run_script(
            &script,
            &mut session,
            &mut history,
            Path::new("."),
            &mut |_, _, _| Ok(()),
        )
        .unwrap_err();
        assert_eq!(e.step, Some(2));
        assert!(e.message.contains("nope"), "{e}");
    }

    #[test]
    fn constrain_steps_pin_project_list_and_undo_on_a_session() {
        use crate::dynamics::Constraint;
        use crate::field::{Primitive, lattice_from_primitive};
        let centre = Vec3::splat(0.95);
        let ball = Primitive::Sphere {
            centre,
            radius: 0.4,
        };
        let lattice = lattice_from_primitive([20; 3], 0.1, Vec3::ZERO, &ball, 0.2, 2).unwrap();
        let text = r#"
version = 1

[[step]]
do = "constrain"
kind = "point"
at = [1.4, 0.95, 0.95]

[[step]]
do = "constrain"
kind = "curve"
points = [[0.95, 1.35, 0.9], [0.95, 1.35, 1.0]]

[[step]]
do = "constrain"
kind = "normal"
at = [0.95, 0.95, 1.35]

[[step]]
do = "unconstrain"
index = 1

[[step]]
do = "undo"

[[step]]
do = "constrain"
kind = "point"
at = [5.0, 5.0, 5.0]
"#;
        let script = parse_script(text, "pins.toml").unwrap();
        let mut session = Session {
            clay: Clay::single(lattice.clone()),
            ..Session::default()
        };
        let mut history = History::default();
        let err = run_script(
            &script,
            &mut session,
            &mut history,
            Path::new("."),
            &mut |_, _, _| Ok(()),
        )
        .unwrap_err();
        // The last pin lies outside the clay: the step is named, earlier steps stay.
        assert_eq!(err.step, Some(6), "{err}");
        assert!(err.to_string().contains("outside"), "{err}");
        let pins = &session.clay.constraints;
        // point, curve, normal + its point; the unconstrain was undone.
        assert_eq!(pins.len(), 4, "{pins:?}");
        let Constraint::Point { at } = pins[0] else {
            panic!("{pins:?}")
        };
        // 1.4 is outside the ball of radius 0.4 about 0.95: moved in onto the surface.
        assert!((at.x - 1.35).abs() < 0.01, "{at}");
        assert!((lattice.value(at) - lattice.iso).abs() < 1e-5);
        assert!(matches!(pins[1], Constraint::Curve { .. }));
        assert!(matches!(pins[2], Constraint::Normal { .. }));
        assert!(matches!(pins[3], Constraint::Point { .. }));
        // Undo all four pin steps (the unconstrain is already undone).
        for _ in 0..3 {
            history.undo(&mut session.clay).unwrap();
        }
        assert!(session.clay.constraints.is_empty());
        history.redo(&mut session.clay).unwrap();
        assert_eq!(session.clay.constraints.len(), 1);
    }
}
