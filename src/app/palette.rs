//! The tool palette: which tool is in the hand and each tool's parameters.
//!
//! The palette keeps every tool's settings, so switching tools and back restores them; the app
//! sends [`ToolPalette::choice`] to the engine whenever the selection or a parameter changes.

use glam::Vec3;

use super::command::ForceMode;
use crate::dynamics::Distribution;
use crate::engine::{PushTool, ToolChoice};
use crate::tools::{ContactParams, ForceTool, GeometricTool, StampParams, ToolAction, ToolShape};

/// The geometric actions, in palette order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ActionKind {
    Add,
    Remove,
    SoftRemove,
    Paint,
    SoftPaint,
    Smooth,
    Stamp,
    Contact,
    Union,
    Intersection,
    Difference,
}

impl ActionKind {
    pub const ALL: [ActionKind; 11] = [
        Self::Add,
        Self::Remove,
        Self::SoftRemove,
        Self::Paint,
        Self::SoftPaint,
        Self::Smooth,
        Self::Stamp,
        Self::Contact,
        Self::Union,
        Self::Intersection,
        Self::Difference,
    ];
}

/// The analytic tool shapes offered (a freeform tool needs a sculpted session: not here yet).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ShapeKind {
    Sphere,
    Ellipsoid,
    Box,
    Cylinder,
    Capsule,
}

impl ShapeKind {
    pub const ALL: [ShapeKind; 5] = [
        Self::Sphere,
        Self::Ellipsoid,
        Self::Box,
        Self::Cylinder,
        Self::Capsule,
    ];

    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Sphere => "sphere",
            Self::Ellipsoid => "ellipsoid",
            Self::Box => "box",
            Self::Cylinder => "cylinder",
            Self::Capsule => "capsule",
        }
    }
}

/// What is selected in the palette.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PaletteEntry {
    Geometric(ActionKind),
    Force(ForceMode),
}

/// Every tool's settings and the current selection.
#[derive(Clone, Debug, PartialEq)]
pub struct ToolPalette {
    pub selected: PaletteEntry,
    pub shape: ShapeKind,
    /// Sphere, cylinder and capsule radius, field units; box and ellipsoid use `extents_fu`.
    pub radius_fu: f32,
    /// Box half extents and ellipsoid radii, field units.
    pub extents_fu: Vec3,
    /// Cylinder and capsule half height, field units.
    pub half_height_fu: f32,
    pub falloff_fu: f32,
    pub deposit_rate_per_s: f32,
    pub remove_rate_per_s: f32,
    pub paint_rgb: [f32; 3],
    pub paint_rate_per_s: f32,
    pub smooth_rate_per_s: f32,
    pub smooth_kernel_fu: f32,
    pub stamp: StampParams,
    pub contact_alpha: f32,
    /// The force tools' settings (each force entry reads the ones it uses).
    pub force: ForceSettings,
}

/// The settings the force entries share; [`ToolPalette::choice`] makes the engine's tool from
/// them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ForceSettings {
    /// Spread `β` of each force over nearby mass points.
    pub distribution: Distribution,
    /// Spread radius, field units.
    pub radius_fu: f32,
    /// Density force per unit of force integral.
    pub gain: f32,
    /// Penetration depth of the chisel and squirt, field units.
    pub depth_fu: f32,
}

impl Default for ForceSettings {
    fn default() -> Self {
        let push = PushTool::default();
        Self {
            distribution: push.distribution,
            radius_fu: push.radius_fu,
            gain: push.gain,
            depth_fu: 0.1,
        }
    }
}

impl ForceSettings {
    /// The engine's tool for a force entry: the point grab is the contact push felt through
    /// the arm (Hua & Qin's single force vector); the others drive the dynamics with their own
    /// force vectors each step.
    #[must_use]
    pub fn choice(&self, mode: ForceMode) -> ToolChoice {
        let Self {
            distribution,
            radius_fu,
            gain,
            depth_fu,
        } = *self;
        match mode {
            ForceMode::PointGrab => ToolChoice::Push(PushTool {
                distribution,
                radius_fu,
                gain,
            }),
            ForceMode::Area => ForceTool::Area {
                distribution,
                radius_fu,
                tracks: 8,
                gain,
            }
            .into(),
            ForceMode::Chisel => ForceTool::Chisel {
                depth_fu,
                radius_fu,
                gain,
            }
            .into(),
            ForceMode::Squirt => ForceTool::Squirt {
                depth_fu,
                radius_fu,
                gain,
            }
            .into(),
            ForceMode::Pull => ForceTool::Pull {
                distribution,
                radius_fu,
                gain,
            }
            .into(),
        }
    }
}

