//! Running the real plate and its part over a stream of commanded segments.

use crate::contact::Contact;
use crate::error::SimError;
use crate::segments::PlateSegment;

use std::collections::VecDeque;

use super::params::PlateParams;
use super::stepper::{EndStop, PlatePoint, Stepper};

/// How long to run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlateRunOptions {
    /// Cycles to simulate (counted at segments that start a cycle).
    pub cycles: u64,
    /// The last cycles over which the feed rate and the plate's mean position are averaged.
    pub average_cycles: u64,
}

/// The outcome of a run of the real plate.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct PlateRun {
    /// Mean part velocity over the averaged cycles (0 if none completed).
    pub feed_rate_mps: f64,
    /// Mean plate position over the averaged cycles (0 if none completed).
    pub mean_position_m: f64,
    /// Largest `|x|` over the run.
    pub peak_excursion_m: f64,
    /// Cycles completed.
    pub cycles: u64,
    /// Set when the run ended at an end stop.
    pub end_stop: Option<EndStop>,
}

/// Runs `segments` (the first must start a cycle) from the plate at rest at `x = 0` and the part
/// at rest on it, for `options.cycles` cycles or until an end stop is hit. With a current loop
/// the drive's force starts at 0; without one it is at its target from the first instant.
pub fn run<I>(
    params: &PlateParams,
    contact: &Contact,
    segments: I,
    options: &PlateRunOptions,
) -> Result<PlateRun, SimError>
where
    I: IntoIterator<Item = PlateSegment>,
{
    run_recording(params, contact, segments, options, None)
}

/// [`run()`], also recording the plate and the part at every event and at
/// [`super::TRACE_SAMPLES_PER_SEGMENT`] instants per segment.
pub fn trace<I>(
    params: &PlateParams,
    contact: &Contact,
    segments: I,
    options: &PlateRunOptions,
) -> Result<(PlateRun, Vec<PlatePoint>), SimError>
where
    I: IntoIterator<Item = PlateSegment>,
{
    let mut points = Vec::new();
    let run = run_recording(params, contact, segments, options, Some(&mut points))?;
    Ok((run, points))
}

fn run_recording<I>(
    params: &PlateParams,
    contact: &Contact,
    segments: I,
    options: &PlateRunOptions,
    points: Option<&mut Vec<PlatePoint>>,
) -> Result<PlateRun, SimError>
where
    I: IntoIterator<Item = PlateSegment>,
{
    if options.average_cycles == 0 || options.average_cycles > options.cycles {
        return Err(SimError::BadRange {
            what: "the averaged cycles must be between 1 and the cycles run",
        });
    }
    let mut stepper = Stepper::new(params, contact)?;
    if points.is_some() {
        stepper = stepper.with_points();
    }
    // (time, part position, ∫x dt) at the start of every cycle still inside the window.
    let mut marks: VecDeque<(f64, f64, f64)> = VecDeque::new();
    let mark = |marks: &mut VecDeque<(f64, f64, f64)>, stepper: &Stepper| {
        marks.push_back((
            stepper.time_s(),
            stepper.part_position_m(),
            stepper.position_integral_ms(),
        ));
        if marks.len() as u64 > options.average_cycles + 1 {
            marks.pop_front();
        }
    };
    let mut cycles = 0_u64;
    let mut started = false;
    let mut segments = segments.into_iter();
    let mut next = segments.next();
    while let Some(segment) = next {
        next = segments.next();
        if segment.starts_cycle {
            if started {
                cycles += 1;
            }
            mark(&mut marks, &stepper);
            if cycles == options.cycles {
                break;
            }
            started = true;
        }
        stepper.segment_before(&segment, next.as_ref())?;
        if stepper.end_stop().is_some() {
            break;
        }
    }
    if stepper.end_stop().is_none() && started && cycles < options.cycles {
        cycles += 1;
        mark(&mut marks, &stepper);
    }
    if let Some(points) = points {
        *points = stepper.take_points();
    }
    // After an end stop the last mark starts the cycle the hit interrupted, so the window holds
    // complete cycles only.
    let (feed_rate_mps, mean_position_m) = match (marks.front(), marks.back()) {
        (Some(first), Some(last)) if marks.len() >= 2 => {
            let window_s = last.0 - first.0;
            ((last.1 - first.1) / window_s, (last.2 - first.2) / window_s)
        }
        _ => (0.0, 0.0),
    };
    Ok(PlateRun {
        feed_rate_mps,
        mean_position_m,
        peak_excursion_m: stepper.peak_excursion_m(),
        cycles,
        end_stop: stepper.end_stop(),
    })
}
