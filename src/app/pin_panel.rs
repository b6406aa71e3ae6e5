//! Pinning with the mouse (Hua & Qin §7.3, Fig. 13): with pin mode on, a click on the clay
//! pins a point there, Ctrl+click pins the normal there (with its point), and a drag across
//! the clay pins the curve it traced; the panel lists the clay's pins, each with a delete
//! button. The gestures become [`EngineCommand`]s; the engine answers with what it pinned.

use glam::Vec3;

use super::command::EngineCommand;
use crate::tools::PinRequest;

/// A drag whose traced points stay within this many knot spans of where it began is a click.
pub const CLICK_SPANS: f32 = 0.5;
/// Consecutive points of a traced curve are at least this many knot spans apart.
pub const CURVE_STEP_SPANS: f32 = 0.25;
/// Most points a traced curve keeps (later points extend the last segment).
pub const MAX_TRACED_POINTS: usize = 512;

/// Pin mode and the gesture in progress.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PinPanel {
    /// Whether left clicks and drags on the clay pin (instead of sculpting).
    pub active: bool,
    /// Surface points of the drag in progress (empty when none).
    traced: Vec<Vec3>,
    /// Whether Ctrl was held when the gesture began.
    normal: bool,
}

impl PinPanel {
    /// Whether a pin gesture is in progress (the camera should not orbit meanwhile).
    #[must_use]
    pub fn tracing(&self) -> bool {
        !self.traced.is_empty()
    }

    /// Feeds one frame of the pointer: `hit` is the clay point under it (if any), `down`
    /// whether the left button is held, `ctrl` whether Ctrl was held when it went down,
    /// `spacing` the clay's knot spacing. Returns the pin to make when a gesture ends.
    pub fn pointer(
        &mut self,
        hit: Option<Vec3>,
        down: bool,
        ctrl: bool,
        spacing: f32,
    ) -> Option<EngineCommand> {
        if !self.active {
            self.traced.clear();
            return None;
        }
        if down {
            match (self.traced.last(), hit) {
                (None, Some(p)) => {
                    self.traced.push(p);
                    self.normal = ctrl;
                }
                (Some(&last), Some(p)) if (p - last).length() >= CURVE_STEP_SPANS * spacing => {
                    if self.traced.len() < MAX_TRACED_POINTS {
                        self.traced.push(p);
                    } else if let Some(end) = self.traced.last_mut() {
                        *end = p;
                    }
                }
                _ => {}
            }
            return None;
        }
        let traced = std::mem::take(&mut self.traced);
        let first = *traced.first()?;
        let reach = traced
            .iter()
            .map(|p| (*p - first).length())
            .fold(0.0, f32::max);
        let request = if reach < CLICK_SPANS * spacing {
            if self.normal {
                PinRequest::Normal(first)
            } else {
                PinRequest::Point(first)
            }
        } else {
            PinRequest::Curve(traced)
        };
        Some(EngineCommand::Pin(request))
    }

    /// The panel: the mode switch, the gestures, and the list of `pins` with a delete button
    /// each, in an area `list_height_pt` high that scrolls (so pins never move what is below
    /// it); a line too long for the panel is cut short, whole on hover. Returns the command a
    /// button asked for.
    pub fn ui(
        &mut self,
        ui: &mut egui::Ui,
        pins: &[String],
        list_height_pt: f32,
    ) -> Option<EngineCommand> {
        ui.checkbox(&mut self.active, "Pin with the mouse");
        ui.label("Click: point; Ctrl+click: normal; drag: curve");
        let mut command = None;
        ui.horizontal_wrapped(|ui| {
            ui.label(format!("{} pins", pins.len()));
            if ui
                .add_enabled(!pins.is_empty(), egui::Button::new("Remove all pins"))
                .clicked()
            {
                command = Some(EngineCommand::Unpin { index: None });
            }
        });
        egui::ScrollArea::both()
            .id_salt("dynaclay pin list")
            .min_scrolled_height(list_height_pt)
            .max_height(list_height_pt)
            .auto_shrink([false, false])
            .show(ui, |ui| {
                for (i, line) in pins.iter().enumerate() {
                    ui.horizontal(|ui| {
                        if ui
                            .small_button("Delete")
                            .on_hover_text("Remove this pin")
                            .clicked()
                        {
                            command = Some(EngineCommand::Unpin { index: Some(i) });
                        }
                        // Cut short, it shows whole on hover.
                        ui.add(egui::Label::new(line).truncate());
                    });
                }
            });
        command
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const H: f32 = 0.1;

    fn gesture(panel: &mut PinPanel, points: &[Vec3], ctrl: bool) -> Option<EngineCommand> {
        for &p in points {
            assert!(panel.pointer(Some(p), true, ctrl, H).is_none());
        }
        panel.pointer(None, false, false, H)
    }

    #[test]
    fn a_click_pins_a_point_ctrl_click_a_normal_and_a_drag_a_curve() {
        let mut panel = PinPanel {
            active: true,
            ..PinPanel::default()
        };
        let p = Vec3::new(1.0, 2.0, 3.0);
        // A little jitter is still a click.
        let click = [p, p + Vec3::X * 0.01, p + Vec3::Y * 0.02];
        assert_eq!(
            gesture(&mut panel, &click, false),
            Some(EngineCommand::Pin(PinRequest::Point(p)))
        );
        assert_eq!(
            gesture(&mut panel, &click, true),
            Some(EngineCommand::Pin(PinRequest::Normal(p)))
        );
        let drag: Vec<Vec3> = (0..=20).map(|i| p + Vec3::X * (0.01 * i as f32)).collect();
        let Some(EngineCommand::Pin(PinRequest::Curve(points))) = gesture(&mut panel, &drag, false)
        else {
            panic!("a drag pins a curve");
        };
        // Points kept a quarter span (0.025) apart: 0.0, 0.03, 0.06, …, 0.18.
        assert_eq!(points.first(), Some(&p));
        assert_eq!(points.len(), 7, "{points:?}");
        assert!(!panel.tracing());
    }

    #[test]
    fn nothing_is_pinned_off_the_clay_or_with_pin_mode_off() {
        let mut panel = PinPanel::default();
        assert_eq!(gesture(&mut panel, &[Vec3::ONE], false), None);
        panel.active = true;
        assert!(panel.pointer(None, true, false, H).is_none());
        assert_eq!(panel.pointer(None, false, false, H), None);
        // A drag that starts off the clay begins where it first meets it.
        assert!(panel.pointer(None, true, false, H).is_none());
        assert!(panel.pointer(Some(Vec3::ONE), true, false, H).is_none());
        assert!(panel.tracing());
        assert_eq!(
            panel.pointer(None, false, false, H),
            Some(EngineCommand::Pin(PinRequest::Point(Vec3::ONE)))
        );
    }

    #[test]
    fn a_long_drag_keeps_a_bounded_number_of_points() {
        let mut panel = PinPanel {
            active: true,
            ..PinPanel::default()
        };
        let drag: Vec<Vec3> = (0..2000).map(|i| Vec3::X * (0.05 * i as f32)).collect();
        let Some(EngineCommand::Pin(PinRequest::Curve(points))) = gesture(&mut panel, &drag, false)
        else {
            panic!("a drag pins a curve");
        };
        assert_eq!(points.len(), MAX_TRACED_POINTS);
        assert_eq!(points.last(), drag.last());
    }
}
