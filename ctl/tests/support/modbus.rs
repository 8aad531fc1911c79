//! A Modbus RTU master for the emulated board's Modbus port: `tokio-modbus`'s RTU client over
//! the loopback TCP connection QEMU serves for UART1, driven one request at a time from the
//! tests' plain (blocking) code, and raw bytes on the same connection for what no client sends
//! (garbage, a frame with a corrupt CRC, a function it has no request for).
//!
//! The frames here are built and checked by `tokio-modbus` and by [`frame`]'s few lines, never by
//! the firmware's own codec.

use std::borrow::Cow;
use std::io::{self, ErrorKind};
use std::pin::{pin, Pin};
use std::sync::Arc;
use std::task::{ready, Context, Poll};
use std::time::{Duration, Instant};

use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::net::TcpStream;
use tokio::runtime::Runtime;
use tokio_modbus::client::{rtu, Client, Context as Modbus};
use tokio_modbus::{ExceptionCode, Request, Response, Slave};

use super::LogClock;

/// The board's slave address.
pub const SLAVE: u8 = 1;

/// A silence the firmware takes as the end of a frame, with room: its frame gap on QEMU is
/// 50 ms of its virtual time (µs ticks of the log's clock).
pub const FRAME_GAP_TICKS: u64 = 150_000;

/// The board's time within which an answer comes, with room (it comes within a millisecond of
/// the request's last byte): a request unanswered while the board's time ran this far was lost.
pub const ANSWER_TICKS: u64 = 300_000;

/// The least wall time to wait for an answer, and the most.
const ANSWER_WALL_MIN: Duration = Duration::from_millis(20);
const ANSWER_WALL_MAX: Duration = Duration::from_secs(10);

/// How often a lost request is sent again by default.
pub const RETRIES: u32 = 2;

/// A request that got no well-formed answer.
#[derive(Debug)]
pub enum Failure {
    /// Nothing while the board's time ran [`ANSWER_TICKS`] (and every retry the same).
    Lost { attempts: u32 },
    /// Nothing within the wall time's limit, however far the board's time ran.
    Timeout(Duration),
    /// The answer came after the request had been given up for lost.
    Late(String),
    /// Bytes that were no answer to the request (CRC, header, function), or the connection failed.
    Transport(tokio_modbus::Error),
}

impl std::fmt::Display for Failure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Failure::Lost { attempts } => write!(
                f,
                "no answer to {attempts} attempts, each while the board's time ran {} ms",
                ANSWER_TICKS / 1000
            ),
            Failure::Timeout(waited) => write!(f, "no answer within {waited:?} of wall time"),
            Failure::Late(what) => write!(f, "a late answer: {what}"),
            Failure::Transport(error) => write!(f, "no well-formed answer: {error}"),
        }
    }
}

/// The master: a `tokio-modbus` RTU client on the connection, and the connection itself.
///
/// A request that stays unanswered while the board's time runs on was lost on its way in and is
/// sent again after a frame gap, as a PLC does after its response timeout: QEMU hands the
/// board a request a byte at a time, and on a loaded host its virtual time can run past the
/// firmware's 50 ms frame gap between two bytes of one frame (see `retried`).
pub struct Master {
    runtime: Runtime,
    client: Modbus,
    stream: Arc<TcpStream>,
    clock: Arc<LogClock>,
    retries: u32,
    /// The wall time the last answer took.
    pub last_round_trip: Duration,
    /// Requests sent again because the board never answered the first.
    pub retried: u64,
}

impl Master {
    /// A master for slave [`SLAVE`] on `stream` (from [`super::Emulator::connect_modbus`]), with
    /// the board's time read from its log's `clock`.
    pub fn new(stream: std::net::TcpStream, clock: Arc<LogClock>) -> Self {
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_io()
            .enable_time()
            .build()
            .expect("a tokio runtime");
        stream.set_nodelay(true).expect("TCP_NODELAY");
        stream.set_nonblocking(true).expect("a non-blocking socket");
        let stream = {
            let _entered = runtime.enter();
            Arc::new(TcpStream::from_std(stream).expect("the socket in tokio"))
        };
        let client = rtu::attach_slave(Shared(Arc::clone(&stream)), Slave(SLAVE));
        Master {
            runtime,
            client,
            stream,
            clock,
            retries: RETRIES,
            last_round_trip: Duration::ZERO,
            retried: 0,
        }
    }

