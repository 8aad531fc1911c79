//! Motor-command firmware of the vibrating-plate parts feeder.
//!
//! The `shared` scheduler turns the configured waveform into segments of whole timer ticks; the
//! board's output stage times every edge in hardware while the control loop preloads the next
//! segment. See `app` for the tasks and `board` for the hardware.
#![no_std]
#![no_main]

mod app;
mod board;
mod config;
mod fault;
mod output;

use defmt_rtt as _;

#[embassy_executor::main]
async fn main(spawner: embassy_executor::Spawner) {
    let board = board::init();
    app::enable_cycle_counter();
    defmt::info!(
        "feeder firmware up: output {}, stopped",
        config::OUTPUT_STAGE
    );
    app::start(spawner, board);
}
