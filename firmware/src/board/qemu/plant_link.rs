//! The lockstep link to a plant simulated on the host (feature `cosim`), over semihosting file
//! I/O: the firmware writes what its output applies to one host file and reads the plant's
//! sensor samples from another, and QEMU runs no instruction while a call waits for the host.
//! Under `-icount` virtual time is the instruction count, so it stands still while the host
//! computes: a run is byte-identical however long the plant takes to answer.
//!
//! # Files
//!
//! Two FIFOs with fixed names in QEMU's working directory, opened with `SYS_OPEN` when the board
//! comes up, samples first (each open waits until the host has opened the other end):
//!
//! * `plant-levels`, written by the firmware: its [`Message`]s;
//! * `plant-samples`, read by the firmware: the plant's [`Sample`]s.
//!
//! `feeder_emulator::plant_link` creates them in a temporary directory and starts QEMU there.
//!
//! # Wire format
//!
//! Fixed-size little-endian records, nothing else on either file. The one definition is here;
//! `feeder_emulator::plant_link` mirrors it.
//!
//! | record | bytes | fields |
//! |---|---|---|
//! | [`Message`], firmware → host | 16 | `tick: u64`, `kind: u32`, `value: i32` |
//! | [`Sample`], host → firmware | 12 | `tick: u64`, `count: i32` |
//!
//! `tick` is the output's actual tick (µs of the plan's clock, counted from the output's first
//! restart: the `actual` of the `EVT seg` lines). By `kind`:
//!
//! * `KIND_CONFIG` (in `encoder`, as the next), first after the open: the encoder is sampled
//!   every `tick` ticks (at every multiple of it) and counts `value` nanometres.
//! * [`KIND_LEVEL`]: from `tick` on the output holds the DAC code `value`.
//! * [`KIND_SAMPLE`]: the firmware waits for the plant's capture at `tick` (`value` 0); the
//!   host answers with exactly one [`Sample`] carrying the same `tick` and the encoder count.
//! * [`KIND_ENABLE`]: from `tick`, the last level's, on the driver is enabled (`value` 1) or
//!   not (0); a disabled driver drives nothing, whatever the code. The driver comes up disabled.
//! * `KIND_STREAM`: the firmware takes the samples up to `tick`, a capture it has had: the
//!   host answers with a [`Sample`] carrying `tick` and, as its count, how many follow, then
//!   those: every interval sample not yet taken with a tick up to `tick`, and every capture, in
//!   time order.
//!
//! The output sends a level at every segment it applies and, at every segment that begins a
//! cycle (or idle period), asks for the capture right after it. The closed loop takes the
//! stream once a cycle, below the edge path; each exchange holds a critical section, so the
//! output's messages never come between a request and its answer.

use core::cell::RefCell;

use cortex_m_semihosting::nr::open::{R_BINARY, W_TRUNC_BINARY};
use cortex_m_semihosting::syscall;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::blocking_mutex::Mutex;

/// Bytes of a [`Message`] on the wire.
pub const MESSAGE_BYTES: usize = 16;
/// Bytes of a [`Sample`] on the wire.
pub const SAMPLE_BYTES: usize = 12;
/// [`Message::kind`]: the output holds the DAC code `value` from `tick` on.
pub const KIND_LEVEL: u32 = 1;
/// [`Message::kind`]: the firmware waits for the capture at `tick`.
pub const KIND_SAMPLE: u32 = 2;
/// [`Message::kind`]: from `tick` on the driver is enabled (`value` 1) or not (0).
pub const KIND_ENABLE: u32 = 5;

/// A record from the firmware to the host.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub struct Message {
    pub tick: u64,
    pub kind: u32,
    pub value: i32,
}

impl Message {
    pub fn encode(&self) -> [u8; MESSAGE_BYTES] {
        let mut bytes = [0; MESSAGE_BYTES];
        bytes[..8].copy_from_slice(&self.tick.to_le_bytes());
        bytes[8..12].copy_from_slice(&self.kind.to_le_bytes());
        bytes[12..].copy_from_slice(&self.value.to_le_bytes());
        bytes
    }
}

/// A record from the host to the firmware: the plant's encoder count at `tick`.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub struct Sample {
    pub tick: u64,
    pub count: i32,
}

impl Sample {
    pub fn decode(bytes: &[u8; SAMPLE_BYTES]) -> Self {
        let mut tick = [0; 8];
        let mut count = [0; 4];
        tick.copy_from_slice(&bytes[..8]);
        count.copy_from_slice(&bytes[8..]);
        Sample {
            tick: u64::from_le_bytes(tick),
            count: i32::from_le_bytes(count),
        }
    }
}

/// One of the link's two files.
#[derive(Clone, Copy, PartialEq, Eq, Debug, defmt::Format)]
pub enum Channel {
    /// `plant-levels`.
    Levels,
    /// `plant-samples`.
    Samples,
}

impl Channel {
    /// The file's name in QEMU's working directory, with the terminating NUL that `SYS_OPEN`
    /// wants.
    fn c_name(self) -> &'static str {
        match self {
            Channel::Levels => "plant-levels\0",
            Channel::Samples => "plant-samples\0",
        }
    }
}

/// What can go wrong on the link. None of them is recoverable: the co-simulation has lost its
/// plant.
#[derive(Clone, Copy, PartialEq, Eq, Debug, defmt::Format)]
pub enum LinkError {
    /// `SYS_OPEN` refused the file (no such file in QEMU's working directory, no access).
    Open(Channel),
    /// `SYS_WRITE` failed with `unwritten` of the message's bytes not written (the host closed
    /// its end).
    Write { unwritten: usize },
    /// `SYS_READ` failed.
    Read,
    /// The host closed its end after `received` bytes of a sample.
    Closed { received: usize },
    /// The host answered the sample request at `asked` with a sample for `answered`.
    OutOfStep { asked: u64, answered: u64 },
}

