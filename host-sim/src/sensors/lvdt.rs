//! Analog LVDT on the plate: voltage = gain·(x + noise) + offset, read through an ADC.

use serde::Deserialize;

use super::signal::{AdcConfig, Noise};
use super::{check_motion, check_sigma, check_time, check_value, PlateMotion};
use crate::error::SimError;

const SENSOR: &str = "lvdt";

/// Gain, offset, seeded position noise and the ADC that reads the LVDT's conditioner.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LvdtConfig {
    /// Conditioner output per plate position in V/m (non-zero; negative for a reversed mount).
    pub gain_v_per_m: f64,
    /// Conditioner output at position zero in V.
    #[serde(default)]
    pub offset_v: f64,
    /// Standard deviation of the position noise in m (0 for none).
    #[serde(default)]
    pub noise_m: f64,
    /// Seed of the noise stream.
    #[serde(default)]
    pub seed: u64,
    pub adc: AdcConfig,
}

impl LvdtConfig {
    pub fn validate(&self) -> Result<(), SimError> {
        check_value(SENSOR, "gain_v_per_m", self.gain_v_per_m, false)?;
        if self.gain_v_per_m == 0.0 {
            return Err(SimError::SensorValue {
                sensor: SENSOR,
                key: "gain_v_per_m",
                value: self.gain_v_per_m,
                allowed: "finite and non-zero",
            });
        }
        check_value(SENSOR, "offset_v", self.offset_v, false)?;
        check_sigma(SENSOR, "noise_m", self.noise_m)?;
        self.adc.validate(SENSOR)
    }
}

/// One sample's reading.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LvdtReading {
    /// The ADC code.
    pub code: u32,
    /// The position the firmware computes from the code: (V(code) − offset) / gain.
    pub position_m: f64,
}

/// An LVDT sampled at increasing times.
#[derive(Debug, Clone)]
pub struct Lvdt {
    config: LvdtConfig,
    noise: Noise,
    previous_t_s: Option<f64>,
}

impl Lvdt {
    pub fn new(config: LvdtConfig) -> Result<Self, SimError> {
        config.validate()?;
        Ok(Lvdt {
            noise: Noise::new(SENSOR, "noise_m", config.noise_m, config.seed)?,
            config,
            previous_t_s: None,
        })
    }

    /// Reads the plate at `t_s`, after the previous sample.
    pub fn sample(&mut self, plate: &impl PlateMotion, t_s: f64) -> Result<LvdtReading, SimError> {
        check_time(SENSOR, t_s, self.previous_t_s)?;
        let position_m = check_motion(SENSOR, t_s, plate.position_m(t_s))?;
        self.previous_t_s = Some(t_s);
        let volts =
            self.config.gain_v_per_m * (position_m + self.noise.next()) + self.config.offset_v;
        let code = self.config.adc.code(volts);
        Ok(LvdtReading {
            code,
            position_m: (self.config.adc.volts(code) - self.config.offset_v)
                / self.config.gain_v_per_m,
        })
    }
}
