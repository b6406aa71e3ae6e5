//! Motion to photon: the stamps that follow a device sample through the engine — the
//! simulation step that first used it, the snapshot that carried its change, the bricks
//! re-meshed from it and the frame that drew them — and the ledger that turns them into
//! per-stroke figures (hand → force, hand → first visible change, hand → settled shape).
//!
//! The stamps are plain numbers (nanoseconds of the [`super::EngineClock`], ticks, snapshot
//! versions) carried forward by the data they describe: the haptic tick stamps its
//! [`super::ToolSample`], the simulation writes [`StrokeStamps`] into every
//! [`super::FieldUpdate`], the graphics loop publishes a [`MeshStamp`] with the meshes it
//! hands over, and whoever draws frames gives the [`MotionToPhoton`] ledger each frame's time
//! and the mesh stamp it drew. Nothing is sent on the side, so a stamp can never describe
//! data its carrier did not hold. The haptic path copies stamps by value only: no allocation,
//! no lock.
//!
//! What a stroke is measured by:
//! - **first visible change**: from the first sample of the stroke whose step changed the clay
//!   to the first frame drawing a snapshot at least as new as that step's;
//! - **settled shape**: from the stroke's last sample that changed the clay (the hand's last
//!   push) to the first frame drawing the settled snapshot: the first snapshot after which the
//!   stroke's remaining motion, summed step by step, moves no coefficient by more than
//!   [`SETTLED_COEFF_TOLERANCE`] (so the drawn clay is within that of its final shape);
//! - **hand → force**: haptic ticks from that first sample to the tick that applied the
//!   snapshot carrying its change, and so rendered force on the changed clay.
//!
//! The ledger is not for the real-time path: it allocates its records.

use std::collections::VecDeque;

use dynaclay_loops::{MotionToPhotonSummary, Spread, StageSpreads};

/// How far, in coefficient units, the clay may still move after the snapshot that counts as
/// its settled shape. The clay's densities run from 0 (empty) to 1 (full) with the surface at
/// 0.5; across the default clay's surface the density falls by about a half per knot span,
/// so 0.01 is about a fiftieth of a knot span of surface motion — a twelfth of a mesh cell
/// at the default four cells per span, below what a frame can show.
pub const SETTLED_COEFF_TOLERANCE: f32 = 0.01;

/// One device sample's way into the clay: the hand's sample, the step that used it and the
/// snapshot that carried the change (plain data, engine-clock nanoseconds).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ChangeStamp {
    /// The haptic tick that read the sample.
    pub sample_tick: u64,
    /// When that tick read the device.
    pub sample_ns: u64,
    /// When the simulation step that used the sample began.
    pub step_ns: u64,
    /// The version of the snapshot (to the graphics loop) that carried the step's change.
    pub snapshot_version: u64,
    /// When that snapshot was published.
    pub snapshot_ns: u64,
}

/// What every snapshot tells its readers about the newest stroke (plain data, copied without
/// allocating; sticky: a stamp stays until the next stroke replaces it, so a reader that skips
/// snapshots still sees it).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StrokeStamps {
    /// The stroke: 1, 2, … in the order the simulation saw them start (0: none yet).
    pub stroke: u64,
    /// The stroke's first sample whose step changed the clay.
    pub first_change: Option<ChangeStamp>,
    /// The stroke's last sample whose step changed the clay, so far.
    pub last_change: Option<ChangeStamp>,
    /// The settled shape's step and snapshot (its sample fields are the step's own sample),
    /// known once the stroke's clay has stopped moving.
    pub settled: Option<ChangeStamp>,
    /// Haptic ticks from the first change's sample to the tick that felt it.
    pub hand_to_force_ticks: Option<u64>,
}

/// What the haptic loop felt of a stroke's first change, carried by its tool samples to the
/// simulation (plain data).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct FeltChange {
    /// The stroke (0: none felt yet).
    pub stroke: u64,
    /// Haptic ticks from the stroke's first change's sample to the tick that applied the
    /// snapshot carrying it.
    pub ticks: u64,
}

