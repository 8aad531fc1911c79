//! The track's light barrier on PB10 (Arduino D6): an NPN sensor whose output, pulled up here,
//! switches to ground while a part interrupts the beam.

use embassy_stm32::exti::ExtiInput;
use embassy_stm32::mode::Async;

use crate::ports::PartSensor;

/// The barrier's input, blocked while low.
pub struct LightBarrier(pub ExtiInput<'static, Async>);

impl PartSensor for LightBarrier {
    const PRESENT: bool = true;

    async fn changed(&mut self) -> bool {
        self.0.wait_for_any_edge().await;
        self.0.is_low()
    }
}
