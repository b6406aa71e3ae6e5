//! The curve and the pivot of the curve and bend force tools (Hua & Qin §7.2) in the window:
//! the curve is the path of the last stroke dragged on the clay, or points clicked on it one
//! by one; the pivot is a point clicked on the clay. While a pick is armed, left clicks on the
//! clay pick instead of sculpting (a click beside the clay still orbits). The curve and the
//! pivot are drawn over the view while the curve or bend tool is in hand.

use glam::Vec3;

use super::command::ForceMode;
use super::palette::{PaletteEntry, ToolPalette};

/// Most points a curve keeps: as many as a stroke carries to the haptic loop.
pub const MAX_CURVE_POINTS: usize = crate::haptics::MAX_STROKE_POINTS;
/// Consecutive points of a recorded stroke path are at least this many knot spans apart.
pub const PATH_STEP_SPANS: f32 = 0.25;

/// What a left click on the clay does while a pick is armed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PathPick {
    /// Nothing armed: clicks sculpt.
    #[default]
    Off,
    /// Each click adds a point to the curve.
    CurvePoints,
    /// The next click sets the pivot (then the pick ends).
    Pivot,
}

/// The curve and pivot panel's state.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ForcePathPanel {
    /// The armed pick.
    pub pick: PathPick,
    /// The surface points of the stroke being dragged.
    recording: Vec<Vec3>,
    /// The path of the last stroke dragged on the clay, field coordinates.
    pub last_stroke: Vec<Vec3>,
}

/// `points` thinned evenly to at most [`MAX_CURVE_POINTS`], keeping both ends.
#[must_use]
pub fn thin(points: &[Vec3]) -> Vec<Vec3> {
    let n = points.len();
    if n <= MAX_CURVE_POINTS {
        return points.to_vec();
    }
    (0..MAX_CURVE_POINTS)
        .map(|i| points[i * (n - 1) / (MAX_CURVE_POINTS - 1)])
        .collect()
}

impl ForcePathPanel {
    /// Whether a pick is armed (left clicks on the clay pick instead of sculpting).
    #[must_use]
    pub fn picking(&self) -> bool {
        self.pick != PathPick::Off
    }

    /// Adds the brush's surface point `at` of a held stroke to the path being recorded
    /// (points closer than [`PATH_STEP_SPANS`] of `spacing` to the last are skipped).
    pub fn record(&mut self, at: Vec3, spacing: f32) {
        if self
            .recording
            .last()
            .is_none_or(|last| last.distance(at) >= PATH_STEP_SPANS * spacing)
        {
            self.recording.push(at);
        }
    }

    /// Ends the stroke being recorded: its path becomes the last stroke's (a stroke of one
    /// point is not a path and is dropped).
    pub fn end_recording(&mut self) {
        if self.recording.len() >= 2 {
            self.last_stroke = thin(&self.recording);
        }
        self.recording.clear();
    }

    /// A click on the clay at `hit` with a pick armed: adds a curve point or sets the pivot.
    /// Returns whether the palette changed.
    pub fn click(&mut self, hit: Vec3, palette: &mut ToolPalette) -> bool {
        match self.pick {
            PathPick::Off => false,
            PathPick::CurvePoints => {
                if palette.curve_fu.len() < MAX_CURVE_POINTS {
                    palette.curve_fu.push(hit);
                }
                true
            }
            PathPick::Pivot => {
                palette.pivot_fu = Some(hit);
                self.pick = PathPick::Off;
                true
            }
        }
    }

    /// Draws the panel; returns whether the palette changed.
    pub fn ui(&mut self, ui: &mut egui::Ui, palette: &mut ToolPalette) -> bool {
        let before = (palette.curve_fu.clone(), palette.pivot_fu);
        ui.label(format!(
            "Curve: {} points · pivot: {}",
            palette.curve_fu.len(),
            palette.pivot_fu.map_or("none".to_owned(), |p| format!(
                "({:.3}, {:.3}, {:.3})",
                p.x, p.y, p.z
            ))
        ));
        let use_last = ui
            .add_enabled(
                !self.last_stroke.is_empty(),
                egui::Button::new("Curve from the last stroke"),
            )
            .on_hover_text("The path of the last stroke dragged on the clay becomes the curve");
        if use_last.clicked() {
            palette.curve_fu.clone_from(&self.last_stroke);
            self.select(palette, ForceMode::Curve);
        }
        ui.horizontal_wrapped(|ui| {
            let mut curve = self.pick == PathPick::CurvePoints;
            if ui
                .toggle_value(&mut curve, "Click curve points")
                .on_hover_text("While on, each left click on the clay adds a point to the curve")
                .changed()
            {
                self.pick = if curve {
                    palette.curve_fu.clear();
                    self.select(palette, ForceMode::Curve);
                    PathPick::CurvePoints
                } else {
                    PathPick::Off
                };
            }
            let mut pivot = self.pick == PathPick::Pivot;
            if ui
                .toggle_value(&mut pivot, "Click the pivot")
                .on_hover_text("The next left click on the clay sets the bend's pivot")
                .changed()
            {
                self.pick = if pivot {
                    self.select(palette, ForceMode::Bend);
                    PathPick::Pivot
                } else {
                    PathPick::Off
                };
            }
        });
        if ui.button("Clear the curve").clicked() {
            palette.curve_fu.clear();
        }
        (palette.curve_fu.clone(), palette.pivot_fu) != before
    }