/// The link's two open files (semihosting handles).
pub struct PlantLink {
    levels: usize,
    samples: usize,
    /// The tick of the last level sent.
    level_tick: u64,
}

impl PlantLink {
    /// Opens `plant-samples` for reading, then `plant-levels` for writing; with FIFOs each
    /// open waits until the host has opened the other end, in the same order. The samples come
    /// first so that a run without the link's FIFOs fails without creating a file.
    pub fn open() -> Result<Self, LinkError> {
        let samples = open(Channel::Samples, R_BINARY)?;
        let levels = open(Channel::Levels, W_TRUNC_BINARY)?;
        Ok(PlantLink {
            levels,
            samples,
            level_tick: 0,
        })
    }

    /// Writes all of `bytes` to `plant-levels`.
    pub fn send(&mut self, bytes: &[u8]) -> Result<(), LinkError> {
        let mut rest = bytes;
        while !rest.is_empty() {
            // SAFETY: SYS_WRITE reads `rest.len()` bytes from `rest`, which outlives the call.
            let unwritten = unsafe { syscall!(WRITE, self.levels, rest.as_ptr(), rest.len()) };
            if unwritten >= rest.len() {
                return Err(LinkError::Write { unwritten });
            }
            rest = &rest[rest.len() - unwritten..];
        }
        Ok(())
    }

    /// Fills all of `buffer` from `plant-samples`, waiting until the host has written it.
    pub fn receive(&mut self, buffer: &mut [u8]) -> Result<(), LinkError> {
        let mut received = 0;
        while received < buffer.len() {
            let rest = &mut buffer[received..];
            // SAFETY: SYS_READ writes at most `rest.len()` bytes into `rest`, which outlives the
            // call.
            let unread = unsafe { syscall!(READ, self.samples, rest.as_mut_ptr(), rest.len()) };
            if unread > rest.len() {
                return Err(LinkError::Read);
            }
            if unread == rest.len() {
                return Err(LinkError::Closed { received });
            }
            received += rest.len() - unread;
        }
        Ok(())
    }

    /// Tells the plant that the output holds `code` from `tick` on.
    pub fn send_level(&mut self, tick: u64, code: u32) -> Result<(), LinkError> {
        let value = i32::try_from(code).unwrap_or(i32::MAX);
        self.level_tick = tick;
        self.send(
            &Message {
                tick,
                kind: KIND_LEVEL,
                value,
            }
            .encode(),
        )
    }

    /// Tells the plant that the driver is enabled (`on`) or not from the last level's tick on:
    /// the control loop switches it at the start of the segment whose level was sent last.
    pub fn send_enable(&mut self, on: bool) -> Result<(), LinkError> {
        self.send(
            &Message {
                tick: self.level_tick,
                kind: KIND_ENABLE,
                value: i32::from(on),
            }
            .encode(),
        )
    }

    /// Reads one [`Sample`].
    pub fn receive_sample(&mut self) -> Result<Sample, LinkError> {
        let mut bytes = [0; SAMPLE_BYTES];
        self.receive(&mut bytes)?;
        Ok(Sample::decode(&bytes))
    }

    /// Asks the plant for its sample at `tick` and waits for it: the encoder count.
    pub fn sample(&mut self, tick: u64) -> Result<i32, LinkError> {
        self.send(
            &Message {
                tick,
                kind: KIND_SAMPLE,
                value: 0,
            }
            .encode(),
        )?;
        let sample = self.receive_sample()?;
        if sample.tick != tick {
            return Err(LinkError::OutOfStep {
                asked: tick,
                answered: sample.tick,
            });
        }
        Ok(sample.count)
    }
}

/// Opens `channel`'s file with the semihosting open mode `mode`.
fn open(channel: Channel, mode: usize) -> Result<usize, LinkError> {
    let name = channel.c_name();
    // SAFETY: SYS_OPEN reads the name's `len - 1` bytes (without the NUL), which is 'static.
    let handle = unsafe { syscall!(OPEN, name.as_ptr(), mode, name.len() - 1) };
    if handle as isize == -1 {
        return Err(LinkError::Open(channel));
    }
    Ok(handle)
}

/// The link, shared by the output stage (levels and captures, at its edges) and the position
/// sensor (the stream, below the edge path).
static LINK: Mutex<CriticalSectionRawMutex, RefCell<Option<PlantLink>>> =
    Mutex::new(RefCell::new(None));

/// Opens the link when the board comes up; without it the run ends (see [`lost`]).
pub fn open_or_end() {
    match PlantLink::open() {
        Ok(link) => LINK.lock(|cell| *cell.borrow_mut() = Some(link)),
        Err(error) => lost(error),
    }
}

/// Runs `exchange` on the link in a critical section; a failed exchange ends the run.
pub fn with<T>(exchange: impl FnOnce(&mut PlantLink) -> Result<T, LinkError>) -> T {
    let result = LINK.lock(|cell| match cell.borrow_mut().as_mut() {
        Some(link) => exchange(link),
        None => Err(LinkError::Closed { received: 0 }),
    });
    result.unwrap_or_else(|error| lost(error))
}

/// The plant is gone: ends the run as a fault does, with the output at zero and the driver
/// disabled, the error logged and a failure exit code.
pub fn lost(error: LinkError) -> ! {
    cortex_m::interrupt::disable();
    crate::ports::write_all(&super::SAFE_STATE_WRITES);
    defmt::error!("plant link: {}", error);
    super::exit::after_fault()
}
