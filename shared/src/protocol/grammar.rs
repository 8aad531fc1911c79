//! What a command line means: the commands, their parameters and the parser.
//!
//! Words are separated by blanks; keywords and units are case-insensitive. A number
//! ([`crate::number::split_decimal`]) takes an optional unit, attached (`50hz`) or as the next word
//! (`50 Hz`), that must be the documented one. A decimal comma (`0,6`) is refused as such.

use super::refusal::ReplyError;
use crate::configuration::{Key, KeyValue, ValueKind};
use crate::number::{parse_length, split_decimal, LengthUnit};
use crate::recipe::{RecipeSlot, RECIPE_SLOTS};
use crate::settings::Setting;

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
    /// `config …`: the machine's configuration on the board.
    Config(ConfigCommand),
    /// `restart`: restart the board, which then runs the saved configuration.
    Restart,
    /// `telemetry on|off`: stream one record per cycle between the replies, or stop.
    Telemetry(bool),
    /// `help`: the command summary.
    Help,
}

/// What `config` does.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ConfigCommand {
    /// `config list`: every key with its value.
    List,
    /// `config get <key>`: one key.
    Get(Key),
    /// `config set <key> <value>`: change one key, checked on its own, not saved yet.
    Set(Key, KeyValue),
    /// `config save`: check the whole configuration and store it on the board.
    Save,
    /// `config defaults`: back to the compiled defaults, not saved yet.
    Defaults,
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

    /// What the number after `set <param>` stands for.
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
                what: "the stroke in mm (or m, µm)",
                units: &["mm", "m", "um", "µm"],
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
        Keyword::Config => {
            let action = words.next().ok_or(ReplyError::MissingArgument {
                what: "list, get, set, save or defaults",
            })?;
            Command::Config(
                match lookup(action, &CONFIG_ACTIONS).ok_or(ReplyError::UnknownCommand)? {
                    ConfigAction::List => ConfigCommand::List,
                    ConfigAction::Get => ConfigCommand::Get(key(words.next())?),
                    ConfigAction::Set => {
                        let key = key(words.next())?;
                        ConfigCommand::Set(key, key_value(key, &mut words)?)
                    }
                    ConfigAction::Save => ConfigCommand::Save,
                    ConfigAction::Defaults => ConfigCommand::Defaults,
                },
            )
        }
        Keyword::Telemetry => {
            let word = words
                .next()
                .ok_or(ReplyError::MissingArgument { what: "on or off" })?;
            match lookup(word, &[("on", true), ("off", false)]) {
                Some(on) => Command::Telemetry(on),
                None => return Err(ReplyError::NotAChoice { what: "on or off" }),
            }
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
    Config,
    Telemetry,
}

const COMMANDS: [(&str, Keyword); 12] = [
    ("start", Keyword::Ready(Command::Start)),
    ("stop", Keyword::Ready(Command::Stop)),
    ("status", Keyword::Ready(Command::Status)),
    ("get", Keyword::Get),
    ("set", Keyword::Set),
    ("recipe", Keyword::Recipe),
    ("reset", Keyword::Ready(Command::Reset)),
    ("config", Keyword::Config),
    ("restart", Keyword::Ready(Command::Restart)),
    ("telemetry", Keyword::Telemetry),
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

#[derive(Clone, Copy)]
enum ConfigAction {
    List,
    Get,
    Set,
    Save,
    Defaults,
}

const CONFIG_ACTIONS: [(&str, ConfigAction); 5] = [
    ("list", ConfigAction::List),
    ("get", ConfigAction::Get),
    ("set", ConfigAction::Set),
    ("save", ConfigAction::Save),
    ("defaults", ConfigAction::Defaults),
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
        Param::Stroke => Setting::StrokeMm(length_mm(value, words)?),
        Param::Accel => Setting::AccelMps2(number(value, words)?),
        Param::Feed => Setting::FeedMmps(number(value, words)?),
        Param::Ramp => Setting::RampCycles(whole(value, words, u16::MAX)?),
    })
}

fn key(word: Option<&str>) -> Result<Key, ReplyError> {
    let word = word.ok_or(ReplyError::MissingArgument {
        what: "a configuration key; config list shows them",
    })?;
    Key::from_keyword(word).ok_or(ReplyError::UnknownKey)
}

