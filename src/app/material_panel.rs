//! Material sliders: mass, damping, stiffness and plasticity of the density springs
//! (Hua & Qin eq. 5), the springs' neighbourhood (6, 18 or 26), the elastic and plastic
//! presets, and the material brush that paints mass, damping, stiffness or plasticity onto
//! the clay (Hua & Qin's material distributions).

use glam::Vec3;

use super::command::EngineCommand;
use crate::dynamics::{Material, MaterialPaint, Neighbourhood, PaintRegion};

/// Slider ranges; stiffness and damping span decades, so their sliders are logarithmic.
pub const MASS_RANGE: std::ops::RangeInclusive<f32> = 0.01..=100.0;
pub const DAMPING_RANGE: std::ops::RangeInclusive<f32> = 0.1..=1000.0;
pub const STIFFNESS_RANGE: std::ops::RangeInclusive<f32> = 1.0..=100_000.0;
pub const PLASTICITY_RANGE: std::ops::RangeInclusive<f32> = 0.0..=50.0;
pub const YIELD_RANGE: std::ops::RangeInclusive<f32> = 0.0..=0.5;
/// Radii the material brush offers, field units.
pub const PAINT_RADIUS_RANGE: std::ops::RangeInclusive<f32> = 0.02..=2.0;

/// The label of a neighbourhood in the selector.
fn neighbourhood_label(nb: Neighbourhood) -> &'static str {
    match nb {
        Neighbourhood::Six => "6 neighbours",
        Neighbourhood::Eighteen => "18 neighbours",
        Neighbourhood::TwentySix => "26 neighbours",
    }
}

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
    ui.horizontal_wrapped(|ui| {
        // Toggles: the preset the sliders match shows selected (neither after a slider moved).
        for (preset, label) in [
            (Material::ELASTIC, "Elastic"),
            (Material::PLASTIC, "Plastic"),
        ] {
            let preset = Material {
                neighbourhood: material.neighbourhood,
                ..preset
            };
            if ui.selectable_label(*material == preset, label).clicked() {
                *material = preset;
            }
        }
        egui::ComboBox::from_label("Springs")
            .selected_text(neighbourhood_label(material.neighbourhood))
            .show_ui(ui, |ui| {
                for nb in Neighbourhood::ALL {
                    ui.selectable_value(&mut material.neighbourhood, nb, neighbourhood_label(nb));
                }
            })
            .response
            .on_hover_text(
                "Which neighbours each density spring joins. The stiffness is normalised, so a \
                 broad push meets the same material (new strokes)",
            );
    });
    *material != before
}

/// The material brush: while it is on, a left drag that starts on the clay paints the chosen
/// values (those ticked) into a ball of `radius_fu` around each surface point it passes,
/// instead of sculpting; "Paint here" paints once around the last point the brush was on.
#[derive(Clone, Debug, PartialEq)]
pub struct MaterialBrush {
    /// Whether a left drag paints material (instead of sculpting).
    pub active: bool,
    /// Radius of the painted ball, field units.
    pub radius_fu: f32,
    /// Mass painted, when `Some`.
    pub mass: Option<f32>,
    /// Damping painted, when `Some`.
    pub damping: Option<f32>,
    /// Stiffness painted, when `Some`.
    pub stiffness: Option<f32>,
    /// Plastic drift rate painted (per second), when `Some`: 0 keeps a spot springy in
    /// plastic clay, a rate above 0 lets a spot of elastic clay keep its dents.
    pub plasticity_per_s: Option<f32>,
    /// Where the drag last painted (`None` between drags).
    last: Option<Vec3>,
}

impl Default for MaterialBrush {
    /// Off; paints a stiffness five times the default material's in a ball of 0.2.
    fn default() -> Self {
        Self {
            active: false,
            radius_fu: 0.2,
            mass: None,
            damping: None,
            stiffness: Some(5.0 * Material::PLASTIC.stiffness),
            plasticity_per_s: None,
            last: None,
        }
    }
}

impl MaterialBrush {
    /// The paint of a ball around `at`, if a value is ticked.
    #[must_use]
    pub fn paint_at(&self, at: Vec3) -> Option<MaterialPaint> {
        let paint = MaterialPaint {
            region: PaintRegion::Sphere {
                centre: at,
                radius_fu: self.radius_fu,
            },
            mass: self.mass,
            damping: self.damping,
            stiffness: self.stiffness,
            plasticity_per_s: self.plasticity_per_s,
        };
        paint.validate().is_ok().then_some(paint)
    }