impl Default for ToolPalette {
    fn default() -> Self {
        Self {
            // The threaded engine applies force tools; start with the one it supports fully.
            selected: PaletteEntry::Force(ForceMode::PointGrab),
            shape: ShapeKind::Sphere,
            radius_fu: 0.1,
            extents_fu: Vec3::new(0.1, 0.06, 0.06),
            half_height_fu: 0.1,
            falloff_fu: 0.05,
            deposit_rate_per_s: 2.0,
            remove_rate_per_s: 2.0,
            paint_rgb: [0.8, 0.2, 0.15],
            paint_rate_per_s: 2.0,
            smooth_rate_per_s: 4.0,
            smooth_kernel_fu: 0.05,
            stamp: StampParams::default(),
            contact_alpha: -0.5,
            force: ForceSettings::default(),
        }
    }
}

/// Label of a palette entry, as shown on its button.
#[must_use]
pub fn entry_label(entry: PaletteEntry) -> &'static str {
    match entry {
        PaletteEntry::Geometric(a) => match a {
            ActionKind::Add => "Add",
            ActionKind::Remove => "Remove",
            ActionKind::SoftRemove => "Soft remove",
            ActionKind::Paint => "Paint",
            ActionKind::SoftPaint => "Soft paint",
            ActionKind::Smooth => "Smooth",
            ActionKind::Stamp => "Stamp",
            ActionKind::Contact => "Contact",
            ActionKind::Union => "Union",
            ActionKind::Intersection => "Intersection",
            ActionKind::Difference => "Difference",
        },
        PaletteEntry::Force(m) => match m {
            ForceMode::PointGrab => "Point grab",
            ForceMode::Area => "Area",
            ForceMode::Chisel => "Chisel",
            ForceMode::Squirt => "Squirt",
            ForceMode::Pull => "Pull",
        },
    }
}

impl ToolPalette {
    /// The tool shape from the current settings.
    #[must_use]
    pub fn tool_shape(&self) -> ToolShape {
        match self.shape {
            ShapeKind::Sphere => ToolShape::Sphere {
                radius_fu: self.radius_fu,
            },
            ShapeKind::Ellipsoid => ToolShape::Ellipsoid {
                radii_fu: self.extents_fu,
            },
            ShapeKind::Box => ToolShape::Box {
                half_extents_fu: self.extents_fu,
            },
            ShapeKind::Cylinder => ToolShape::Cylinder {
                radius_fu: self.radius_fu,
                half_height_fu: self.half_height_fu,
            },
            ShapeKind::Capsule => ToolShape::Capsule {
                radius_fu: self.radius_fu,
                half_height_fu: self.half_height_fu,
            },
        }
    }

    /// The action of a geometric entry with its current parameters.
    #[must_use]
    pub fn action(&self, kind: ActionKind) -> ToolAction {
        match kind {
            ActionKind::Add => ToolAction::Add {
                deposit_rate_per_s: self.deposit_rate_per_s,
            },
            ActionKind::Remove => ToolAction::Remove,
            ActionKind::SoftRemove => ToolAction::SoftRemove {
                rate_per_s: self.remove_rate_per_s,
            },
            ActionKind::Paint => ToolAction::Paint {
                rgb: self.paint_rgb,
            },
            ActionKind::SoftPaint => ToolAction::SoftPaint {
                rgb: self.paint_rgb,
                rate_per_s: self.paint_rate_per_s,
            },
            ActionKind::Smooth => ToolAction::Smooth {
                rate_per_s: self.smooth_rate_per_s,
                kernel_fu: self.smooth_kernel_fu,
            },
            ActionKind::Stamp => ToolAction::Stamp(self.stamp),
            ActionKind::Contact => ToolAction::Contact(ContactParams {
                alpha: self.contact_alpha,
                rate_per_s: crate::tools::DEFAULT_DEFORM_RATE_PER_S,
            }),
            ActionKind::Union => ToolAction::Union,
            ActionKind::Intersection => ToolAction::Intersection,
            ActionKind::Difference => ToolAction::Difference,
        }
    }

