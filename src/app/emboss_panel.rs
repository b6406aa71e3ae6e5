//! Embossing from the window (Guo & Qin §5.1, the clay's emboss tool): an image file (PNG or
//! JPEG) whose brightness is raised (or, engraved, sunk) by a depth, laid on the clay by a
//! projection placed at the last point the brush was on — planar along the surface's normal
//! there, cylindrical about the vertical axis through the clay's centre at the brush's height,
//! or spherical about the clay's centre — as the script's `emboss` step does. One undo step;
//! the image is read on the bridge thread.

use glam::Vec3;

use super::command::EngineCommand;
use crate::tools::{EmbossParams, Projection};

/// The projections offered.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ProjectionKind {
    /// Along the surface normal at the brush point, a square `size` wide.
    #[default]
    Planar,
    /// Around the vertical (y) axis through the clay's centre, `size` tall, facing the brush.
    Cylindrical,
    /// Longitude and latitude about the clay's centre, the image's top at +y.
    Spherical,
}

/// The emboss panel's state.
#[derive(Clone, Debug, PartialEq)]
pub struct EmbossPanel {
    /// The image file.
    pub image: String,
    /// How it lies on the clay.
    pub projection: ProjectionKind,
    /// The planar image's width, or the cylindrical one's height, field units.
    pub size_fu: f32,
    /// How far white moves the surface, field units.
    pub depth_fu: f32,
    /// Sink instead of raising.
    pub engrave: bool,
}

impl Default for EmbossPanel {
    fn default() -> Self {
        Self {
            image: "logo.png".into(),
            projection: ProjectionKind::Planar,
            size_fu: 0.6,
            depth_fu: 0.04,
            engrave: false,
        }
    }
}

/// Where the brush is: the surface point, its outward normal, and the view's up direction
/// (the planar image's top).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BrushFrame {
    pub at: Vec3,
    pub normal: Vec3,
    pub view_up: Vec3,
}

impl EmbossPanel {
    /// The emboss parameters at `brush` on a clay centred at `clay_centre`.
    #[must_use]
    pub fn params(&self, brush: BrushFrame, clay_centre: Vec3) -> EmbossParams {
        let projection = match self.projection {
            ProjectionKind::Planar => {
                // The view's up, unless it runs along the normal (looking straight at a
                // face from above): then any direction across it.
                let up = if brush.view_up.cross(brush.normal).length_squared() > 1e-4 {
                    brush.view_up
                } else {
                    brush.normal.any_orthonormal_vector()
                };
                Projection::Planar {
                    centre: brush.at,
                    axis: brush.normal,
                    up,
                    size_fu: self.size_fu,
                }
            }
            ProjectionKind::Cylindrical => {
                let centre = Vec3::new(clay_centre.x, brush.at.y, clay_centre.z);
                let facing = brush.at - centre;
                Projection::Cylindrical {
                    centre,
                    axis: Vec3::Y,
                    up: if facing.length_squared() > 1e-8 {
                        facing
                    } else {
                        Vec3::Z
                    },
                    height_fu: self.size_fu,
                }
            }
            ProjectionKind::Spherical => Projection::Spherical {
                centre: clay_centre,
                up: Vec3::Y,
            },
        };
        EmbossParams {
            projection,
            depth_fu: self.depth_fu,
            engrave: self.engrave,
        }
    }

    /// Draws the panel. `brush` is where the brush last was on the clay. Returns the command
    /// to send, or a message for the log when the settings are invalid.
    pub fn ui(
        &mut self,
        ui: &mut egui::Ui,
        brush: Option<BrushFrame>,
        clay_centre: Vec3,
    ) -> Option<Result<EngineCommand, String>> {
        ui.horizontal_wrapped(|ui| {
            let label = ui.label("Image");
            ui.add(egui::TextEdit::singleline(&mut self.image).desired_width(160.0))
                .labelled_by(label.id);
        });
        ui.horizontal_wrapped(|ui| {
            ui.radio_value(&mut self.projection, ProjectionKind::Planar, "Planar");
            ui.radio_value(
                &mut self.projection,
                ProjectionKind::Cylindrical,
                "Cylindrical",
            );
            ui.radio_value(&mut self.projection, ProjectionKind::Spherical, "Spherical");
        });
        if self.projection != ProjectionKind::Spherical {
            let what = if self.projection == ProjectionKind::Planar {
                "Image width"
            } else {
                "Image height"
            };
            ui.add(egui::Slider::new(&mut self.size_fu, 0.02..=3.0).text(what));
        }
        ui.add(
            egui::Slider::new(&mut self.depth_fu, 0.002..=0.3)
                .logarithmic(true)
                .text("Relief depth"),
        );
        ui.checkbox(&mut self.engrave, "Engrave (sink instead of raise)");
        let button = if self.engrave {
            "Engrave at the brush point"
        } else {
            "Emboss at the brush point"
        };
        if brush.is_none() {
            ui.weak("move the pointer over the clay to place the image");
        }
        let clicked = ui
            .add_enabled(brush.is_some(), egui::Button::new(button))
            .clicked();
        let brush = brush.filter(|_| clicked)?;
        let params = self.params(brush, clay_centre);
        Some(
            params
                .validate()
                .map(|()| EngineCommand::Emboss {
                    image: std::path::PathBuf::from(self.image.trim()),
                    params,
                })
                .map_err(|e| e.to_string()),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_projection_is_placed_from_the_brush_and_the_clay() {
        let brush = BrushFrame {
            at: Vec3::new(1.15, 1.725, 1.3),
            normal: Vec3::Y,
            view_up: Vec3::Y,
        };
        let centre = Vec3::splat(1.15);
        let mut panel = EmbossPanel::default();
        let p = panel.params(brush, centre);
        let Projection::Planar {
            centre: c,
            axis,
            up,
            size_fu: size,
        } = p.projection
        else {
            panic!("planar expected");
        };
        assert_eq!((c, axis, size), (brush.at, Vec3::Y, 0.6));
        // Looking straight down the normal, the up is taken across it.
        assert!(up.dot(Vec3::Y).abs() < 1e-6);
        p.validate().unwrap();
        panel.projection = ProjectionKind::Cylindrical;
        let Projection::Cylindrical { centre: c, up, .. } = panel.params(brush, centre).projection
        else {
            panic!("cylindrical expected");
        };
        assert_eq!(c, Vec3::new(1.15, 1.725, 1.15));
        assert!((up.normalize() - Vec3::Z).length() < 1e-5);
        panel.projection = ProjectionKind::Spherical;
        assert_eq!(
            panel.params(brush, centre).projection,
            Projection::Spherical {
                centre,
                up: Vec3::Y
            }
        );
    }
}
