//! The part's feed rate on the plate the drive and the slide make of a cycle's plan, and the
//! amplitude that gives the ideal plate's feed.
//!
//! The drive's current loop is a first-order lag `τ·ȧ + a = u`: in the periodic motion it
//! settles into, the plate's velocity is `v = v_u − τ·a` with `v_u` the plan's own velocity
//! from rest at the cycle's start ([`CycleShape::behind_lag`](super::CycleShape::behind_lag)).
//! The lag rounds every corner of the velocity profile, and the feed, set by where the part's
//! velocity crosses the plate's, falls: at 150 Hz of bandwidth by 5 % at 50 Hz and d = 0.53, by
//! 45 % at 100 Hz and d = 0.61. The slide's forces (Coulomb and viscous friction, a centring
//! spring) are fed forward segment by segment as their mean along the plan
//! ([`SegmentMotion::slide_mps2`]); inside a segment what they leave bends the profile too.
//! Scaling the levels by an amplitude `m` brings the feed back as far as the drive's linear
//! range allows.
//!
//! The plate is integrated through the cycle with the lag exact at every step and the slide's
//! forces by the step's start (a change of the velocity's sign placed inside its step); a
//! constant bias, as the loop's centring applies, makes its velocity periodic. The part is the
//! paper's (Section III): a point mass under Coulomb friction `μg`, sliding at `±μg` toward
//! the plate's velocity or stuck to the plate while the plate's acceleration is at most `μg`.
//! Its periodic motion is found by Newton's steps on its velocity at the cycle's start, kept
//! in a bracket (one cycle's map is monotone), each crossing placed inside its step.

use libm::{exp, fabs};

use super::envelope::ENVELOPE;
use super::identify::Identified;
use super::shape::{sign, CommandSegment, CycleShape, SegmentMotion};
use crate::waveform::Waveform;

/// Steps of the part's integration per cycle: the amplitude found is within 3·10⁻⁴ of 4000 steps'
/// at 150 Hz of bandwidth, 50–100 Hz and d = 0.53–0.61.
pub const STEPS_PER_CYCLE: usize = 250;
/// The periodic motion's search stops at this velocity error.
const VELOCITY_TOLERANCE_MPS: f64 = 1e-6;
const SEARCH_STEPS_MAX: usize = 60;
/// The amplitude's search stops at this relative feed error.
const FEED_TOLERANCE: f64 = 3e-4;
const AMPLITUDE_STEPS_MAX: usize = 12;

/// What moves the plate besides the command: the drive's lag and the slide, each force over
/// the moving mass.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PlateModel {
    pub lag_s: f64,
    pub coulomb_mps2: f64,
    pub viscous_per_s: f64,
    pub spring_per_s2: f64,
}

impl PlateModel {
    /// The ideal plate: it follows the plan.
    pub const IDEAL: PlateModel = PlateModel {
        lag_s: 0.0,
        coulomb_mps2: 0.0,
        viscous_per_s: 0.0,
        spring_per_s2: 0.0,
    };

    /// The plate of an identified drive.
    pub fn of(drive: &Identified) -> Self {
        PlateModel {
            lag_s: drive.lag_s,
            coulomb_mps2: drive.coulomb_mps2,
            viscous_per_s: drive.viscous_per_s,
            spring_per_s2: drive.spring_per_s2,
        }
    }
}

/// The plate's periodic motion through one cycle of `segments` on a plate model, with the
/// slide's forces fed forward segment by segment.
#[derive(Debug, Clone, Copy)]
struct LaggedCycle<'a> {
    segments: &'a [CommandSegment],
    model: PlateModel,
    /// The lag's output at the cycle's start, periodic.
    start_accel_mps2: f64,
    /// The plate's position at the start, about the cycle's mean.
    start_m: f64,
    /// The slide's feedforward in each segment, and the bias that keeps the velocity periodic.
    feedforward_mps2: [f64; 4],
    bias_mps2: f64,
    /// What the start's velocity has beside the lag's: the plate does not drift.
    start_shift_mps: f64,
    /// The plan's turn (the stroke's far end).
    turn_s: f64,
}

