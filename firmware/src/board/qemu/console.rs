//! The operator's serial console on UART0 (`--features console`), with the configuration and
//! the recipes in the flash file (`file_store`): the feeder waits, stopped, for commands, and
//! thread mode has nothing to do.

use defmt::unwrap;
use embassy_executor::SendSpawner;
use feeder_shared::configuration::Configuration;
use feeder_shared::TickClock;

use super::exit::sleep_forever;
use super::file_store::FileStore;
use super::uart::Uart;
use crate::{configured, ports};

/// The console's image has no part sensor: no track control.
pub type PartSensor = ports::NoPartSensor;

/// The part sensor the console's image has: none.
pub fn part_sensor() -> PartSensor {
    ports::NoPartSensor
}

/// The console's end of UART0 and the board's flash.
pub struct Operator {
    port: Uart,
    store: FileStore,
}

impl Operator {
    pub fn new() -> Self {
        Self {
            port: Uart::new(),
            store: FileStore::open(),
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

/// Thread mode with the console: nothing to do.
pub fn idle() -> ! {
    sleep_forever()
}

/// The operator's console on UART0, with the flash file.
#[embassy_executor::task]
async fn console_task(operator: Operator, clock: TickClock) {
    crate::console::serve(operator.port, operator.store, clock).await
}
