//! CSG in the window (Guo & Qin Table 1): union, difference or intersection of the clay with
//! another clay (a session file) or with a solid (sphere, box or cylinder) placed at the last
//! point the brush was on. Each is one undo step, applied by the engine as a script's `csg`
//! step (a session) or `tool` step (a solid) is.
//!
//! Intersection keeps only the clay inside the operand, so it asks for a second click first.

use glam::Vec3;

use super::command::{CsgOperand, EngineCommand};
use crate::tools::{ToolAction, ToolPose, ToolShape};

/// The operations offered, in panel order.
pub const CSG_OPS: [ToolAction; 3] = [
    ToolAction::Union,
    ToolAction::Difference,
    ToolAction::Intersection,
];

/// Where the other operand comes from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum OperandKind {
    /// A solid at the brush point.
    #[default]
    Solid,
    /// The clay of a session file.
    Session,
}

/// The solids offered.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SolidKind {
    #[default]
    Sphere,
    Box,
    Cylinder,
}

/// The CSG panel's state.
#[derive(Clone, Debug, PartialEq)]
pub struct CsgPanel {
    /// The operation.
    pub op: ToolAction,
    /// Solid or session.
    pub operand: OperandKind,
    /// The solid's kind.
    pub solid: SolidKind,
    /// The sphere's and cylinder's radius, the box's half edge, field units.
    pub size_fu: f32,
    /// The cylinder's half height (along y), field units.
    pub half_height_fu: f32,
    /// The solid's potential falls over this band on each side of its surface, field units
    /// (the edge's sharpness: narrower is sharper, down to what the clay's knot spacing holds).
    pub falloff_fu: f32,
    /// The session file of a session operand.
    pub session_path: String,
    /// An intersection waiting for its confirming click.
    confirming: bool,
}

impl Default for CsgPanel {
    fn default() -> Self {
        Self {
            op: ToolAction::Difference,
            operand: OperandKind::Solid,
            solid: SolidKind::Sphere,
            size_fu: 0.2,
            half_height_fu: 0.2,
            falloff_fu: 0.05,
            session_path: "other.dclay".into(),
            confirming: false,
        }
    }
}

impl CsgPanel {
    /// The solid's shape (cylinder axes along y, the view's usual up).
    #[must_use]
    pub fn shape(&self) -> ToolShape {
        match self.solid {
            SolidKind::Sphere => ToolShape::Sphere {
                radius_fu: self.size_fu,
            },
            SolidKind::Box => ToolShape::Box {
                half_extents_fu: Vec3::splat(self.size_fu),
            },
            SolidKind::Cylinder => ToolShape::Cylinder {
                radius_fu: self.size_fu,
                half_height_fu: self.half_height_fu,
            },
        }
    }

    /// The command for the panel's settings with the solid at `at` (`None`: no brush point
    /// yet, so a solid operand cannot be placed).
    #[must_use]
    pub fn command(&self, at: Option<Vec3>) -> Option<EngineCommand> {
        let operand = match self.operand {
            OperandKind::Session => {
                CsgOperand::Session(std::path::PathBuf::from(self.session_path.trim()))
            }
            OperandKind::Solid => {
                let rotation = match self.solid {
                    // The tool's cylinder runs along its local z: turn it upright.
                    SolidKind::Cylinder => {
                        glam::Quat::from_rotation_x(-std::f32::consts::FRAC_PI_2)
                    }
                    _ => glam::Quat::IDENTITY,
                };
                CsgOperand::Solid {
                    shape: Box::new(self.shape()),
                    pose: ToolPose {
                        position_fu: at?,
                        rotation,
                    },
                    falloff_fu: self.falloff_fu,
                }
            }
        };
        Some(EngineCommand::Csg {
            op: self.op,
            operand,
        })
    }

