//! The host end of the firmware's lockstep plant link (the `cosim` image): two FIFOs in a
//! temporary directory that QEMU runs in, a [`PlantLink`] over them, and a thread that serves a
//! [`Plant`] until the firmware ends.
//!
//! The firmware writes a [`Message`] for every level its output applies and, at the start of
//! every cycle, a sample request, then waits for the answer; with an encoder it also takes the
//! samples of each cycle (a stream request). QEMU runs no instruction while it waits, so under
//! `-icount` the firmware sees no time pass however long the plant computes. The wire format is
//! defined in the firmware (`firmware/src/board/qemu/plant_link.rs`) and mirrored here:
//! fixed-size little-endian records, firmware → host `tick: u64, kind: u32, value: i32`
//! (16 bytes), host → firmware `tick: u64, count: i32` (12 bytes).

use std::fs::{File, OpenOptions};
use std::io::{self, ErrorKind, Read, Write};
use std::os::unix::fs::OpenOptionsExt;
use std::path::Path;
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

use rustix::fs::{Mode, OFlags, CWD};
use tempfile::TempDir;

use crate::LaunchError;

/// The rate of the ticks the firmware's messages carry: the QEMU board's output clock.
pub const TICK_HZ: u32 = feeder_shared::scenario::QEMU_TICK_HZ;

/// The FIFO the firmware writes its messages to, in QEMU's working directory.
pub const LEVELS_FILE: &str = "plant-levels";
/// The FIFO the firmware reads the plant's samples from, in QEMU's working directory.
pub const SAMPLES_FILE: &str = "plant-samples";
/// Bytes of a message from the firmware.
pub const MESSAGE_BYTES: usize = 16;
/// Bytes of a sample to the firmware.
pub const SAMPLE_BYTES: usize = 12;
/// The `kind` of a level message.
const KIND_LEVEL: u32 = 1;
/// The `kind` of a sample request.
const KIND_SAMPLE: u32 = 2;
/// The `kind` of the encoder's configuration.
const KIND_CONFIG: u32 = 3;
/// The `kind` of a stream request.
const KIND_STREAM: u32 = 4;
/// The `kind` of the driver enable's change.
const KIND_ENABLE: u32 = 5;

/// How long [`PlantThread::join`] keeps releasing a thread that waits for QEMU to open the
/// FIFOs after QEMU has ended.
const RELEASE_LIMIT: Duration = Duration::from_secs(2);

/// A record from the firmware.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Message {
    /// From `tick` (the output's actual tick, µs) on, the output holds the DAC code `code`.
    Level { tick: u64, code: i32 },
    /// The firmware waits for the plant's sample at `tick`.
    SampleRequest { tick: u64 },
    /// The encoder is sampled at every multiple of `interval_ticks` and counts `resolution_nm`.
    Config {
        interval_ticks: u64,
        resolution_nm: i32,
    },
    /// The firmware takes the samples up to `tick`: a header (`tick`, how many follow), then
    /// those.
    StreamRequest { tick: u64 },
    /// From `tick` (the last level's) on, the driver is enabled (`on`) or not.
    Enable { tick: u64, on: bool },
}

impl Message {
    /// Reads a record; `None` for an unknown kind.
    pub fn decode(bytes: &[u8; MESSAGE_BYTES]) -> Option<Self> {
        let tick = u64::from_le_bytes(bytes[..8].try_into().ok()?);
        let kind = u32::from_le_bytes(bytes[8..12].try_into().ok()?);
        let value = i32::from_le_bytes(bytes[12..].try_into().ok()?);
        match kind {
            KIND_LEVEL => Some(Message::Level { tick, code: value }),
            KIND_SAMPLE => Some(Message::SampleRequest { tick }),
            KIND_CONFIG => Some(Message::Config {
                interval_ticks: tick,
                resolution_nm: value,
            }),
            KIND_STREAM => Some(Message::StreamRequest { tick }),
            KIND_ENABLE => Some(Message::Enable {
                tick,
                on: value != 0,
            }),
            _ => None,
        }
    }

