//! Line and scatter charts as SVG or PNG (by file extension). PNG text is rendered with the
//! embedded DejaVu Sans font, so no system font is needed.

use std::f64::consts::LN_10;
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

/// The colour of a legend entry that stands for a mark in every colour.
const NEUTRAL: RGBColor = RGBColor(70, 70, 70);

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
    /// One-pixel dots, for samples too many or too quantised to join with a line.
    Dots,
}

impl Mark {
    /// Lines go below points, so that a fitted or modelled curve hides no sample.
    fn is_line(self) -> bool {
        matches!(self, Mark::Line | Mark::ThinLine | Mark::DashedLine)
    }
}

/// One legend entry: a name beside a swatch of its mark in its colour (a neutral grey where the
/// entry stands for the mark in every colour).
#[derive(Debug, Clone, PartialEq)]
pub struct Key {
    pub name: String,
    pub mark: Mark,
    pub color: Option<usize>,
}

/// How the y axis maps values.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum YAxis {
    #[default]
    Linear,
    /// Symmetric logarithmic: `sign(y)·log10(1 + |y|/linear_within)`, linear near zero and
    /// logarithmic beyond `linear_within`, so that curves of millimetres and of metres are both
    /// read off one axis.
    SymLog { linear_within: f64 },
}

impl YAxis {
    /// A value's place on the axis.
    fn map(self, y: f64) -> f64 {
        match self {
            YAxis::Linear => y,
            YAxis::SymLog { linear_within } => {
                y.signum() * (y.abs() / linear_within).ln_1p() / LN_10
            }
        }
    }

    /// The value at a place on the axis.
    fn unmap(self, y: f64) -> f64 {
        match self {
            YAxis::Linear => y,
            YAxis::SymLog { linear_within } => {
                y.signum() * linear_within * (y.abs() * LN_10).exp_m1()
            }
        }
    }
}

/// What a chart adds to its series: its legend, where not one entry a series, and its y axis.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Options {
    /// The legend's entries; none: one for every series under its name, series of one name,
    /// mark and colour sharing one.
    pub keys: Option<Vec<Key>>,
    pub y_axis: YAxis,
}

/// One named series of `(x, y)` points with a palette colour index.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    pub name: String,
    pub points: Vec<(f64, f64)>,
    pub mark: Mark,
    pub color: usize,
}

/// A moment a chart marks with a vertical dashed line across its data, named in the legend.
#[derive(Debug, Clone, PartialEq)]
pub struct Moment {
    pub x: f64,
    pub name: String,
}