    /// The selected tool with its parameters, as sent to the engine.
    #[must_use]
    pub fn choice(&self) -> ToolChoice {
        match self.selected {
            PaletteEntry::Geometric(kind) => ToolChoice::Geometric(GeometricTool {
                shape: self.tool_shape(),
                action: self.action(kind),
                falloff_fu: self.falloff_fu,
            }),
            PaletteEntry::Force(mode) => self.force.choice(mode),
        }
    }

    /// Draws the palette; true when the selection or a parameter changed.
    pub fn ui(&mut self, ui: &mut egui::Ui) -> bool {
        let before = self.clone();
        ui.label("Geometric tools");
        ui.horizontal_wrapped(|ui| {
            for a in ActionKind::ALL {
                let e = PaletteEntry::Geometric(a);
                ui.selectable_value(&mut self.selected, e, entry_label(e));
            }
        });
        ui.label("Force tools");
        ui.horizontal_wrapped(|ui| {
            for m in ForceMode::ALL {
                let e = PaletteEntry::Force(m);
                ui.selectable_value(&mut self.selected, e, entry_label(e));
            }
        });
        ui.separator();
        match self.selected {
            PaletteEntry::Geometric(kind) => self.geometric_ui(ui, kind),
            PaletteEntry::Force(mode) => self.force_ui(ui, mode),
        }
        *self != before
    }

    fn geometric_ui(&mut self, ui: &mut egui::Ui, kind: ActionKind) {
        egui::ComboBox::from_label("Shape")
            .selected_text(self.shape.name())
            .show_ui(ui, |ui| {
                for s in ShapeKind::ALL {
                    ui.selectable_value(&mut self.shape, s, s.name());
                }
            });
        match self.shape {
            ShapeKind::Sphere => {
                ui.add(egui::Slider::new(&mut self.radius_fu, 0.005..=1.0).text("Radius"));
            }
            ShapeKind::Ellipsoid | ShapeKind::Box => {
                for (v, label) in [
                    (&mut self.extents_fu.x, "Half size x"),
                    (&mut self.extents_fu.y, "Half size y"),
                    (&mut self.extents_fu.z, "Half size z"),
                ] {
                    ui.add(egui::Slider::new(v, 0.005..=1.0).text(label));
                }
            }
            ShapeKind::Cylinder | ShapeKind::Capsule => {
                ui.add(egui::Slider::new(&mut self.radius_fu, 0.005..=1.0).text("Radius"));
                ui.add(
                    egui::Slider::new(&mut self.half_height_fu, 0.005..=1.0).text("Half height"),
                );
            }
        }
        ui.add(egui::Slider::new(&mut self.falloff_fu, 0.001..=0.5).text("Falloff"));
        match kind {
            ActionKind::Add => {
                ui.add(
                    egui::Slider::new(&mut self.deposit_rate_per_s, 0.1..=50.0)
                        .logarithmic(true)
                        .text("Deposit rate /s"),
                );
            }
            ActionKind::SoftRemove => {
                ui.add(
                    egui::Slider::new(&mut self.remove_rate_per_s, 0.1..=50.0)
                        .logarithmic(true)
                        .text("Erase rate /s"),
                );
            }
            ActionKind::Paint | ActionKind::SoftPaint => {
                ui.horizontal(|ui| {
                    ui.label("Colour");
                    ui.color_edit_button_rgb(&mut self.paint_rgb);
                });
                if kind == ActionKind::SoftPaint {
                    ui.add(
                        egui::Slider::new(&mut self.paint_rate_per_s, 0.1..=50.0)
                            .logarithmic(true)
                            .text("Paint rate /s"),
                    );
                }
            }
            ActionKind::Smooth => {
                ui.add(
                    egui::Slider::new(&mut self.smooth_rate_per_s, 0.1..=50.0)
                        .logarithmic(true)
                        .text("Smooth rate /s"),
                );
                ui.add(egui::Slider::new(&mut self.smooth_kernel_fu, 0.005..=0.5).text("Kernel"));
            }
            ActionKind::Stamp => {
                let p = &mut self.stamp;
                ui.add(egui::Slider::new(&mut p.s, 0.05..=0.9).text("s (zero crossing)"));
                ui.add(egui::Slider::new(&mut p.m, 0.01..=0.5).text("m (bulge rise)"));
                ui.add(egui::Slider::new(&mut p.r, 0.01..=0.5).text("r (bulge fall)"));
                ui.add(egui::Slider::new(&mut p.k, -6.0..=6.0).text("k (−slope at s)"));
                ui.add(egui::Slider::new(&mut p.n, 0.0..=1.0).text("n (bulge height)"));
                if let Err(e) = p.validate() {
                    ui.colored_label(ui.visuals().warn_fg_color, e.to_string());
                }
            }
            ActionKind::Contact => {
                ui.add(
                    egui::Slider::new(&mut self.contact_alpha, -2.0..=2.0)
                        .text("α (dent < 0 < bulge)"),
                );
            }
            ActionKind::Remove
            | ActionKind::Union
            | ActionKind::Intersection
            | ActionKind::Difference => {}
        }
    }

