//! Line and scatter charts as SVG or PNG (by file extension). PNG text is rendered with the
//! embedded DejaVu Sans font, so no system font is needed.

mod axis;
mod legend;
mod series;

use std::ops::Range;
use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::FontStyle;

use host_sim::closed_loop::MEAN_POSITION_LIMIT_M;
use host_sim::SimError;

use axis::{linear_ticks, symlog_ticks, TickedAxis};
use legend::{legend_keys, legend_position};
use series::bounds;

pub use axis::YAxis;
pub use series::{moment_lines, Key, Labels, Mark, Moment, Options, Panel, Series};

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

/// The colour of a legend entry that stands for a mark in every colour.
const NEUTRAL: RGBColor = RGBColor(70, 70, 70);

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

/// What one chart file holds.
enum Layout<'a> {
    /// One chart.
    Single(Labels<'a>, &'a [Series], &'a Options),
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
    chart_with(path, labels, series, &Options::default())
}

/// Writes the chart to `path` with its own legend or y axis: `.svg` or `.png`.
pub fn chart_with(
    path: &Path,
    labels: Labels<'_>,
    series: &[Series],
    options: &Options,
) -> Result<(), SimError> {
    write(path, SIZE, &Layout::Single(labels, series, options))
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

/// The panel of a plate's mean position over each cycle: `mean` (time in s, position in µm) as a
/// thin line under `name`, with the closed loop's bound of ±[`MEAN_POSITION_LIMIT_M`] dashed over
/// `bound_s`, the times it is judged over, where it is.
pub fn mean_position_panel(
    name: impl Into<String>,
    mean: Vec<(f64, f64)>,
    bound_s: Option<Range<f64>>,
) -> Panel<'static> {
    let mut series = vec![Series::new(name, mean, Mark::ThinLine, 0)];
    if let Some(x) = bound_s {
        let limit_um = MEAN_POSITION_LIMIT_M * 1e6;
        for y in [limit_um, -limit_um] {
            series.push(Series::level(format!("±{limit_um:.0} µm"), y, x.clone(), 1));
        }
    }
    Panel {
        y: "cycle mean position (µm)",
        series,
    }
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
        Layout::Single(labels, series, options) => draw(
            root,
            Some(labels.title),
            labels.x,
            labels.y,
            series,
            options,
        ),
        Layout::Stacked { title, x, panels } => {
            let below = root.titled(title, (FONT, 22)).map_err(text)?;
            let areas = below.split_evenly((panels.len().max(1), 1));
            for (area, panel) in areas.iter().zip(panels.iter()) {
                draw(area, None, x, panel.y, &panel.series, &Options::default())?;
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
    options: &Options,
) -> Result<(), String> {
    let text = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    let y_axis = options.y_axis;
    let series: Vec<Series> = series
        .iter()
        .map(|one| Series {
            points: one
                .points
                .iter()
                .map(|&(x, y)| (x, y_axis.map(y)))
                .collect(),
            ..one.clone()
        })
        .collect();
    let keys = legend_keys(&series, options);
    let (x_range, y_range) = bounds(&series);
    let (width_px, height_px) = root.dim_in_pixel();
    let plot_px = (
        f64::from(width_px) - f64::from(Y_LABEL_AREA_PX + 2 * MARGIN_PX),
        f64::from(height_px)
            - f64::from(X_LABEL_AREA_PX + 2 * MARGIN_PX)
            - if caption.is_some() { CAPTION_PX } else { 0.0 },
    );
    let data_y_range = y_range.clone();
    let (legend, y_range) = legend_position(&series, &keys, &x_range, y_range, plot_px);
    let x_ticks = linear_ticks(&x_range);
    let y_ticks = match y_axis {
        YAxis::Linear => linear_ticks(&y_range),
        YAxis::SymLog { linear_within } => symlog_ticks(&data_y_range, linear_within),
    };
    let mut builder = ChartBuilder::on(root);
    if let Some(caption) = caption {
        builder.caption(caption, (FONT, 22));
    }
    let mut chart = builder
        .margin(MARGIN_PX)
        .x_label_area_size(X_LABEL_AREA_PX)
        .y_label_area_size(Y_LABEL_AREA_PX)
        .build_cartesian_2d(
            TickedAxis {
                range: x_range,
                ticks: x_ticks.at.clone(),
            },
            TickedAxis {
                range: y_range,
                ticks: y_ticks.at.clone(),
            },
        )
        .map_err(text)?;
    let x_label = |value: &f64| x_ticks.label(*value);
    let y_label = |value: &f64| y_ticks.label(y_axis.unmap(*value));
    chart
        .configure_mesh()
        .x_desc(x)
        .y_desc(y)
        .x_label_formatter(&x_label)
        .y_label_formatter(&y_label)
        .label_style((FONT, 14))
        .axis_desc_style((FONT, 16))
        .bold_line_style(RGBColor(215, 215, 215))
        .draw()
        .map_err(text)?;
    let lines_first = series
        .iter()
        .filter(|one| one.mark.is_line())
        .chain(series.iter().filter(|one| !one.mark.is_line()));
    for one in lines_first {
        let color = PALETTE[one.color % PALETTE.len()];
        let points = one.points.iter().copied();
        match one.mark {
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
            Mark::Dots => {
                chart.draw_series(points.map(|point| Circle::new(point, 1, color.filled())))
            }
        }
        .map_err(text)?;
    }
    for key in &keys {
        let color = key
            .color
            .map_or(NEUTRAL, |index| PALETTE[index % PALETTE.len()]);
        let mark = key.mark;
        chart
            .draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())
            .map_err(text)?
            .label(key.name.as_str())
            .legend(move |(x, y)| {
                // A swatch 18 px wide, drawn as the mark is.
                let solid =
                    |width: u32| PathElement::new([(x, y), (x + 18, y)], color.stroke_width(width));
                let broken = |dash: i32, gap: i32, width: u32| {
                    let ends = vec![(x, y), (x + 18, y)].into_iter();
                    plotters::element::DashedPathElement::new(
                        ends,
                        dash,
                        gap,
                        color.stroke_width(width),
                    )
                };
                match mark {
                    // A one-pixel swatch would be too faint to tell its colour by.
                    Mark::Line | Mark::ThinLine => solid(2).into_dyn(),
                    Mark::DashedLine => broken(7, 4, 2).into_dyn(),
                    Mark::Points => Circle::new((x + 9, y), 3, color.filled()).into_dyn(),
                    Mark::OpenPoints => {
                        Circle::new((x + 9, y), 4, color.stroke_width(1)).into_dyn()
                    }
                    Mark::Dots => broken(2, 4, 2).into_dyn(),
                }
            });
    }
    if !keys.is_empty() {
        chart
            .configure_series_labels()
            .position(legend)
            .label_font((FONT, 14))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()
            .map_err(text)?;
    }
    Ok(())
}
