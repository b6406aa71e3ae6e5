//! SVG plots of loop latency: per loop, a histogram of period error and one of compute time, on
//! logarithmic axes so both the body of the distribution and its rare tail are visible.
//!
//! Not for the real-time path (allocates, may write files). Works from a [`LatencyRecorder`],
//! which a loop hands back when it ends ([`crate::LoopReport::recorder`]).

use std::fmt;
use std::path::{Path, PathBuf};

use hdrhistogram::Histogram;
use plotters::prelude::*;

use crate::recorder::LatencyRecorder;

/// Size of one panel in pixels.
const PANEL: (u32, u32) = (520, 300);
/// Smallest bin upper edge (ns) and growth factor of the logarithmic bins.
const FIRST_BIN_NS: u64 = 100;
const BIN_GROWTH: f64 = 1.5;

/// A plot could not be drawn or written.
#[derive(Debug)]
pub enum PlotError {
    /// Plotters failed while drawing.
    Draw(String),
    /// The SVG could not be written to `path`.
    Write {
        /// Where the file was to go.
        path: PathBuf,
        /// The OS error.
        source: std::io::Error,
    },
}

impl fmt::Display for PlotError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Draw(m) => write!(f, "drawing latency plot: {m}"),
            Self::Write { path, source } => {
                write!(f, "writing latency plot {}: {source}", path.display())
            }
        }
    }
}

impl std::error::Error for PlotError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Self::Write { source, .. } => Some(source),
            Self::Draw(_) => None,
        }
    }
}

fn draw_err(e: impl fmt::Display) -> PlotError {
    PlotError::Draw(e.to_string())
}

/// Renders the histograms of several loops (one row each: period error, compute time) as an SVG
/// document.
///
/// # Errors
/// [`PlotError::Draw`] if plotters fails.
pub fn latency_svg(loops: &[(&str, &LatencyRecorder)]) -> Result<String, PlotError> {
    let rows = u32::try_from(loops.len().max(1)).unwrap_or(u32::MAX);
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (PANEL.0 * 2, PANEL.1.saturating_mul(rows)))
            .into_drawing_area();
        root.fill(&WHITE).map_err(draw_err)?;
        let panels = root.split_evenly((rows as usize, 2));
        for (row, (name, rec)) in loops.iter().enumerate() {
            draw_histogram(
                &panels[row * 2],
                &format!("{name}: period error"),
                rec.period_error_histogram(),
                &BLUE,
            )?;
            draw_histogram(
                &panels[row * 2 + 1],
                &format!("{name}: compute time"),
                rec.compute_histogram(),
                &RED,
            )?;
        }
        root.present().map_err(draw_err)?;
    }
    Ok(svg)
}

/// Writes [`latency_svg`] to `path`.
///
/// # Errors
/// [`PlotError::Draw`] if plotters fails, [`PlotError::Write`] (with the path) if the file
/// cannot be written.
pub fn write_latency_svg(path: &Path, loops: &[(&str, &LatencyRecorder)]) -> Result<(), PlotError> {
    let svg = latency_svg(loops)?;
    std::fs::write(path, svg).map_err(|source| PlotError::Write {
        path: path.to_path_buf(),
        source,
    })
}

/// Logarithmic bins of a histogram in µs: (lower edge, upper edge, count), empty bins left out.
fn log_bins(hist: &Histogram<u64>) -> Vec<(f64, f64, u64)> {
    let mut bins = Vec::new();
    if hist.is_empty() {
        return bins;
    }
    let mut lower_ns = 0u64;
    for v in hist.iter_log(FIRST_BIN_NS, BIN_GROWTH) {
        let upper_ns = v.value_iterated_to();
        let count = v.count_since_last_iteration();
        if count > 0 {
            bins.push((lower_ns as f64 / 1e3, upper_ns as f64 / 1e3, count));
        }
        lower_ns = upper_ns;
    }
    bins
}

fn draw_histogram<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    title: &str,
    hist: &Histogram<u64>,
    colour: &RGBColor,
) -> Result<(), PlotError> {
    let bins = log_bins(hist);
    let x_min = FIRST_BIN_NS as f64 / 1e3 / BIN_GROWTH;
    let x_max = bins.iter().map(|b| b.1).fold(x_min * 10.0, f64::max) * BIN_GROWTH;
    let y_max = bins.iter().map(|b| b.2).max().unwrap_or(1) as f64 * 2.0;
    let y_min = 0.5;
    let mut chart = ChartBuilder::on(area)
        .caption(title, ("sans-serif", 16))
        .margin(8)
        .x_label_area_size(36)
        .y_label_area_size(56)
        .build_cartesian_2d((x_min..x_max).log_scale(), (y_min..y_max).log_scale())
        .map_err(draw_err)?;
    chart
        .configure_mesh()
        .x_desc("µs (log)")
        .y_desc("ticks (log)")
        .x_label_formatter(&|v| format!("{v:.3}"))
        .y_label_formatter(&|v| format!("{v:.0}"))
        .draw()
        .map_err(draw_err)?;
    chart
        .draw_series(bins.iter().map(|&(lo, hi, count)| {
            Rectangle::new(
                [(lo.max(x_min), y_min), (hi, count as f64)],
                colour.mix(0.6).filled(),
            )
        }))
        .map_err(draw_err)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use std::time::{Duration, Instant};

    use super::*;
    use crate::recorder::TickTiming;

    fn recorder_with_ticks() -> LatencyRecorder {
        let period = Duration::from_millis(1);
        let mut rec = LatencyRecorder::new(period);
        let t0 = Instant::now();
        for i in 0..500u32 {
            let late = Duration::from_nanos(u64::from(i % 7) * 300);
            rec.record_tick(&TickTiming {
                scheduled: t0 + period * i,
                woke: t0 + period * i + late,
                compute: Duration::from_micros(3 + u64::from(i % 5)),
                skipped_before: 0,
            });
        }
        rec
    }

    #[test]
    fn bins_cover_every_recorded_tick() {
        let rec = recorder_with_ticks();
        let bins = log_bins(rec.compute_histogram());
        assert_eq!(bins.iter().map(|b| b.2).sum::<u64>(), 500);
        assert!(
            bins.windows(2).all(|w| w[0].1 <= w[1].0 + 1e-9),
            "bins overlap"
        );
        assert!(
            log_bins(LatencyRecorder::new(Duration::from_millis(1)).compute_histogram()).is_empty()
        );
    }

    #[test]
    fn svg_has_a_panel_per_loop_and_quantity() {
        let a = recorder_with_ticks();
        let b = LatencyRecorder::new(Duration::from_micros(250));
        let svg = latency_svg(&[("haptic", &a), ("sim", &b)]).expect("svg");
        assert!(svg.starts_with("<svg"), "{}", &svg[..svg.len().min(80)]);
        for title in [
            "haptic: period error",
            "haptic: compute time",
            "sim: period error",
            "sim: compute time",
        ] {
            assert!(svg.contains(title), "missing {title}");
        }
        assert!(svg.contains("<rect"));
    }

    #[test]
    fn write_error_names_the_path() {
        let rec = recorder_with_ticks();
        let path = Path::new("/nonexistent-dir-for-dynaclay-test/plot.svg");
        let err = write_latency_svg(path, &[("x", &rec)]).expect_err("must fail");
        assert!(
            err.to_string()
                .contains("/nonexistent-dir-for-dynaclay-test/plot.svg")
        );
    }
}
