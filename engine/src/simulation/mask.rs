//! The freeze mask in the running stage: mask edits as undo steps, and the live region's holds
//! kept in step with the clay's mask (`dynaclay_core::tools::mask`).

#[allow(clippy::wildcard_imports)] // the stage's own module: its types and imports
use super::*;
use dynaclay_core::tools::{MaskEdit, MaskReport, region_holds};

impl SimulationStage {
    /// Applies a [`Command::Mask`] as one undo step (a held stroke ends first) and gives the
    /// live region the new holds.
    ///
    /// # Errors
    /// [`CommandError::Mask`] for a bad brush or centre; dabs applied before it stay, as one
    /// step.
    pub(super) fn edit_mask(&mut self, edit: &MaskEdit) -> Result<MaskReport, CommandError> {
        self.end_stroke_now();
        let mut rec = StepRecorder::new(edit.name());
        let report = edit.apply(&mut self.clay, Some(&mut rec));
        self.commit(rec);
        self.refresh_region_holds();
        self.mask_dirty = true;
        Ok(report?)
    }

    /// The live region's holds made again from the clay's mask (after a mask edit).
    pub(super) fn refresh_region_holds(&mut self) {
        if let Some(state) = self.region.as_mut() {
            let b = state.coeff_box();
            region_holds(&self.clay, self.region_patch, b, &mut state.held);
        }
    }
}

#[cfg(test)]
mod tests {
    use crossbeam::channel::bounded;
    use dynaclay_core::tools::{MaskBrush, MaskMode};

    use super::super::tests::{sphere_top, stages_on_sphere};
    use super::*;
    use crate::Stages;

    /// Masks the sphere's top (held fully within `radius_fu / 2` of it) through the command.
    fn mask_top(s: &mut Stages, top: Vec3, radius_fu: f32) -> MaskReport {
        let (tx, rx) = bounded(1);
        s.commands
            .send(Command::Mask {
                edit: MaskEdit::Paint {
                    brush: MaskBrush {
                        radius_fu,
                        strength: 1.0,
                        mode: MaskMode::Freeze,
                    },
                    centres_fu: vec![top],
                },
                reply: Some(tx),
            })
            .unwrap();
        s.sim.apply_commands();
        rx.try_recv().unwrap().unwrap()
    }

    /// Pushes the top in with the contact push (the default tool) for half a second, the
    /// force from the top to a tip 0.04 below it, and lets go; returns the clay's density at
    /// points just below the top before and after.
    fn press_top(s: &mut Stages, top: Vec3) -> Vec<(f32, f32)> {
        let probes: Vec<Vec3> = (0..5)
            .map(|n| top - Vec3::Y * (0.005 + 0.01 * n as f32))
            .collect();
        let before: Vec<f32> = probes
            .iter()
            .map(|&x| s.sim.clay.density.value(x))
            .collect();
        let (steps, settle) = (500_u64, 50_u64);
        for n in 0..=steps + settle {
            let pressing = n < steps;
            let tip = top - Vec3::Y * (0.04 * n.min(steps) as f32 / steps as f32);
            let sample = ToolSample {
                tip_fu: tip,
                force_from_fu: top,
                force_to_fu: tip,
                in_contact: pressing,
                stroke_active: pressing,
                device_time_us: n * 1000,
                tick: n,
                ..ToolSample::IDLE
            };
            s.sim.apply_commands();
            s.sim.step(&sample);
        }
        probes
            .iter()
            .zip(before)
            .map(|(&x, b)| (b, s.sim.clay.density.value(x)))
            .collect()
    }

    #[test]
    fn a_masked_top_holds_under_a_pressed_stroke_that_dents_the_free_top() {
        let mut free = stages_on_sphere(12);
        let top = sphere_top(&free);
        let dent = press_top(&mut free, top);
        let moved = dent.iter().map(|(b, a)| (a - b).abs()).fold(0.0, f32::max);
        assert!(moved > 1e-3, "the free top moved {moved}");

        let mut held = stages_on_sphere(12);
        let report = mask_top(&mut held, top, 1.2);
        assert!(report.changed > 0);
        assert_eq!(held.sim.undo_len(), 1, "the mask stroke is an undo step");
        let kept = press_top(&mut held, top);
        for (b, a) in kept {
            assert!((a - b).abs() <= 1e-6, "held top moved from {b} to {a}");
        }
    }

    #[test]
    fn mask_commands_invert_clear_and_undo() {
        let mut s = stages_on_sphere(12);
        let top = sphere_top(&s);
        mask_top(&mut s, top, 0.3);
        let painted = s.sim.clay.mask.clone().unwrap();
        for edit in [MaskEdit::Invert, MaskEdit::Clear] {
            s.commands
                .send(Command::Mask { edit, reply: None })
                .unwrap();
        }
        s.sim.apply_commands();
        assert!(!s.sim.clay.mask.as_ref().unwrap().any());
        assert_eq!(s.sim.undo_len(), 3);
        s.commands.send(Command::Undo).unwrap();
        s.sim.apply_commands();
        let inverted = s.sim.clay.mask.as_ref().unwrap();
        assert!(
            (inverted.value_at(top) - (1.0 - painted.value_at(top))).abs() < 1e-6,
            "undo brings the inverted mask back"
        );
        s.commands.send(Command::Undo).unwrap();
        s.sim.apply_commands();
        assert_eq!(s.sim.clay.mask.as_ref().unwrap(), &painted);
        // A bad brush is refused with what is wrong.
        let (tx, rx) = bounded(1);
        s.commands
            .send(Command::Mask {
                edit: MaskEdit::Paint {
                    brush: MaskBrush {
                        radius_fu: -1.0,
                        strength: 1.0,
                        mode: MaskMode::Freeze,
                    },
                    centres_fu: vec![top],
                },
                reply: Some(tx),
            })
            .unwrap();
        s.sim.apply_commands();
        let e = rx.try_recv().unwrap().unwrap_err();
        assert!(e.to_string().contains("radius_fu"), "{e}");
    }
}
