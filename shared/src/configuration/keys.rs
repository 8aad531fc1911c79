//! The configuration's keys: their names and units on the console, their ranges and which of
//! them change what the output does.

use super::{ConfigError, Configuration, Problem};
use crate::settings::Settings;
use crate::waveform::Drive;

/// One configuration setting, as `config get` and `config set` name it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Key {
    DacZero,
    DacScale,
    DacMargin,
    PwmFullScale,
    MinFrequency,
    MaxFrequency,
    MaxAccel,
    MaxStroke,
    EncoderResolution,
    EncoderDirection,
    ClosedLoop,
    PartMu,
    TrackFull,
    TrackEmpty,
    StartFrequency,
    StartDuty,
    StartStroke,
    StartAccel,
    StartRamp,
    ModbusAddress,
    ModbusBaud,
    ModbusParity,
    LinkTimeout,
    ConsoleWatchdog,
}

/// A configuration value in the key's console unit.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum KeyValue {
    Number(f64),
    Switch(bool),
}

/// What a key's value is typed as on the console.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ValueKind {
    /// A number, with an optional unit among `units`.
    Number { units: &'static [&'static str] },
    /// A whole number from `min` to `max`.
    Whole { min: u32, max: u32 },
    /// One of two words, for false and true.
    Switch { off: &'static str, on: &'static str },
}

/// A key's documentation and range: console unit, what the value is, its range.
struct Spec {
    keyword: &'static str,
    unit: &'static str,
    what: &'static str,
    kind: ValueKind,
    min: f64,
    max: f64,
    /// Changing it changes what the output does: refused while the plate moves.
    output: bool,
}

const HZ: &[&str] = &["hz"];
const MPS2: &[&str] = &["m/s2", "m/s^2", "m/s²"];
const MM: &[&str] = &["mm"];
const UM: &[&str] = &["um", "µm"];
const S: &[&str] = &["s"];
const PLAIN: &[&str] = &[];
const COUNTS: &[&str] = &["counts"];

const fn number(
    keyword: &'static str,
    unit: &'static str,
    what: &'static str,
    units: &'static [&'static str],
    (min, max): (f64, f64),
    output: bool,
) -> Spec {
    Spec {
        keyword,
        unit,
        what,
        kind: ValueKind::Number { units },
        min,
        max,
        output,
    }
}

const fn whole(keyword: &'static str, what: &'static str, max: u16, output: bool) -> Spec {
    whole_in(keyword, "", what, (0, max as u32), output)
}

const fn whole_in(
    keyword: &'static str,
    unit: &'static str,
    what: &'static str,
    (min, max): (u32, u32),
    output: bool,
) -> Spec {
    Spec {
        keyword,
        unit,
        what,
        kind: ValueKind::Whole { min, max },
        min: min as f64,
        max: max as f64,
        output,
    }
}

const fn switch(
    keyword: &'static str,
    what: &'static str,
    off: &'static str,
    on: &'static str,
    output: bool,
) -> Spec {
    Spec {
        keyword,
        unit: "",
        what,
        kind: ValueKind::Switch { off, on },
        min: 0.0,
        max: 1.0,
        output,
    }
}

impl Key {
    /// Every key, in the order `config list` shows them.
    pub const ALL: [Key; 24] = [
        Key::DacZero,
        Key::DacScale,
        Key::DacMargin,
        Key::PwmFullScale,
        Key::MinFrequency,
        Key::MaxFrequency,
        Key::MaxAccel,
        Key::MaxStroke,
        Key::EncoderResolution,
        Key::EncoderDirection,
        Key::ClosedLoop,
        Key::PartMu,
        Key::TrackFull,
        Key::TrackEmpty,
        Key::StartFrequency,
        Key::StartDuty,
        Key::StartStroke,
        Key::StartAccel,
        Key::StartRamp,
        Key::ModbusAddress,
        Key::ModbusBaud,
        Key::ModbusParity,
        Key::LinkTimeout,
        Key::ConsoleWatchdog,
    ];

