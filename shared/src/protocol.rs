//! The operator's command protocol: one ASCII command per line, exactly one reply line each.
//!
//! Bytes from the serial port go into a [`LineAssembler`], which yields one
//! `Result<`[`Command`]`, `[`ReplyError`]`>` per non-blank line. The controller executes the
//! command and answers with a [`Reply`] (`OK …` or `ERR <code> <explanation>`), which the
//! transport writes out followed by `\r\n`. Keywords and units are case-insensitive; numbers take
//! an optional unit, attached (`50hz`) or separate (`50 Hz`), that must match the documented one.
//!
//! A `set` command never touches the running machine directly: [`Settings::apply`] turns it into a
//! fully validated candidate ([`Applied`]: settings, tick plan, predicted feed rate) or a typed
//! [`Error`], so a rejected command changes nothing. The reference is `shared/PROTOCOL.md`.

use core::fmt::{self, Write};
use core::str;

use heapless::{String, Vec};

use crate::error::{positive, Error, Quantity};
use crate::model::{self, Friction};
use crate::number::{split_decimal, Fixed};
use crate::plan::{TickClock, TickPlan};
use crate::recipe::{RecipeSlot, RecordError, RECIPE_SLOTS};
use crate::scheduler::Phase;
use crate::waveform::{Drive, Limits, Waveform, WaveformSpec};

/// Longest command line accepted, in bytes, without its terminator and leading blanks.
pub const MAX_LINE_BYTES: usize = 64;
/// Capacity of a reply line in bytes, without its terminator. Longer replies are truncated.
pub const REPLY_CAPACITY: usize = 320;

const BACKSPACE: u8 = 0x08;
const DELETE: u8 = 0x7f;

/// A parsed command line.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Command {
    /// `start`: soft start at the next cycle boundary.
    Start,
    /// `stop`: soft stop at the next cycle boundary.
    Stop,
    /// `status`: state, active parameters, predicted feed rate, fault, uptime, cycle count.
    Status,
    /// `get <param>`: one active parameter.
    Get(Param),
    /// `set <param> <value>`: change one parameter, validated before anything changes.
    Set(Setting),
    /// `recipe save <n>`: store the current settings in slot `n`.
    RecipeSave(RecipeSlot),
    /// `recipe load <n>`: load slot `n` (defaults if the record is missing or corrupt).
    RecipeLoad(RecipeSlot),
    /// `recipe list`: what each slot holds.
    RecipeList,
    /// `reset`: clear a latched fault.
    Reset,
    /// `help`: the command summary.
    Help,
}

/// A parameter that `get` reports and `set` changes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Param {
    /// Drive frequency, Hz.
    Frequency,
    /// Duty cycle `d`, a fraction in (0.5, 1).
    Duty,
    /// Peak-to-peak stroke `x_max`, mm.
    Stroke,
    /// Peak acceleration `a_max`, m/s².
    Accel,
    /// Feed rate, mm/s: predicted by `get`, targeted by `set` through the inverse model.
    Feed,
    /// Soft start/stop length, cycles.
    Ramp,
}

impl Param {
    /// Every parameter, in reply order.
    pub const ALL: [Param; 6] = [
        Param::Frequency,
        Param::Duty,
        Param::Stroke,
        Param::Accel,
        Param::Ramp,
        Param::Feed,
    ];

    /// The keyword used in `get` and `set`.
    pub const fn keyword(self) -> &'static str {
        match self {
            Param::Frequency => "freq",
            Param::Duty => "duty",
            Param::Stroke => "stroke",
            Param::Accel => "accel",
            Param::Feed => "feed",
            Param::Ramp => "ramp",
        }
    }

    /// The key, with its unit, used in replies (`freq_hz=50`).
    pub const fn reply_key(self) -> &'static str {
        match self {
            Param::Frequency => "freq_hz",
            Param::Duty => "duty",
            Param::Stroke => "stroke_mm",
            Param::Accel => "accel_mps2",
            Param::Feed => "feed_mmps",
            Param::Ramp => "ramp_cycles",
        }
    }

    /// `value` with the decimal places shown in replies.
    const fn fixed(self, value: f64) -> Fixed {
        let decimals = match self {
            Param::Frequency | Param::Feed => 3,
            Param::Duty | Param::Stroke => 4,
            Param::Accel => 2,
            Param::Ramp => 0,
        };
        Fixed { value, decimals }
    }

    const fn value(self) -> Value {
        match self {
            Param::Frequency => Value {
                what: "the frequency in Hz",
                units: &["hz"],
            },
            Param::Duty => Value {
                what: "the duty cycle as a plain fraction",
                units: &[],
            },
            Param::Stroke => Value {
                what: "the stroke in mm",
                units: &["mm"],
            },
            Param::Accel => Value {
                what: "the peak acceleration in m/s2",
                units: &["m/s2", "m/s^2", "m/s²"],
            },
            Param::Feed => Value {
                what: "the feed rate in mm/s",
                units: &["mm/s"],
            },
            Param::Ramp => Value {
                what: "the ramp length in cycles",
                units: &["cycles", "cycle"],
            },
        }
    }
}