    /// The record as the firmware writes it.
    pub fn encode(&self) -> [u8; MESSAGE_BYTES] {
        let (tick, kind, value) = match *self {
            Message::Level { tick, code } => (tick, KIND_LEVEL, code),
            Message::SampleRequest { tick } => (tick, KIND_SAMPLE, 0),
            Message::Config {
                interval_ticks,
                resolution_nm,
            } => (interval_ticks, KIND_CONFIG, resolution_nm),
            Message::StreamRequest { tick } => (tick, KIND_STREAM, 0),
            Message::Enable { tick, on } => (tick, KIND_ENABLE, i32::from(on)),
        };
        let mut bytes = [0; MESSAGE_BYTES];
        bytes[..8].copy_from_slice(&tick.to_le_bytes());
        bytes[8..12].copy_from_slice(&kind.to_le_bytes());
        bytes[12..].copy_from_slice(&value.to_le_bytes());
        bytes
    }
}

/// The answer to a sample request at `tick`: the encoder count.
pub fn encode_sample(tick: u64, count: i32) -> [u8; SAMPLE_BYTES] {
    let mut bytes = [0; SAMPLE_BYTES];
    bytes[..8].copy_from_slice(&tick.to_le_bytes());
    bytes[8..].copy_from_slice(&count.to_le_bytes());
    bytes
}

/// A plant on the host: it takes every level the firmware applies and answers every sample
/// request, in the firmware's order and with its ticks.
pub trait Plant {
    /// From `tick` on the output holds DAC code `code`.
    fn level(&mut self, tick: u64, code: i32);
    /// From `tick` on the driver is enabled (`on`) or not: a disabled driver drives nothing,
    /// whatever the code.
    fn enable(&mut self, tick: u64, on: bool);
    /// The encoder count at `tick`.
    fn sample(&mut self, tick: u64) -> i32;
    /// The firmware samples the encoder at every multiple of `interval_ticks` and reads
    /// `resolution_nm` per count; an error says why this plant cannot serve that.
    fn configure(&mut self, interval_ticks: u64, resolution_nm: i32) -> Result<(), String>;
    /// The samples not yet taken up to `tick` (every interval sample and every sample answered),
    /// in time order, as `(tick, count)`.
    fn stream(&mut self, tick: u64) -> Vec<(u64, i32)>;
}

/// The plant of the link's proof: the sample is the running sum of the level codes received,
/// modulo 2³¹. Deterministic, and sensitive to every level and to the order of the exchanges.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct EchoPlant {
    sum: u32,
}

impl Plant for EchoPlant {
    fn level(&mut self, _tick: u64, code: i32) {
        self.sum = self.sum.wrapping_add(code as u32) & (u32::MAX >> 1);
    }

    /// The echo ignores the enable.
    fn enable(&mut self, _tick: u64, _on: bool) {}

    fn sample(&mut self, _tick: u64) -> i32 {
        self.sum as i32
    }

    fn configure(&mut self, _interval_ticks: u64, _resolution_nm: i32) -> Result<(), String> {
        Ok(())
    }

    /// The sum so far, once.
    fn stream(&mut self, tick: u64) -> Vec<(u64, i32)> {
        vec![(tick, self.sum as i32)]
    }
}

/// What a served link carried.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LinkCounts {
    /// Level messages received.
    pub levels: u64,
    /// Samples answered.
    pub samples: u64,
}

/// A temporary directory with the link's two FIFOs, removed when dropped.
pub struct PlantDir {
    dir: TempDir,
}

impl PlantDir {
    /// Creates the directory and the FIFOs [`LEVELS_FILE`] and [`SAMPLES_FILE`] in it.
    pub fn new() -> io::Result<Self> {
        let dir = tempfile::Builder::new().prefix("feeder-plant-").tempdir()?;
        for name in [LEVELS_FILE, SAMPLES_FILE] {
            rustix::fs::mkfifoat(CWD, dir.path().join(name), Mode::RUSR | Mode::WUSR)?;
        }
        Ok(PlantDir { dir })
    }

    /// The directory, to run QEMU in.
    pub fn path(&self) -> &Path {
        self.dir.path()
    }