    const fn spec(self) -> Spec {
        match self {
            Key::DacZero => whole("dac_zero", "the DAC code of zero acceleration", 4095, true),
            Key::DacScale => number(
                "dac_counts_per_mps2",
                "",
                "the DAC counts per m/s2",
                COUNTS,
                (0.1, 1000.0),
                true,
            ),
            Key::DacMargin => whole(
                "dac_margin",
                "the DAC codes left out of the linear range at either end",
                2047,
                true,
            ),
            Key::PwmFullScale => number(
                "pwm_full_mps2",
                " m/s2",
                "the acceleration at full PWM duty in m/s2",
                MPS2,
                (1.0, 10_000.0),
                true,
            ),
            Key::MinFrequency => number(
                "min_freq_hz",
                " Hz",
                "the lowest frequency in Hz",
                HZ,
                (10.0, 500.0),
                true,
            ),
            Key::MaxFrequency => number(
                "max_freq_hz",
                " Hz",
                "the highest frequency in Hz",
                HZ,
                (10.0, 500.0),
                true,
            ),
            Key::MaxAccel => number(
                "max_accel_mps2",
                " m/s2",
                "the motor's peak acceleration in m/s2",
                MPS2,
                (1.0, 10_000.0),
                true,
            ),
            Key::MaxStroke => number(
                "max_stroke_mm",
                " mm",
                "the plate's travel in mm",
                MM,
                (0.01, 100.0),
                true,
            ),
            Key::EncoderResolution => number(
                "encoder_um",
                " um",
                "the encoder's travel per count in um",
                UM,
                (0.001, 100.0),
                true,
            ),
            Key::EncoderDirection => switch(
                "encoder_dir",
                "forward or reversed",
                "forward",
                "reversed",
                true,
            ),
            Key::ClosedLoop => switch("closed_loop", "on or off", "off", "on", true),
            Key::PartMu => number(
                "part_mu",
                "",
                "the part's friction coefficient",
                PLAIN,
                (0.01, 2.0),
                true,
            ),
            Key::TrackFull => number(
                "track_full_s",
                " s",
                "the blocked time of a full track in s",
                S,
                (0.01, 60.0),
                false,
            ),
            Key::TrackEmpty => number(
                "track_empty_s",
                " s",
                "the clear time of an empty track in s",
                S,
                (0.01, 60.0),
                false,
            ),
            Key::StartFrequency => number(
                "start_freq_hz",
                " Hz",
                "the start-up frequency in Hz",
                HZ,
                (10.0, 500.0),
                false,
            ),
            Key::StartDuty => number(
                "start_duty",
                "",
                "the start-up duty cycle",
                PLAIN,
                (0.5, 1.0),
                false,
            ),
            Key::StartStroke => number(
                "start_stroke_mm",
                " mm",
                "the start-up stroke in mm",
                MM,
                (0.001, 100.0),
                false,
            ),
            Key::StartAccel => number(
                "start_accel_mps2",
                " m/s2",
                "the start-up peak acceleration in m/s2",
                MPS2,
                (0.01, 10_000.0),
                false,
            ),
            Key::StartRamp => whole("start_ramp", "the start-up ramp in cycles", u16::MAX, false),
            Key::ModbusAddress => whole_in(
                "modbus_address",
                "",
                "the Modbus slave address",
                (1, 247),
                false,
            ),
            Key::ModbusBaud => whole_in(
                "modbus_baud",
                " baud",
                "the Modbus port's rate in baud",
                (1200, 115_200),
                false,
            ),
            Key::ModbusParity => switch(
                "modbus_parity",
                "even (8E1) or none (8N2)",
                "none",
                "even",
                false,
            ),
            Key::LinkTimeout => whole_in(
                "link_timeout_ms",
                " ms",
                "the link watchdog's silence in ms, 0 for off",
                (0, 60_000),
                false,
            ),
            Key::ConsoleWatchdog => switch("console_watchdog", "on or off", "off", "on", false),
        }
    }