/// A requested parameter change, in the units of the protocol.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Setting {
    FrequencyHz(f64),
    Duty(f64),
    /// Holds the stroke from now on; the peak acceleration follows from Eq. 5.
    StrokeMm(f64),
    /// Holds the peak acceleration from now on; the stroke follows from Eq. 5.
    AccelMps2(f64),
    /// Chooses the duty with the inverse model, holding frequency and stroke or acceleration.
    FeedMmps(f64),
    RampCycles(u16),
}

/// What a number on a command line stands for, and the units it may carry.
#[derive(Clone, Copy)]
struct Value {
    what: &'static str,
    units: &'static [&'static str],
}

const SLOT: Value = Value {
    what: "a recipe slot number from 0 to 7",
    units: &[],
};

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
    /// 24: a word that should be a number is not one.
    BadNumber { what: &'static str },
    /// 25: the number is NaN or infinite (or overflows to infinity).
    NotFinite,
    /// 26: the unit after the number is not the documented one.
    WrongUnit { what: &'static str },
    /// 27: a count or slot number has a fractional part.
    NotWholeNumber { what: &'static str },
    /// 28: a count or slot number lies outside `min..=max`.
    OutOfRange {
        what: &'static str,
        min: u32,
        max: u32,
    },
    /// 40–54: the new parameters were refused by validation (one code per [`Error`] variant).
    Rejected(Error),
    /// 60: the command needs the feeder to be stopped.
    NotStopped,
    /// 61: a fault is latched; `reset` clears it.
    FaultLatched,
    /// 62: the recipe store could not be written.
    StorageFailed,
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
            ReplyError::UnknownParameter => 23,
            ReplyError::BadNumber { .. } => 24,
            ReplyError::NotFinite => 25,
            ReplyError::WrongUnit { .. } => 26,
            ReplyError::NotWholeNumber { .. } => 27,
            ReplyError::OutOfRange { .. } => 28,
            ReplyError::Rejected(error) => rejected_code(error),
            ReplyError::NotStopped => 60,
            ReplyError::FaultLatched => 61,
            ReplyError::StorageFailed => 62,
        }
    }
}

/// One code per validation error, 40–55.
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
            ReplyError::BadNumber { what } => write!(f, "not a number: expected {}", what),
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
                f.write_str("the recipe could not be written to flash; nothing changed")
            }
        }
    }
}

/// Parses one command line (without its terminator).
pub fn parse(line: &str) -> Result<Command, ReplyError> {
    let mut words = line.split_ascii_whitespace();
    let keyword = words.next().ok_or(ReplyError::UnknownCommand)?;
    let command = match lookup(keyword, &COMMANDS).ok_or(ReplyError::UnknownCommand)? {
        Keyword::Ready(command) => command,
        Keyword::Get => Command::Get(param(words.next())?),
        Keyword::Set => {
            let param = param(words.next())?;
            Command::Set(setting(param, &mut words)?)
        }
        Keyword::Recipe => {
            let action = words.next().ok_or(ReplyError::MissingArgument {
                what: "save, load or list",
            })?;
            match lookup(action, &RECIPE_ACTIONS).ok_or(ReplyError::UnknownCommand)? {
                RecipeAction::Save => Command::RecipeSave(slot(&mut words)?),
                RecipeAction::Load => Command::RecipeLoad(slot(&mut words)?),
                RecipeAction::List => Command::RecipeList,
            }
        }
    };
    match words.next() {
        Some(_) => Err(ReplyError::UnexpectedArgument),
        None => Ok(command),
    }
}