    fn force_ui(&mut self, ui: &mut egui::Ui, mode: ForceMode) {
        let f = &mut self.force;
        egui::ComboBox::from_label("Distribution")
            .selected_text(distribution_name(f.distribution))
            .show_ui(ui, |ui| {
                for d in DISTRIBUTIONS {
                    ui.selectable_value(&mut f.distribution, d, distribution_name(d));
                }
            });
        ui.add(egui::Slider::new(&mut f.radius_fu, 0.005..=1.0).text("Spread radius"));
        ui.add(
            egui::Slider::new(&mut f.gain, 1.0e3..=1.0e9)
                .logarithmic(true)
                .text("Gain"),
        );
        if matches!(mode, ForceMode::Chisel | ForceMode::Squirt) {
            ui.add(egui::Slider::new(&mut f.depth_fu, 0.001..=0.2).text("Depth"));
        }
    }
}

/// The distributions `β` offered for force tools.
pub const DISTRIBUTIONS: [Distribution; 5] = [
    Distribution::Constant,
    Distribution::Gaussian,
    Distribution::Spherical,
    Distribution::Cylindrical,
    Distribution::Conical,
];

/// Label of a distribution.
#[must_use]
pub fn distribution_name(d: Distribution) -> &'static str {
    match d {
        Distribution::Constant => "constant",
        Distribution::Gaussian => "gaussian",
        Distribution::Spherical => "spherical",
        Distribution::Cylindrical => "cylindrical",
        Distribution::Conical => "conical",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_default_choice_is_a_valid_tool() {
        let mut p = ToolPalette::default();
        for a in ActionKind::ALL {
            for s in ShapeKind::ALL {
                p.selected = PaletteEntry::Geometric(a);
                p.shape = s;
                let ToolChoice::Geometric(t) = p.choice() else {
                    panic!("geometric entry gave a force tool");
                };
                t.validate().unwrap_or_else(|e| panic!("{a:?} {s:?}: {e}"));
            }
        }
        p.selected = PaletteEntry::Force(ForceMode::Chisel);
        assert!(matches!(
            p.choice(),
            ToolChoice::Force {
                tool: ForceTool::Chisel { .. },
                ..
            }
        ));
        p.selected = PaletteEntry::Force(ForceMode::PointGrab);
        assert!(matches!(p.choice(), ToolChoice::Push(_)));
    }

    #[test]
    fn parameters_survive_switching_tools() {
        let mut p = ToolPalette {
            smooth_kernel_fu: 0.123,
            ..ToolPalette::default()
        };
        p.selected = PaletteEntry::Geometric(ActionKind::Smooth);
        p.selected = PaletteEntry::Force(ForceMode::Area);
        p.selected = PaletteEntry::Geometric(ActionKind::Smooth);
        let ToolChoice::Geometric(t) = p.choice() else {
            panic!("expected geometric");
        };
        assert_eq!(
            t.action,
            ToolAction::Smooth {
                rate_per_s: 4.0,
                kernel_fu: 0.123
            }
        );
    }
}