impl<'a> LaggedCycle<'a> {
    fn new(segments: &'a [CommandSegment], model: PlateModel) -> Self {
        let lag_s = if model.lag_s > 0.0 { model.lag_s } else { 0.0 };
        let (mut slope, mut constant) = (1.0, 0.0);
        if lag_s > 0.0 {
            for segment in segments {
                let decay = exp(-segment.duration_s / lag_s);
                slope *= decay;
                constant = segment.accel_mps2 + (constant - segment.accel_mps2) * decay;
            }
        }
        let shape = CycleShape::new(segments);
        let motion = shape.map_or([SegmentMotion::default(); 4], |shape| shape.segment_motion);
        let mut cycle = LaggedCycle {
            segments,
            model: PlateModel { lag_s, ..model },
            start_accel_mps2: if lag_s > 0.0 {
                constant / (1.0 - slope)
            } else {
                segments.first().map_or(0.0, |s| s.accel_mps2)
            },
            start_m: shape.map_or(0.0, |shape| -shape.mean_m),
            feedforward_mps2: motion.map(|m| {
                m.slide_mps2(model.coulomb_mps2, model.viscous_per_s, model.spring_per_s2)
            }),
            bias_mps2: 0.0,
            start_shift_mps: 0.0,
            turn_s: shape.map_or(0.0, |shape| shape.turn_s),
        };
        // The centring's bias and the start's velocity: the velocity periodic, and no drift
        // (the loop keeps the plate's mean at the centre). Exact in one round without a slide;
        // with one, the second takes up what the slide's forces make of the first's change.
        let period_s = cycle.period_s();
        let slide =
            model.coulomb_mps2 != 0.0 || model.viscous_per_s != 0.0 || model.spring_per_s2 != 0.0;
        for _ in 0..if slide { 2 } else { 1 } {
            let (mut end_v, mut end_m) = (cycle.start_velocity_mps(), cycle.start_m);
            cycle.for_each_step(|_, v, _, x| (end_v, end_m) = (v, x));
            cycle.bias_mps2 -= (end_v - cycle.start_velocity_mps()) / period_s;
            cycle.start_shift_mps -= (end_m - cycle.start_m) / period_s;
        }
        cycle
    }

    fn period_s(&self) -> f64 {
        self.segments.iter().map(|s| s.duration_s).sum()
    }

    /// The plate's velocity at the cycle's start: `v_u = 0` there.
    fn start_velocity_mps(&self) -> f64 {
        -self.model.lag_s * self.start_accel_mps2 + self.start_shift_mps
    }

    /// Calls `step(h, velocity, acceleration, position)` with the plate's state at the end of
    /// every step of the cycle.
    fn for_each_step(&self, mut step: impl FnMut(f64, f64, f64, f64)) {
        let period_s = self.period_s();
        let PlateModel {
            lag_s,
            coulomb_mps2,
            viscous_per_s,
            spring_per_s2,
        } = self.model;
        let (mut lagged, mut v, mut x) = (
            self.start_accel_mps2,
            self.start_velocity_mps(),
            self.start_m,
        );
        for (place, segment) in self.segments.iter().enumerate() {
            let u = segment.accel_mps2;
            let fed_mps2 =
                self.feedforward_mps2.get(place).copied().unwrap_or(0.0) + self.bias_mps2;
            let count = libm::ceil(segment.duration_s / period_s * STEPS_PER_CYCLE as f64).max(1.0);
            let h = segment.duration_s / count;
            let decay = if lag_s > 0.0 { exp(-h / lag_s) } else { 0.0 };
            // The lag's output averaged over a step, as a share of its distance from `u`.
            let mean_share = if lag_s > 0.0 {
                (1.0 - decay) * lag_s / h
            } else {
                0.0
            };
            for _ in 0..count as usize {
                let drive = u + (lagged - u) * mean_share;
                lagged = u + (lagged - u) * decay;
                let smooth = drive + fed_mps2 - viscous_per_s * v - spring_per_s2 * x;
                let mut next_v = v + (smooth - coulomb_mps2 * sign(v)) * h;
                if v * next_v < 0.0 {
                    // The slide's friction turns with the velocity inside the step.
                    let fraction = v / (v - next_v);
                    let signed = sign(v) * fraction + sign(next_v) * (1.0 - fraction);
                    next_v = v + (smooth - coulomb_mps2 * signed) * h;
                }
                let accel = (next_v - v) / h;
                x += (v + next_v) / 2.0 * h;
                v = next_v;
                step(h, v, accel, x);
            }
        }
    }

    /// The stroke read `τ` after the start and `τ` after the plan's turn, as the loop reads it.
    fn latched_stroke_m(&self) -> f64 {
        let (start_at, turn_at) = (self.model.lag_s, self.turn_s + self.model.lag_s);
        let (mut t, mut x_prev) = (0.0, self.start_m);
        let (mut start_m, mut turn_m) = (self.start_m, self.start_m);
        self.for_each_step(|h, _, _, x| {
            for (at, read) in [(start_at, &mut start_m), (turn_at, &mut turn_m)] {
                if t <= at && at < t + h {
                    *read = x_prev + (x - x_prev) * (at - t) / h;
                }
            }
            t += h;
            x_prev = x;
        });
        turn_m - start_m
    }

