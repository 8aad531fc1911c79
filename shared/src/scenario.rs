//! The settings of an emulated run's scripted operator: `key=value` words such as `cycles=1000`
//! or `freq_hz=100`. The QEMU firmware reads them from its semihosting command line and
//! `cargo xtask run` checks them with this same parser before it starts the emulator, so a word
//! is refused with the same explanation in both places.
//!
//! Numbers are checked here for form (a count is a whole number of at least one, a physical value
//! is finite, a length may carry its unit: `stroke_m=2.5mm`); whether a waveform is possible is the
//! waveform's own check ([`crate::Waveform`]).

use core::fmt;

use crate::number::{parse_length, split_decimal, LengthError, LengthUnit};

/// The keys, each with its meaning, in the order a help text lists them.
pub const SCENARIO_KEYS: [(&str, &str); 14] = [
    (
        "cycles",
        "request the soft stop once N cycles have begun, with the closed loop counted from the \
         release of its soft start (N ≥ 1)",
    ),
    ("freq_hz", "waveform frequency"),
    ("duty", "duty at start"),
    ("stroke_m", "stroke (peak-to-peak plate travel), in m or with its unit (2.5mm, 2500um)"),
    ("new_duty", "duty of the live change at half the cycles"),
    ("ramp", "soft start and stop cycles"),
    ("panic_at", "panic in thread mode once this many cycles have begun"),
    ("overflow_at", "from this cycle on, recurse in thread mode until the stack overflows"),
    ("mask_at", "at this cycle, mask interrupts in thread mode for two periods: a missed edge"),
    ("late_preload_at", "preload this cycle's first segment too late: a missed edge, then a restart"),
    ("changes", "random operator changes between start and stop: settings in and past range, stops and starts"),
    ("seed", "seed of the random changes"),
    ("track_full_at", "from this cycle on, the track's light barrier is blocked (a full track)"),
    ("track_room_at", "from this cycle on, the barrier is clear again (the track has room)"),
];

/// One setting of the scripted operator.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ScenarioSetting {
    /// `cycles=N`: request the soft stop once `N` cycles have begun (with the closed loop, from
    /// the cycle at which its course released the soft start).
    Cycles(u32),
    /// `freq_hz=F`: the waveform frequency.
    FreqHz(f64),
    /// `duty=D`: the duty at start.
    Duty(f64),
    /// `stroke_m=X`: the peak-to-peak stroke.
    StrokeM(f64),
    /// `new_duty=D`: the duty of the live change at half the cycles.
    NewDuty(f64),
    /// `ramp=R`: soft start and stop cycles.
    Ramp(u16),
    /// `panic_at=C`: panic in thread mode once `C` cycles have begun.
    PanicAt(u32),
    /// `overflow_at=C`: from cycle `C` on, recurse in thread mode until the stack overflows.
    OverflowAt(u32),
    /// `mask_at=C`: at cycle `C`, mask interrupts in thread mode for two periods.
    MaskAt(u32),
    /// `late_preload_at=C`: preload the first segment of cycle `C` past its deadline.
    LatePreloadAt(u32),
    /// `changes=K`: `K` random operator changes spread over the run.
    Changes(u32),
    /// `seed=S`: the seed of the random changes.
    Seed(u32),
    /// `track_full_at=C`: from cycle `C` on, the track's light barrier is blocked.
    TrackFullAt(u32),
    /// `track_room_at=C`: from cycle `C` on, the barrier is clear again.
    TrackRoomAt(u32),
}

/// Why a scenario word was refused; each names the word or value as typed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ScenarioError<'a> {
    /// The word has no `=`.
    NotKeyValue(&'a str),
    /// The key is not one of [`SCENARIO_KEYS`].
    UnknownKey(&'a str),
    /// The value is not a whole number in the key's range.
    NotACount {
        key: &'static str,
        value: &'a str,
        min: u32,
        max: u32,
    },
    /// The value is not a finite decimal number.
    NotFinite { key: &'static str, value: &'a str },
    /// The value is not a finite length, in metres or with its unit.
    NotALength {
        key: &'static str,
        value: &'a str,
        error: LengthError,
    },
}

impl fmt::Display for ScenarioError<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ScenarioError::NotKeyValue(word) => {
                write!(f, "scenario setting `{word}` is not of the form key=value")
            }
            ScenarioError::UnknownKey(key) => {
                write!(f, "unknown scenario key `{key}` (known: ")?;
                for (index, (known, _)) in SCENARIO_KEYS.iter().enumerate() {
                    if index > 0 {
                        f.write_str(", ")?;
                    }
                    f.write_str(known)?;
                }
                f.write_str(")")
            }
            ScenarioError::NotACount {
                key,
                value,
                min,
                max,
            } => write!(
                f,
                "{key}={value}: {key} must be a whole number from {min} to {max}"
            ),
            ScenarioError::NotFinite { key, value } => {
                write!(f, "{key}={value}: {key} must be a finite decimal number")
            }
            ScenarioError::NotALength { key, value, error } => write!(
                f,
                "{key}={value}: {key} must be a finite length in m or with its unit: {error}"
            ),
        }
    }
}

/// Reads one `key=value` word.
pub fn parse_setting(word: &str) -> Result<ScenarioSetting, ScenarioError<'_>> {
    let (key, value) = word
        .split_once('=')
        .ok_or(ScenarioError::NotKeyValue(word))?;
    let count = |key: &'static str, min: u32, max: u32| {
        value
            .parse::<u32>()
            .ok()
            .filter(|n| (min..=max).contains(n))
            .ok_or(ScenarioError::NotACount {
                key,
                value,
                min,
                max,
            })
    };
    let finite = |key: &'static str| match split_decimal(value) {
        Some((number, "")) if number.is_finite() => Ok(number),
        _ => Err(ScenarioError::NotFinite { key, value }),
    };
    Ok(match key {
        "cycles" => ScenarioSetting::Cycles(count("cycles", 1, u32::MAX)?),
        "freq_hz" => ScenarioSetting::FreqHz(finite("freq_hz")?),
        "duty" => ScenarioSetting::Duty(finite("duty")?),
        "stroke_m" => ScenarioSetting::StrokeM(
            parse_length(value, LengthUnit::Metre, LengthUnit::Metre).map_err(|error| {
                ScenarioError::NotALength {
                    key: "stroke_m",
                    value,
                    error,
                }
            })?,
        ),
        "new_duty" => ScenarioSetting::NewDuty(finite("new_duty")?),
        "ramp" => ScenarioSetting::Ramp(value.parse().map_err(|_| ScenarioError::NotACount {
            key: "ramp",
            value,
            min: 0,
            max: u16::MAX.into(),
        })?),
        "panic_at" => ScenarioSetting::PanicAt(count("panic_at", 0, u32::MAX)?),
        "overflow_at" => ScenarioSetting::OverflowAt(count("overflow_at", 0, u32::MAX)?),
        "mask_at" => ScenarioSetting::MaskAt(count("mask_at", 0, u32::MAX)?),
        "late_preload_at" => ScenarioSetting::LatePreloadAt(count("late_preload_at", 0, u32::MAX)?),
        "changes" => ScenarioSetting::Changes(count("changes", 0, u32::MAX)?),
        "seed" => ScenarioSetting::Seed(count("seed", 0, u32::MAX)?),
        "track_full_at" => ScenarioSetting::TrackFullAt(count("track_full_at", 0, u32::MAX)?),
        "track_room_at" => ScenarioSetting::TrackRoomAt(count("track_room_at", 0, u32::MAX)?),
        _ => return Err(ScenarioError::UnknownKey(key)),
    })
}
