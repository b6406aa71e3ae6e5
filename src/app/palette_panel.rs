//! The tool palette's panel: the tool buttons and the chosen tool's settings.

use super::command::ForceMode;
use super::force_path_panel::summary_ui;
use super::palette::{
    ActionKind, DISTRIBUTIONS, PaletteEntry, ShapeKind, ToolPalette, distribution_name, entry_label,
};
use crate::tools::ContactParams;

impl ToolPalette {
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
                if self.freeform.is_some() {
                    ui.selectable_value(&mut self.shape, ShapeKind::Freeform, "freeform");
                }
            });
        match self.shape {
            ShapeKind::Sphere => {
                ui.add(egui::Slider::new(&mut self.radius_fu, 0.005..=1.0).text("Radius"));
                super::falloff_curve_panel::falloff_curve_ui(ui, &mut self.falloff_curve);
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
            ShapeKind::Freeform => super::library_panel::freeform_ui(ui, &mut self.freeform),
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
                ui.horizontal_wrapped(|ui| {
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
                ui.add(
                    egui::Slider::new(&mut p.rate_per_s, 0.1..=100.0)
                        .logarithmic(true)
                        .text("Stamps /s"),
                );
                if let Err(e) = p.validate() {
                    ui.colored_label(ui.visuals().warn_fg_color, e.to_string());
                }
            }
            ActionKind::Contact => {
                let max = ContactParams::MAX_ALPHA;
                ui.add(
                    egui::Slider::new(&mut self.contact_alpha, -max..=max)
                        .text("α (dent < 0 < bulge)"),
                );
                ui.add(
                    egui::Slider::new(&mut self.contact_rate_per_s, 0.1..=100.0)
                        .logarithmic(true)
                        .text("Contacts /s"),
                );
            }
            ActionKind::Remove | ActionKind::Union | ActionKind::Difference => {}
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
        if mode == ForceMode::Bend {
            ui.add(egui::Slider::new(&mut f.bend_samples, 1..=64).text("Bend samples"));
        }
        if matches!(mode, ForceMode::Curve | ForceMode::Bend) {
            summary_ui(ui, mode, &self.curve_fu, self.pivot_fu);
        }
    }
}