/// What the graphics loop hands to whoever draws frames with its meshes (plain data).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MeshStamp {
    /// The snapshot version the graphics loop's field (and so its meshes) holds.
    pub snapshot_version: u64,
    /// When the meshes of that snapshot were ready (applied and re-meshed).
    pub meshed_ns: u64,
    /// When the bricks holding the newest stroke's first change were ready.
    pub first_change_meshed_ns: Option<u64>,
    /// When the bricks holding the newest stroke's settled shape were ready.
    pub settled_meshed_ns: Option<u64>,
    /// The newest stroke, as the snapshot told it.
    pub stroke: StrokeStamps,
}

/// One stretch of the path, stage by stage, engine-clock nanoseconds.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StagePath {
    /// The hand's sample.
    pub sample_ns: u64,
    /// The simulation step.
    pub step_ns: u64,
    /// The snapshot's publication.
    pub snapshot_ns: u64,
    /// The bricks ready.
    pub meshed_ns: u64,
    /// The frame drawn.
    pub frame_ns: u64,
}

impl StagePath {
    /// Whether every stage comes no earlier than the one before it.
    #[must_use]
    pub fn is_ordered(&self) -> bool {
        self.sample_ns <= self.step_ns
            && self.step_ns <= self.snapshot_ns
            && self.snapshot_ns <= self.meshed_ns
            && self.meshed_ns <= self.frame_ns
    }

    /// From the sample to the frame, milliseconds.
    #[must_use]
    pub fn total_ms(&self) -> f64 {
        ms(self.sample_ns, self.frame_ns)
    }
}

/// One stroke's figures.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StrokeLatency {
    /// The stroke (see [`StrokeStamps::stroke`]).
    pub stroke: u64,
    /// The sample tick of the stroke's first change.
    pub first_change_tick: Option<u64>,
    /// Haptic ticks from the first change's sample to the force on the changed clay.
    pub hand_to_force_ticks: Option<u64>,
    /// The first visible change's path.
    pub first_visible: Option<StagePath>,
    /// The settled shape's path.
    pub settled: Option<StagePath>,
}

/// Frames remembered to find the one that first drew a snapshot known to be settled only
/// later (at 60 frames a second, a minute).
const FRAMES_KEPT: usize = 3600;

/// Finished strokes kept for the figures.
const STROKES_KEPT: usize = 4096;

/// Gathers the frames drawn and the stamps they drew into per-stroke figures.
#[derive(Clone, Debug, Default)]
pub struct MotionToPhoton {
    /// (snapshot version drawn, frame time), in drawing order.
    frames: VecDeque<(u64, u64)>,
    /// The newest stroke, while its settled shape is not drawn yet.
    open: Option<StrokeLatency>,
    /// Finished strokes, oldest first.
    done: VecDeque<StrokeLatency>,
}

impl MotionToPhoton {
    /// An empty ledger.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// Notes a frame finished at `frame_ns` that drew the meshes stamped `drawn`, and what
    /// `drawn` tells of the newest stroke.
    pub fn frame(&mut self, frame_ns: u64, drawn: &MeshStamp) {
        if self.frames.len() >= FRAMES_KEPT {
            self.frames.pop_front();
        }
        self.frames.push_back((drawn.snapshot_version, frame_ns));
        self.observe(drawn);
    }

