//! Panic and HardFault: make the output safe before anything else, then log.
//!
//! Both handlers zero the command and drop the driver enable through the board's registers,
//! log through defmt and wait for the independent watchdog, which resets the board. It comes
//! up faulted (LED blinking) and needs a press of B1 to acknowledge.

use core::panic::PanicInfo;

use cortex_m_rt::{exception, ExceptionFrame};

use crate::board;

#[panic_handler]
fn panic(info: &PanicInfo) -> ! {
    board::emergency_stop();
    defmt::error!("panic: {}", defmt::Display2Format(info));
    wait_for_watchdog()
}

#[exception]
unsafe fn HardFault(frame: &ExceptionFrame) -> ! {
    board::emergency_stop();
    defmt::error!(
        "HardFault at pc {=u32:#010x}, lr {=u32:#010x}",
        frame.pc(),
        frame.lr()
    );
    wait_for_watchdog()
}

fn wait_for_watchdog() -> ! {
    loop {
        cortex_m::asm::wfi();
    }
}
