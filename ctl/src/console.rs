//! The connection to the feeder's serial console, over a serial port or TCP: one command line
//! out, one reply line back, and the telemetry lines the board streams between replies
//! (`feeder_shared::telemetry`), kept in order until taken.

use std::collections::VecDeque;
use std::io::{self, Read, Write};
use std::net::TcpStream;
use std::time::{Duration, Instant};

use feeder_shared::telemetry::{Record, MARKER};

/// Longest reply line accepted, in bytes.
const MAX_REPLY_BYTES: usize = 1024;

/// Telemetry records kept until taken, the oldest dropped beyond: over an hour at 50 Hz, where
/// nobody takes them (telemetry left on at the prompt).
const KEPT_RECORDS: usize = 200_000;

/// Where the console is.
pub enum Target<'a> {
    Serial { path: &'a str, baud: u32 },
    Tcp(&'a str),
}

impl std::fmt::Display for Target<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Target::Serial { path, baud } => write!(f, "serial port {path} at {baud} baud"),
            Target::Tcp(address) => write!(f, "TCP {address}"),
        }
    }
}

/// A connection to the console: one command line out, one reply line back.
pub struct Console {
    link: Box<dyn Link>,
    /// How long a reply may take.
    timeout: Duration,
    /// Telemetry records received and not taken yet.
    telemetry: VecDeque<Record>,
    /// Bytes of the line being received.
    partial: Vec<u8>,
}

trait Link: Read + Write {
    /// Sets how long a read waits.
    fn set_wait(&mut self, wait: Duration) -> io::Result<()>;
}

impl Link for TcpStream {
    fn set_wait(&mut self, wait: Duration) -> io::Result<()> {
        self.set_read_timeout(Some(wait.max(Duration::from_millis(1))))
    }
}

impl Link for Box<dyn serialport::SerialPort> {
    fn set_wait(&mut self, wait: Duration) -> io::Result<()> {
        self.set_timeout(wait).map_err(io::Error::from)
    }
}

/// A line from the board.
enum Line {
    Reply(String),
    Telemetry,
}

impl Console {
    pub fn open(target: &Target, timeout: Duration) -> io::Result<Self> {
        let link: Box<dyn Link> = match *target {
            Target::Serial { path, baud } => {
                let port = serialport::new(path, baud).timeout(timeout).open()?;
                port.clear(serialport::ClearBuffer::Input)?;
                Box::new(port)
            }
            Target::Tcp(address) => {
                let stream = TcpStream::connect(address)?;
                stream.set_nodelay(true)?;
                Box::new(stream)
            }
        };
        Ok(Console {
            link,
            timeout,
            telemetry: VecDeque::new(),
            partial: Vec::new(),
        })
    }

    /// Sends `line` and returns the reply line without its terminator; telemetry lines that
    /// arrive before it are kept for [`Console::take_telemetry`].
    pub fn command(&mut self, line: &str) -> io::Result<String> {
        self.link.write_all(line.as_bytes())?;
        self.link.write_all(b"\r\n")?;
        self.link.flush()?;
        let deadline = Instant::now() + self.timeout;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.line(left)? {
                Some(Line::Reply(reply)) => return Ok(reply),
                Some(Line::Telemetry) => {}
                None if left.is_zero() => {
                    return Err(io::Error::new(io::ErrorKind::TimedOut, "no reply in time"))
                }
                None => {}
            }
        }
    }

    /// Reads what arrives within `wait`, keeping the telemetry; a reply line that arrives
    /// unasked is an error.
    pub fn listen(&mut self, wait: Duration) -> io::Result<()> {
        let deadline = Instant::now() + wait;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.line(left)? {
                Some(Line::Reply(reply)) => {
                    return Err(io::Error::new(
                        io::ErrorKind::InvalidData,
                        format!("a reply nobody asked for: {reply}"),
                    ))
                }
                Some(Line::Telemetry) => {}
                None if left.is_zero() => return Ok(()),
                None => {}
            }
        }
    }

    /// The telemetry records received so far, oldest first.
    pub fn take_telemetry(&mut self) -> Vec<Record> {
        self.telemetry.drain(..).collect()
    }

    /// The next line within `wait`, or `None`; a telemetry line goes to the records (a line
    /// that does not read as one is an error).
    fn line(&mut self, wait: Duration) -> io::Result<Option<Line>> {
        self.link.set_wait(wait)?;
        let mut bytes = [0u8; 256];
        loop {
            if let Some(end) = self.partial.iter().position(|&byte| byte == b'\n') {
                let raw: Vec<u8> = self.partial.drain(..=end).collect();
                let text = String::from_utf8_lossy(&raw);
                let text = text.trim_end_matches(['\r', '\n']);
                if let Some(fields) = text.strip_prefix(MARKER) {
                    let record = Record::parse_line(fields).map_err(|error| {
                        io::Error::new(io::ErrorKind::InvalidData, format!("{error}: {text:?}"))
                    })?;
                    if self.telemetry.len() == KEPT_RECORDS {
                        self.telemetry.pop_front();
                    }
                    self.telemetry.push_back(record);
                    return Ok(Some(Line::Telemetry));
                }
                let mut reply = text.to_string();
                reply.truncate(MAX_REPLY_BYTES);
                return Ok(Some(Line::Reply(reply)));
            }
            match self.link.read(&mut bytes) {
                Ok(0) => {
                    return Err(io::Error::new(
                        io::ErrorKind::UnexpectedEof,
                        "connection closed",
                    ))
                }
                Ok(read) => self.partial.extend_from_slice(&bytes[..read]),
                Err(error) if error.kind() == io::ErrorKind::Interrupted => {}
                Err(error)
                    if matches!(
                        error.kind(),
                        io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut
                    ) =>
                {
                    return Ok(None)
                }
                Err(error) => return Err(error),
            }
        }
    }
}

/// The value of `key=` in a reply.
pub fn field<'a>(reply: &'a str, key: &str) -> Option<&'a str> {
    reply
        .split_whitespace()
        .find_map(|word| word.strip_prefix(key)?.strip_prefix('='))
}

/// The board's clock in a `status` reply, s.
pub fn uptime_s(status: &str) -> Option<f64> {
    field(status, "uptime_s")?.parse().ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_field_is_read_by_its_exact_key() {
        let status =
            "OK state=running uptime_s=12.5 loop=feeding loop_error=none gain_pos=1.02 lag_ms=0.16";
        assert_eq!(field(status, "loop"), Some("feeding"));
        assert_eq!(field(status, "loop_error"), Some("none"));
        assert_eq!(field(status, "lag_ms"), Some("0.16"));
        assert_eq!(field(status, "gain"), None);
        assert_eq!(field(status, "lag"), None);
        assert_eq!(uptime_s(status), Some(12.5));
    }
}
