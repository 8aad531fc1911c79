//! One error type for every fallible operation in this crate.
//!
//! Each variant names the offending quantity, carries the value that was refused and, through
//! [`core::fmt::Display`], explains why in words a machine operator can act on.

use core::fmt;

use crate::number::Significant;
use crate::segment::SegmentKind;

/// The physical or configuration quantity an [`Error`] refers to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Quantity {
    PeriodS,
    FrequencyHz,
    Duty,
    StrokeM,
    AccelMps2,
    ClockHz,
    FrictionCoefficient,
    GravityMps2,
    MassKg,
    ForceN,
    FeedRateMps,
    MinFrequencyLimitHz,
    MaxFrequencyLimitHz,
    AccelLimitMps2,
    StrokeLimitM,
}

impl Quantity {
    /// Name with unit, as used in messages.
    pub const fn name(self) -> &'static str {
        match self {
            Quantity::PeriodS => "period (s)",
            Quantity::FrequencyHz => "frequency (Hz)",
            Quantity::Duty => "duty cycle",
            Quantity::StrokeM => "stroke x_max (m)",
            Quantity::AccelMps2 => "peak acceleration a_max (m/s²)",
            Quantity::ClockHz => "timer clock (Hz)",
            Quantity::FrictionCoefficient => "friction coefficient μ",
            Quantity::GravityMps2 => "gravity (m/s²)",
            Quantity::MassKg => "part mass (kg)",
            Quantity::ForceN => "external force (N)",
            Quantity::FeedRateMps => "feed rate (m/s)",
            Quantity::MinFrequencyLimitHz => "minimum frequency limit (Hz)",
            Quantity::MaxFrequencyLimitHz => "maximum frequency limit (Hz)",
            Quantity::AccelLimitMps2 => "motor acceleration limit (m/s²)",
            Quantity::StrokeLimitM => "stroke travel limit (m)",
        }
    }
}

