//! Bytes into RTU request frames. A frame of a function the slave serves is complete when it
//! holds as many bytes as its function code says ([`rmodbus::guess_request_frame_len`]); one of
//! another function (whose length only its sender knows) ends at the next silence longer than
//! the frame gap, and is a frame if its CRC holds, so that it can be answered with the
//! exception "illegal function". A silence drops any other partial frame, and after bytes that
//! cannot be a frame (too long, a broken CRC) everything is ignored until such a silence, so
//! that the next request is read from its first byte.

use rmodbus::consts::ModbusFunction;
use rmodbus::{guess_request_frame_len, ErrorKind, ModbusProto};

/// The longest RTU frame: address, PDU of at most 253 bytes, CRC.
pub const MAX_FRAME_BYTES: usize = 256;

/// The silence that ends a frame on a line at `baud` with 11-bit characters: 3.5 characters,
/// and 1750 µs from 19200 baud up, as the Modbus serial line specification fixes it.
pub const fn frame_gap_us(baud: u32) -> u64 {
    if baud > 19_200 || baud == 0 {
        1_750
    } else {
        // 3.5 characters of 11 bits: 38.5 bit times.
        38_500_000u64.div_ceil(baud as u64)
    }
}

/// Collects request frames from received bytes; see the module documentation.
#[derive(Debug, Clone)]
pub struct FrameAssembler {
    bytes: [u8; MAX_FRAME_BYTES],
    len: usize,
    gap_us: u64,
    /// When the last byte arrived, µs.
    last_us: Option<u64>,
    /// Ignoring bytes until the next gap.
    discarding: bool,
    /// Frames and partial frames dropped.
    dropped: u32,
}

impl FrameAssembler {
    /// An assembler that ends a partial frame after `gap_us` of silence.
    pub const fn new(gap_us: u64) -> Self {
        Self {
            bytes: [0; MAX_FRAME_BYTES],
            len: 0,
            gap_us,
            last_us: None,
            discarding: false,
            dropped: 0,
        }
    }

    /// Takes `byte`, received at `now_us`; returns the request it completes.
    pub fn push(&mut self, byte: u8, now_us: u64) -> Option<&[u8]> {
        if let Some(last_us) = self.last_us {
            if now_us.saturating_sub(last_us) > self.gap_us {
                self.end_silence();
            }
        }
        self.last_us = Some(now_us);
        if self.discarding {
            return None;
        }
        self.bytes[self.len] = byte;
        self.len += 1;
        if self.len >= 2 && ModbusFunction::try_from(self.bytes[1]).is_err() {
            if self.len == MAX_FRAME_BYTES {
                self.discard();
            }
            return None;
        }
        match guess_request_frame_len(&self.bytes[..self.len], ModbusProto::Rtu) {
            Ok(expected) if self.len >= usize::from(expected) => {
                let len = self.len;
                self.len = 0;
                Some(&self.bytes[..len])
            }
            Err(ErrorKind::OOB) | Ok(_) if self.len < MAX_FRAME_BYTES => None,
            _ => {
                self.discard();
                None
            }
        }
    }

    /// A silence of at least the frame gap ended at `now_us` with nothing received: the
    /// request of a function that gives no length, if the bytes held are one with its CRC, and
    /// otherwise a partial frame is dropped. Call it when a receive times out.
    pub fn silence(&mut self, now_us: u64) -> Option<&[u8]> {
        let quiet = self
            .last_us
            .is_some_and(|last_us| now_us.saturating_sub(last_us) > self.gap_us);
        if !quiet {
            return None;
        }
        let len = self.len;
        let framed = !self.discarding && crc_holds(&self.bytes[..len]);
        self.len = 0;
        self.discarding = false;
        match framed {
            true => Some(&self.bytes[..len]),
            false => {
                if len > 0 {
                    self.dropped = self.dropped.saturating_add(1);
                }
                None
            }
        }
    }

    /// The request that arrived last was refused as a frame (its CRC, its shape): what follows
    /// it until a silence belongs to it.
    pub fn discard(&mut self) {
        self.discarding = true;
        self.len = 0;
        self.dropped = self.dropped.saturating_add(1);
    }

    /// A partial frame is held, or bytes are being ignored until a silence: a silence now
    /// would change something.
    pub const fn pending(&self) -> bool {
        self.len > 0 || self.discarding
    }

    /// Frames and partial frames dropped so far.
    pub const fn dropped(&self) -> u32 {
        self.dropped
    }

    /// The frame gap, µs.
    pub const fn gap_us(&self) -> u64 {
        self.gap_us
    }

    fn end_silence(&mut self) {
        if self.len > 0 {
            self.dropped = self.dropped.saturating_add(1);
        }
        self.len = 0;
        self.discarding = false;
    }
}

/// The RTU frame's CRC, computed bitwise (no table in flash).
const CRC: crc::Crc<u16, crc::NoTable> = crc::Crc::<u16, crc::NoTable>::new(&crc::CRC_16_MODBUS);

/// `frame` is an address and a function code at least, and ends in the CRC of the bytes before
/// it, low byte first.
pub(super) fn crc_holds(frame: &[u8]) -> bool {
    match frame.len().checked_sub(2) {
        Some(body) if body >= 2 => CRC.checksum(&frame[..body]).to_le_bytes() == frame[body..],
        _ => false,
    }
}