#[derive(Clone, Copy)]
enum Keyword {
    Ready(Command),
    Get,
    Set,
    Recipe,
}

const COMMANDS: [(&str, Keyword); 9] = [
    ("start", Keyword::Ready(Command::Start)),
    ("stop", Keyword::Ready(Command::Stop)),
    ("status", Keyword::Ready(Command::Status)),
    ("get", Keyword::Get),
    ("set", Keyword::Set),
    ("recipe", Keyword::Recipe),
    ("reset", Keyword::Ready(Command::Reset)),
    ("help", Keyword::Ready(Command::Help)),
    ("?", Keyword::Ready(Command::Help)),
];

#[derive(Clone, Copy)]
enum RecipeAction {
    Save,
    Load,
    List,
}

const RECIPE_ACTIONS: [(&str, RecipeAction); 3] = [
    ("save", RecipeAction::Save),
    ("load", RecipeAction::Load),
    ("list", RecipeAction::List),
];

fn lookup<T: Copy>(word: &str, table: &[(&str, T)]) -> Option<T> {
    table
        .iter()
        .find(|(name, _)| name.eq_ignore_ascii_case(word))
        .map(|&(_, value)| value)
}

fn param(word: Option<&str>) -> Result<Param, ReplyError> {
    let word = word.ok_or(ReplyError::MissingArgument {
        what: "a parameter: freq, duty, stroke, accel, feed or ramp",
    })?;
    Param::ALL
        .into_iter()
        .find(|param| param.keyword().eq_ignore_ascii_case(word))
        .ok_or(ReplyError::UnknownParameter)
}

fn setting<'a>(
    param: Param,
    words: &mut impl Iterator<Item = &'a str>,
) -> Result<Setting, ReplyError> {
    let value = param.value();
    Ok(match param {
        Param::Frequency => Setting::FrequencyHz(number(value, words)?),
        Param::Duty => Setting::Duty(number(value, words)?),
        Param::Stroke => Setting::StrokeMm(number(value, words)?),
        Param::Accel => Setting::AccelMps2(number(value, words)?),
        Param::Feed => Setting::FeedMmps(number(value, words)?),
        Param::Ramp => Setting::RampCycles(whole(value, words, u16::MAX)?),
    })
}

fn slot<'a>(words: &mut impl Iterator<Item = &'a str>) -> Result<RecipeSlot, ReplyError> {
    let max = RECIPE_SLOTS as u16 - 1;
    let index = whole(SLOT, words, max)?;
    RecipeSlot::new(index as u8).ok_or(ReplyError::OutOfRange {
        what: SLOT.what,
        min: 0,
        max: max.into(),
    })
}

/// A whole number in `0..=max`.
fn whole<'a>(
    value: Value,
    words: &mut impl Iterator<Item = &'a str>,
    max: u16,
) -> Result<u16, ReplyError> {
    let number = number(value, words)?;
    if !(0.0..=f64::from(max)).contains(&number) {
        return Err(ReplyError::OutOfRange {
            what: value.what,
            min: 0,
            max: max.into(),
        });
    }
    let whole = number as u16;
    if f64::from(whole) != number {
        return Err(ReplyError::NotWholeNumber { what: value.what });
    }
    Ok(whole)
}

/// A finite number with an optional unit, attached or as the next word.
fn number<'a>(value: Value, words: &mut impl Iterator<Item = &'a str>) -> Result<f64, ReplyError> {
    let word = words
        .next()
        .ok_or(ReplyError::MissingArgument { what: value.what })?;
    let (number, attached) =
        split_decimal(word).ok_or(ReplyError::BadNumber { what: value.what })?;
    if !number.is_finite() {
        return Err(ReplyError::NotFinite);
    }
    let unit = if attached.is_empty() {
        words.next()
    } else {
        Some(attached)
    };
    match unit {
        Some(unit) if !value.units.iter().any(|u| u.eq_ignore_ascii_case(unit)) => {
            Err(ReplyError::WrongUnit { what: value.what })
        }
        _ => Ok(number),
    }
}

/// Assembles bytes into command lines.
///
/// A line ends at CR, LF or CRLF. Leading blanks are skipped and blank lines are ignored;
/// backspace and DEL erase the last character. A line longer than [`MAX_LINE_BYTES`] is
/// discarded and answered with one [`ReplyError::LineTooLong`] when it ends; a line that is not
/// UTF-8 or holds control characters with [`ReplyError::NotText`].
#[derive(Debug, Clone, Default)]
pub struct LineAssembler {
    line: Vec<u8, MAX_LINE_BYTES>,
    overlong: bool,
    after_cr: bool,
}

