//! The plate's three-level acceleration waveform (paper, Section II, Eq. 1–5).
//!
//! One period `T` is split into a forward semicycle `F = dT` and a backward semicycle
//! `B = (1 − d)T`. The acceleration is `+a` on `[0, t1)`, `0` on `[t1, t2)`, `−a` on `[t2, t3)` and
//! `+a` on `[t3, T)`, with `t3 = F + B/2` (errata 1: the backward swing turns at the middle of
//! `B`). The plate is at rest at `t = 0`, `F` and `T`, and returns to its start every cycle.

use crate::error::{finite, positive, Error, Quantity};
use crate::segment::SegmentKind;
use libm::sqrt;

/// How the amplitude of the waveform is specified: exactly one of stroke or peak acceleration.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Drive {
    /// Peak-to-peak plate travel `x_max` in metres; `a_max` follows from Eq. 5.
    Stroke { stroke_m: f64 },
    /// Peak plate acceleration `a_max` in m/s²; `x_max` follows from Eq. 5.
    Accel { accel_mps2: f64 },
}

/// The independent design parameters of a waveform.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct WaveformSpec {
    pub period_s: f64,
    pub duty: f64,
    pub drive: Drive,
}

impl WaveformSpec {
    /// A spec given by frequency instead of period. A non-positive or non-finite frequency gives
    /// a period that [`Waveform::new`] refuses in terms of the period, so callers that want the
    /// frequency named in the refusal check it first.
    pub const fn from_frequency(frequency_hz: f64, duty: f64, drive: Drive) -> Self {
        Self {
            period_s: 1.0 / frequency_hz,
            duty,
            drive,
        }
    }
}

/// Limits of the machine the waveform runs on. Use [`Limits::NONE`] for pure analysis.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Limits {
    pub min_frequency_hz: f64,
    pub max_frequency_hz: f64,
    /// Motor peak acceleration limit.
    pub max_accel_mps2: f64,
    /// Plate travel limit (peak-to-peak).
    pub max_stroke_m: f64,
}

impl Limits {
    /// No limits beyond the physics (`T > 0`, `0.5 < d < 1`).
    pub const NONE: Limits = Limits {
        min_frequency_hz: 0.0,
        max_frequency_hz: f64::INFINITY,
        max_accel_mps2: f64::INFINITY,
        max_stroke_m: f64::INFINITY,
    };

    fn validate(&self) -> Result<(), Error> {
        let checks = [
            (Quantity::MinFrequencyLimitHz, self.min_frequency_hz),
            (Quantity::MaxFrequencyLimitHz, self.max_frequency_hz),
            (Quantity::AccelLimitMps2, self.max_accel_mps2),
            (Quantity::StrokeLimitM, self.max_stroke_m),
        ];
        for (quantity, value) in checks {
            if value.is_nan() || value < 0.0 {
                return Err(Error::InvalidLimit { quantity, value });
            }
        }
        Ok(())
    }
}

/// `x_max / a_max = (T(1 − d)/2)²` (Eq. 5): the peak-to-peak stroke per unit of peak
/// acceleration at period `period_s` and duty `duty`, in m per m/s².
pub fn stroke_per_accel_s2(period_s: f64, duty: f64) -> f64 {
    let half_backward_s = period_s * (1.0 - duty) / 2.0;
    half_backward_s * half_backward_s
}

/// A validated waveform with every derived quantity of Eq. 1–5 (SI units).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Waveform {
    pub period_s: f64,
    pub duty: f64,
    /// Peak acceleration `a_max`.
    pub accel_mps2: f64,
    /// Peak-to-peak travel `x_max` (Eq. 5).
    pub stroke_m: f64,
    /// Forward semicycle `F = dT`.
    pub forward_s: f64,
    /// Backward semicycle `B = (1 − d)T`.
    pub backward_s: f64,
    /// Plateau `P = T·sqrt(2d − 1)` (Eq. 2).
    pub plateau_s: f64,
    /// End of the first `+a` segment, `t1 = (F − P)/2` (Eq. 4).
    pub t1_s: f64,
    /// End of the plateau, `t2 = (F + P)/2` (Eq. 4).
    pub t2_s: f64,
    /// Turn of the backward swing, `t3 = F + B/2`.
    pub t3_s: f64,
    /// Peak forward velocity `v_max = a·t1` (Eq. 4).
    pub v_max_mps: f64,
    /// Peak backward velocity `v_min = −a·B/2`.
    pub v_min_mps: f64,
}

