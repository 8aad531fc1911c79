//! RCC (RM0440, "Reset and clock control"): every register as storage, and the ready flags that
//! follow their enables at once (HSI, HSE, PLL, LSI, LSE, HSI48), the clock switch's status
//! following its selection, and the reset flags with their clearing.

use super::registers::{masked, plain, Register, RegisterFile};
use super::Access;

const CR: u32 = 0x00;
const CFGR: u32 = 0x08;
const BDCR: u32 = 0x90;
const CSR: u32 = 0x94;
const CRRCR: u32 = 0x98;

/// CSR's reset flags (bits 25–31) and RMVF (bit 23), which clears them.
const CSR_RESET_FLAGS: u32 = 0xFE00_0000;
const CSR_RMVF: u32 = 1 << 23;
/// IWDGRSTF: the last reset was the independent watchdog's.
pub const CSR_IWDGRSTF: u32 = 1 << 29;
/// PINRSTF and BORRSTF: a power-on reset.
const CSR_POWER_ON: u32 = 1 << 26 | 1 << 27;

const TABLE: &[Register] = &[
    plain(CR, 0x0000_0500),
    plain(0x04, 0x4000_0000),
    plain(CFGR, 0x0000_0005),
    plain(0x0C, 0x0000_1000),
    plain(0x18, 0),
    plain(0x1C, 0),
    masked(0x20, 0, 0),
    plain(0x28, 0),
    plain(0x2C, 0),
    plain(0x30, 0),
    plain(0x38, 0),
    plain(0x3C, 0),
    plain(0x40, 0),
    plain(0x48, 0x0000_0100),
    plain(0x4C, 0),
    plain(0x50, 0),
    plain(0x58, 0x0000_0400),
    plain(0x5C, 0),
    plain(0x60, 0),
    plain(0x68, 0x0000_130F),
    plain(0x6C, 0x050F_667F),
    plain(0x70, 0x0000_0101),
    plain(0x78, 0xF2FE_C3FF),
    plain(0x7C, 0x0000_0103),
    plain(0x80, 0x0437_F801),
    plain(0x88, 0),
    plain(BDCR, 0),
    plain(CSR, CSR_POWER_ON | 0x0C00_0000),
    plain(CRRCR, 0),
    plain(0x9C, 0),
];

#[derive(Debug, Clone)]
pub struct Rcc {
    registers: RegisterFile,
}

impl Rcc {
    pub fn new() -> Self {
        Rcc {
            registers: RegisterFile::new(TABLE),
        }
    }

    /// After a reset by the independent watchdog: its flag set, the rest as at power-up.
    pub fn after_watchdog_reset(&self) -> Self {
        let mut rcc = Rcc::new();
        let flags = self.registers.get(CSR) & CSR_RESET_FLAGS;
        rcc.registers
            .set(CSR, (0x0C00_0000 & !CSR_RESET_FLAGS) | flags | CSR_IWDGRSTF);
        rcc
    }

    pub fn read(&self, offset: u32) -> Access {
        self.registers.read(offset)
    }

    pub fn write(&mut self, offset: u32, value: u32) -> bool {
        let flags_before = self.registers.get(CSR) & CSR_RESET_FLAGS;
        if !self.registers.write(offset, value) {
            return false;
        }
        let follow = |value: u32, pairs: &[(u32, u32)]| {
            pairs.iter().fold(value, |value, &(on, ready)| {
                if value & (1 << on) != 0 {
                    value | 1 << ready
                } else {
                    value & !(1 << ready)
                }
            })
        };
        match offset {
            CR => {
                let value = follow(self.registers.get(CR), &[(8, 10), (16, 17), (24, 25)]);
                self.registers.set(CR, value);
            }
            CFGR => {
                let value = self.registers.get(CFGR);
                self.registers
                    .set(CFGR, (value & !0xC) | (value & 0x3) << 2);
            }
            BDCR => {
                let value = follow(self.registers.get(BDCR), &[(0, 1)]);
                self.registers.set(BDCR, value);
            }
            CSR => {
                let value = follow(self.registers.get(CSR), &[(0, 1)]);
                let flags = if value & CSR_RMVF != 0 {
                    0
                } else {
                    flags_before
                };
                self.registers
                    .set(CSR, (value & !(CSR_RESET_FLAGS | CSR_RMVF)) | flags);
            }
            CRRCR => {
                let value = follow(self.registers.get(CRRCR), &[(0, 1)]);
                self.registers.set(CRRCR, value);
            }
            _ => {}
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ready_flags_follow_their_enables_and_the_switch_its_selection() {
        let mut rcc = Rcc::new();
        rcc.write(CR, 1 << 8 | 1 << 24);
        assert_eq!(
            rcc.read(CR),
            Access::Value(1 << 8 | 1 << 10 | 1 << 24 | 1 << 25)
        );
        rcc.write(CFGR, 3);
        assert_eq!(rcc.read(CFGR), Access::Value(0xF));
    }

    #[test]
    fn rmvf_clears_the_reset_flags_and_a_watchdog_reset_sets_its_own() {
        let mut rcc = Rcc::new().after_watchdog_reset();
        let Access::Value(csr) = rcc.read(CSR) else {
            panic!()
        };
        assert_ne!(csr & CSR_IWDGRSTF, 0);
        rcc.write(CSR, csr | CSR_RMVF);
        let Access::Value(csr) = rcc.read(CSR) else {
            panic!()
        };
        assert_eq!(csr & (CSR_RESET_FLAGS | CSR_RMVF), 0);
    }
}