    /// Takes in what `latest` (the newest mesh stamp, drawn or not) tells of the newest
    /// stroke, against the frames drawn so far: a stroke is known settled only some time after
    /// the frame that drew its settled shape, and no frame may follow when nothing changes.
    pub fn observe(&mut self, latest: &MeshStamp) {
        let s = latest.stroke;
        if s.stroke == 0 {
            return;
        }
        if self.open.is_some_and(|o| o.stroke != s.stroke) {
            self.close();
        }
        if self.open.is_none() && self.done.back().is_some_and(|d| d.stroke >= s.stroke) {
            // This stroke is finished already (its settled shape was drawn).
            return;
        }
        let first_frame_at = |version: u64| {
            self.frames
                .iter()
                .find(|(drawn, _)| *drawn >= version)
                .map(|(_, at_ns)| *at_ns)
        };
        let first_visible = s.first_change.and_then(|fc| {
            first_frame_at(fc.snapshot_version).map(|frame_ns| StagePath {
                sample_ns: fc.sample_ns,
                step_ns: fc.step_ns,
                snapshot_ns: fc.snapshot_ns,
                meshed_ns: latest.first_change_meshed_ns.unwrap_or(latest.meshed_ns),
                frame_ns,
            })
        });
        let settled = match (s.settled, s.last_change) {
            (Some(settled), Some(last)) => {
                first_frame_at(settled.snapshot_version).map(|frame_ns| StagePath {
                    sample_ns: last.sample_ns,
                    step_ns: settled.step_ns,
                    snapshot_ns: settled.snapshot_ns,
                    meshed_ns: latest.settled_meshed_ns.unwrap_or(latest.meshed_ns),
                    frame_ns,
                })
            }
            _ => None,
        };
        let open = self.open.get_or_insert(StrokeLatency {
            stroke: s.stroke,
            ..StrokeLatency::default()
        });
        open.hand_to_force_ticks = open.hand_to_force_ticks.or(s.hand_to_force_ticks);
        open.first_change_tick = s.first_change.map(|fc| fc.sample_tick);
        open.first_visible = open.first_visible.or(first_visible);
        if settled.is_some() {
            open.settled = settled;
            self.close();
        }
    }

    /// Files the open stroke (with whatever it reached) among the finished ones.
    fn close(&mut self) {
        if let Some(o) = self.open.take() {
            if self.done.len() >= STROKES_KEPT {
                self.done.pop_front();
            }
            self.done.push_back(o);
        }
    }

    /// The finished strokes, oldest first, then the open one.
    pub fn strokes(&self) -> impl Iterator<Item = &StrokeLatency> {
        self.done.iter().chain(self.open.iter())
    }

    /// The newest stroke that has a first visible change.
    #[must_use]
    pub fn latest(&self) -> Option<&StrokeLatency> {
        self.open
            .iter()
            .chain(self.done.iter().rev())
            .find(|s| s.first_visible.is_some())
    }

    /// The figures over every stroke that changed the clay; `presenter` says what drew the
    /// frames.
    #[must_use]
    pub fn summary(&self, presenter: &str) -> MotionToPhotonSummary {
        let strokes: Vec<StrokeLatency> = self.strokes().copied().collect();
        summarize(&strokes, presenter)
    }
}

/// The figures over every stroke of `strokes` that changed the clay (strokes of several runs
/// may be pooled); `presenter` says what drew the frames.
#[must_use]
pub fn summarize(strokes: &[StrokeLatency], presenter: &str) -> MotionToPhotonSummary {
    let changed: Vec<&StrokeLatency> = strokes
        .iter()
        .filter(|s| s.first_change_tick.is_some())
        .collect();
    let ticks: Vec<f64> = changed
        .iter()
        .filter_map(|s| s.hand_to_force_ticks)
        .map(|t| t as f64)
        .collect();
    let firsts: Vec<StagePath> = changed.iter().filter_map(|s| s.first_visible).collect();
    let settled: Vec<StagePath> = changed.iter().filter_map(|s| s.settled).collect();
    MotionToPhotonSummary {
        presenter: presenter.to_string(),
        strokes: changed.len() as u64,
        hand_to_force_ticks: Spread::of(&ticks),
        first_visible_ms: Spread::of(&totals(&firsts)),
        settled_ms: Spread::of(&totals(&settled)),
        first_visible_stages: stage_spreads(&firsts),
        settled_stages: stage_spreads(&settled),
    }
}

fn totals(paths: &[StagePath]) -> Vec<f64> {
    paths.iter().map(StagePath::total_ms).collect()
}

