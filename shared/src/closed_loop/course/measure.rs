//! What the course reads of the plate: positions sampled at ticks ([`PositionSample`]) and, of
//! a cycle begun, where it turned and its mean position.

use crate::closed_loop::shape::CycleShape;

/// A plate position sampled at a tick of the output's timeline.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PositionSample {
    pub tick: u64,
    pub position_m: f64,
}

/// A cycle begun, as the course keeps it until the next boundary.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Begun {
    pub(super) start: PositionSample,
    pub(super) shape: CycleShape,
    /// Runs at the plan's full amplitude: only those cycles' strokes and means are held.
    pub(super) full: bool,
    pub(super) idle: bool,
    /// A settle segment.
    pub(super) settle: bool,
    pub(super) clock_hz: u32,
}

/// The position sampled nearest `delay_s` after the turning tick of cycle `last`: the drive's
/// current loop delays the plate's motion by its lag, and the velocity is zero at the delayed
/// turn, so the nearest sample is off by at most `a·Δt²/8`.
pub(super) fn turn_position_m(last: &Begun, samples: &[PositionSample], delay_s: f64) -> f64 {
    position_near_m(last, samples, last.shape.turn_s + delay_s)
}

/// The position latched nearest `after_s` after the start of cycle `last`: at its start or
/// sampled through it.
pub(super) fn position_near_m(last: &Begun, samples: &[PositionSample], after_s: f64) -> f64 {
    let tick = last.start.tick as f64 + after_s * f64::from(last.clock_hz);
    let distance = |sample: &PositionSample| libm::fabs(sample.tick as f64 - tick);
    samples
        .iter()
        .chain(core::iter::once(&last.start))
        .min_by(|a, b| distance(a).total_cmp(&distance(b)))
        .map_or(last.start.position_m, |sample| sample.position_m)
}

/// The mean position from `start` to `end` through `samples` (trapezoids).
pub fn mean_position_m(
    start: PositionSample,
    samples: &[PositionSample],
    end: PositionSample,
) -> f64 {
    let mut area = 0.0;
    let mut previous = start;
    for sample in samples.iter().chain(core::iter::once(&end)) {
        let ticks = sample.tick.saturating_sub(previous.tick) as f64;
        area += ticks * (sample.position_m + previous.position_m) / 2.0;
        previous = *sample;
    }
    let ticks = end.tick.saturating_sub(start.tick) as f64;
    if ticks > 0.0 {
        area / ticks
    } else {
        start.position_m
    }
}

/// The acceleration of a parabola fitted to the positions from `start` through `samples` to
/// `end` (least squares on `x = x₀ + v·t + a·t²/2`, `t` from `start`, ticks of `clock_hz`), m/s²;
/// `None` with fewer than four positions.
pub(super) fn fitted_accel_mps2(
    start: PositionSample,
    samples: &[PositionSample],
    end: PositionSample,
    clock_hz: u32,
) -> Option<f64> {
    let points = || {
        core::iter::once(&start)
            .chain(samples)
            .chain(core::iter::once(&end))
    };
    if points().count() < 4 || clock_hz == 0 {
        return None;
    }
    // Normal equations of the basis [1, t, t²/2], solved by Cramer's rule.
    let mut normal = [[0.0; 3]; 3];
    let mut right = [0.0; 3];
    for point in points() {
        let t = point.tick.saturating_sub(start.tick) as f64 / f64::from(clock_hz);
        let basis = [1.0, t, t * t / 2.0];
        for row in 0..3 {
            for column in 0..3 {
                normal[row][column] += basis[row] * basis[column];
            }
            right[row] += basis[row] * point.position_m;
        }
    }
    let det = |m: [[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let whole = det(normal);
    let mut replaced = normal;
    for (row, value) in right.iter().enumerate() {
        replaced[row][2] = *value;
    }
    let accel_mps2 = det(replaced) / whole;
    accel_mps2.is_finite().then_some(accel_mps2)
}
