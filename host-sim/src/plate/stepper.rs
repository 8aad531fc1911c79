//! The real plate and its part advanced one commanded segment at a time, for callers that choose
//! each segment from what the plate did before (a closed loop) as well as for [`super::run()`].

use crate::contact::Contact;
use crate::error::SimError;
use crate::segments::PlateSegment;

use super::free::FreeSolver;
use super::linear::{self, Matrix, State, F, P, Q, U, V, X};
use super::model::{ContactEvent, Part, PlateModel, Slide};
use super::motion::GeneralSolver;
use super::params::PlateParams;
use super::solver::Solver;
use super::trajectory::{Piece, Trajectory};

/// Samples per segment of a trace, evenly spaced, besides every event.
pub const TRACE_SAMPLES_PER_SEGMENT: usize = 32;

/// At most this many events within one segment before the run is refused as chatter.
const MAX_EVENTS_PER_SEGMENT: usize = 10_000;

/// Where the plate hit an end stop.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct EndStop {
    pub time_s: f64,
    /// `±x_lim`.
    pub position_m: f64,
    pub velocity_mps: f64,
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

/// The plate on its slide and the part riding on it, from the plate at rest at `x = 0` and the
/// part at rest on it. With a current loop the drive's force starts at 0; without one it is at
/// its target from the first instant of each segment.
#[derive(Debug)]
pub struct Stepper {
    model: PlateModel,
    /// The free slide's scalar solution where the slide has no Coulomb friction, else the
    /// general solver.
    solver: Box<dyn Solver>,
    z: State,
    slide: Slide,
    part: Part,
    time_s: f64,
    peak_m: f64,
    end_stop: Option<EndStop>,
    points: Option<Vec<PlatePoint>>,
    pieces: Option<Vec<Piece>>,
    /// The drive's enable: while off its target force is zero, whatever the command.
    drive_enabled: bool,
}

impl Stepper {
    /// Refuses a plate whose parameters are out of range.
    pub fn new(params: &PlateParams, contact: &Contact) -> Result<Self, SimError> {
        params.validate()?;
        let slide = if params.coulomb_friction_n > 0.0 {
            Slide::Stuck
        } else {
            Slide::Free
        };
        let model = PlateModel::new(*params, *contact);
        let solver: Box<dyn Solver> = match FreeSolver::new(&model) {
            Some(free) => Box::new(free),
            None => Box::new(GeneralSolver::new(&model)),
        };
        Ok(Stepper {
            model,
            solver,
            z: [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0],
            slide,
            part: Part::Stuck,
            time_s: 0.0,
            peak_m: 0.0,
            end_stop: None,
            points: None,
            pieces: None,
            drive_enabled: true,
        })
    }

    /// Switches the drive's enable for the segments that follow (on from the start): while it
    /// is off the drive's target force is zero, its offset included, and with a current loop
    /// its force decays to zero through it.
    pub fn set_drive_enabled(&mut self, enabled: bool) {
        self.drive_enabled = enabled;
    }

    /// Also records the plate and the part at every event and at [`TRACE_SAMPLES_PER_SEGMENT`]
    /// instants per segment ([`Stepper::take_points`]).
    pub fn with_points(mut self) -> Self {
        self.points = Some(Vec::new());
        self
    }

    /// Also records the motion between events exactly, for sensors ([`Stepper::trajectory`]).
    pub fn with_trajectory(mut self) -> Self {
        self.pieces = Some(Vec::new());
        self
    }

    /// Time since the start.
    pub fn time_s(&self) -> f64 {
        self.time_s
    }

    pub fn plate_position_m(&self) -> f64 {
        self.z[X]
    }

    pub fn plate_velocity_mps(&self) -> f64 {
        self.z[V]
    }

    /// The part's displacement along the track since the start.
    pub fn part_position_m(&self) -> f64 {
        self.z[P]
    }

    /// `∫x dt` since the start, for the plate's mean position.
    pub fn position_integral_ms(&self) -> f64 {
        self.z[Q]
    }

    /// Largest `|x|` so far.
    pub fn peak_excursion_m(&self) -> f64 {
        self.peak_m
    }

    /// Set once the plate has hit an end stop; no segment runs after it.
    pub fn end_stop(&self) -> Option<EndStop> {
        self.end_stop
    }

