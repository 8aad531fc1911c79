//! Telemetry: one [`Record`] per cycle, its line on the console's link and its parser.
//!
//! A board streams records between its replies once `telemetry on` asks for them. A record's line
//! starts with [`MARKER`] (a reply starts with `OK` or `ERR`), then its fields, one word each, in
//! [`COLUMNS`]' order, `-` for a field the board does not have (no closed loop, no part sensor):
//!
//! ```text
//! T 1234 24.68 running feeding 1.2 1280.4 1.0012 0.9987 0.0123 19938 4236 3.1 room 12 none
//! ```
//!
//! The link carries what it can: a board writes a line only when the link has had time to carry
//! the last ones within [`LINK_SHARE`] of its capacity ([`Pacer`]), so the lines of the cycles
//! between are left out, and a reply never waits for more than the one line being sent.

use core::fmt::{self, Write};

use crate::closed_loop::{mean_position_m, PositionSample, Stage, TrackState};
use crate::number::Fixed;
use crate::scheduler::Phase;
use crate::supervisor::Fault;

/// The start of a telemetry line.
pub const MARKER: &str = "T ";

/// A column of the record: its name and its unit (empty for a count or a word).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Column {
    pub name: &'static str,
    pub unit: &'static str,
}

impl Column {
    /// Writes the column's name in a recording's header: the name, then `_` and the unit
    /// (`mean_um`, `bias_mps2`).
    pub fn write_header(&self, out: &mut impl Write) -> fmt::Result {
        out.write_str(self.name)?;
        if !self.unit.is_empty() {
            out.write_char('_')?;
            out.write_str(self.unit)?;
        }
        Ok(())
    }
}

const fn column(name: &'static str, unit: &'static str) -> Column {
    Column { name, unit }
}

/// The record's fields in their order on the line and in a recording's header.
pub const COLUMNS: [Column; 15] = [
    column("cycle", ""),
    column("uptime", "s"),
    column("phase", ""),
    column("loop", ""),
    column("mean", "um"),
    column("peak", "um"),
    column("trim_pos", ""),
    column("trim_neg", ""),
    column("bias", "mps2"),
    column("slack", "ticks"),
    column("edge_work", "cycles"),
    column("cpu_load", "pct"),
    column("track", ""),
    column("parts", "per_min"),
    column("fault", ""),
];

/// The longest line a record makes, marker included, without its terminator.
pub const MAX_LINE_BYTES: usize = 160;

/// The share of the link's capacity that telemetry may take: the rest is the replies'.
pub const LINK_SHARE: f64 = 0.5;

/// One cycle as the board saw it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Record {
    /// The cycle (or idle period) begun last, counted from power-up.
    pub cycle: u64,
    pub uptime_ms: u64,
    pub phase: Phase,
    /// The closed loop's stage, on a board that runs it.
    pub stage: Option<Stage>,
    /// The plate's mean position over the last cycle the closed loop measured, m.
    pub mean_m: Option<f64>,
    /// The plate's largest distance from its centre over that cycle, m.
    pub peak_m: Option<f64>,
    /// The closed loop's factors on the `+a` and `−a` levels and its bias, m/s², for the cycle
    /// it decided last.
    pub trim_positive: Option<f64>,
    pub trim_negative: Option<f64>,
    pub bias_mps2: Option<f64>,
    /// The least preload slack over the cycle, in output ticks, where the stage reads it.
    pub slack_ticks: Option<u32>,
    /// The most CPU cycles from an edge to its preload over the last report period.
    pub edge_work_cycles: Option<u32>,
    /// The edges' share of the CPU over the last report period, %.
    pub cpu_load_pct: Option<f64>,
    pub track: Option<TrackState>,
    pub parts_per_minute: Option<f64>,
    /// The latched fault.
    pub fault: Option<Fault>,
}

