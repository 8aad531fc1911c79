//! The application: control loop, button, status LED and watchdog monitor. Board-independent;
//! the board hands over its parts (`crate::ports`) and runs the executors.

mod control;
mod monitor;
mod panel;

use defmt::unwrap;
use embassy_executor::SendSpawner;

use crate::board;
use crate::output::SegmentOutput;
use crate::ports::{Board, Operator, Parts};
use control::ControlLoop;

type Output = <board::Hardware as Parts>::Output;
type DriverEnable = <board::Hardware as Parts>::DriverEnable;

/// Spawns the tasks: the control loop on the board's control executor, above the others; the
/// button, the LED, the monitor and the operator on `spawner` (the monitor where the board's
/// watchdog needs it).
pub fn start(spawner: SendSpawner, board: Board<board::Hardware>) {
    monitor::enable_cycle_counter();
    board::announce();
    let clock = board.output.clock();
    let control = ControlLoop::new(
        board.output,
        board.driver_enable,
        board.after_watchdog_reset,
    );
    board.control_spawner.spawn(unwrap!(control_task(control)));
    spawner.spawn(unwrap!(panel::button_task(board.button)));
    spawner.spawn(unwrap!(panel::led_task(board.led)));
    monitor::spawn(spawner, board.control_spawner, board.watchdog);
    board.operator.spawn(spawner, clock);
}

#[embassy_executor::task]
async fn control_task(control: ControlLoop<Output, DriverEnable>) {
    control.run().await
}
