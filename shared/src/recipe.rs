//! Recipes: named parameter sets stored as fixed-size binary records, one per slot.
//!
//! A record is [`RECORD_LEN`] bytes, little-endian, a multiple of the flash's 8-byte write unit:
//!
//! | offset | size | field                                                   |
//! |-------:|-----:|---------------------------------------------------------|
//! |      0 |    4 | magic `FDRC`                                            |
//! |      4 |    2 | format version ([`FORMAT_VERSION`])                     |
//! |      6 |    1 | slot number                                             |
//! |      7 |    1 | drive: 0 = stroke, 1 = peak acceleration                |
//! |      8 |    8 | frequency, Hz (`f64`)                                   |
//! |     16 |    8 | duty cycle (`f64`)                                      |
//! |     24 |    8 | stroke in m or peak acceleration in m/s² (`f64`)        |
//! |     32 |    2 | ramp length, cycles                                     |
//! |     34 |    2 | reserved, zero                                          |
//! |     36 |    4 | CRC-32 (IEEE, reflected) of bytes 0..36                 |
//!
//! Erased flash (all `0xFF`) reads as an empty slot. A record that is empty, corrupt, of another
//! format version, stored for another slot or no longer valid on the machine loads nothing and
//! names the reason ([`RecordError`]).

use core::fmt;

use crate::error::Error;
use crate::settings::{Applied, Machine, Settings};
use crate::waveform::Drive;

/// Number of recipe slots.
pub const RECIPE_SLOTS: usize = 8;
/// Size of one record in bytes.
pub const RECORD_LEN: usize = 40;
/// First four bytes of every record.
pub const MAGIC: [u8; 4] = *b"FDRC";
/// The record format this code writes and reads.
pub const FORMAT_VERSION: u16 = 1;

const VERSION_AT: usize = 4;
const SLOT_AT: usize = 6;
const DRIVE_AT: usize = 7;
const FREQUENCY_AT: usize = 8;
const DUTY_AT: usize = 16;
const DRIVE_VALUE_AT: usize = 24;
const RAMP_AT: usize = 32;
const RESERVED_AT: usize = 34;
const CRC_AT: usize = 36;

const DRIVE_STROKE: u8 = 0;
const DRIVE_ACCEL: u8 = 1;
const ERASED: u8 = 0xff;

/// A recipe slot number, `0..RECIPE_SLOTS`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RecipeSlot(u8);

impl RecipeSlot {
    /// The slot with this number, if there is one.
    pub const fn new(number: u8) -> Option<Self> {
        if (number as usize) < RECIPE_SLOTS {
            Some(RecipeSlot(number))
        } else {
            None
        }
    }

    pub const fn number(self) -> u8 {
        self.0
    }

    /// Zero-based index, for arrays of slots and flash offsets.
    pub const fn index(self) -> usize {
        self.0 as usize
    }

    /// Every slot in order.
    pub fn all() -> impl Iterator<Item = RecipeSlot> {
        (0..RECIPE_SLOTS as u8).map(RecipeSlot)
    }
}

impl fmt::Display for RecipeSlot {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.0)
    }
}

/// Why a stored record was not used.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RecordError {
    /// The slot is erased: nothing was ever saved there.
    Empty,
    /// The record does not start with [`MAGIC`].
    BadMagic,
    /// The record has a format version this code does not read.
    UnsupportedVersion { found: u16 },
    /// The stored CRC does not match the record's contents.
    CrcMismatch { stored: u32, computed: u32 },
    /// The record was written for another slot.
    WrongSlot { found: u8, expected: RecipeSlot },
    /// The CRC matches but a field holds a value no writer produces.
    Malformed,
    /// The record is intact but its parameters are refused on this machine.
    Rejected(Error),
}

impl RecordError {
    /// One word for `recipe list`.
    pub const fn short_name(&self) -> &'static str {
        match self {
            RecordError::Empty => "empty",
            RecordError::BadMagic | RecordError::CrcMismatch { .. } | RecordError::Malformed => {
                "corrupt"
            }
            RecordError::UnsupportedVersion { found } if *found < FORMAT_VERSION => "old-version",
            RecordError::UnsupportedVersion { .. } => "new-version",
            RecordError::WrongSlot { .. } => "wrong-slot",
            RecordError::Rejected(_) => "rejected",
        }
    }
}

impl fmt::Display for RecordError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RecordError::Empty => f.write_str("no recipe saved in this slot"),
            RecordError::BadMagic => f.write_str("corrupt record: no recipe header"),
            RecordError::UnsupportedVersion { found } if *found < FORMAT_VERSION => write!(
                f,
                "record format version {} is older than the supported version {}",
                found, FORMAT_VERSION
            ),
            RecordError::UnsupportedVersion { found } => write!(
                f,
                "record format version {} is newer than the supported version {}",
                found, FORMAT_VERSION
            ),
            RecordError::CrcMismatch { stored, computed } => write!(
                f,
                "corrupt record: CRC 0x{:08x} stored, 0x{:08x} computed",
                stored, computed
            ),
            RecordError::WrongSlot { found, expected } => {
                write!(f, "record belongs to slot {}, not slot {}", found, expected)
            }
            RecordError::Malformed => f.write_str("corrupt record: invalid field"),
            RecordError::Rejected(error) => write!(f, "stored parameters refused: {}", error),
        }
    }
}

