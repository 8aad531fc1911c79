//! Incremental encoder on the plate: an exact, noiseless count of plate position.

use serde::Deserialize;

use super::{check_motion, check_time, check_value, PlateMotion};
use crate::error::SimError;

const SENSOR: &str = "encoder";

/// Count resolution and an optional index mark.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EncoderConfig {
    /// Plate travel per count in m (e.g. 1e-6).
    pub resolution_m: f64,
    /// Position of the index mark in m; it lies in the count at `index_m`.
    #[serde(default)]
    pub index_m: Option<f64>,
    /// Mounted the other way round: it counts down as the plate moves forward, the count at
    /// `x` being the forward one's at `−x`.
    #[serde(default)]
    pub reversed: bool,
}

impl EncoderConfig {
    /// The count at `position_m`, `None` beyond 2^53 counts.
    pub fn count(&self, position_m: f64) -> Option<i64> {
        count_of(self.along(position_m), self.resolution_m)
    }

    /// `position_m` along the encoder's scale.
    fn along(&self, position_m: f64) -> f64 {
        if self.reversed {
            -position_m
        } else {
            position_m
        }
    }

    pub fn validate(&self) -> Result<(), SimError> {
        check_value(SENSOR, "resolution_m", self.resolution_m, true)?;
        if let Some(index_m) = self.index_m {
            if count_of(index_m, self.resolution_m).is_none() {
                return Err(SimError::SensorValue {
                    sensor: SENSOR,
                    key: "index_m",
                    value: index_m,
                    allowed: "finite and within 2^53 counts of zero",
                });
            }
        }
        Ok(())
    }
}

/// One sample tick's reading.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct EncoderReading {
    /// `floor(x / resolution_m)`: count·resolution ≤ x < (count + 1)·resolution.
    pub count: i64,
    /// The count entered the index count since the previous tick (never on the first tick).
    pub index: bool,
}

/// An encoder sampled at increasing ticks.
#[derive(Debug, Clone)]
pub struct Encoder {
    config: EncoderConfig,
    index_count: Option<i64>,
    previous: Option<(f64, i64)>,
}

impl Encoder {
    pub fn new(config: EncoderConfig) -> Result<Self, SimError> {
        config.validate()?;
        let index_count = config.index_m.and_then(|index_m| config.count(index_m));
        Ok(Encoder {
            config,
            index_count,
            previous: None,
        })
    }

    /// Reads the plate at `t_s`, after the previous tick.
    pub fn sample(
        &mut self,
        plate: &impl PlateMotion,
        t_s: f64,
    ) -> Result<EncoderReading, SimError> {
        check_time(SENSOR, t_s, self.previous.map(|(t, _)| t))?;
        let position_m = check_motion(SENSOR, t_s, plate.position_m(t_s))?;
        let count = self.config.count(position_m).ok_or(SimError::SensorInput {
            sensor: SENSOR,
            t_s,
            reason: "the position is beyond 2^53 counts",
        })?;
        let index = match (self.index_count, self.previous) {
            (Some(mark), Some((_, before))) => {
                (before < mark && mark <= count) || (count <= mark && mark < before)
            }
            _ => false,
        };
        self.previous = Some((t_s, count));
        Ok(EncoderReading { count, index })
    }
}

/// `floor(position / resolution)`, corrected by one count where the division rounded across an
/// integer, so that count·resolution ≤ position < (count + 1)·resolution holds in f64; `None`
/// beyond 2^53 counts (or for a position that is not finite), where counts are no longer exact.
fn count_of(position_m: f64, resolution_m: f64) -> Option<i64> {
    let mut count = (position_m / resolution_m).floor();
    if count * resolution_m > position_m {
        count -= 1.0;
    } else if (count + 1.0) * resolution_m <= position_m {
        count += 1.0;
    }
    (count.abs() < 9_007_199_254_740_992.0).then_some(count as i64)
}
