//! Plots of loop latency, one page in SVG or PNG: per loop, a histogram of period error and one
//! of compute time on a logarithmic µs/ms axis (so both the body of the distribution and its
//! rare tail are visible) with p50/p99/p99.9/max marked, and a timeline of the run with
//! deadline misses marked. The platform probe's period error is drawn over each loop's, so
//! engine and machine are seen together.
//!
//! The PNG is drawn by plotters' bitmap backend with text from an embedded font (Ubuntu Light,
//! the one egui ships, drawn by [`CrispText`]), so it reads the same on a machine without system
//! fonts, and encoded with `png`.
//!
//! Not for the real-time path (allocates, may write files). Works from a [`LatencyRecorder`],
//! which a loop hands back when it ends ([`crate::LoopReport::recorder`]).

use std::path::Path;
use std::sync::OnceLock;

use hdrhistogram::Histogram;
use plotters::backend::RGBPixel;
use plotters::coord::Shift;
use plotters::prelude::*;

use crate::glyphs::CrispText;
use crate::recorder::{LatencyRecorder, Percentiles};
use crate::timeline::Timeline;

/// Size of one panel in pixels (three per loop: a page 1440 px wide).
const PANEL: (u32, u32) = (480, 300);
/// Grid colours: light enough that the data stands out.
const GRID_FINE: RGBColor = RGBColor(242, 242, 242);
const GRID_MAIN: RGBColor = RGBColor(220, 220, 220);
/// The probe's overlay colour.
const PROBE_COLOUR: RGBColor = RGBColor(60, 60, 60);
/// Percentile marker colour.
const MARKER_COLOUR: RGBColor = RGBColor(200, 120, 0);
/// Smallest bin upper edge (ns) and growth factor of the logarithmic bins.
const FIRST_BIN_NS: u64 = 100;
const BIN_GROWTH: f64 = 1.5;
/// The font family every label asks for.
const FONT_FAMILY: &str = "sans-serif";

/// A plot could not be drawn or written.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// Plotters failed while drawing.
    #[error("drawing latency plot: {0}")]
    Draw(String),
    /// The embedded font could not be loaded for the plots' text.
    #[error("loading the plot font: {0}")]
    Font(String),
    /// The PNG could not be encoded.
    #[error("encoding latency plot as PNG: {0}")]
    Encode(#[from] png::EncodingError),
    /// The plot could not be written (the previous file at the path is untouched).
    #[error("writing latency plot: {0}")]
    Write(#[source] dynaclay_files::WriteError),
}

fn draw_err(e: impl std::fmt::Display) -> PlotError {
    PlotError::Draw(e.to_string())
}

/// Registers the embedded font for [`FONT_FAMILY`] once per process; every later call returns
/// the first outcome.
fn ensure_font() -> Result<(), PlotError> {
    static REGISTERED: OnceLock<Result<(), String>> = OnceLock::new();
    REGISTERED
        .get_or_init(|| {
            plotters::style::register_font(
                FONT_FAMILY,
                FontStyle::Normal,
                epaint_default_fonts::UBUNTU_LIGHT,
            )
            .map_err(|_| "the embedded Ubuntu Light font is not a valid font".to_string())
        })
        .clone()
        .map_err(PlotError::Font)
}

/// The page's size in pixels for `loops` rows (one row per loop, at least one).
#[must_use]
pub fn page_size(loops: usize) -> (u32, u32) {
    let rows = u32::try_from(loops.max(1)).unwrap_or(u32::MAX);
    (PANEL.0 * 3, PANEL.1.saturating_mul(rows))
}

/// Draws the page on `root`: per loop (one row each) the period-error histogram with the
/// probe's overlaid when `probe` is given, the compute-time histogram and the timeline.
fn draw_page<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    loops: &[(&str, &LatencyRecorder)],
    probe: Option<&LatencyRecorder>,
) -> Result<(), PlotError> {
    root.fill(&WHITE).map_err(draw_err)?;
    let panels = root.split_evenly((loops.len().max(1), 3));
    for (row, (name, rec)) in loops.iter().enumerate() {
        let stats = rec.stats();
        draw_histogram(
            &panels[row * 3],
            &Histo {
                title: format!("{name}: period error"),
                series: name,
                hist: rec.period_error_histogram(),
                marks: stats.period_error,
                colour: BLUE,
                // Only a loop at the probe's rate is comparable with it.
                probe: probe
                    .filter(|p| p.nominal_period() == rec.nominal_period())
                    .map(LatencyRecorder::period_error_histogram),
            },
        )?;
        draw_histogram(
            &panels[row * 3 + 1],
            &Histo {
                title: format!("{name}: compute time"),
                series: name,
                hist: rec.compute_histogram(),
                marks: stats.compute,
                colour: RED,
                probe: None,
            },
        )?;
        draw_timeline(
            &panels[row * 3 + 2],
            &format!("{name}: over the run"),
            rec.timeline(),
            rec.nominal_period(),
        )?;
    }
    root.present().map_err(draw_err)
}

