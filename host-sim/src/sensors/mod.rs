//! Sensors of the simulated plate, read as the firmware would read them.
//!
//! Each sensor samples a motion source at the times it is asked for: the plate through
//! [`PlateMotion`], a part through [`PartMotion`] (any `Fn(f64) -> f64` of time in s is one, and
//! so is a [`SampledPart`]).
//! [`encoder`] counts plate position exactly; [`lvdt`] is the analog position alternative;
//! [`accelerometer`] is the plate's acceleration through a first-order low-pass; [`light_barrier`]
//! finds when a part passes a point of the track. Noise is seeded (ChaCha8 with a normal
//! distribution), so the same seed gives the same readings bit for bit. [`SensorsConfig`] is the
//! body of a `[sensors]` table.

pub mod accelerometer;
pub mod encoder;
pub mod light_barrier;
pub mod lvdt;
pub mod signal;

use serde::Deserialize;

use crate::error::SimError;

pub use accelerometer::{Accelerometer, AccelerometerConfig, AccelerometerReading};
pub use encoder::{Encoder, EncoderConfig, EncoderReading};
pub use light_barrier::{BarrierEdge, LightBarrier, LightBarrierConfig, SampledPart};
pub use lvdt::{Lvdt, LvdtConfig, LvdtReading};
pub use signal::AdcConfig;

/// The plate's motion along the track, at any time t in s.
pub trait PlateMotion {
    fn position_m(&self, t_s: f64) -> f64;
    fn velocity_mps(&self, t_s: f64) -> f64;
    fn accel_mps2(&self, t_s: f64) -> f64;
}

/// The position of a part's front along the track, at any time t in s.
pub trait PartMotion {
    fn position_m(&self, t_s: f64) -> f64;
}

impl<F: Fn(f64) -> f64> PartMotion for F {
    fn position_m(&self, t_s: f64) -> f64 {
        self(t_s)
    }
}

/// Every sensor a plant can carry; each one is optional.
#[derive(Debug, Clone, PartialEq, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SensorsConfig {
    pub encoder: Option<EncoderConfig>,
    pub lvdt: Option<LvdtConfig>,
    pub accelerometer: Option<AccelerometerConfig>,
    pub light_barrier: Option<LightBarrierConfig>,
}

impl SensorsConfig {
    /// Reads and validates the body of a `[sensors]` table; `source` names it in errors.
    pub fn from_toml_str(source: &str, text: &str) -> Result<Self, SimError> {
        let config: SensorsConfig = toml::from_str(text).map_err(|error| SimError::SensorFile {
            source: source.to_owned(),
            reason: error.message().to_owned(),
        })?;
        config.validate()?;
        Ok(config)
    }

    /// Checks every present sensor's values.
    pub fn validate(&self) -> Result<(), SimError> {
        if let Some(encoder) = &self.encoder {
            encoder.validate()?;
        }
        if let Some(lvdt) = &self.lvdt {
            lvdt.validate()?;
        }
        if let Some(accelerometer) = &self.accelerometer {
            accelerometer.validate()?;
        }
        if let Some(barrier) = &self.light_barrier {
            barrier.validate()?;
        }
        Ok(())
    }
}

/// Refuses a value that is not finite and, when `positive`, not greater than zero.
pub(crate) fn check_value(
    sensor: &'static str,
    key: &'static str,
    value: f64,
    positive: bool,
) -> Result<(), SimError> {
    if positive {
        check_allowed(
            sensor,
            key,
            value,
            value > 0.0,
            "finite and greater than zero",
        )
    } else {
        check_allowed(sensor, key, value, true, "finite")
    }
}

/// Refuses a standard deviation that is not finite or is negative (zero turns the noise off).
pub(crate) fn check_sigma(
    sensor: &'static str,
    key: &'static str,
    value: f64,
) -> Result<(), SimError> {
    check_allowed(sensor, key, value, value >= 0.0, "finite and not negative")
}

/// Refuses a value that is not finite or not `within` what the key allows, `allowed` in words.
fn check_allowed(
    sensor: &'static str,
    key: &'static str,
    value: f64,
    within: bool,
    allowed: &'static str,
) -> Result<(), SimError> {
    if value.is_finite() && within {
        Ok(())
    } else {
        Err(SimError::SensorValue {
            sensor,
            key,
            value,
            allowed,
        })
    }
}

/// Refuses a sample time that is not finite or not after the previous one.
pub(crate) fn check_time(
    sensor: &'static str,
    t_s: f64,
    previous_t_s: Option<f64>,
) -> Result<(), SimError> {
    let reason = if !t_s.is_finite() {
        "the sample time is not finite"
    } else if previous_t_s.is_some_and(|previous| t_s <= previous) {
        "the sample time is not after the previous one"
    } else {
        return Ok(());
    };
    Err(SimError::SensorInput {
        sensor,
        t_s,
        reason,
    })
}

/// Refuses a motion value that is not finite.
pub(crate) fn check_motion(sensor: &'static str, t_s: f64, value: f64) -> Result<f64, SimError> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(SimError::SensorInput {
            sensor,
            t_s,
            reason: "the motion value is not finite",
        })
    }
}
