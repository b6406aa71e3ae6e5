//! The session's tool library as the running engine keeps it: tools made from the sculpt
//! ([`dynaclay_core::tools::capture_tool`]) are stored under a name and saved with the session, and a
//! script's later steps use them by name ([`LibraryTool`]), resolved on the simulation thread
//! when the step runs (the tool did not exist when the script was laid out).
//!
//! Not real-time: making a tool fits a lattice; using one clones it.

use glam::Vec3;

use dynaclay_core::field::MultiPatchField;
use dynaclay_core::io::ToolPreset;
use dynaclay_core::tools::{
    CaptureError, GeometricTool, Selection, ToolAction, ToolShape, capture_tool,
};

use dynaclay_core::io::MAX_TOOL_NAME_BYTES;

/// A library tool named by a script step, with what the step changes about it.
#[derive(Clone, Debug, PartialEq)]
pub struct LibraryTool {
    /// The preset's name.
    pub name: String,
    /// Scale along the tool's local axes, multiplying a freeform preset's own.
    pub scale: Vec3,
    /// The action to use instead of the preset's.
    pub action: Option<ToolAction>,
    /// The falloff band to use instead of the preset's.
    pub falloff_fu: Option<f32>,
}

/// Why a library tool could not be made or used.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum LibraryError {
    /// No preset of that name.
    #[error("no tool preset named {name:?}")]
    NoPreset {
        /// The name asked for.
        name: String,
    },
    /// A scale was asked of an analytic preset.
    #[error("tool preset {name:?} is not a freeform shape, so it takes no scale")]
    NotFreeform {
        /// The preset's name.
        name: String,
    },
    /// The name is empty or too long.
    #[error("a tool's name must be 1 to {MAX_TOOL_NAME_BYTES} bytes, got {len}")]
    BadName {
        /// Its length, bytes.
        len: usize,
    },
    /// The clay could not be captured.
    #[error("make tool {name:?}: {error}")]
    Capture {
        /// The tool's name.
        name: String,
        /// Why.
        error: CaptureError,
    },
    /// The resolved tool's parameters are invalid.
    #[error("tool preset {name:?}: {error}")]
    Invalid {
        /// The preset's name.
        name: String,
        /// Why.
        error: dynaclay_core::tools::ToolError,
    },
}

/// Checks a library tool's name.
///
/// # Errors
/// [`LibraryError::BadName`] for an empty name or one over [`MAX_TOOL_NAME_BYTES`].
pub fn check_name(name: &str) -> Result<(), LibraryError> {
    if name.is_empty() || name.len() > MAX_TOOL_NAME_BYTES {
        return Err(LibraryError::BadName { len: name.len() });
    }
    Ok(())
}

/// Makes the preset `name` from the clay `field` inside `selection`, with `action` and
/// `falloff_fu` as its defaults.
///
/// # Errors
/// [`LibraryError::BadName`] or [`LibraryError::Capture`].
pub fn make_preset(
    field: &MultiPatchField,
    name: &str,
    selection: &Selection,
    action: ToolAction,
    falloff_fu: f32,
) -> Result<ToolPreset, LibraryError> {
    check_name(name)?;
    let tool = capture_tool(field, selection).map_err(|error| LibraryError::Capture {
        name: name.to_owned(),
        error,
    })?;
    Ok(ToolPreset {
        name: name.to_owned(),
        shape: ToolShape::Freeform(tool),
        action,
        falloff_fu,
    })
}

/// Stores `preset` in `library`, replacing the one of the same name; true when one was
/// replaced.
pub fn store_preset(library: &mut Vec<ToolPreset>, preset: ToolPreset) -> bool {
    match library.iter_mut().find(|t| t.name == preset.name) {
        Some(old) => {
            *old = preset;
            true
        }
        None => {
            library.push(preset);
            false
        }
    }
}

/// One line about a stored preset, for logs and script notes.
#[must_use]
pub fn describe_preset(preset: &ToolPreset, replaced: bool) -> String {
    let size = match &preset.shape {
        ToolShape::Freeform(f) => {
            let [x, y, z] = f.lattice.dims;
            format!("a {x}×{y}×{z} lattice at spacing {:.4}", f.lattice.spacing)
        }
        other => format!("a {other:?}"),
    };
    let verb = if replaced { "replaced" } else { "added" };
    format!(
        "tool {:?} {verb} in the library: {size}, action {}",
        preset.name,
        preset.action.name()
    )
}

impl LibraryTool {
    /// The preset with this name as a geometric tool, with the step's scale, action and
    /// falloff applied.
    ///
    /// # Errors
    /// [`LibraryError::NoPreset`], [`LibraryError::NotFreeform`] for a scale other than one on
    /// an analytic preset, or [`LibraryError::Invalid`].
    pub fn resolve(&self, library: &[ToolPreset]) -> Result<GeometricTool, LibraryError> {
        let preset = library
            .iter()
            .find(|t| t.name == self.name)
            .ok_or_else(|| LibraryError::NoPreset {
                name: self.name.clone(),
            })?;
        let shape = match &preset.shape {
            ToolShape::Freeform(f) => {
                let mut f = f.clone();
                f.scale *= self.scale;
                ToolShape::Freeform(f)
            }
            analytic if self.scale == Vec3::ONE => analytic.clone(),
            _ => {
                return Err(LibraryError::NotFreeform {
                    name: self.name.clone(),
                });
            }
        };
        let tool = GeometricTool {
            shape,
            action: self.action.unwrap_or(preset.action),
            falloff_fu: self.falloff_fu.unwrap_or(preset.falloff_fu),
        };
        tool.validate().map_err(|error| LibraryError::Invalid {
            name: self.name.clone(),
            error,
        })?;
        Ok(tool)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use dynaclay_core::field::{Primitive, lattice_from_primitive};

    #[test]
    fn a_made_tool_is_stored_by_name_and_resolved_with_the_steps_changes() {
        let field = MultiPatchField::new(
            lattice_from_primitive(
                [20; 3],
                0.1,
                Vec3::ZERO,
                &Primitive::Sphere {
                    centre: Vec3::splat(0.95),
                    radius: 0.4,
                },
                0.2,
                2,
            )
            .unwrap(),
        );
        let selection = Selection::Ball {
            centre: Vec3::splat(0.95),
            radius_fu: 0.5,
        };
        let mut library = Vec::new();
        let made = make_preset(&field, "ball", &selection, ToolAction::Union, 0.05).unwrap();
        assert!(!store_preset(&mut library, made.clone()));
        assert!(store_preset(&mut library, made));
        assert_eq!(library.len(), 1);
        assert!(describe_preset(&library[0], false).contains("\"ball\" added"));
        let used = LibraryTool {
            name: "ball".into(),
            scale: Vec3::new(2.0, 1.0, 1.0),
            action: Some(ToolAction::Difference),
            falloff_fu: None,
        }
        .resolve(&library)
        .unwrap();
        assert_eq!(used.action, ToolAction::Difference);
        let ToolShape::Freeform(f) = &used.shape else {
            panic!("expected a freeform shape");
        };
        assert_eq!(f.scale, Vec3::new(2.0, 1.0, 1.0));
        let missing = LibraryTool {
            name: "cube".into(),
            scale: Vec3::ONE,
            action: None,
            falloff_fu: None,
        };
        assert_eq!(
            missing.resolve(&library),
            Err(LibraryError::NoPreset {
                name: "cube".into()
            })
        );
        assert!(matches!(
            make_preset(&field, "", &selection, ToolAction::Union, 0.05),
            Err(LibraryError::BadName { len: 0 })
        ));
    }
}
