//! The app's sections for the tools that need more than a brush: the tool library (a tool
//! made from the sculpt), the curve and pivot of the curve and bend tools, CSG and emboss;
//! the clicks that pick curve points and the pivot; and their marks over the view (the
//! selection, the curve, the pivot).

use glam::Vec3;

use super::emboss_panel::BrushFrame;
use super::state::SculptApp;

impl SculptApp {
    /// The sections, drawn in the controls panel; true when the palette changed.
    pub(super) fn sculpt_sections(&mut self, ui: &mut egui::Ui) -> bool {
        let mut tool_changed = false;
        egui::CollapsingHeader::new("Tool library")
            .default_open(false)
            .show(ui, |ui| {
                let field = &self.link.field().value;
                let mut failed = None;
                let (command, changed) =
                    self.library
                        .ui(ui, self.refine_at, field, &mut self.palette, &mut failed);
                tool_changed |= changed;
                if let Some(line) = failed {
                    self.note(line);
                }
                if let Some(command) = command {
                    self.send(command);
                }
            });
        egui::CollapsingHeader::new("Curve and pivot")
            .default_open(false)
            .show(ui, |ui| {
                tool_changed |= self.force_path.ui(ui, &mut self.palette);
            });
        egui::CollapsingHeader::new("Detail")
            .default_open(false)
            .show(ui, |ui| self.detail_pending |= self.detail.ui(ui));
        egui::CollapsingHeader::new("CSG")
            .default_open(false)
            .show(ui, |ui| {
                if let Some(command) = self.csg.ui(ui, self.refine_at) {
                    self.send(command);
                }
            });
        egui::CollapsingHeader::new("Emboss")
            .default_open(false)
            .show(ui, |ui| {
                let brush = self.brush_frame();
                let centre = crate::engine::clay_centre(self.link.field().value.base());
                match self.emboss.ui(ui, brush, centre) {
                    Some(Ok(command)) => {
                        self.send(command);
                    }
                    Some(Err(e)) => self.note(format!("emboss: {e}")),
                    None => {}
                }
            });
        tool_changed
    }

    /// Where the brush last was on the clay, with the view's up.
    fn brush_frame(&self) -> Option<BrushFrame> {
        let at = self.refine_at?;
        let normal = self.brush_normal?;
        let (_, view_up) = self.camera.right_up();
        Some(BrushFrame {
            at,
            normal,
            view_up,
        })
    }

    /// With a curve-point or pivot pick armed, a left click on the clay picks (and does not
    /// sculpt); `hit` is the clay point under the pointer. Returns whether the pick took the
    /// pointer this frame (a press beside the clay still orbits).
    pub(super) fn path_pick_input(&mut self, hit: Option<Vec3>, clicked: bool) -> bool {
        if !self.force_path.picking() {
            return false;
        }
        if clicked
            && let Some(p) = hit
            && self.force_path.click(p, &mut self.palette)
        {
            // Sent now: this frame's settings went out before the view took the click.
            self.resend_tool();
        }
        true
    }

    /// The selection, curve and pivot in screen points over the view `rect`, as polylines
    /// (segments behind the eye are left out).
    #[must_use]
    pub fn sculpt_marks_on_screen(&mut self, rect: egui::Rect) -> Vec<Vec<egui::Pos2>> {
        let spacing = self.link.field().value.finest_spacing();
        let size = rect.size().max(egui::vec2(1.0, 1.0));
        let vp = self.camera.view_projection(size.x / size.y);
        let to_screen = |x: Vec3| {
            let c = vp * x.extend(1.0);
            (c.w > 0.0).then(|| {
                egui::pos2(
                    rect.min.x + (c.x / c.w + 1.0) * 0.5 * size.x,
                    rect.min.y + (1.0 - c.y / c.w) * 0.5 * size.y,
                )
            })
        };
        let mut world: Vec<Vec<Vec3>> = Vec::new();
        if self.library.show_selection
            && let Some(at) = self.refine_at
        {
            world.extend(
                self.library
                    .outline(at)
                    .into_iter()
                    .map(|(a, b)| vec![a, b]),
            );
        }
        world.extend(self.force_path.marks(&self.palette, spacing));
        world
            .iter()
            .map(|line| {
                line.iter()
                    .filter_map(|&x| to_screen(x))
                    .collect::<Vec<_>>()
            })
            .filter(|line| line.len() >= 2)
            .collect()
    }

    /// Paints the selection, the curve and the pivot over the scene image.
    pub(super) fn paint_sculpt_marks(&mut self, ui: &egui::Ui, rect: egui::Rect) {
        let painter = ui.painter_at(rect);
        let colour = egui::Color32::from_rgb(230, 190, 60);
        for line in self.sculpt_marks_on_screen(rect) {
            painter.add(egui::Shape::line(line, egui::Stroke::new(1.5, colour)));
        }
    }
}
