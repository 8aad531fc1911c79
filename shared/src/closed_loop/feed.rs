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
//! ([`SegmentMotion::slide_mps2`](super::SegmentMotion::slide_mps2)); inside a segment what they leave bends the profile too.
//! Scaling the levels by an amplitude `m` brings the feed back as far as the drive's linear
//! range allows.
//!
//! The plate is the identified one (`plate`), the part the paper's (`part`).

mod part;
mod plate;

use libm::fabs;

pub use plate::{PlateModel, STEPS_PER_CYCLE};

use super::envelope::ENVELOPE;
use super::identify::Identified;
use super::shape::CommandSegment;
use crate::waveform::Waveform;
use plate::PlateCycle;

/// The amplitude's search stops at this relative feed error.
const FEED_TOLERANCE: f64 = 3e-4;
const AMPLITUDE_STEPS_MAX: usize = 12;

/// The part's feed rate (its mean velocity) on `model`'s plate playing `segments`
/// periodically, the part sliding at `part_mps2 = μg`.
pub fn feed_rate_mps(segments: &[CommandSegment], model: PlateModel, part_mps2: f64) -> f64 {
    PlateCycle::new(segments, model).feed_rate_mps(part_mps2)
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
    let lagged_m = PlateCycle::new(&at[..count], lag_only).latched_stroke_m();
    let stroke_m = PlateCycle::new(&at[..count], model).latched_stroke_m();
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