/// Everything that can be refused.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Error {
    /// The value is NaN or infinite.
    NotFinite { quantity: Quantity },
    /// The value must be strictly positive.
    NotPositive { quantity: Quantity, value: f64 },
    /// `d ≤ 0.5`: the velocity profile is symmetric or backward-biased, so the part does not feed
    /// forward (Eq. 9 gives `v_eq ≤ 0`, Eq. 2 has no real plateau below 0.5).
    DutyTooLow { duty: f64 },
    /// `d ≥ 1`: no time is left for the backward swing `B = T(1 − d)`.
    DutyTooHigh { duty: f64 },
    /// The frequency lies outside the band the caller allows.
    FrequencyOutOfBand {
        frequency_hz: f64,
        min_hz: f64,
        max_hz: f64,
    },
    /// The derived or requested peak acceleration exceeds the motor's limit.
    AccelAboveLimit { accel_mps2: f64, limit_mps2: f64 },
    /// The derived or requested stroke exceeds the plate's travel.
    StrokeAboveLimit { stroke_m: f64, limit_m: f64 },
    /// A held stroke needs more than the motor's peak acceleration at this frequency and duty:
    /// the motor allows at most `limit_m = a_limit·(T(1 − d)/2)²` there (Eq. 5).
    StrokeAboveAccelLimit {
        stroke_m: f64,
        limit_m: f64,
        accel_limit_mps2: f64,
        frequency_hz: f64,
        duty: f64,
    },
    /// A held peak acceleration moves the plate further than its travel at this frequency and
    /// duty: the travel allows at most `limit_mps2 = x_limit/(T(1 − d)/2)²` there (Eq. 5).
    AccelAboveTravelLimit {
        accel_mps2: f64,
        limit_mps2: f64,
        stroke_limit_m: f64,
        frequency_hz: f64,
        duty: f64,
    },
    /// A caller-supplied limit is NaN or negative, so nothing could be checked against it.
    InvalidLimit { quantity: Quantity, value: f64 },
    /// At this clock a segment of the waveform is shorter than half a tick and would vanish.
    SegmentTooShort {
        segment: SegmentKind,
        exact_ticks: f64,
    },
    /// A segment is shorter than the output stage's floor ([`crate::TickClock`]): its edge could
    /// come before software has preloaded the next segment.
    SegmentBelowFloor {
        segment: SegmentKind,
        ticks: u32,
        min_ticks: u32,
        clock_hz: u32,
    },
    /// The closed loop runs this waveform, and its peak acceleration leaves the loop no room in
    /// the output's linear range for the drives it is designed for
    /// ([`crate::closed_loop::Envelope::loop_accel_max_mps2`]).
    AccelAboveLoopRoom {
        accel_mps2: f64,
        limit_mps2: f64,
        linear_mps2: f64,
    },
    /// The period or a segment needs more ticks than the timer can count.
    TicksOverflow {
        segment: SegmentKind,
        exact_ticks: f64,
        max_ticks: u32,
    },
    /// A new plan was requested with a timer clock other than the running one.
    ClockMismatch { running_hz: u32, requested_hz: u32 },
    /// `a_max ≤ μg`: the part sticks to the plate and never feeds.
    NoSlip {
        accel_mps2: f64,
        friction_accel_mps2: f64,
    },
    /// The external force overcomes friction or makes the part stick, so the linear viscous law
    /// (Eq. 10) does not apply.
    OutsideViscousRange { force_n: f64 },
    /// No duty within the limits reaches the target feed rate while the part keeps sliding.
    FeedRateAboveReach { target_mps: f64, max_mps: f64 },
    /// Every admissible duty within the limits feeds faster than the target.
    FeedRateBelowReach { target_mps: f64, min_mps: f64 },
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Error::NotFinite { quantity } => write!(f, "{} must be a finite number", quantity.name()),
            Error::NotPositive { quantity, value } => {
                write!(f, "{} must be greater than zero, got {}", quantity.name(), Significant(value))
            }
            Error::DutyTooLow { duty } => write!(
                f,
                "duty cycle {} must be above 0.5: at or below 0.5 the plate's velocity profile is \
                 not forward-biased and the part does not feed",
                Significant(duty)
            ),
            Error::DutyTooHigh { duty } => write!(
                f,
                "duty cycle {} must be below 1: at 1 there is no time left for the backward swing",
                Significant(duty)
            ),
            Error::FrequencyOutOfBand { frequency_hz, min_hz, max_hz } => write!(
                f,
                "frequency {} Hz is outside the allowed band {}..={} Hz",
                Significant(frequency_hz), Significant(min_hz), Significant(max_hz)
            ),
            Error::AccelAboveLimit { accel_mps2, limit_mps2 } => write!(
                f,
                "peak acceleration {} m/s² exceeds the motor limit of {} m/s²",
                Significant(accel_mps2), Significant(limit_mps2)
            ),
            Error::StrokeAboveLimit { stroke_m, limit_m } => write!(
                f,
                "stroke {} m exceeds the plate travel limit of {} m",
                Significant(stroke_m), Significant(limit_m)
            ),
            Error::StrokeAboveAccelLimit { stroke_m, limit_m, accel_limit_mps2, frequency_hz, duty } => {
                write!(
                    f,
                    "stroke {} m exceeds the {} m that the motor limit of {} m/s² allows at {} Hz \
                     and duty cycle {}",
                    Significant(stroke_m), Significant(limit_m), Significant(accel_limit_mps2),
                    Significant(frequency_hz), Significant(duty)
                )
            }
            Error::AccelAboveTravelLimit { accel_mps2, limit_mps2, stroke_limit_m, frequency_hz, duty } => {
                write!(
                    f,
                    "peak acceleration {} m/s² exceeds the {} m/s² that the plate travel limit of \
                     {} m allows at {} Hz and duty cycle {}",
                    Significant(accel_mps2), Significant(limit_mps2), Significant(stroke_limit_m),
                    Significant(frequency_hz), Significant(duty)
                )
            }
            Error::InvalidLimit { quantity, value } => {
                write!(f, "{} must be a non-negative number, got {}", quantity.name(), Significant(value))
            }
            Error::SegmentTooShort { segment, exact_ticks } => write!(
                f,
                "the {} segment lasts {} timer ticks and would round to zero: use a faster clock \
                 or a duty further from its limits",
                segment.name(),
                Significant(exact_ticks)
            ),
            Error::SegmentBelowFloor { segment, ticks, min_ticks, clock_hz } => write!(
                f,
                "the {} segment lasts {} ticks of the {} Hz clock ({} us), shorter than the {} \
                 ticks ({} us) the output stage needs to preload the next edge: choose a duty \
                 further from its limits or a lower frequency",
                segment.name(),
                ticks,
                clock_hz,
                Significant(1e6 * f64::from(ticks) / f64::from(clock_hz)),
                min_ticks,
                Significant(1e6 * f64::from(min_ticks) / f64::from(clock_hz))
            ),
            Error::AccelAboveLoopRoom { accel_mps2, limit_mps2, linear_mps2 } => write!(
                f,
                "peak acceleration {} m/s² is more than the closed loop can hold: the output's \
                 linear range reaches {} m/s², and undoing the weakest drive gain, the largest \
                 offset and the slide friction the loop is designed for leaves at most {} m/s²; \
                 choose a shorter stroke or a lower frequency",
                Significant(accel_mps2), Significant(linear_mps2), Significant(limit_mps2)
            ),
            Error::TicksOverflow { segment, exact_ticks, max_ticks } => write!(
                f,
                "the {} segment needs {} timer ticks but the timer counts at most {}: use a slower \
                 clock or a higher frequency",
                segment.name(),
                Significant(exact_ticks),
                max_ticks
            ),
            Error::ClockMismatch { running_hz, requested_hz } => write!(
                f,
                "the new plan is for a {} Hz clock but the scheduler runs on {} Hz",
                requested_hz, running_hz
            ),
            Error::NoSlip { accel_mps2, friction_accel_mps2 } => write!(
                f,
                "peak acceleration {} m/s² does not exceed μg = {} m/s²: the part sticks to the \
                 plate and does not feed",
                Significant(accel_mps2), Significant(friction_accel_mps2)
            ),
            Error::OutsideViscousRange { force_n } => write!(
                f,
                "external force {} N makes the part stick or overcomes friction: the linear viscous \
                 law does not hold there",
                Significant(force_n)
            ),
            Error::FeedRateAboveReach { target_mps, max_mps } => write!(
                f,
                "feed rate {} m/s cannot be reached within the limits while the part slides; the \
                 most is {} m/s",
                Significant(target_mps), Significant(max_mps)
            ),
            Error::FeedRateBelowReach { target_mps, min_mps } => write!(
                f,
                "feed rate {} m/s is below what the limits allow; the least is {} m/s",
                Significant(target_mps), Significant(min_mps)
            ),
        }
    }
}

impl core::error::Error for Error {}

/// Checks that `value` is finite and strictly positive.
pub(crate) fn positive(quantity: Quantity, value: f64) -> Result<f64, Error> {
    if !value.is_finite() {
        Err(Error::NotFinite { quantity })
    } else if value <= 0.0 {
        Err(Error::NotPositive { quantity, value })
    } else {
        Ok(value)
    }
}

/// Checks that `value` is finite (any sign).
pub(crate) fn finite(quantity: Quantity, value: f64) -> Result<f64, Error> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(Error::NotFinite { quantity })
    }
}
