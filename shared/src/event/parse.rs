//! Reading an event back from a log line, without allocating. Words are split and keys matched
//! with closures and `strip_prefix` (see [`super`] on the generic string code the firmware also
//! uses).

use core::fmt;

use super::{EdgeWork, Event, SegmentEvent, EVENT_MARKER};
use crate::{Drive, SegmentKind, WaveformSpec};

/// Why a line that carries the event marker is not an event; the words it names borrow from the
/// line.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EventError<'a> {
    /// Nothing follows the marker.
    NoName,
    UnknownEvent(&'a str),
    /// The event needs this key.
    Missing(&'static str),
    /// The key's value is not a whole number.
    NotWhole(&'static str),
    /// The key's value is not a number.
    NotNumber(&'static str),
    /// The key's value is not an integer.
    NotInteger(&'static str),
    /// The key's value does not fit its field.
    OutOfRange(&'static str),
    /// A plan gives both `stroke_m` and `accel_mps2`, or neither.
    Drive,
    UnknownKind(&'a str),
    /// `level` is not `-1`, `0` or `1`.
    Level,
    /// `state` is not `on` or `off`.
    State,
}

impl fmt::Display for EventError<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            EventError::NoName => f.write_str("no event name"),
            EventError::UnknownEvent(name) => write!(f, "unknown event `{name}`"),
            EventError::Missing(key) => write!(f, "no `{key}`"),
            EventError::NotWhole(key) => write!(f, "`{key}` is not a whole number"),
            EventError::NotNumber(key) => write!(f, "`{key}` is not a number"),
            EventError::NotInteger(key) => write!(f, "`{key}` is not an integer"),
            EventError::OutOfRange(key) => write!(f, "`{key}` is out of range"),
            EventError::Drive => f.write_str("needs exactly one of `stroke_m`, `accel_mps2`"),
            EventError::UnknownKind(kind) => write!(f, "unknown segment kind `{kind}`"),
            EventError::Level => f.write_str("`level` must be -1, 0 or 1"),
            EventError::State => f.write_str("`state` must be on or off"),
        }
    }
}

/// Reads one log line: `Ok(None)` for a line without the marker. The event starts after the
/// first marker; words other than its keys' `key=value` are ignored, and of a key given twice
/// the last value counts.
pub fn parse_line(line: &str) -> Result<Option<Event>, EventError<'_>> {
    let Some((_, event)) = line.split_once(EVENT_MARKER) else {
        return Ok(None);
    };
    let name = words(event).next().ok_or(EventError::NoName)?;
    let fields = Fields(event);
    let event = match name {
        "plan" => plan(&fields)?,
        "start" => Event::Start {
            tick: fields.whole("tick")?,
        },
        "stop" => Event::Stop {
            tick: fields.whole("tick")?,
        },
        "halt" => Event::Halt {
            tick: fields.whole("tick")?,
        },
        "quickstop" => Event::QuickStop {
            tick: fields.whole("tick")?,
        },
        "seg" => Event::Segment(segment(&fields, began_slack_ticks)?),
        "replay" => Event::Replay(segment(&fields, replay_slack_ticks)?),
        "zero" => Event::Zero {
            actual_tick: fields.whole("actual")?,
        },
        "enable" => Event::Enable {
            actual_tick: fields.whole("actual")?,
            enabled: match fields.text("state")? {
                "on" => true,
                "off" => false,
                _ => return Err(EventError::State),
            },
        },
        "work" => Event::Work(EdgeWork {
            edges: fields.whole("edges")?,
            max_cycles: fields.whole("max_cycles")?,
            total_cycles: fields.whole("total_cycles")?,
            clock_hz: fields.whole("clock_hz")?,
        }),
        "end" => Event::End {
            tick: fields.whole("tick")?,
        },
        other => return Err(EventError::UnknownEvent(other)),
    };
    Ok(Some(event))
}

fn plan<'a>(fields: &Fields<'a>) -> Result<Event, EventError<'a>> {
    let drive = match (fields.get("stroke_m"), fields.get("accel_mps2")) {
        (Some(_), None) => Drive::Stroke {
            stroke_m: fields.real("stroke_m")?,
        },
        (None, Some(_)) => Drive::Accel {
            accel_mps2: fields.real("accel_mps2")?,
        },
        _ => return Err(EventError::Drive),
    };
    let ramp: u64 = fields.whole("ramp")?;
    Ok(Event::Plan {
        tick: fields.whole("tick")?,
        spec: WaveformSpec {
            period_s: fields.real("period_s")?,
            duty: fields.real("duty")?,
            drive,
        },
        clock_hz: fields.whole("clock_hz")?,
        ramp_cycles: u16::try_from(ramp).map_err(|_| EventError::OutOfRange("ramp"))?,
    })
}

/// A `seg` or `replay` event, whose `slack` (if any) `slack_ticks` reads.
fn segment<'a>(
    fields: &Fields<'a>,
    slack_ticks: fn(&'a str) -> Result<i64, EventError<'a>>,
) -> Result<SegmentEvent, EventError<'a>> {
    let kind = fields.text("kind")?;
    let kind = SegmentKind::ALL
        .into_iter()
        .find(|known| known.name() == kind)
        .ok_or(EventError::UnknownKind(kind))?;
    let level = fields
        .text("level")?
        .parse()
        .ok()
        .filter(|level: &i8| (-1..=1).contains(level))
        .ok_or(EventError::Level)?;
    let slack_ticks = fields.get("slack").map(slack_ticks).transpose()?;
    Ok(SegmentEvent {
        cycle: fields.whole("cycle")?,
        kind,
        planned_tick: fields.whole("planned")?,
        actual_tick: fields.whole("actual")?,
        ticks: fields.whole("ticks")?,
        level,
        step: fields.whole("step")?,
        steps: fields.whole("steps")?,
        slack_ticks,
    })
}

/// A segment that began was preloaded in time: its slack is a `u32`.
fn began_slack_ticks(text: &str) -> Result<i64, EventError<'_>> {
    text.parse::<u32>()
        .map(i64::from)
        .map_err(|_| EventError::NotWhole("slack"))
}

/// A replay's slack is negative when the preload came late.
fn replay_slack_ticks(text: &str) -> Result<i64, EventError<'_>> {
    text.parse().map_err(|_| EventError::NotInteger("slack"))
}

/// The words of `text`, as `split_whitespace` gives them.
fn words(text: &str) -> impl Iterator<Item = &str> {
    text.split(|c: char| c.is_whitespace())
        .filter(|word| !word.is_empty())
}

/// The `key=value` words of an event (its name is the first word).
struct Fields<'a>(&'a str);

impl<'a> Fields<'a> {
    /// The value of the last `key=` word after the name.
    fn get(&self, key: &str) -> Option<&'a str> {
        words(self.0)
            .skip(1)
            .filter_map(|word| word.strip_prefix(key)?.strip_prefix('='))
            .last()
    }

    fn text(&self, key: &'static str) -> Result<&'a str, EventError<'a>> {
        self.get(key).ok_or(EventError::Missing(key))
    }

    /// A whole number, which must fit `T`.
    fn whole<T: TryFrom<u64>>(&self, key: &'static str) -> Result<T, EventError<'a>> {
        let value: u64 = self
            .text(key)?
            .parse()
            .map_err(|_| EventError::NotWhole(key))?;
        T::try_from(value).map_err(|_| EventError::OutOfRange(key))
    }

    fn real(&self, key: &'static str) -> Result<f64, EventError<'a>> {
        self.text(key)?
            .parse()
            .map_err(|_| EventError::NotNumber(key))
    }
}