    /// Sets how often a lost request is sent again (0: never).
    pub fn set_retries(&mut self, retries: u32) {
        self.retries = retries;
    }

    /// Sends `request` and returns its answer: the response or the exception; `Err` when no
    /// well-formed answer came. A lost request is sent again, up to the retries set.
    pub fn try_call(
        &mut self,
        request: Request<'_>,
    ) -> Result<Result<Response, ExceptionCode>, Failure> {
        let mut attempts = 1;
        loop {
            match self.attempt(request.clone()) {
                Err(Failure::Lost { .. }) if attempts <= self.retries => {
                    // Nothing may come back now; the firmware drops what it holds of the
                    // request at the next frame gap.
                    self.no_answer().map_err(Failure::Late)?;
                    self.retried += 1;
                    attempts += 1;
                }
                Err(Failure::Lost { .. }) => return Err(Failure::Lost { attempts }),
                outcome => return outcome,
            }
        }
    }

    /// Sends `request` once and waits for its answer while the board's time runs
    /// [`ANSWER_TICKS`].
    fn attempt(
        &mut self,
        request: Request<'_>,
    ) -> Result<Result<Response, ExceptionCode>, Failure> {
        let asked = Instant::now();
        let from = self.clock.tick();
        let clock = &self.clock;
        let client = &mut self.client;
        let outcome = self.runtime.block_on(async {
            let mut call = pin!(client.call(request));
            loop {
                let step = Duration::from_millis(2);
                if let Ok(outcome) = tokio::time::timeout(step, call.as_mut()).await {
                    return Ok(outcome);
                }
                let waited = asked.elapsed();
                if waited >= ANSWER_WALL_MIN && clock.tick() >= from + ANSWER_TICKS {
                    return Err(Failure::Lost { attempts: 1 });
                }
                if waited >= ANSWER_WALL_MAX {
                    return Err(Failure::Timeout(waited));
                }
            }
        });
        self.last_round_trip = asked.elapsed();
        match outcome {
            Err(failure) => Err(failure),
            Ok(Err(error)) => Err(Failure::Transport(error)),
            Ok(Ok(answer)) => Ok(answer),
        }
    }

    /// Checks that nothing arrives while the board's time passes a frame gap (and at least a
    /// few ms of wall time): what was sent gets no answer, and the firmware has dropped what it
    /// held of it. `Err` shows what arrived.
    pub fn no_answer(&mut self) -> Result<(), String> {
        let from = self.clock.tick();
        let started = Instant::now();
        while self.clock.tick() < from + FRAME_GAP_TICKS
            || started.elapsed() < Duration::from_millis(5)
        {
            self.expect_silence(Duration::from_millis(2))?;
            if started.elapsed() > ANSWER_WALL_MAX {
                return Err("the board's time stands still".into());
            }
        }
        Ok(())
    }

    /// Sends `request` and returns its answer; panics when no well-formed answer came.
    pub fn call(&mut self, request: Request<'_>) -> Result<Response, ExceptionCode> {
        let shown = format!("{request:?}");
        self.try_call(request)
            .unwrap_or_else(|failure| panic!("{shown}: {failure}"))
    }

    /// Function 3: `count` holding registers from `address`.
    pub fn read_holding(&mut self, address: u16, count: u16) -> Result<Vec<u16>, ExceptionCode> {
        self.call(Request::ReadHoldingRegisters(address, count))
            .map(|response| match response {
                Response::ReadHoldingRegisters(words) => words,
                other => panic!("a read of holding registers answered {other:?}"),
            })
    }

    /// Function 4: `count` input registers from `address`.
    pub fn read_input(&mut self, address: u16, count: u16) -> Result<Vec<u16>, ExceptionCode> {
        self.call(Request::ReadInputRegisters(address, count))
            .map(|response| match response {
                Response::ReadInputRegisters(words) => words,
                other => panic!("a read of input registers answered {other:?}"),
            })
    }