    /// Lets a [`PlantLink::open`] that waits for a firmware that will never come go on: opens
    /// the other end of each FIFO without waiting, to be called until the link has ended (the
    /// link's opens come one after the other). The samples' reader is returned and must be kept
    /// open until then; the levels' writer is closed at once, so the link then reads the end of
    /// the firmware's messages.
    fn release(&self) -> Option<File> {
        let nonblocking = OFlags::NONBLOCK.bits() as i32;
        let samples = OpenOptions::new()
            .read(true)
            .custom_flags(nonblocking)
            .open(self.path().join(SAMPLES_FILE))
            .ok();
        // Fails (ENXIO) when nobody waits to read: then nothing is to be released.
        let _ = OpenOptions::new()
            .write(true)
            .custom_flags(nonblocking)
            .open(self.path().join(LEVELS_FILE));
        samples
    }
}

/// The host's ends of the link: the firmware's messages in, the plant's samples out.
pub struct PlantLink {
    levels: File,
    samples: File,
}

impl PlantLink {
    /// Opens the FIFOs in `dir` in the firmware's order: [`SAMPLES_FILE`] for writing, then
    /// [`LEVELS_FILE`] for reading. Each open waits until the firmware has opened its end.
    pub fn open(dir: &Path) -> io::Result<Self> {
        let samples = OpenOptions::new()
            .write(true)
            .open(dir.join(SAMPLES_FILE))?;
        let levels = File::open(dir.join(LEVELS_FILE))?;
        Ok(PlantLink { levels, samples })
    }

    /// The firmware's next message, waiting for it; `None` once the firmware has ended.
    pub fn receive(&mut self) -> io::Result<Option<Message>> {
        let mut bytes = [0; MESSAGE_BYTES];
        let mut received = 0;
        while received < MESSAGE_BYTES {
            match self.levels.read(&mut bytes[received..]) {
                Ok(0) if received == 0 => return Ok(None),
                Ok(0) => {
                    return Err(io::Error::new(
                        ErrorKind::UnexpectedEof,
                        format!("the firmware ended after {received} bytes of a message"),
                    ))
                }
                Ok(n) => received += n,
                Err(error) if error.kind() == ErrorKind::Interrupted => {}
                Err(error) => return Err(error),
            }
        }
        Message::decode(&bytes).map(Some).ok_or_else(|| {
            io::Error::new(
                ErrorKind::InvalidData,
                format!("not a message from the firmware: {bytes:02x?}"),
            )
        })
    }

    /// Answers the sample request at `tick` with `count`.
    pub fn answer(&mut self, tick: u64, count: i32) -> io::Result<()> {
        self.samples.write_all(&encode_sample(tick, count))
    }

    /// Serves `plant` until the firmware ends: every level to the plant, every sample request
    /// answered with the plant's sample at its tick.
    pub fn serve<P: Plant>(&mut self, plant: &mut P) -> io::Result<LinkCounts> {
        let mut counts = LinkCounts::default();
        while let Some(message) = self.receive()? {
            match message {
                Message::Level { tick, code } => {
                    plant.level(tick, code);
                    counts.levels += 1;
                }
                Message::SampleRequest { tick } => {
                    let count = plant.sample(tick);
                    self.answer(tick, count)?;
                    counts.samples += 1;
                }
                Message::Config {
                    interval_ticks,
                    resolution_nm,
                } => plant
                    .configure(interval_ticks, resolution_nm)
                    .map_err(|reason| io::Error::new(ErrorKind::InvalidInput, reason))?,
                Message::Enable { tick, on } => plant.enable(tick, on),
                Message::StreamRequest { tick } => {
                    let samples = plant.stream(tick);
                    self.answer(tick, samples.len() as i32)?;
                    for (tick, count) in samples {
                        self.answer(tick, count)?;
                    }
                }
            }
        }
        Ok(counts)
    }
}

/// A plant served on its own thread over a [`PlantDir`]'s link.
pub struct PlantThread<P> {
    dir: PlantDir,
    handle: JoinHandle<io::Result<(P, LinkCounts)>>,
}

