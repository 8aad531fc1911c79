//! When an identification is refused: the ranges it must fall in ([`IdentifyLimits`]) and why
//! it was refused ([`IdentifyError`]).

use libm::sqrt;

use crate::closed_loop::envelope::{Cause, ENVELOPE};
use crate::number::Significant;

/// The ranges an identification must fall in for the feeder to run.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct IdentifyLimits {
    /// Each gain within `[gain_min, gain_max]`.
    pub gain_min: f64,
    pub gain_max: f64,
    /// `|e|` at most this.
    pub offset_max_mps2: f64,
    /// The plate must move at least this far from its first position.
    pub min_excursion_m: f64,
    /// A centring spring's `k/M` at most this.
    pub spring_max_per_s2: f64,
    /// The current loop's lag at most this.
    pub lag_max_s: f64,
}

impl IdentifyLimits {
    /// The envelope's gains, offset and current loop ([`Envelope::identified_gains`](crate::closed_loop::Envelope::identified_gains),
    /// [`Envelope::offset_max_mps2`](crate::closed_loop::Envelope::offset_max_mps2),
    /// [`Envelope::lag_max_s`](crate::closed_loop::Envelope::lag_max_s)), a motion of at least 20
    /// `resolution_m`, and the envelope's stiffest spring on its lightest plate
    /// ([`Envelope::spring_max_per_s2`](crate::closed_loop::Envelope::spring_max_per_s2)).
    pub fn for_probe(resolution_m: f64) -> Self {
        let (gain_min, gain_max) = ENVELOPE.identified_gains();
        IdentifyLimits {
            gain_min,
            gain_max,
            offset_max_mps2: ENVELOPE.offset_max_mps2(),
            min_excursion_m: 20.0 * resolution_m,
            spring_max_per_s2: ENVELOPE.spring_max_per_s2(),
            lag_max_s: ENVELOPE.lag_max_s(),
        }
    }
}

/// Why an identification was refused.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum IdentifyError {
    /// Fewer latches than the fit has unknowns, or a latch outside the probe or out of order.
    Latches,
    /// The command has no positive or no negative part: its gain cannot be told.
    Probe,
    /// The plate did not move: motor disconnected, driver disabled or a sensor that is stuck.
    NoMotion { excursion_m: f64 },
    /// The latches do not tell the unknowns apart.
    Singular,
    /// A gain outside its range; a negative one means the motor or the sensor is wired backwards.
    Gain { positive: bool, gain: f64 },
    /// The zero offset is beyond its limit.
    Offset { offset_mps2: f64, limit_mps2: f64 },
    /// A centring spring stiffer than the loop holds.
    Spring {
        spring_per_s2: f64,
        limit_per_s2: f64,
    },
    /// A position sensor coarser than the loop reads: refused before the plate moves.
    Sensor { resolution_m: f64, limit_m: f64 },
    /// A current loop slower than the loop needs.
    Lag { lag_s: f64, limit_s: f64 },
}

impl IdentifyError {
    /// The envelope's property it names, if any.
    pub fn cause(&self) -> Option<Cause> {
        match self {
            IdentifyError::Gain { .. } => Some(Cause::Gain),
            IdentifyError::Offset { .. } => Some(Cause::Offset),
            IdentifyError::Spring { .. } => Some(Cause::Spring),
            IdentifyError::Sensor { .. } => Some(Cause::Sensor),
            IdentifyError::Lag { .. } => Some(Cause::Lag),
            _ => None,
        }
    }
}

impl core::fmt::Display for IdentifyError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            IdentifyError::Latches => f.write_str(
                "identification needs 14 to 512 positions, in time order, inside the probe",
            ),
            IdentifyError::Probe => {
                f.write_str("the probe must command both a positive and a negative acceleration")
            }
            IdentifyError::NoMotion { excursion_m } => write!(
                f,
                "the plate moved {excursion_m} m during the probe: check the motor, the driver \
                 enable and the position sensor"
            ),
            IdentifyError::Singular => {
                f.write_str("the probe's positions do not determine the drive's gains")
            }
            IdentifyError::Gain { positive, gain } => {
                let direction = if positive { "positive" } else { "negative" };
                if gain < 0.0 {
                    write!(
                        f,
                        "the drive's {direction} gain is {gain:.4}: the motor or the position sensor \
                         is wired backwards"
                    )
                } else {
                    let (min, max) = ENVELOPE.identified_gains();
                    write!(
                        f,
                        "the drive's {direction} gain is {gain:.4}, outside {min:.4}–{max:.4}: {}",
                        Cause::Gain.remedy()
                    )
                }
            }
            IdentifyError::Offset {
                offset_mps2,
                limit_mps2,
            } => write!(
                f,
                "the drive's zero offset is {offset_mps2:.2} m/s², beyond ±{limit_mps2:.2} m/s²: {}",
                Cause::Offset.remedy()
            ),
            IdentifyError::Spring {
                spring_per_s2,
                limit_per_s2,
            } => write!(
                f,
                "the plate's mount is a spring of k/M = {} 1/s² (natural frequency {} Hz), \
                 stiffer than the {} 1/s² the loop holds at this frequency: {}",
                Significant(spring_per_s2),
                Significant(sqrt(spring_per_s2.max(0.0)) / (2.0 * core::f64::consts::PI)),
                Significant(limit_per_s2),
                Cause::Spring.remedy()
            ),
            IdentifyError::Lag { lag_s, limit_s } => {
                let bandwidth_hz = |lag_s: f64| 1.0 / (2.0 * core::f64::consts::PI * lag_s);
                write!(
                    f,
                    "the drive's current loop lags {:.3} ms (a bandwidth of {:.0} Hz), slower \
                     than the {:.3} ms ({:.0} Hz) the loop needs: {}",
                    lag_s * 1e3,
                    bandwidth_hz(lag_s),
                    limit_s * 1e3,
                    bandwidth_hz(limit_s),
                    Cause::Lag.remedy()
                )
            }
            IdentifyError::Sensor {
                resolution_m,
                limit_m,
            } => write!(
                f,
                "the position sensor counts {:.2} µm, coarser than the {:.2} µm the loop reads: {}",
                resolution_m * 1e6,
                limit_m * 1e6,
                Cause::Sensor.remedy()
            ),
        }
    }
}
