//! Why the course stopped ([`CourseError`]).

use crate::closed_loop::cycle_loop::LoopError;
use crate::closed_loop::envelope::Cause;
use crate::closed_loop::identify::IdentifyError;

/// Why the course stopped.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CourseError {
    Identify(IdentifyError),
    Loop(LoopError),
    /// The plate did not settle at the centre within the allowed held cycles.
    Centring {
        error_m: f64,
    },
    /// A cycle of the plan never turns back.
    Plan,
    /// The boundary of this cycle reached the course too late or not at all.
    MissedBoundary {
        cycle: u64,
    },
    /// The position sensor had no capture at this cycle start tick.
    NoCapture {
        tick: u64,
    },
    /// The identification was not handed over within the hold the course gives it.
    IdentifyLate {
        hold_s: f64,
    },
}

impl CourseError {
    /// One word for the console's `status` (`loop_error=`): the envelope's cause where the
    /// identification names one.
    pub fn name(&self) -> &'static str {
        match self {
            CourseError::Identify(error) => error.cause().map_or("identification", Cause::name),
            CourseError::Loop(LoopError::Backwards { .. }) => "encoder-reversed",
            CourseError::Loop(_) => "loop-limit",
            CourseError::Centring { .. } => "centring",
            CourseError::Plan => "plan",
            CourseError::MissedBoundary { .. } => "missed-boundary",
            CourseError::NoCapture { .. } => "no-capture",
            CourseError::IdentifyLate { .. } => "identification-late",
        }
    }

    /// The envelope's property it names, if any.
    pub fn cause(&self) -> Option<Cause> {
        match self {
            CourseError::Identify(error) => error.cause(),
            _ => None,
        }
    }
}

impl core::fmt::Display for CourseError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            CourseError::Identify(error) => write!(f, "identification: {error}"),
            CourseError::Loop(error) => write!(f, "closed loop: {error}"),
            CourseError::Centring { error_m } => write!(
                f,
                "the plate is still {error_m} m from its centre after the centring's last cycle"
            ),
            CourseError::Plan => f.write_str("a planned cycle does not turn back"),
            CourseError::MissedBoundary { cycle } => write!(
                f,
                "the closed loop missed the start of cycle {cycle}: it cannot keep up with the output"
            ),
            CourseError::NoCapture { tick } => write!(
                f,
                "the position sensor has no capture at the cycle start tick {tick}"
            ),
            CourseError::IdentifyLate { hold_s } => write!(
                f,
                "the drive's identification was not done within the {hold_s} s the course holds \
                 the plate for it"
            ),
        }
    }
}
