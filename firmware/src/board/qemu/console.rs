//! The operator's serial console on UART0 (`--features console`), with recipes kept in RAM: the
//! feeder waits, stopped, for commands, and thread mode has nothing to do.

use core::convert::Infallible;

use defmt::unwrap;
use embassy_executor::SendSpawner;
use feeder_shared::recipe::{RECIPE_SLOTS, RECORD_LEN};
use feeder_shared::{RecipeSlot, RecipeStore, TickClock};

use super::exit::sleep_forever;
use super::uart::Uart;
use crate::ports;

/// The console's end of UART0.
/// The console's image has no part sensor: no track control.
pub type PartSensor = ports::NoPartSensor;

/// The part sensor the console's image has: none.
pub fn part_sensor() -> PartSensor {
    ports::NoPartSensor
}

pub struct Operator(Uart);

impl Operator {
    pub fn new() -> Self {
        Self(Uart::new())
    }
}

impl ports::Operator for Operator {
    fn spawn(self, spawner: SendSpawner, clock: TickClock) {
        spawner.spawn(unwrap!(console_task(self.0, clock)));
    }
}

/// Thread mode with the console: nothing to do.
pub fn idle() -> ! {
    sleep_forever()
}

/// The operator's console on UART0, with recipes in RAM.
#[embassy_executor::task]
async fn console_task(port: Uart, clock: TickClock) {
    crate::console::serve(port, RamRecipes::new(), clock).await
}

/// Recipe records in RAM: erased at every start of the emulation.
struct RamRecipes {
    records: [[u8; RECORD_LEN]; RECIPE_SLOTS],
}

impl RamRecipes {
    fn new() -> Self {
        Self {
            records: [[0xff; RECORD_LEN]; RECIPE_SLOTS],
        }
    }
}

impl RecipeStore for RamRecipes {
    type Error = Infallible;

    fn read(&mut self, slot: RecipeSlot) -> [u8; RECORD_LEN] {
        self.records
            .get(slot.index())
            .copied()
            .unwrap_or([0xff; RECORD_LEN])
    }

    fn write(&mut self, slot: RecipeSlot, record: &[u8; RECORD_LEN]) -> Result<(), Infallible> {
        if let Some(stored) = self.records.get_mut(slot.index()) {
            *stored = *record;
        }
        Ok(())
    }
}