/// Renders one page as SVG text: per loop (one row each) the period-error histogram with the
/// probe's overlaid when `probe` is given, the compute-time histogram and the timeline.
///
/// # Errors
/// [`PlotError::Draw`] if plotters fails, [`PlotError::Font`] if the embedded font is refused.
pub fn latency_svg(
    loops: &[(&str, &LatencyRecorder)],
    probe: Option<&LatencyRecorder>,
) -> Result<String, PlotError> {
    ensure_font()?;
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, page_size(loops.len())).into_drawing_area();
        draw_page(&root, loops, probe)?;
    }
    Ok(svg)
}

/// Renders the page of [`latency_svg`] as an 8-bit RGB PNG of [`page_size`] pixels, returned
/// as the file's bytes.
///
/// # Errors
/// [`PlotError::Draw`] if plotters fails, [`PlotError::Font`] if the embedded font is refused,
/// [`PlotError::Encode`] if the PNG cannot be encoded.
pub fn latency_png(
    loops: &[(&str, &LatencyRecorder)],
    probe: Option<&LatencyRecorder>,
) -> Result<Vec<u8>, PlotError> {
    ensure_font()?;
    let (w, h) = page_size(loops.len());
    let mut rgb = vec![0u8; w as usize * h as usize * 3];
    {
        let bitmap = BitMapBackend::<RGBPixel>::with_buffer_and_format(&mut rgb, (w, h))
            .map_err(draw_err)?;
        let backend = CrispText::new(bitmap, epaint_default_fonts::UBUNTU_LIGHT)
            .map_err(|e| PlotError::Font(e.to_string()))?;
        draw_page(&backend.into_drawing_area(), loops, probe)?;
    }
    let mut out = Vec::new();
    {
        let mut encoder = png::Encoder::new(&mut out, w, h);
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Eight);
        let mut writer = encoder.write_header()?;
        writer.write_image_data(&rgb)?;
        writer.finish()?;
    }
    Ok(out)
}

/// Writes [`latency_svg`] to `path` atomically ([`dynaclay_files::write_atomic`]).
///
/// # Errors
/// [`PlotError::Draw`] if plotters fails, [`PlotError::Write`] (with the path) if the file
/// cannot be written.
pub fn write_latency_svg(
    path: &Path,
    loops: &[(&str, &LatencyRecorder)],
    probe: Option<&LatencyRecorder>,
) -> Result<(), PlotError> {
    let svg = latency_svg(loops, probe)?;
    dynaclay_files::write_atomic(path, svg.as_bytes()).map_err(PlotError::Write)
}

/// A time in µs as a reader says it, in the unit that keeps it between 1 and 1000, to one
/// decimal that is dropped when it is zero: "100 ns", "1 µs", "250 µs", "1 ms", "2.5 ms"
/// (2.96 ms reads "3 ms"). The one spelling of a time in the plots, the report and the
/// window.
#[must_use]
pub fn time_label(us: f64) -> String {
    let trim = |v: f64| {
        let tenths = (v * 10.0).round() / 10.0;
        if tenths.fract() == 0.0 {
            format!("{tenths:.0}")
        } else {
            format!("{tenths:.1}")
        }
    };
    if us >= 1000.0 {
        format!("{} ms", trim(us / 1000.0))
    } else if us >= 1.0 {
        format!("{} µs", trim(us))
    } else {
        format!("{} ns", trim(us * 1000.0))
    }
}