/// The vertical lines of the `moments` within the x range `series` are drawn over, across its y
/// range, each in its own colour from `first_color` on.
pub fn moment_lines(moments: &[Moment], series: &[Series], first_color: usize) -> Vec<Series> {
    let (x_range, y_range) = bounds(series);
    moments
        .iter()
        .filter(|moment| x_range.contains(&moment.x))
        .zip(first_color..)
        .map(|(moment, color)| Series {
            name: moment.name.clone(),
            points: vec![(moment.x, y_range.start), (moment.x, y_range.end)],
            mark: Mark::DashedLine,
            color,
        })
        .collect()
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

/// The legend's entries: the chart's own, or one for every series, series of one name, mark and
/// colour (the two sides of one bound) sharing theirs.
fn legend_keys(series: &[Series], options: &Options) -> Vec<Key> {
    if let Some(keys) = &options.keys {
        return keys.clone();
    }
    let mut keys: Vec<Key> = Vec::new();
    for one in series {
        let key = Key {
            name: one.name.clone(),
            mark: one.mark,
            color: Some(one.color),
        };
        if !keys.contains(&key) {
            keys.push(key);
        }
    }
    keys
}

/// The legend's corner or edge of the plot that hides none of the drawn points (lines counted
/// along their length), the upper right first among equals; where every one would hide some, the
/// y axis grows upwards by the legend's height and the legend goes in the upper right, above
/// the data. Returns the position and the y range. The legend's size is estimated from its
/// entries and the label font: a line of 20 px each, 8 px a character.
fn legend_position(
    series: &[Series],
    keys: &[Key],
    x_range: &std::ops::Range<f64>,
    y_range: std::ops::Range<f64>,
    plot_px: (f64, f64),
) -> (SeriesLabelPosition, std::ops::Range<f64>) {
    use SeriesLabelPosition::{
        LowerLeft, LowerMiddle, LowerRight, MiddleLeft, MiddleRight, UpperLeft, UpperMiddle,
        UpperRight,
    };
    let longest = keys
        .iter()
        .map(|key| key.name.chars().count())
        .max()
        .unwrap_or(0);
    let width = ((40.0 + 8.0 * longest as f64) / plot_px.0.max(1.0)).min(1.0);
    let height = ((10.0 + 20.0 * keys.len() as f64) / plot_px.1.max(1.0)).min(1.0);
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
            Mark::Points | Mark::OpenPoints | Mark::Dots => drawn.extend(points),
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

/// A linear axis over `range` whose grid lines and labels sit at `ticks`.
struct TickedAxis {
    range: std::ops::Range<f64>,
    ticks: Vec<f64>,
}

impl Ranged for TickedAxis {
    type FormatOption = plotters::coord::ranged1d::DefaultFormatting;
    type ValueType = f64;

    fn map(&self, value: &f64, limit: (i32, i32)) -> i32 {
        plotters::coord::types::RangedCoordf64::from(self.range.clone()).map(value, limit)
    }

    fn key_points<Hint: plotters::coord::ranged1d::KeyPointHint>(&self, hint: Hint) -> Vec<f64> {
        match hint.weight() {
            plotters::coord::ranged1d::KeyPointWeight::Bold => self.ticks.clone(),
            plotters::coord::ranged1d::KeyPointWeight::Any => Vec::new(),
        }
    }

    fn range(&self) -> std::ops::Range<f64> {
        self.range.clone()
    }
}

/// An axis's tick positions and how its labels are written.
#[derive(Debug, Clone, PartialEq)]
struct Ticks {
    at: Vec<f64>,
    /// Decimal places of every label; none: each label with as many as its value needs.
    decimals: Option<usize>,
}

impl Ticks {
    /// A tick's label: never `-0`, and with the places the axis's step needs.
    fn label(&self, value: f64) -> String {
        let text = match self.decimals {
            Some(decimals) => format!("{value:.decimals$}"),
            None if value.abs() >= 1.0 || value == 0.0 => format!("{value:.0}"),
            None => format!("{}", feeder_shared::number::Significant(value)),
        };
        match text.strip_prefix('-') {
            Some(magnitude) if magnitude.chars().all(|c| c == '0' || c == '.') => {
                magnitude.to_owned()
            }
            Some(magnitude) => format!("−{magnitude}"),
            None => text,
        }
    }
}

/// About eight ticks at a step of 1, 2 or 5 times a power of ten, labelled with the places the
/// step needs.
fn linear_ticks(range: &std::ops::Range<f64>) -> Ticks {
    let span = range.end - range.start;
    if !(span.is_finite() && span > 0.0) {
        return Ticks {
            at: Vec::new(),
            decimals: Some(0),
        };
    }
    let power = (span / 8.0).log10().floor();
    let unit = 10f64.powf(power);
    let step = [1.0, 2.0, 5.0, 10.0]
        .into_iter()
        .map(|factor| factor * unit)
        .find(|step| span / step <= 10.0)
        .unwrap_or(10.0 * unit);
    let first = (range.start / step).ceil() as i64;
    let last = (range.end / step).floor() as i64;
    Ticks {
        at: (first..=last).map(|k| k as f64 * step).collect(),
        decimals: Some((-step.log10().floor()).max(0.0) as usize),
    }
}

/// Ticks of a [`YAxis::SymLog`] axis, in its mapped values: zero and every power of ten from
/// ten times `linear_within` on (the first a third of a decade clear of zero), either side,
/// within `range`.
fn symlog_ticks(range: &std::ops::Range<f64>, linear_within: f64) -> Ticks {
    let axis = YAxis::SymLog { linear_within };
    let mut at = vec![0.0];
    let mut value = 10.0 * linear_within;
    while value.is_finite() && axis.map(value) <= range.end.max(-range.start) {
        at.extend([axis.map(value), axis.map(-value)]);
        value *= 10.0;
    }
    at.retain(|tick| range.contains(tick));
    at.sort_by(f64::total_cmp);
    Ticks { at, decimals: None }
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
        let keys = legend_keys(&series, &Options::default());
        let (position, y_range) = legend_position(&series, &keys, &range, range.clone(), plot_px);
        assert!(matches!(position, SeriesLabelPosition::UpperLeft));
        assert_eq!(y_range, range);
        // Points everywhere: the y axis grows and the legend's band above the data is empty.
        let series = [points("a", grid_without(2.0, 2.0, 2.0, 2.0))];
        let (position, y_range) = legend_position(&series, &keys, &range, range.clone(), plot_px);
        assert!(matches!(position, SeriesLabelPosition::UpperRight));
        let height = (10.0 + 20.0) / plot_px.1;
        let highest = 1.0 / (y_range.end - y_range.start);
        assert!(highest <= 1.0 - height + 1e-12, "{highest} {height}");
    }

    #[test]
    fn the_two_sides_of_a_bound_share_one_legend_entry() {
        let bound = |y: f64| Series {
            name: "±50 µm".into(),
            points: vec![(0.0, y), (1.0, y)],
            mark: Mark::DashedLine,
            color: 1,
        };
        let series = [
            points("sliding", vec![(0.0, 0.0), (1.0, 1.0)]),
            bound(50.0),
            bound(-50.0),
        ];
        let names: Vec<String> = legend_keys(&series, &Options::default())
            .into_iter()
            .map(|key| key.name)
            .collect();
        assert_eq!(names, ["sliding", "±50 µm"]);
    }

    #[test]
    fn a_legend_of_its_own_replaces_the_series_names() {
        let key = Key {
            name: "quasi-static (Eq. 9)".into(),
            mark: Mark::DashedLine,
            color: None,
        };
        let options = Options {
            keys: Some(vec![key.clone()]),
            ..Options::default()
        };
        let series = [points("a", vec![(0.0, 0.0)])];
        assert_eq!(legend_keys(&series, &options), [key]);
    }

    #[test]
    fn tick_labels_never_read_minus_zero_and_carry_the_steps_places() {
        for range in [
            -0.1537..0.1537,
            -52.0..101.0,
            -1e-9..3e-9,
            0.978..1.026,
            -1.0..1e-17,
        ] {
            let ticks = linear_ticks(&range);
            assert!(ticks.at.len() >= 3, "{range:?}: {ticks:?}");
            let labels: Vec<String> = ticks.at.iter().map(|&at| ticks.label(at)).collect();
            for label in &labels {
                let magnitude = label.trim_start_matches(['-', '−']);
                let is_zero = magnitude.chars().all(|c| c == '0' || c == '.');
                assert!(!(is_zero && label != magnitude), "{range:?}: {labels:?}");
            }
            let mut distinct = labels.clone();
            distinct.dedup();
            assert_eq!(distinct, labels, "{range:?}");
        }
        let ticks = linear_ticks(&(-0.1537..0.1537));
        assert_eq!(ticks.label(-0.0), "0.00");
        assert_eq!(ticks.label(1e-17), "0.00");
        assert_eq!(ticks.label(-0.05), "−0.05");
        assert_eq!(linear_ticks(&(0.0..250.0)).label(250.0), "250");
    }

    #[test]
    fn the_symlog_axis_is_linear_near_zero_logarithmic_beyond_and_labelled_in_data_units() {
        let axis = YAxis::SymLog { linear_within: 0.1 };
        for y in [-3500.0, -76.6, -1.0, -1e-4, 0.0, 2.5, 1807.9, 3076.4] {
            let back = axis.unmap(axis.map(y));
            assert!((back - y).abs() <= 1e-12 * y.abs().max(1.0), "{y} {back}");
        }
        // Monotone, and a decade far from zero is one unit of the axis.
        assert!(axis.map(-1.0) < axis.map(0.0) && axis.map(0.0) < axis.map(1e-3));
        let decade = axis.map(1000.0) - axis.map(100.0);
        assert!((decade - 1.0).abs() < 1e-3, "{decade}");
        let range = axis.map(-80.0)..axis.map(3500.0);
        let ticks = symlog_ticks(&range, 0.1);
        let labels: Vec<String> = ticks
            .at
            .iter()
            .map(|&at| ticks.label(axis.unmap(at)))
            .collect();
        assert_eq!(labels, ["−10", "−1", "0", "1", "10", "100", "1000"]);
    }

    #[test]
    fn moments_outside_the_data_are_not_drawn_and_the_others_span_it() {
        let series = [points("trace", vec![(0.0, -2.0), (111.0, 5.0)])];
        let moments = [
            Moment {
                x: 40.0,
                name: "start".into(),
            },
            Moment {
                x: 216.0,
                name: "new duty".into(),
            },
        ];
        let lines = moment_lines(&moments, &series, 3);
        assert_eq!(lines.len(), 1);
        assert_eq!(lines[0].name, "start");
        assert_eq!(lines[0].color, 3);
        let (_, y_range) = bounds(&series);
        assert_eq!(
            lines[0].points,
            [(40.0, y_range.start), (40.0, y_range.end)]
        );
    }
}
