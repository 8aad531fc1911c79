//! Running the real plate and its part over a stream of commanded segments.

use crate::error::SimError;
use crate::plant::{Contact, PlateSegment};

use super::linear::{self, Matrix, State, F, P, Q, U, V, X};
use super::motion::{Event, Model, Part, Slide};
use super::params::PlateParams;
use super::regime::Regimes;

/// How long to run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlateRunOptions {
    /// Cycles to simulate (counted at segments that start a cycle).
    pub cycles: u64,
    /// The last cycles over which the feed rate and the plate's mean position are averaged.
    pub average_cycles: u64,
}

/// Where the plate hit an end stop.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct EndStop {
    pub time_s: f64,
    /// `±x_lim`.
    pub position_m: f64,
    pub velocity_mps: f64,
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

/// The plate and the part at one instant of a traced run.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct PlatePoint {
    pub time_s: f64,
    pub plate_position_m: f64,
    pub plate_velocity_mps: f64,
    pub part_velocity_mps: f64,
    /// The segment's commanded acceleration.
    pub command_mps2: f64,
}

/// Samples per segment of a trace, evenly spaced, besides every event.
pub const TRACE_SAMPLES_PER_SEGMENT: usize = 32;

/// At most this many events within one segment before the run is refused as chatter.
const MAX_EVENTS_PER_SEGMENT: usize = 10_000;

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
/// [`TRACE_SAMPLES_PER_SEGMENT`] instants per segment.
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

fn point(time_s: f64, z: &State, part: Part, command_mps2: f64) -> PlatePoint {
    PlatePoint {
        time_s,
        plate_position_m: z[X],
        plate_velocity_mps: z[V],
        part_velocity_mps: if part == Part::Stuck { z[V] } else { z[U] },
        command_mps2,
    }
}

/// Pushes the samples of a segment of `duration_s` (from `start_s`) that fall in
/// `[from_s, until_s)` of it, from the state `z` at `from_s` under `a`.
#[allow(clippy::too_many_arguments)]
fn sample(
    points: &mut Vec<PlatePoint>,
    a: &Matrix,
    z: &State,
    part: Part,
    command_mps2: f64,
    (start_s, duration_s): (f64, f64),
    from_s: f64,
    until_s: f64,
) {
    let step_s = duration_s / TRACE_SAMPLES_PER_SEGMENT as f64;
    for k in 0..TRACE_SAMPLES_PER_SEGMENT {
        let at_s = k as f64 * step_s;
        if at_s >= from_s && at_s < until_s {
            let zt = linear::apply(&linear::exp(a, at_s - from_s), z);
            points.push(point(start_s + at_s, &zt, part, command_mps2));
        }
    }
}

fn run_recording<I>(
    params: &PlateParams,
    contact: &Contact,
    segments: I,
    options: &PlateRunOptions,
    mut points: Option<&mut Vec<PlatePoint>>,
) -> Result<PlateRun, SimError>
where
    I: IntoIterator<Item = PlateSegment>,
{
    params.validate()?;
    if options.average_cycles == 0 || options.average_cycles > options.cycles {
        return Err(SimError::BadRange {
            what: "the averaged cycles must be between 1 and the cycles run",
        });
    }
    let model = Model::new(*params, *contact);
    let mut regimes = Regimes::default();
    let mut z: State = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0];
    let mut slide = if params.coulomb_friction_n > 0.0 {
        Slide::Stuck
    } else {
        Slide::Free
    };
    let mut part = Part::Stuck;
    let mut time_s = 0.0;
    let mut peak_m = 0.0_f64;
    // (time, part position, ∫x dt) at the start of every cycle still inside the window.
    let mut marks: std::collections::VecDeque<(f64, f64, f64)> = Default::default();
    let mut cycles = 0_u64;
    let mut started = false;
    let mut end_stop = None;
    'segments: for segment in segments {
        if segment.starts_cycle {
            if started {
                cycles += 1;
            }
            marks.push_back((time_s, z[P], z[Q]));
            if marks.len() as u64 > options.average_cycles + 1 {
                marks.pop_front();
            }
            if cycles == options.cycles {
                break;
            }
            started = true;
        }
        let valid = segment.duration_s >= 0.0
            && segment.duration_s.is_finite()
            && segment.accel_mps2.is_finite();
        if !valid {
            return Err(SimError::BadRange {
                what: "every segment needs a finite duration ≥ 0 and a finite acceleration",
            });
        }
        let target_n = params.target_force_n(segment.accel_mps2);
        if model.lag_per_s.is_none() {
            z[F] = target_n;
        }
        let mut offset_s = 0.0;
        for _ in 0..MAX_EVENTS_PER_SEGMENT {
            model.settle(&mut z, &mut slide, &mut part);
            let regime = regimes.get(&model, slide, part, target_n);
            let a = &regime.a;
            let rest_s = (segment.duration_s - offset_s).max(0.0);
            let (next, end_z) = model.next_event(regime, &z, rest_s, |x| {
                peak_m = peak_m.max(x.abs());
            });
            if let Some(points) = points.as_deref_mut() {
                let until_s = next.map_or(segment.duration_s, |(_, t)| offset_s + t);
                let span = (time_s, segment.duration_s);
                let command = segment.accel_mps2;
                sample(points, a, &z, part, command, span, offset_s, until_s);
            }
            z = end_z;
            if part == Part::Stuck {
                z[U] = z[V];
            }
            peak_m = peak_m.max(z[X].abs());
            match next {
                None => {
                    time_s += segment.duration_s;
                    continue 'segments;
                }
                Some((Event::EndStop, t)) => {
                    let x_lim = params.end_stop_m.unwrap_or(f64::INFINITY);
                    end_stop = Some(EndStop {
                        time_s: time_s + offset_s + t,
                        position_m: x_lim.copysign(z[X]),
                        velocity_mps: z[V],
                    });
                    peak_m = peak_m.max(x_lim);
                    if let Some(points) = points.as_deref_mut() {
                        points.push(point(time_s + offset_s + t, &z, part, segment.accel_mps2));
                    }
                    break 'segments;
                }
                Some((event, t)) => {
                    offset_s += t;
                    model.apply(event, &mut z, &mut slide, &mut part);
                    if let Some(points) = points.as_deref_mut() {
                        points.push(point(time_s + offset_s, &z, part, segment.accel_mps2));
                    }
                }
            }
        }
        return Err(SimError::Chatter {
            time_s: time_s + offset_s,
        });
    }
    if end_stop.is_none() && started && cycles < options.cycles {
        cycles += 1;
        marks.push_back((time_s, z[P], z[Q]));
        if marks.len() as u64 > options.average_cycles + 1 {
            marks.pop_front();
        }
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
        peak_excursion_m: peak_m,
        cycles,
        end_stop,
    })
}