impl LineAssembler {
    pub const fn new() -> Self {
        LineAssembler {
            line: Vec::new(),
            overlong: false,
            after_cr: false,
        }
    }

    /// Takes one received byte; at the end of a non-blank line returns what it asks for.
    pub fn push(&mut self, byte: u8) -> Option<Result<Command, ReplyError>> {
        let after_cr = core::mem::replace(&mut self.after_cr, byte == b'\r');
        match byte {
            b'\n' if after_cr => None,
            b'\r' | b'\n' => self.finish(),
            BACKSPACE | DELETE => {
                self.erase();
                None
            }
            b' ' | b'\t' if self.line.is_empty() => None,
            _ => {
                if self.line.push(byte).is_err() {
                    self.overlong = true;
                }
                None
            }
        }
    }

    /// Drops a partial line, for example after a transport error.
    pub fn clear(&mut self) {
        *self = Self::new();
    }

    fn finish(&mut self) -> Option<Result<Command, ReplyError>> {
        let overlong = core::mem::take(&mut self.overlong);
        let result = if overlong {
            Some(Err(ReplyError::LineTooLong))
        } else if self.line.is_empty() {
            None
        } else {
            Some(match str::from_utf8(&self.line) {
                Ok(text) if !text.chars().any(|c| c.is_control() && c != '\t') => parse(text),
                _ => Err(ReplyError::NotText),
            })
        };
        self.line.clear();
        result
    }

    /// Removes the last character (all bytes of a UTF-8 sequence) unless the line overflowed.
    fn erase(&mut self) {
        if self.overlong {
            return;
        }
        while let Some(byte) = self.line.pop() {
            if byte & 0xc0 != 0x80 {
                break;
            }
        }
    }
}

/// The machine a setting is validated for: its limits, the part's friction (for the feed-rate
/// model) and the waveform timer.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Machine {
    pub limits: Limits,
    pub friction: Friction,
    pub clock: TickClock,
}

impl Machine {
    /// Steady-state feed rate the model predicts for `waveform` on this machine.
    pub fn feed_rate_mps(&self, waveform: &Waveform) -> f64 {
        model::steady_state(waveform, &self.friction).feed_rate_mps
    }
}

/// The operator's parameters: what `set` changes and a recipe stores.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Settings {
    pub frequency_hz: f64,
    pub duty: f64,
    pub drive: Drive,
    pub ramp_cycles: u16,
}

impl Settings {
    /// The paper's operating point: 50 Hz, `d = 2 − √2`, 2.5 mm stroke, ramping over 10 cycles.
    pub const DEFAULT: Settings = Settings {
        frequency_hz: 50.0,
        duty: model::DUTY_OPT,
        drive: Drive::Stroke { stroke_m: 0.0025 },
        ramp_cycles: 10,
    };

    /// Validates these settings on `machine`: waveform within the limits and a representable
    /// tick plan.
    pub fn validate(&self, machine: &Machine) -> Result<Applied, Error> {
        let frequency_hz = positive(Quantity::FrequencyHz, self.frequency_hz)?;
        let spec = WaveformSpec::from_frequency(frequency_hz, self.duty, self.drive);
        let waveform = Waveform::new(spec, &machine.limits)?;
        let plan = TickPlan::new(&waveform, machine.clock)?;
        Ok(Applied {
            settings: *self,
            plan,
            feed_rate_mps: machine.feed_rate_mps(&waveform),
        })
    }

    /// The settings after `setting`, fully validated; `self` is left as it is either way.
    pub fn apply(&self, setting: Setting, machine: &Machine) -> Result<Applied, Error> {
        let mut next = *self;
        match setting {
            Setting::FrequencyHz(frequency_hz) => next.frequency_hz = frequency_hz,
            Setting::Duty(duty) => next.duty = duty,
            Setting::StrokeMm(stroke_mm) => {
                next.drive = Drive::Stroke {
                    stroke_m: stroke_mm / 1000.0,
                }
            }
            Setting::AccelMps2(accel_mps2) => next.drive = Drive::Accel { accel_mps2 },
            Setting::RampCycles(ramp_cycles) => next.ramp_cycles = ramp_cycles,
            Setting::FeedMmps(feed_mmps) => {
                let period_s = 1.0 / positive(Quantity::FrequencyHz, self.frequency_hz)?;
                let waveform = model::duty_for_feed_rate(
                    period_s,
                    feed_mmps / 1000.0,
                    self.drive,
                    &machine.friction,
                    &machine.limits,
                )?;
                next.duty = waveform.duty;
            }
        }
        next.validate(machine)
    }
}