    /// The part's velocity at the cycle's end and its displacement through the cycle, from
    /// `part_v` at its start.
    /// And the derivative of the velocity at the end by the one at the start: the part keeps a
    /// change of its velocity while it slides, scaled at each meeting with the plate by the
    /// ratio of how fast the two velocities part after it to how fast they closed before; a
    /// part that sticks forgets it.
    fn part_cycle(&self, part_mps2: f64, mut part_v: f64) -> (f64, f64, f64) {
        let mut moved_m = 0.0;
        let mut plate_v = self.start_velocity_mps();
        let mut stuck = false;
        let mut slope = 1.0;
        self.for_each_step(|h, next_plate_v, accel, _| {
            if stuck && fabs(accel) <= part_mps2 {
                moved_m += (part_v + next_plate_v) / 2.0 * h;
                part_v = next_plate_v;
                plate_v = next_plate_v;
                return;
            }
            stuck = false;
            let ahead = plate_v - part_v;
            let direction = if ahead != 0.0 {
                sign(ahead)
            } else {
                sign(accel)
            };
            let next_v = part_v + direction * part_mps2 * h;
            let next_ahead = next_plate_v - next_v;
            if next_ahead * direction > 0.0 || direction == 0.0 {
                moved_m += (part_v + next_v) / 2.0 * h;
                part_v = next_v;
            } else {
                // The part meets the plate inside the step: it sticks there or slides on the
                // other way.
                let fraction = ahead / (ahead - next_ahead);
                let met_v = part_v + direction * part_mps2 * fraction * h;
                let rest_s = (1.0 - fraction) * h;
                moved_m += (part_v + met_v) / 2.0 * fraction * h;
                part_v = if fabs(accel) <= part_mps2 {
                    stuck = true;
                    slope = 0.0;
                    next_plate_v
                } else {
                    slope *= (accel + direction * part_mps2) / (accel - direction * part_mps2);
                    met_v - direction * part_mps2 * rest_s
                };
                moved_m += (met_v + part_v) / 2.0 * rest_s;
            }
            plate_v = next_plate_v;
        });
        (part_v, moved_m, slope)
    }

    /// The plate's lowest and highest velocity through the cycle.
    fn velocity_range(&self) -> (f64, f64) {
        let start_v = self.start_velocity_mps();
        let (mut low, mut high) = (start_v, start_v);
        self.for_each_step(|_, v, _, _| {
            low = low.min(v);
            high = high.max(v);
        });
        (low, high)
    }

    /// The part's mean velocity in its periodic motion on this plate.
    fn feed_rate_mps(&self, part_mps2: f64) -> f64 {
        // One cycle's map `F` is monotone and maps the plate's velocity range into itself:
        // `F(v) − v` is at least 0 at `low` and at most 0 at `high`. Between the part's changes
        // of course `F` is linear, so Newton's steps (with the slope from the pass itself)
        // land on the fixed point in a few passes; a step that leaves the bracket bisects it.
        let (mut low, mut high) = self.velocity_range();
        let mut v = (low + high) / 2.0;
        let mut moved_m = 0.0;
        for _ in 0..SEARCH_STEPS_MAX {
            let (end_v, moved, slope) = self.part_cycle(part_mps2, v);
            moved_m = moved;
            let gap = end_v - v;
            if gap >= 0.0 {
                low = v;
            }
            if gap <= 0.0 {
                high = v;
            }
            if fabs(gap) <= VELOCITY_TOLERANCE_MPS || high - low <= VELOCITY_TOLERANCE_MPS {
                break;
            }
            let newton = v - gap / (slope - 1.0);
            v = if slope < 1.0 && low < newton && newton < high {
                newton
            } else {
                (low + high) / 2.0
            };
        }
        moved_m / self.period_s()
    }
}

/// The part's feed rate (its mean velocity) on `model`'s plate playing `segments`
/// periodically, the part sliding at `part_mps2 = μg`.
pub fn feed_rate_mps(segments: &[CommandSegment], model: PlateModel, part_mps2: f64) -> f64 {
    LaggedCycle::new(segments, model).feed_rate_mps(part_mps2)
}

/// The amplitude that gives the plate the ideal plate's feed.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FeedCompensation {
    /// The factor on every level.
    pub amplitude: f64,
    /// The feed at that amplitude, and the ideal plate's.
    pub feed_mps: f64,
    pub ideal_mps: f64,
    /// The amplitude needed is beyond `amplitude_max`: `amplitude` is that limit, and
    /// `feed_mps` the feed the feeder gives instead of the ideal.
    pub limited: bool,
    /// The stroke the plate shows at that amplitude (read behind the lag) over the plan's
    /// stroke behind the lag alone, times the amplitude: the loop holds the stroke there.
    pub stroke_factor: f64,
}

