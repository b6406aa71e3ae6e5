//! The simulation's share of motion to photon (see [`crate::motion_to_photon`]): which step
//! first used a stroke's sample to change the clay, which snapshot carried it, and when the
//! stroke's clay counts as settled.
//!
//! Settling: after the stroke's last change by the hand, every region step's largest
//! coefficient move is logged with its snapshot; when the stroke's motion ends (its region
//! retires, the next stroke starts, the engine stops) the settled snapshot is the first whose
//! remaining moves sum to at most [`SETTLED_COEFF_TOLERANCE`], a bound on how far the clay it
//! holds is from the final shape. Allocates only the log and one copy of the region's
//! coefficients (the simulation loop may allocate).

use dynaclay_core::field::{BSplineLattice, CoeffBox};

use crate::motion_to_photon::{ChangeStamp, FeltChange, SETTLED_COEFF_TOLERANCE, StrokeStamps};

/// Region steps logged after a stroke's last change before it is settled regardless (a
/// region whose motion outlasts this is judged on what was logged).
const SETTLE_LOG_MAX: usize = 1 << 16;

/// What the step in progress will stamp on its snapshot.
#[derive(Clone, Copy, Debug, Default)]
struct StepInProgress {
    sample_tick: u64,
    sample_ns: u64,
    step_ns: u64,
    /// The hand changed the clay in this step (a push, a held tool applied).
    by_hand: bool,
    /// The largest coefficient move of this step's region (0 without a region).
    moved: f32,
}

/// The newest stroke's stamps and its settling log.
#[derive(Debug, Default)]
pub(super) struct StrokeTrack {
    stamps: StrokeStamps,
    step: Option<StepInProgress>,
    /// Region steps since the stroke's last change: their stamp and largest move.
    since_last_change: Vec<(ChangeStamp, f32)>,
    /// The region's coefficients before this step, and which patch and box they are.
    before: Vec<f32>,
    before_box: Option<(usize, CoeffBox)>,
}

impl StrokeTrack {
    /// The stamps every snapshot carries.
    pub(super) fn stamps(&self) -> StrokeStamps {
        self.stamps
    }

    /// A new stroke starts: the previous one is settled with what it logged.
    pub(super) fn stroke_started(&mut self) {
        self.settle();
        self.stamps = StrokeStamps {
            stroke: self.stamps.stroke + 1,
            ..StrokeStamps::default()
        };
        self.since_last_change.clear();
    }

    /// A step under a sample read at `sample_ns` (tick `sample_tick`) begins at `step_ns`;
    /// `felt` is what the haptic loop has felt so far.
    pub(super) fn step_began(
        &mut self,
        sample_tick: u64,
        sample_ns: u64,
        step_ns: u64,
        felt: FeltChange,
    ) {
        self.step = Some(StepInProgress {
            sample_tick,
            sample_ns,
            step_ns,
            ..StepInProgress::default()
        });
        if felt.stroke != 0 && felt.stroke == self.stamps.stroke {
            self.stamps.hand_to_force_ticks = Some(felt.ticks);
        }
    }

    /// This step's hand changed the clay.
    pub(super) fn changed_by_hand(&mut self) {
        if let Some(s) = self.step.as_mut() {
            s.by_hand = true;
        }
    }

    /// Whether the stroke changed the clay and is not settled yet.
    fn settling(&self) -> bool {
        self.stamps.last_change.is_some() && self.stamps.settled.is_none()
    }

    /// Before the region (box `b` of patch `patch`, on `lattice`) steps: keeps its
    /// coefficients while the stroke is settling.
    pub(super) fn before_region_step(
        &mut self,
        lattice: &BSplineLattice,
        patch: usize,
        b: CoeffBox,
    ) {
        if !self.settling() {
            self.before_box = None;
            return;
        }
        self.before.clear();
        for_each_row(lattice, b, |row| self.before.extend_from_slice(row));
        self.before_box = Some((patch, b));
    }

    /// After the region stepped: notes its largest coefficient move (unbounded when the region
    /// is not the one kept before the step).
    pub(super) fn after_region_step(
        &mut self,
        lattice: &BSplineLattice,
        patch: usize,
        b: CoeffBox,
    ) {
        let settling = self.settling();
        let Some(step) = self.step.as_mut() else {
            return;
        };
        if self.before_box != Some((patch, b)) {
            if settling {
                step.moved = f32::INFINITY;
            }
            return;
        }
        let mut moved = 0.0f32;
        let mut at = 0;
        for_each_row(lattice, b, |row| {
            for (now, was) in row.iter().zip(&self.before[at..at + row.len()]) {
                moved = moved.max((now - was).abs());
            }
            at += row.len();
        });
        step.moved = moved;
    }