impl Record {
    /// The record with only what every board has.
    pub const fn new(cycle: u64, uptime_ms: u64, phase: Phase, fault: Option<Fault>) -> Self {
        Record {
            cycle,
            uptime_ms,
            phase,
            stage: None,
            mean_m: None,
            peak_m: None,
            trim_positive: None,
            trim_negative: None,
            bias_mps2: None,
            slack_ticks: None,
            edge_work_cycles: None,
            cpu_load_pct: None,
            track: None,
            parts_per_minute: None,
            fault,
        }
    }

    /// Writes the record's line, marker first, without a terminator.
    pub fn write_line(&self, out: &mut impl Write) -> fmt::Result {
        out.write_str(MARKER)?;
        self.write_fields(out, ' ')
    }

    /// Writes the fields separated by `separator` (a recording's row with `,`).
    pub fn write_fields(&self, out: &mut impl Write, separator: char) -> fmt::Result {
        let fixed = |value: Option<f64>, scale: f64, decimals: u32| {
            value.map(|value| Fixed {
                value: value * scale,
                decimals,
            })
        };
        let fields: [&dyn OptionalField; 15] = [
            &Some(self.cycle),
            &Some(Fixed {
                value: self.uptime_ms as f64 / 1e3,
                decimals: 3,
            }),
            &Some(self.phase.name()),
            &self.stage.map(Stage::name),
            &fixed(self.mean_m, 1e6, 1),
            &fixed(self.peak_m, 1e6, 1),
            &fixed(self.trim_positive, 1.0, 5),
            &fixed(self.trim_negative, 1.0, 5),
            &fixed(self.bias_mps2, 1.0, 4),
            &self.slack_ticks,
            &self.edge_work_cycles,
            &fixed(self.cpu_load_pct, 1.0, 1),
            &self.track.map(TrackState::name),
            &fixed(self.parts_per_minute, 1.0, 1),
            &Some(self.fault.map_or("none", Fault::name)),
        ];
        for (index, field) in fields.iter().enumerate() {
            if index > 0 {
                out.write_char(separator)?;
            }
            field.write(out)?;
        }
        Ok(())
    }

    /// The record of a telemetry line (with or without its marker and terminator).
    pub fn parse_line(line: &str) -> Result<Record, ParseError> {
        let line = line.trim_end_matches(['\r', '\n']);
        let fields = line.strip_prefix(MARKER).unwrap_or(line);
        let mut words = fields.split(' ');
        let mut next = |column: usize| {
            words
                .next()
                .filter(|word| !word.is_empty())
                .ok_or(ParseError { column })
        };
        let record = Record {
            cycle: whole(next(0)?, 0)?.ok_or(ParseError { column: 0 })?,
            uptime_ms: {
                let seconds = number(next(1)?, 1)?.ok_or(ParseError { column: 1 })?;
                libm::round(seconds * 1e3) as u64
            },
            phase: word(next(2)?, 2, &PHASES, Phase::name)?.ok_or(ParseError { column: 2 })?,
            stage: word(next(3)?, 3, &STAGES, Stage::name)?,
            mean_m: number(next(4)?, 4)?.map(|um| um * 1e-6),
            peak_m: number(next(5)?, 5)?.map(|um| um * 1e-6),
            trim_positive: number(next(6)?, 6)?,
            trim_negative: number(next(7)?, 7)?,
            bias_mps2: number(next(8)?, 8)?,
            slack_ticks: whole(next(9)?, 9)?,
            edge_work_cycles: whole(next(10)?, 10)?,
            cpu_load_pct: number(next(11)?, 11)?,
            track: word(next(12)?, 12, &TRACK_STATES, TrackState::name)?,
            parts_per_minute: number(next(13)?, 13)?,
            fault: {
                let text = next(14)?;
                match text {
                    "none" => None,
                    _ => Some(
                        word(text, 14, &FAULTS, Fault::name)?.ok_or(ParseError { column: 14 })?,
                    ),
                }
            },
        };
        match words.next() {
            Some(_) => Err(ParseError {
                column: COLUMNS.len(),
            }),
            None => Ok(record),
        }
    }
}