    /// The key's name on the console.
    pub const fn keyword(self) -> &'static str {
        self.spec().keyword
    }

    /// What the value stands for, for refusals.
    pub const fn what(self) -> &'static str {
        self.spec().what
    }

    /// How the value is typed.
    pub const fn kind(self) -> ValueKind {
        self.spec().kind
    }

    /// The unit after a value in messages (with its leading space), or nothing.
    pub const fn unit_suffix(self) -> &'static str {
        self.spec().unit
    }

    /// Changing this key changes what the output does: refused while the plate moves.
    pub const fn changes_output(self) -> bool {
        self.spec().output
    }

    /// The key named `word` (case-insensitive).
    pub fn from_keyword(word: &str) -> Option<Key> {
        Key::ALL
            .into_iter()
            .find(|key| key.keyword().eq_ignore_ascii_case(word))
    }

    /// The start-up drive's key: stroke or peak acceleration, whichever `settings` hold.
    pub const fn startup(settings: &Settings) -> Key {
        match settings.drive {
            Drive::Stroke { .. } => Key::StartStroke,
            Drive::Accel { .. } => Key::StartAccel,
        }
    }

    /// The value on its own: a number within the key's range, a switch for a switch.
    pub fn check(self, value: KeyValue) -> Result<(), ConfigError> {
        let spec = self.spec();
        match (spec.kind, value) {
            (ValueKind::Switch { .. }, KeyValue::Switch(_)) => Ok(()),
            (ValueKind::Whole { .. }, KeyValue::Number(number))
                if (spec.min..=spec.max).contains(&number) && libm::trunc(number) != number =>
            {
                Err(ConfigError::new(self, Problem::NotWhole { value: number }))
            }
            (ValueKind::Number { .. } | ValueKind::Whole { .. }, KeyValue::Number(number))
                if (spec.min..=spec.max).contains(&number) =>
            {
                Ok(())
            }
            (_, value) => Err(ConfigError::new(
                self,
                Problem::OutOfRange {
                    value: match value {
                        KeyValue::Number(number) => number,
                        KeyValue::Switch(on) => f64::from(u8::from(on)),
                    },
                    min: spec.min,
                    max: spec.max,
                },
            )),
        }
    }

    /// The key's value in `configuration`, in its console unit; `None` for the start-up drive's
    /// key the start-up settings do not hold.
    pub fn get(self, configuration: &Configuration) -> Option<KeyValue> {
        let c = configuration;
        let number = |value: f64| Some(KeyValue::Number(value));
        match self {
            Key::DacZero => number(f64::from(c.dac.zero_code)),
            Key::DacScale => number(c.dac.counts_per_mps2),
            Key::DacMargin => number(f64::from(c.dac.linear_margin_counts)),
            Key::PwmFullScale => number(c.pwm.full_duty_accel_mps2),
            Key::MinFrequency => number(c.limits.min_frequency_hz),
            Key::MaxFrequency => number(c.limits.max_frequency_hz),
            Key::MaxAccel => number(c.limits.max_accel_mps2),
            Key::MaxStroke => number(c.limits.max_stroke_m * 1e3),
            Key::EncoderResolution => number(c.encoder.resolution_m * 1e6),
            Key::EncoderDirection => Some(KeyValue::Switch(c.encoder.reversed)),
            Key::ClosedLoop => Some(KeyValue::Switch(c.closed_loop)),
            Key::PartMu => number(c.part_mu),
            Key::TrackFull => number(c.track.full_after_s),
            Key::TrackEmpty => number(c.track.empty_after_s),
            Key::StartFrequency => number(c.startup.frequency_hz),
            Key::StartDuty => number(c.startup.duty),
            Key::StartStroke => match c.startup.drive {
                Drive::Stroke { stroke_m } => number(stroke_m * 1e3),
                Drive::Accel { .. } => None,
            },
            Key::StartAccel => match c.startup.drive {
                Drive::Accel { accel_mps2 } => number(accel_mps2),
                Drive::Stroke { .. } => None,
            },
            Key::StartRamp => number(f64::from(c.startup.ramp_cycles)),
            Key::ModbusAddress => number(f64::from(c.line.modbus_address)),
            Key::ModbusBaud => number(f64::from(c.line.baud)),
            Key::ModbusParity => Some(KeyValue::Switch(c.line.parity_even)),
            Key::LinkTimeout => number(f64::from(c.line.link_timeout_ms)),
            Key::ConsoleWatchdog => Some(KeyValue::Switch(c.line.console_watchdog)),
        }
    }

    /// `configuration` with this key set to `value`, checked on its own ([`Key::check`]);
    /// `configuration` is left as it is either way. Setting the start-up stroke or peak
    /// acceleration makes it the start-up drive.
    pub fn set(
        self,
        configuration: &Configuration,
        value: KeyValue,
    ) -> Result<Configuration, ConfigError> {
        self.check(value)?;
        let mut c = *configuration;
        let (number, on) = match value {
            KeyValue::Number(number) => (number, false),
            KeyValue::Switch(on) => (0.0, on),
        };
        // Whole numbers are checked to lie in 0..=max above: the casts are exact.
        match self {
            Key::DacZero => c.dac.zero_code = number as u16,
            Key::DacScale => c.dac.counts_per_mps2 = number,
            Key::DacMargin => c.dac.linear_margin_counts = number as u16,
            Key::PwmFullScale => c.pwm.full_duty_accel_mps2 = number,
            Key::MinFrequency => c.limits.min_frequency_hz = number,
            Key::MaxFrequency => c.limits.max_frequency_hz = number,
            Key::MaxAccel => c.limits.max_accel_mps2 = number,
            Key::MaxStroke => c.limits.max_stroke_m = number / 1e3,
            Key::EncoderResolution => c.encoder.resolution_m = number / 1e6,
            Key::EncoderDirection => c.encoder.reversed = on,
            Key::ClosedLoop => c.closed_loop = on,
            Key::PartMu => c.part_mu = number,
            Key::TrackFull => c.track.full_after_s = number,
            Key::TrackEmpty => c.track.empty_after_s = number,
            Key::StartFrequency => c.startup.frequency_hz = number,
            Key::StartDuty => c.startup.duty = number,
            Key::StartStroke => {
                c.startup.drive = Drive::Stroke {
                    stroke_m: number / 1e3,
                }
            }
            Key::StartAccel => c.startup.drive = Drive::Accel { accel_mps2: number },
            Key::StartRamp => c.startup.ramp_cycles = number as u16,
            Key::ModbusAddress => c.line.modbus_address = number as u8,
            Key::ModbusBaud => c.line.baud = number as u32,
            Key::ModbusParity => c.line.parity_even = on,
            Key::LinkTimeout => c.line.link_timeout_ms = number as u16,
            Key::ConsoleWatchdog => c.line.console_watchdog = on,
        }
        Ok(c)
    }
}
