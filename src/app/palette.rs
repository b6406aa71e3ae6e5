//! The tool palette: which tool is in the hand and each tool's parameters.
//!
//! The palette keeps every tool's settings, so switching tools and back restores them; the app
//! sends [`ToolPalette::choice`] to the engine whenever the selection or a parameter changes.

use glam::Vec3;

use super::command::ForceMode;
use crate::dynamics::Distribution;
use crate::engine::{PushTool, ToolChoice};
use crate::tools::{
    ContactParams, FalloffCurve, ForceTool, GeometricTool, StampParams, ToolAction, ToolShape,
};

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
    Difference,
}

impl ActionKind {
    /// Every brush. Intersection is not one: it is CSG with another clay (the window's
    /// "CSG with a session"), since as a brush it would delete the whole clay outside the tool.
    pub const ALL: [ActionKind; 10] = [
        Self::Add,
        Self::Remove,
        Self::SoftRemove,
        Self::Paint,
        Self::SoftPaint,
        Self::Smooth,
        Self::Stamp,
        Self::Contact,
        Self::Union,
        Self::Difference,
    ];
}

/// The tool shapes offered: the analytic ones, and a freeform tool made from the sculpt (see
/// [`super::LibraryPanel`]), offered once the library holds one.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ShapeKind {
    Sphere,
    Ellipsoid,
    Box,
    Cylinder,
    Capsule,
    Freeform,
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
            Self::Freeform => "freeform",
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
    /// The sphere brush's profile from centre to edge (the sphere curve: the sphere itself).
    pub falloff_curve: FalloffCurve,
    pub deposit_rate_per_s: f32,
    pub remove_rate_per_s: f32,
    pub paint_rgb: [f32; 3],
    pub paint_rate_per_s: f32,
    pub smooth_rate_per_s: f32,
    pub smooth_kernel_fu: f32,
    pub stamp: StampParams,
    pub contact_alpha: f32,
    /// Whole contact applications per second of dwell.
    pub contact_rate_per_s: f32,
    /// The force tools' settings (each force entry reads the ones it uses).
    pub force: ForceSettings,
    /// The library tool the freeform shape uses (`None` until one is made or chosen).
    pub freeform: Option<FreeformChoice>,
    /// The curve tool's user curve, field coordinates (see [`super::ForcePathPanel`]).
    pub curve_fu: Vec<Vec3>,
    /// The bend's pivot, field coordinates (`None` until one is picked).
    pub pivot_fu: Option<Vec3>,
}

/// The library tool in the palette's freeform shape: its name and shape (its scale included).
#[derive(Clone, Debug, PartialEq)]
pub struct FreeformChoice {
    /// The library tool's name.
    pub name: String,
    /// Its shape.
    pub tool: crate::tools::FreeformTool,
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
    /// Samples along the bend's arm (pivot to grab).
    pub bend_samples: u32,
}

impl Default for ForceSettings {
    fn default() -> Self {
        let push = PushTool::default();
        Self {
            distribution: push.distribution,
            radius_fu: push.radius_fu,
            gain: push.gain,
            depth_fu: 0.1,
            bend_samples: 12,
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
            bend_samples,
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
            ForceMode::Curve => ForceTool::Curve { radius_fu, gain }.into(),
            ForceMode::Bend => ForceTool::Bend {
                samples: bend_samples,
                radius_fu,
                gain,
            }
            .into(),
        }
    }
}

/// The stamp's default: Ferley's shape (Fig. 12) with a low bulge (`n` 0.15) whose fall runs
/// out to the edge of the falloff band (`s + m + r = 1`), printed five times a second, so a
/// stroke leaves the tool's print and a low, smooth rim beside it (a stamp printed a hundred
/// times a second heaps its bulges into a wall, and a bulge cut short at the band rings in the
/// refit).
pub const DEFAULT_STAMP: StampParams = StampParams {
    s: 0.5,
    m: 0.2,
    r: 0.3,
    k: -2.0,
    n: 0.15,
    rate_per_s: 5.0,
};

/// The contact tool's default strength: a dent with a rim.
pub const DEFAULT_CONTACT_ALPHA: f32 = -1.0;

/// The contact tool's default rate, whole applications per second of dwell: enough that a
/// one-second stroke dents to the tool's surface, few enough that the rim stays low.
pub const DEFAULT_CONTACT_RATE_PER_S: f32 = 5.0;

impl Default for ToolPalette {
    /// Defaults that visibly work in the window (`tests/palette_defaults.rs` walks them on the
    /// default block): the pointer presses the tip 1.5 knot spans into the clay, so a brush of
    /// radius 0.25 (2.5 spans) reaches a knot span above the surface to add and 4 spans down
    /// to carve, and a falloff of two knot spans (a band four spans wide, as the starting clay
    /// is fitted) is smooth enough for the local refit to follow without ringing.
    fn default() -> Self {
        Self {
            // The threaded engine applies force tools; start with the one it supports fully.
            selected: PaletteEntry::Force(ForceMode::PointGrab),
            shape: ShapeKind::Sphere,
            radius_fu: 0.25,
            extents_fu: Vec3::new(0.25, 0.15, 0.15),
            half_height_fu: 0.25,
            falloff_fu: 0.2,
            falloff_curve: FalloffCurve::Sphere,
            deposit_rate_per_s: 8.0,
            remove_rate_per_s: 8.0,
            paint_rgb: [0.8, 0.2, 0.15],
            paint_rate_per_s: 8.0,
            smooth_rate_per_s: 10.0,
            smooth_kernel_fu: 0.15,
            stamp: DEFAULT_STAMP,
            contact_alpha: DEFAULT_CONTACT_ALPHA,
            contact_rate_per_s: DEFAULT_CONTACT_RATE_PER_S,
            force: ForceSettings::default(),
            freeform: None,
            curve_fu: Vec::new(),
            pivot_fu: None,
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
            ActionKind::Difference => "Difference",
        },
        PaletteEntry::Force(m) => match m {
            ForceMode::PointGrab => "Point grab",
            ForceMode::Area => "Area",
            ForceMode::Chisel => "Chisel",
            ForceMode::Squirt => "Squirt",
            ForceMode::Pull => "Pull",
            ForceMode::Curve => "Curve",
            ForceMode::Bend => "Bend",
        },
    }
}

impl ToolPalette {
    /// The tool shape from the current settings.
    #[must_use]
    pub fn tool_shape(&self) -> ToolShape {
        match self.shape {
            ShapeKind::Sphere => ToolShape::round(self.radius_fu, self.falloff_curve.clone()),
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
            // Without a library tool the freeform entry is not offered; a sphere stands in.
            ShapeKind::Freeform => match &self.freeform {
                Some(f) => ToolShape::Freeform(f.tool.clone()),
                None => ToolShape::Sphere {
                    radius_fu: self.radius_fu,
                },
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
                rate_per_s: self.contact_rate_per_s,
            }),
            ActionKind::Union => ToolAction::Union,
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
            PaletteEntry::Force(mode) => {
                let mut choice = self.force.choice(mode);
                if let ToolChoice::Force { curve, pivot, .. } = &mut choice {
                    match mode {
                        ForceMode::Curve => curve.clone_from(&self.curve_fu),
                        // Without a picked pivot the bend turns about the clay's origin.
                        ForceMode::Bend => *pivot = self.pivot_fu.unwrap_or(Vec3::ZERO),
                        _ => {}
                    }
                }
                choice
            }
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
                rate_per_s: ToolPalette::default().smooth_rate_per_s,
                kernel_fu: 0.123
            }
        );
    }
}