impl Default for Settings {
    fn default() -> Self {
        Settings::DEFAULT
    }
}

/// Validated settings, ready for the scheduler (`set_plan`, `set_ramp_cycles`).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Applied {
    pub settings: Settings,
    pub plan: TickPlan,
    /// Steady-state feed rate the model predicts for the plan's waveform.
    pub feed_rate_mps: f64,
}

impl Applied {
    fn params(&self) -> Params {
        Params {
            waveform: self.plan.waveform,
            ramp_cycles: self.settings.ramp_cycles,
            feed_rate_mps: self.feed_rate_mps,
        }
    }
}

/// A snapshot of the controller for `status` and `get`.
#[derive(Debug, Clone, Copy)]
pub struct Status<F> {
    pub phase: Phase,
    /// The latched fault's cause, if any; a latched fault is reported as `state=fault`.
    pub fault: Option<F>,
    /// The waveform in force.
    pub waveform: Waveform,
    pub ramp_cycles: u16,
    /// Predicted steady-state feed rate of `waveform` ([`Machine::feed_rate_mps`]).
    pub feed_rate_mps: f64,
    pub uptime_ms: u64,
    /// Cycles (including idle periods) begun since power-up.
    pub cycles: u64,
}

/// The reportable parameters.
struct Params {
    waveform: Waveform,
    ramp_cycles: u16,
    feed_rate_mps: f64,
}

impl Params {
    fn value(&self, param: Param) -> f64 {
        match param {
            Param::Frequency => self.waveform.frequency_hz(),
            Param::Duty => self.waveform.duty,
            Param::Stroke => self.waveform.stroke_m * 1000.0,
            Param::Accel => self.waveform.accel_mps2,
            Param::Feed => self.feed_rate_mps * 1000.0,
            Param::Ramp => f64::from(self.ramp_cycles),
        }
    }

    fn write(&self, out: &mut Reply, param: Param) {
        let _ = write!(
            out,
            " {}={}",
            param.reply_key(),
            param.fixed(self.value(param))
        );
    }

    fn write_all(&self, out: &mut Reply) {
        for param in Param::ALL {
            self.write(out, param);
        }
    }
}

const HELP: &str = "commands: start | stop | status | get freq|duty|stroke|accel|feed|ramp | \
    set freq <Hz> | set duty <0.5..1> | set stroke <mm> | set accel <m/s2> | set feed <mm/s> | \
    set ramp <cycles> | recipe save <0-7> | recipe load <0-7> | recipe list | reset | help";

/// One reply line: `OK …` or `ERR <code> <explanation>`, printable ASCII, no terminator.
///
/// Writing to it (through [`fmt::Write`]) transliterates non-ASCII (`²` → `2`, `μ` → `mu`),
/// turns control characters into spaces and truncates at [`REPLY_CAPACITY`] instead of failing.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Reply {
    text: String<REPLY_CAPACITY>,
}

impl Reply {
    fn start(head: &str) -> Self {
        let mut reply = Reply {
            text: String::new(),
        };
        let _ = reply.write_str(head);
        reply
    }

    /// `OK`, followed by the text of `args` if it is not empty.
    pub fn ok(args: fmt::Arguments<'_>) -> Self {
        let mut reply = Self::start("OK ");
        let _ = reply.write_fmt(args);
        if reply.text.ends_with(' ') {
            reply.text.pop();
        }
        reply
    }

    /// `ERR <code> <explanation>`.
    pub fn error(error: &ReplyError) -> Self {
        let mut reply = Self::start("ERR");
        let _ = write!(reply, " {} {}", error.code(), error);
        reply
    }

    /// The reply to `help`.
    pub fn help() -> Self {
        Self::ok(format_args!("{}", HELP))
    }