    /// Puts `mode` in hand (the curve or the bend).
    fn select(&self, palette: &mut ToolPalette, mode: ForceMode) {
        palette.selected = PaletteEntry::Force(mode);
    }

    /// The polylines to draw over the view: the curve, and a small cross at the pivot, for
    /// the tool in hand (none for other tools).
    #[must_use]
    pub fn marks(&self, palette: &ToolPalette, spacing: f32) -> Vec<Vec<Vec3>> {
        let mut marks = Vec::new();
        match palette.selected {
            PaletteEntry::Force(ForceMode::Curve) if palette.curve_fu.len() >= 2 => {
                marks.push(palette.curve_fu.clone());
            }
            PaletteEntry::Force(ForceMode::Curve) => {
                // One point: a short cross so it shows.
                if let Some(&p) = palette.curve_fu.first() {
                    marks.extend(cross(p, spacing));
                }
            }
            PaletteEntry::Force(ForceMode::Bend) => {
                if let Some(p) = palette.pivot_fu {
                    marks.extend(cross(p, spacing));
                }
            }
            _ => {}
        }
        marks
    }
}

/// Three short segments crossing at `p`, a knot span long each.
fn cross(p: Vec3, spacing: f32) -> [Vec<Vec3>; 3] {
    let h = 0.5 * spacing;
    [Vec3::X, Vec3::Y, Vec3::Z].map(|a| vec![p - a * h, p + a * h])
}

/// The curve and pivot lines of the palette's force settings (shown under the curve and the
/// bend entries).
pub fn summary_ui(ui: &mut egui::Ui, mode: ForceMode, curve: &[Vec3], pivot: Option<Vec3>) {
    match mode {
        ForceMode::Curve if curve.is_empty() => {
            ui.weak("No curve yet: see Curve and pivot (last stroke or clicked points).");
        }
        ForceMode::Curve => {
            ui.weak(format!("Curve of {} points.", curve.len()));
        }
        ForceMode::Bend if pivot.is_none() => {
            ui.weak("No pivot yet: see Curve and pivot (click the pivot on the clay).");
        }
        _ => {
            if let Some(p) = pivot {
                ui.weak(format!("Pivot at ({:.3}, {:.3}, {:.3}).", p.x, p.y, p.z));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::ToolChoice;
    use crate::tools::ForceTool;

    #[test]
    fn a_recorded_stroke_becomes_the_curve_and_a_click_the_pivot() {
        let mut panel = ForcePathPanel::default();
        let mut palette = ToolPalette::default();
        // A drag of 1000 surface samples a hundredth of a span apart, recorded every quarter
        // span: 40 points.
        for i in 0..1000 {
            panel.record(Vec3::new(0.001 * i as f32, 1.0, 1.0), 0.1);
        }
        panel.end_recording();
        assert_eq!(panel.last_stroke.len(), 40);
        palette.curve_fu.clone_from(&panel.last_stroke);
        palette.selected = PaletteEntry::Force(ForceMode::Curve);
        let ToolChoice::Force { tool, curve, .. } = palette.choice() else {
            panic!("expected a force tool");
        };
        assert!(matches!(tool, ForceTool::Curve { .. }));
        assert_eq!(curve, panel.last_stroke);
        // Clicks: the pivot pick ends after one click.
        panel.pick = PathPick::Pivot;
        assert!(panel.click(Vec3::ONE, &mut palette));
        assert!(!panel.picking());
        palette.selected = PaletteEntry::Force(ForceMode::Bend);
        let ToolChoice::Force { tool, pivot, .. } = palette.choice() else {
            panic!("expected a force tool");
        };
        assert!(matches!(tool, ForceTool::Bend { samples: 12, .. }));
        assert_eq!(pivot, Vec3::ONE);
        assert_eq!(panel.marks(&palette, 0.1).len(), 3);
        // A long path is thinned to the haptic loop's capacity, ends kept.
        let long: Vec<Vec3> = (0..1000).map(|i| Vec3::X * i as f32).collect();
        let thinned = thin(&long);
        assert_eq!(thinned.len(), MAX_CURVE_POINTS);
        assert_eq!(thinned.first(), long.first());
        assert_eq!(thinned.last(), long.last());
    }
}
