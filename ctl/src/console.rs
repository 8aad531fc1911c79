//! The connection to the feeder's serial console, over a serial port or TCP: one command line
//! out, one reply line back.

use std::io::{self, Read, Write};
use std::net::TcpStream;
use std::time::Duration;

/// Longest reply line accepted, in bytes.
const MAX_REPLY_BYTES: usize = 1024;

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
}

trait Link: Read + Write {}
impl<T: Read + Write> Link for T {}

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
                stream.set_read_timeout(Some(timeout))?;
                stream.set_nodelay(true)?;
                Box::new(stream)
            }
        };
        Ok(Console { link })
    }

    /// Sends `line` and returns the reply line without its terminator.
    pub fn command(&mut self, line: &str) -> io::Result<String> {
        self.link.write_all(line.as_bytes())?;
        self.link.write_all(b"\r\n")?;
        self.link.flush()?;
        self.reply()
    }

    fn reply(&mut self) -> io::Result<String> {
        let mut reply = Vec::new();
        let mut byte = [0u8];
        loop {
            match self.link.read(&mut byte) {
                Ok(0) => {
                    return Err(io::Error::new(
                        io::ErrorKind::UnexpectedEof,
                        "connection closed",
                    ))
                }
                Ok(_) if byte[0] == b'\n' => break,
                Ok(_) if byte[0] == b'\r' => {}
                Ok(_) if reply.len() < MAX_REPLY_BYTES => reply.push(byte[0]),
                Ok(_) => {}
                Err(error) if error.kind() == io::ErrorKind::Interrupted => {}
                Err(error)
                    if matches!(
                        error.kind(),
                        io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut
                    ) =>
                {
                    return Err(io::Error::new(io::ErrorKind::TimedOut, "no reply in time"))
                }
                Err(error) => return Err(error),
            }
        }
        Ok(String::from_utf8_lossy(&reply).into_owned())
    }
}
