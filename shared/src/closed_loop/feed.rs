//! The part's feed rate on the plate the drive makes of a cycle's plan, and the amplitude that
//! gives the ideal plate's feed.
//!
//! The drive's current loop is a first-order lag `τ·ȧ + a = u`: in the periodic motion it
//! settles into, the plate's velocity is `v = v_u − τ·a` with `v_u` the plan's own velocity
//! from rest at the cycle's start ([`CycleShape::behind_lag`](super::CycleShape::behind_lag)).
//! The lag rounds every corner of the velocity profile, and the feed, set by where the part's
//! velocity crosses the plate's, falls: at 150 Hz of bandwidth by 5 % at 50 Hz and d = 0.53, by
//! 45 % at 100 Hz and d = 0.61. Scaling the levels by an amplitude `m` brings it back as far as
//! the drive's linear range allows.
//!
//! The part is the paper's (Section III): a point mass under Coulomb friction `μg`, sliding
//! at `±μg` toward the plate's velocity or stuck to the plate while the plate's acceleration is
//! at most `μg`. Its periodic motion is found by regula falsi on its velocity at the cycle's
//! start (one cycle's map is monotone), each cycle integrated in [`STEPS_PER_CYCLE`] steps with
//! the plate's motion exact at every step and each crossing placed inside its step.

use libm::{exp, fabs};

use super::identify::Identified;
use super::shape::{sign, CommandSegment};
use crate::waveform::Waveform;

/// Steps of the part's integration per cycle: the amplitude found is within 3·10⁻⁴ of 4000 steps'
/// at 150 Hz of bandwidth, 50–100 Hz and d = 0.53–0.61.
pub const STEPS_PER_CYCLE: usize = 250;
/// The periodic motion's search stops at this velocity error.
const VELOCITY_TOLERANCE_MPS: f64 = 1e-7;
const SEARCH_STEPS_MAX: usize = 60;
/// The amplitude's search stops at this relative feed error.
const FEED_TOLERANCE: f64 = 1e-4;
const AMPLITUDE_STEPS_MAX: usize = 12;

/// The plate's motion through one cycle of `segments` behind a lag.
#[derive(Debug, Clone, Copy)]
struct LaggedCycle<'a> {
    segments: &'a [CommandSegment],
    lag_s: f64,
    /// The lag's output at the cycle's start, periodic.
    start_accel_mps2: f64,
}

impl<'a> LaggedCycle<'a> {
    fn new(segments: &'a [CommandSegment], lag_s: f64) -> Self {
        let lag_s = if lag_s > 0.0 { lag_s } else { 0.0 };
        let (mut slope, mut constant) = (1.0, 0.0);
        if lag_s > 0.0 {
            for segment in segments {
                let decay = exp(-segment.duration_s / lag_s);
                slope *= decay;
                constant = segment.accel_mps2 + (constant - segment.accel_mps2) * decay;
            }
        }
        LaggedCycle {
            segments,
            lag_s,
            start_accel_mps2: if lag_s > 0.0 {
                constant / (1.0 - slope)
            } else {
                segments.first().map_or(0.0, |s| s.accel_mps2)
            },
        }
    }

    fn period_s(&self) -> f64 {
        self.segments.iter().map(|s| s.duration_s).sum()
    }

    /// The plate's velocity at the cycle's start: `v_u = 0` there.
    fn start_velocity_mps(&self) -> f64 {
        -self.lag_s * self.start_accel_mps2
    }

    /// Calls `step(h, plate velocity at the step's end, plate acceleration at its end)` for every
    /// step of the cycle.
    fn for_each_step(&self, mut step: impl FnMut(f64, f64, f64)) {
        let period_s = self.period_s();
        let (mut planned_v, mut accel) = (0.0, self.start_accel_mps2);
        for segment in self.segments {
            let u = segment.accel_mps2;
            let count = libm::ceil(segment.duration_s / period_s * STEPS_PER_CYCLE as f64).max(1.0);
            let h = segment.duration_s / count;
            let decay = if self.lag_s > 0.0 {
                exp(-h / self.lag_s)
            } else {
                0.0
            };
            for _ in 0..count as usize {
                planned_v += u * h;
                accel = u + (accel - u) * decay;
                step(h, planned_v - self.lag_s * accel, accel);
            }
        }
    }

