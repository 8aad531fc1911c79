//! Why a line or a command was refused: [`ReplyError`], its stable code and its explanation.

use core::fmt;

use super::limits::MAX_LINE_BYTES;
use crate::configuration::ConfigError;
use crate::error::Error;
use crate::recipe::{RecipeSlot, RecordError};

/// Why a line was refused. Codes are stable; see `shared/PROTOCOL.md`.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ReplyError {
    /// 10: the line exceeded [`MAX_LINE_BYTES`].
    LineTooLong,
    /// 11: the line is not UTF-8 text or contains control characters.
    NotText,
    /// 20: the first word (or the word after `recipe`) is no command.
    UnknownCommand,
    /// 21: a required word is missing.
    MissingArgument { what: &'static str },
    /// 22: words follow a complete command.
    UnexpectedArgument,
    /// 23: `get` or `set` names no parameter.
    UnknownParameter,
    /// 23: `config get` or `config set` names no configuration key.
    UnknownKey,
    /// 24: a word that should be a number is not one.
    BadNumber { what: &'static str },
    /// 24: a word that should be a number has a decimal comma (`0,6`).
    DecimalComma { what: &'static str },
    /// 25: the number is NaN or infinite (or overflows to infinity).
    NotFinite,
    /// 26: the unit after the number is not the documented one.
    WrongUnit { what: &'static str },
    /// 29: the word after a switch's key is neither of its two words.
    NotAChoice { what: &'static str },
    /// 27: a count or slot number has a fractional part.
    NotWholeNumber { what: &'static str },
    /// 28: a count or slot number lies outside `min..=max`.
    OutOfRange {
        what: &'static str,
        min: u32,
        max: u32,
    },
    /// 40–58: the new parameters were refused by validation (one code per [`Error`] variant).
    Rejected(Error),
    /// 65: a configuration value, or the configuration as a whole, was refused.
    ConfigRefused(ConfigError),
    /// 66: the board keeps no configuration.
    NoConfiguration,
    /// 60: the command needs the feeder to be stopped.
    NotStopped,
    /// 61: a fault is latched; `reset` clears it.
    FaultLatched,
    /// 62: the recipe store could not be written.
    StorageFailed,
    /// 63 if the slot is empty, 64 if its record is unusable: `recipe load` loaded nothing.
    RecipeUnusable {
        slot: RecipeSlot,
        issue: RecordError,
    },
}

impl ReplyError {
    /// The stable numeric code sent after `ERR`.
    pub const fn code(&self) -> u16 {
        match self {
            ReplyError::LineTooLong => 10,
            ReplyError::NotText => 11,
            ReplyError::UnknownCommand => 20,
            ReplyError::MissingArgument { .. } => 21,
            ReplyError::UnexpectedArgument => 22,
            ReplyError::UnknownParameter | ReplyError::UnknownKey => 23,
            ReplyError::BadNumber { .. } | ReplyError::DecimalComma { .. } => 24,
            ReplyError::NotFinite => 25,
            ReplyError::WrongUnit { .. } => 26,
            ReplyError::NotWholeNumber { .. } => 27,
            ReplyError::OutOfRange { .. } => 28,
            ReplyError::NotAChoice { .. } => 29,
            ReplyError::ConfigRefused(_) => 65,
            ReplyError::NoConfiguration => 66,
            ReplyError::Rejected(error) => rejected_code(error),
            ReplyError::NotStopped => 60,
            ReplyError::FaultLatched => 61,
            ReplyError::StorageFailed => 62,
            ReplyError::RecipeUnusable {
                issue: RecordError::Empty,
                ..
            } => 63,
            ReplyError::RecipeUnusable { .. } => 64,
        }
    }
}

/// One code per validation error, 40–58.
const fn rejected_code(error: &Error) -> u16 {
    match error {
        Error::NotFinite { .. } => 40,
        Error::NotPositive { .. } => 41,
        Error::DutyTooLow { .. } => 42,
        Error::DutyTooHigh { .. } => 43,
        Error::FrequencyOutOfBand { .. } => 44,
        Error::AccelAboveLimit { .. } => 45,
        Error::StrokeAboveLimit { .. } => 46,
        Error::InvalidLimit { .. } => 47,
        Error::SegmentTooShort { .. } => 48,
        Error::TicksOverflow { .. } => 49,
        Error::ClockMismatch { .. } => 50,
        Error::NoSlip { .. } => 51,
        Error::OutsideViscousRange { .. } => 52,
        Error::FeedRateAboveReach { .. } => 53,
        Error::FeedRateBelowReach { .. } => 54,
        Error::SegmentBelowFloor { .. } => 55,
        Error::AccelAboveLoopRoom { .. } => 56,
        Error::StrokeAboveAccelLimit { .. } => 57,
        Error::AccelAboveTravelLimit { .. } => 58,
    }
}

impl From<Error> for ReplyError {
    fn from(error: Error) -> Self {
        ReplyError::Rejected(error)
    }
}

impl fmt::Display for ReplyError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ReplyError::LineTooLong => {
                write!(f, "line longer than {} bytes, ignored", MAX_LINE_BYTES)
            }
            ReplyError::NotText => f.write_str("line contains bytes that are not text, ignored"),
            ReplyError::UnknownCommand => {
                f.write_str("unknown command; send help for the list of commands")
            }
            ReplyError::MissingArgument { what } => write!(f, "missing {}", what),
            ReplyError::UnexpectedArgument => {
                f.write_str("unexpected words after the command; send help for the syntax")
            }
            ReplyError::UnknownParameter => {
                f.write_str("unknown parameter; use freq, duty, stroke, accel, feed or ramp")
            }
            ReplyError::UnknownKey => {
                f.write_str("unknown configuration key; config list shows them")
            }
            ReplyError::NotAChoice { what } => write!(f, "expected {}", what),
            ReplyError::ConfigRefused(error) => write!(f, "{}; nothing changed", error),
            ReplyError::NoConfiguration => f.write_str("this board keeps no configuration"),
            ReplyError::BadNumber { what } => write!(f, "not a number: expected {}", what),
            ReplyError::DecimalComma { what } => write!(
                f,
                "not a number: use a decimal point, not a comma; expected {}",
                what
            ),
            ReplyError::NotFinite => f.write_str("the number must be finite"),
            ReplyError::WrongUnit { what } => write!(f, "wrong unit: expected {}", what),
            ReplyError::NotWholeNumber { what } => {
                write!(f, "not a whole number: expected {}", what)
            }
            ReplyError::OutOfRange { what, min, max } => {
                write!(f, "out of range: expected {} from {} to {}", what, min, max)
            }
            ReplyError::Rejected(error) => write!(f, "{}; nothing changed", error),
            ReplyError::NotStopped => {
                f.write_str("only allowed while stopped; send stop and wait for state=stopped")
            }
            ReplyError::FaultLatched => {
                f.write_str("a fault is latched; check status, then send reset")
            }
            ReplyError::StorageFailed => {
                f.write_str("the flash could not be written; nothing changed")
            }
            ReplyError::RecipeUnusable { slot, issue } => {
                write!(f, "recipe {} not loaded: {}; nothing changed", slot, issue)
            }
        }
    }
}
