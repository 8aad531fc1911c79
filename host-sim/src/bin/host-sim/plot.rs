//! Line and scatter charts as SVG or PNG (by file extension). PNG text is rendered with the
//! embedded DejaVu Sans font, so no system font is needed.

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::FontStyle;

use host_sim::SimError;

const SIZE: (u32, u32) = (960, 600);
const FONT: &str = "sans-serif";
const PALETTE: [RGBColor; 8] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(23, 190, 207),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
];

/// How a series is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mark {
    Line,
    /// A one-pixel line, for long traces that would merge into a band at the usual width.
    ThinLine,
    DashedLine,
    Points,
    /// Hollow circles: points set apart from the filled ones of the same colour.
    OpenPoints,
}

/// One named series of `(x, y)` points with a palette colour index.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    pub name: String,
    pub points: Vec<(f64, f64)>,
    pub mark: Mark,
    pub color: usize,
}

/// Titles of a chart.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Labels<'a> {
    pub title: &'a str,
    pub x: &'a str,
    pub y: &'a str,
}

/// Chart file formats, by extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Format {
    Svg,
    Png,
}

fn format(path: &Path) -> Result<Format, SimError> {
    let extension = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    match extension.as_deref() {
        Some("svg") => Ok(Format::Svg),
        Some("png") => Ok(Format::Png),
        _ => Err(SimError::Output {
            path: path.display().to_string(),
            reason: "the plot file must end in .svg or .png".into(),
        }),
    }
}

/// Refuses a chart path of a format [`chart`] cannot write, before anything is computed.
pub fn check_path(path: &Path) -> Result<(), SimError> {
    format(path).map(|_| ())
}

/// One panel of a [`stacked`] chart: its y axis title and its series.
#[derive(Debug, Clone, PartialEq)]
pub struct Panel<'a> {
    pub y: &'a str,
    pub series: Vec<Series>,
}

/// What one chart file holds.
enum Layout<'a> {
    /// One chart.
    Single(Labels<'a>, &'a [Series]),
    /// Panels stacked top to bottom under one title, each with the x axis titled `x`.
    Stacked {
        title: &'a str,
        x: &'a str,
        panels: &'a [Panel<'a>],
    },
}

/// Height of each panel of a [`stacked`] chart.
const PANEL_HEIGHT: u32 = 300;

/// Writes the chart to `path`: `.svg` or `.png`.
pub fn chart(path: &Path, labels: Labels<'_>, series: &[Series]) -> Result<(), SimError> {
    write(path, SIZE, &Layout::Single(labels, series))
}

/// Writes `panels` stacked top to bottom under `title`, each over its own time (or other) axis
/// titled `x`, to `path`: `.svg` or `.png`.
pub fn stacked(path: &Path, title: &str, x: &str, panels: &[Panel<'_>]) -> Result<(), SimError> {
    let height = 40 + PANEL_HEIGHT * u32::try_from(panels.len()).unwrap_or(1).max(1);
    write(
        path,
        (SIZE.0, height),
        &Layout::Stacked { title, x, panels },
    )
}

fn write(path: &Path, size: (u32, u32), layout: &Layout<'_>) -> Result<(), SimError> {
    let failure = |reason: String| SimError::Output {
        path: path.display().to_string(),
        reason,
    };
    let format = format(path)?;
    // Creating the file first reports an unwritable path in the system's words, not the backend's.
    std::fs::File::create(path).map_err(|e| failure(e.to_string()))?;
    // Both backends lay text out with the embedded font's metrics.
    plotters::style::register_font(FONT, FontStyle::Normal, dejavu::sans::regular())
        .map_err(|_| failure("the embedded font is unreadable".into()))?;
    match format {
        Format::Svg => {
            let root = SVGBackend::new(path, size).into_drawing_area();
            draw_layout(&root, layout).map_err(failure)?;
            root.present().map_err(|e| failure(e.to_string()))
        }
        Format::Png => {
            let root = BitMapBackend::new(path, size).into_drawing_area();
            draw_layout(&root, layout).map_err(failure)?;
            root.present().map_err(|e| failure(e.to_string()))
        }
    }
}

fn draw_layout<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    layout: &Layout<'_>,
) -> Result<(), String> {
    let text = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    root.fill(&WHITE).map_err(text)?;
    match layout {
        Layout::Single(labels, series) => {
            draw(root, Some(labels.title), labels.x, labels.y, series)
        }
        Layout::Stacked { title, x, panels } => {
            let below = root.titled(title, (FONT, 22)).map_err(text)?;
            let areas = below.split_evenly((panels.len().max(1), 1));
            for (area, panel) in areas.iter().zip(panels.iter()) {
                draw(area, None, x, panel.y, &panel.series)?;
            }
            Ok(())
        }
    }
}

fn draw<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    caption: Option<&str>,
    x: &str,
    y: &str,
    series: &[Series],
) -> Result<(), String> {
    let text = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    let (x_range, y_range) = bounds(series);
    let mut builder = ChartBuilder::on(root);
    if let Some(caption) = caption {
        builder.caption(caption, (FONT, 22));
    }
    let mut chart = builder
        .margin(16)
        .x_label_area_size(48)
        .y_label_area_size(72)
        .build_cartesian_2d(x_range, y_range)
        .map_err(text)?;
    chart
        .configure_mesh()
        .x_desc(x)
        .y_desc(y)
        .label_style((FONT, 14))
        .axis_desc_style((FONT, 16))
        .light_line_style(RGBColor(235, 235, 235))
        .draw()
        .map_err(text)?;
    for one in series {
        let color = PALETTE[one.color % PALETTE.len()];
        let points = one.points.iter().copied();
        let drawn = match one.mark {
            Mark::Line => chart.draw_series(LineSeries::new(points, color.stroke_width(2))),
            Mark::ThinLine => chart.draw_series(LineSeries::new(points, color.stroke_width(1))),
            Mark::DashedLine => {
                chart.draw_series(DashedLineSeries::new(points, 8, 5, color.stroke_width(2)))
            }
            Mark::Points => {
                chart.draw_series(points.map(|point| Circle::new(point, 3, color.filled())))
            }
            Mark::OpenPoints => {
                chart.draw_series(points.map(|point| Circle::new(point, 4, color.stroke_width(1))))
            }
        }
        .map_err(text)?;
        drawn
            .label(one.name.as_str())
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 18, y)], color.stroke_width(2)));
    }
    chart
        .configure_series_labels()
        .label_font((FONT, 14))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()
        .map_err(text)?;
    Ok(())
}

/// Axis ranges covering every finite point, with a little margin.
fn bounds(series: &[Series]) -> (std::ops::Range<f64>, std::ops::Range<f64>) {
    let points = series
        .iter()
        .flat_map(|s| s.points.iter())
        .filter(|p| p.0.is_finite() && p.1.is_finite());
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for &(x, y) in points {
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    }
    if x0 > x1 {
        return (0.0..1.0, 0.0..1.0);
    }
    let pad = |low: f64, high: f64| {
        let span = if high > low {
            high - low
        } else {
            low.abs().max(1e-9)
        };
        (low - 0.04 * span)..(high + 0.04 * span)
    };
    (pad(x0, x1), pad(y0, y1))
}
