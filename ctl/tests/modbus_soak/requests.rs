//! The random master's requests: reads and writes of random addresses and values (inside the
//! map and past it, inside the machine's range and past it), functions the slave does not
//! serve, and bytes that are no request for it (garbage, corrupt CRCs, frames for another
//! slave, frames cut short), each with what it must get.

use std::time::Duration;

use feeder_shared::drive::MACHINE_LIMITS;
use feeder_shared::modbus::{Holding, Input};
use tokio_modbus::Request;

use crate::support::modbus::{frame, SLAVE};

/// The holding registers.
pub const HOLDINGS: u16 = Holding::ALL.len() as u16;
/// The input registers.
pub const INPUTS: u16 = Input::ALL.len() as u16;
/// The recipe slots the soak saves before it starts; the others stay empty.
pub const SAVED_SLOTS: u16 = 4;

/// SplitMix64: a small generator whose sequence depends on the seed alone.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Rng(seed)
    }

    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in `low..=high`.
    pub fn between(&mut self, low: u64, high: u64) -> u64 {
        low + self.next_u64() % (high - low + 1)
    }

    pub fn word(&mut self, low: u16, high: u16) -> u16 {
        self.between(u64::from(low), u64::from(high)) as u16
    }

    pub fn chance(&mut self, percent: u64) -> bool {
        self.next_u64() % 100 < percent
    }

    pub fn byte(&mut self) -> u8 {
        self.next_u64() as u8
    }

    /// An index into `weights`, chosen in proportion to them.
    pub fn weighted(&mut self, weights: &[u64]) -> usize {
        let total: u64 = weights.iter().sum();
        let mut point = self.next_u64() % total;
        for (index, weight) in weights.iter().enumerate() {
            if point < *weight {
                return index;
            }
            point -= weight;
        }
        weights.len() - 1
    }
}

/// One thing the master does.
#[derive(Debug, Clone)]
pub enum Planned {
    /// Function 3.
    ReadHolding { address: u16, count: u16 },
    /// Function 4.
    ReadInput { address: u16, count: u16 },
    /// Function 6 (`multiple` false, one value) or 16.
    Write {
        address: u16,
        values: Vec<u16>,
        multiple: bool,
    },
    /// A function the slave does not serve, through the client: exception 01.
    Unsupported(Request<'static>),
    /// Bytes that must get no answer and change nothing.
    Raw { what: &'static str, bytes: Vec<u8> },
    /// The master thinks for a while (far less than the link timeout).
    Pause(Duration),
}

impl Planned {
    /// The counter it is reported under.
    pub fn kind(&self) -> &'static str {
        match self {
            Planned::ReadHolding { .. } => "read holding",
            Planned::ReadInput { .. } => "read input",
            Planned::Write {
                multiple: false, ..
            } => "write single",
            Planned::Write { multiple: true, .. } => "write multiple",
            Planned::Unsupported(_) => "unsupported function",
            Planned::Raw { what, .. } => what,
            Planned::Pause(_) => "pause",
        }
    }
}

/// What the master knows of the feeder when it picks a request.
pub struct Hints {
    /// The feeder ran (or was starting) at the last read.
    pub running: bool,
}

/// The random master.
pub struct Generator {
    rng: Rng,
}

impl Generator {
    pub fn new(seed: u64) -> Self {
        Generator {
            rng: Rng::new(seed),
        }
    }

    pub fn next(&mut self, hints: &Hints) -> Planned {
        const WEIGHTS: [u64; 10] = [15, 25, 26, 8, 4, 3, 3, 2, 1, 2];
        match self.rng.weighted(&WEIGHTS) {
            0 => {
                let (address, count) = self.range(HOLDINGS);
                Planned::ReadHolding { address, count }
            }
            1 => {
                let (address, count) = self.range(INPUTS);
                Planned::ReadInput { address, count }
            }
            2 => {
                let address = if self.rng.chance(4) {
                    self.rng.word(HOLDINGS, 60)
                } else if self.rng.chance(30) {
                    // Start and stop often: the feeder runs for a good part of the soak.
                    0
                } else {
                    self.rng.word(0, HOLDINGS - 1)
                };
                let value = self.value(address, hints);
                Planned::Write {
                    address,
                    values: vec![value],
                    multiple: false,
                }
            }
            3 => {
                let address = self.rng.word(0, HOLDINGS - 1);
                let count = self.rng.word(1, 4);
                let values = (address..address + count)
                    .map(|register| self.value(register, hints))
                    .collect();
                Planned::Write {
                    address,
                    values,
                    multiple: true,
                }
            }
            4 => Planned::Unsupported(self.unsupported()),
            5 => Planned::Raw {
                what: "garbage",
                bytes: self.garbage(),
            },
            6 => {
                let mask = self.rng.word(1, u16::MAX);
                let request = self.valid_frame(SLAVE, hints);
                Planned::Raw {
                    what: "corrupt CRC",
                    bytes: frame::corrupt(request, mask),
                }
            }
            7 => {
                let slave = self.rng.word(2, 247) as u8;
                Planned::Raw {
                    what: "another slave",
                    bytes: self.valid_frame(slave, hints),
                }
            }
            8 => {
                let request = self.valid_frame(SLAVE, hints);
                let cut = self.rng.between(1, request.len() as u64 - 1) as usize;
                Planned::Raw {
                    what: "cut short",
                    bytes: request[..cut].to_vec(),
                }
            }
            _ => Planned::Pause(Duration::from_millis(self.rng.between(1, 10))),
        }
    }

