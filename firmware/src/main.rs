//! Motor-command firmware of the vibrating-plate parts feeder.
//!
//! The `shared` scheduler turns the configured waveform into segments of whole timer ticks; the
//! board's output stage times every edge in hardware while the control loop preloads the next
//! segment. See `app` for the tasks, `ports` for what they need from a board and `board` for the
//! hardware.
#![no_std]
#![no_main]

mod app;
mod board;
mod config;
mod configured;
#[cfg(feature = "console")]
mod console;
mod fault;
#[cfg(feature = "console")]
mod line;
mod mailbox;
mod output;
mod ports;
/// The scripted QEMU image's scenarios and the G474's fault drill overflow the stack.
#[cfg(any(feature = "board-g474", not(feature = "console")))]
mod stack_overflow;
mod status;
#[cfg(feature = "console")]
mod telemetry;
mod trace;

#[cortex_m_rt::entry]
fn main() -> ! {
    board::run(app::start)
}