/// A share of ticks as a percentage with as many decimals as it needs: "10%", "0.1%".
#[must_use]
pub fn share_label(share: f64) -> String {
    let pc = share * 100.0;
    let decimals = if pc >= 1.0 {
        0
    } else {
        (-pc.log10()).ceil().clamp(1.0, 6.0) as usize
    };
    format!("{pc:.decimals$}%")
}

/// Powers of ten (in µs) inside `lo..=hi`, for axis labels.
fn decades(lo: f64, hi: f64) -> Vec<f64> {
    (-3..=8)
        .map(|e| 10f64.powi(e))
        .filter(|v| (lo..=hi).contains(v))
        .collect()
}

/// Powers of ten of a share (10⁻⁸ to 1) inside `lo..=hi`, for the histograms' share axis.
fn share_decades(lo: f64, hi: f64) -> Vec<f64> {
    (-8..=0)
        .map(|e| 10f64.powi(e))
        .filter(|v| (lo..=hi).contains(v))
        .collect()
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

/// The outline of histogram bins `(lower edge, upper edge, height)` as one path that never
/// turns back on itself: it drops to `floor` only across a gap between bins (a path that goes
/// down and straight back up draws broken in the bitmap backend).
fn step_outline(bins: &[(f64, f64, f64)], x_min: f64, floor: f64) -> Vec<(f64, f64)> {
    let mut path = Vec::with_capacity(bins.len() * 2 + 4);
    let mut last_hi: Option<f64> = None;
    for &(lo, hi, h) in bins {
        let lo = lo.max(x_min);
        match last_hi {
            Some(prev) if (lo - prev).abs() <= prev * 1e-9 => {}
            Some(prev) => path.extend([(prev, floor), (lo, floor)]),
            None => path.push((lo, floor)),
        }
        path.extend([(lo, h), (hi, h)]);
        last_hi = Some(hi);
    }
    if let Some(prev) = last_hi {
        path.push((prev, floor));
    }
    path
}

/// One histogram panel's contents.
struct Histo<'a> {
    title: String,
    series: &'a str,
    hist: &'a Histogram<u64>,
    marks: Percentiles,
    colour: RGBColor,
    probe: Option<&'a Histogram<u64>>,
}

