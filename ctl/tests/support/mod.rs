//! The QEMU console image under test, shared by the QEMU-backed tests: the firmware built with
//! the `console` feature (`FEEDER_QEMU_ELF`) started by `feeder-emulator` with its serial port
//! on a free loopback TCP port, its decoded log handed line by line to a [`LogSink`], and a
//! client for the console that reads one reply line at a time. A board launched with its Modbus
//! port ([`Emulator::launch_with_modbus`]) has that port on a second loopback TCP port, where
//! [`modbus::Master`] speaks RTU frames to it.

// Each test uses its own part of this module.
#![allow(dead_code)]

pub mod modbus;

use std::io::{self, BufRead, BufReader, ErrorKind, Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::Stdio;
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

use feeder_emulator::{Board, Serial};

/// Longest to wait for QEMU to open its serial port.
const PORT_OPEN_TIMEOUT: Duration = Duration::from_secs(20);

/// Longest to wait for one reply line by default.
pub const REPLY_TIMEOUT: Duration = Duration::from_secs(10);

/// The console image named by `FEEDER_QEMU_ELF` (`cargo xtask test` sets it).
pub fn console_image() -> PathBuf {
    std::env::var_os("FEEDER_QEMU_ELF")
        .filter(|path| !path.is_empty())
        .map(PathBuf::from)
        .expect("FEEDER_QEMU_ELF must name the QEMU firmware built with the console feature")
}

/// The whole number in the environment variable `name`, `None` when it is unset; a value that
/// is not one (or is zero, where it must be `positive`) fails the test, naming the variable.
pub fn env_number(name: &str, positive: bool) -> Option<u64> {
    let text = std::env::var(name).ok()?;
    let number = text
        .trim()
        .parse::<u64>()
        .ok()
        .filter(|n| *n > 0 || !positive);
    match (number, positive) {
        (Some(number), _) => Some(number),
        (None, true) => panic!("{name}={text:?} is not a positive number"),
        (None, false) => panic!("{name}={text:?} is not a whole number"),
    }
}

/// Takes the decoded log, one line at a time, on the log thread.
pub trait LogSink: Send + 'static {
    fn line(&mut self, line: &str);
}

/// Keeps every line.
impl LogSink for Vec<String> {
    fn line(&mut self, line: &str) {
        self.push(line.to_string());
    }
}

/// QEMU and its log decoder; both are ended when this is dropped, however the test ends.
pub struct Emulator<S> {
    board: Board,
    log_thread: Option<JoinHandle<S>>,
    port: u16,
    /// The Modbus port's loopback TCP port, where the board was launched with one.
    modbus_port: Option<u16>,
    /// The board's own flash, erased at launch, where it was not given one.
    _flash: Option<tempfile::TempDir>,
}

impl<S: LogSink> Emulator<S> {
    /// Starts `elf` under QEMU with its serial port on a free loopback port, its decoded log
    /// going to `sink` and an erased flash of its own.
    pub fn launch(elf: &Path, sink: S) -> Self {
        let flash = tempfile::tempdir().expect("a directory for the board's flash");
        let mut emulator = Self::launch_in(elf, sink, flash.path());
        emulator._flash = Some(flash);
        emulator
    }

    /// Starts `elf` as [`Self::launch`] does, with the flash file in `dir`: what an earlier
    /// board saved there is still there.
    pub fn launch_in(elf: &Path, sink: S, dir: &Path) -> Self {
        let port = free_port();
        Self::start(elf, sink, dir, Serial::Tcp { port })
    }

    /// Starts `elf` as [`Self::launch`] does, with its Modbus port (UART1) too on a free
    /// loopback port: [`Self::connect_modbus`] connects a master to it.
    pub fn launch_with_modbus(elf: &Path, sink: S) -> Self {
        let flash = tempfile::tempdir().expect("a directory for the board's flash");
        let console = free_port();
        let modbus = loop {
            let modbus = free_port();
            if modbus != console {
                break modbus;
            }
        };
        let mut emulator = Self::start(elf, sink, flash.path(), Serial::Lines { console, modbus });
        emulator._flash = Some(flash);
        emulator
    }

    fn start(elf: &Path, sink: S, dir: &Path, serial: Serial) -> Self {
        let (port, modbus_port) = match serial {
            Serial::Tcp { port } => (port, None),
            Serial::Lines { console, modbus } => (console, Some(modbus)),
            Serial::None => panic!("the console image needs its serial port"),
        };
        let mut board = Board::start(elf, &[] as &[&str], serial, Stdio::piped(), dir)
            .unwrap_or_else(|error| panic!("the emulated board starts: {error}"));
        let decoded = board.decoded_log().expect("the decoded log is piped");
        let log_thread = thread::spawn(move || forward_lines(decoded, sink));
        Emulator {
            board,
            log_thread: Some(log_thread),
            port,
            modbus_port,
            _flash: None,
        }
    }

    /// The serial console's address, as `feeder-ctl --tcp` takes it.
    pub fn address(&self) -> String {
        format!("127.0.0.1:{}", self.port)
    }

