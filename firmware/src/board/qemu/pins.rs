//! The driver enable in its register, and the parts the machine lacks: the LED, the button and
//! the watchdog.

use core::convert::Infallible;

use embedded_hal::digital::{ErrorType, InputPin, OutputPin};
use embedded_hal_async::digital::Wait;

use super::{register_write, DRIVER_ENABLE};
use crate::ports::Watchdog;

/// The driver enable, in [`DRIVER_ENABLE`]; in lockstep each change also goes to the plant.
pub struct EnableRegister {
    on: Option<bool>,
}

impl EnableRegister {
    pub const fn new() -> Self {
        EnableRegister { on: None }
    }

    fn set(&mut self, on: bool) {
        register_write(DRIVER_ENABLE as usize, u32::from(on));
        if self.on.replace(on) != Some(on) {
            #[cfg(feature = "cosim")]
            super::plant_link::with(|plant| plant.send_enable(on));
        }
    }
}

impl ErrorType for EnableRegister {
    type Error = Infallible;
}

impl OutputPin for EnableRegister {
    fn set_low(&mut self) -> Result<(), Infallible> {
        self.set(false);
        Ok(())
    }

    fn set_high(&mut self) -> Result<(), Infallible> {
        self.set(true);
        Ok(())
    }
}

/// The LED: no pin on this machine; its state shows in the log.
pub struct EmulatedPin;

impl ErrorType for EmulatedPin {
    type Error = Infallible;
}

impl OutputPin for EmulatedPin {
    fn set_low(&mut self) -> Result<(), Infallible> {
        Ok(())
    }

    fn set_high(&mut self) -> Result<(), Infallible> {
        Ok(())
    }
}

/// The scenario presses no button.
pub struct NoButton;

impl ErrorType for NoButton {
    type Error = Infallible;
}

impl InputPin for NoButton {
    fn is_high(&mut self) -> Result<bool, Infallible> {
        Ok(false)
    }

    fn is_low(&mut self) -> Result<bool, Infallible> {
        Ok(true)
    }
}

impl Wait for NoButton {
    async fn wait_for_high(&mut self) -> Result<(), Infallible> {
        core::future::pending().await
    }

    async fn wait_for_low(&mut self) -> Result<(), Infallible> {
        Ok(())
    }

    async fn wait_for_rising_edge(&mut self) -> Result<(), Infallible> {
        core::future::pending().await
    }

    async fn wait_for_falling_edge(&mut self) -> Result<(), Infallible> {
        core::future::pending().await
    }

    async fn wait_for_any_edge(&mut self) -> Result<(), Infallible> {
        core::future::pending().await
    }
}

/// QEMU models no independent watchdog for this machine; the monitor's feeding is a no-op.
pub struct NoWatchdog;

impl Watchdog for NoWatchdog {
    /// Progress is only logged, so rarely.
    const MONITOR_PERIOD_US: u64 = 100_000;
    /// Without a watchdog the monitor runs with the other tasks.
    const WATCHES_TASKS: bool = false;

    /// Nothing to feed; the monitor's feed counts as made.
    fn feed(&mut self) -> bool {
        true
    }
}
