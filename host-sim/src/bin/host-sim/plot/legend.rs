//! A chart's legend: its entries and the place on the plot where it hides no data.

use std::ops::Range;

use plotters::prelude::SeriesLabelPosition;

use super::series::{Key, Mark, Options, Series};

/// The legend's entries: the chart's own, or one for every series, series of one name, mark and
/// colour (the two sides of one bound) sharing theirs.
pub(super) fn legend_keys(series: &[Series], options: &Options) -> Vec<Key> {
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
pub(super) fn legend_position(
    series: &[Series],
    keys: &[Key],
    x_range: &Range<f64>,
    y_range: Range<f64>,
    plot_px: (f64, f64),
) -> (SeriesLabelPosition, Range<f64>) {
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

#[cfg(test)]
mod tests {
    use super::*;

    fn points(name: &str, points: Vec<(f64, f64)>) -> Series {
        Series::new(name, points, Mark::Points, 0)
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
}
