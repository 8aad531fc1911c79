//! The machine's configuration: every per-machine setting a board powers up with, kept on the
//! board in a versioned, CRC-checked record ([`record`]) and edited from the console by key
//! ([`Key`]).
//!
//! The compiled defaults are [`Configuration::DEFAULT`]; a board reads its stored record at
//! power-up and falls back to the defaults, naming why, when the record is missing, corrupt, of
//! another layout or refused. Every value is checked on its own when it is set
//! ([`Key::check`]) and the whole configuration before it is saved or used
//! ([`Configuration::check`]): the start-up settings must run on the machine the configuration
//! describes, and its drive limits must stay inside the output's linear range.

mod keys;
pub mod record;

use core::fmt;

use crate::closed_loop::TrackConfig;
use crate::drive::{DacCalibration, DriveError, PwmCalibration, MACHINE_LIMITS};
use crate::error::Error;
use crate::model::{Friction, STANDARD_GRAVITY_MPS2};
use crate::number::Significant;
use crate::plan::TickClock;
use crate::settings::{plan_waveform, Machine, Settings};
use crate::waveform::Limits;

pub use keys::{Key, KeyValue, ValueKind};

/// How the board's position encoder counts.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct EncoderSetup {
    /// Plate travel per count, m.
    pub resolution_m: f64,
    /// The encoder counts down when the plate moves forward (where a positive command pushes
    /// it): its counts are negated before the closed loop sees them.
    pub reversed: bool,
}

impl EncoderSetup {
    /// 1 µm per count, counting up forward.
    pub const DEFAULT: EncoderSetup = EncoderSetup {
        resolution_m: 1e-6,
        reversed: false,
    };

    /// The plate's position of the centre of count `count`, m, forward positive.
    pub fn position_m(&self, count: i32) -> f64 {
        let forward = if self.reversed {
            -f64::from(count)
        } else {
            f64::from(count)
        };
        (forward + 0.5) * self.resolution_m
    }
}

/// The production line's link: the Modbus RTU port and the link watchdog.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LineSetup {
    /// The board's Modbus slave address, 1 to 247.
    pub modbus_address: u8,
    /// The Modbus port's rate, baud.
    pub baud: u32,
    /// Even parity and one stop bit (8E1, Modbus's default); otherwise no parity and two stop
    /// bits (8N2), so that a character is 11 bits either way.
    pub parity_even: bool,
    /// The longest silence of a link that drives the feeder before a soft stop, ms; 0 turns
    /// the link watchdog off.
    pub link_timeout_ms: u16,
    /// The watchdog watches the console too (a console that starts the feeder must then speak
    /// at least every `link_timeout_ms`).
    pub console_watchdog: bool,
}

impl LineSetup {
    /// Address 1 at 19200 baud 8E1 (Modbus's defaults), the watchdog at 2 s for Modbus and off
    /// for the console.
    pub const DEFAULT: LineSetup = LineSetup {
        modbus_address: 1,
        baud: 19_200,
        parity_even: true,
        link_timeout_ms: 2_000,
        console_watchdog: false,
    };
}

/// Which output stage a board drives; it decides which calibration bounds the drive limits.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum OutputKind {
    Dac,
    Pwm,
}

/// What a board is, fixed when its image is built: what a configuration is checked against.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BoardFacts {
    /// The output's tick clock, on which the start-up waveform must be representable.
    pub clock: TickClock,
    pub output: OutputKind,
    /// The board has a position encoder: the closed loop can run.
    pub encoder: bool,
}

/// Every per-machine setting; see the module documentation.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Configuration {
    /// The analog driver input's calibration (its `max_code` is the converter's, not a setting).
    pub dac: DacCalibration,
    /// The PWM driver input's calibration.
    pub pwm: PwmCalibration,
    /// What the machine can do; every waveform is validated against it.
    pub limits: Limits,
    pub encoder: EncoderSetup,
    /// The closed loop runs where the board has an encoder.
    pub closed_loop: bool,
    /// The part's Coulomb friction coefficient μ on the plate: the feed-rate model and the
    /// closed loop's compensation of the feed.
    pub part_mu: f64,
    /// Track control's hysteresis.
    pub track: TrackConfig,
    /// The operator's settings at power-up.
    pub startup: Settings,
    /// The line's link: Modbus port and link watchdog.
    pub line: LineSetup,
}

impl Configuration {
    /// The compiled defaults: shared's documented calibrations, the machine's limits
    /// ([`MACHINE_LIMITS`]), a 1 µm encoder counting up, the closed loop on, μ = 0.3
    /// ([`Friction::CONFIGURED`]), a track full after 0.5 s blocked and empty after 1 s clear,
    /// [`Settings::DEFAULT`] and [`LineSetup::DEFAULT`].
    pub const DEFAULT: Configuration = Configuration {
        dac: DacCalibration::DEFAULT,
        pwm: PwmCalibration::DEFAULT,
        limits: MACHINE_LIMITS,
        encoder: EncoderSetup::DEFAULT,
        closed_loop: true,
        part_mu: Friction::CONFIGURED.mu,
        track: TrackConfig {
            full_after_s: 0.5,
            empty_after_s: 1.0,
        },
        startup: Settings::DEFAULT,
        line: LineSetup::DEFAULT,
    };