fn stage_spreads(paths: &[StagePath]) -> StageSpreads {
    let of = |f: fn(&StagePath) -> f64| Spread::of(&paths.iter().map(f).collect::<Vec<_>>());
    StageSpreads {
        sample_to_step_ms: of(|p| ms(p.sample_ns, p.step_ns)),
        step_to_snapshot_ms: of(|p| ms(p.step_ns, p.snapshot_ns)),
        snapshot_to_mesh_ms: of(|p| ms(p.snapshot_ns, p.meshed_ns)),
        mesh_to_frame_ms: of(|p| ms(p.meshed_ns, p.frame_ns)),
    }
}

/// Milliseconds from `from_ns` to `to_ns` (negative if out of order, so a broken order shows).
fn ms(from_ns: u64, to_ns: u64) -> f64 {
    (to_ns as f64 - from_ns as f64) / 1.0e6
}

#[cfg(test)]
mod tests {
    use super::*;

    fn change(tick: u64, ns: u64, version: u64) -> ChangeStamp {
        ChangeStamp {
            sample_tick: tick,
            sample_ns: ns,
            step_ns: ns + 100,
            snapshot_version: version,
            snapshot_ns: ns + 200,
        }
    }

    fn stamp(version: u64, meshed_ns: u64, stroke: StrokeStamps) -> MeshStamp {
        MeshStamp {
            snapshot_version: version,
            meshed_ns,
            first_change_meshed_ns: None,
            settled_meshed_ns: None,
            stroke,
        }
    }

    #[test]
    fn a_stroke_is_visible_at_the_first_frame_that_drew_its_change_and_settled_at_the_settled_snapshots_frame()
     {
        let mut ledger = MotionToPhoton::new();
        let first = change(10, 10_000_000, 12);
        let mut s = StrokeStamps {
            stroke: 1,
            ..StrokeStamps::default()
        };
        // A frame before the change: nothing visible yet.
        ledger.frame(11_000_000, &stamp(11, 10_500_000, s));
        s.first_change = Some(first);
        s.last_change = Some(first);
        ledger.frame(12_000_000, &stamp(11, 10_500_000, s));
        assert!(
            ledger.latest().is_none(),
            "the drawn snapshot predates the change"
        );
        ledger.frame(30_000_000, &stamp(15, 29_000_000, s));
        let l = *ledger.latest().unwrap();
        let fv = l.first_visible.unwrap();
        assert_eq!((fv.sample_ns, fv.frame_ns), (10_000_000, 30_000_000));
        assert!(fv.is_ordered());
        assert_eq!(l.first_change_tick, Some(10));

        // The last push at 50 ms; the shape settles at snapshot 60, drawn by the frame at
        // 80 ms, but known settled only later.
        let last = change(50, 50_000_000, 52);
        s.last_change = Some(last);
        ledger.frame(80_000_000, &stamp(60, 79_000_000, s));
        ledger.frame(95_000_000, &stamp(70, 94_000_000, s));
        s.settled = Some(change(58, 58_000_000, 60));
        s.hand_to_force_ticks = Some(2);
        ledger.frame(500_000_000, &stamp(400, 499_000_000, s));
        let done = *ledger.strokes().next().unwrap();
        let settled = done.settled.unwrap();
        assert_eq!(
            (settled.sample_ns, settled.frame_ns),
            (50_000_000, 80_000_000)
        );
        let m = ledger.summary("test");
        assert_eq!(m.strokes, 1);
        assert_eq!(m.first_visible_ms.p50, 20.0);
        assert_eq!(m.settled_ms.p50, 30.0);
        assert_eq!(m.hand_to_force_ticks.p50, 2.0);

        // Later frames of the finished stroke change nothing; a new stroke opens a record.
        ledger.frame(600_000_000, &stamp(500, 599_000_000, s));
        assert_eq!(ledger.strokes().count(), 1);
        ledger.frame(
            700_000_000,
            &stamp(
                600,
                699_000_000,
                StrokeStamps {
                    stroke: 2,
                    ..StrokeStamps::default()
                },
            ),
        );
        assert_eq!(ledger.strokes().count(), 2);
        assert_eq!(
            ledger.summary("test").strokes,
            1,
            "stroke 2 changed nothing"
        );
    }
}
