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
