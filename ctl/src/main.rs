//! `feeder-ctl`: talks to the feeder's serial console, over a serial port (the NUCLEO's ST-LINK
//! virtual COM port) or over TCP (QEMU's `-serial tcp:…`).
//!
//! ```text
//! feeder-ctl (--port PATH [--baud N] | --tcp HOST:PORT) [--timeout-ms N] [COMMAND WORDS…]
//! ```
//!
//! With command words, sends them as one line, prints the reply and exits with 0 for `OK`, 1 for
//! `ERR`. Without, reads commands from standard input (with a prompt on a terminal) and prints
//! each reply. Exit code 2: bad arguments or a connection or timeout error.

use std::io::{self, BufRead, IsTerminal, Read, Write};
use std::net::TcpStream;
use std::process::ExitCode;
use std::time::Duration;

use clap::{ArgGroup, Parser};

/// Longest reply line accepted, in bytes.
const MAX_REPLY_BYTES: usize = 1024;
/// Longest reply timeout accepted: an hour.
const MAX_TIMEOUT_MS: u32 = 3_600_000;

/// Talks to the feeder's serial console: one command per line, one `OK …` or `ERR …` reply.
#[derive(Parser)]
#[command(
    name = "feeder-ctl",
    version,
    allow_negative_numbers = true,
    group(ArgGroup::new("target").required(true).args(["port", "tcp"]))
)]
struct Options {
    /// Serial port, e.g. /dev/ttyACM0 (the NUCLEO's ST-LINK virtual COM port).
    #[arg(long, value_name = "PATH")]
    port: Option<String>,
    /// Baud rate of the serial port.
    #[arg(long, value_name = "N", default_value_t = 115_200, requires = "port",
          value_parser = clap::value_parser!(u32).range(1..))]
    baud: u32,
    /// TCP serial, e.g. QEMU's `-serial tcp:127.0.0.1:4444,server=on,wait=off`.
    #[arg(long, value_name = "HOST:PORT")]
    tcp: Option<String>,
    /// How long to wait for a reply, in milliseconds.
    #[arg(long, value_name = "N", default_value_t = 3000,
          value_parser = clap::value_parser!(u32).range(1..=i64::from(MAX_TIMEOUT_MS)))]
    timeout_ms: u32,
    /// One command (e.g. `set feed 30`, `set duty -0.5`); without it, commands are read from
    /// standard input. Exit code 0 for `OK`, 1 for `ERR`, 2 for bad arguments, a connection
    /// error or no reply in time.
    #[arg(
        trailing_var_arg = true,
        allow_hyphen_values = true,
        value_name = "COMMAND"
    )]
    command: Vec<String>,
}

/// Where the console is.
enum Target<'a> {
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

impl Options {
    fn target(&self) -> Target<'_> {
        match (&self.port, &self.tcp) {
            (Some(path), _) => Target::Serial {
                path,
                baud: self.baud,
            },
            (None, Some(address)) => Target::Tcp(address),
            (None, None) => unreachable!("clap requires one of --port and --tcp"),
        }
    }
}

/// A connection to the console: one command line out, one reply line back.
struct Console {
    link: Box<dyn Link>,
}

trait Link: Read + Write {}
impl<T: Read + Write> Link for T {}

impl Console {
    fn open(target: &Target, timeout: Duration) -> io::Result<Self> {
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
    fn command(&mut self, line: &str) -> io::Result<String> {
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

fn interactive(console: &mut Console) -> io::Result<()> {
    let stdin = io::stdin();
    let prompt = stdin.is_terminal();
    let mut lines = stdin.lock().lines();
    loop {
        if prompt {
            print!("feeder> ");
            io::stdout().flush()?;
        }
        let Some(line) = lines.next().transpose()? else {
            return Ok(());
        };
        let line = line.trim();
        if line.is_empty() {
            continue;
        }
        if matches!(line, "quit" | "exit") {
            return Ok(());
        }
        println!("{}", console.command(line)?);
    }
}

fn main() -> ExitCode {
    let options = Options::parse();
    let timeout = Duration::from_millis(options.timeout_ms.into());
    let target = options.target();
    let mut console = match Console::open(&target, timeout) {
        Ok(console) => console,
        Err(error) => {
            eprintln!("feeder-ctl: cannot open {target}: {error}");
            return ExitCode::from(2);
        }
    };
    let result = if options.command.is_empty() {
        interactive(&mut console).map(|()| true)
    } else {
        console.command(&options.command.join(" ")).map(|reply| {
            println!("{reply}");
            reply.starts_with("OK")
        })
    };
    match result {
        Ok(true) => ExitCode::SUCCESS,
        Ok(false) => ExitCode::FAILURE,
        Err(error) => {
            eprintln!("feeder-ctl: {error}");
            ExitCode::from(2)
        }
    }
}
