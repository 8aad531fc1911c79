//! A plant file: the plate's keys ([`PlateParams`]) at the top level and the sensors it carries
//! in an optional `[sensors]` table ([`SensorsConfig`]). Unknown keys are refused in either.
//! Every refusal names the key, with its table, and the line and column that hold the fault.

use std::ops::Range;
use std::path::Path;

use serde::Deserialize;
use toml::de::{DeTable, DeValue, Deserializer, ValueDeserializer};

use crate::error::{out_of_range, PlantPlace, SimError};
use crate::sensors::SensorsConfig;

use super::params::PlateParams;

/// The table a plant file lists its sensors in.
const SENSORS: &str = "sensors";

/// The plate and its sensors, as a plant file describes them.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PlantFile {
    pub plate: PlateParams,
    pub sensors: SensorsConfig,
}

impl PlantFile {
    /// Parses and validates a plant file's text; `source` names it in errors.
    pub fn from_toml_str(source: &str, text: &str) -> Result<Self, SimError> {
        let mut document = match DeTable::parse(text) {
            Ok(document) => document,
            Err(error) => {
                let (partial, _) = DeTable::parse_recoverable(text);
                return Err(Entries::of(text, partial.get_ref()).refuse(source, &error));
            }
        };
        let entries = Entries::of(text, document.get_ref());
        let refuse = |error: toml::de::Error| entries.refuse(source, &error);
        let sensors = document.get_mut().remove(SENSORS);
        let plate = PlateParams::deserialize(Deserializer::from(document)).map_err(refuse)?;
        let sensors = match sensors {
            None => SensorsConfig::default(),
            Some(value) => {
                SensorsConfig::deserialize(ValueDeserializer::from(value)).map_err(refuse)?
            }
        };
        plate
            .validate()
            .and_then(|()| sensors.validate())
            .map_err(|error| entries.refuse_value(source, error))?;
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

impl PlateParams {
    /// Parses and validates a plant file's text (its `[sensors]` table, if any, too).
    pub fn from_toml_str(text: &str) -> Result<Self, SimError> {
        Ok(PlantFile::from_toml_str("TOML text", text)?.plate)
    }

    /// Reads, parses and validates the plant file at `path` (its `[sensors]` table, if any, too).
    pub fn from_path(path: &Path) -> Result<Self, SimError> {
        Ok(PlantFile::from_path(path)?.plate)
    }
}

/// One key of a plant file, at any depth, where the text holds it.
struct Entry {
    /// The key's path from the top level: `["sensors", "accelerometer", "adc", "bits"]`.
    path: Vec<String>,
    /// How many of the path's first keys a `[table]` header names.
    header_depth: usize,
    key: Range<usize>,
    value: Range<usize>,
}

impl Entry {
    /// Whether the entry is a table a `[header]` opens.
    fn is_header(&self) -> bool {
        !self.path.is_empty() && self.header_depth == self.path.len()
    }

    /// The key as the file writes it: `[sensors.encoder] resolution_m`, `mass_kg`,
    /// `[sensors.encoder]` for a table opened by its header.
    fn name(&self) -> String {
        let (table, key) = self.path.split_at(self.header_depth);
        match (table.is_empty(), key.is_empty()) {
            (true, _) => key.join("."),
            (false, true) => format!("[{}]", table.join(".")),
            (false, false) => format!("[{}] {}", table.join("."), key.join(".")),
        }
    }
}

/// Every key of a plant file with its place, to name the key and the line of a fault.
struct Entries<'t> {
    text: &'t str,
    entries: Vec<Entry>,
}

impl<'t> Entries<'t> {
    fn of(text: &'t str, document: &DeTable) -> Self {
        let mut entries = Vec::new();
        collect(text, document, &[], 0, &mut entries);
        Entries { text, entries }
    }