    /// Connects to the serial console as soon as QEMU has opened the port.
    pub fn connect(&mut self) -> Console {
        let deadline = Instant::now() + PORT_OPEN_TIMEOUT;
        loop {
            if let Ok(Some(status)) = self.board.try_exit_status() {
                panic!("QEMU ended before its serial port opened: {status}");
            }
            match TcpStream::connect(("127.0.0.1", self.port)) {
                Ok(stream) => return Console::new(stream),
                Err(_) if Instant::now() < deadline => thread::sleep(Duration::from_millis(20)),
                Err(error) => panic!("QEMU's serial port never opened: {error}"),
            }
        }
    }

    /// The Modbus port's address (RTU frames over TCP), on a board launched with it.
    pub fn modbus_address(&self) -> SocketAddr {
        let port = self
            .modbus_port
            .expect("the board was launched with its Modbus port (launch_with_modbus)");
        SocketAddr::from(([127, 0, 0, 1], port))
    }

    /// Connects to the Modbus port as soon as QEMU has opened it (QEMU serves one client at a
    /// time: the connection is the board's master until it is dropped).
    pub fn connect_modbus(&mut self) -> TcpStream {
        let address = self.modbus_address();
        let deadline = Instant::now() + PORT_OPEN_TIMEOUT;
        loop {
            if let Ok(Some(status)) = self.board.try_exit_status() {
                panic!("QEMU ended before its Modbus port opened: {status}");
            }
            match TcpStream::connect(address) {
                Ok(stream) => return stream,
                Err(_) if Instant::now() < deadline => thread::sleep(Duration::from_millis(20)),
                Err(error) => panic!("QEMU's Modbus port never opened: {error}"),
            }
        }
    }

    /// Ends QEMU, lets the decoder drain and returns the sink, which has seen every line.
    pub fn shut_down(mut self) -> S {
        self.board
            .stop()
            .unwrap_or_else(|error| panic!("the emulated board stops: {error}"));
        self.log_thread
            .take()
            .expect("the log thread runs until shut down")
            .join()
            .expect("the log thread does not panic")
    }
}

fn free_port() -> u16 {
    let listener = TcpListener::bind("127.0.0.1:0").expect("a free loopback port");
    listener.local_addr().expect("bound address").port()
}

/// Hands every decoded line (without its terminator) to `sink` until the decoder ends.
fn forward_lines<S: LogSink>(decoded: impl Read, mut sink: S) -> S {
    let mut reader = BufReader::new(decoded);
    let mut bytes = Vec::new();
    loop {
        bytes.clear();
        match reader.read_until(b'\n', &mut bytes) {
            Ok(0) | Err(_) => return sink,
            Ok(_) => {
                let line = String::from_utf8_lossy(&bytes);
                sink.line(line.trim_end_matches(['\r', '\n']));
            }
        }
    }
}

/// The serial console: raw bytes out, reply lines back.
pub struct Console {
    writer: TcpStream,
    reader: BufReader<TcpStream>,
}

impl Console {
    fn new(stream: TcpStream) -> Self {
        stream.set_nodelay(true).expect("TCP_NODELAY");
        stream
            .set_read_timeout(Some(REPLY_TIMEOUT))
            .expect("a read timeout");
        let writer = stream.try_clone().expect("a second handle on the socket");
        Console {
            writer,
            reader: BufReader::new(stream),
        }
    }

    /// Sets how long [`Self::reply`] waits.
    pub fn set_reply_timeout(&mut self, timeout: Duration) {
        self.reader
            .get_ref()
            .set_read_timeout(Some(timeout))
            .expect("a read timeout");
    }

    /// Writes `bytes` as they are, in one write.
    pub fn write(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.writer.write_all(bytes)
    }

    /// The next reply line, without its CR LF, within [`REPLY_TIMEOUT`].
    pub fn reply(&mut self) -> io::Result<String> {
        self.reply_within(REPLY_TIMEOUT)
    }

    /// The next reply line, without its CR LF, waiting up to about `limit` for it (in steps of
    /// the socket's read timeout); a part of the line that arrived before a timeout is kept.
    pub fn reply_within(&mut self, limit: Duration) -> io::Result<String> {
        let deadline = Instant::now() + limit;
        let mut bytes = Vec::new();
        loop {
            match self.reader.read_until(b'\n', &mut bytes) {
                Ok(_) => break,
                Err(error)
                    if matches!(error.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut)
                        && Instant::now() < deadline => {}
                Err(error) => return Err(error),
            }
        }
        match bytes.strip_suffix(b"\n") {
            Some(line) => {
                let line = line.strip_suffix(b"\r").unwrap_or(line);
                String::from_utf8(line.to_vec())
                    .map_err(|_| io::Error::new(ErrorKind::InvalidData, "a reply is not text"))
            }
            None if bytes.is_empty() => Err(ErrorKind::UnexpectedEof.into()),
            None => Err(io::Error::new(
                ErrorKind::UnexpectedEof,
                format!(
                    "the console closed mid-reply: {:?}",
                    String::from_utf8_lossy(&bytes)
                ),
            )),
        }
    }