    /// The step's snapshot is published as `snapshot_version` at `snapshot_ns`.
    pub(super) fn published(&mut self, snapshot_version: u64, snapshot_ns: u64) {
        let Some(step) = self.step.take() else {
            return;
        };
        let stamp = ChangeStamp {
            sample_tick: step.sample_tick,
            sample_ns: step.sample_ns,
            step_ns: step.step_ns,
            snapshot_version,
            snapshot_ns,
        };
        if step.by_hand && self.stamps.stroke != 0 && self.stamps.settled.is_none() {
            self.stamps.first_change.get_or_insert(stamp);
            self.stamps.last_change = Some(stamp);
            self.since_last_change.clear();
        } else if self.settling() && step.moved > 0.0 {
            self.since_last_change.push((stamp, step.moved));
            if self.since_last_change.len() >= SETTLE_LOG_MAX {
                self.settle();
            }
        }
    }

    /// The stroke's clay has stopped moving (or is taken as stopped): its settled snapshot is
    /// the first whose remaining logged moves sum to at most the tolerance.
    pub(super) fn settle(&mut self) {
        let Some(last) = self.stamps.last_change else {
            return;
        };
        if self.stamps.settled.is_some() {
            return;
        }
        let mut settled = self.since_last_change.last().map_or(last, |(s, _)| *s);
        let mut remaining = 0.0f32;
        for (i, (_, moved)) in self.since_last_change.iter().enumerate().rev() {
            remaining += moved;
            if remaining > SETTLED_COEFF_TOLERANCE {
                break;
            }
            // The clay before this move was within the tolerance of the final shape.
            settled = if i == 0 {
                last
            } else {
                self.since_last_change[i - 1].0
            };
        }
        self.stamps.settled = Some(settled);
        self.since_last_change.clear();
        self.before_box = None;
    }
}

/// Calls `f` with each x-row of box `b` of `lattice`, z slowest.
fn for_each_row(lattice: &BSplineLattice, b: CoeffBox, mut f: impl FnMut(&[f32])) {
    let Some(b) = b.clipped(lattice.dims) else {
        return;
    };
    let len = b.max[0] + 1 - b.min[0];
    let mut values = vec![0.0; len];
    for k in b.min[2]..=b.max[2] {
        for j in b.min[1]..=b.max[1] {
            lattice.coeffs.read_row_at([b.min[0], j, k], &mut values);
            f(&values);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn step(track: &mut StrokeTrack, tick: u64, by_hand: bool, moved: f32) {
        track.step_began(tick, tick * 1000, tick * 1000 + 10, FeltChange::default());
        if by_hand {
            track.changed_by_hand();
        }
        if let Some(s) = track.step.as_mut() {
            s.moved = moved;
        }
        track.published(tick, tick * 1000 + 20);
    }

    #[test]
    fn the_settled_snapshot_is_the_first_whose_remaining_moves_fit_the_tolerance() {
        let mut track = StrokeTrack::default();
        track.stroke_started();
        step(&mut track, 1, false, 0.0);
        step(&mut track, 2, true, 0.3);
        step(&mut track, 3, true, 0.3);
        // After the last push the clay moves on: 0.05, 0.02, then a tail of 0.004 + 0.003 +
        // 0.002 (0.009 in all, within 0.01).
        for (tick, moved) in [(4, 0.05), (5, 0.02), (6, 0.004), (7, 0.003), (8, 0.002)] {
            step(&mut track, tick, false, moved);
        }
        let s = track.stamps();
        assert_eq!(s.first_change.map(|c| c.sample_tick), Some(2));
        assert_eq!(s.last_change.map(|c| c.sample_tick), Some(3));
        assert_eq!(s.settled, None, "not known before the motion ends");
        track.settle();
        let settled = track.stamps().settled.unwrap();
        assert_eq!(
            settled.snapshot_version, 5,
            "after tick 5 only 0.009 is left"
        );

        // A stroke whose clay stops at once settles at its last change; a stroke that never
        // changed the clay has no settled shape.
        track.stroke_started();
        step(&mut track, 10, true, 0.0);
        track.settle();
        assert_eq!(track.stamps().settled.map(|c| c.snapshot_version), Some(10));
        track.stroke_started();
        step(&mut track, 20, false, 0.0);
        track.settle();
        assert_eq!(track.stamps().settled, None);
        assert_eq!(track.stamps().stroke, 3);
    }
}
