//! Reading a decoded log (defmt-print's or probe-rs's output): its events, in the shared text
//! ([`feeder_shared::event`]), and the lines that report a firmware error.

use std::fmt;
use std::io::{BufRead, Read};

use feeder_shared::event::{self, Event};

/// A line that carries the event marker but cannot be read.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ParseError {
    pub line: String,
    pub reason: String,
}

/// Characters of a log line a message shows.
pub const SHOWN_LINE_CHARS: usize = 120;

impl fmt::Display for ParseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "unreadable event ({}): {}",
            self.reason,
            excerpt(&self.line)
        )
    }
}

/// `line` as a message shows it: at most [`SHOWN_LINE_CHARS`] characters, then `…`.
pub fn excerpt(line: &str) -> String {
    match line.char_indices().nth(SHOWN_LINE_CHARS) {
        Some((end, _)) => format!("{}…", &line[..end]),
        None => line.to_string(),
    }
}

impl std::error::Error for ParseError {}

/// What one line of a decoded log holds.
#[derive(Debug, Clone, PartialEq)]
pub enum LogLine {
    Event(Event),
    /// A firmware error: a line with `ERROR` or `panic` (defmt's error level, the panic
    /// handler's message).
    FirmwareError,
    Other,
}

/// Reads one line of a decoded log.
pub fn read_line(line: &str) -> Result<LogLine, ParseError> {
    Ok(match parse_line(line)? {
        Some(event) => LogLine::Event(event),
        None if line.contains("ERROR") || line.contains("panic") => LogLine::FirmwareError,
        None => LogLine::Other,
    })
}

/// Reads one log line: `Ok(None)` for lines without an event.
pub fn parse_line(line: &str) -> Result<Option<Event>, ParseError> {
    event::parse_line(line).map_err(|error| ParseError {
        line: line.trim_end().to_string(),
        reason: error.to_string(),
    })
}

/// A decoded log: its events and the lines that report a firmware error.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Stream {
    pub events: Vec<Event>,
    /// The firmware's error lines ([`LogLine::FirmwareError`]).
    pub errors: Vec<String>,
}

/// Longest line read: decoded event lines are a few hundred bytes at most, so a longer one means
/// the input is not a decoded log.
pub const MAX_LINE_BYTES: usize = 64 * 1024;

/// Reads a decoded log (defmt-print's or probe-rs's output): UTF-8 lines of at most
/// [`MAX_LINE_BYTES`].
pub fn read_stream(mut reader: impl BufRead) -> Result<Stream, HilError> {
    let mut stream = Stream::default();
    let mut bytes = Vec::new();
    for number in 1.. {
        bytes.clear();
        let read = (&mut reader)
            .take(MAX_LINE_BYTES as u64 + 1)
            .read_until(b'\n', &mut bytes)
            .map_err(|error| HilError::Read(error.to_string()))?;
        if read == 0 {
            break;
        }
        let text = bytes.strip_suffix(b"\n").unwrap_or(&bytes);
        if text.len() > MAX_LINE_BYTES {
            return Err(HilError::Read(format!(
                "line {number} is longer than {MAX_LINE_BYTES} bytes"
            )));
        }
        let text = text.strip_suffix(b"\r").unwrap_or(text);
        let line = std::str::from_utf8(text)
            .map_err(|_| HilError::Read(format!("line {number} is not UTF-8 text")))?;
        match read_line(line) {
            Ok(LogLine::Event(event)) => stream.events.push(event),
            Ok(LogLine::FirmwareError) => stream.errors.push(line.trim_end().to_string()),
            Ok(LogLine::Other) => {}
            Err(error) => {
                return Err(HilError::Parse {
                    line: number,
                    error,
                })
            }
        }
    }
    Ok(stream)
}

/// Why a stream could not be analysed; the message leaves naming the stream to the caller.
#[derive(Debug, Clone, PartialEq)]
pub enum HilError {
    /// The reader failed, or a line is not text or too long.
    Read(String),
    /// A line (counted from 1) carries the event marker but cannot be read.
    Parse { line: usize, error: ParseError },
}

impl fmt::Display for HilError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            HilError::Read(reason) => f.write_str(reason),
            HilError::Parse { line, error } => write!(f, "line {line}: {error}"),
        }
    }
}

impl std::error::Error for HilError {}
