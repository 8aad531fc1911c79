//! The application: control loop, button, status LED and watchdog monitor. Board-independent;
//! the board hands over its parts (`crate::ports`) and runs the executors.

mod control;
mod monitor;
mod panel;
pub(crate) mod regulate;
mod track;

use defmt::unwrap;
use embassy_executor::SendSpawner;

use crate::output::SegmentOutput;
use crate::ports::{Board, Operator, PartSensor, Parts, PositionSensor};
use crate::{board, configured};
use control::ControlLoop;

type Output = <board::Hardware as Parts>::Output;
type DriverEnable = <board::Hardware as Parts>::DriverEnable;
type Sensor = <board::Hardware as Parts>::Sensor;
type Barrier = <board::Hardware as Parts>::PartSensor;

/// Spawns the tasks: the control loop on the board's control executor, above the others; the
/// button, the LED, the monitor and the operator on `spawner` (the monitor where the board's
/// watchdog needs it); with a position sensor, the closed loop on the board's loop executor
/// and the drive's identification on the background executor; with a part sensor, track control on `spawner`.
pub fn start(spawner: SendSpawner, board: Board<board::Hardware>) {
    monitor::enable_cycle_counter();
    board::announce();
    let clock = board.output.clock();
    let level_step_mps2 = board.output.level_step_mps2();
    let control = ControlLoop::new(
        board.output,
        board.driver_enable,
        board.latched_at_power_up,
    );
    board.control_spawner.spawn(unwrap!(control_task(control)));
    if Barrier::PRESENT {
        spawner.spawn(unwrap!(track::track_task(board.part_sensor)));
    }
    if configured::get().loop_runs(Sensor::PRESENT) {
        board.loop_spawner.spawn(unwrap!(regulate::regulate_task(
            board.sensor,
            level_step_mps2
        )));
        board
            .background_spawner
            .spawn(unwrap!(regulate::identify_task()));
    }
    spawner.spawn(unwrap!(panel::button_task(board.button)));
    spawner.spawn(unwrap!(panel::led_task(board.led)));
    monitor::spawn(spawner, board.control_spawner, board.watchdog);
    board.operator.spawn(spawner, clock);
}

#[embassy_executor::task]
async fn control_task(control: ControlLoop<Output, DriverEnable>) {
    control.run().await
}
