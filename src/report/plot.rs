//! Line plots as PNG (plotters, bitmap backend; the DejaVu Sans font is embedded, so no
//! system font is needed).

use std::ops::Range;
use std::path::Path;
use std::sync::Once;

use anyhow::{anyhow, bail, Result};
use plotters::coord::ranged1d::{DefaultFormatting, KeyPointHint, Ranged};
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;

/// One curve.
#[derive(Clone, Debug)]
pub struct Series {
    pub name: String,
    pub points: Vec<(f64, f64)>,
    /// Drawn as a dashed line without markers (references, baselines).
    pub dashed: bool,
    /// An interval about each point, (x, low, high), drawn as a translucent band.
    pub band: Vec<(f64, f64, f64)>,
}

impl Series {
    pub fn new(name: &str, points: Vec<(f64, f64)>) -> Series {
        Series {
            name: name.into(),
            points,
            dashed: false,
            band: Vec::new(),
        }
    }

    /// The curve with a band from `low` to `high` at each of its points' x.
    pub fn with_band(mut self, band: Vec<(f64, f64, f64)>) -> Series {
        self.band = band;
        self
    }

    pub fn dashed(name: &str, points: Vec<(f64, f64)>) -> Series {
        Series {
            dashed: true,
            ..Series::new(name, points)
        }
    }
}

#[derive(Clone, Debug)]
pub struct Axes {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub log_x: bool,
    pub log_y: bool,
}

static FONT: Once = Once::new();

/// Distinct, readable on white (the matplotlib "tab10" order).
const COLOURS: [RGBColor; 6] = [
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(0, 0, 0),
];

fn register_font() {
    FONT.call_once(|| {
        // The embedded font is valid; a failure would only lose the text.
        let _ = plotters::style::register_font(
            "sans-serif",
            FontStyle::Normal,
            dejavu::sans::regular(),
        );
    });
}

/// The range of the values, widened a little (in log10 units on a log axis, where only
/// positive values count).
fn range(values: impl Iterator<Item = f64>) -> Result<Range<f64>> {
    let v: Vec<f64> = values.filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        bail!("nothing to plot");
    }
    let (lo, hi) = v
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
            (a.min(x), b.max(x))
        });
    let pad = if hi > lo { 0.05 * (hi - lo) } else { 0.5 };
    Ok(lo - pad..hi + pad)
}

/// A tick label: plain for moderate values (trailing zeros dropped), else scientific.
fn tick(v: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    if !(1e-2..1e4).contains(&v.abs()) {
        return format!("{v:.1e}");
    }
    let s = format!("{v:.3}");
    s.trim_end_matches('0').trim_end_matches('.').to_string()
}

/// Tick positions (axis units) within `r`: on a log axis the values 1, 2, 5 of each
/// decade (1, 2, ..., 9 where that gives fewer than three, else linear 1-2-5 steps of
/// the values), on a linear axis multiples of a 1-2-5 step.
fn key_points(r: &Range<f64>, log: bool) -> Vec<f64> {
    if !log {
        return linear_ticks(r.start, r.end);
    }
    let inside = |v: &f64| r.start <= *v && *v <= r.end;
    let decades = r.start.floor() as i32..=r.end.ceil() as i32;
    for mantissas in [
        &[1.0, 2.0, 5.0][..],
        &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0],
    ] {
        let ticks: Vec<f64> = decades
            .clone()
            .flat_map(|e| mantissas.iter().map(move |m| (m * 10f64.powi(e)).log10()))
            .filter(inside)
            .collect();
        if ticks.len() >= 3 {
            return ticks;
        }
    }
    linear_ticks(10f64.powf(r.start), 10f64.powf(r.end))
        .into_iter()
        .filter(|v| *v > 0.0)
        .map(f64::log10)
        .collect()
}

/// A linear coordinate that ticks at `key_points` (plotters' own ticks are evenly
/// spaced in axis units, which on a log axis lands on values like 6.31).
struct Ticked {
    inner: RangedCoordf64,
    ticks: Vec<f64>,
}

impl Ticked {
    fn new(r: Range<f64>, log: bool) -> Ticked {
        Ticked {
            ticks: key_points(&r, log),
            inner: r.into(),
        }
    }
}