    /// Draws the panel; `at` is the last brush point on the clay. Returns the command to send.
    pub fn ui(&mut self, ui: &mut egui::Ui, at: Option<Vec3>) -> Option<EngineCommand> {
        let before = self.op;
        ui.horizontal_wrapped(|ui| {
            for op in CSG_OPS {
                let label = match op {
                    ToolAction::Union => "Union with operand",
                    ToolAction::Difference => "Subtract operand",
                    _ => "Intersect with operand",
                };
                ui.radio_value(&mut self.op, op, label);
            }
        });
        if self.op != before {
            self.confirming = false;
        }
        ui.horizontal_wrapped(|ui| {
            ui.label("With");
            ui.radio_value(
                &mut self.operand,
                OperandKind::Solid,
                "a solid at the brush",
            );
            ui.radio_value(&mut self.operand, OperandKind::Session, "a session file");
        });
        match self.operand {
            OperandKind::Solid => {
                ui.horizontal_wrapped(|ui| {
                    ui.radio_value(&mut self.solid, SolidKind::Sphere, "Sphere");
                    ui.radio_value(&mut self.solid, SolidKind::Box, "Box");
                    ui.radio_value(&mut self.solid, SolidKind::Cylinder, "Cylinder");
                });
                let size = match self.solid {
                    SolidKind::Box => "Half edge",
                    _ => "Radius",
                };
                ui.add(egui::Slider::new(&mut self.size_fu, 0.01..=1.0).text(size));
                if self.solid == SolidKind::Cylinder {
                    ui.add(
                        egui::Slider::new(&mut self.half_height_fu, 0.01..=1.0).text("Half height"),
                    );
                }
                ui.add(
                    egui::Slider::new(&mut self.falloff_fu, 0.005..=0.3)
                        .logarithmic(true)
                        .text("Edge band"),
                );
                match at {
                    Some(p) => ui.weak(format!(
                        "centred on the brush point ({:.3}, {:.3}, {:.3})",
                        p.x, p.y, p.z
                    )),
                    None => ui.weak("move the pointer over the clay to place the solid"),
                };
            }
            OperandKind::Session => {
                ui.horizontal_wrapped(|ui| {
                    let label = ui.label("File");
                    ui.add(egui::TextEdit::singleline(&mut self.session_path).desired_width(160.0))
                        .labelled_by(label.id);
                });
                ui.weak("The session's clay, in its own field coordinates.");
            }
        }
        let ready = self.operand == OperandKind::Session || at.is_some();
        let label = if self.confirming {
            "Confirm: keep only the clay inside"
        } else {
            "Apply CSG"
        };
        let mut command = None;
        if ui.add_enabled(ready, egui::Button::new(label)).clicked() {
            if self.op == ToolAction::Intersection && !self.confirming {
                self.confirming = true;
            } else {
                self.confirming = false;
                command = self.command(at);
            }
        }
        if self.confirming {
            ui.colored_label(
                ui.visuals().warn_fg_color,
                "Intersection removes all the clay outside the operand; click again to apply.",
            );
        }
        command
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_panel_makes_solid_and_session_operands() {
        let mut panel = CsgPanel::default();
        assert!(panel.command(None).is_none(), "a solid needs a brush point");
        let Some(EngineCommand::Csg { op, operand }) = panel.command(Some(Vec3::ONE)) else {
            panic!("expected a CSG command");
        };
        assert_eq!(op, ToolAction::Difference);
        assert_eq!(
            operand,
            CsgOperand::Solid {
                shape: Box::new(ToolShape::Sphere { radius_fu: 0.2 }),
                pose: ToolPose::at(Vec3::ONE),
                falloff_fu: 0.05,
            }
        );
        panel.operand = OperandKind::Session;
        panel.op = ToolAction::Union;
        assert_eq!(
            panel.command(None),
            Some(EngineCommand::Csg {
                op: ToolAction::Union,
                operand: CsgOperand::Session("other.dclay".into()),
            })
        );
    }
}
