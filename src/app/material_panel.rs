//! Material sliders: mass, damping, stiffness and plasticity of the density springs
//! (Hua & Qin eq. 5), with the elastic and plastic presets.

use crate::dynamics::Material;

/// Slider ranges; stiffness and damping span decades, so their sliders are logarithmic.
pub const MASS_RANGE: std::ops::RangeInclusive<f32> = 0.01..=100.0;
pub const DAMPING_RANGE: std::ops::RangeInclusive<f32> = 0.1..=1000.0;
pub const STIFFNESS_RANGE: std::ops::RangeInclusive<f32> = 1.0..=100_000.0;
pub const PLASTICITY_RANGE: std::ops::RangeInclusive<f32> = 0.0..=50.0;
pub const YIELD_RANGE: std::ops::RangeInclusive<f32> = 0.0..=0.5;

/// Draws the sliders for `material`; true when a value changed.
pub fn material_ui(ui: &mut egui::Ui, material: &mut Material) -> bool {
    let before = *material;
    ui.add(
        egui::Slider::new(&mut material.mass, MASS_RANGE)
            .logarithmic(true)
            .text("Mass"),
    );
    ui.add(
        egui::Slider::new(&mut material.damping, DAMPING_RANGE)
            .logarithmic(true)
            .text("Damping"),
    );
    ui.add(
        egui::Slider::new(&mut material.stiffness, STIFFNESS_RANGE)
            .logarithmic(true)
            .text("Stiffness"),
    );
    ui.add(
        egui::Slider::new(&mut material.plasticity_per_s, PLASTICITY_RANGE).text("Plasticity /s"),
    );
    ui.add(egui::Slider::new(&mut material.yield_density, YIELD_RANGE).text("Yield density"));
    ui.horizontal(|ui| {
        if ui.button("Elastic").clicked() {
            *material = Material::ELASTIC;
        }
        if ui.button("Plastic").clicked() {
            *material = Material::PLASTIC;
        }
    });
    *material != before
}
