//! The small system blocks, as storage with what the firmware waits for: PWR (its voltage
//! scaling always settled), the flash interface (latency, the unlock sequence; programming is
//! the machine's), SYSCFG and the debug unit (its identity and freeze bits).

use super::registers::{masked, plain, Register, RegisterFile};
use super::Access;

const PWR_TABLE: &[Register] = &[
    plain(0x00, 0x0000_0200),
    plain(0x04, 0),
    plain(0x08, 0x0000_8000),
    plain(0x0C, 0),
    masked(0x10, 0, 0),
    // SR2: REGLPF, VOSF and PVDO clear, voltage scaling done.
    masked(0x14, 0, 0),
    masked(0x18, 0, 0),
    plain(0x20, 0),
    plain(0x24, 0),
    plain(0x28, 0),
    plain(0x2C, 0),
    plain(0x30, 0),
    plain(0x34, 0),
    plain(0x38, 0),
    plain(0x3C, 0),
    plain(0x40, 0),
    plain(0x44, 0),
    plain(0x48, 0),
    plain(0x4C, 0),
    plain(0x50, 0),
    plain(0x54, 0),
    plain(0x58, 0),
    plain(0x5C, 0),
    plain(0x80, 0x0000_0100),
];

/// PWR at 0x4000_7000.
pub fn pwr() -> RegisterFile {
    RegisterFile::new(PWR_TABLE)
}

const SYSCFG_TABLE: &[Register] = &[
    plain(0x00, 0),
    plain(0x04, 0x7C00_0001),
    plain(0x08, 0),
    plain(0x0C, 0),
    plain(0x10, 0),
    plain(0x14, 0),
    plain(0x18, 0),
    plain(0x1C, 0),
    plain(0x20, 0),
    plain(0x24, 0),
];

/// SYSCFG at 0x4001_0000 (EXTICR1–4 select each EXTI line's port).
pub fn syscfg() -> RegisterFile {
    RegisterFile::new(SYSCFG_TABLE)
}

/// DBGMCU's IDCODE: revision 0x2000 of device 0x469 (STM32G47x/G48x).
pub const DBGMCU_IDCODE: u32 = 0x2000_6469;

const DBGMCU_TABLE: &[Register] = &[
    masked(0x00, DBGMCU_IDCODE, 0),
    plain(0x04, 0),
    plain(0x08, 0),
    plain(0x0C, 0),
    plain(0x10, 0),
];

/// DBGMCU at 0xE004_2000.
pub fn dbgmcu() -> RegisterFile {
    RegisterFile::new(DBGMCU_TABLE)
}

const ACR: u32 = 0x00;
const KEYR: u32 = 0x08;
const SR: u32 = 0x10;
const CR: u32 = 0x14;
const CR_LOCK: u32 = 1 << 31;
/// CR's STRT: an erase starts.
const CR_STRT: u32 = 1 << 16;
/// FLASH_OPTR as a NUCLEO-G474RE leaves the factory: dual bank (DBANK, bit 22) among the rest.
const OPTR_FACTORY: u32 = 0xFFEF_F8AA;
const KEYS: [u32; 2] = [0x4567_0123, 0xCDEF_89AB];

const FLASH_TABLE: &[Register] = &[
    plain(ACR, 0x0000_0600),
    masked(0x04, 0, 0),
    masked(KEYR, 0, 0),
    masked(0x0C, 0, 0),
    // SR: EOP and the error flags are rc_w1; BSY never set (operations end at once).
    plain(SR, 0),
    plain(CR, CR_LOCK | 1 << 30),
    plain(0x18, 0),
    masked(0x20, OPTR_FACTORY, 0),
    masked(0x24, 0, 0),
    masked(0x28, 0, 0),
    masked(0x2C, 0, 0),
    masked(0x30, 0, 0),
    masked(0x44, 0, 0),
    masked(0x48, 0, 0),
    masked(0x4C, 0, 0),
    masked(0x50, 0, 0),
    plain(0x70, 0),
    plain(0x80, 0),
];

/// The flash interface at 0x4002_2000: its registers, and whether it is unlocked.
#[derive(Debug, Clone)]
pub struct FlashInterface {
    registers: RegisterFile,
    keys_seen: usize,
}

impl FlashInterface {
    pub fn new() -> Self {
        FlashInterface {
            registers: RegisterFile::new(FLASH_TABLE),
            keys_seen: 0,
        }
    }

    pub fn read(&self, offset: u32) -> Access {
        self.registers.read(offset)
    }

    pub fn write(&mut self, offset: u32, value: u32) -> bool {
        match offset {
            KEYR => {
                if KEYS.get(self.keys_seen) == Some(&value) {
                    self.keys_seen += 1;
                    if self.keys_seen == KEYS.len() {
                        let cr = self.registers.get(CR);
                        self.registers.set(CR, cr & !CR_LOCK);
                        self.keys_seen = 0;
                    }
                } else {
                    self.keys_seen = 0;
                }
                true
            }
            SR => {
                let sr = self.registers.get(SR);
                self.registers.set(SR, sr & !value);
                true
            }
            CR => {
                let locked = self.registers.get(CR) & CR_LOCK != 0;
                if locked && value & CR_LOCK == 0 {
                    return true;
                }
                self.registers.write(CR, value)
            }
            _ => self.registers.write(offset, value),
        }
    }

    /// The control register: programming and erase requests.
    pub fn control(&self) -> u32 {
        self.registers.get(CR)
    }

    /// The end of an operation: EOP, and STRT cleared.
    pub fn finish(&mut self) {
        let sr = self.registers.get(SR);
        self.registers.set(SR, sr | 1);
        let cr = self.registers.get(CR);
        self.registers.set(CR, cr & !CR_STRT);
    }

    /// The wait states set (LATENCY, bits 3:0).
    pub fn latency(&self) -> u32 {
        self.registers.get(ACR) & 0xF
    }
}
