//! The settings of an emulated run's scripted operator: `key=value` words such as `cycles=1000`
//! or `freq_hz=100`. The QEMU firmware reads them from its semihosting command line and
//! `cargo xtask run` checks them with this same parser before it starts the emulator, so a word
//! is refused with the same explanation in both places.
//!
//! Numbers are checked here for form (a count is a whole number of at least one, a physical value
//! is finite, a length may carry its unit: `stroke_m=2.5mm`). Whether the run's waveforms are
//! possible on the emulated board is [`Scenario::check`]: the waveform's own check
//! ([`crate::Waveform`]) against the machine's limits, the closed loop's room where it runs, the
//! segment floor of the board's clock ([`qemu_clock`]) and the DAC's range, with the functions
//! and figures the firmware uses.

use core::fmt;

use crate::drive::{DacCalibration, DriveError, MACHINE_LIMITS};
use crate::error::{positive, Error, Quantity};
use crate::number::{parse_length, split_decimal, LengthError, LengthUnit, Significant};
use crate::plan::TickClock;
use crate::settings::{plan_waveform, Settings};
use crate::waveform::{Drive, WaveformSpec};

/// The emulated board's `-icount shift`: every instruction advances virtual time by 2^shift ns,
/// so a run is deterministic and its timer cycles count instructions.
pub const QEMU_ICOUNT_SHIFT: u32 = 4;

/// Virtual time per instruction on the emulated board, in seconds.
pub const QEMU_INSTRUCTION_S: f64 = (1u32 << QEMU_ICOUNT_SHIFT) as f64 * 1e-9;

/// The emulated board's output tick rate: embassy's default tick of 1 µs.
pub const QEMU_TICK_HZ: u32 = 1_000_000;

/// The emulated board's output clock, its shortest segment the worst work per edge at QEMU's
/// speed times the margin (528 ticks).
pub fn qemu_clock() -> TickClock {
    TickClock::new(QEMU_TICK_HZ).with_edge_work_floor(QEMU_INSTRUCTION_S)
}

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

/// The cycles after which a run without `cycles=` requests its soft stop.
const DEFAULT_STOP_AFTER_CYCLES: u32 = 300;

/// How much the live change raises the duty when `new_duty=` is not given.
const DEFAULT_DUTY_CHANGE: f64 = 0.02;

/// A scripted run: its words applied over the power-up settings ([`Settings::DEFAULT`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Scenario {
    /// Request the soft stop once this many cycles have begun.
    pub stop_after_cycles: u32,
    /// The waveform at start.
    pub spec: WaveformSpec,
    /// The duty of the live change at half the cycles (without `new_duty=`: the start's duty
    /// plus 0.02).
    pub new_duty: f64,
    pub ramp_cycles: u16,
    pub panic_at_cycle: Option<u32>,
    pub overflow_cycle: Option<u32>,
    pub mask_cycle: Option<u32>,
    pub late_preload_cycle: Option<u32>,
    pub random_changes: u32,
    pub seed: u32,
    pub track_full_cycle: Option<u32>,
    pub track_room_cycle: Option<u32>,
}

/// Which of a run's two waveforms.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RunWaveform {
    /// The waveform the run starts with (`freq_hz`, `duty`, `stroke_m`).
    Start,
    /// The live change's (`new_duty`).
    LiveChange,
}

/// Why a scenario's run cannot go as asked on the emulated board: which waveform, its duty and
/// the cause.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ScenarioRefusal {
    pub which: RunWaveform,
    pub duty: f64,
    pub cause: RefusalCause,
}

/// What refused a run's waveform.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RefusalCause {
    /// Its own check, the machine's limits, the closed loop's room or the board's clock.
    Waveform(Error),
    /// The DAC, which cannot output its peak acceleration.
    Drive(DriveError),
}

impl fmt::Display for ScenarioRefusal {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.which {
            RunWaveform::Start => f.write_str("the waveform at start (freq_hz, duty, stroke_m)")?,
            RunWaveform::LiveChange => write!(
                f,
                "the live change's waveform (new_duty = {})",
                Significant(self.duty)
            )?,
        }
        match self.cause {
            RefusalCause::Waveform(error) => write!(f, ": {error}"),
            RefusalCause::Drive(error) => write!(f, ", on the DAC: {error}"),
        }
    }
}