/// The amplitude within `[1/amplitude_max, amplitude_max]` that gives `model`'s plate playing
/// `segments` the feed the ideal plate has, found by secant steps on the feed.
pub fn compensate(
    segments: &[CommandSegment],
    model: PlateModel,
    part_mps2: f64,
    amplitude_max: f64,
) -> FeedCompensation {
    let ideal_mps = feed_rate_mps(segments, PlateModel::IDEAL, part_mps2);
    let count = segments.len().min(4);
    let scaled = |amplitude: f64| {
        let mut scaled = [CommandSegment {
            duration_s: 0.0,
            accel_mps2: 0.0,
        }; 4];
        for (scaled, segment) in scaled.iter_mut().zip(&segments[..count]) {
            *scaled = CommandSegment {
                accel_mps2: segment.accel_mps2 * amplitude,
                ..*segment
            };
        }
        scaled
    };
    let feed_at = |amplitude: f64| feed_rate_mps(&scaled(amplitude)[..count], model, part_mps2);
    let (low, high) = (1.0 / amplitude_max, amplitude_max);
    let mut result = FeedCompensation {
        amplitude: 1.0,
        feed_mps: feed_at(1.0),
        ideal_mps,
        limited: false,
        stroke_factor: 1.0,
    };
    if ideal_mps.is_nan() || ideal_mps <= 0.0 || model == PlateModel::IDEAL {
        return result;
    }
    let mut previous = (0.0, 0.0);
    for _ in 0..AMPLITUDE_STEPS_MAX {
        let error = result.feed_mps / ideal_mps - 1.0;
        if fabs(error) <= FEED_TOLERANCE {
            break;
        }
        // Feed grows about as the amplitude: the first step assumes it proportional.
        let slope = if previous.0 != 0.0 && result.amplitude != previous.0 {
            (result.feed_mps - previous.1) / (result.amplitude - previous.0)
        } else {
            result.feed_mps / result.amplitude
        };
        if slope.is_nan() || slope <= 0.0 {
            break;
        }
        let next = (result.amplitude + (ideal_mps - result.feed_mps) / slope).clamp(low, high);
        if next == result.amplitude {
            break;
        }
        previous = (result.amplitude, result.feed_mps);
        result.amplitude = next;
        result.feed_mps = feed_at(next);
    }
    result.limited = fabs(result.feed_mps / ideal_mps - 1.0) > 10.0 * FEED_TOLERANCE
        && (result.amplitude == low || result.amplitude == high);
    let at = scaled(result.amplitude);
    let lag_only = PlateModel {
        lag_s: model.lag_s,
        ..PlateModel::IDEAL
    };
    let lagged_m = LaggedCycle::new(&at[..count], lag_only).latched_stroke_m();
    let stroke_m = LaggedCycle::new(&at[..count], model).latched_stroke_m();
    if lagged_m > 0.0 && stroke_m > 0.0 {
        result.stroke_factor = stroke_m / lagged_m;
    }
    result
}

/// A feed compensation to find: for the plan of `waveform` on the identified drive, a part of
/// `part_mps2 = μg`, within the drive's linear range. The course asks for it once per plan and
/// drive ([`Course::feed_request`](super::Course::feed_request)); solving it takes tens of
/// milliseconds on a microcontroller, so the firmware solves it off the boundary's path.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FeedRequest {
    pub waveform: Waveform,
    pub model: PlateModel,
    pub part_mps2: f64,
    pub amplitude_max: f64,
}

impl FeedRequest {
    /// The request for `waveform` on `drive`: the amplitude may rise as far as its levels,
    /// through the weaker gain and with the offset and friction held beside them, stay within
    /// `linear_mps2` and the drive's full scale ([`ENVELOPE`]), less [`LOOP_HEADROOM`] for the
    /// loop's own trims.
    pub fn new(waveform: &Waveform, drive: &Identified, part_mps2: f64, linear_mps2: f64) -> Self {
        let reach_mps2 = linear_mps2.min(ENVELOPE.full_scale_mps2);
        let room_mps2 = reach_mps2 - fabs(drive.offset_mps2) - fabs(drive.coulomb_mps2);
        let weaker_gain = drive.gain_positive.min(drive.gain_negative);
        let amplitude_max = room_mps2 * weaker_gain / (waveform.accel_mps2 * (1.0 + LOOP_HEADROOM));
        FeedRequest {
            waveform: *waveform,
            model: PlateModel::of(drive),
            part_mps2,
            amplitude_max: if amplitude_max.is_finite() {
                amplitude_max.max(1.0)
            } else {
                1.0
            },
        }
    }

    /// The amplitude that gives the ideal plate's feed, or the feed the drive allows.
    pub fn solve(&self) -> FeedCompensation {
        let segments = CommandSegment::cycle_of(&self.waveform);
        compensate(&segments, self.model, self.part_mps2, self.amplitude_max)
    }
}

/// What of the drive's linear range the compensated levels leave to the loop's trims.
pub const LOOP_HEADROOM: f64 = 0.1;