impl Ranged for Ticked {
    type FormatOption = DefaultFormatting;
    type ValueType = f64;

    fn map(&self, value: &f64, limit: (i32, i32)) -> i32 {
        self.inner.map(value, limit)
    }

    fn key_points<Hint: KeyPointHint>(&self, hint: Hint) -> Vec<f64> {
        // Light grid lines ask for more points than the bold ones: only ours are drawn.
        match hint.weight().allow_light_points() {
            true => Vec::new(),
            false => self.ticks.clone(),
        }
    }

    fn range(&self) -> Range<f64> {
        self.inner.range()
    }
}

/// Multiples of a 1-2-5 step (about an eighth of the range) within lo..=hi.
fn linear_ticks(lo: f64, hi: f64) -> Vec<f64> {
    let raw = (hi - lo) / 8.0;
    if !(raw > 0.0 && raw.is_finite()) {
        return vec![lo];
    }
    let base = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * base)
        .find(|s| *s >= raw)
        .unwrap_or(10.0 * base);
    ((lo / step).ceil() as i64..=(hi / step).floor() as i64)
        .map(|k| k as f64 * step)
        .collect()
}

/// A value as plotted: log10 of it on a log axis (plotters' own log axes label only
/// whole decades, useless for a range within one), so ticks are placed evenly in
/// log units and labelled with the value itself.
fn to_axis(v: f64, log: bool) -> f64 {
    match (log, v > 0.0) {
        (false, _) => v,
        (true, true) => v.log10(),
        (true, false) => f64::NAN,
    }
}

