//! What analog sensors share: an ADC that quantises a voltage, and seeded Gaussian noise.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde::Deserialize;

use crate::error::SimError;

/// An ADC of `bits` bits spanning `min_v` to `max_v`: a voltage reads as the code of the step it
/// falls in (floor), clamped to the range; a code reads back as its step's midpoint.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AdcConfig {
    pub bits: u32,
    pub min_v: f64,
    pub max_v: f64,
}

impl AdcConfig {
    /// Checks the width (1 to 32 bits) and the range (finite, `max_v` above `min_v`).
    pub fn validate(&self, sensor: &'static str) -> Result<(), SimError> {
        if !(1..=32).contains(&self.bits) {
            return Err(SimError::SensorValue {
                sensor,
                key: "adc.bits",
                value: f64::from(self.bits),
                allowed: "from 1 to 32",
            });
        }
        super::check_value(sensor, "adc.min_v", self.min_v, false)?;
        if !(self.max_v.is_finite() && self.max_v > self.min_v) {
            return Err(SimError::SensorValue {
                sensor,
                key: "adc.max_v",
                value: self.max_v,
                allowed: "finite and above adc.min_v",
            });
        }
        Ok(())
    }

    /// The number of codes, 2^bits.
    fn codes(&self) -> f64 {
        2f64.powi(self.bits as i32)
    }

    /// The width of one code in V.
    pub fn lsb_v(&self) -> f64 {
        (self.max_v - self.min_v) / self.codes()
    }

    /// The code a voltage reads as, saturating at 0 and 2^bits − 1.
    pub fn code(&self, volts: f64) -> u32 {
        let step = ((volts - self.min_v) / self.lsb_v()).floor();
        step.clamp(0.0, self.codes() - 1.0) as u32
    }

    /// The voltage a code stands for: the midpoint of its step.
    pub fn volts(&self, code: u32) -> f64 {
        self.min_v + (f64::from(code) + 0.5) * self.lsb_v()
    }
}

/// Zero-mean Gaussian noise of a given standard deviation from a seeded ChaCha8 stream.
///
/// ChaCha8 and the ziggurat's table steps are integer and IEEE arithmetic, the same everywhere.
/// Its rare wedge and tail steps call exp and ln through num-traits, which the workspace builds
/// with `std` (the platform's maths library): a platform whose exp or ln rounds differently from
/// the one that pinned the stream in `tests/sensors.rs` could differ there, in the last bit.
#[derive(Debug, Clone)]
pub(crate) struct Noise {
    rng: ChaCha8Rng,
    normal: Normal<f64>,
}

impl Noise {
    /// Noise of standard deviation `sigma` (already checked finite and not negative).
    pub(crate) fn new(
        sensor: &'static str,
        key: &'static str,
        sigma: f64,
        seed: u64,
    ) -> Result<Self, SimError> {
        let normal = Normal::new(0.0, sigma).map_err(|_| SimError::SensorValue {
            sensor,
            key,
            value: sigma,
            allowed: "finite and not negative",
        })?;
        Ok(Noise {
            rng: ChaCha8Rng::seed_from_u64(seed),
            normal,
        })
    }

    /// The next noise value.
    pub(crate) fn next(&mut self) -> f64 {
        self.normal.sample(&mut self.rng)
    }
}
