//! What a chart is made of: its series and their marks, the legend's entries, the moments it
//! marks, its titles and panels, and the ranges its data spans.

use std::ops::Range;

use super::axis::YAxis;

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
    pub(super) fn is_line(self) -> bool {
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

impl Series {
    /// `points` drawn with `mark` in palette colour `color`, under `name`.
    pub fn new(name: impl Into<String>, points: Vec<(f64, f64)>, mark: Mark, color: usize) -> Self {
        Series {
            name: name.into(),
            points,
            mark,
            color,
        }
    }

    /// A dashed horizontal line at `y` over `x`: a bound or a level the chart marks.
    pub fn level(name: impl Into<String>, y: f64, x: Range<f64>, color: usize) -> Self {
        Series::new(
            name,
            vec![(x.start, y), (x.end, y)],
            Mark::DashedLine,
            color,
        )
    }
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

/// One panel of a chart of panels stacked top to bottom: its y axis title and its series.
#[derive(Debug, Clone, PartialEq)]
pub struct Panel<'a> {
    pub y: &'a str,
    pub series: Vec<Series>,
}

/// Axis ranges covering every finite point, with a little margin.
pub(super) fn bounds(series: &[Series]) -> (Range<f64>, Range<f64>) {
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

    #[test]
    fn moments_outside_the_data_are_not_drawn_and_the_others_span_it() {
        let series = [Series::new(
            "trace",
            vec![(0.0, -2.0), (111.0, 5.0)],
            Mark::Points,
            0,
        )];
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