    /// The points recorded so far (empty unless [`Stepper::with_points`]).
    pub fn take_points(&mut self) -> Vec<PlatePoint> {
        self.points.as_mut().map(std::mem::take).unwrap_or_default()
    }

    /// The motion recorded so far (empty unless [`Stepper::with_trajectory`]).
    pub fn trajectory(&self) -> Trajectory {
        Trajectory::new(self.pieces.clone().unwrap_or_default())
    }

    /// Runs one commanded segment, or up to the end stop it hits. Refuses a duration that is
    /// negative or not finite and an acceleration that is not finite, changing nothing.
    pub fn segment(&mut self, segment: &PlateSegment) -> Result<(), SimError> {
        self.segment_before(segment, None)
    }

    /// [`Stepper::segment`], knowing the segment that comes `next`: where it holds the command,
    /// the plate's motion is worked out over both at once. The outcome is the same.
    pub fn segment_before(
        &mut self,
        segment: &PlateSegment,
        next: Option<&PlateSegment>,
    ) -> Result<(), SimError> {
        if !segment.is_valid() {
            return Err(SimError::BadRange {
                what: "every segment needs a finite duration ≥ 0 and a finite acceleration",
            });
        }
        if self.end_stop.is_some() {
            return Ok(());
        }
        let model = &self.model;
        let target_n = if self.drive_enabled {
            model.params.target_force_n(segment.accel_mps2)
        } else {
            0.0
        };
        if model.lag_per_s.is_none() {
            self.z[F] = target_n;
        }
        let command = segment.accel_mps2;
        // A next segment of the same (finite) command holds it; one of a bad duration is
        // refused when it comes, and holds nothing meanwhile.
        let held_s = next
            .filter(|next| next.accel_mps2 == segment.accel_mps2 && next.duration_s.is_finite())
            .map_or(0.0, |next| next.duration_s.max(0.0));
        self.solver
            .begin(target_n, segment.duration_s, segment.duration_s + held_s);
        let mut offset_s = 0.0;
        for _ in 0..MAX_EVENTS_PER_SEGMENT {
            model.settle(&mut self.z, &mut self.slide, &mut self.part);
            let (next, end_z) =
                self.solver
                    .next_event(self.slide, self.part, &self.z, offset_s, &mut self.peak_m);
            let until_s = next.map_or(segment.duration_s, |(_, t)| offset_s + t);
            if self.points.is_some() || self.pieces.is_some() {
                let a = model.matrix(self.slide, self.part, target_n);
                if let Some(points) = self.points.as_mut() {
                    let span = (self.time_s, segment.duration_s);
                    sample(
                        points, &a, &self.z, self.part, command, span, offset_s, until_s,
                    );
                }
                if let Some(pieces) = self.pieces.as_mut() {
                    pieces.push(Piece {
                        start_s: self.time_s + offset_s,
                        end_s: self.time_s + until_s,
                        a,
                        z: self.z,
                    });
                }
            }
            self.z = end_z;
            if self.part == Part::Stuck {
                self.z[U] = self.z[V];
            }
            self.peak_m = self.peak_m.max(self.z[X].abs());
            match next {
                None => {
                    self.time_s += segment.duration_s;
                    return Ok(());
                }
                Some((ContactEvent::EndStop, t)) => {
                    let x_lim = model.params.end_stop_m.unwrap_or(f64::INFINITY);
                    let time_s = self.time_s + offset_s + t;
                    self.end_stop = Some(EndStop {
                        time_s,
                        position_m: x_lim.copysign(self.z[X]),
                        velocity_mps: self.z[V],
                    });
                    self.peak_m = self.peak_m.max(x_lim);
                    self.time_s = time_s;
                    if let Some(points) = self.points.as_mut() {
                        points.push(point(time_s, &self.z, self.part, command));
                    }
                    return Ok(());
                }
                Some((event, t)) => {
                    offset_s += t;
                    model.apply(event, &mut self.z, &mut self.slide, &mut self.part);
                    if let Some(points) = self.points.as_mut() {
                        let time_s = self.time_s + offset_s;
                        points.push(point(time_s, &self.z, self.part, command));
                    }
                }
            }
        }
        Err(SimError::Chatter {
            time_s: self.time_s + offset_s,
        })
    }
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
