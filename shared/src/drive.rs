//! From a segment's level and amplitude to the value the motor driver's input receives.
//!
//! Two output stages are supported: an analog command from a DAC (a calibrated zero code plus or
//! minus an amplitude code) and, for H-bridge drivers, a PWM magnitude with a direction line. The
//! full-scale amplitude is converted once per plan (floating point, checked against the stage's
//! range: for the DAC the linear range of its buffered output, so that no level clips); every
//! segment is then mapped in integers, with the soft-start fraction `step / steps` applied by
//! rounding half up. `+a` and `−a` use the same magnitude, so the two are exactly
//! symmetric about zero and the command carries no DC acceleration bias.

use crate::number::Significant;
use crate::scheduler::Amplitude;
use crate::waveform::{Level, Limits};
use core::fmt;
use libm::round;

/// What the machine can do: its linear motor's peak acceleration with the plate mounted, the
/// plate's peak-to-peak travel before the end stops and the frequencies it is built for. The
/// firmware validates every waveform against them; the host simulator holds its runs to them
/// unless told otherwise.
pub const MACHINE_LIMITS: Limits = Limits {
    min_frequency_hz: 50.0,
    max_frequency_hz: 100.0,
    max_accel_mps2: 200.0,
    max_stroke_m: 5.0e-3,
};

// No level the machine's limits allow leaves the default DAC's linear range.
const _: () = assert!(MACHINE_LIMITS.max_accel_mps2 <= DacCalibration::DEFAULT.linear_limit_mps2());

/// Why an output stage refused a calibration or a peak acceleration.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DriveError {
    /// The scale factor (counts per m/s² or m/s² at full duty) is NaN, infinite or not positive.
    InvalidScale { value: f64 },
    /// The peak acceleration is NaN, infinite or negative.
    InvalidAccel { accel_mps2: f64 },
    /// The DAC zero code lies outside the linear range of the converter's output (`min_code` to
    /// `max_code`, both included).
    ZeroOutOfRange {
        zero_code: u16,
        min_code: u16,
        max_code: u16,
    },
    /// The DAC codes of the peak acceleration leave the linear range of the converter's output
    /// (`min_code` to `max_code`): the output would clip. This calibration reaches at most
    /// `linear_limit_mps2`.
    BeyondLinearRange {
        accel_mps2: f64,
        linear_limit_mps2: f64,
        min_code: u16,
        max_code: u16,
    },
    /// The PWM duty in counts exceeds the period.
    AmplitudeOutOfRange {
        accel_mps2: f64,
        amplitude_counts: f64,
        headroom_counts: u16,
    },
    /// The PWM period has no counts, so no duty can be expressed.
    EmptyPwmPeriod,
}

impl fmt::Display for DriveError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            DriveError::InvalidScale { value } => {
                write!(
                    f,
                    "output scale {} must be a finite number greater than zero",
                    Significant(value)
                )
            }
            DriveError::InvalidAccel { accel_mps2 } => {
                write!(
                    f,
                    "peak acceleration {} m/s² must be finite and non-negative",
                    Significant(accel_mps2)
                )
            }
            DriveError::ZeroOutOfRange {
                zero_code,
                min_code,
                max_code,
            } => {
                write!(
                    f,
                    "DAC zero code {} lies outside the output's linear range, codes {} to {}",
                    zero_code, min_code, max_code
                )
            }
            DriveError::BeyondLinearRange {
                accel_mps2,
                linear_limit_mps2,
                min_code,
                max_code,
            } => {
                write!(
                    f,
                    "peak acceleration {} m/s² needs DAC codes outside the output's linear range, \
                     codes {} to {}: this calibration reaches at most {} m/s²",
                    Significant(accel_mps2),
                    min_code,
                    max_code,
                    Significant(linear_limit_mps2)
                )
            }
            DriveError::AmplitudeOutOfRange {
                accel_mps2,
                amplitude_counts,
                headroom_counts,
            } => {
                write!(
                    f,
                    "peak acceleration {} m/s² needs a duty of {} counts but the PWM period has \
                     {} counts",
                    Significant(accel_mps2),
                    Significant(amplitude_counts),
                    headroom_counts
                )
            }
            DriveError::EmptyPwmPeriod => write!(f, "the PWM period must be at least one count"),
        }
    }
}

impl core::error::Error for DriveError {}

/// `counts · step / steps`, rounded half up, in integers. `step` above `steps` counts as full
/// amplitude; `steps = 0` gives zero.
pub const fn scale_counts(counts: u16, amplitude: Amplitude) -> u16 {
    if amplitude.steps == 0 {
        return 0;
    }
    let steps = amplitude.steps as u32;
    let step = if amplitude.step > amplitude.steps {
        steps
    } else {
        amplitude.step as u32
    };
    ((counts as u32 * step + steps / 2) / steps) as u16
}

