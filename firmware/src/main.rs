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
#[cfg(feature = "console")]
mod console;
mod fault;
mod output;
mod trace;

#[cfg(feature = "board-g474")]
#[embassy_executor::main]
async fn main(spawner: embassy_executor::Spawner) {
    let board = board::init();
    app::enable_cycle_counter();
    defmt::info!(
        "feeder firmware up: output {=str}, stopped",
        board::OUTPUT_STAGE
    );
    let _ = app::start(spawner.make_send(), board);
}

#[cfg(feature = "board-qemu")]
#[cortex_m_rt::entry]
fn main() -> ! {
    let (spawner, board) = board::init();
    app::enable_cycle_counter();
    defmt::info!("feeder firmware up on QEMU mps2-an386: output reported as events, stopped");
    let clock = app::start(spawner, board);
    board::spawn_operator(spawner, clock);
    board::idle()
}
