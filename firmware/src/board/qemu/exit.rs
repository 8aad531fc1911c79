//! How an emulated run ends after a fault: the output's state as its registers hold it, then a
//! semihosting exit code that fails the run; and thread mode's spin.

use core::cell::Cell;
use core::sync::atomic::{AtomicBool, Ordering};

use cortex_m_semihosting::debug::{self, EXIT_FAILURE};
use critical_section::Mutex;
use embassy_time::Instant;

use super::{register_read, DRIVER_ENABLE, OUTPUT_CODE};
use crate::configured;
use crate::trace;

/// Set once the run ends with a failure, so that a fault while reporting only exits.
static ENDING: AtomicBool = AtomicBool::new(false);
/// Clock tick of actual tick 0 (the output's first restart), for the report at the end of a
/// failed run.
static TIMELINE_TICKS: Mutex<Cell<u64>> = Mutex::new(Cell::new(u64::MAX));

/// Records the clock tick of the output's actual tick 0.
pub fn set_timeline(ticks: u64) {
    critical_section::with(|cs| TIMELINE_TICKS.borrow(cs).set(ticks));
}

/// Whether the driver is enabled, as the output's register holds it.
pub fn driver_enabled() -> bool {
    register_read(DRIVER_ENABLE as usize) != 0
}

/// Ends the emulation with a failure code, so a panic or fault fails the run: interrupts off,
/// then the output's state as its registers hold it (`EVT zero` if it holds the zero code,
/// `EVT enable`), then the exit.
pub fn after_fault() -> ! {
    cortex_m::interrupt::disable();
    if !ENDING.swap(true, Ordering::Relaxed) {
        let actual_tick = Instant::now()
            .as_ticks()
            .saturating_sub(critical_section::with(|cs| TIMELINE_TICKS.borrow(cs).get()));
        let code = register_read(OUTPUT_CODE as usize);
        if code == u32::from(configured::get().dac.zero_code) {
            trace::zero(actual_tick);
        } else {
            defmt::error!("the output holds code {=u32} at the end", code);
        }
        trace::enable(actual_tick, driver_enabled());
    }
    debug::exit(EXIT_FAILURE);
    sleep_forever()
}

/// Thread mode has nothing to do: every task runs in an interrupt. It spins instead of sleeping
/// so that, under `-icount`, virtual time is exactly the instruction count: QEMU advances an idle
/// (`wfi`) CPU by host time, which would make runs differ.
pub fn sleep_forever() -> ! {
    loop {
        cortex_m::asm::nop();
    }
}