    /// The entry a fault at byte `at` belongs to: the narrowest key or value that holds it, or
    /// else the last key before it on its line (a syntax error after a key's `=`).
    fn at(&self, at: usize) -> Option<&Entry> {
        let holds = |range: &Range<usize>| range.contains(&at) || range.start == at;
        self.entries
            .iter()
            .flat_map(|entry| {
                [&entry.key, &entry.value]
                    .into_iter()
                    .filter(|range| holds(range))
                    .map(move |range| (range.len(), entry))
            })
            .min_by_key(|(len, _)| *len)
            .map(|(_, entry)| entry)
            .or_else(|| {
                self.entries
                    .iter()
                    .filter(|entry| {
                        self.text
                            .get(entry.key.start..at)
                            .is_some_and(|between| !between.contains('\n'))
                    })
                    .max_by_key(|entry| entry.key.start)
            })
    }

    /// The bare key a fault's span spells where no entry holds it (a key written twice), under
    /// the last `[table]` header before it.
    fn written_key(&self, span: Range<usize>) -> Option<String> {
        let key = self.text.get(span.clone())?;
        let bare = |c: char| c.is_ascii_alphanumeric() || c == '_' || c == '-';
        if key.is_empty() || !key.chars().all(bare) {
            return None;
        }
        let table = self
            .entries
            .iter()
            .filter(|entry| entry.is_header() && entry.value.start <= span.start)
            .max_by_key(|entry| entry.value.start);
        Some(match table {
            Some(table) => format!("[{}] {key}", table.path.join(".")),
            None => key.to_owned(),
        })
    }

    /// A parser's or a deserializer's refusal, at its key and place.
    fn refuse(&self, source: &str, error: &toml::de::Error) -> SimError {
        let place = error.span().map(|span| {
            let (line, column) = line_column(self.text, span.start);
            PlantPlace {
                line,
                column,
                key: self
                    .at(span.start)
                    .map(Entry::name)
                    .or_else(|| self.written_key(span)),
            }
        });
        SimError::PlantFile {
            source: source.to_owned(),
            place,
            reason: error.message().to_owned(),
        }
    }

    /// A value out of its range, at its key's value; a value the file does not write (a key at
    /// its default) keeps its refusal, which names the key.
    fn refuse_value(&self, source: &str, error: SimError) -> SimError {
        let (path, value, allowed) = match &error {
            SimError::PlantValue {
                key,
                value,
                allowed,
            } => (vec![*key], *value, *allowed),
            SimError::SensorValue {
                sensor,
                key,
                value,
                allowed,
            } => {
                let mut path = vec![SENSORS, sensor];
                path.extend(key.split('.'));
                (path, *value, *allowed)
            }
            _ => return error,
        };
        let Some(entry) = self.entries.iter().find(|entry| entry.path == path) else {
            return error;
        };
        let (line, column) = line_column(self.text, entry.value.start);
        SimError::PlantFile {
            source: source.to_owned(),
            place: Some(PlantPlace {
                line,
                column,
                key: Some(entry.name()),
            }),
            reason: out_of_range(allowed, value),
        }
    }
}

/// Lists every key of `table` and of the tables within it, below `prefix` (not the keys a
/// syntax error leaves without text).
fn collect(
    text: &str,
    table: &DeTable,
    prefix: &[String],
    header_depth: usize,
    entries: &mut Vec<Entry>,
) {
    for (key, value) in table.iter().filter(|(key, _)| !key.span().is_empty()) {
        let mut path = prefix.to_vec();
        path.push(key.get_ref().to_string());
        let is_header = matches!(value.get_ref(), DeValue::Table(_))
            && text
                .get(value.span().start..)
                .is_some_and(|rest| rest.starts_with('['));
        let depth = if is_header { path.len() } else { header_depth };
        if let DeValue::Table(inner) = value.get_ref() {
            collect(text, inner, &path, depth, entries);
        }
        entries.push(Entry {
            path,
            header_depth: depth,
            key: key.span(),
            value: value.span(),
        });
    }
}

/// The line and column, both from 1 and the column in characters, of byte `at` of `text`.
fn line_column(text: &str, at: usize) -> (usize, usize) {
    let before = text.get(..at).unwrap_or(text);
    let line_start = before.rfind('\n').map_or(0, |newline| newline + 1);
    (
        before.matches('\n').count() + 1,
        before[line_start..].chars().count() + 1,
    )
}
