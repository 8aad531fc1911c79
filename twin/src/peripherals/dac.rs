//! DAC1 (RM0440, "Digital-to-analog converter"), channel 1 as the firmware drives it: the
//! holding registers, the output register that takes the holding value at once without a
//! trigger or on the selected trigger with one (TEN1, TSEL1), the software trigger, the ready
//! flag that follows the enable; channel 2 and the sample-and-hold and sawtooth registers as
//! storage.

use super::registers::{masked, plain, Register, RegisterFile};
use super::Access;

const CR: u32 = 0x00;
const SWTRIGR: u32 = 0x04;
const DHR12R1: u32 = 0x08;
const DHR12L1: u32 = 0x0C;
const DHR8R1: u32 = 0x10;
const DOR1: u32 = 0x2C;
const SR: u32 = 0x34;

const CR_EN1: u32 = 1 << 0;
const CR_TEN1: u32 = 1 << 1;
/// SR's DAC1RDY (bit 11) and DAC2RDY (bit 27).
const SR_RDY1: u32 = 1 << 11;
const SR_RDY2: u32 = 1 << 27;

/// TSEL1's trigger from TIM2's TRGO (RM0440, DAC1 "Interconnection", dac_ch1_trg4).
pub const TSEL_TIM2_TRGO: u32 = 4;

const TABLE: &[Register] = &[
    plain(CR, 0),
    masked(SWTRIGR, 0, 0),
    masked(DHR12R1, 0, 0xFFF),
    masked(DHR12L1, 0, 0xFFF0),
    masked(DHR8R1, 0, 0xFF),
    masked(0x14, 0, 0xFFF),
    masked(0x18, 0, 0xFFF0),
    masked(0x1C, 0, 0xFF),
    plain(0x20, 0),
    plain(0x24, 0),
    plain(0x28, 0),
    masked(DOR1, 0, 0),
    masked(0x30, 0, 0),
    masked(SR, 0, 0x2000_2000),
    plain(0x38, 0),
    plain(0x3C, 0),
    plain(0x40, 0),
    plain(0x44, 0),
    plain(0x48, 0x0001_0001),
    plain(0x4C, 0x0001_0001),
    plain(0x58, 0),
    plain(0x5C, 0),
    plain(0x60, 0),
];

#[derive(Debug, Clone)]
pub struct Dac {
    registers: RegisterFile,
    /// Channel 1's holding value, right-aligned 12 bits.
    holding: u32,
}

impl Dac {
    pub fn new() -> Self {
        Dac {
            registers: RegisterFile::new(TABLE),
            holding: 0,
        }
    }

    pub fn read(&self, offset: u32) -> Access {
        match offset {
            SR => {
                let cr = self.registers.get(CR);
                let ready = if cr & CR_EN1 != 0 { SR_RDY1 } else { 0 }
                    | if cr & (1 << 16) != 0 { SR_RDY2 } else { 0 };
                Access::Value(self.registers.get(SR) | ready)
            }
            DHR12R1 => Access::Value(self.holding),
            DHR12L1 => Access::Value(self.holding << 4),
            DHR8R1 => Access::Value(self.holding >> 4),
            _ => self.registers.read(offset),
        }
    }

    /// Writes a register; returns the output code when it changed at once (no trigger).
    pub fn write(&mut self, offset: u32, value: u32) -> Result<Option<u32>, ()> {
        match offset {
            DHR12R1 => self.holding = value & 0xFFF,
            DHR12L1 => self.holding = (value >> 4) & 0xFFF,
            DHR8R1 => self.holding = (value & 0xFF) << 4,
            SWTRIGR => {
                if value & 1 != 0 && self.trigger_selection() == Some(0) {
                    return Ok(self.latch());
                }
                return Ok(None);
            }
            SR => {
                let sr = self.registers.get(SR);
                self.registers.set(SR, sr & !(value & 0x2000_2000));
                return Ok(None);
            }
            _ => {
                if !self.registers.write(offset, value) {
                    return Err(());
                }
            }
        }
        let cr = self.registers.get(CR);
        if cr & CR_EN1 != 0 && cr & CR_TEN1 == 0 {
            return Ok(self.latch());
        }
        Ok(None)
    }

    /// TSEL1 where the trigger is on (TEN1) and the channel enabled.
    fn trigger_selection(&self) -> Option<u32> {
        let cr = self.registers.get(CR);
        (cr & CR_EN1 != 0 && cr & CR_TEN1 != 0).then_some((cr >> 2) & 0xF)
    }

    /// A trigger `tsel` fired: the output takes the holding value if it is channel 1's.
    pub fn trigger(&mut self, tsel: u32) -> Option<u32> {
        (self.trigger_selection() == Some(tsel))
            .then(|| self.latch())
            .flatten()
    }

    /// DOR1 takes the holding value; the new code if it changed.
    fn latch(&mut self) -> Option<u32> {
        let before = self.registers.get(DOR1);
        self.registers.set(DOR1, self.holding);
        (before != self.holding).then_some(self.holding)
    }

    /// The code on the output now.
    pub fn output(&self) -> u32 {
        self.registers.get(DOR1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_triggered_channel_latches_only_on_its_trigger() {
        let mut dac = Dac::new();
        dac.write(CR, CR_EN1).unwrap();
        assert_eq!(
            dac.write(DHR12R1, 2048).unwrap(),
            Some(2048),
            "untriggered: at once"
        );
        dac.write(CR, CR_EN1 | CR_TEN1 | TSEL_TIM2_TRGO << 2)
            .unwrap();
        assert_eq!(dac.write(DHR12R1, 1000).unwrap(), None);
        assert_eq!(dac.trigger(3), None, "another timer's");
        assert_eq!(dac.trigger(TSEL_TIM2_TRGO), Some(1000));
        assert_eq!(dac.output(), 1000);
        assert_eq!(dac.read(SR), Access::Value(SR_RDY1));
    }
}
