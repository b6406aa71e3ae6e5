//! The tool library in the window (Ferley §4.1.2, a tool made from the sculpt): a selection —
//! a box or a ball — placed around the last point the brush was on, drawn over the view;
//! **Make tool from selection** captures the clay inside it as a freeform tool, stores it in
//! the session's library (saved with the session) and makes it the palette's shape; the
//! library's tools can be picked again as the freeform shape for stamp, add, remove or any
//! other geometric action.
//!
//! The capture reads the clay the window shows (the engine's latest published field), off the
//! loops; the engine only stores the result.

use glam::Vec3;

use super::command::EngineCommand;
use super::palette::{ActionKind, FreeformChoice, PaletteEntry, ShapeKind, ToolPalette};
use crate::field::MultiPatchField;
use crate::io::ToolPreset;
use crate::tools::{Selection, ToolAction, ToolShape, capture_tool};

/// The selection's shapes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SelectionKind {
    /// An axis-aligned box.
    #[default]
    Box,
    /// A ball.
    Ball,
}

/// The library panel's state.
#[derive(Clone, Debug, PartialEq)]
pub struct LibraryPanel {
    /// The selection's shape.
    pub kind: SelectionKind,
    /// Half the selection's size (the box's half edge, the ball's radius), field units.
    pub half_fu: f32,
    /// The name the next tool is made under.
    pub name: String,
    /// The session's library as the window knows it (tools made here and a loaded session's).
    pub tools: Vec<ToolPreset>,
    /// Whether the selection is drawn over the view.
    pub show_selection: bool,
    /// Tools made so far (for the next default name).
    made: usize,
}

impl Default for LibraryPanel {
    fn default() -> Self {
        Self {
            kind: SelectionKind::Box,
            half_fu: 0.2,
            name: "tool 1".into(),
            tools: Vec::new(),
            show_selection: true,
            made: 0,
        }
    }
}

impl LibraryPanel {
    /// The selection around `at` (the brush point).
    #[must_use]
    pub fn selection(&self, at: Vec3) -> Selection {
        match self.kind {
            SelectionKind::Box => Selection::Box {
                centre: at,
                half_extents_fu: Vec3::splat(self.half_fu),
            },
            SelectionKind::Ball => Selection::Ball {
                centre: at,
                radius_fu: self.half_fu,
            },
        }
    }

    /// Replaces the known library (a loaded session's); the palette's freeform shape follows
    /// its tool of the same name, or goes back to a sphere when there is none.
    pub fn set_tools(&mut self, tools: Vec<ToolPreset>, palette: &mut ToolPalette) {
        self.tools = tools;
        let current = palette.freeform.as_ref().map(|f| f.name.clone());
        palette.freeform = current.and_then(|name| self.choice(&name));
        if palette.freeform.is_none() && palette.shape == ShapeKind::Freeform {
            palette.shape = ShapeKind::Sphere;
        }
    }

    /// The library tool `name` as the palette's freeform choice (`None`: no such freeform
    /// tool).
    fn choice(&self, name: &str) -> Option<FreeformChoice> {
        self.tools
            .iter()
            .find(|t| t.name == name)
            .and_then(|t| match &t.shape {
                ToolShape::Freeform(tool) => Some(FreeformChoice {
                    name: t.name.clone(),
                    tool: tool.clone(),
                }),
                _ => None,
            })
    }