    /// Function 6: one holding register.
    pub fn write_register(&mut self, address: u16, value: u16) -> Result<(), ExceptionCode> {
        self.call(Request::WriteSingleRegister(address, value))
            .map(|response| match response {
                Response::WriteSingleRegister(echoed, written)
                    if (echoed, written) == (address, value) => {}
                other => panic!("a write of {value} to {address} answered {other:?}"),
            })
    }

    /// Function 16: holding registers from `address`.
    pub fn write_registers(&mut self, address: u16, values: &[u16]) -> Result<(), ExceptionCode> {
        self.call(Request::WriteMultipleRegisters(
            address,
            Cow::Borrowed(values),
        ))
        .map(|response| match response {
            Response::WriteMultipleRegisters(echoed, count)
                if (echoed, usize::from(count)) == (address, values.len()) => {}
            other => panic!("a write of {values:?} from {address} answered {other:?}"),
        })
    }

    /// Writes `bytes` as they are, outside any request.
    pub fn send_raw(&mut self, bytes: &[u8]) {
        let stream = &self.stream;
        self.runtime
            .block_on(async {
                let mut sent = 0;
                while sent < bytes.len() {
                    stream.writable().await?;
                    match stream.try_write(&bytes[sent..]) {
                        Ok(count) => sent += count,
                        Err(error) if error.kind() == ErrorKind::WouldBlock => {}
                        Err(error) => return Err(error),
                    }
                }
                Ok(())
            })
            .unwrap_or_else(|error| panic!("the Modbus port takes raw bytes: {error}"));
    }

    /// Sends `bytes` raw and reads exactly `count` bytes back (the answer to a request sent
    /// raw), sending them again as [`Self::try_call`] does a request lost on its way in.
    pub fn raw_exchange(&mut self, bytes: &[u8], count: usize) -> Vec<u8> {
        for _ in 0..=self.retries {
            self.send_raw(bytes);
            if let Some(answer) = self.read_raw(count) {
                return answer;
            }
            self.no_answer()
                .unwrap_or_else(|found| panic!("after {bytes:02x?} was lost: {found}"));
            self.retried += 1;
        }
        panic!("no answer to {bytes:02x?}, sent {} times", self.retries + 1)
    }

    /// Reads exactly `count` raw bytes, or `None` when none came while the board's time ran
    /// [`ANSWER_TICKS`].
    fn read_raw(&mut self, count: usize) -> Option<Vec<u8>> {
        let stream = &self.stream;
        let clock = &self.clock;
        let from = clock.tick();
        let asked = Instant::now();
        let mut bytes = vec![0u8; count];
        let mut filled = 0;
        let read = self.runtime.block_on(async {
            while filled < count {
                let step = Duration::from_millis(2);
                match tokio::time::timeout(step, stream.readable()).await {
                    Ok(ready) => ready?,
                    Err(_) => {
                        let waited = asked.elapsed();
                        let lost = waited >= ANSWER_WALL_MIN && clock.tick() >= from + ANSWER_TICKS;
                        if filled == 0 && (lost || waited >= ANSWER_WALL_MAX) {
                            return Ok(false);
                        }
                        if waited >= ANSWER_WALL_MAX {
                            return Err(io::Error::from(ErrorKind::TimedOut));
                        }
                        continue;
                    }
                }
                match stream.try_read(&mut bytes[filled..]) {
                    Ok(0) => return Err(io::Error::from(ErrorKind::UnexpectedEof)),
                    Ok(received) => filled += received,
                    Err(error) if error.kind() == ErrorKind::WouldBlock => {}
                    Err(error) => return Err(error),
                }
            }
            Ok(true)
        });
        match read {
            Ok(true) => Some(bytes),
            Ok(false) => None,
            Err(error) => panic!("{filled} of {count} bytes, then: {error}"),
        }
    }

