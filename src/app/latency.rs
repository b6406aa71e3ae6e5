//! Live loop-latency plots: a short history of each loop's published figures (period error,
//! compute time, achieved rate) and strip charts drawn with egui's painter.
//!
//! A loop's sample is added only when that loop published new statistics (a new view version
//! whose tick count for the loop moved on), so a stalled loop shows a flat, ageing chart
//! rather than invented points, and the bridge republishing the same figures adds nothing. The charts use the
//! painter directly rather than `egui_plot`: three fixed-size strip charts need only line
//! strips and a scale, and a plotting crate would have to track egui's version exactly.

use std::collections::VecDeque;

use dynaclay_loops::LatencyStats;

use super::view::LoopId;

/// Samples kept per loop (the loops publish figures about once a second: two minutes).
pub const HISTORY_LEN: usize = 120;

/// One point of a loop's history.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LatencySample {
    /// Seconds since the app started.
    pub t_s: f64,
    pub period_error_p99_us: f64,
    pub compute_p50_us: f64,
    pub compute_p99_us: f64,
    pub rate_hz: f64,
}

/// The recent history of the three loops.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LatencyHistory {
    pub samples: [VecDeque<LatencySample>; 3],
    /// The latest figures per loop, for the numeric summary.
    pub latest: [LatencyStats; 3],
    last_version: u64,
    /// Tick count of each loop's last recorded figures.
    last_ticks: [u64; 3],
}

impl LatencyHistory {
    /// Records `loops` (from a view of `version`) at `t_s`: one sample for each loop whose
    /// figures are new (ticks recorded and changed since its last sample). Returns whether
    /// a sample was added.
    pub fn record(&mut self, version: u64, t_s: f64, loops: &[LatencyStats; 3]) -> bool {
        if version == 0 || version == self.last_version {
            return false;
        }
        self.last_version = version;
        self.latest = *loops;
        let mut added = false;
        for ((hist, s), seen) in self.samples.iter_mut().zip(loops).zip(&mut self.last_ticks) {
            if s.ticks == 0 || s.ticks == *seen {
                continue;
            }
            *seen = s.ticks;
            added = true;
            if hist.len() == HISTORY_LEN {
                hist.pop_front();
            }
            hist.push_back(LatencySample {
                t_s,
                period_error_p99_us: s.period_error.p99_us,
                compute_p50_us: s.compute.p50_us,
                compute_p99_us: s.compute.p99_us,
                rate_hz: s.achieved_rate_hz,
            });
        }
        added
    }

    /// Draws a summary line and two strip charts (period error, compute time) per loop.
    pub fn ui(&self, ui: &mut egui::Ui) {
        for id in LoopId::ALL {
            let s = &self.latest[id.index()];
            let hist = &self.samples[id.index()];
            ui.strong(id.name());
            if s.ticks == 0 {
                ui.weak("no figures yet");
                continue;
            }
            ui.label(format!(
                "{:.0} / {:.0} Hz, {} misses, {} late >1 ms",
                s.achieved_rate_hz, s.nominal_rate_hz, s.deadline_misses, s.late_over_1ms
            ));
            ui.label(format!(
                "period error p99 {:.1} µs, compute p50 {:.1} / p99 {:.1} µs",
                s.period_error.p99_us, s.compute.p50_us, s.compute.p99_us
            ));
            let colours = [
                egui::Color32::from_rgb(230, 160, 60),
                egui::Color32::from_rgb(90, 170, 240),
                egui::Color32::from_rgb(120, 220, 140),
            ];
            strip_chart(
                ui,
                "period error p99 µs",
                &[(
                    hist.iter().map(|p| p.period_error_p99_us).collect(),
                    colours[0],
                )],
            );
            strip_chart(
                ui,
                "compute p50 / p99 µs",
                &[
                    (hist.iter().map(|p| p.compute_p50_us).collect(), colours[2]),
                    (hist.iter().map(|p| p.compute_p99_us).collect(), colours[1]),
                ],
            );
        }
    }
}

