//! The steps that several readers of a script take apart the same way, read once: a `tool`
//! or `preset` step's geometric tool and poses ([`ScriptStep::tool_step`]) and an `emboss`
//! step's parameters ([`ScriptStep::emboss_params`]). Validation, the engine's plan and the
//! RBF session mode all go through these, so a step means one thing to each of them.

use super::*;
use crate::io::ToolPreset;
use crate::tools::{EmbossParams, GeometricTool};

/// Which geometric tool a `tool` or `preset` step applies.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum StepTool<'a> {
    /// A shape and an action written in the step (`do = "tool"`).
    Given {
        /// The shape (a `freeform` one names a library tool).
        shape: &'a ShapeSpec,
        /// What the tool does.
        action: ToolAction,
        /// Its potential's falloff band, field units.
        falloff_fu: f32,
    },
    /// A tool of the library, by name (`do = "preset"`).
    Preset {
        /// The library tool's name.
        name: &'a str,
    },
}

/// A `tool` or `preset` step: a geometric tool applied at each pose.
#[derive(Clone, Debug, PartialEq)]
pub struct ToolStep<'a> {
    /// The tool.
    pub tool: StepTool<'a>,
    /// Where it is applied, field coordinates (a preset's poses are unrotated).
    pub poses: Vec<ToolPose>,
    /// Seconds the application takes.
    pub duration_s: f32,
    /// The density patch it edits (a preset edits patch 0).
    pub patch: u16,
}

/// Why a step's geometric tool could not be made.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ToolStepError {
    /// A `freeform` shape's library tool, or a preset, is missing or not a freeform shape.
    #[error("{0}")]
    Preset(#[from] PresetError),
}

impl ScriptStep {
    /// The geometric tool application of a `tool` or `preset` step; `None` for any other.
    #[must_use]
    pub fn tool_step(&self) -> Option<ToolStep<'_>> {
        match self {
            Self::Tool {
                shape,
                action,
                positions,
                falloff_fu,
                rotation,
                duration_s,
                patch,
            } => Some(ToolStep {
                tool: StepTool::Given {
                    shape,
                    action: *action,
                    falloff_fu: *falloff_fu,
                },
                poses: poses(positions, *rotation),
                duration_s: *duration_s,
                patch: *patch,
            }),
            Self::Preset {
                name,
                positions,
                duration_s,
            } => Some(ToolStep {
                tool: StepTool::Preset { name },
                poses: poses(positions, None),
                duration_s: *duration_s,
                patch: 0,
            }),
            _ => None,
        }
    }

    /// The parameters of an `emboss` step (not yet checked: see
    /// [`EmbossParams::validate`]); `None` for any other step.
    #[must_use]
    pub fn emboss_params(&self) -> Option<EmbossParams> {
        match self {
            Self::Emboss {
                projection,
                depth,
                engrave,
                ..
            } => Some(EmbossParams {
                projection: projection.projection(),
                depth_fu: *depth,
                engrave: *engrave,
            }),
            _ => None,
        }
    }
}

impl ToolStep<'_> {
    /// The library tool's name when the step's tool is one (a preset, or a `freeform`
    /// shape), with the scale a `freeform` shape gives it.
    #[must_use]
    pub fn library_tool(&self) -> Option<(&str, Vec3)> {
        match self.tool {
            StepTool::Given {
                shape: ShapeSpec::Freeform { preset, scale },
                ..
            } => Some((preset, Vec3::from_array(*scale))),
            StepTool::Given { .. } => None,
            StepTool::Preset { name } => Some((name, Vec3::ONE)),
        }
    }

    /// The geometric tool, with library tools looked up by name in `library`.
    ///
    /// # Errors
    /// [`ToolStepError::Preset`] when a library tool is missing (or, for a `freeform` shape,
    /// not a freeform shape).
    pub fn geometric_tool<'l>(
        &self,
        library: impl Fn(&str) -> Option<&'l ToolPreset>,
    ) -> Result<GeometricTool, ToolStepError> {
        match self.tool {
            StepTool::Given {
                shape,
                action,
                falloff_fu,
            } => Ok(GeometricTool {
                shape: shape.resolve(|name| library(name).map(|t| &t.shape))?,
                action,
                falloff_fu,
            }),
            StepTool::Preset { name } => {
                let preset = library(name).ok_or_else(|| PresetError::Missing {
                    name: name.to_owned(),
                })?;
                Ok(GeometricTool {
                    shape: preset.shape.clone(),
                    action: preset.action,
                    falloff_fu: preset.falloff_fu,
                })
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const STEPS: &str = r#"
version = 1

[[step]]
do = "tool"
shape = { kind = "sphere", radius_fu = 0.2 }
action = { kind = "add", deposit_rate_per_s = 4.0 }
positions = [[0.5, 0.5, 0.5], [0.6, 0.5, 0.5]]
rotation = [0.0, 0.0, 0.7071068, 0.7071068]
duration_s = 0.5
patch = 1

[[step]]
do = "preset"
name = "gouge"
positions = [[0.1, 0.2, 0.3]]
duration_s = 0.25

[[step]]
do = "tool"
shape = { kind = "freeform", preset = "gouge", scale = [2.0, 1.0, 1.0] }
action = { kind = "remove" }
positions = [[0.0, 0.0, 0.0]]

[[step]]
do = "undo"
"#;

    fn gouge() -> ToolPreset {
        ToolPreset {
            name: "gouge".into(),
            shape: ToolShape::Box {
                half_extents_fu: Vec3::new(0.1, 0.05, 0.02),
            },
            action: ToolAction::Remove,
            falloff_fu: 0.03,
        }
    }

    #[test]
    fn tool_and_preset_steps_read_as_one_kind_of_step() {
        let script = parse_script(STEPS, "steps.toml").unwrap();
        let library = [gouge()];
        let lookup = |name: &str| library.iter().find(|t| t.name == name);

        let tool = script.steps[0].tool_step().expect("a tool step");
        assert_eq!(tool.poses.len(), 2);
        assert_eq!(tool.poses[1].position_fu, Vec3::new(0.6, 0.5, 0.5));
        assert!((tool.poses[0].rotation.length() - 1.0).abs() < 1e-6);
        assert_eq!((tool.duration_s, tool.patch), (0.5, 1));
        assert_eq!(tool.library_tool(), None);
        let made = tool.geometric_tool(lookup).unwrap();
        assert_eq!(made.shape, ToolShape::Sphere { radius_fu: 0.2 });

        let preset = script.steps[1].tool_step().expect("a preset step");
        assert_eq!(preset.library_tool(), Some(("gouge", Vec3::ONE)));
        assert_eq!(preset.poses[0].rotation, glam::Quat::IDENTITY);
        assert_eq!((preset.duration_s, preset.patch), (0.25, 0));
        let made = preset.geometric_tool(lookup).unwrap();
        assert_eq!(
            (made.shape, made.action, made.falloff_fu),
            (gouge().shape, gouge().action, 0.03)
        );
        assert_eq!(
            preset.geometric_tool(|_| None).unwrap_err().to_string(),
            "no tool preset named \"gouge\""
        );

        let freeform = script.steps[2].tool_step().expect("a tool step");
        assert_eq!(
            freeform.library_tool(),
            Some(("gouge", Vec3::new(2.0, 1.0, 1.0)))
        );
        // The library's gouge is a box, not a freeform shape.
        assert!(matches!(
            freeform.geometric_tool(lookup),
            Err(ToolStepError::Preset(PresetError::NotFreeform { .. }))
        ));

        assert!(script.steps[3].tool_step().is_none());
        assert!(script.steps[3].emboss_params().is_none());
    }
}