/// `accel_mps2 · per_mps2` rounded to whole counts, or why the scale or the acceleration is
/// invalid.
fn rounded_counts(accel_mps2: f64, per_mps2: f64) -> Result<f64, DriveError> {
    if !per_mps2.is_finite() || per_mps2 <= 0.0 {
        return Err(DriveError::InvalidScale { value: per_mps2 });
    }
    if !accel_mps2.is_finite() || accel_mps2 < 0.0 {
        return Err(DriveError::InvalidAccel { accel_mps2 });
    }
    Ok(round(accel_mps2 * per_mps2))
}

/// Calibration of an analog driver input fed by a DAC.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DacCalibration {
    /// Code at which the driver commands zero acceleration, in counts. Default 2048, mid-scale of
    /// a 12-bit converter; measure the driver's offset and enter it here.
    pub zero_code: u16,
    /// DAC counts per m/s² of commanded plate acceleration. Default 8, so ±200 m/s² (the
    /// machine's limit, [`MACHINE_LIMITS`]) spans ±1600 counts around the zero code, inside the linear range.
    pub counts_per_mps2: f64,
    /// Largest code of the converter, in counts. Default 4095 (12 bits).
    pub max_code: u16,
    /// Codes this close to either end of the converter's range leave its output's linear range.
    /// Default 249: the buffered output of the STM32G474's DAC follows the code only from 0.2 V to
    /// VREF+ − 0.2 V (datasheet DS12288, "DAC characteristics"), and 0.2 V is 248.2 codes at
    /// VREF+ = 3.3 V (RM0440, DAC, "DAC output voltage": VREF+ · code / 4096), rounded up.
    pub linear_margin_counts: u16,
}

impl DacCalibration {
    /// The documented defaults (see the fields): linear codes 249 to 3846, so at most
    /// 1798 counts on either side of the zero code, 224.75 m/s².
    pub const DEFAULT: Self = Self {
        zero_code: 2048,
        counts_per_mps2: 8.0,
        max_code: 4095,
        linear_margin_counts: 249,
    };

    /// The lowest and the highest code of the linear range.
    pub const fn linear_codes(&self) -> (u16, u16) {
        (
            self.linear_margin_counts,
            self.max_code.saturating_sub(self.linear_margin_counts),
        )
    }

    /// Counts from the zero code to the nearer end of the linear range; `None` if the zero code
    /// lies outside it.
    const fn linear_headroom_counts(&self) -> Option<u16> {
        let (min_code, max_code) = self.linear_codes();
        if self.zero_code < min_code || self.zero_code > max_code {
            return None;
        }
        let below = self.zero_code - min_code;
        let above = max_code - self.zero_code;
        Some(if below < above { below } else { above })
    }

    /// The largest peak acceleration whose codes stay in the linear range, in m/s² (zero if the
    /// zero code lies outside it).
    pub const fn linear_limit_mps2(&self) -> f64 {
        match self.linear_headroom_counts() {
            Some(headroom_counts) => headroom_counts as f64 / self.counts_per_mps2,
            None => 0.0,
        }
    }

    /// The plate acceleration the driver commands at DAC code `code`: the calibration read
    /// backwards, for a plant that receives the codes.
    pub fn accel_mps2(&self, code: i32) -> f64 {
        f64::from(code - i32::from(self.zero_code)) / self.counts_per_mps2
    }

    /// The code commanding `accel_mps2` of either sign, or why it is not in the output's linear
    /// range: one level of a cycle the closed loop has trimmed.
    pub fn code(&self, accel_mps2: f64) -> Result<u16, DriveError> {
        let magnitude = self.levels(libm::fabs(accel_mps2))?.amplitude_counts;
        Ok(if accel_mps2 < 0.0 {
            self.zero_code - magnitude
        } else {
            self.zero_code + magnitude
        })
    }

    /// The codes of a plan with peak acceleration `peak_accel_mps2`, or why they do not fit in
    /// the output's linear range.
    pub fn levels(&self, peak_accel_mps2: f64) -> Result<DacLevels, DriveError> {
        let (min_code, max_code) = self.linear_codes();
        let Some(headroom_counts) = self.linear_headroom_counts() else {
            return Err(DriveError::ZeroOutOfRange {
                zero_code: self.zero_code,
                min_code,
                max_code,
            });
        };
        let counts = rounded_counts(peak_accel_mps2, self.counts_per_mps2)?;
        if counts > f64::from(headroom_counts) {
            return Err(DriveError::BeyondLinearRange {
                accel_mps2: peak_accel_mps2,
                linear_limit_mps2: self.linear_limit_mps2(),
                min_code,
                max_code,
            });
        }
        Ok(DacLevels {
            zero_code: self.zero_code,
            amplitude_counts: counts as u16,
        })
    }
}

