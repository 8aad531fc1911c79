//! The configuration's record in flash: [`RECORD_LEN`] bytes, little-endian, a multiple of the
//! flash's 8-byte write unit.
//!
//! | offset | size | field                                                        |
//! |-------:|-----:|--------------------------------------------------------------|
//! |      0 |    4 | magic `FDCF`                                                 |
//! |      4 |    2 | layout version ([`FORMAT_VERSION`])                          |
//! |      6 |    2 | record length in bytes ([`RECORD_LEN`])                      |
//! |      8 |    2 | DAC zero code                                                |
//! |     10 |    2 | DAC linear margin, counts                                    |
//! |     12 |    2 | start-up ramp, cycles                                        |
//! |     14 |    1 | flags: bit 0 encoder reversed, bit 1 closed loop on          |
//! |     15 |    1 | start-up drive: 0 = stroke, 1 = peak acceleration            |
//! |     16 |    8 | DAC counts per m/s² (`f64`)                                  |
//! |     24 |    8 | PWM full-duty acceleration, m/s² (`f64`)                     |
//! |     32 |   32 | limits: min and max frequency (Hz), peak acceleration (m/s²), travel (m) |
//! |     64 |    8 | encoder resolution, m per count (`f64`)                      |
//! |     72 |    8 | part friction coefficient μ (`f64`)                          |
//! |     80 |   16 | track full after, empty after, s (`f64` each)                |
//! |     96 |   24 | start-up frequency (Hz), duty, stroke (m) or acceleration (m/s²) |
//! |    120 |    1 | Modbus slave address                                         |
//! |    121 |    1 | line flags: bit 0 no parity (8N2), bit 1 console watchdog on |
//! |    122 |    2 | link timeout, ms (0: off)                                    |
//! |    124 |    4 | Modbus rate, baud                                            |
//! |    128 |    4 | reserved, zero                                               |
//! |    132 |    4 | CRC-32 (IEEE, reflected) of bytes 0..132                     |
//!
//! Erased flash (all `0xFF`) reads as no record. Layout 1, the first, was 128 bytes long with
//! zeros at 120..124 and its CRC at 124: it is read with the line's settings at their defaults
//! ([`LineSetup::DEFAULT`]), so a board keeps its calibration across the update. A record of
//! any other layout version is refused by name ([`RecordError::UnsupportedVersion`]). A record
//! that decodes is still checked as a whole before it is used ([`load`]).

use super::{BoardFacts, ConfigError, Configuration, EncoderSetup, LineSetup};
use crate::closed_loop::TrackConfig;
use crate::drive::{DacCalibration, PwmCalibration};
use crate::recipe::{crc32, RecordError};
use crate::settings::Settings;
use crate::waveform::{Drive, Limits};

/// Size of the record in bytes.
pub const RECORD_LEN: usize = 136;
/// First four bytes of the record.
pub const MAGIC: [u8; 4] = *b"FDCF";
/// The layout this code writes and reads.
pub const FORMAT_VERSION: u16 = 2;
/// The first layout, still read: without the line's settings.
const FIRST_VERSION: u16 = 1;
/// The first layout's length.
const FIRST_LEN: usize = 128;

const CRC_AT: usize = RECORD_LEN - 4;
const LINE_NO_PARITY: u8 = 1;
const LINE_CONSOLE_WATCHDOG: u8 = 2;
const FLAG_REVERSED: u8 = 1;
const FLAG_CLOSED_LOOP: u8 = 2;
const DRIVE_STROKE: u8 = 0;
const DRIVE_ACCEL: u8 = 1;

/// Why a stored configuration was not used.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum LoadError {
    /// The record is missing, corrupt or of another layout.
    Record(RecordError),
    /// The record is intact but refused on this board.
    Refused(ConfigError),
}

impl core::fmt::Display for LoadError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            LoadError::Record(RecordError::Empty) => f.write_str("no configuration saved"),
            LoadError::Record(error) => write!(f, "{}", error),
            LoadError::Refused(error) => write!(f, "stored configuration refused: {}", error),
        }
    }
}

/// Writes fields one after another.
struct Writer {
    record: [u8; RECORD_LEN],
    at: usize,
}

impl Writer {
    fn put(&mut self, bytes: &[u8]) {
        for (slot, &byte) in self.record.iter_mut().skip(self.at).zip(bytes) {
            *slot = byte;
        }
        self.at += bytes.len();
    }
    fn u16(&mut self, value: u16) {
        self.put(&value.to_le_bytes())
    }
    fn f64(&mut self, value: f64) {
        self.put(&value.to_le_bytes())
    }
}

/// Reads fields one after another.
struct Reader<'a> {
    record: &'a [u8; RECORD_LEN],
    at: usize,
}

impl Reader<'_> {
    fn take<const N: usize>(&mut self) -> [u8; N] {
        let mut bytes = [0u8; N];
        for (byte, &stored) in bytes.iter_mut().zip(self.record.iter().skip(self.at)) {
            *byte = stored;
        }
        self.at += N;
        bytes
    }
    fn u8(&mut self) -> u8 {
        self.take::<1>()[0]
    }
    fn u16(&mut self) -> u16 {
        u16::from_le_bytes(self.take())
    }
    fn u32(&mut self) -> u32 {
        u32::from_le_bytes(self.take())
    }
    fn f64(&mut self) -> f64 {
        f64::from_le_bytes(self.take())
    }
}