fn draw_histogram<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    h: &Histo<'_>,
) -> Result<(), PlotError> {
    let share = |hist: &Histogram<u64>| {
        let total = hist.len().max(1) as f64;
        log_bins(hist)
            .into_iter()
            .map(|(lo, hi, n)| (lo, hi, n as f64 / total))
            .collect::<Vec<_>>()
    };
    let bins = share(h.hist);
    let probe_bins = h.probe.map(share).unwrap_or_default();
    let x_min = FIRST_BIN_NS as f64 / 1e3;
    let x_max = bins
        .iter()
        .chain(&probe_bins)
        .map(|b| b.1)
        .fold(h.marks.max_us.max(x_min * 100.0), f64::max)
        * BIN_GROWTH;
    let y_min = bins
        .iter()
        .chain(&probe_bins)
        .map(|b| b.2)
        .fold(1.0, f64::min)
        / 3.0;
    let y_max = 3.0;
    let mut chart = ChartBuilder::on(area)
        .caption(&h.title, (FONT_FAMILY, 16))
        .margin(8)
        .x_label_area_size(40)
        .y_label_area_size(64)
        .build_cartesian_2d(
            (x_min..x_max)
                .log_scale()
                .with_key_points(decades(x_min, x_max)),
            (y_min..y_max)
                .log_scale()
                .with_key_points(share_decades(y_min, y_max)),
        )
        .map_err(draw_err)?;
    chart
        .configure_mesh()
        .light_line_style(GRID_FINE)
        .bold_line_style(GRID_MAIN)
        .axis_desc_style((FONT_FAMILY, 12))
        .y_desc("share of ticks (log)")
        .x_label_formatter(&|v| time_label(*v))
        .y_label_formatter(&|v| share_label(*v))
        .draw()
        .map_err(draw_err)?;
    let colour = h.colour;
    chart
        .draw_series(bins.iter().map(|&(lo, hi, s)| {
            Rectangle::new([(lo.max(x_min), y_min), (hi, s)], colour.mix(0.55).filled())
        }))
        .map_err(draw_err)?
        .label(h.series.to_string())
        .legend(move |(x, y)| Rectangle::new([(x, y - 4), (x + 12, y + 4)], colour.filled()));
    if !probe_bins.is_empty() {
        chart
            .draw_series(LineSeries::new(
                step_outline(&probe_bins, x_min, y_min),
                PROBE_COLOUR.stroke_width(2),
            ))
            .map_err(draw_err)?
            .label("probe (sleeping thread)")
            .legend(|(x, y)| PathElement::new([(x, y), (x + 12, y)], PROBE_COLOUR.stroke_width(2)));
    }
    // The legend first, so the percentile labels drawn next stay readable over it.
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.85))
        .border_style(GRID_MAIN)
        .label_font((FONT_FAMILY, 11))
        .draw()
        .map_err(draw_err)?;
    let marks = [
        ("p50", h.marks.p50_us),
        ("p99", h.marks.p99_us),
        ("p99.9", h.marks.p999_us),
        ("max", h.marks.max_us),
    ];
    for (i, (label, value)) in marks.into_iter().enumerate() {
        let x = value.clamp(x_min, x_max);
        chart
            .draw_series(std::iter::once(PathElement::new(
                [(x, y_min), (x, y_max)],
                MARKER_COLOUR.stroke_width(1),
            )))
            .map_err(draw_err)?;
        // Labels step down the panel so neighbouring markers do not overwrite each other.
        let y = y_max / 2.2f64.powi(i32::try_from(i).unwrap_or(0) + 1);
        chart
            .draw_series(std::iter::once(Text::new(
                format!("{label} {}", time_label(value)),
                (x, y),
                (FONT_FAMILY, 11).into_font().color(&MARKER_COLOUR),
            )))
            .map_err(draw_err)?;
    }
    Ok(())
}