    /// The part's velocity at the cycle's end and its displacement through the cycle, from
    /// `part_v` at its start.
    fn part_cycle(&self, part_mps2: f64, mut part_v: f64) -> (f64, f64) {
        let mut moved_m = 0.0;
        let mut plate_v = self.start_velocity_mps();
        let mut stuck = false;
        self.for_each_step(|h, next_plate_v, accel| {
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
                    next_plate_v
                } else {
                    met_v - direction * part_mps2 * rest_s
                };
                moved_m += (met_v + part_v) / 2.0 * rest_s;
            }
            plate_v = next_plate_v;
        });
        (part_v, moved_m)
    }

    /// The plate's lowest and highest velocity through the cycle.
    fn velocity_range(&self) -> (f64, f64) {
        let start_v = self.start_velocity_mps();
        let (mut low, mut high) = (start_v, start_v);
        self.for_each_step(|_, v, _| {
            low = low.min(v);
            high = high.max(v);
        });
        (low, high)
    }

    /// The part's mean velocity in its periodic motion on this plate.
    fn feed_rate_mps(&self, part_mps2: f64) -> f64 {
        let period_s = self.period_s();
        let (mut low, mut high) = self.velocity_range();
        // One cycle's map `F` is monotone and maps the plate's velocity range into itself:
        // `F(v) − v` is at least 0 at `low` and at most 0 at `high`.
        let mut low_gap = self.part_cycle(part_mps2, low).0 - low;
        let mut high_gap = self.part_cycle(part_mps2, high).0 - high;
        let mut moved_m = self.part_cycle(part_mps2, (low + high) / 2.0).1;
        let mut side = 0;
        for _ in 0..SEARCH_STEPS_MAX {
            let v = if low_gap - high_gap > 0.0 {
                low + (high - low) * low_gap / (low_gap - high_gap)
            } else {
                (low + high) / 2.0
            };
            let (end_v, moved) = self.part_cycle(part_mps2, v);
            moved_m = moved;
            let gap = end_v - v;
            if fabs(gap) <= VELOCITY_TOLERANCE_MPS || high - low <= VELOCITY_TOLERANCE_MPS {
                break;
            }
            // Illinois: halve the stale end's gap so that both ends move.
            if gap > 0.0 {
                (low, low_gap) = (v, gap);
                if side == 1 {
                    high_gap /= 2.0;
                }
                side = 1;
            } else {
                (high, high_gap) = (v, gap);
                if side == -1 {
                    low_gap /= 2.0;
                }
                side = -1;
            }
        }
        moved_m / period_s
    }
}

/// The part's feed rate (its mean velocity) on a plate that plays `segments` periodically
/// through a current loop of lag `lag_s`, the part sliding at `part_mps2 = μg`.
pub fn feed_rate_mps(segments: &[CommandSegment], lag_s: f64, part_mps2: f64) -> f64 {
    LaggedCycle::new(segments, lag_s).feed_rate_mps(part_mps2)
}

/// The amplitude that gives a plate behind the drive's lag the ideal plate's feed.
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
}

/// The amplitude within `[1/amplitude_max, amplitude_max]` that gives the plate of `segments`
/// behind `lag_s` the feed the ideal plate (no lag) has, found by secant steps on the feed.
pub fn compensate(
    segments: &[CommandSegment],
    lag_s: f64,
    part_mps2: f64,
    amplitude_max: f64,
) -> FeedCompensation {
    let ideal_mps = feed_rate_mps(segments, 0.0, part_mps2);
    let feed_at = |amplitude: f64| {
        let mut scaled = [CommandSegment {
            duration_s: 0.0,
            accel_mps2: 0.0,
        }; 4];
        let count = segments.len().min(4);
        for (scaled, segment) in scaled.iter_mut().zip(&segments[..count]) {
            *scaled = CommandSegment {
                accel_mps2: segment.accel_mps2 * amplitude,
                ..*segment
            };
        }
        feed_rate_mps(&scaled[..count], lag_s, part_mps2)
    };
    let (low, high) = (1.0 / amplitude_max, amplitude_max);
    let mut result = FeedCompensation {
        amplitude: 1.0,
        feed_mps: feed_at(1.0),
        ideal_mps,
        limited: false,
    };
    if ideal_mps.is_nan() || ideal_mps <= 0.0 || lag_s <= 0.0 {
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
    pub lag_s: f64,
    pub part_mps2: f64,
    pub amplitude_max: f64,
}

impl FeedRequest {
    /// The request for `waveform` on `drive`: the amplitude may rise as far as its levels,
    /// through the weaker gain and with the offset and friction held beside them, stay within
    /// `linear_mps2`, less [`LOOP_HEADROOM`] for the loop's own trims.
    pub fn new(waveform: &Waveform, drive: &Identified, part_mps2: f64, linear_mps2: f64) -> Self {
        let room_mps2 = linear_mps2 - fabs(drive.offset_mps2) - fabs(drive.coulomb_mps2);
        let weaker_gain = drive.gain_positive.min(drive.gain_negative);
        let amplitude_max = room_mps2 * weaker_gain / (waveform.accel_mps2 * (1.0 + LOOP_HEADROOM));
        FeedRequest {
            waveform: *waveform,
            lag_s: drive.lag_s,
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
        let segments = self.waveform.segments().map(|segment| CommandSegment {
            duration_s: segment.duration_s,
            accel_mps2: f64::from(segment.level.sign()) * self.waveform.accel_mps2,
        });
        compensate(&segments, self.lag_s, self.part_mps2, self.amplitude_max)
    }
}

/// What of the drive's linear range the compensated levels leave to the loop's trims.
pub const LOOP_HEADROOM: f64 = 0.1;
