//! Motion to photon: the serialisable per-stroke figures of the path a sculptor sees, from the
//! hand's sample to the frame that drew the clay it moved, and their table for the report.
//!
//! Not for the real-time path: building a summary sorts and allocates. The engine's ledger
//! (`dynaclay_engine::MotionToPhoton`) gathers the stamps; this module holds only the figures
//! and their text, so that `latency.json` ([`crate::ProfileDoc`]) and the report carry them.

use std::fmt::Write as _;

use serde::{Deserialize, Serialize};

/// Percentiles of a set of figures (nearest rank); all zero with `count` 0.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Spread {
    /// How many figures.
    pub count: u64,
    /// The median.
    pub p50: f64,
    /// The 95th percentile.
    pub p95: f64,
    /// The largest.
    pub max: f64,
}

impl Spread {
    /// The spread of `values` (NaNs are left out).
    #[must_use]
    pub fn of(values: &[f64]) -> Self {
        let mut v: Vec<f64> = values.iter().copied().filter(|x| !x.is_nan()).collect();
        if v.is_empty() {
            return Self::default();
        }
        v.sort_by(f64::total_cmp);
        let rank = |q: f64| {
            // Nearest rank: the smallest value with at least q of the figures at or below it.
            let r = (q * v.len() as f64).ceil() as usize;
            v[r.clamp(1, v.len()) - 1]
        };
        Self {
            count: v.len() as u64,
            p50: rank(0.50),
            p95: rank(0.95),
            max: v[v.len() - 1],
        }
    }
}

/// Where the time of one stretch of the path went, per stage, milliseconds (medians and 95th
/// percentiles over strokes).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct StageSpreads {
    /// From the hand's sample (the haptic tick that read it) to the simulation step that used it.
    pub sample_to_step_ms: Spread,
    /// From that step to the snapshot (triple-buffer publication) that carried its change.
    pub step_to_snapshot_ms: Spread,
    /// From the snapshot to the re-meshed bricks (the graphics loop applied it and re-meshed).
    pub snapshot_to_mesh_ms: Spread,
    /// From the bricks to the frame that drew them (upload, draw, the frame finished).
    pub mesh_to_frame_ms: Spread,
}

/// The motion-to-photon figures of a run: per stroke, hand → force (haptic ticks),
/// hand → first visible change and hand → settled shape (milliseconds), as percentiles over
/// the strokes, with the stages each went through.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct MotionToPhotonSummary {
    /// What drew the frames ("offscreen lavapipe", "window", "none: meshes only").
    pub presenter: String,
    /// Strokes that changed the clay.
    pub strokes: u64,
    /// Haptic ticks from the stroke's first sample that changed the clay to the tick whose
    /// force was rendered on the clay holding that change.
    pub hand_to_force_ticks: Spread,
    /// From the stroke's first sample that changed the clay to the first frame that drew the
    /// change.
    pub first_visible_ms: Spread,
    /// From the stroke's last sample that changed the clay (the hand's last push) to the first
    /// frame that drew the settled shape (every later change of that stroke together moves no
    /// coefficient by more than the settling tolerance).
    pub settled_ms: Spread,
    /// The first visible change, stage by stage.
    pub first_visible_stages: StageSpreads,
    /// The settled shape, stage by stage (the sample is the last push; the step, snapshot,
    /// mesh and frame are the settled shape's).
    pub settled_stages: StageSpreads,
}

/// The report's section: one row per figure, with the stages of the first visible change.
#[must_use]
pub fn motion_table(m: &MotionToPhotonSummary) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "Frames drawn by: {}; strokes that changed the clay: {}.\n",
        m.presenter, m.strokes
    );
    out.push_str("| figure | n | p50 | p95 | max |\n| --- | ---: | ---: | ---: | ---: |\n");
    let mut row = |name: &str, s: &Spread, unit: &str| {
        let _ = writeln!(
            out,
            "| {name} ({unit}) | {} | {:.1} | {:.1} | {:.1} |",
            s.count, s.p50, s.p95, s.max
        );
    };
    row("hand → force", &m.hand_to_force_ticks, "ticks");
    row("hand → first visible change", &m.first_visible_ms, "ms");
    row("hand → settled shape", &m.settled_ms, "ms");
    for (what, st) in [
        ("first visible", &m.first_visible_stages),
        ("settled", &m.settled_stages),
    ] {
        row(
            &format!("{what}: sample → step"),
            &st.sample_to_step_ms,
            "ms",
        );
        row(
            &format!("{what}: step → snapshot"),
            &st.step_to_snapshot_ms,
            "ms",
        );
        row(
            &format!("{what}: snapshot → mesh"),
            &st.snapshot_to_mesh_ms,
            "ms",
        );
        row(&format!("{what}: mesh → frame"), &st.mesh_to_frame_ms, "ms");
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_rank_percentiles() {
        let v: Vec<f64> = (1..=20).map(f64::from).collect();
        let s = Spread::of(&v);
        assert_eq!((s.count, s.p50, s.p95, s.max), (20, 10.0, 19.0, 20.0));
        let one = Spread::of(&[7.0, f64::NAN]);
        assert_eq!((one.count, one.p50, one.p95, one.max), (1, 7.0, 7.0, 7.0));
        assert_eq!(Spread::of(&[]), Spread::default());
    }

    #[test]
    fn the_table_names_every_figure() {
        let m = MotionToPhotonSummary {
            presenter: "offscreen".into(),
            strokes: 2,
            first_visible_ms: Spread::of(&[12.0, 30.0]),
            ..MotionToPhotonSummary::default()
        };
        let t = motion_table(&m);
        assert!(t.contains("offscreen") && t.contains("strokes that changed the clay: 2"));
        assert!(t.contains("| hand → first visible change (ms) | 2 | 12.0 | 30.0 | 30.0 |"));
        assert!(t.contains("settled: mesh → frame"));
    }
}
