//! A GPIO port (RM0440, "General-purpose I/Os"): mode, type, speed, pulls, alternate functions,
//! the output data register with its set/reset and reset registers, and the input data as the
//! pins are: an output reads back what it drives, an input what is driven from outside, else
//! its pull.

use super::Access;

const MODER: u32 = 0x00;
const OTYPER: u32 = 0x04;
const OSPEEDR: u32 = 0x08;
const PUPDR: u32 = 0x0C;
const IDR: u32 = 0x10;
const ODR: u32 = 0x14;
const BSRR: u32 = 0x18;
const LCKR: u32 = 0x1C;
const AFRL: u32 = 0x20;
const AFRH: u32 = 0x24;
const BRR: u32 = 0x28;

#[derive(Debug, Clone)]
pub struct Port {
    moder: u32,
    otyper: u32,
    ospeedr: u32,
    pupdr: u32,
    odr: u32,
    lckr: u32,
    afr: [u32; 2],
    /// Levels driven from outside, by pin: `None` where nothing drives the pin.
    external: [Option<bool>; 16],
}

impl Port {
    /// Port `name` ('A', 'B', …) at its reset values.
    pub fn new(name: char) -> Self {
        let (moder, ospeedr, pupdr) = match name {
            'A' => (0xABFF_FFFF, 0x0C00_0000, 0x6400_0000),
            'B' => (0xFFFF_FEBF, 0, 0x0000_0100),
            _ => (0xFFFF_FFFF, 0, 0),
        };
        Port {
            moder,
            otyper: 0,
            ospeedr,
            pupdr,
            odr: 0,
            lckr: 0,
            afr: [0, 0],
            external: [None; 16],
        }
    }

    fn mode(&self, pin: u32) -> u32 {
        (self.moder >> (2 * pin)) & 3
    }

    /// The level on `pin`.
    pub fn level(&self, pin: u32) -> bool {
        if self.mode(pin) == 1 {
            return self.odr & (1 << pin) != 0;
        }
        match self.external[pin as usize] {
            Some(level) => level,
            None => (self.pupdr >> (2 * pin)) & 3 == 1,
        }
    }

    /// The alternate function `pin` is switched to (AFRL, AFRH), if it is in that mode.
    pub fn alternate(&self, pin: u32) -> Option<u32> {
        (self.mode(pin) == 2).then(|| (self.afr[pin as usize / 8] >> (4 * (pin % 8))) & 0xF)
    }

    /// Whether `pin` is a push-pull output driving high.
    pub fn drives_high(&self, pin: u32) -> bool {
        self.mode(pin) == 1 && self.odr & (1 << pin) != 0
    }

    /// Drives `pin` from outside (`None`: released).
    pub fn drive(&mut self, pin: u32, level: Option<bool>) {
        self.external[pin as usize] = level;
    }

    pub fn read(&self, offset: u32) -> Access {
        let value = match offset {
            MODER => self.moder,
            OTYPER => self.otyper,
            OSPEEDR => self.ospeedr,
            PUPDR => self.pupdr,
            IDR => (0..16)
                .filter(|&pin| self.level(pin))
                .fold(0, |v, pin| v | 1 << pin),
            ODR => self.odr,
            BSRR | BRR => 0,
            LCKR => self.lckr,
            AFRL => self.afr[0],
            AFRH => self.afr[1],
            _ => return Access::Unmodelled,
        };
        Access::Value(value)
    }

    pub fn write(&mut self, offset: u32, value: u32) -> bool {
        match offset {
            MODER => self.moder = value,
            OTYPER => self.otyper = value & 0xFFFF,
            OSPEEDR => self.ospeedr = value,
            PUPDR => self.pupdr = value,
            IDR => {}
            ODR => self.odr = value & 0xFFFF,
            BSRR => self.odr = (self.odr | (value & 0xFFFF)) & !(value >> 16),
            BRR => self.odr &= !(value & 0xFFFF),
            LCKR => self.lckr = value,
            AFRL => self.afr[0] = value,
            AFRH => self.afr[1] = value,
            _ => return false,
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bsrr_sets_before_it_resets_and_an_output_reads_back() {
        let mut port = Port::new('A');
        port.write(MODER, 1 << 20);
        port.write(BSRR, 1 << 10);
        assert!(port.drives_high(10));
        port.write(BSRR, 1 << 26);
        assert!(!port.drives_high(10));
        // PA13 and PA15 keep their reset pull-ups (the debug port's).
        assert_eq!(port.read(IDR), Access::Value(1 << 13 | 1 << 15));
    }

    #[test]
    fn a_pin_in_its_alternate_function_names_it() {
        let mut port = Port::new('A');
        assert_eq!(port.alternate(12), None, "PA12 analog at reset");
        port.write(MODER, 0xABFF_FFFF & !(3 << 24) | 2 << 24);
        port.write(AFRH, 7 << 16);
        assert_eq!(port.alternate(12), Some(7));
    }

    #[test]
    fn an_input_reads_its_pull_until_driven() {
        let mut port = Port::new('C');
        port.write(MODER, 0);
        port.write(PUPDR, 1 << 26);
        assert!(port.level(13));
        port.drive(13, Some(false));
        assert!(!port.level(13));
    }
}