    /// A block of registers to read: mostly inside the map, sometimes past its end.
    fn range(&mut self, registers: u16) -> (u16, u16) {
        if self.rng.chance(10) {
            (self.rng.word(0, registers + 4), self.rng.word(1, 8))
        } else {
            let address = self.rng.word(0, registers - 1);
            (address, self.rng.word(1, registers - address))
        }
    }

    /// A value for holding register `address`: mostly around the machine's range, sometimes
    /// any.
    fn value(&mut self, address: u16, hints: &Hints) -> u16 {
        let any = self.rng.chance(12);
        let limits = MACHINE_LIMITS;
        let rng = &mut self.rng;
        match Holding::at(address) {
            _ if any => rng.word(0, u16::MAX),
            Some(Holding::Run) => match hints.running {
                true => u16::from(rng.chance(20)),
                false => u16::from(rng.chance(80)),
            },
            Some(Holding::Recipe) => rng.word(0, 9),
            Some(Holding::Duty) => rng.word(4_800, 9_800),
            Some(Holding::Frequency) => {
                let low = limits.min_frequency_hz * 90.0;
                let high = limits.max_frequency_hz * 105.0;
                rng.word(low as u16, high as u16)
            }
            Some(Holding::Stroke) => rng.word(100, (limits.max_stroke_m * 1.1e6) as u16),
            Some(Holding::Accel) => rng.word(50, (limits.max_accel_mps2 * 11.0) as u16),
            Some(Holding::Feed) => rng.word(50, 3_000),
            // Short ramps: a stop ends soon.
            Some(Holding::Ramp) => rng.word(0, 30),
            Some(Holding::Acknowledge) => match rng.chance(85) {
                true => 1,
                false => rng.word(0, u16::MAX),
            },
            None => rng.word(0, u16::MAX),
        }
    }

    fn unsupported(&mut self) -> Request<'static> {
        let address = self.rng.word(0, 20);
        match self.rng.between(0, 4) {
            0 => Request::ReadCoils(address, self.rng.word(1, 16)),
            1 => Request::ReadDiscreteInputs(address, self.rng.word(1, 16)),
            2 => Request::WriteSingleCoil(address, self.rng.chance(50)),
            3 => Request::WriteMultipleCoils(address, vec![true, false, true].into()),
            // In the 8 bytes the slave's framing expects of a function it has no length for.
            _ => Request::Custom(0x2b, vec![0x0e, 0x01, 0x00, 0x00].into()),
        }
    }

    /// A well-formed request frame to `slave`.
    fn valid_frame(&mut self, slave: u8, hints: &Hints) -> Vec<u8> {
        match self.rng.between(0, 3) {
            0 => {
                let (address, count) = self.range(HOLDINGS);
                frame::read(slave, 3, address, count)
            }
            1 => {
                let (address, count) = self.range(INPUTS);
                frame::read(slave, 4, address, count)
            }
            2 => {
                let address = self.rng.word(0, HOLDINGS - 1);
                let value = self.value(address, hints);
                frame::write_register(slave, address, value)
            }
            _ => {
                let address = self.rng.word(0, HOLDINGS - 1);
                let count = self.rng.word(1, 3);
                let mut data = address.to_be_bytes().to_vec();
                data.extend_from_slice(&count.to_be_bytes());
                data.push(2 * count as u8);
                for register in address..address + count {
                    let value = self.value(register, hints);
                    data.extend_from_slice(&value.to_be_bytes());
                }
                frame::build(slave, 16, &data)
            }
        }
    }

    /// Random bytes that are no request for this slave (or a broadcast).
    fn garbage(&mut self) -> Vec<u8> {
        loop {
            let len = self.rng.between(1, 48) as usize;
            let bytes: Vec<u8> = (0..len).map(|_| self.rng.byte()).collect();
            if !could_be_a_request(&bytes) {
                return bytes;
            }
        }
    }
}

/// Whether `bytes` begin with a frame for this slave or a broadcast whose CRC holds: the
/// length the slave takes a frame to have (8 bytes, or what function 15's and 16's byte count
/// says).
fn could_be_a_request(bytes: &[u8]) -> bool {
    if bytes.len() < 4 || ![0, SLAVE].contains(&bytes[0]) {
        return false;
    }
    let len = match bytes[1] {
        15 | 16 if bytes.len() >= 7 => usize::from(bytes[6]) + 9,
        15 | 16 => return false,
        _ => 8,
    };
    len <= bytes.len() && {
        let crc = frame::crc(&bytes[..len - 2]).to_le_bytes();
        bytes[len - 2..len] == crc
    }
}