    /// Checks that nothing arrives within `quiet`: every line has had its one reply.
    pub fn expect_silence(&mut self, quiet: Duration) -> Result<(), String> {
        self.set_reply_timeout(quiet);
        let outcome = match self.reader.fill_buf() {
            Ok([]) => Err("the console closed the connection".to_string()),
            Ok(unsolicited) => Err(format!(
                "unsolicited bytes from the console: {:?}",
                String::from_utf8_lossy(unsolicited)
            )),
            Err(error) if matches!(error.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {
                Ok(())
            }
            Err(error) => Err(format!("the console failed: {error}")),
        };
        self.set_reply_timeout(REPLY_TIMEOUT);
        outcome
    }

    /// Sends raw bytes (a line with its terminator) and returns the reply line.
    pub fn send(&mut self, bytes: &[u8]) -> String {
        self.write(bytes).expect("the console takes the line");
        self.reply().expect("a reply in time")
    }

    /// Sends `line` with CR LF and returns the reply line.
    pub fn command(&mut self, line: &str) -> String {
        self.send(format!("{line}\r\n").as_bytes())
    }

    /// Sends `line` and checks that the reply starts with `expected`.
    pub fn expect(&mut self, line: &str, expected: &str) -> String {
        let reply = self.command(line);
        assert!(
            reply.starts_with(expected),
            "{line:?}: expected {expected:?}, got {reply:?}"
        );
        reply
    }

    /// Polls `status` until the state is `state`, for at most `timeout`.
    pub fn wait_for_state(&mut self, state: &str, timeout: Duration) {
        let wanted = format!("OK state={state} ");
        let deadline = Instant::now() + timeout;
        loop {
            let reply = self.command("status");
            if reply.starts_with(&wanted) {
                return;
            }
            assert!(reply.starts_with("OK state="), "status: {reply:?}");
            assert!(
                Instant::now() < deadline,
                "not {state} after {timeout:?}: {reply}"
            );
            thread::sleep(Duration::from_millis(50));
        }
    }
}

/// The firmware's virtual time as its log shows it: the start tick of the newest segment
/// reported (µs on the QEMU image's 1 MHz output clock). The emulation runs on virtual time,
/// which under QEMU's instruction counting keeps no pace with the wall clock (it runs several
/// times faster while the board idles); a silence the firmware must see (a Modbus frame gap) is
/// waited for on this clock.
#[derive(Default)]
pub struct LogClock {
    tick: std::sync::atomic::AtomicU64,
}

impl LogClock {
    /// The newest segment's start tick.
    pub fn tick(&self) -> u64 {
        self.tick.load(std::sync::atomic::Ordering::Relaxed)
    }

    /// Waits until the log has moved at least `ticks` past where it is now, and at least
    /// `at_least` of wall time; `Err` after `limit` of wall time.
    pub fn wait_for(&self, ticks: u64, at_least: Duration, limit: Duration) -> Result<(), String> {
        let started = Instant::now();
        let from = self.tick();
        loop {
            let waited = started.elapsed();
            if self.tick() >= from + ticks && waited >= at_least {
                return Ok(());
            }
            if waited > limit {
                return Err(format!(
                    "the firmware's log moved {} ticks in {waited:?}, not {ticks}",
                    self.tick() - from
                ));
            }
            thread::sleep(Duration::from_micros(500));
        }
    }

    fn saw(&self, line: &str) {
        // `EVT seg cycle=… kind=… planned=<tick> …`, read without the full parser.
        let Some(event) = line.split("EVT seg ").nth(1) else {
            return;
        };
        let planned = event
            .split(' ')
            .find_map(|word| word.strip_prefix("planned="))
            .and_then(|tick| tick.parse().ok());
        if let Some(tick) = planned {
            self.tick
                .fetch_max(tick, std::sync::atomic::Ordering::Relaxed);
        }
    }
}

/// A [`LogSink`] that keeps every line and keeps a [`LogClock`], then passes each line on.
pub struct Clocked<S> {
    inner: S,
    lines: Vec<String>,
    clock: std::sync::Arc<LogClock>,
}

impl<S: LogSink> Clocked<S> {
    /// `inner` with a clock, which the test reads while the board runs.
    pub fn new(inner: S) -> (Self, std::sync::Arc<LogClock>) {
        let clock = std::sync::Arc::new(LogClock::default());
        let sink = Clocked {
            inner,
            lines: Vec::new(),
            clock: std::sync::Arc::clone(&clock),
        };
        (sink, clock)
    }

    /// The sink passed on to, and every line.
    pub fn into_parts(self) -> (S, Vec<String>) {
        (self.inner, self.lines)
    }
}

impl<S: LogSink> LogSink for Clocked<S> {
    fn line(&mut self, line: &str) {
        self.clock.saw(line);
        self.lines.push(line.to_string());
        self.inner.line(line);
    }
}

/// Passes nothing on: a [`Clocked`] sink's lines alone.
impl LogSink for () {
    fn line(&mut self, _: &str) {}
}
