//! The guided calibration's verdicts (`feeder-ctl calibrate`): what the closed loop's
//! identification of the drive means for the machine's configuration, judged against the
//! envelope the loop is held to ([`ENVELOPE`]).
//!
//! The identification finds the drive's zero offset `o` (m/s² at a zero command); the driver
//! input's zero code is then `o·c` counts off (`c` the DAC's counts per m/s²), and moving it by
//! `−round(o·c)` takes the offset to within half a count. Gains, lag and offset must lie within
//! the envelope for the loop to hold the plate at all; the identification refuses a drive
//! outside it, so a calibration that finds one reports it as found.
//!
//! The calibration's start runs at a low amplitude ([`CALIBRATION_STROKE_M`]); what the machine
//! can do at full amplitude, its usable stroke, follows from the drive it identified
//! ([`UsableStroke`]).

use crate::closed_loop::{Identified, ENVELOPE};
use crate::drive::DacCalibration;
use crate::waveform::{stroke_per_accel_s2, Limits};

/// The stroke the calibration's start runs at, m, or the configured one where that is smaller:
/// low enough that the start-up swing stays well inside any travel the envelope allows.
pub const CALIBRATION_STROKE_M: f64 = 1.0e-3;

/// What bounds the usable stroke.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StrokeBound {
    /// The drive: its largest command on the weaker side, with the offset against it.
    Drive,
    /// The plate's travel, `max_stroke_m`.
    Travel,
}

impl StrokeBound {
    pub const fn name(self) -> &'static str {
        match self {
            StrokeBound::Drive => "drive",
            StrokeBound::Travel => "travel",
        }
    }
}

/// The largest stroke the machine gives at one frequency and duty, with the drive identified.
///
/// A plate level `±a` takes the command `(a ∓ o)/g±` from a drive of gains `g±` and offset `o`,
/// and no command may exceed the machine's peak acceleration `L` (`max_accel_mps2`), so
/// `a ≤ min(g₊·L + o, g₋·L − o)`; the stroke is then `a·(T(1 − d)/2)²` (Eq. 5), or the travel
/// where that is less.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UsableStroke {
    pub frequency_hz: f64,
    pub duty: f64,
    /// The largest plate level, m/s².
    pub accel_mps2: f64,
    /// The largest peak-to-peak stroke, m.
    pub stroke_m: f64,
    pub bound: StrokeBound,
}

impl UsableStroke {
    /// The usable stroke of `drive` on a machine limited by `limits` at `frequency_hz`, `duty`.
    pub fn at(drive: &Identified, limits: &Limits, frequency_hz: f64, duty: f64) -> Self {
        let command_mps2 = limits.max_accel_mps2;
        let accel_mps2 = (drive.gain_positive * command_mps2 + drive.offset_mps2)
            .min(drive.gain_negative * command_mps2 - drive.offset_mps2)
            .max(0.0);
        let drive_stroke_m = accel_mps2 * stroke_per_accel_s2(1.0 / frequency_hz, duty);
        let (stroke_m, bound) = if drive_stroke_m <= limits.max_stroke_m {
            (drive_stroke_m, StrokeBound::Drive)
        } else {
            (limits.max_stroke_m, StrokeBound::Travel)
        };
        UsableStroke {
            frequency_hz,
            duty,
            accel_mps2,
            stroke_m,
            bound,
        }
    }
}

/// Whether a start's largest distance from the plate's centre, `peak_m`, left the plate clear of
/// its stops: within half the travel `travel_m` (the stops' distance from a centred plate).
pub fn swing_within(peak_m: f64, travel_m: f64) -> bool {
    peak_m < travel_m / 2.0
}

/// What the calibration found of the drive, and what it proposes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DriveVerdict {
    pub drive: Identified,
    /// The zero offset in DAC counts, `o·c`.
    pub offset_counts: f64,
    /// The zero code that takes the offset off, where it is a count or more away.
    pub proposed_zero_code: Option<u16>,
    /// Each check against the envelope: the gains, the lag and the offset within their limits.
    pub gains_within: bool,
    pub lag_within: bool,
    pub offset_within: bool,
}

impl DriveVerdict {
    /// Judges the identified `drive` for a DAC calibrated as `dac`.
    pub fn judge(drive: &Identified, dac: &DacCalibration) -> Self {
        let offset_counts = drive.offset_mps2 * dac.counts_per_mps2;
        let correction = libm::round(offset_counts);
        let proposed = f64::from(dac.zero_code) - correction;
        let (min_code, max_code) = dac.linear_codes();
        let proposed_zero_code = (correction != 0.0
            && proposed >= f64::from(min_code)
            && proposed <= f64::from(max_code))
        .then_some(proposed as u16);
        let within = |gain: f64| (ENVELOPE.gain_min..=ENVELOPE.gain_max).contains(&gain);
        DriveVerdict {
            drive: *drive,
            offset_counts,
            proposed_zero_code,
            gains_within: within(drive.gain_positive) && within(drive.gain_negative),
            lag_within: drive.lag_s <= ENVELOPE.lag_max_s(),
            offset_within: libm::fabs(drive.offset_mps2) <= ENVELOPE.offset_max_mps2(),
        }
    }