/// The algorithm of [`crc32`], bit by bit: a lookup table would cost 1 KiB of flash for 36 bytes
/// per record.
const CRC32: crc::Crc<u32, crc::NoTable> =
    crc::Crc::<u32, crc::NoTable>::new(&crc::CRC_32_ISO_HDLC);

/// CRC-32 (IEEE 802.3: polynomial 0x04C11DB7 reflected, initial value and final XOR all ones).
pub fn crc32(bytes: &[u8]) -> u32 {
    CRC32.checksum(bytes)
}

/// The record storing `settings` in `slot`.
pub fn encode(slot: RecipeSlot, settings: &Settings) -> [u8; RECORD_LEN] {
    let mut record = [0u8; RECORD_LEN];
    let (drive, drive_value) = match settings.drive {
        Drive::Stroke { stroke_m } => (DRIVE_STROKE, stroke_m),
        Drive::Accel { accel_mps2 } => (DRIVE_ACCEL, accel_mps2),
    };
    put(&mut record, 0, &MAGIC);
    put(&mut record, VERSION_AT, &FORMAT_VERSION.to_le_bytes());
    put(&mut record, SLOT_AT, &[slot.number()]);
    put(&mut record, DRIVE_AT, &[drive]);
    put(
        &mut record,
        FREQUENCY_AT,
        &settings.frequency_hz.to_le_bytes(),
    );
    put(&mut record, DUTY_AT, &settings.duty.to_le_bytes());
    put(&mut record, DRIVE_VALUE_AT, &drive_value.to_le_bytes());
    put(&mut record, RAMP_AT, &settings.ramp_cycles.to_le_bytes());
    let crc = crc32(&record[..CRC_AT]);
    put(&mut record, CRC_AT, &crc.to_le_bytes());
    record
}

/// The settings stored in `record`, read from `slot`.
pub fn decode(record: &[u8; RECORD_LEN], slot: RecipeSlot) -> Result<Settings, RecordError> {
    if record.iter().all(|&byte| byte == ERASED) {
        return Err(RecordError::Empty);
    }
    if take::<4>(record, 0) != MAGIC {
        return Err(RecordError::BadMagic);
    }
    let version = u16::from_le_bytes(take(record, VERSION_AT));
    if version != FORMAT_VERSION {
        return Err(RecordError::UnsupportedVersion { found: version });
    }
    let stored = u32::from_le_bytes(take(record, CRC_AT));
    let computed = crc32(&record[..CRC_AT]);
    if stored != computed {
        return Err(RecordError::CrcMismatch { stored, computed });
    }
    let [found] = take(record, SLOT_AT);
    if found != slot.number() {
        return Err(RecordError::WrongSlot {
            found,
            expected: slot,
        });
    }
    let drive_value = f64::from_le_bytes(take(record, DRIVE_VALUE_AT));
    let drive = match take(record, DRIVE_AT) {
        [DRIVE_STROKE] => Drive::Stroke {
            stroke_m: drive_value,
        },
        [DRIVE_ACCEL] => Drive::Accel {
            accel_mps2: drive_value,
        },
        _ => return Err(RecordError::Malformed),
    };
    if take::<2>(record, RESERVED_AT) != [0, 0] {
        return Err(RecordError::Malformed);
    }
    Ok(Settings {
        frequency_hz: f64::from_le_bytes(take(record, FREQUENCY_AT)),
        duty: f64::from_le_bytes(take(record, DUTY_AT)),
        drive,
        ramp_cycles: u16::from_le_bytes(take(record, RAMP_AT)),
    })
}

/// The validated settings of the record read from `slot`, or why it holds none that can run on
/// `machine`.
pub fn load(
    record: &[u8; RECORD_LEN],
    slot: RecipeSlot,
    machine: &Machine,
) -> Result<Applied, RecordError> {
    decode(record, slot)?
        .validate(machine)
        .map_err(RecordError::Rejected)
}

fn put(record: &mut [u8; RECORD_LEN], at: usize, bytes: &[u8]) {
    for (slot, &byte) in record.iter_mut().skip(at).zip(bytes) {
        *slot = byte;
    }
}

fn take<const N: usize>(record: &[u8; RECORD_LEN], at: usize) -> [u8; N] {
    let mut bytes = [0u8; N];
    for (byte, &stored) in bytes.iter_mut().zip(record.iter().skip(at)) {
        *byte = stored;
    }
    bytes
}