    /// One frame of a drag: `hit` is the clay's surface under the pointer, `held` whether the
    /// drag is held. Paints where the drag starts and then every quarter radius along it.
    pub fn pointer(&mut self, hit: Option<Vec3>, held: bool) -> Option<MaterialPaint> {
        if !held {
            self.last = None;
            return None;
        }
        let at = hit?;
        if self
            .last
            .is_some_and(|last| last.distance(at) < 0.25 * self.radius_fu)
        {
            return None;
        }
        self.last = Some(at);
        self.paint_at(at)
    }

    /// Whether a drag is painting.
    #[must_use]
    pub fn painting(&self) -> bool {
        self.last.is_some()
    }

    /// Draws the brush's section (closed at first); `here` is the last surface point the
    /// brush was on. Returns a command when a button asks for one.
    pub fn ui(&mut self, ui: &mut egui::Ui, here: Option<Vec3>) -> Option<EngineCommand> {
        egui::CollapsingHeader::new("Paint material")
            .default_open(false)
            .show(ui, |ui| self.controls(ui, here))
            .body_returned
            .flatten()
    }

    /// The brush's controls, inside its section.
    fn controls(&mut self, ui: &mut egui::Ui, here: Option<Vec3>) -> Option<EngineCommand> {
        let mut command = None;
        ui.checkbox(&mut self.active, "Paint material with the brush")
            .on_hover_text(
                "A left drag on the clay paints the ticked values instead of sculpting; the \
                 simulation uses them where they are painted",
            );
        ui.add(
            egui::Slider::new(&mut self.radius_fu, PAINT_RADIUS_RANGE)
                .logarithmic(true)
                .text("Paint radius"),
        );
        let defaults = Material::PLASTIC;
        type Row<'a> = (
            &'a str,
            &'a str,
            &'a mut Option<f32>,
            f32,
            std::ops::RangeInclusive<f32>,
        );
        let rows: [Row<'_>; 4] = [
            (
                "Paint mass",
                "mass",
                &mut self.mass,
                defaults.mass,
                MASS_RANGE,
            ),
            (
                "Paint damping",
                "damping",
                &mut self.damping,
                defaults.damping,
                DAMPING_RANGE,
            ),
            (
                "Paint stiffness",
                "stiffness",
                &mut self.stiffness,
                defaults.stiffness,
                STIFFNESS_RANGE,
            ),
            (
                "Paint plasticity",
                "plasticity /s",
                &mut self.plasticity_per_s,
                // Ticked, it first paints a springy spot (no drift) into the plastic clay.
                0.0,
                PLASTICITY_RANGE,
            ),
        ];
        for (label, unit, value, default, range) in rows {
            ui.horizontal_wrapped(|ui| {
                let mut on = value.is_some();
                if ui.checkbox(&mut on, label).changed() {
                    *value = on.then_some(default);
                }
                let mut v = value.unwrap_or(default);
                let slider = ui.add_enabled(
                    on,
                    egui::Slider::new(&mut v, range)
                        .logarithmic(true)
                        .text(unit),
                );
                if slider.changed() && on {
                    *value = Some(v);
                }
            });
        }
        ui.horizontal_wrapped(|ui| {
            let paint = here.and_then(|at| self.paint_at(at));
            if ui
                .add_enabled(paint.is_some(), egui::Button::new("Paint here"))
                .on_hover_text("Paint the ticked values around the last point the brush was on")
                .clicked()
                && let Some(paint) = paint
            {
                command = Some(EngineCommand::PaintMaterial(paint));
            }
            if ui
                .button("Clear painted material")
                .on_hover_text("The uniform material applies everywhere again")
                .clicked()
            {
                command = Some(EngineCommand::ClearMaterialPaint);
            }
        });
        command
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_drag_paints_where_it_starts_and_every_quarter_radius() {
        let mut brush = MaterialBrush::default();
        let at = Vec3::new(1.0, 1.0, 1.0);
        assert!(brush.pointer(Some(at), false).is_none(), "not held");
        let first = brush.pointer(Some(at), true).unwrap();
        assert_eq!(
            first.region,
            PaintRegion::Sphere {
                centre: at,
                radius_fu: 0.2
            }
        );
        assert_eq!(first.stiffness, Some(5.0 * Material::PLASTIC.stiffness));
        assert!(brush.painting());
        // Less than a quarter radius on: nothing; more: a paint there.
        assert!(brush.pointer(Some(at + Vec3::X * 0.04), true).is_none());
        assert!(brush.pointer(Some(at + Vec3::X * 0.06), true).is_some());
        assert!(brush.pointer(None, true).is_none(), "off the clay");
        assert!(brush.pointer(None, false).is_none());
        assert!(!brush.painting(), "released");
        // Nothing ticked: nothing to paint.
        brush.stiffness = None;
        assert!(brush.pointer(Some(at), true).is_none());
    }
}
