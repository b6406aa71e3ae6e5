//! The freeze mask in the window: a Mask tool that paints the mask with the sculpting brush's
//! radius instead of sculpting (Ctrl held, or the Erase toggle, frees instead of freezing),
//! and Invert and Clear buttons. What is masked is held by every tool and by the dynamics
//! ([`crate::tools::MaskEdit`]); the view draws it tinted.

use glam::Vec3;

use super::command::EngineCommand;
use crate::tools::{MaskBrush, MaskEdit, MaskMode};

/// The spacing of a mask drag's dabs, as a fraction of the brush radius (close enough that
/// the soft dabs join into an even band).
pub const MASK_DAB_SPACING: f32 = 0.25;

/// The Mask tool's settings and the drag in progress.
#[derive(Clone, Debug, PartialEq)]
pub struct MaskPanel {
    /// Whether a left drag on the clay paints the mask (instead of sculpting).
    pub active: bool,
    /// Whether a drag frees masked clay (the eraser) rather than freezing it; Ctrl held
    /// during a drag does the same.
    pub erase: bool,
    /// How far one dab moves the hold toward its goal at the brush's centre, `0..=1`.
    pub strength: f32,
    /// Where the drag last dabbed (`None` between drags).
    last: Option<Vec3>,
}

impl Default for MaskPanel {
    /// Off, freezing, full strength.
    fn default() -> Self {
        Self {
            active: false,
            erase: false,
            strength: 1.0,
            last: None,
        }
    }
}

impl MaskPanel {
    /// The brush of a dab of `radius_fu`; `erase_held` (Ctrl) turns a freezing brush into
    /// the eraser for this drag.
    #[must_use]
    pub fn brush(&self, radius_fu: f32, erase_held: bool) -> MaskBrush {
        MaskBrush {
            radius_fu,
            strength: self.strength.clamp(0.0, 1.0),
            mode: if self.erase || erase_held {
                MaskMode::Free
            } else {
                MaskMode::Freeze
            },
        }
    }

    /// One frame of a drag: `hit` is the clay's surface under the pointer, `held` whether the
    /// drag is held. Dabs where the drag starts and then every [`MASK_DAB_SPACING`] of the
    /// radius along it; `None` for a frame that adds no dab or a brush that is not valid.
    pub fn pointer(
        &mut self,
        hit: Option<Vec3>,
        held: bool,
        radius_fu: f32,
        erase_held: bool,
    ) -> Option<MaskEdit> {
        if !held {
            self.last = None;
            return None;
        }
        let at = hit?;
        if self
            .last
            .is_some_and(|last| last.distance(at) < MASK_DAB_SPACING * radius_fu)
        {
            return None;
        }
        self.last = Some(at);
        let brush = self.brush(radius_fu, erase_held);
        brush.validate().is_ok().then(|| MaskEdit::Paint {
            brush,
            centres_fu: vec![at],
        })
    }

    /// Whether a drag is painting the mask.
    #[must_use]
    pub fn painting(&self) -> bool {
        self.last.is_some()
    }

    /// The tool's controls: the switch, Freeze and Erase as toggles (the one in effect shows
    /// selected), the strength, and Invert and Clear. Returns a command when a button asks
    /// for one.
    pub fn ui(&mut self, ui: &mut egui::Ui) -> Option<EngineCommand> {
        let mut command = None;
        ui.checkbox(&mut self.active, "Paint mask with the brush")
            .on_hover_text(
                "A left drag on the clay masks it with the brush's radius instead of \
                 sculpting; masked clay is frozen for every tool and the dynamics, and is \
                 drawn darker. Hold Ctrl while dragging to erase",
            );
        ui.horizontal(|ui| {
            if ui.selectable_label(!self.erase, "Freeze").clicked() {
                self.erase = false;
            }
            if ui.selectable_label(self.erase, "Erase").clicked() {
                self.erase = true;
            }
        });
        ui.add(egui::Slider::new(&mut self.strength, 0.05..=1.0).text("Mask strength"));
        ui.horizontal(|ui| {
            if ui
                .button("Invert mask")
                .on_hover_text("Masked clay becomes free and free clay masked (one undo step)")
                .clicked()
            {
                command = Some(EngineCommand::Mask(MaskEdit::Invert));
            }
            if ui
                .button("Clear mask")
                .on_hover_text("Frees all the clay (one undo step)")
                .clicked()
            {
                command = Some(EngineCommand::Mask(MaskEdit::Clear));
            }
        });
        command
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_drag_dabs_where_it_starts_then_every_quarter_radius_and_ctrl_erases() {
        let mut panel = MaskPanel::default();
        let r = 0.2;
        let start = Vec3::new(1.0, 1.7, 1.0);
        let Some(MaskEdit::Paint { brush, centres_fu }) =
            panel.pointer(Some(start), true, r, false)
        else {
            panic!("the first frame of a drag dabs");
        };
        assert_eq!(centres_fu, vec![start]);
        assert_eq!((brush.radius_fu, brush.mode), (r, MaskMode::Freeze));
        assert!(panel.painting());
        // Less than a quarter radius further: no dab.
        assert!(
            panel
                .pointer(Some(start + Vec3::X * 0.04), true, r, false)
                .is_none()
        );
        let Some(MaskEdit::Paint { brush, .. }) =
            panel.pointer(Some(start + Vec3::X * 0.06), true, r, true)
        else {
            panic!("a quarter radius on, the drag dabs again");
        };
        assert_eq!(brush.mode, MaskMode::Free);
        // Released: nothing, and the next drag starts afresh.
        assert!(panel.pointer(Some(start), false, r, false).is_none());
        assert!(!panel.painting());
        panel.erase = true;
        let Some(MaskEdit::Paint { brush, .. }) = panel.pointer(Some(start), true, r, false) else {
            panic!("a new drag dabs");
        };
        assert_eq!(brush.mode, MaskMode::Free);
        // Off the clay nothing is dabbed.
        panel.pointer(None, false, r, false);
        assert!(panel.pointer(None, true, r, false).is_none());
    }
}
