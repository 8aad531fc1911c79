//! The independent watchdog (RM0440, "Independent watchdog"): started by 0xCCCC, reloaded by
//! 0xAAAA, its prescaler and reload written after 0x5555; a down-counter on LSI through the
//! prescaler, which runs on from the start and is not reset by a reload, so a reload of `R`
//! expires after `R` to `R + 1` prescaled periods. The LSI runs at its nominal 32 kHz.

use super::{Access, Cycles, CORE_HZ};

const KR: u32 = 0x00;
const PR: u32 = 0x04;
const RLR: u32 = 0x08;
const SR: u32 = 0x0C;
const WINR: u32 = 0x10;

/// The LSI's nominal rate (DS12288: 29.5–34 kHz).
pub const LSI_HZ: u64 = 32_000;

#[derive(Debug, Clone)]
pub struct Iwdg {
    prescaler: u32,
    reload: u32,
    window: u32,
    unlocked: bool,
    /// When it was started: the prescaler's ticks count from here.
    started_at: Option<Cycles>,
    /// The prescaled tick at which the counter reaches zero.
    expiry_tick: u64,
    /// The last refresh.
    pub refreshed_at: Option<Cycles>,
}

impl Iwdg {
    pub fn new() -> Self {
        Iwdg {
            prescaler: 0,
            reload: 0xFFF,
            window: 0xFFF,
            unlocked: false,
            started_at: None,
            expiry_tick: 0,
            refreshed_at: None,
        }
    }

    /// LSI periods per prescaled tick: 4, 8, … 256.
    fn divider(&self) -> u64 {
        4 << self.prescaler.min(6)
    }

    /// The time of prescaled tick `k` after the start.
    fn tick_at(&self, start: Cycles, k: u64) -> Cycles {
        start
            + ((u128::from(k) * u128::from(self.divider()) * u128::from(CORE_HZ))
                / u128::from(LSI_HZ)) as u64
    }

    /// The first prescaled tick after `now`.
    fn next_tick(&self, start: Cycles, now: Cycles) -> u64 {
        let elapsed = u128::from(now - start) * u128::from(LSI_HZ);
        (elapsed / (u128::from(self.divider()) * u128::from(CORE_HZ))) as u64 + 1
    }

    fn reload_at(&mut self, now: Cycles) {
        if let Some(start) = self.started_at {
            self.expiry_tick = self.next_tick(start, now) + u64::from(self.reload);
            self.refreshed_at = Some(now);
        }
        self.unlocked = false;
    }

    /// When the counter reaches zero and resets the board, once started.
    pub fn expiry(&self) -> Option<Cycles> {
        self.started_at
            .map(|start| self.tick_at(start, self.expiry_tick))
    }

    pub fn read(&self, offset: u32) -> Access {
        Access::Value(match offset {
            KR => 0,
            PR => self.prescaler,
            RLR => self.reload,
            SR => 0,
            WINR => self.window,
            _ => return Access::Unmodelled,
        })
    }

    pub fn write(&mut self, offset: u32, value: u32, now: Cycles) -> bool {
        match offset {
            KR => match value & 0xFFFF {
                // Started, the counter counts down from its reset value 0xFFF; the reload
                // register takes effect at the first refresh.
                0xCCCC => {
                    if self.started_at.is_none() {
                        self.started_at = Some(now);
                        self.expiry_tick = 0xFFF;
                    }
                    self.unlocked = false;
                }
                0xAAAA => self.reload_at(now),
                0x5555 => self.unlocked = true,
                _ => self.unlocked = false,
            },
            PR if self.unlocked => self.prescaler = value & 0x7,
            RLR if self.unlocked => self.reload = value & 0xFFF,
            WINR if self.unlocked => self.window = value & 0xFFF,
            PR | RLR | WINR | SR => {}
            _ => return false,
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_reload_of_seven_expires_after_seven_to_eight_prescaled_periods() {
        let mut iwdg = Iwdg::new();
        iwdg.write(KR, 0x5555, 0);
        iwdg.write(PR, 0, 0);
        iwdg.write(RLR, 7, 0);
        iwdg.write(KR, 0xCCCC, 0);
        // One prescaled period: 4 LSI periods, 125 µs, 21 250 cycles at 170 MHz; the first
        // period counts from 0xFFF.
        assert_eq!(iwdg.expiry(), Some(0xFFF * 21_250));
        // A reload just before a tick expires 7 periods and that remnant later, 1.0 ms; just
        // after one, a remnant short of 8 periods later, 0.875 ms.
        iwdg.write(KR, 0xAAAA, 21_249);
        assert_eq!(iwdg.expiry(), Some(8 * 21_250));
        iwdg.write(KR, 0xAAAA, 21_251);
        assert_eq!(iwdg.expiry(), Some(9 * 21_250));
    }

    #[test]
    fn prescaler_and_reload_need_the_unlock() {
        let mut iwdg = Iwdg::new();
        iwdg.write(RLR, 7, 0);
        assert_eq!(iwdg.read(RLR), Access::Value(0xFFF));
    }
}
