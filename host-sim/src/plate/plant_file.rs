//! A plant file: the plate's keys ([`PlateParams`]) at the top level and the sensors it carries
//! in an optional `[sensors]` table ([`SensorsConfig`]). Unknown keys are refused in either.

use std::path::Path;

use serde::Deserialize;

use crate::error::SimError;
use crate::sensors::SensorsConfig;

use super::params::PlateParams;

/// The plate and its sensors, as a plant file describes them.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PlantFile {
    pub plate: PlateParams,
    pub sensors: SensorsConfig,
}

impl PlantFile {
    /// Parses and validates a plant file's text; `source` names it in errors.
    pub fn from_toml_str(source: &str, text: &str) -> Result<Self, SimError> {
        let plant_error = |reason: String| SimError::PlantFile {
            source: source.to_owned(),
            reason,
        };
        let mut table: toml::Table =
            toml::from_str(text).map_err(|error| plant_error(error.message().to_owned()))?;
        let sensors = match table.remove("sensors") {
            None => SensorsConfig::default(),
            Some(value) => {
                let sensors =
                    SensorsConfig::deserialize(value).map_err(|error| SimError::SensorFile {
                        source: source.to_owned(),
                        reason: error.message().to_owned(),
                    })?;
                sensors.validate()?;
                sensors
            }
        };
        let plate = PlateParams::deserialize(toml::Value::Table(table))
            .map_err(|error| plant_error(error.message().to_owned()))?;
        plate.validate()?;
        Ok(PlantFile { plate, sensors })
    }

    /// Reads, parses and validates the plant file at `path`.
    pub fn from_path(path: &Path) -> Result<Self, SimError> {
        let source = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|error| SimError::Input {
            source: source.clone(),
            reason: error.to_string(),
        })?;
        Self::from_toml_str(&source, &text)
    }
}