    /// The reply to `status`: `OK state=… freq_hz=… … uptime_s=… cycles=… fault=…`.
    pub fn status<F: fmt::Display>(status: &Status<F>) -> Self {
        let state = match (&status.fault, status.phase) {
            (Some(_), _) => "fault",
            (None, Phase::Stopped) => "stopped",
            (None, Phase::Starting) => "starting",
            (None, Phase::Running) => "running",
            (None, Phase::Stopping) => "stopping",
        };
        let mut reply = Self::start("OK state=");
        let _ = reply.write_str(state);
        Self::params_of(status).write_all(&mut reply);
        let _ = write!(
            reply,
            " uptime_s={}.{:03} cycles={} fault=",
            status.uptime_ms / 1000,
            status.uptime_ms % 1000,
            status.cycles
        );
        let _ = match &status.fault {
            Some(cause) => write!(reply, "{}", cause),
            None => reply.write_str("none"),
        };
        reply
    }

    /// The reply to `get <param>`: `OK <key>=<value>`.
    pub fn get<F>(param: Param, status: &Status<F>) -> Self {
        let mut reply = Self::start("OK");
        Self::params_of(status).write(&mut reply, param);
        reply
    }

    /// The reply to an accepted `set`: every parameter the candidate will run with.
    pub fn applied(applied: &Applied) -> Self {
        let mut reply = Self::start("OK");
        applied.params().write_all(&mut reply);
        reply
    }

    /// The reply to a successful `recipe save`.
    pub fn recipe_saved(slot: RecipeSlot) -> Self {
        Self::ok(format_args!("recipe {} saved", slot))
    }

    /// The reply to `recipe load`: what was loaded, and why defaults were used if they were.
    pub fn recipe_loaded(slot: RecipeSlot, loaded: &crate::recipe::Loaded) -> Self {
        let mut reply = match &loaded.issue {
            None => Self::ok(format_args!("recipe {} loaded", slot)),
            Some(issue) => Self::ok(format_args!(
                "recipe {} not usable ({}), defaults loaded",
                slot, issue
            )),
        };
        loaded.applied.params().write_all(&mut reply);
        reply
    }

    /// The reply to `recipe list`, one entry per slot: `<n>=<freq>Hz/<duty>/<stroke>mm` (or
    /// `…/<accel>m/s2`) and `/r<ramp>`, or why the slot holds no recipe.
    pub fn recipe_list(entries: &[Result<Settings, RecordError>; RECIPE_SLOTS]) -> Self {
        let mut reply = Self::start("OK recipes");
        for (index, entry) in entries.iter().enumerate() {
            let _ = write!(reply, " {}=", index);
            let _ = match entry {
                Ok(settings) => {
                    let _ = write!(
                        reply,
                        "{}Hz/{}/",
                        Param::Frequency.fixed(settings.frequency_hz),
                        Param::Duty.fixed(settings.duty)
                    );
                    let _ = match settings.drive {
                        Drive::Stroke { stroke_m } => {
                            write!(reply, "{}mm", Param::Stroke.fixed(stroke_m * 1000.0))
                        }
                        Drive::Accel { accel_mps2 } => {
                            write!(reply, "{}m/s2", Param::Accel.fixed(accel_mps2))
                        }
                    };
                    write!(reply, "/r{}", settings.ramp_cycles)
                }
                Err(error) => reply.write_str(error.short_name()),
            };
        }
        reply
    }

    fn params_of<F>(status: &Status<F>) -> Params {
        Params {
            waveform: status.waveform,
            ramp_cycles: status.ramp_cycles,
            feed_rate_mps: status.feed_rate_mps,
        }
    }

    pub fn as_str(&self) -> &str {
        self.text.as_str()
    }

    /// True for `OK` replies.
    pub fn is_ok(&self) -> bool {
        self.text.starts_with("OK")
    }
}

impl fmt::Write for Reply {
    fn write_str(&mut self, text: &str) -> fmt::Result {
        for c in text.chars() {
            let ascii = match c {
                ' '..='~' => {
                    let _ = self.text.push(c);
                    continue;
                }
                'μ' | 'µ' => "mu",
                '²' => "2",
                '³' => "3",
                '·' | '×' => "*",
                '−' | '–' | '—' => "-",
                '≤' => "<=",
                '≥' => ">=",
                '…' => "...",
                c if c.is_control() => " ",
                _ => "?",
            };
            let _ = self.text.push_str(ascii);
        }
        Ok(())
    }
}

impl fmt::Display for Reply {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}