/// The value after `config set <key>`, typed as the key's kind.
fn key_value<'a>(
    key: Key,
    words: &mut impl Iterator<Item = &'a str>,
) -> Result<KeyValue, ReplyError> {
    match key.kind() {
        ValueKind::Number { units } => Ok(KeyValue::Number(number(
            Value {
                what: key.what(),
                units,
            },
            words,
        )?)),
        ValueKind::Whole { min, max } => {
            let value = Value {
                what: key.what(),
                units: &["counts", "cycles", "baud", "ms"],
            };
            Ok(KeyValue::Number(f64::from(whole_in(
                value, words, min, max,
            )?)))
        }
        ValueKind::Switch { off, on } => {
            let word = words
                .next()
                .ok_or(ReplyError::MissingArgument { what: key.what() })?;
            if word.eq_ignore_ascii_case(off) {
                Ok(KeyValue::Switch(false))
            } else if word.eq_ignore_ascii_case(on) {
                Ok(KeyValue::Switch(true))
            } else {
                Err(ReplyError::NotAChoice { what: key.what() })
            }
        }
    }
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
    // In range of a u16 by construction.
    whole_in(value, words, 0, max.into()).map(|whole| whole as u16)
}

/// A whole number in `min..=max`.
fn whole_in<'a>(
    value: Value,
    words: &mut impl Iterator<Item = &'a str>,
    min: u32,
    max: u32,
) -> Result<u32, ReplyError> {
    let number = number(value, words)?;
    if !(f64::from(min)..=f64::from(max)).contains(&number) {
        return Err(ReplyError::OutOfRange {
            what: value.what,
            min,
            max,
        });
    }
    let whole = number as u32;
    if f64::from(whole) != number {
        return Err(ReplyError::NotWholeNumber { what: value.what });
    }
    Ok(whole)
}

/// A finite number with an optional unit, attached or as the next word.
fn number<'a>(value: Value, words: &mut impl Iterator<Item = &'a str>) -> Result<f64, ReplyError> {
    let (number, _, unit) = numeral(value, words)?;
    match unit {
        Some(unit) if !value.units.iter().any(|u| u.eq_ignore_ascii_case(unit)) => {
            Err(ReplyError::WrongUnit { what: value.what })
        }
        _ => Ok(number),
    }
}

/// A length in millimetres, typed in `mm` (or bare), `m` or `µm` (`um`): the unit's power of ten
/// is applied to the number's decimal exponent before its one rounding
/// ([`crate::number::parse_length`]), so `0.0025 m` is exactly `2.5` mm.
fn length_mm<'a>(
    value: Value,
    words: &mut impl Iterator<Item = &'a str>,
) -> Result<f64, ReplyError> {
    let (_, word, unit) = numeral(value, words)?;
    let typed = match unit {
        Some(unit) => {
            LengthUnit::from_word(unit).ok_or(ReplyError::WrongUnit { what: value.what })?
        }
        None => LengthUnit::Millimetre,
    };
    let digits = word.get(..word.len() - split_decimal(word).map_or(0, |(_, rest)| rest.len()));
    digits
        .and_then(|digits| parse_length(digits, typed, LengthUnit::Millimetre).ok())
        .ok_or(ReplyError::BadNumber { what: value.what })
}

/// The next word's number, the word itself and the unit written after it (attached, or as the
/// following word), refusing a decimal comma, a non-number and a non-finite value.
fn numeral<'a>(
    value: Value,
    words: &mut impl Iterator<Item = &'a str>,
) -> Result<(f64, &'a str, Option<&'a str>), ReplyError> {
    let word = words
        .next()
        .ok_or(ReplyError::MissingArgument { what: value.what })?;
    let (number, attached) = match split_decimal(word) {
        Some((_, rest)) if decimal_comma(rest) => {
            return Err(ReplyError::DecimalComma { what: value.what })
        }
        Some(split) => split,
        None if decimal_comma(word) => return Err(ReplyError::DecimalComma { what: value.what }),
        None => return Err(ReplyError::BadNumber { what: value.what }),
    };
    if !number.is_finite() {
        return Err(ReplyError::NotFinite);
    }
    let unit = if attached.is_empty() {
        words.next()
    } else {
        Some(attached)
    };
    Ok((number, word, unit))
}

/// `text` starts with a comma followed by a digit: a decimal comma (`0,6` leaves `,6`).
fn decimal_comma(text: &str) -> bool {
    text.strip_prefix(',')
        .is_some_and(|fraction| fraction.starts_with(|c: char| c.is_ascii_digit()))
}