/// The record storing `configuration`.
pub fn encode(configuration: &Configuration) -> [u8; RECORD_LEN] {
    let c = configuration;
    let mut out = Writer {
        record: [0u8; RECORD_LEN],
        at: 0,
    };
    let (drive, drive_value) = match c.startup.drive {
        Drive::Stroke { stroke_m } => (DRIVE_STROKE, stroke_m),
        Drive::Accel { accel_mps2 } => (DRIVE_ACCEL, accel_mps2),
    };
    let flags = if c.encoder.reversed { FLAG_REVERSED } else { 0 }
        | if c.closed_loop { FLAG_CLOSED_LOOP } else { 0 };
    out.put(&MAGIC);
    out.u16(FORMAT_VERSION);
    out.u16(RECORD_LEN as u16);
    out.u16(c.dac.zero_code);
    out.u16(c.dac.linear_margin_counts);
    out.u16(c.startup.ramp_cycles);
    out.put(&[flags, drive]);
    out.f64(c.dac.counts_per_mps2);
    out.f64(c.pwm.full_duty_accel_mps2);
    out.f64(c.limits.min_frequency_hz);
    out.f64(c.limits.max_frequency_hz);
    out.f64(c.limits.max_accel_mps2);
    out.f64(c.limits.max_stroke_m);
    out.f64(c.encoder.resolution_m);
    out.f64(c.part_mu);
    out.f64(c.track.full_after_s);
    out.f64(c.track.empty_after_s);
    out.f64(c.startup.frequency_hz);
    out.f64(c.startup.duty);
    out.f64(drive_value);
    let line_flags = if c.line.parity_even {
        0
    } else {
        LINE_NO_PARITY
    } | if c.line.console_watchdog {
        LINE_CONSOLE_WATCHDOG
    } else {
        0
    };
    out.put(&[c.line.modbus_address, line_flags]);
    out.u16(c.line.link_timeout_ms);
    out.put(&c.line.baud.to_le_bytes());
    let crc = crc32(&out.record[..CRC_AT]);
    out.at = CRC_AT;
    out.put(&crc.to_le_bytes());
    out.record
}

/// The configuration stored in `record`, not yet checked as a whole.
pub fn decode(record: &[u8; RECORD_LEN]) -> Result<Configuration, RecordError> {
    if record.iter().all(|&byte| byte == 0xff) {
        return Err(RecordError::Empty);
    }
    let mut input = Reader { record, at: 0 };
    if input.take::<4>() != MAGIC {
        return Err(RecordError::BadMagic);
    }
    let version = input.u16();
    let length = match version {
        FORMAT_VERSION => RECORD_LEN,
        FIRST_VERSION => FIRST_LEN,
        found => return Err(RecordError::UnsupportedVersion { found }),
    };
    let crc_at = length - 4;
    let stored = u32::from_le_bytes(Reader { record, at: crc_at }.take());
    let computed = crc32(&record[..crc_at]);
    if stored != computed {
        return Err(RecordError::CrcMismatch { stored, computed });
    }
    if usize::from(input.u16()) != length {
        return Err(RecordError::Malformed);
    }
    let zero_code = input.u16();
    let linear_margin_counts = input.u16();
    let ramp_cycles = input.u16();
    let flags = input.u8();
    let drive = input.u8();
    if flags & !(FLAG_REVERSED | FLAG_CLOSED_LOOP) != 0 {
        return Err(RecordError::Malformed);
    }
    let counts_per_mps2 = input.f64();
    let full_duty_accel_mps2 = input.f64();
    let limits = Limits {
        min_frequency_hz: input.f64(),
        max_frequency_hz: input.f64(),
        max_accel_mps2: input.f64(),
        max_stroke_m: input.f64(),
    };
    let resolution_m = input.f64();
    let part_mu = input.f64();
    let track = TrackConfig {
        full_after_s: input.f64(),
        empty_after_s: input.f64(),
    };
    let frequency_hz = input.f64();
    let duty = input.f64();
    let drive_value = input.f64();
    let drive = match drive {
        DRIVE_STROKE => Drive::Stroke {
            stroke_m: drive_value,
        },
        DRIVE_ACCEL => Drive::Accel {
            accel_mps2: drive_value,
        },
        _ => return Err(RecordError::Malformed),
    };
    let line = match version {
        FIRST_VERSION => LineSetup::DEFAULT,
        _ => {
            let modbus_address = input.u8();
            let line_flags = input.u8();
            if line_flags & !(LINE_NO_PARITY | LINE_CONSOLE_WATCHDOG) != 0 {
                return Err(RecordError::Malformed);
            }
            LineSetup {
                modbus_address,
                parity_even: line_flags & LINE_NO_PARITY == 0,
                console_watchdog: line_flags & LINE_CONSOLE_WATCHDOG != 0,
                link_timeout_ms: input.u16(),
                baud: input.u32(),
            }
        }
    };
    if input.u32() != 0 {
        return Err(RecordError::Malformed);
    }
    Ok(Configuration {
        dac: DacCalibration {
            zero_code,
            counts_per_mps2,
            linear_margin_counts,
            ..DacCalibration::DEFAULT
        },
        pwm: PwmCalibration {
            full_duty_accel_mps2,
        },
        limits,
        encoder: EncoderSetup {
            resolution_m,
            reversed: flags & FLAG_REVERSED != 0,
        },
        closed_loop: flags & FLAG_CLOSED_LOOP != 0,
        part_mu,
        track,
        startup: Settings {
            frequency_hz,
            duty,
            drive,
            ramp_cycles,
        },
        line,
    })
}

/// The configuration of `record`, checked as a whole for `board`, or why it is not used.
pub fn load(record: &[u8; RECORD_LEN], board: &BoardFacts) -> Result<Configuration, LoadError> {
    let configuration = decode(record).map_err(LoadError::Record)?;
    configuration.check(board).map_err(LoadError::Refused)?;
    Ok(configuration)
}
