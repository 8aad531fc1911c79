//! Bytes into RTU request frames. A frame is complete when it holds as many bytes as its
//! function code says ([`rmodbus::guess_request_frame_len`]); a silence longer than the frame
//! gap drops a partial frame, and after a byte that cannot begin a frame (a frame too long, a
//! function code that gives no length) everything is ignored until such a silence, so that the
//! next request is read from its first byte.

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

    /// A silence of at least the frame gap ended at `now_us` with nothing received: a partial
    /// frame is dropped. Call it when a receive times out.
    pub fn silence(&mut self, now_us: u64) {
        if self
            .last_us
            .is_some_and(|last_us| now_us.saturating_sub(last_us) > self.gap_us)
        {
            self.end_silence();
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
