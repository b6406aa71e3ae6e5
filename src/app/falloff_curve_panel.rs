//! The falloff curve in the tool settings: a menu of the presets and a custom curve, and a
//! preview of the brush's profile (its depth from centre to edge) whose custom control points
//! are dragged to edit it.

use crate::tools::{FalloffCurve, MAX_FALLOFF_POINTS};

/// Preview size, points (fixed, so the settings below do not move with the curve).
const PREVIEW_SIZE: egui::Vec2 = egui::vec2(200.0, 80.0);
/// Samples of the preview's line.
const PREVIEW_SAMPLES: usize = 64;
/// Radius of a custom control point's handle, points.
const HANDLE_RADIUS: f32 = 5.0;

/// Draws the curve menu and the preview; true when the curve changed.
pub fn falloff_curve_ui(ui: &mut egui::Ui, curve: &mut FalloffCurve) -> bool {
    let before = curve.clone();
    egui::ComboBox::from_label("Falloff curve")
        .selected_text(curve.name())
        .show_ui(ui, |ui| {
            for preset in FalloffCurve::PRESETS {
                let name = preset.name();
                ui.selectable_value(curve, preset, name);
            }
            if !matches!(curve, FalloffCurve::Custom(_)) {
                let start = FalloffCurve::default_custom();
                ui.selectable_value(curve, start, "custom");
            } else {
                ui.label("custom (drag the points)");
            }
        })
        .response
        .on_hover_text(
            "The brush's depth from its centre (left) to its edge (right); the brush faces the \
             clay where a stroke begins",
        );
    preview_ui(ui, curve);
    if let FalloffCurve::Custom(points) = curve {
        ui.horizontal(|ui| {
            if ui
                .add_enabled(
                    points.len() < MAX_FALLOFF_POINTS,
                    egui::Button::new("Add point"),
                )
                .clicked()
            {
                split_widest_span(points);
            }
            if ui
                .add_enabled(points.len() > 2, egui::Button::new("Remove point"))
                .clicked()
            {
                points.remove(points.len() / 2);
            }
        });
    }
    *curve != before
}

/// The profile's preview; a custom curve's points are dragged within it (the end points
/// move only up and down, the inner ones between their neighbours).
fn preview_ui(ui: &mut egui::Ui, curve: &mut FalloffCurve) {
    let (rect, _) = ui.allocate_exact_size(PREVIEW_SIZE, egui::Sense::hover());
    let to_screen = |u: f32, depth: f32| {
        egui::pos2(
            rect.min.x + u * rect.width(),
            rect.max.y - depth * rect.height(),
        )
    };
    if let FalloffCurve::Custom(points) = curve {
        let last = points.len() - 1;
        for i in 0..points.len() {
            let [u, depth] = points[i];
            let centre = to_screen(u, depth);
            let handle =
                egui::Rect::from_center_size(centre, egui::Vec2::splat(4.0 * HANDLE_RADIUS));
            let response = ui.interact(
                handle,
                ui.make_persistent_id(("falloff point", i)),
                egui::Sense::drag(),
            );
            if response.dragged() {
                let delta = response.drag_delta();
                let new_depth = (depth - delta.y / rect.height()).clamp(0.0, 1.0);
                let new_u = if i == 0 || i == last {
                    u
                } else {
                    let room = 1e-3;
                    (u + delta.x / rect.width())
                        .clamp(points[i - 1][0] + room, points[i + 1][0] - room)
                };
                points[i] = [new_u, new_depth];
            }
        }
    }
    let painter = ui.painter_at(rect);
    let visuals = ui.visuals();
    painter.rect_filled(rect, 2.0, visuals.extreme_bg_color);
    let line: Vec<egui::Pos2> = (0..=PREVIEW_SAMPLES)
        .map(|i| {
            let u = i as f32 / PREVIEW_SAMPLES as f32;
            to_screen(u, curve.value(u))
        })
        .collect();
    painter.add(egui::Shape::line(
        line,
        egui::Stroke::new(2.0, visuals.selection.bg_fill),
    ));
    if let FalloffCurve::Custom(points) = curve {
        for &[u, depth] in points.iter() {
            painter.circle_filled(to_screen(u, depth), HANDLE_RADIUS, visuals.text_color());
        }
    }
}

/// Adds a point in the middle of the widest span of a custom curve, on its line.
fn split_widest_span(points: &mut Vec<[f32; 2]>) {
    let Some(i) = (1..points.len()).max_by(|&a, &b| {
        let wa = points[a][0] - points[a - 1][0];
        let wb = points[b][0] - points[b - 1][0];
        wa.total_cmp(&wb)
    }) else {
        return;
    };
    let ([u0, c0], [u1, c1]) = (points[i - 1], points[i]);
    points.insert(i, [0.5 * (u0 + u1), 0.5 * (c0 + c1)]);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn adding_a_point_splits_the_widest_span_on_the_line_and_keeps_the_curve_valid() {
        let mut points = vec![[0.0, 1.0], [0.2, 0.9], [1.0, 0.1]];
        split_widest_span(&mut points);
        assert_eq!(points, vec![[0.0, 1.0], [0.2, 0.9], [0.6, 0.5], [1.0, 0.1]]);
        let curve = FalloffCurve::Custom(points);
        curve.validate().unwrap();
        assert!((curve.value(0.6) - 0.5).abs() < 1e-6);
    }
}