    /// Every check passed.
    pub fn accepted(&self) -> bool {
        self.gains_within && self.lag_within && self.offset_within
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn drive(offset_mps2: f64, gain_positive: f64, lag_s: f64) -> Identified {
        Identified {
            gain_positive,
            gain_negative: 0.98,
            offset_mps2,
            lag_s,
            ..Identified::NOMINAL
        }
    }

    #[test]
    fn an_offset_of_a_count_or_more_moves_the_zero_code_the_other_way() {
        // realistic.toml's 1.051 m/s² at 8 counts per m/s² is 8.4 counts: 2048 − 8.
        let verdict = DriveVerdict::judge(&drive(1.051, 1.02, 1.6e-4), &DacCalibration::DEFAULT);
        assert!((verdict.offset_counts - 8.408).abs() < 1e-9);
        assert_eq!(verdict.proposed_zero_code, Some(2040));
        assert!(verdict.accepted());
        let small = DriveVerdict::judge(&drive(-0.05, 1.0, 0.0), &DacCalibration::DEFAULT);
        assert_eq!(small.proposed_zero_code, None, "under half a count");
    }

    #[test]
    fn a_drive_outside_the_envelope_is_named_by_its_check() {
        let slow = DriveVerdict::judge(&drive(0.0, 1.0, 2e-3), &DacCalibration::DEFAULT);
        assert!(!slow.lag_within && slow.gains_within && !slow.accepted());
        let weak = DriveVerdict::judge(&drive(0.0, 0.8, 0.0), &DacCalibration::DEFAULT);
        assert!(!weak.gains_within);
        let far = DriveVerdict::judge(&drive(-6.0, 1.0, 0.0), &DacCalibration::DEFAULT);
        assert!(!far.offset_within);
        assert_eq!(far.proposed_zero_code, Some(2096));
    }

    #[test]
    fn the_usable_stroke_puts_the_weaker_sides_command_at_the_limit() {
        let limits = Limits {
            max_stroke_m: 1.0,
            ..crate::drive::MACHINE_LIMITS
        };
        for (gain_positive, gain_negative, offset_mps2) in
            [(1.02, 0.98, 1.0), (0.95, 1.05, -2.0), (1.0, 1.0, 3.0)]
        {
            let drive = Identified {
                gain_positive,
                gain_negative,
                offset_mps2,
                ..Identified::NOMINAL
            };
            let usable = UsableStroke::at(&drive, &limits, 50.0, 0.586);
            let a = usable.accel_mps2;
            let commands = [
                (a - offset_mps2) / gain_positive,
                (a + offset_mps2) / gain_negative,
            ];
            let largest = commands[0].max(commands[1]);
            assert!(
                (largest - limits.max_accel_mps2).abs() < 1e-9,
                "{commands:?}: one side at the limit"
            );
            assert!(commands.iter().all(|c| *c <= limits.max_accel_mps2 + 1e-9));
            // Eq. 5 at 50 Hz, d = 0.586: (0.02·0.414/2)² = 1.713 96e-5 m per m/s².
            assert!((usable.stroke_m - a * 1.713_96e-5).abs() < 1e-12 * a);
            assert_eq!(usable.bound, StrokeBound::Drive);
        }
    }

    #[test]
    fn the_travel_bounds_the_usable_stroke_where_the_drive_gives_more() {
        let limits = crate::drive::MACHINE_LIMITS;
        let drive = Identified::NOMINAL;
        // 200 m/s² at 50 Hz, d = 0.52: (0.02·0.48/2)²·200 = 4.61 mm, under the 5 mm travel.
        let within = UsableStroke::at(&drive, &limits, 50.0, 0.52);
        assert!((within.stroke_m - 4.608e-3).abs() < 1e-9);
        assert_eq!(within.bound, StrokeBound::Drive);
        let stronger = Limits {
            max_accel_mps2: 400.0,
            ..limits
        };
        let capped = UsableStroke::at(&drive, &stronger, 50.0, 0.52);
        assert_eq!(capped.stroke_m, limits.max_stroke_m);
        assert_eq!(capped.bound, StrokeBound::Travel);
        assert!(swing_within(2.4e-3, 5e-3) && !swing_within(2.5e-3, 5e-3));
    }
}