impl<P: Plant + Send + 'static> PlantThread<P> {
    /// Creates the FIFOs and starts serving `plant` on them: the thread waits until QEMU,
    /// started in [`PlantThread::dir`], opens them.
    pub fn start(plant: P) -> io::Result<Self> {
        let dir = PlantDir::new()?;
        let path = dir.path().to_path_buf();
        let handle = thread::Builder::new().name("plant".into()).spawn(move || {
            let mut plant = plant;
            let mut link = PlantLink::open(&path)?;
            let counts = link.serve(&mut plant)?;
            Ok((plant, counts))
        })?;
        Ok(PlantThread { dir, handle })
    }

    /// The directory with the FIFOs, QEMU's working directory.
    pub fn dir(&self) -> &Path {
        self.dir.path()
    }

    /// Waits for the plant once QEMU has ended, and returns it with the link's counts. A thread
    /// still waiting for QEMU to open the FIFOs is released first.
    pub fn join(self) -> Result<(P, LinkCounts), LaunchError> {
        let started = Instant::now();
        let mut kept = Vec::new();
        while !self.handle.is_finished() && started.elapsed() < RELEASE_LIMIT {
            kept.extend(self.dir.release());
            thread::sleep(Duration::from_millis(10));
        }
        if !self.handle.is_finished() {
            return Err(LaunchError::Plant(io::Error::other(
                "the plant thread did not end after QEMU",
            )));
        }
        self.handle
            .join()
            .map_err(|_| LaunchError::Plant(io::Error::other("the plant thread panicked")))?
            .map_err(LaunchError::Plant)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_message_reads_back_as_it_was_written() {
        for message in [
            Message::Level {
                tick: 0x0102_0304_0506_0708,
                code: -5,
            },
            Message::SampleRequest { tick: 40_000 },
            Message::Config {
                interval_ticks: 250,
                resolution_nm: 1000,
            },
            Message::StreamRequest { tick: 60_000 },
            Message::Enable {
                tick: 70_000,
                on: true,
            },
            Message::Enable {
                tick: 80_000,
                on: false,
            },
        ] {
            assert_eq!(Message::decode(&message.encode()), Some(message));
        }
        let level = Message::Level {
            tick: 1,
            code: 2048,
        }
        .encode();
        assert_eq!(level, [1, 0, 0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 8, 0, 0]);
        assert_eq!(
            encode_sample(2, -1),
            [2, 0, 0, 0, 0, 0, 0, 0, 0xff, 0xff, 0xff, 0xff]
        );
    }

    #[test]
    fn an_unknown_kind_is_refused() {
        let mut bytes = Message::SampleRequest { tick: 3 }.encode();
        bytes[8] = 7;
        assert_eq!(Message::decode(&bytes), None);
    }

    #[test]
    fn the_echo_plant_sums_the_codes_modulo_2_to_the_31() {
        let mut plant = EchoPlant::default();
        plant.level(0, i32::MAX);
        plant.level(1, 3);
        assert_eq!(plant.sample(2), 2);
    }

    /// A firmware stand-in on the other ends of the FIFOs: the link answers each request with
    /// the sum so far, and ends when the firmware closes its end.
    #[test]
    fn the_thread_serves_the_plant_until_the_firmware_closes_the_link() {
        let thread = PlantThread::start(EchoPlant::default()).unwrap();
        let mut samples = File::open(thread.dir().join(SAMPLES_FILE)).unwrap();
        let mut levels = OpenOptions::new()
            .write(true)
            .open(thread.dir().join(LEVELS_FILE))
            .unwrap();
        let mut answer = [0; SAMPLE_BYTES];
        for (tick, code) in [(0, 2048), (10, 100), (20, -50)] {
            levels
                .write_all(&Message::Level { tick, code }.encode())
                .unwrap();
            levels
                .write_all(&Message::SampleRequest { tick }.encode())
                .unwrap();
            samples.read_exact(&mut answer).unwrap();
            assert_eq!(answer[..8], tick.to_le_bytes());
        }
        assert_eq!(answer[8..], (2048 + 100 - 50i32).to_le_bytes());
        drop(levels);
        let (_, counts) = thread.join().unwrap();
        assert_eq!(
            counts,
            LinkCounts {
                levels: 3,
                samples: 3
            }
        );
    }

    #[test]
    fn a_thread_whose_firmware_never_came_is_released() {
        let thread = PlantThread::start(EchoPlant::default()).unwrap();
        let (_, counts) = thread.join().unwrap();
        assert_eq!(counts, LinkCounts::default());
    }
}