    /// Checks that nothing arrives within `quiet`; `Err` shows what did.
    pub fn expect_silence(&mut self, quiet: Duration) -> Result<(), String> {
        let stream = &self.stream;
        let mut bytes = [0u8; 256];
        let received = self.runtime.block_on(async {
            tokio::time::timeout(quiet, async {
                loop {
                    stream.readable().await?;
                    match stream.try_read(&mut bytes) {
                        Ok(count) => return Ok(count),
                        Err(error) if error.kind() == ErrorKind::WouldBlock => {}
                        Err(error) => return Err(error),
                    }
                }
            })
            .await
        });
        match received {
            Err(_) => Ok(()),
            Ok(Ok(0)) => Err("the Modbus port closed the connection".into()),
            Ok(Ok(count)) => Err(format!("unsolicited bytes: {:02x?}", &bytes[..count])),
            Ok(Err(error)) => Err(format!("the Modbus port failed: {error}")),
        }
    }
}

/// The connection, shared by the client and [`Master`]'s raw bytes.
struct Shared(Arc<TcpStream>);

impl AsyncRead for Shared {
    fn poll_read(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<io::Result<()>> {
        loop {
            ready!(self.0.poll_read_ready(cx))?;
            match self.0.try_read(buf.initialize_unfilled()) {
                Ok(count) => {
                    buf.advance(count);
                    return Poll::Ready(Ok(()));
                }
                Err(error) if error.kind() == ErrorKind::WouldBlock => {}
                Err(error) => return Poll::Ready(Err(error)),
            }
        }
    }
}

impl AsyncWrite for Shared {
    fn poll_write(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        bytes: &[u8],
    ) -> Poll<io::Result<usize>> {
        loop {
            ready!(self.0.poll_write_ready(cx))?;
            match self.0.try_write(bytes) {
                Ok(count) => return Poll::Ready(Ok(count)),
                Err(error) if error.kind() == ErrorKind::WouldBlock => {}
                Err(error) => return Poll::Ready(Err(error)),
            }
        }
    }

    fn poll_flush(self: Pin<&mut Self>, _: &mut Context<'_>) -> Poll<io::Result<()>> {
        Poll::Ready(Ok(()))
    }

    fn poll_shutdown(self: Pin<&mut Self>, _: &mut Context<'_>) -> Poll<io::Result<()>> {
        Poll::Ready(Ok(()))
    }
}

/// RTU frames built by hand, for what the client does not send: CRC-16/MODBUS (reflected
/// polynomial 0xA001, initial 0xFFFF), low byte first.
pub mod frame {
    /// The CRC of `bytes`.
    pub fn crc(bytes: &[u8]) -> u16 {
        let mut crc = 0xffff_u16;
        for &byte in bytes {
            crc ^= u16::from(byte);
            for _ in 0..8 {
                crc = if crc & 1 != 0 {
                    (crc >> 1) ^ 0xa001
                } else {
                    crc >> 1
                };
            }
        }
        crc
    }

    /// `slave`, `function` and `data` with their CRC.
    pub fn build(slave: u8, function: u8, data: &[u8]) -> Vec<u8> {
        let mut frame = vec![slave, function];
        frame.extend_from_slice(data);
        let crc = crc(&frame);
        frame.extend_from_slice(&crc.to_le_bytes());
        frame
    }

    /// Function 6 to `slave`: `value` into holding register `address`.
    pub fn write_register(slave: u8, address: u16, value: u16) -> Vec<u8> {
        let mut data = address.to_be_bytes().to_vec();
        data.extend_from_slice(&value.to_be_bytes());
        build(slave, 6, &data)
    }

    /// Function 3 or 4 to `slave`: `count` registers from `address`.
    pub fn read(slave: u8, function: u8, address: u16, count: u16) -> Vec<u8> {
        let mut data = address.to_be_bytes().to_vec();
        data.extend_from_slice(&count.to_be_bytes());
        build(slave, function, &data)
    }

    /// `frame` with its CRC's bits flipped by `mask` (not 0): a corrupt CRC.
    pub fn corrupt(mut frame: Vec<u8>, mask: u16) -> Vec<u8> {
        assert_ne!(mask, 0, "a mask that changes the CRC");
        let len = frame.len();
        let crc = u16::from_le_bytes([frame[len - 2], frame[len - 1]]) ^ mask;
        frame[len - 2..].copy_from_slice(&crc.to_le_bytes());
        frame
    }
}
