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

/// The space around a chart's plot: its margin, the axes' label areas and a caption.
const MARGIN_PX: u32 = 16;
const X_LABEL_AREA_PX: u32 = 48;
const Y_LABEL_AREA_PX: u32 = 72;
const CAPTION_PX: f64 = 30.0;

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
    let (width_px, height_px) = root.dim_in_pixel();
    let plot_px = (
        f64::from(width_px) - f64::from(Y_LABEL_AREA_PX + 2 * MARGIN_PX),
        f64::from(height_px)
            - f64::from(X_LABEL_AREA_PX + 2 * MARGIN_PX)
            - if caption.is_some() { CAPTION_PX } else { 0.0 },
    );
    let (legend, y_range) = legend_position(series, &x_range, y_range, plot_px);
    let mut builder = ChartBuilder::on(root);
    if let Some(caption) = caption {
        builder.caption(caption, (FONT, 22));
    }
    let mut chart = builder
        .margin(MARGIN_PX)
        .x_label_area_size(X_LABEL_AREA_PX)
        .y_label_area_size(Y_LABEL_AREA_PX)
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
        .position(legend)
        .label_font((FONT, 14))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()
        .map_err(text)?;
    Ok(())
}

/// The legend's corner or edge of the plot that hides none of the drawn points (lines counted
/// along their length), the upper right first among equals; where every one would hide some, the
/// y axis grows upwards by the legend's height and the legend goes in the upper right, above
/// the data. Returns the position and the y range. The legend's size is estimated from its
/// entries and the label font: a line of 20 px each, 8 px a character.
fn legend_position(
    series: &[Series],
    x_range: &std::ops::Range<f64>,
    y_range: std::ops::Range<f64>,
    plot_px: (f64, f64),
) -> (SeriesLabelPosition, std::ops::Range<f64>) {
    use SeriesLabelPosition::{
        LowerLeft, LowerMiddle, LowerRight, MiddleLeft, MiddleRight, UpperLeft, UpperMiddle,
        UpperRight,
    };
    let longest = series
        .iter()
        .map(|s| s.name.chars().count())
        .max()
        .unwrap_or(0);
    let width = ((40.0 + 8.0 * longest as f64) / plot_px.0.max(1.0)).min(1.0);
    let height = ((10.0 + 20.0 * series.len() as f64) / plot_px.1.max(1.0)).min(1.0);
    // Where each candidate's box starts, as fractions of the plot from its lower left corner.
    let (left, centre_x, right) = (0.0, (1.0 - width) / 2.0, 1.0 - width);
    let (low, middle, high) = (0.0, (1.0 - height) / 2.0, 1.0 - height);
    let candidates = [
        (UpperRight, right, high),
        (UpperLeft, left, high),
        (LowerRight, right, low),
        (LowerLeft, left, low),
        (MiddleRight, right, middle),
        (MiddleLeft, left, middle),
        (UpperMiddle, centre_x, high),
        (LowerMiddle, centre_x, low),
    ];
    let fraction = |(x, y): (f64, f64)| {
        (
            (x - x_range.start) / (x_range.end - x_range.start),
            (y - y_range.start) / (y_range.end - y_range.start),
        )
    };
    let mut drawn: Vec<(f64, f64)> = Vec::new();
    for one in series {
        let points = one.points.iter().map(|&p| fraction(p));
        match one.mark {
            Mark::Points | Mark::OpenPoints => drawn.extend(points),
            Mark::Line | Mark::ThinLine | Mark::DashedLine => {
                let points: Vec<_> = points.collect();
                drawn.extend(points.first());
                for pair in points.windows(2) {
                    let ((x0, y0), (x1, y1)) = (pair[0], pair[1]);
                    let steps = ((x1 - x0).hypot(y1 - y0) * 100.0).ceil().clamp(1.0, 1000.0);
                    drawn.extend((1..=steps as usize).map(|k| {
                        let t = k as f64 / steps;
                        (x0 + t * (x1 - x0), y0 + t * (y1 - y0))
                    }));
                }
            }
        }
    }
    let hidden = |x0: f64, y0: f64| {
        drawn
            .iter()
            .filter(|(x, y)| (x0..=x0 + width).contains(x) && (y0..=y0 + height).contains(y))
            .count()
    };
    match candidates
        .into_iter()
        .find(|&(_, x0, y0)| hidden(x0, y0) == 0)
    {
        Some((position, _, _)) => (position, y_range),
        None => {
            let span = (y_range.end - y_range.start) / (1.0 - height.min(0.5));
            (UpperRight, y_range.start..y_range.start + span)
        }
    }
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

#[cfg(test)]
mod tests {
    use super::*;

    fn points(name: &str, points: Vec<(f64, f64)>) -> Series {
        Series {
            name: name.into(),
            points,
            mark: Mark::Points,
            color: 0,
        }
    }

    /// A grid of points over the unit square, less those in `[x0, x1] × [y0, y1]`.
    fn grid_without(x0: f64, x1: f64, y0: f64, y1: f64) -> Vec<(f64, f64)> {
        (0..=20)
            .flat_map(|i| (0..=20).map(move |j| (f64::from(i) / 20.0, f64::from(j) / 20.0)))
            .filter(|&(x, y)| !((x0..=x1).contains(&x) && (y0..=y1).contains(&y)))
            .collect()
    }

    #[test]
    fn the_legend_goes_where_it_hides_no_point() {
        let plot_px = (800.0, 500.0);
        let range = 0.0..1.0;
        // The upper right is taken, the upper left free.
        let series = [points("a", grid_without(0.0, 0.6, 0.7, 1.0))];
        let (position, y_range) = legend_position(&series, &range, range.clone(), plot_px);
        assert!(matches!(position, SeriesLabelPosition::UpperLeft));
        assert_eq!(y_range, range);
        // Points everywhere: the y axis grows and the legend's band above the data is empty.
        let series = [points("a", grid_without(2.0, 2.0, 2.0, 2.0))];
        let (position, y_range) = legend_position(&series, &range, range.clone(), plot_px);
        assert!(matches!(position, SeriesLabelPosition::UpperRight));
        let height = (10.0 + 20.0) / plot_px.1;
        let highest = 1.0 / (y_range.end - y_range.start);
        assert!(highest <= 1.0 - height + 1e-12, "{highest} {height}");
    }
}
