//! A chart's axes: how the y axis maps values, where the ticks sit and how they are labelled.

use std::f64::consts::LN_10;
use std::ops::Range;

use plotters::coord::ranged1d::{DefaultFormatting, KeyPointHint, KeyPointWeight, Ranged};
use plotters::coord::types::RangedCoordf64;

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
    pub(super) fn map(self, y: f64) -> f64 {
        match self {
            YAxis::Linear => y,
            YAxis::SymLog { linear_within } => {
                y.signum() * (y.abs() / linear_within).ln_1p() / LN_10
            }
        }
    }

    /// The value at a place on the axis.
    pub(super) fn unmap(self, y: f64) -> f64 {
        match self {
            YAxis::Linear => y,
            YAxis::SymLog { linear_within } => {
                y.signum() * linear_within * (y.abs() * LN_10).exp_m1()
            }
        }
    }
}

/// A linear axis over `range` whose grid lines and labels sit at `ticks`.
pub(super) struct TickedAxis {
    pub(super) range: Range<f64>,
    pub(super) ticks: Vec<f64>,
}

impl Ranged for TickedAxis {
    type FormatOption = DefaultFormatting;
    type ValueType = f64;

    fn map(&self, value: &f64, limit: (i32, i32)) -> i32 {
        RangedCoordf64::from(self.range.clone()).map(value, limit)
    }

    fn key_points<Hint: KeyPointHint>(&self, hint: Hint) -> Vec<f64> {
        match hint.weight() {
            KeyPointWeight::Bold => self.ticks.clone(),
            KeyPointWeight::Any => Vec::new(),
        }
    }

    fn range(&self) -> Range<f64> {
        self.range.clone()
    }
}

/// An axis's tick positions and how its labels are written.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Ticks {
    pub(super) at: Vec<f64>,
    /// Decimal places of every label; none: each label with as many as its value needs.
    decimals: Option<usize>,
}

impl Ticks {
    /// A tick's label: never `-0`, and with the places the axis's step needs.
    pub(super) fn label(&self, value: f64) -> String {
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
pub(super) fn linear_ticks(range: &Range<f64>) -> Ticks {
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
pub(super) fn symlog_ticks(range: &Range<f64>, linear_within: f64) -> Ticks {
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

#[cfg(test)]
mod tests {
    use super::*;

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
}
