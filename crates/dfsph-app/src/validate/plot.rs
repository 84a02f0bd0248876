//! One PNG per comparison, drawn with plotters into a memory buffer and encoded with `png`.
//! Experiments are drawn as markers, simulations as lines. Text uses the Ubuntu Light font
//! embedded in `epaint_default_fonts` (the viewer's font), so nothing depends on system fonts.

use std::path::Path;
use std::sync::Once;

use anyhow::{anyhow, Context, Result};
use plotters::prelude::*;
use plotters::style::FontStyle;

/// How a series is drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Style {
    /// A simulation: a line.
    Line,
    /// A dashed line (reference curves, other solvers).
    Dashed,
    /// An experiment: hollow circles.
    Markers,
    /// Many small filled dots (particle clouds).
    Dots,
    /// A thin, light line (raw, noisy signals behind a smoothed one).
    Faint,
}

/// One data set on a plot.
#[derive(Clone, Debug)]
pub struct Series {
    pub label: String,
    pub points: Vec<(f64, f64)>,
    pub style: Style,
    /// Index into the palette.
    pub color: usize,
}

impl Series {
    pub fn new(
        label: impl Into<String>,
        points: Vec<(f64, f64)>,
        style: Style,
        color: usize,
    ) -> Self {
        Self {
            label: label.into(),
            points: points
                .into_iter()
                .filter(|(x, y)| x.is_finite() && y.is_finite())
                .collect(),
            style,
            color,
        }
    }
}

/// A plot: title, axis labels with units, series, optional fixed ranges.
#[derive(Clone, Debug)]
pub struct Plot {
    /// File name inside the report directory, `*.png`.
    pub file: String,
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub series: Vec<Series>,
    pub x_range: Option<(f64, f64)>,
    pub y_range: Option<(f64, f64)>,
    /// Legend in the upper right corner instead of the upper left.
    pub legend_right: bool,
}

impl Plot {
    pub fn new(file: &str, title: &str, x_label: &str, y_label: &str) -> Self {
        Self {
            file: file.to_string(),
            title: title.to_string(),
            x_label: x_label.to_string(),
            y_label: y_label.to_string(),
            series: Vec::new(),
            x_range: None,
            y_range: None,
            legend_right: false,
        }
    }

    pub fn with(mut self, s: Series) -> Self {
        self.series.push(s);
        self
    }
}

const PALETTE: [RGBColor; 8] = [
    RGBColor(0, 0, 0),
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(127, 127, 127),
];

const WIDTH: u32 = 960;
const HEIGHT: u32 = 620;

fn register_fonts() -> Result<()> {
    static ONCE: Once = Once::new();
    let mut ok = true;
    ONCE.call_once(|| {
        ok = plotters::style::register_font(
            "sans-serif",
            FontStyle::Normal,
            epaint_default_fonts::UBUNTU_LIGHT,
        )
        .is_ok();
    });
    if ok {
        Ok(())
    } else {
        Err(anyhow!("cannot load the embedded plot font"))
    }
}

fn range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
        (lo.min(v), hi.max(v))
    });
    if !lo.is_finite() || !hi.is_finite() {
        return (0.0, 1.0);
    }
    let span = (hi - lo).max(1e-9 * hi.abs().max(1.0));
    (lo - 0.04 * span, hi + 0.04 * span)
}

/// Draw `plot` into `dir/plot.file`.
pub fn render(plot: &Plot, dir: &Path) -> Result<()> {
    register_fonts()?;
    let mut buf = vec![255u8; (WIDTH * HEIGHT * 3) as usize];
    draw(plot, &mut buf).map_err(|e| anyhow!("cannot draw `{}`: {e}", plot.file))?;
    let path = dir.join(&plot.file);
    dfsph_io::write_atomic(&path, |w| {
        let mut enc = png::Encoder::new(w, WIDTH, HEIGHT);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        // Plots are mostly flat colour: the best compression with adaptive filtering makes
        // them about ten times smaller than the defaults (they are committed to the repo).
        enc.set_compression(png::Compression::Best);
        enc.set_adaptive_filter(png::AdaptiveFilterType::Adaptive);
        let mut writer = enc.write_header().map_err(std::io::Error::other)?;
        writer
            .write_image_data(&buf)
            .map_err(std::io::Error::other)?;
        writer.finish().map_err(std::io::Error::other)
    })
    .with_context(|| format!("cannot write `{}`", path.display()))
}

fn draw(plot: &Plot, buf: &mut [u8]) -> std::result::Result<(), Box<dyn std::error::Error>> {
    let root = BitMapBackend::with_buffer(buf, (WIDTH, HEIGHT)).into_drawing_area();
    root.fill(&WHITE)?;
    let xr = plot.x_range.unwrap_or_else(|| {
        range(
            plot.series
                .iter()
                .flat_map(|s| s.points.iter().map(|p| p.0)),
        )
    });
    let yr = plot.y_range.unwrap_or_else(|| {
        range(
            plot.series
                .iter()
                .flat_map(|s| s.points.iter().map(|p| p.1)),
        )
    });
    let mut chart = ChartBuilder::on(&root)
        .caption(&plot.title, ("sans-serif", 24))
        .margin(16)
        .x_label_area_size(52)
        .y_label_area_size(78)
        .build_cartesian_2d(xr.0..xr.1, yr.0..yr.1)?;
    chart
        .configure_mesh()
        .x_desc(plot.x_label.as_str())
        .y_desc(plot.y_label.as_str())
        .axis_desc_style(("sans-serif", 20))
        .label_style(("sans-serif", 16))
        .light_line_style(RGBColor(235, 235, 235))
        .draw()?;
    let inside = |p: &&(f64, f64)| p.0 >= xr.0 && p.0 <= xr.1 && p.1 >= yr.0 && p.1 <= yr.1;
    for s in &plot.series {
        let color = PALETTE[s.color % PALETTE.len()];
        let pts = s.points.clone();
        let anno = match s.style {
            Style::Line => chart.draw_series(LineSeries::new(pts, color.stroke_width(2)))?,
            Style::Dashed => {
                chart.draw_series(DashedLineSeries::new(pts, 8, 5, color.stroke_width(2)))?
            }
            Style::Faint => {
                chart.draw_series(LineSeries::new(pts, color.mix(0.3).stroke_width(1)))?
            }
            Style::Markers => chart.draw_series(
                pts.iter()
                    .filter(inside)
                    .map(|&p| Circle::new(p, 5, color.stroke_width(2))),
            )?,
            Style::Dots => chart.draw_series(
                pts.iter()
                    .filter(inside)
                    .map(|&p| Circle::new(p, 1, color.mix(0.5).filled())),
            )?,
        };
        let anno = anno.label(s.label.as_str());
        match s.style {
            Style::Markers | Style::Dots => {
                anno.legend(move |(x, y)| Circle::new((x + 10, y), 5, color.stroke_width(2)));
            }
            Style::Faint => {
                anno.legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], color.mix(0.3).stroke_width(1))
                });
            }
            Style::Line | Style::Dashed => {
                anno.legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
                });
            }
        }
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 16))
        .position(if plot.legend_right {
            SeriesLabelPosition::UpperRight
        } else {
            SeriesLabelPosition::UpperLeft
        })
        .draw()?;
    root.present()?;
    Ok(())
}