    /// Makes a tool of the clay `field` inside the selection around `at` under the panel's
    /// name, keeps it, and makes it the palette's shape (a force tool in hand gives way to
    /// the stamp). Returns the command that stores it in the engine's library.
    ///
    /// # Errors
    /// Why the capture failed (a selection holding no clay, a bad name), for the log.
    pub fn make_tool(
        &mut self,
        field: &MultiPatchField,
        at: Vec3,
        palette: &mut ToolPalette,
    ) -> Result<EngineCommand, String> {
        let name = self.name.trim().to_owned();
        crate::engine::check_name(&name).map_err(|e| e.to_string())?;
        let tool = capture_tool(field, &self.selection(at)).map_err(|e| e.to_string())?;
        let preset = ToolPreset {
            name: name.clone(),
            shape: ToolShape::Freeform(tool),
            action: ToolAction::Union,
            falloff_fu: palette.falloff_fu,
        };
        crate::engine::store_preset(&mut self.tools, preset.clone());
        self.made += 1;
        self.name = format!("tool {}", self.made + 1);
        self.use_tool(&name, palette);
        Ok(EngineCommand::AddTool(Box::new(preset)))
    }

    /// Makes library tool `name` the palette's shape; true when it is a freeform tool.
    pub fn use_tool(&self, name: &str, palette: &mut ToolPalette) -> bool {
        let Some(choice) = self.choice(name) else {
            return false;
        };
        palette.freeform = Some(choice);
        palette.shape = ShapeKind::Freeform;
        if matches!(palette.selected, PaletteEntry::Force(_)) {
            palette.selected = PaletteEntry::Geometric(ActionKind::Stamp);
        }
        true
    }

    /// Draws the panel. `at` is the last brush point on the clay (where the selection is),
    /// `field` the clay shown. Returns the command to send, and whether the palette changed;
    /// a failure goes to `note`.
    pub fn ui(
        &mut self,
        ui: &mut egui::Ui,
        at: Option<Vec3>,
        field: &MultiPatchField,
        palette: &mut ToolPalette,
        note: &mut Option<String>,
    ) -> (Option<EngineCommand>, bool) {
        let mut command = None;
        let mut changed = false;
        ui.horizontal_wrapped(|ui| {
            ui.label("Selection");
            ui.radio_value(&mut self.kind, SelectionKind::Box, "Box");
            ui.radio_value(&mut self.kind, SelectionKind::Ball, "Ball");
        });
        ui.add(egui::Slider::new(&mut self.half_fu, 0.02..=1.0).text("Selection half size"));
        ui.checkbox(&mut self.show_selection, "Show the selection");
        match at {
            Some(p) => ui.weak(format!(
                "{} of half size {:.3} around the brush point ({:.3}, {:.3}, {:.3})",
                match self.kind {
                    SelectionKind::Box => "box",
                    SelectionKind::Ball => "ball",
                },
                self.half_fu,
                p.x,
                p.y,
                p.z
            )),
            None => ui.weak("move the pointer over the clay to place the selection"),
        };
        ui.horizontal_wrapped(|ui| {
            let label = ui.label("Name");
            ui.add(egui::TextEdit::singleline(&mut self.name).desired_width(120.0))
                .labelled_by(label.id);
        });
        let make = ui
            .add_enabled(at.is_some(), egui::Button::new("Make tool from selection"))
            .on_hover_text(
                "Capture the clay inside the selection as a freeform tool, keep it in the \
                 session's library and use it as the tool's shape",
            );
        if make.clicked()
            && let Some(p) = at
        {
            match self.make_tool(field, p, palette) {
                Ok(c) => {
                    command = Some(c);
                    changed = true;
                }
                Err(e) => *note = Some(format!("make tool: {e}")),
            }
        }
        let mut picked = None;
        for t in &self.tools {
            ui.horizontal_wrapped(|ui| {
                let used = palette.shape == ShapeKind::Freeform
                    && palette.freeform.as_ref().is_some_and(|f| f.name == t.name);
                ui.label(if used {
                    format!("* {}", t.name)
                } else {
                    t.name.clone()
                });
                if ui
                    .add_enabled(!used, egui::Button::new(format!("Use {}", t.name)))
                    .clicked()
                {
                    picked = Some(t.name.clone());
                }
            });
        }
        if let Some(name) = picked {
            changed |= self.use_tool(&name, palette);
        }
        (command, changed)
    }

