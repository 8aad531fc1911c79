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

const USAGE: &str =
    "usage: feeder-ctl (--port PATH [--baud N] | --tcp HOST:PORT) [--timeout-ms N] [COMMAND...]
  --port PATH     serial port, e.g. /dev/ttyACM0 (NUCLEO ST-LINK virtual COM port)
  --baud N        baud rate of the serial port (default 115200)
  --tcp HOST:PORT TCP serial, e.g. QEMU's -serial tcp:127.0.0.1:4444,server=on,wait=off
  --timeout-ms N  how long to wait for a reply (default 3000)
  COMMAND...      one command (e.g. `set feed 30`); without it, commands are read from stdin";

/// Longest reply line accepted, in bytes.
const MAX_REPLY_BYTES: usize = 1024;

/// Where the console is.
enum Target {
    Serial { path: String, baud: u32 },
    Tcp(String),
}

struct Options {
    target: Target,
    timeout: Duration,
    command: Vec<String>,
}

fn parse_options(mut args: impl Iterator<Item = String>) -> Result<Options, String> {
    let mut port = None;
    let mut tcp = None;
    let mut baud = 115_200;
    let mut timeout = Duration::from_millis(3000);
    let mut command = Vec::new();
    while let Some(arg) = args.next() {
        let mut value = |name: &str| args.next().ok_or(format!("{name} needs a value"));
        match arg.as_str() {
            "--port" => port = Some(value("--port")?),
            "--tcp" => tcp = Some(value("--tcp")?),
            "--baud" => {
                baud = value("--baud")?
                    .parse()
                    .map_err(|_| "--baud needs a number".to_string())?
            }
            "--timeout-ms" => {
                timeout = Duration::from_millis(
                    value("--timeout-ms")?
                        .parse()
                        .map_err(|_| "--timeout-ms needs a number".to_string())?,
                )
            }
            "-h" | "--help" => return Err(String::new()),
            _ => {
                command.push(arg);
                command.extend(args.by_ref());
            }
        }
    }
    let target = match (port, tcp) {
        (Some(path), None) => Target::Serial { path, baud },
        (None, Some(address)) => Target::Tcp(address),
        _ => return Err("give exactly one of --port and --tcp".to_string()),
    };
    Ok(Options {
        target,
        timeout,
        command,
    })
}

/// A connection to the console: one command line out, one reply line back.
struct Console {
    link: Box<dyn Link>,
}

trait Link: Read + Write {}
impl<T: Read + Write> Link for T {}

impl Console {
    fn open(target: &Target, timeout: Duration) -> io::Result<Self> {
        let link: Box<dyn Link> = match target {
            Target::Serial { path, baud } => {
                let port = serialport::new(path, *baud).timeout(timeout).open()?;
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
    let options = match parse_options(std::env::args().skip(1)) {
        Ok(options) => options,
        Err(message) => {
            if !message.is_empty() {
                eprintln!("feeder-ctl: {message}");
            }
            eprintln!("{USAGE}");
            return ExitCode::from(2);
        }
    };
    let result = Console::open(&options.target, options.timeout).and_then(|mut console| {
        if options.command.is_empty() {
            interactive(&mut console).map(|()| true)
        } else {
            let reply = console.command(&options.command.join(" "))?;
            println!("{reply}");
            Ok(reply.starts_with("OK"))
        }
    });
    match result {
        Ok(true) => ExitCode::SUCCESS,
        Ok(false) => ExitCode::FAILURE,
        Err(error) => {
            eprintln!("feeder-ctl: {error}");
            ExitCode::from(2)
        }
    }
}