impl Waveform {
    /// Derives and validates a waveform. Every refusal is a typed [`Error`]; nothing is clamped.
    pub fn new(spec: WaveformSpec, limits: &Limits) -> Result<Self, Error> {
        limits.validate()?;
        let period_s = positive(Quantity::PeriodS, spec.period_s)?;
        let duty = finite(Quantity::Duty, spec.duty)?;
        if duty <= 0.5 {
            return Err(Error::DutyTooLow { duty });
        }
        if duty >= 1.0 {
            return Err(Error::DutyTooHigh { duty });
        }
        let frequency_hz = 1.0 / period_s;
        if !(limits.min_frequency_hz..=limits.max_frequency_hz).contains(&frequency_hz) {
            return Err(Error::FrequencyOutOfBand {
                frequency_hz,
                min_hz: limits.min_frequency_hz,
                max_hz: limits.max_frequency_hz,
            });
        }
        let stroke_per_accel_s2 = stroke_per_accel_s2(period_s, duty);
        let (accel_mps2, stroke_m) = match spec.drive {
            Drive::Stroke { stroke_m } => {
                let stroke_m = positive(Quantity::StrokeM, stroke_m)?;
                (stroke_m / stroke_per_accel_s2, stroke_m)
            }
            Drive::Accel { accel_mps2 } => {
                let accel_mps2 = positive(Quantity::AccelMps2, accel_mps2)?;
                (accel_mps2, accel_mps2 * stroke_per_accel_s2)
            }
        };
        if !accel_mps2.is_finite() {
            return Err(Error::NotFinite {
                quantity: Quantity::AccelMps2,
            });
        }
        if !stroke_m.is_finite() || stroke_m <= 0.0 {
            return Err(Error::NotPositive {
                quantity: Quantity::StrokeM,
                value: stroke_m,
            });
        }
        let accel_over = accel_mps2 > limits.max_accel_mps2;
        let stroke_over = stroke_m > limits.max_stroke_m;
        // The motor's acceleration limit as a stroke, and the plate's travel as an acceleration,
        // at this period and duty (Eq. 5).
        let accel_limit_as_stroke_m = limits.max_accel_mps2 * stroke_per_accel_s2;
        let travel_as_accel_mps2 = limits.max_stroke_m / stroke_per_accel_s2;
        // A refusal names the quantity that was set and the tighter of the two limits on it.
        match spec.drive {
            Drive::Stroke { .. }
                if stroke_over && limits.max_stroke_m <= accel_limit_as_stroke_m =>
            {
                Err(Error::StrokeAboveLimit {
                    stroke_m,
                    limit_m: limits.max_stroke_m,
                })
            }
            Drive::Stroke { .. } if accel_over || stroke_over => {
                Err(Error::StrokeAboveAccelLimit {
                    stroke_m,
                    limit_m: accel_limit_as_stroke_m,
                    accel_limit_mps2: limits.max_accel_mps2,
                    frequency_hz,
                    duty,
                })
            }
            Drive::Accel { .. } if accel_over && limits.max_accel_mps2 <= travel_as_accel_mps2 => {
                Err(Error::AccelAboveLimit {
                    accel_mps2,
                    limit_mps2: limits.max_accel_mps2,
                })
            }
            Drive::Accel { .. } if accel_over || stroke_over => Err(Error::AccelAboveTravelLimit {
                accel_mps2,
                limit_mps2: travel_as_accel_mps2,
                stroke_limit_m: limits.max_stroke_m,
                frequency_hz,
                duty,
            }),
            _ => Ok(Self::derive(period_s, duty, accel_mps2, stroke_m)),
        }
    }

    fn derive(period_s: f64, duty: f64, accel_mps2: f64, stroke_m: f64) -> Self {
        let forward_s = duty * period_s;
        let backward_s = period_s - forward_s;
        let plateau_s = period_s * sqrt(2.0 * duty - 1.0);
        // t1 = (F − P)/2 = B²/(2(F + P)) by Eq. 1, without the cancellation of F − P as d → 1.
        let t1_s = backward_s * backward_s / (2.0 * (forward_s + plateau_s));
        Waveform {
            period_s,
            duty,
            accel_mps2,
            stroke_m,
            forward_s,
            backward_s,
            plateau_s,
            t1_s,
            t2_s: forward_s - t1_s,
            t3_s: forward_s + backward_s / 2.0,
            v_max_mps: accel_mps2 * t1_s,
            v_min_mps: -accel_mps2 * backward_s / 2.0,
        }
    }

    pub fn frequency_hz(&self) -> f64 {
        1.0 / self.period_s
    }

    /// `a_max / x_max = 4 / (T(1 − d))²` (Eq. 5).
    pub fn accel_per_stroke_per_s2(&self) -> f64 {
        self.accel_mps2 / self.stroke_m
    }

    /// The four segments of one cycle with their exact real-valued durations (Fig. 2a). The two
    /// `+a` segments last as long together as the `−a` segment, so the plate ends at rest.
    pub fn segments(&self) -> [ExactSegment; 4] {
        [
            ExactSegment {
                kind: SegmentKind::Accelerate,
                level: Level::Positive,
                duration_s: self.t1_s,
            },
            ExactSegment {
                kind: SegmentKind::Plateau,
                level: Level::Zero,
                duration_s: self.plateau_s,
            },
            ExactSegment {
                kind: SegmentKind::Reverse,
                level: Level::Negative,
                duration_s: self.t3_s - self.t2_s,
            },
            ExactSegment {
                kind: SegmentKind::Return,
                level: Level::Positive,
                duration_s: self.period_s - self.t3_s,
            },
        ]
    }
}

/// The three command levels of the motor: `+a_max`, `0`, `−a_max`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Level {
    Positive,
    Zero,
    Negative,
}

impl Level {
    /// `+1`, `0` or `−1`.
    pub const fn sign(self) -> i8 {
        match self {
            Level::Positive => 1,
            Level::Zero => 0,
            Level::Negative => -1,
        }
    }
}

/// One segment of the waveform with its exact duration.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ExactSegment {
    pub kind: SegmentKind,
    pub level: Level,
    pub duration_s: f64,
}