impl Scenario {
    /// The run without any word: the power-up settings, 300 cycles.
    pub const DEFAULT: Scenario = Scenario {
        stop_after_cycles: DEFAULT_STOP_AFTER_CYCLES,
        spec: Settings::DEFAULT.spec(),
        new_duty: Settings::DEFAULT.duty + DEFAULT_DUTY_CHANGE,
        ramp_cycles: Settings::DEFAULT.ramp_cycles,
        panic_at_cycle: None,
        overflow_cycle: None,
        mask_cycle: None,
        late_preload_cycle: None,
        random_changes: 0,
        seed: 1,
        track_full_cycle: None,
        track_room_cycle: None,
    };

    /// Applies the `key=value` words in order over [`Scenario::DEFAULT`]; the first word refused
    /// is the error.
    pub fn parse<'a>(words: impl IntoIterator<Item = &'a str>) -> Result<Self, ScenarioError<'a>> {
        let mut scenario = Scenario::DEFAULT;
        let mut new_duty = None;
        for word in words {
            match parse_setting(word)? {
                ScenarioSetting::Cycles(n) => scenario.stop_after_cycles = n,
                ScenarioSetting::FreqHz(f) => scenario.spec.period_s = 1.0 / f,
                ScenarioSetting::Duty(d) => scenario.spec.duty = d,
                ScenarioSetting::StrokeM(stroke_m) => {
                    scenario.spec.drive = Drive::Stroke { stroke_m }
                }
                ScenarioSetting::NewDuty(d) => new_duty = Some(d),
                ScenarioSetting::Ramp(r) => scenario.ramp_cycles = r,
                ScenarioSetting::PanicAt(c) => scenario.panic_at_cycle = Some(c),
                ScenarioSetting::OverflowAt(c) => scenario.overflow_cycle = Some(c),
                ScenarioSetting::MaskAt(c) => scenario.mask_cycle = Some(c),
                ScenarioSetting::LatePreloadAt(c) => scenario.late_preload_cycle = Some(c),
                ScenarioSetting::Changes(k) => scenario.random_changes = k,
                ScenarioSetting::Seed(seed) => scenario.seed = seed,
                ScenarioSetting::TrackFullAt(c) => scenario.track_full_cycle = Some(c),
                ScenarioSetting::TrackRoomAt(c) => scenario.track_room_cycle = Some(c),
            }
        }
        scenario.new_duty = new_duty.unwrap_or(scenario.spec.duty + DEFAULT_DUTY_CHANGE);
        Ok(scenario)
    }

    /// The waveform of `which`.
    pub fn waveform(&self, which: RunWaveform) -> WaveformSpec {
        match which {
            RunWaveform::Start => self.spec,
            RunWaveform::LiveChange => WaveformSpec {
                duty: self.new_duty,
                ..self.spec
            },
        }
    }

    /// Whether both of the run's waveforms pass the checks the firmware makes before it plays
    /// one: a positive frequency, the waveform within [`MACHINE_LIMITS`], the closed loop's room
    /// where it runs (`loop_linear_mps2`: the output's linear range, as the firmware's
    /// `config::LOOP_LINEAR_MPS2`), a tick plan on `clock` ([`qemu_clock`] for the emulated
    /// board) and the default DAC's range for its peak acceleration.
    pub fn check(
        &self,
        clock: TickClock,
        loop_linear_mps2: Option<f64>,
    ) -> Result<(), ScenarioRefusal> {
        for which in [RunWaveform::Start, RunWaveform::LiveChange] {
            let spec = self.waveform(which);
            let refused = |cause| ScenarioRefusal {
                which,
                duty: spec.duty,
                cause,
            };
            let (waveform, _) = positive(Quantity::FrequencyHz, 1.0 / spec.period_s)
                .and_then(|_| plan_waveform(spec, &MACHINE_LIMITS, loop_linear_mps2, clock))
                .map_err(|error| refused(RefusalCause::Waveform(error)))?;
            DacCalibration::DEFAULT
                .levels(waveform.accel_mps2)
                .map_err(|error| refused(RefusalCause::Drive(error)))?;
        }
        Ok(())
    }
}
