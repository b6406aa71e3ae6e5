//! Live loop latency with `egui_plot`: per loop, a histogram of period error and compute time
//! over the last two minutes (logarithmic µs/ms axis, share of ticks on a log scale, p99
//! marked) and a scrolling timeline of each interval's worst period error and compute time
//! with the period and the deadline misses marked.
//!
//! The loops publish their figures about once a second, with coarse half-octave bins
//! ([`dynaclay_loops::LogBins`]) of both quantities since they started. A loop's sample is
//! added only when that loop published new figures (a new view version whose tick count for
//! the loop moved on), so a stalled loop shows a flat, ageing timeline rather than invented
//! points; each sample keeps what was recorded since the loop's previous sample (the
//! difference of the bins), so the histogram and the timeline describe recent ticks rather
//! than the whole run.

use std::collections::VecDeque;

use dynaclay_loops::{LatencyStats, LogBins, share_label, time_label};
use egui_plot::{
    Axis, AxisHints, Bar, BarChart, GridInput, GridMark, HLine, HoverPosition, Line, Plot,
    PlotPoint, Points, VLine,
};

use super::view::LoopId;

/// Samples kept per loop (the loops publish figures about once a second: two minutes).
pub const HISTORY_LEN: usize = 120;

/// The lowest share of ticks drawn (log₁₀): 10⁻⁶, one tick in a million.
const SHARE_FLOOR_LOG10: f64 = -6.0;
/// The lower edge given to the first bin (which starts at zero), µs, so it has a width on a
/// log axis.
const FIRST_BIN_FLOOR_US: f64 = 0.064;
/// Plot heights, points.
const HISTOGRAM_HEIGHT: f32 = 120.0;
const TIMELINE_HEIGHT: f32 = 110.0;

const PERIOD_ERROR_COLOUR: egui::Color32 = egui::Color32::from_rgb(90, 150, 240);
const COMPUTE_COLOUR: egui::Color32 = egui::Color32::from_rgb(235, 110, 90);
const MISS_COLOUR: egui::Color32 = egui::Color32::from_rgb(230, 60, 60);

/// One point of a loop's history.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LatencySample {
    /// Seconds since the app started.
    pub t_s: f64,
    /// The loop's figures since it started, as published.
    pub period_error_p99_us: f64,
    pub compute_p50_us: f64,
    pub compute_p99_us: f64,
    pub rate_hz: f64,
    /// What was recorded since the loop's previous sample.
    pub period_error_bins: LogBins,
    pub compute_bins: LogBins,
    /// Deadline misses since the previous sample.
    pub new_misses: u64,
}

/// The recent history of the three loops.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LatencyHistory {
    pub samples: [VecDeque<LatencySample>; 3],
    /// The latest figures per loop, for the numeric summary.
    pub latest: [LatencyStats; 3],
    last_version: u64,
    /// Each loop's figures at its last sample (tick count, bins, misses).
    last_seen: [LatencyStats; 3],
}

/// Where the pointer is, on a data point or not.
fn hover_point(pos: &HoverPosition<'_>) -> PlotPoint {
    match *pos {
        HoverPosition::NearDataPoint { position, .. } | HoverPosition::Elsewhere { position } => {
            position
        }
    }
}

/// Grid marks at every whole number (every decade, on a log₁₀ axis) inside the bounds; even
/// decades are the major marks, so on a narrow plot every other decade keeps its label.
fn decade_marks(input: GridInput) -> Vec<GridMark> {
    let (lo, hi) = input.bounds;
    if !(lo.is_finite() && hi.is_finite()) || hi - lo > 40.0 {
        return Vec::new();
    }
    let first = lo.ceil() as i64;
    let last = hi.floor() as i64;
    (first..=last)
        .map(|d| GridMark {
            value: d as f64,
            step_size: if d % 2 == 0 { 2.0 } else { 1.0 },
        })
        .collect()
}

/// An axis whose tick labels may sit closer than egui_plot's default (the panel is narrow).
fn tight_axis(axis: Axis, format: fn(f64) -> String) -> AxisHints<'static> {
    let hints = match axis {
        Axis::X => AxisHints::new_x().label_spacing(28.0..=40.0),
        Axis::Y => AxisHints::new_y().label_spacing(14.0..=20.0),
    };
    hints.formatter(move |mark, _| format(mark.value))
}

fn log_time_label(log10_us: f64) -> String {
    time_label(10f64.powf(log10_us))
}

fn log_share_label(log10_share: f64) -> String {
    share_label(10f64.powf(log10_share))
}

fn seconds_label(s: f64) -> String {
    format!("{s:.0} s")
}

/// A line of coloured keys above a plot (in place of a legend, which would cover a small plot).
fn keys(ui: &mut egui::Ui, entries: &[(String, egui::Color32)]) {
    ui.horizontal_wrapped(|ui| {
        ui.spacing_mut().item_spacing.x = 10.0;
        for (text, colour) in entries {
            ui.label(
                egui::RichText::new(format!("— {text}"))
                    .small()
                    .color(*colour),
            );
        }
    });
}