/// The upper end of a chart's scale: the largest value rounded up to 1, 2 or 5 × 10ⁿ.
#[must_use]
pub fn nice_ceiling(max: f64) -> f64 {
    if !(max.is_finite() && max > 0.0) {
        return 1.0;
    }
    let decade = 10f64.powf(max.log10().floor());
    [1.0, 2.0, 5.0, 10.0]
        .into_iter()
        .map(|m| m * decade)
        .find(|&v| v >= max)
        .unwrap_or(10.0 * decade)
}

fn strip_chart(ui: &mut egui::Ui, title: &str, series: &[(Vec<f64>, egui::Color32)]) {
    let width = ui.available_width().max(60.0);
    let (rect, _) = ui.allocate_exact_size(egui::vec2(width, 48.0), egui::Sense::hover());
    let painter = ui.painter_at(rect);
    let visuals = ui.visuals();
    painter.rect_filled(rect, 2.0, visuals.extreme_bg_color);
    let max = series
        .iter()
        .flat_map(|(v, _)| v.iter().copied())
        .fold(0.0f64, f64::max);
    let top = nice_ceiling(max);
    for (values, colour) in series {
        if values.len() < 2 {
            continue;
        }
        let n = (HISTORY_LEN - 1) as f32;
        let offset = HISTORY_LEN - values.len();
        let points: Vec<egui::Pos2> = values
            .iter()
            .enumerate()
            .map(|(i, &v)| {
                let x = rect.left() + rect.width() * (offset + i) as f32 / n;
                let y = rect.bottom() - rect.height() * (v / top).clamp(0.0, 1.0) as f32;
                egui::pos2(x, y)
            })
            .collect();
        painter.add(egui::Shape::line(points, egui::Stroke::new(1.5, *colour)));
    }
    let font = egui::FontId::monospace(10.0);
    painter.text(
        rect.left_top() + egui::vec2(3.0, 2.0),
        egui::Align2::LEFT_TOP,
        format!("{title} (0–{top})"),
        font,
        visuals.text_color(),
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stats(p99: f64) -> LatencyStats {
        let mut s = LatencyStats {
            ticks: 10 + p99 as u64,
            achieved_rate_hz: 999.0,
            ..LatencyStats::default()
        };
        s.period_error.p99_us = p99;
        s
    }

    #[test]
    fn samples_are_added_once_per_new_version_and_bounded() {
        let mut h = LatencyHistory::default();
        let idle = LatencyStats::default();
        assert!(!h.record(0, 0.0, &[stats(1.0), idle, idle]));
        assert!(h.record(1, 0.1, &[stats(1.0), idle, idle]));
        assert!(!h.record(1, 0.2, &[stats(2.0), idle, idle]));
        assert_eq!(h.samples[0].len(), 1);
        assert!(h.samples[1].is_empty(), "a loop with no ticks adds nothing");
        // A new view repeating a loop's figures (same tick count) adds nothing for it.
        assert!(!h.record(2, 0.3, &[stats(1.0), idle, idle]));
        assert!(h.record(3, 0.4, &[stats(1.0), stats(3.0), idle]));
        assert_eq!((h.samples[0].len(), h.samples[1].len()), (1, 1));
        for v in 4..(HISTORY_LEN as u64 + 50) {
            h.record(v, v as f64, &[stats(v as f64), idle, idle]);
        }
        assert_eq!(h.samples[0].len(), HISTORY_LEN);
        let last = h.samples[0].back().unwrap();
        assert_eq!(last.period_error_p99_us, (HISTORY_LEN + 49) as f64);
    }

    #[test]
    fn nice_ceiling_rounds_up_to_one_two_five() {
        assert_eq!(nice_ceiling(0.0), 1.0);
        assert_eq!(nice_ceiling(f64::NAN), 1.0);
        assert_eq!(nice_ceiling(3.0), 5.0);
        assert_eq!(nice_ceiling(12.0), 20.0);
        assert_eq!(nice_ceiling(500.0), 500.0);
        assert_eq!(nice_ceiling(501.0), 1000.0);
    }
}
