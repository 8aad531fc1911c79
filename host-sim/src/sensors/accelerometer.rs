//! Accelerometer on the plate: its acceleration through a first-order low-pass, plus seeded
//! noise, scaled to volts and read through an ADC.
//!
//! The low-pass is the exact discretisation of the lag τ·ẏ = u − y between samples with the input
//! held at its sampled value (zero-order hold): y_k = u_{k−1} + (y_{k−1} − u_{k−1})·exp(−Δt/τ),
//! τ = 1/(2π·f_bw), starting at rest (y_0 = 0). It is exact for an acceleration that is constant
//! between samples; otherwise the sample rate must resolve the acceleration's changes.

use core::f64::consts::TAU;

use serde::Deserialize;

use super::signal::{AdcConfig, Noise};
use super::{check_motion, check_sigma, check_time, check_value, PlateMotion};
use crate::error::SimError;

const SENSOR: &str = "accelerometer";

/// Bandwidth, noise, sensitivity and the ADC that reads the sensor.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AccelerometerConfig {
    /// −3 dB bandwidth of the sensor's first-order low-pass in Hz.
    pub bandwidth_hz: f64,
    /// Standard deviation of the output noise in m/s² (0 for none).
    #[serde(default)]
    pub noise_mps2: f64,
    /// Seed of the noise stream.
    #[serde(default)]
    pub seed: u64,
    /// Output per acceleration in V/(m/s²), non-zero (0.3 V/g ≈ 0.0306 V/(m/s²)).
    pub sensitivity_v_per_mps2: f64,
    pub adc: AdcConfig,
}

impl AccelerometerConfig {
    pub fn validate(&self) -> Result<(), SimError> {
        check_value(SENSOR, "bandwidth_hz", self.bandwidth_hz, true)?;
        check_sigma(SENSOR, "noise_mps2", self.noise_mps2)?;
        check_value(
            SENSOR,
            "sensitivity_v_per_mps2",
            self.sensitivity_v_per_mps2,
            false,
        )?;
        if self.sensitivity_v_per_mps2 == 0.0 {
            return Err(SimError::SensorValue {
                sensor: SENSOR,
                key: "sensitivity_v_per_mps2",
                value: 0.0,
                allowed: "finite and non-zero",
            });
        }
        self.adc.validate(SENSOR)
    }

    /// The low-pass time constant τ = 1/(2π·f_bw) in s.
    pub fn time_constant_s(&self) -> f64 {
        1.0 / (TAU * self.bandwidth_hz)
    }
}

/// One sample's reading.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AccelerometerReading {
    /// The filtered acceleration before noise and ADC, in m/s².
    pub filtered_mps2: f64,
    /// The ADC code.
    pub code: u32,
    /// The acceleration the firmware computes from the code: V(code) / sensitivity.
    pub accel_mps2: f64,
}

/// An accelerometer sampled at increasing times.
#[derive(Debug, Clone)]
pub struct Accelerometer {
    config: AccelerometerConfig,
    noise: Noise,
    /// The previous sample's time and input, and the filter state.
    previous: Option<(f64, f64)>,
    filtered_mps2: f64,
}

impl Accelerometer {
    pub fn new(config: AccelerometerConfig) -> Result<Self, SimError> {
        config.validate()?;
        Ok(Accelerometer {
            noise: Noise::new(SENSOR, "noise_mps2", config.noise_mps2, config.seed)?,
            config,
            previous: None,
            filtered_mps2: 0.0,
        })
    }

    /// Reads the plate at `t_s`, after the previous sample.
    pub fn sample(
        &mut self,
        plate: &impl PlateMotion,
        t_s: f64,
    ) -> Result<AccelerometerReading, SimError> {
        check_time(SENSOR, t_s, self.previous.map(|(t, _)| t))?;
        let input_mps2 = check_motion(SENSOR, t_s, plate.accel_mps2(t_s))?;
        if let Some((previous_t_s, held_mps2)) = self.previous {
            // libm's exp, not the platform's: the same readings on every platform.
            let decay = libm::exp(-(t_s - previous_t_s) / self.config.time_constant_s());
            self.filtered_mps2 = held_mps2 + (self.filtered_mps2 - held_mps2) * decay;
        }
        self.previous = Some((t_s, input_mps2));
        let sensitivity = self.config.sensitivity_v_per_mps2;
        let code = self
            .config
            .adc
            .code(sensitivity * (self.filtered_mps2 + self.noise.next()));
        Ok(AccelerometerReading {
            filtered_mps2: self.filtered_mps2,
            code,
            accel_mps2: self.config.adc.volts(code) / sensitivity,
        })
    }
}