    /// The part's friction, under standard gravity.
    pub const fn friction(&self) -> Friction {
        Friction {
            mu: self.part_mu,
            gravity_mps2: STANDARD_GRAVITY_MPS2,
        }
    }

    /// The closed loop runs on a board with (`encoder`) or without an encoder: it needs one and
    /// the configuration must want it.
    pub const fn loop_runs(&self, encoder: bool) -> bool {
        encoder && self.closed_loop
    }

    /// The peak acceleration the output's linear range reaches, m/s².
    pub const fn linear_limit_mps2(&self, output: OutputKind) -> f64 {
        match output {
            OutputKind::Dac => self.dac.linear_limit_mps2(),
            OutputKind::Pwm => self.pwm.full_duty_accel_mps2,
        }
    }

    /// The machine every waveform is validated for on `board`.
    pub const fn machine(&self, board: &BoardFacts) -> Machine {
        Machine {
            limits: self.limits,
            friction: self.friction(),
            clock: board.clock,
            loop_linear_mps2: if self.loop_runs(board.encoder) {
                Some(self.linear_limit_mps2(board.output))
            } else {
                None
            },
        }
    }

    /// Checks the whole configuration for `board`: every value on its own ([`Key::check`]), the
    /// drive limits inside the output's linear range, the closed loop only with an encoder and
    /// the start-up settings valid on the machine it describes.
    pub fn check(&self, board: &BoardFacts) -> Result<(), ConfigError> {
        for key in Key::ALL {
            if let Some(value) = key.get(self) {
                key.check(value)?;
            }
        }
        self.dac
            .levels(0.0)
            .map_err(|error| ConfigError::new(Key::DacZero, Problem::Drive(error)))?;
        if self.limits.min_frequency_hz >= self.limits.max_frequency_hz {
            return Err(ConfigError::new(
                Key::MaxFrequency,
                Problem::NotAbove {
                    other: Key::MinFrequency,
                },
            ));
        }
        let linear_mps2 = self.linear_limit_mps2(board.output);
        if self.limits.max_accel_mps2 > linear_mps2 {
            return Err(ConfigError::new(
                Key::MaxAccel,
                Problem::BeyondOutput { linear_mps2 },
            ));
        }
        if self.closed_loop && !board.encoder {
            return Err(ConfigError::new(Key::ClosedLoop, Problem::NoEncoder));
        }
        let machine = self.machine(board);
        plan_waveform(
            self.startup.spec(),
            &machine.limits,
            machine.loop_linear_mps2,
            machine.clock,
        )
        .map_err(|error| ConfigError::new(Key::startup(&self.startup), Problem::Startup(error)))?;
        Ok(())
    }
}

impl Default for Configuration {
    fn default() -> Self {
        Configuration::DEFAULT
    }
}

/// Why a configuration value, or a configuration as a whole, was refused.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ConfigError {
    /// The key to change.
    pub key: Key,
    pub problem: Problem,
}

impl ConfigError {
    pub const fn new(key: Key, problem: Problem) -> Self {
        ConfigError { key, problem }
    }
}

/// What is wrong with a configuration value.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Problem {
    /// The value lies outside the key's range (both ends included).
    OutOfRange { value: f64, min: f64, max: f64 },
    /// A count or a code has a fractional part.
    NotWhole { value: f64 },
    /// The output stage refuses the calibration.
    Drive(DriveError),
    /// The value must lie above the other key's.
    NotAbove { other: Key },
    /// The drive limit lies beyond the output's linear range.
    BeyondOutput { linear_mps2: f64 },
    /// The closed loop is on but the board has no encoder.
    NoEncoder,
    /// The start-up settings are refused on the machine the configuration describes.
    Startup(Error),
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: ", self.key.keyword())?;
        match self.problem {
            Problem::OutOfRange { value, min, max } => write!(
                f,
                "{} lies outside {} to {}{}",
                Significant(value),
                Significant(min),
                Significant(max),
                self.key.unit_suffix()
            ),
            Problem::NotWhole { value } => {
                write!(f, "{} is not a whole number", Significant(value))
            }
            Problem::Drive(error) => write!(f, "{}", error),
            Problem::NotAbove { other } => {
                write!(f, "must lie above {}", other.keyword())
            }
            Problem::BeyondOutput { linear_mps2 } => write!(
                f,
                "the output's linear range reaches only {} m/s2: lower it or change the output's \
                 calibration",
                Significant(linear_mps2)
            ),
            Problem::NoEncoder => f.write_str("this board has no encoder: set closed_loop off"),
            Problem::Startup(error) => write!(f, "the start-up settings are refused: {}", error),
        }
    }
}

impl core::error::Error for ConfigError {}

#[cfg(test)]
mod tests;