/// The plate over one cycle, from the capture at its start (`start`) through the samples
/// `during` it to the capture at its end (`end`): its mean position (trapezoids, as the closed
/// loop measures it, [`mean_position_m`]) and its farthest distance from the centre, m.
pub fn cycle_positions(
    start: PositionSample,
    during: &[PositionSample],
    end: PositionSample,
) -> (f64, f64) {
    let peak_m = during
        .iter()
        .chain([&start, &end])
        .fold(0.0_f64, |peak, sample| {
            peak.max(libm::fabs(sample.position_m))
        });
    (mean_position_m(start, during, end), peak_m)
}

/// A field that may be absent (`-`).
trait OptionalField {
    fn write(&self, out: &mut dyn Write) -> fmt::Result;
}

impl<T: fmt::Display> OptionalField for Option<T> {
    fn write(&self, out: &mut dyn Write) -> fmt::Result {
        match self {
            Some(value) => write!(out, "{}", value),
            None => out.write_char('-'),
        }
    }
}

/// A line that is no telemetry record: the column whose word is missing or unreadable
/// ([`COLUMNS`]' length: words after the last column).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ParseError {
    pub column: usize,
}

impl fmt::Display for ParseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match COLUMNS.get(self.column) {
            Some(column) => write!(f, "telemetry line: no valid {}", column.name),
            None => f.write_str("telemetry line: words after the last column"),
        }
    }
}

const PHASES: [Phase; 4] = [
    Phase::Stopped,
    Phase::Starting,
    Phase::Running,
    Phase::Stopping,
];
const STAGES: [Stage; 7] = Stage::ALL;
const TRACK_STATES: [TrackState; 2] = [TrackState::Empty, TrackState::Full];
const FAULTS: [Fault; 6] = Fault::ALL;

/// The one of `all` whose `name` is `text`, `None` for `-`.
fn word<T: Copy>(
    text: &str,
    column: usize,
    all: &[T],
    name: fn(T) -> &'static str,
) -> Result<Option<T>, ParseError> {
    if text == "-" {
        return Ok(None);
    }
    all.iter()
        .copied()
        .find(|&item| name(item) == text)
        .map(Some)
        .ok_or(ParseError { column })
}

fn number(text: &str, column: usize) -> Result<Option<f64>, ParseError> {
    if text == "-" {
        return Ok(None);
    }
    text.parse::<f64>()
        .ok()
        .filter(|value| value.is_finite())
        .map(Some)
        .ok_or(ParseError { column })
}

fn whole<T: core::str::FromStr>(text: &str, column: usize) -> Result<Option<T>, ParseError> {
    if text == "-" {
        return Ok(None);
    }
    text.parse::<T>()
        .map(Some)
        .map_err(|_| ParseError { column })
}

/// Paces telemetry lines to [`LINK_SHARE`] of a link of `baud` (10 bits a byte, 8N1): after a
/// line of `n` bytes the next waits until the link has carried `n / LINK_SHARE` bytes' worth of
/// time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pacer {
    us_per_byte: f64,
    /// When the next line may go, µs.
    next_us: u64,
}

impl Pacer {
    pub fn new(baud: u32) -> Self {
        Pacer {
            us_per_byte: 10.0e6 / f64::from(baud.max(1)) / LINK_SHARE,
            next_us: 0,
        }
    }

    /// Whether a line may go at `now_us`.
    pub fn ready(&self, now_us: u64) -> bool {
        now_us >= self.next_us
    }

    /// A line of `bytes` (terminator included) went at `now_us`.
    pub fn sent(&mut self, now_us: u64, bytes: usize) {
        self.next_us = now_us + libm::ceil(bytes as f64 * self.us_per_byte) as u64;
    }

    /// How long a line of `bytes` occupies the link, µs: the longest a reply waits behind it.
    pub fn line_us(&self, bytes: usize) -> f64 {
        bytes as f64 * self.us_per_byte * LINK_SHARE
    }
}

#[cfg(test)]
mod tests;
