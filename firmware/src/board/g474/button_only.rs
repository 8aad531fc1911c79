//! No operator but B1 (without the `console` feature): LPUART1 and the flash stay as reset left
//! them.

use embassy_executor::SendSpawner;
use embassy_stm32::peripherals::{FLASH, LPUART1, PA2, PA3};
use embassy_stm32::Peri;
use feeder_shared::TickClock;

use crate::ports;

/// The button, which the application serves, is the only operator.
pub struct Operator;

impl Operator {
    /// Takes the console's peripherals, so that the board builds either operator the same way.
    pub fn new(
        _lpuart: Peri<'static, LPUART1>,
        _tx: Peri<'static, PA2>,
        _rx: Peri<'static, PA3>,
        _flash: Peri<'static, FLASH>,
    ) -> Self {
        Self
    }
}

impl ports::Operator for Operator {
    fn spawn(self, _: SendSpawner, _: TickClock) {}
}