fn draw_timeline<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    title: &str,
    timeline: &Timeline,
    period: std::time::Duration,
) -> Result<(), PlotError> {
    let window_s = timeline.window().as_secs_f64();
    let windows = timeline.windows();
    let x_max = (windows.len() as f64 * window_s).max(window_s);
    let y_min = FIRST_BIN_NS as f64 / 1e3;
    let period_us = period.as_secs_f64() * 1e6;
    let worst_us = windows
        .iter()
        .map(|w| w.max_period_error_ns.max(w.max_compute_ns) as f64 / 1e3)
        .fold(period_us, f64::max);
    let y_max = worst_us * 4.0;
    let misses: u64 = windows.iter().map(|w| u64::from(w.deadline_misses)).sum();
    let mut chart = ChartBuilder::on(area)
        .caption(title, (FONT_FAMILY, 16))
        .margin(8)
        .x_label_area_size(40)
        .y_label_area_size(64)
        .build_cartesian_2d(
            0.0..x_max,
            (y_min..y_max)
                .log_scale()
                .with_key_points(decades(y_min, y_max)),
        )
        .map_err(draw_err)?;
    chart
        .configure_mesh()
        .light_line_style(GRID_FINE)
        .bold_line_style(GRID_MAIN)
        .axis_desc_style((FONT_FAMILY, 12))
        .x_desc("seconds")
        .y_desc(format!("worst per {} (log)", time_label(window_s * 1e6)))
        .y_label_formatter(&|v| time_label(*v))
        .x_label_formatter(&|v| format!("{v:.1}"))
        .draw()
        .map_err(draw_err)?;
    let series = |pick: fn(&crate::timeline::TimelineWindow) -> u64| {
        windows
            .iter()
            .enumerate()
            .filter(|(_, w)| w.ticks > 0)
            .map(move |(i, w)| {
                (
                    (i as f64 + 0.5) * window_s,
                    (pick(w) as f64 / 1e3).clamp(y_min, y_max),
                )
            })
            .collect::<Vec<_>>()
    };
    chart
        .draw_series(LineSeries::new(
            series(|w| w.max_period_error_ns),
            BLUE.stroke_width(1),
        ))
        .map_err(draw_err)?
        .label("period error")
        .legend(|(x, y)| PathElement::new([(x, y), (x + 12, y)], BLUE.stroke_width(2)));
    chart
        .draw_series(LineSeries::new(
            series(|w| w.max_compute_ns),
            RED.stroke_width(1),
        ))
        .map_err(draw_err)?
        .label("compute")
        .legend(|(x, y)| PathElement::new([(x, y), (x + 12, y)], RED.stroke_width(2)));
    chart
        .draw_series(std::iter::once(PathElement::new(
            [(0.0, period_us), (x_max, period_us)],
            GRID_MAIN.stroke_width(2),
        )))
        .map_err(draw_err)?
        .label(format!("period {}", time_label(period_us)))
        .legend(|(x, y)| PathElement::new([(x, y), (x + 12, y)], GRID_MAIN.stroke_width(2)));
    let miss_y = y_max / 1.6;
    chart
        .draw_series(
            windows
                .iter()
                .enumerate()
                .filter(|(_, w)| w.deadline_misses > 0)
                .map(|(i, _)| {
                    Cross::new(
                        ((i as f64 + 0.5) * window_s, miss_y),
                        4,
                        RED.stroke_width(2),
                    )
                }),
        )
        .map_err(draw_err)?
        .label(format!("deadline misses: {misses}"))
        .legend(|(x, y)| Cross::new((x + 6, y), 4, RED.stroke_width(2)));
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::LowerRight)
        .background_style(WHITE.mix(0.85))
        .border_style(GRID_MAIN)
        .label_font((FONT_FAMILY, 11))
        .draw()
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
    fn step_outline_goes_down_only_across_gaps() {
        let bins = [(1.0, 2.0, 0.5), (2.0, 3.0, 0.25), (5.0, 6.0, 0.1)];
        assert_eq!(
            step_outline(&bins, 0.1, 0.01),
            vec![
                (1.0, 0.01),
                (1.0, 0.5),
                (2.0, 0.5),
                (2.0, 0.25),
                (3.0, 0.25),
                (3.0, 0.01),
                (5.0, 0.01),
                (5.0, 0.1),
                (6.0, 0.1),
                (6.0, 0.01),
            ]
        );
        assert!(step_outline(&[], 0.1, 0.01).is_empty());
    }

    #[test]
    fn time_labels_read_in_units() {
        assert_eq!(time_label(1.0), "1 µs");
        assert_eq!(time_label(100.0), "100 µs");
        assert_eq!(time_label(1000.0), "1 ms");
        assert_eq!(time_label(2500.0), "2.5 ms");
        assert_eq!(time_label(0.1), "100 ns");
        assert_eq!(time_label(2960.0), "3 ms");
        assert_eq!(time_label(2940.0), "2.9 ms");
        assert_eq!(decades(0.1, 5000.0), vec![0.1, 1.0, 10.0, 100.0, 1000.0]);
        assert_eq!(share_decades(0.0005, 3.0), vec![0.001, 0.01, 0.1, 1.0]);
        assert_eq!(share_label(0.25), "25%");
        assert_eq!(share_label(0.001), "0.1%");
        assert_eq!(share_label(0.0001), "0.01%");
    }

    #[test]
    fn svg_marks_percentiles_units_probe_and_misses() {
        let mut a = recorder_with_ticks();
        // One tick 1.5 ms late: a deadline miss on the timeline.
        let t0 = Instant::now();
        a.record_tick(&TickTiming {
            scheduled: t0,
            woke: t0 + Duration::from_micros(1500),
            compute: Duration::from_micros(3),
            skipped_before: 0,
        });
        let probe = recorder_with_ticks();
        let svg = latency_svg(&[("haptic", &a)], Some(&probe)).expect("svg");
        let p = a.stats().period_error;
        for label in [
            format!("p50 {}", time_label(p.p50_us)),
            format!("p99 {}", time_label(p.p99_us)),
            format!("p99.9 {}", time_label(p.p999_us)),
            format!("max {}", time_label(p.max_us)),
        ] {
            assert!(svg.contains(&label), "missing marker {label}");
        }
        for text in [
            "1 µs",
            "100 µs",
            "1 ms",
            "probe (sleeping thread)",
            "haptic: over the run",
            "deadline misses: 1",
            "period 1 ms",
        ] {
            assert!(svg.contains(text), "missing {text}");
        }
        // No bare-number tick labels such as "1.000".
        assert!(!svg.contains(">1.000<"));
        // Without a probe, or with one at another rate, there is no overlay.
        let alone = latency_svg(&[("haptic", &a)], None).expect("svg");
        assert!(!alone.contains("probe (sleeping thread)"));
        let other_rate = LatencyRecorder::new(Duration::from_micros(250));
        let apart = latency_svg(&[("haptic", &a)], Some(&other_rate)).expect("svg");
        assert!(!apart.contains("probe (sleeping thread)"));
    }

    #[test]
    fn svg_has_a_panel_per_loop_and_quantity() {
        let a = recorder_with_ticks();
        let b = LatencyRecorder::new(Duration::from_micros(250));
        let svg = latency_svg(&[("haptic", &a), ("sim", &b)], None).expect("svg");
        assert!(svg.starts_with("<svg"), "{}", &svg[..svg.len().min(80)]);
        for title in [
            "haptic: period error",
            "haptic: compute time",
            "sim: period error",
            "sim: compute time",
            "haptic: over the run",
            "sim: over the run",
        ] {
            assert!(svg.contains(title), "missing {title}");
        }
        assert!(svg.contains("<rect"));
    }

    /// Decodes a PNG into (width, height, RGB bytes).
    fn decode_png(bytes: &[u8]) -> (u32, u32, Vec<u8>) {
        let decoder = png::Decoder::new(std::io::Cursor::new(bytes));
        let mut reader = decoder.read_info().expect("png header");
        let mut buf = vec![0; reader.output_buffer_size().expect("buffer size")];
        let info = reader.next_frame(&mut buf).expect("png frame");
        assert_eq!(info.color_type, png::ColorType::Rgb);
        assert_eq!(info.bit_depth, png::BitDepth::Eight);
        buf.truncate(info.buffer_size());
        (info.width, info.height, buf)
    }

    #[test]
    fn png_decodes_at_the_page_size_with_the_plot_drawn() {
        let a = recorder_with_ticks();
        let b = LatencyRecorder::new(Duration::from_micros(250));
        let probe = recorder_with_ticks();
        let bytes = latency_png(&[("haptic", &a), ("sim", &b)], Some(&probe)).expect("png");
        let (w, h, rgb) = decode_png(&bytes);
        assert_eq!((w, h), page_size(2));
        assert_eq!((w, h), (1440, 600));
        let pixels: Vec<&[u8]> = rgb.chunks_exact(3).collect();
        assert_eq!(pixels.len(), 1440 * 600);
        // A white page with the percentile markers, the histogram bars and dark text on it.
        let count = |want: [u8; 3]| pixels.iter().filter(|p| **p == want).count();
        assert!(
            count([255, 255, 255]) > pixels.len() / 2,
            "not a white page"
        );
        let marker = [MARKER_COLOUR.0, MARKER_COLOUR.1, MARKER_COLOUR.2];
        assert!(count(marker) > 50, "no percentile markers");
        assert!(
            pixels.iter().any(|p| p.iter().all(|&c| c < 80)),
            "no dark text"
        );
        // One loop: one row.
        let (w1, h1, _) = decode_png(&latency_png(&[("haptic", &a)], None).expect("png"));
        assert_eq!((w1, h1), page_size(1));
        assert_eq!(page_size(0), page_size(1));
    }

    #[test]
    fn write_error_names_the_path() {
        let rec = recorder_with_ticks();
        let path = Path::new("/nonexistent-dir-for-dynaclay-test/plot.svg");
        let err = write_latency_svg(path, &[("x", &rec)], None).expect_err("must fail");
        assert!(
            err.to_string()
                .contains("/nonexistent-dir-for-dynaclay-test/plot.svg")
        );
    }
}
