//! No operator but B1 (without the `console` feature): LPUART1, USART1 and the discrete lines'
//! pins stay as reset left them; the configuration saved in flash (by a console image) is read
//! at power-up.

use embassy_executor::SendSpawner;
use embassy_stm32::flash::Flash;
use embassy_stm32::peripherals::{FLASH, LPUART1, PA2, PA3};
use embassy_stm32::Peri;
use feeder_shared::configuration::Configuration;
use feeder_shared::TickClock;

use super::flash_store::FlashStore;
use super::pins::LinePins;
use crate::{configured, ports};

/// The button, which the application serves, is the only operator.
pub struct Operator {
    store: FlashStore,
}

impl Operator {
    /// Takes the console's peripherals, so that the board builds either operator the same way.
    pub fn new(
        _lpuart: Peri<'static, LPUART1>,
        _tx: Peri<'static, PA2>,
        _rx: Peri<'static, PA3>,
        flash: Peri<'static, FLASH>,
        _line: LinePins,
    ) -> Self {
        Self {
            store: FlashStore::new(Flash::new_blocking(flash)),
        }
    }
}

impl ports::Operator for Operator {
    fn load_configuration(&mut self, clock: TickClock) -> Configuration {
        configured::at_power_up(&mut self.store, clock)
    }

    fn spawn(self, _: SendSpawner, _: TickClock) {}
}
