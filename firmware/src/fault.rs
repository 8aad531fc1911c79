//! Panic and HardFault: make the output safe before anything else, then log.
//!
//! Both handlers zero the command and drop the driver enable through the board's registers,
//! log through defmt and hand over to the board: on the NUCLEO-G474RE the independent watchdog
//! resets it and it comes up faulted (LED blinking, B1 acknowledges); under QEMU the emulation
//! exits with a failure code.

use core::panic::PanicInfo;

use cortex_m_rt::{exception, ExceptionFrame};

use crate::board;

#[panic_handler]
fn panic(info: &PanicInfo) -> ! {
    board::emergency_stop();
    defmt::error!("panic: {}", defmt::Display2Format(info));
    board::after_fault()
}

#[exception]
unsafe fn HardFault(frame: &ExceptionFrame) -> ! {
    board::emergency_stop();
    defmt::error!(
        "HardFault at pc {=u32:#010x}, lr {=u32:#010x}",
        frame.pc(),
        frame.lr()
    );
    board::after_fault()
}