/// One bar per non-empty bin: x is log₁₀ µs (the bin's geometric middle, its log width), y
/// log₁₀ of the bin's share of ticks, drawn up from [`SHARE_FLOOR_LOG10`].
#[must_use]
pub fn histogram_bars(bins: &LogBins) -> Vec<Bar> {
    let total = bins.total();
    if total == 0 {
        return Vec::new();
    }
    bins.counts()
        .iter()
        .enumerate()
        .filter(|(_, c)| **c > 0)
        .map(|(i, &c)| {
            let lo = (LogBins::lower_edge_ns(i) / 1e3)
                .max(FIRST_BIN_FLOOR_US)
                .log10();
            let hi = (LogBins::upper_edge_ns(i) / 1e3).log10();
            let share = (c as f64 / total as f64).log10().max(SHARE_FLOOR_LOG10);
            Bar::new((lo + hi) / 2.0, share - SHARE_FLOOR_LOG10)
                .width((hi - lo) * 0.9)
                .base_offset(SHARE_FLOOR_LOG10)
        })
        .collect()
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
        for ((hist, s), seen) in self.samples.iter_mut().zip(loops).zip(&mut self.last_seen) {
            if s.ticks == 0 || s.ticks == seen.ticks {
                continue;
            }
            // A loop that started again (fewer ticks than before) counts from zero.
            let restarted = s.ticks < seen.ticks;
            let earlier = if restarted {
                LatencyStats::default()
            } else {
                *seen
            };
            *seen = *s;
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
                period_error_bins: s.period_error_bins.since(&earlier.period_error_bins),
                compute_bins: s.compute_bins.since(&earlier.compute_bins),
                new_misses: s.deadline_misses.saturating_sub(earlier.deadline_misses),
            });
        }
        added
    }

    /// The bins of every sample kept for loop `index` (the last two minutes), added up:
    /// (period error, compute time).
    #[must_use]
    pub fn window_bins(&self, index: usize) -> (LogBins, LogBins) {
        let mut period_error = LogBins::default();
        let mut compute = LogBins::default();
        for s in &self.samples[index] {
            period_error.add(&s.period_error_bins);
            compute.add(&s.compute_bins);
        }
        (period_error, compute)
    }

    /// Per loop: a summary, the histogram and the timeline.
    pub fn ui(&self, ui: &mut egui::Ui) {
        let now_s = self
            .samples
            .iter()
            .filter_map(|h| h.back().map(|s| s.t_s))
            .fold(0.0, f64::max);
        for id in LoopId::ALL {
            let s = &self.latest[id.index()];
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
            self.histogram_ui(ui, id);
            self.timeline_ui(ui, id, now_s, s.nominal_rate_hz);
        }
    }

    fn histogram_ui(&self, ui: &mut egui::Ui, id: LoopId) {
        let (period_error, compute) = self.window_bins(id.index());
        let p99 = |b: &LogBins| b.quantile_ns(0.99).map(|ns| ns / 1e3);
        let marks = [
            ("period error p99", p99(&period_error), PERIOD_ERROR_COLOUR),
            ("compute p99", p99(&compute), COMPUTE_COLOUR),
        ];
        let mut entries = Vec::new();
        for (name, value, colour) in &marks {
            if let Some(us) = value {
                entries.push((format!("{name} ≤ {}", time_label(*us)), *colour));
            }
        }
        keys(ui, &entries);
        Plot::new(("latency histogram", id.index()))
            .height(HISTOGRAM_HEIGHT)
            .allow_zoom(false)
            .allow_drag(false)
            .allow_scroll(false)
            .allow_boxed_zoom(false)
            .include_y(SHARE_FLOOR_LOG10)
            .include_y(0.0)
            .x_grid_spacer(decade_marks)
            .y_grid_spacer(decade_marks)
            .custom_x_axes(vec![tight_axis(Axis::X, log_time_label)])
            .custom_y_axes(vec![tight_axis(Axis::Y, log_share_label)])
            .label_formatter(|pos| {
                let p = hover_point(pos);
                Some(format!(
                    "{}: {} of ticks",
                    time_label(10f64.powf(p.x)),
                    share_label(10f64.powf(p.y))
                ))
            })
            .show(ui, |plot| {
                plot.bar_chart(
                    BarChart::new("period error", histogram_bars(&period_error))
                        .color(PERIOD_ERROR_COLOUR.gamma_multiply(0.6)),
                );
                plot.bar_chart(
                    BarChart::new("compute", histogram_bars(&compute))
                        .color(COMPUTE_COLOUR.gamma_multiply(0.6)),
                );
                for (name, value, colour) in marks {
                    if let Some(us) = value {
                        plot.vline(
                            VLine::new(format!("{name} ≤ {}", time_label(us)), us.log10())
                                .color(colour)
                                .width(1.5),
                        );
                    }
                }
            });
    }

    fn timeline_ui(&self, ui: &mut egui::Ui, id: LoopId, now_s: f64, nominal_rate_hz: f64) {
        let hist = &self.samples[id.index()];
        let worst = |pick: fn(&LatencySample) -> &LogBins| -> Vec<[f64; 2]> {
            hist.iter()
                .filter_map(|s| {
                    pick(s)
                        .worst_ns()
                        .map(|ns| [s.t_s - now_s, (ns / 1e3).log10()])
                })
                .collect()
        };
        let period_error = worst(|s| &s.period_error_bins);
        let compute = worst(|s| &s.compute_bins);
        let period_us = if nominal_rate_hz > 0.0 {
            1e6 / nominal_rate_hz
        } else {
            1000.0
        };
        let top = period_error
            .iter()
            .chain(&compute)
            .map(|p| p[1])
            .fold(period_us.log10(), f64::max)
            + 0.3;
        let misses: Vec<[f64; 2]> = hist
            .iter()
            .filter(|s| s.new_misses > 0)
            .map(|s| [s.t_s - now_s, top])
            .collect();
        keys(
            ui,
            &[
                ("worst period error".into(), PERIOD_ERROR_COLOUR),
                ("worst compute".into(), COMPUTE_COLOUR),
                (
                    format!("period {}", time_label(period_us)),
                    egui::Color32::GRAY,
                ),
                ("deadline misses".into(), MISS_COLOUR),
            ],
        );
        Plot::new(("latency timeline", id.index()))
            .height(TIMELINE_HEIGHT)
            .allow_zoom(false)
            .allow_drag(false)
            .allow_scroll(false)
            .allow_boxed_zoom(false)
            .include_x(-(HISTORY_LEN as f64))
            .include_x(0.0)
            .include_y(-1.0)
            .include_y(top)
            .y_grid_spacer(decade_marks)
            .custom_x_axes(vec![tight_axis(Axis::X, seconds_label)])
            .custom_y_axes(vec![tight_axis(Axis::Y, log_time_label)])
            .label_formatter(|pos| {
                let p = hover_point(pos);
                Some(format!("{:.0} s: {}", p.x, time_label(10f64.powf(p.y))))
            })
            .show(ui, |plot| {
                plot.hline(
                    HLine::new(
                        format!("period {}", time_label(period_us)),
                        period_us.log10(),
                    )
                    .color(egui::Color32::GRAY)
                    .width(1.0),
                );
                plot.line(
                    Line::new("worst period error", period_error)
                        .color(PERIOD_ERROR_COLOUR)
                        .width(1.5),
                );
                plot.line(
                    Line::new("worst compute", compute)
                        .color(COMPUTE_COLOUR)
                        .width(1.5),
                );
                if !misses.is_empty() {
                    plot.points(
                        Points::new("deadline misses", misses)
                            .color(MISS_COLOUR)
                            .shape(egui_plot::MarkerShape::Cross)
                            .radius(4.0),
                    );
                }
            });
    }
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
    fn each_sample_keeps_what_was_recorded_since_the_last() {
        let mut h = LatencyHistory::default();
        let idle = LatencyStats::default();
        let mut s = LatencyStats {
            ticks: 100,
            deadline_misses: 1,
            ..LatencyStats::default()
        };
        for _ in 0..100 {
            s.compute_bins.record(5_000);
            s.period_error_bins.record(1_000);
        }
        h.record(1, 1.0, &[s, idle, idle]);
        s.ticks = 200;
        s.deadline_misses = 3;
        for _ in 0..100 {
            s.compute_bins.record(5_000);
        }
        s.compute_bins.record(2_000_000);
        h.record(2, 2.0, &[s, idle, idle]);
        let second = h.samples[0][1];
        assert_eq!(second.compute_bins.total(), 101);
        assert_eq!(second.period_error_bins.total(), 0);
        assert_eq!(second.new_misses, 2);
        assert!(second.compute_bins.worst_ns().unwrap() > 2e6);
        let (period_error, compute) = h.window_bins(0);
        assert_eq!((period_error.total(), compute.total()), (100, 201));
        // The loop started again: its figures count from zero.
        let mut again = LatencyStats {
            ticks: 10,
            ..LatencyStats::default()
        };
        again.compute_bins.record(5_000);
        h.record(3, 3.0, &[again, idle, idle]);
        assert_eq!(h.samples[0][2].compute_bins.total(), 1);
    }

    #[test]
    fn bars_sit_on_a_log_axis_from_the_share_floor() {
        assert!(histogram_bars(&LogBins::default()).is_empty());
        let mut b = LogBins::default();
        for _ in 0..999 {
            b.record(10_000);
        }
        b.record(1_000_000);
        let bars = histogram_bars(&b);
        assert_eq!(bars.len(), 2);
        // 10 µs and 1 ms land near log₁₀ 1 and 3; 99.9% and 0.1% of ticks.
        assert!((bars[0].argument - 1.0).abs() < 0.2, "{}", bars[0].argument);
        assert!((bars[1].argument - 3.0).abs() < 0.2, "{}", bars[1].argument);
        assert!((bars[1].value + SHARE_FLOOR_LOG10 - (-3.0)).abs() < 1e-9);
        assert_eq!(bars[0].base_offset, Some(SHARE_FLOOR_LOG10));
    }
}
