//! The operator's serial console on LPUART1 (ST-LINK virtual COM port, 115200 8N1), with the
//! configuration and the recipes in flash (`--features console`).

use defmt::{error, unwrap};
use embassy_executor::SendSpawner;
use embassy_stm32::flash::Flash;
use embassy_stm32::interrupt::{self, InterruptExt, Priority};
use embassy_stm32::peripherals::{FLASH, LPUART1, PA2, PA3};
use embassy_stm32::usart::{self, BufferedUart};
use embassy_stm32::{bind_interrupts, Peri};
use feeder_shared::configuration::Configuration;
use feeder_shared::TickClock;

use super::flash_store::FlashStore;
use crate::{configured, ports};

bind_interrupts!(struct Irqs {
    LPUART1 => usart::BufferedInterruptHandler<LPUART1>;
});

/// Bytes the console's transmitter buffers: a whole reply line.
const TX_BUFFER_BYTES: usize = 336;
/// Bytes the console's receiver buffers while a reply is being composed.
const RX_BUFFER_BYTES: usize = 128;

/// The console's peripherals and the flash, handed to [`console_task`].
pub struct Operator {
    lpuart: Peri<'static, LPUART1>,
    tx: Peri<'static, PA2>,
    rx: Peri<'static, PA3>,
    store: FlashStore,
}

impl Operator {
    pub fn new(
        lpuart: Peri<'static, LPUART1>,
        tx: Peri<'static, PA2>,
        rx: Peri<'static, PA3>,
        flash: Peri<'static, FLASH>,
    ) -> Self {
        Self {
            lpuart,
            tx,
            rx,
            store: FlashStore::new(Flash::new_blocking(flash)),
        }
    }
}

impl ports::Operator for Operator {
    fn load_configuration(&mut self, clock: TickClock) -> Configuration {
        configured::at_power_up(&mut self.store, clock)
    }

    fn spawn(self, spawner: SendSpawner, clock: TickClock) {
        spawner.spawn(unwrap!(console_task(self, clock)));
    }
}

/// Serves the console in thread mode, below every interrupt.
#[embassy_executor::task]
async fn console_task(console: Operator, clock: TickClock) {
    let mut tx_buffer = [0u8; TX_BUFFER_BYTES];
    let mut rx_buffer = [0u8; RX_BUFFER_BYTES];
    // Below the edges and the control executor.
    interrupt::LPUART1.set_priority(Priority::P3);
    let port = match BufferedUart::new(
        console.lpuart,
        console.rx,
        console.tx,
        &mut tx_buffer,
        &mut rx_buffer,
        Irqs,
        usart::Config::default(),
    ) {
        Ok(port) => port,
        Err(err) => {
            error!(
                "console disabled: LPUART1 refused its configuration: {}",
                err
            );
            return;
        }
    };
    crate::console::serve(port, console.store, clock).await
}