impl Default for DacCalibration {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// DAC codes of one plan: zero code and full amplitude in counts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DacLevels {
    zero_code: u16,
    amplitude_counts: u16,
}

impl DacLevels {
    /// The code for `level` at `amplitude`: `zero ± amplitude_counts · step / steps`.
    pub const fn code(&self, level: Level, amplitude: Amplitude) -> u16 {
        let offset = scale_counts(self.amplitude_counts, amplitude);
        match level {
            Level::Positive => self.zero_code + offset,
            Level::Zero => self.zero_code,
            Level::Negative => self.zero_code - offset,
        }
    }

    /// The code that commands zero acceleration.
    pub const fn zero_code(&self) -> u16 {
        self.zero_code
    }

    /// Offset of the `±a` codes from the zero code at full amplitude, in counts.
    pub const fn amplitude_counts(&self) -> u16 {
        self.amplitude_counts
    }
}

/// Calibration of a PWM-plus-direction driver input.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PwmCalibration {
    /// Plate acceleration commanded at 100 % duty, in m/s². Default 250 m/s².
    pub full_duty_accel_mps2: f64,
}

impl PwmCalibration {
    /// The documented defaults (see the fields).
    pub const DEFAULT: Self = Self {
        full_duty_accel_mps2: 250.0,
    };

    /// The duty and direction commanding `accel_mps2` of either sign on a PWM timer whose
    /// period is `period_counts` counts: one level of a cycle the closed loop has trimmed.
    pub fn command(&self, accel_mps2: f64, period_counts: u16) -> Result<PwmCommand, DriveError> {
        let duty_counts = self
            .levels(libm::fabs(accel_mps2), period_counts)?
            .peak_duty_counts;
        Ok(PwmCommand {
            duty_counts,
            direction: if accel_mps2 < 0.0 {
                Direction::Reverse
            } else {
                Direction::Forward
            },
        })
    }

    /// The duties of a plan with peak acceleration `peak_accel_mps2` on a PWM timer whose period
    /// is `period_counts` counts (100 % duty), or why it does not fit.
    pub fn levels(
        &self,
        peak_accel_mps2: f64,
        period_counts: u16,
    ) -> Result<PwmLevels, DriveError> {
        if period_counts == 0 {
            return Err(DriveError::EmptyPwmPeriod);
        }
        let full = self.full_duty_accel_mps2;
        if !full.is_finite() || full <= 0.0 {
            return Err(DriveError::InvalidScale { value: full });
        }
        let per_mps2 = f64::from(period_counts) / full;
        let counts = rounded_counts(peak_accel_mps2, per_mps2)?;
        if counts > f64::from(period_counts) {
            return Err(DriveError::AmplitudeOutOfRange {
                accel_mps2: peak_accel_mps2,
                amplitude_counts: counts,
                headroom_counts: period_counts,
            });
        }
        Ok(PwmLevels {
            peak_duty_counts: counts as u16,
            period_counts,
        })
    }
}

impl Default for PwmCalibration {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// Sign of the commanded acceleration on the direction line.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Direction {
    /// `+a` (and zero, where the duty is 0 and the direction does not matter).
    Forward,
    /// `−a`.
    Reverse,
}

/// Duty (in timer counts) and direction for one segment.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PwmCommand {
    pub duty_counts: u16,
    pub direction: Direction,
}

/// PWM duties of one plan.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PwmLevels {
    peak_duty_counts: u16,
    period_counts: u16,
}

impl PwmLevels {
    /// The duty and direction for `level` at `amplitude`.
    pub const fn command(&self, level: Level, amplitude: Amplitude) -> PwmCommand {
        let duty_counts = scale_counts(self.peak_duty_counts, amplitude);
        match level {
            Level::Positive => PwmCommand {
                duty_counts,
                direction: Direction::Forward,
            },
            Level::Zero => PwmCommand {
                duty_counts: 0,
                direction: Direction::Forward,
            },
            Level::Negative => PwmCommand {
                duty_counts,
                direction: Direction::Reverse,
            },
        }
    }

    /// Duty at full amplitude, in counts.
    pub const fn peak_duty_counts(&self) -> u16 {
        self.peak_duty_counts
    }

    /// Counts of one PWM period (100 % duty).
    pub const fn period_counts(&self) -> u16 {
        self.period_counts
    }
}