    /// The selection's outline around `at` as world segments: a box's twelve edges, or three
    /// great circles of a ball (24 segments each).
    #[must_use]
    pub fn outline(&self, at: Vec3) -> Vec<(Vec3, Vec3)> {
        let h = self.half_fu;
        match self.kind {
            SelectionKind::Box => {
                let corner = |i: u32| {
                    at + Vec3::new(
                        if i & 1 == 0 { -h } else { h },
                        if i & 2 == 0 { -h } else { h },
                        if i & 4 == 0 { -h } else { h },
                    )
                };
                let mut edges = Vec::with_capacity(12);
                for i in 0..8u32 {
                    for bit in [1, 2, 4] {
                        if i & bit == 0 {
                            edges.push((corner(i), corner(i | bit)));
                        }
                    }
                }
                edges
            }
            SelectionKind::Ball => {
                let n = 24;
                let mut edges = Vec::with_capacity(3 * n);
                for (u, v) in [(Vec3::X, Vec3::Y), (Vec3::Y, Vec3::Z), (Vec3::Z, Vec3::X)] {
                    let point = |k: usize| {
                        let a = std::f32::consts::TAU * k as f32 / n as f32;
                        at + h * (a.cos() * u + a.sin() * v)
                    };
                    edges.extend((0..n).map(|k| (point(k), point(k + 1))));
                }
                edges
            }
        }
    }
}

/// The freeform shape's settings in the palette: which library tool, and its scale.
pub fn freeform_ui(ui: &mut egui::Ui, freeform: &mut Option<FreeformChoice>) {
    match freeform {
        Some(f) => {
            ui.label(format!("Library tool: {}", f.name));
            for (v, label) in [
                (&mut f.tool.scale.x, "Scale x"),
                (&mut f.tool.scale.y, "Scale y"),
                (&mut f.tool.scale.z, "Scale z"),
            ] {
                ui.add(
                    egui::Slider::new(v, 0.1..=4.0)
                        .logarithmic(true)
                        .text(label),
                );
            }
        }
        None => {
            ui.weak("No library tool yet: make one in the Tool library section.");
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::ToolChoice;
    use crate::field::{Primitive, lattice_from_primitive};

    #[test]
    fn a_made_tool_becomes_the_palettes_freeform_shape_and_its_library_entry() {
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
        let mut panel = LibraryPanel::default();
        let mut palette = ToolPalette::default();
        let command = panel
            .make_tool(&field, Vec3::splat(0.95), &mut palette)
            .unwrap();
        let EngineCommand::AddTool(preset) = command else {
            panic!("expected AddTool, got {command:?}");
        };
        assert_eq!(preset.name, "tool 1");
        assert_eq!(panel.name, "tool 2");
        assert_eq!(panel.tools.len(), 1);
        assert_eq!(palette.shape, ShapeKind::Freeform);
        // The point grab in hand gives way to the stamp, with the captured shape.
        let ToolChoice::Geometric(tool) = palette.choice() else {
            panic!("expected a geometric tool");
        };
        assert!(matches!(tool.action, ToolAction::Stamp(_)));
        assert_eq!(tool.shape, preset.shape);
        tool.validate().unwrap();
        // A selection beside the clay holds nothing: refused, nothing kept.
        let err = panel
            .make_tool(&field, Vec3::splat(0.2), &mut palette)
            .unwrap_err();
        assert!(err.contains("holds no clay"), "{err}");
        assert_eq!(panel.tools.len(), 1);
        // A loaded library without the tool puts the palette back on a sphere.
        panel.set_tools(Vec::new(), &mut palette);
        assert_eq!(palette.shape, ShapeKind::Sphere);
        assert!(palette.freeform.is_none());
        assert_eq!(panel.outline(Vec3::ZERO).len(), 12);
        panel.kind = SelectionKind::Ball;
        assert_eq!(panel.outline(Vec3::ZERO).len(), 72);
    }
}
