//! The guided calibration's verdicts (`feeder-ctl calibrate`): what the closed loop's
//! identification of the drive means for the machine's configuration, judged against the
//! envelope the loop is held to ([`ENVELOPE`]).
//!
//! The identification finds the drive's zero offset `o` (m/s² at a zero command); the driver
//! input's zero code is then `o·c` counts off (`c` the DAC's counts per m/s²), and moving it by
//! `−round(o·c)` takes the offset to within half a count. Gains, lag and offset must lie within
//! the envelope for the loop to hold the plate at all; the identification refuses a drive
//! outside it, so a calibration that finds one reports it as found.

use crate::closed_loop::{Identified, ENVELOPE};
use crate::drive::DacCalibration;

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
}
