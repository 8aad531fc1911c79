//! The independent watchdog and the feed pulses on PB5 for the external enable keeper.

use embassy_stm32::gpio::{self, Level, Speed};
use embassy_stm32::peripherals::{IWDG, PB5};
use embassy_stm32::wdg::IndependentWatchdog;
use embassy_stm32::Peri;

use super::{drill, segment_timer};
use crate::app;
use crate::config;

/// The independent watchdog, fed only while the output plays what the control loop preloaded,
/// and the feed pulses on PB5: every feed toggles it, for an external retriggerable monostable
/// that keeps the driver enabled only while the pulses go on (`firmware/README.md`).
pub struct OutputWatchdog {
    iwdg: IndependentWatchdog<'static, IWDG>,
    feed_pulses: gpio::Output<'static>,
}

impl OutputWatchdog {
    /// Starts the watchdog. Its first period counts down from the reset value 0xFFF (512 ms at
    /// LSI/4, RM0440, IWDG, "Independent watchdog functional description"), which covers the rest
    /// of the start-up; every feed then reloads the configured timeout.
    pub fn start(iwdg: Peri<'static, IWDG>, feed_pulses: Peri<'static, PB5>) -> Self {
        let mut watchdog = Self {
            iwdg: IndependentWatchdog::new(iwdg, config::WATCHDOG_TIMEOUT_US),
            feed_pulses: gpio::Output::new(feed_pulses, Level::Low, Speed::Low),
        };
        watchdog.iwdg.unleash();
        watchdog
    }
}

impl app::Watchdog for OutputWatchdog {
    /// Feeds unless the output replays a segment.
    fn feed(&mut self) {
        if segment_timer::replaying() {
            return;
        }
        self.iwdg.pet();
        self.feed_pulses.toggle();
        drill::provoke_when_due();
    }
}
