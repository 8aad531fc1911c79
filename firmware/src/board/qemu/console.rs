//! The operator's serial console on UART0 and the Modbus port on UART1 (`--features console`),
//! with the configuration and the recipes in the flash file (`file_store`): the feeder waits,
//! stopped, for commands, and thread mode has nothing to do. The machine has no pins a host can
//! drive: no discrete lines.

use defmt::unwrap;
use embassy_executor::SendSpawner;
use feeder_shared::configuration::Configuration;
use feeder_shared::TickClock;

use super::exit::sleep_forever;
use super::file_store::FileStore;
use super::pins::{EmulatedPin, NoButton};
use super::uart::{Port, Uart};
use crate::line::{DiscreteLines, ModbusPort};
use crate::{configured, ports};

/// The silence that ends a Modbus frame on the emulated port. QEMU's serial backend is a TCP
/// socket: it carries no character timing, and a frame's bytes arrive as fast as the host's
/// scheduler passes them on, so the gap is far longer than a serial line's 3.5 characters
/// (a master waits longer than this for an answer before it sends again).
const MODBUS_GAP_US: u64 = 50_000;

/// The console's image has no part sensor: no track control.
pub type PartSensor = ports::NoPartSensor;

/// The part sensor the console's image has: none.
pub fn part_sensor() -> PartSensor {
    ports::NoPartSensor
}

/// The console's end of UART0, the Modbus port's of UART1 and the board's flash.
pub struct Operator {
    port: Uart,
    modbus: Uart,
    store: FileStore,
}

impl Operator {
    pub fn new() -> Self {
        Self {
            port: Uart::new(Port::Console),
            modbus: Uart::new(Port::Modbus),
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

/// The operator's console on UART0 and the Modbus port on UART1, with the flash file.
#[embassy_executor::task]
async fn console_task(operator: Operator, clock: TickClock) {
    let modbus = ModbusPort {
        port: operator.modbus,
        gap_us: MODBUS_GAP_US,
        // No bus to turn around: the socket carries the answer on its own.
        turnaround_us: 0,
    };
    crate::console::serve(
        operator.port,
        operator.store,
        clock,
        Some(modbus),
        None::<DiscreteLines<NoButton, EmulatedPin>>,
    )
    .await
}
