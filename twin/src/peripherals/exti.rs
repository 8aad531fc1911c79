//! EXTI (RM0440, "Extended interrupts and events controller"), the configurable lines 0–15
//! from the GPIO pins SYSCFG selects: masks, edge selection, software triggers and the pending
//! register (rc_w1); lines 16 and up as storage.

use super::registers::{masked, plain, Register, RegisterFile};
use super::Access;

const IMR1: u32 = 0x00;
const RTSR1: u32 = 0x08;
const FTSR1: u32 = 0x0C;
const SWIER1: u32 = 0x10;
const PR1: u32 = 0x14;

const TABLE: &[Register] = &[
    plain(IMR1, 0xFF82_0000),
    plain(0x04, 0),
    plain(RTSR1, 0),
    plain(FTSR1, 0),
    plain(SWIER1, 0),
    masked(PR1, 0, 0),
    plain(0x20, 0x0000_0187),
    plain(0x24, 0),
    plain(0x28, 0),
    plain(0x2C, 0),
    plain(0x30, 0),
    masked(0x34, 0, 0),
];

#[derive(Debug, Clone)]
pub struct Exti {
    registers: RegisterFile,
}

impl Exti {
    pub fn new() -> Self {
        Exti {
            registers: RegisterFile::new(TABLE),
        }
    }

    pub fn read(&self, offset: u32) -> Access {
        self.registers.read(offset)
    }

    pub fn write(&mut self, offset: u32, value: u32) -> bool {
        match offset {
            PR1 => {
                let pending = self.registers.get(PR1);
                self.registers.set(PR1, pending & !value);
                true
            }
            SWIER1 => {
                let pending = self.registers.get(PR1);
                let masked = value & self.registers.get(IMR1);
                self.registers.set(PR1, pending | masked);
                true
            }
            _ => self.registers.write(offset, value),
        }
    }

    /// An edge on line `line`: pending if that edge is selected.
    pub fn edge(&mut self, line: u32, rising: bool) {
        let selected = self.registers.get(if rising { RTSR1 } else { FTSR1 });
        if selected & (1 << line) != 0 {
            let pending = self.registers.get(PR1);
            self.registers.set(PR1, pending | 1 << line);
        }
    }

    /// Lines pending and unmasked, as a bit set.
    pub fn interrupts(&self) -> u32 {
        self.registers.get(PR1) & self.registers.get(IMR1)
    }
}