/// Draws `series` into a PNG at `path` (900×600).
pub fn line_plot(path: &Path, axes: &Axes, series: &[Series]) -> Result<()> {
    register_font();
    let series: Vec<Series> = series
        .iter()
        .map(|s| Series {
            points: s
                .points
                .iter()
                .map(|&(x, y)| (to_axis(x, axes.log_x), to_axis(y, axes.log_y)))
                .collect(),
            band: s
                .band
                .iter()
                .map(|&(x, lo, hi)| {
                    let y = |v: f64| to_axis(v, axes.log_y);
                    (to_axis(x, axes.log_x), y(lo), y(hi))
                })
                .collect(),
            ..s.clone()
        })
        .collect();
    let xr = range(series.iter().flat_map(|s| s.points.iter().map(|p| p.0)))?;
    let yr = range(series.iter().flat_map(|s| {
        let band = s.band.iter().flat_map(|b| [b.1, b.2]);
        s.points.iter().map(|p| p.1).chain(band)
    }))?;
    let label = |log: bool| move |v: &f64| tick(if log { 10f64.powf(*v) } else { *v });
    let (x_label, y_label) = (label(axes.log_x), label(axes.log_y));
    let err = |e: &dyn std::fmt::Display| anyhow!("cannot draw {}: {e}", path.display());
    let root = BitMapBackend::new(path, (900, 600)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(&axes.title, ("sans-serif", 22))
        .margin(16)
        .x_label_area_size(50)
        .y_label_area_size(80)
        .build_cartesian_2d(Ticked::new(xr, axes.log_x), Ticked::new(yr, axes.log_y))
        .map_err(|e| err(&e))?;
    let log_note = |label: &str, log: bool| {
        if log {
            format!("{label} (log scale)")
        } else {
            label.to_string()
        }
    };
    chart
        .configure_mesh()
        .x_desc(log_note(&axes.x_label, axes.log_x))
        .y_desc(log_note(&axes.y_label, axes.log_y))
        .label_style(("sans-serif", 15))
        .axis_desc_style(("sans-serif", 17))
        .x_label_formatter(&x_label)
        .y_label_formatter(&y_label)
        .draw()
        .map_err(|e| err(&e))?;
    for (i, s) in series.iter().enumerate() {
        let color = COLOURS[i % COLOURS.len()].to_rgba();
        let style = ShapeStyle {
            color,
            filled: false,
            stroke_width: 2,
        };
        let points: Vec<(f64, f64)> = s
            .points
            .iter()
            .copied()
            .filter(|p| p.0.is_finite() && p.1.is_finite())
            .collect();
        let band: Vec<(f64, f64, f64)> = s
            .band
            .iter()
            .copied()
            .filter(|b| b.0.is_finite() && b.1.is_finite() && b.2.is_finite())
            .collect();
        if band.len() >= 2 {
            // The upper edge left to right, then the lower edge back.
            let outline: Vec<(f64, f64)> = band
                .iter()
                .map(|b| (b.0, b.2))
                .chain(band.iter().rev().map(|b| (b.0, b.1)))
                .collect();
            chart
                .draw_series(std::iter::once(Polygon::new(
                    outline,
                    color.mix(0.15).filled(),
                )))
                .map_err(|e| err(&e))?;
        }
        let anno = if s.dashed {
            chart
                .draw_series(DashedLineSeries::new(points, 8, 5, style))
                .map_err(|e| err(&e))?
        } else {
            // Markers only where points are few enough to tell apart.
            let marker = if points.len() <= 40 { 3 } else { 0 };
            chart
                .draw_series(LineSeries::new(points, style).point_size(marker))
                .map_err(|e| err(&e))?
        };
        anno.label(s.name.as_str()).legend(move |(x, y)| {
            PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
        });
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 15))
        .draw()
        .map_err(|e| err(&e))?;
    root.present().map_err(|e| err(&e))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tick_labels_are_short() {
        assert_eq!(tick(0.0), "0");
        assert_eq!(tick(250.0), "250");
        assert_eq!(tick(0.125), "0.125");
        assert_eq!(tick(1.5e-4), "1.5e-4");
    }

    /// Log axes tick at 1, 2, 5 per decade (Fig. 6's σ_t: 5, 10, 20, 50), finer in a
    /// narrow range; linear axes at a 1-2-5 step.
    #[test]
    fn ticks_are_round_values() {
        let values = |r: Range<f64>, log: bool| -> Vec<String> {
            key_points(&r, log)
                .iter()
                .map(|v| tick(if log { 10f64.powf(*v) } else { *v }))
                .collect()
        };
        let log = |a: f64, b: f64| a.log10()..b.log10();
        assert_eq!(values(log(4.0, 60.0), true), ["5", "10", "20", "50"]);
        assert_eq!(
            values(log(3e-5, 3e-4), true),
            ["5.0e-5", "1.0e-4", "2.0e-4"]
        );
        assert_eq!(values(log(1.1, 4.5), true), ["2", "3", "4"]);
        assert_eq!(values(log(1.05, 1.95), true), ["1.2", "1.4", "1.6", "1.8"]);
        assert_eq!(values(0.05..1.02, false), ["0.2", "0.4", "0.6", "0.8", "1"]);
    }

    #[test]
    fn a_plot_is_a_png_with_curves_and_text() {
        let path = std::env::temp_dir().join(format!("mediareg_plot_{}.png", std::process::id()));
        let axes = Axes {
            title: "t".into(),
            x_label: "x".into(),
            y_label: "y".into(),
            log_x: true,
            log_y: true,
        };
        let series = [
            Series::new("a", vec![(1.0, 1e-3), (2.0, 5e-4), (4.0, 2.5e-4)]),
            Series::dashed("b", vec![(1.0, 2e-3), (4.0, 2e-3)]),
        ];
        line_plot(&path, &axes, &series).unwrap();
        let decoder =
            png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&path).unwrap()));
        let mut reader = decoder.read_info().unwrap();
        let mut buf = vec![0; reader.output_buffer_size().unwrap()];
        let info = reader.next_frame(&mut buf).unwrap();
        assert_eq!((info.width, info.height), (900, 600));
        // Not blank: white background plus several other colours (curves, text, grid).
        let mut colours = std::collections::HashSet::new();
        for px in buf[..info.buffer_size()].chunks(info.color_type.samples()) {
            colours.insert(px.to_vec());
        }
        assert!(colours.len() > 20, "only {} colours", colours.len());
        // Nothing to plot is an error, not an empty picture.
        assert!(line_plot(&path, &axes, &[Series::new("c", vec![(0.0, -1.0)])]).is_err());
        let _ = std::fs::remove_file(&path);
    }
}
