//! Errors of the simulator: the shared crate's [`Error`] for every physical or configuration
//! refusal, plus the few conditions only the simulator can detect.

use core::fmt;

use feeder_shared::closed_loop::{Cause, CourseError, IdentifyError};
use feeder_shared::number::Significant;
use feeder_shared::DriveError;
use feeder_shared::{Error, Quantity};

#[derive(Debug, Clone, PartialEq)]
pub enum SimError {
    /// A parameter refused by the shared crate (its message is shown as is).
    Shared(Error),
    /// Static friction below kinetic friction has no consistent stick–slip motion.
    StaticBelowKinetic { mu: f64, mu_static: f64 },
    /// A sweep, fit or search was asked for with too few or inconsistent points.
    BadRange { what: &'static str },
    /// A frequency without a period: NaN, infinite, zero or negative.
    BadFrequency { frequency_hz: f64 },
    /// A request the command line cannot run as given; the text names the flags and values.
    Request(String),
    /// Writing an output file failed.
    Output { path: String, reason: String },
    /// Reading an input (file or stream) failed.
    Input { source: String, reason: String },
    /// An event stream without a single segment event, with the firmware's first error line.
    NoSegments {
        source: String,
        firmware_error: Option<String>,
    },
    /// A plant file refused: not valid TOML, an unknown key, a value of the wrong type or out of
    /// its range; the place names the key (with its table) and the line and column.
    PlantFile {
        source: String,
        place: Option<PlantPlace>,
        reason: String,
    },
    /// A plant file's value outside its physical range.
    PlantValue {
        key: &'static str,
        value: f64,
        allowed: &'static str,
    },
    /// The plate or the part changed contact state without end at one instant (stick–slip
    /// chatter the event model cannot resolve).
    Chatter { time_s: f64 },
    /// A sensors table on its own that is not valid TOML or holds an unknown key (the parser's
    /// message names it).
    SensorFile { source: String, reason: String },
    /// A sensor's configuration value outside its range.
    SensorValue {
        sensor: &'static str,
        key: &'static str,
        value: f64,
        allowed: &'static str,
    },
    /// A sensor sampled at a time it cannot use, or fed a motion value that is not finite.
    SensorInput {
        sensor: &'static str,
        t_s: f64,
        reason: &'static str,
    },
    /// A run needs a sensor its plant file does not list.
    MissingSensor { sensor: &'static str },
    /// The drive's identification at start-up refused to let the feeder run.
    Identification(IdentifyError),
    /// The closed loop's course stopped at this time.
    Loop { time_s: f64, error: CourseError },
    /// A level the closed loop trimmed does not fit the output's DAC.
    TrimmedLevel { time_s: f64, error: DriveError },
}

impl SimError {
    /// The closed loop's envelope property a give-up names, if any.
    pub fn cause(&self) -> Option<Cause> {
        match self {
            SimError::Identification(error) => error.cause(),
            SimError::Loop { error, .. } => error.cause(),
            _ => None,
        }
    }
}

impl fmt::Display for SimError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SimError::Shared(error) => error.fmt(f),
            SimError::StaticBelowKinetic { mu, mu_static } => write!(
                f,
                "static friction coefficient μ_s = {} must not be below the kinetic coefficient \
                 μ = {}",
                Significant(*mu_static),
                Significant(*mu)
            ),
            SimError::BadRange { what } => write!(f, "{what}"),
            SimError::BadFrequency { frequency_hz } => write!(
                f,
                "{} must be finite and greater than zero, got {}",
                Quantity::FrequencyHz.name(),
                Significant(*frequency_hz)
            ),
            SimError::Request(what) => write!(f, "{what}"),
            SimError::Output { path, reason } => write!(f, "cannot write {path}: {reason}"),
            SimError::Input { source, reason } => write!(f, "cannot read {source}: {reason}"),
            SimError::NoSegments {
                source,
                firmware_error: None,
            } => write!(
                f,
                "{source} holds no segments (`EVT seg` lines): is it the firmware's decoded event \
                 log?"
            ),
            SimError::NoSegments {
                source,
                firmware_error: Some(line),
            } => write!(
                f,
                "{source} holds no segments; the firmware reported: {line}"
            ),
            SimError::PlantFile {
                source,
                place: None,
                reason,
            } => write!(f, "cannot load the plant from {source}: {reason}"),
            SimError::PlantFile {
                source,
                place: Some(place),
                reason,
            } => write!(f, "cannot load the plant from {source}, {place}: {reason}"),
            SimError::PlantValue {
                key,
                value,
                allowed,
            } => write!(f, "plant key `{key}` {}", out_of_range(allowed, *value)),
            SimError::Chatter { time_s } => write!(
                f,
                "the plate or part changed contact state without end at t = {} s",
                Significant(*time_s)
            ),
            SimError::SensorFile { source, reason } => {
                write!(f, "cannot load the sensors from {source}: {reason}")
            }
            SimError::SensorValue {
                sensor,
                key,
                value,
                allowed,
            } => write!(
                f,
                "sensor `{sensor}` key `{key}` {}",
                out_of_range(allowed, *value)
            ),
            SimError::SensorInput {
                sensor,
                t_s,
                reason,
            } => write!(
                f,
                "sensor `{sensor}` at t = {} s: {reason}",
                Significant(*t_s)
            ),
            SimError::MissingSensor { sensor } => write!(
                f,
                "this run reads the plate's {sensor}: the plant file needs a `[sensors.{sensor}]` \
                 table"
            ),
            SimError::Identification(error) => write!(f, "identification refused: {error}"),
            SimError::TrimmedLevel { time_s, error } => write!(
                f,
                "the closed loop stopped at t = {} s: a trimmed level does not fit the DAC: {error}",
                Significant(*time_s)
            ),
            SimError::Loop { time_s, error } => write!(
                f,
                "the closed loop stopped at t = {} s: {error}",
                Significant(*time_s)
            ),
        }
    }
}

impl std::error::Error for SimError {}

/// Why a value is refused: the range it must lie in and the value it has.
pub(crate) fn out_of_range(allowed: &str, value: f64) -> String {
    format!("must be {allowed}, got {}", Significant(value))
}

/// Where a plant file holds a fault: the line and column (from 1, in characters) and the key
/// with its table, if the fault lies in a key's entry (a syntax error between entries does not).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PlantPlace {
    pub line: usize,
    pub column: usize,
    pub key: Option<String>,
}

impl fmt::Display for PlantPlace {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "line {}, column {}", self.line, self.column)?;
        match &self.key {
            Some(key) => write!(f, ", key `{key}`"),
            None => Ok(()),
        }
    }
}

impl From<Error> for SimError {
    fn from(error: Error) -> Self {
        SimError::Shared(error)
    }
}
