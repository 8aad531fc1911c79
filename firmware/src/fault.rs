//! Panic and HardFault: make the output safe before anything else, then log.
//!
//! The safe state is one table per board: 32-bit stores that zero the command and drop the driver
//! enable through the registers alone, whatever state the drivers are in. Each board module
//! defines it as `pub static SAFE_STATE_WRITES: [RegisterWrite; N]` (immutable, so it lies in
//! flash); the HardFault entry takes its address and its size in bytes, so N is free and there
//! is no terminator. The panic handler makes the stores from Rust, the HardFault entry from
//! assembly.
//!
//! * HardFault: the entry (`HardFault`, below; on the NUCLEO-G474RE also NMI's and every
//!   unbound interrupt's, `board::g474`) uses registers only until the stores are made, so
//!   a fault whose stack is gone still reaches them: under flip-link a stack overflow faults when
//!   the stack pointer crosses the bottom of RAM, and the exception frame cannot be stacked
//!   either. It then reads the stacked pc and lr if the frame was stacked, resets the main stack
//!   pointer to its initial value (word 0 of the vector table) and enters Rust
//!   ([`report_hard_fault`]), which logs the fault status registers.
//! * Panic: interrupts are disabled first, so that no handler (the control loop) runs again and
//!   drives the output, then the stores are made and the message logged.
//!
//! Both then hand over to the board (`board::after_fault`): on the NUCLEO-G474RE the
//! independent watchdog resets it and it comes up faulted (LED blinking, B1 acknowledges);
//! under QEMU the emulation reports the output's state and exits with a failure code.

use core::panic::PanicInfo;
use core::sync::atomic::{AtomicBool, Ordering};

use cortex_m::peripheral::SCB;

use crate::board;
use crate::ports;

/// Bytes of the board's table, which the HardFault entry walks from its start to its end.
const SAFE_STATE_BYTES: usize = core::mem::size_of_val(&board::SAFE_STATE_WRITES);

/// ICSR's number of the exception being handled (0: thread mode).
const VECTACTIVE: u32 = 0x1ff;

/// EXC_RETURN's bit set when the exception returns to thread mode.
const RETURN_TO_THREAD: u32 = 1 << 3;

/// CFSR bits of a fault while the exception frame was stacked: MSTKERR (MPU) and STKERR (bus).
const STACKING_ERRORS: u32 = 1 << 4 | 1 << 12;

/// Set by the first fault that logs: a fault while one is logged (a logger that panics when
/// entered again) only hands over to the board.
static LOGGED: AtomicBool = AtomicBool::new(false);

/// True for the first fault to log.
fn first_to_log() -> bool {
    !LOGGED.swap(true, Ordering::Relaxed)
}

#[panic_handler]
fn panic(info: &PanicInfo) -> ! {
    cortex_m::interrupt::disable();
    ports::write_all(&board::SAFE_STATE_WRITES);
    if first_to_log() {
        // SAFETY: a read of the interrupt control and state register.
        let active = unsafe { (*SCB::PTR).icsr.read() } & VECTACTIVE;
        if active == 0 {
            defmt::error!("panic in thread mode: {}", defmt::Display2Format(info));
        } else {
            defmt::error!(
                "panic in exception {=u32}: {}",
                active,
                defmt::Display2Format(info)
            );
        }
    }
    board::after_fault()
}

// The HardFault handler: `HardFault` is the symbol the vector table takes (cortex-m-rt's link.x
// only PROVIDEs a default for it). r0–r3 and r12 are free: the handler never returns.
// It makes the table's stores, drops any floating-point state reserved lazily on the faulting
// stack (so that no floating-point instruction later writes there), takes the stacked pc and lr
// in r2 and r3 when CFSR shows the frame was stacked (0 otherwise), resets the main stack
// pointer (cortex-m-rt runs thread mode on it too) and branches to Rust with
// (sp at the fault, EXC_RETURN, pc, lr).
core::arch::global_asm!(
    ".section .text.HardFault, \"ax\"",
    ".global HardFault",
    ".type HardFault, %function",
    ".thumb_func",
    "HardFault:",
    "    ldr   r0, ={writes}",
    "    ldr   r1, ={writes} + {bytes}",
    "1:  cmp   r0, r1",
    "    beq   2f",
    "    ldmia r0!, {{r2, r3}}",
    "    str   r3, [r2]",
    "    b     1b",
    "2:  dsb",
    "    ldr   r0, =0xE000EF34",
    "    ldr   r1, [r0]",
    "    bic   r1, r1, #1",
    "    str   r1, [r0]",
    "    mrs   r0, msp",
    "    mov   r1, lr",
    "    movs  r2, #0",
    "    movs  r3, #0",
    "    ldr   r12, =0xE000ED28",
    "    ldr   r12, [r12]",
    "    tst   r12, #{mstkerr}",
    "    bne   3f",
    "    tst   r12, #{stkerr}",
    "    bne   3f",
    "    ldr   r2, [r0, #24]",
    "    ldr   r3, [r0, #20]",
    "3:  ldr   r12, =__vector_table",
    "    ldr   r12, [r12]",
    "    msr   msp, r12",
    "    b     {report}",
    "    .ltorg",
    ".size HardFault, . - HardFault",
    writes = sym board::SAFE_STATE_WRITES,
    bytes = const SAFE_STATE_BYTES,
    mstkerr = const STACKING_ERRORS & 0xff,
    stkerr = const STACKING_ERRORS & !0xff,
    report = sym report_hard_fault,
);

/// The exception's name in the log: HardFault, NMI, a configurable fault, or one without a
/// handler (its number is logged beside it).
fn exception_name(number: u32) -> &'static str {
    match number {
        2 => "NMI",
        3 => "HardFault",
        4 => "MemManage",
        5 => "BusFault",
        6 => "UsageFault",
        _ => "an exception without a handler",
    }
}

/// The HardFault handler's Rust part, on a fresh stack with the output already safe: logs the
/// fault and hands over to the board. `sp` is the stack pointer at the fault, `exc_return` the
/// exception's return code; `pc` and `lr` are the stacked ones, lost when the frame could not
/// be stacked.
extern "C" fn report_hard_fault(sp: u32, exc_return: u32, pc: u32, lr: u32) -> ! {
    // SAFETY: reads of the fault status registers, which nothing else writes.
    let scb = unsafe { &*SCB::PTR };
    let cfsr = scb.cfsr.read();
    let number = scb.icsr.read() & VECTACTIVE;
    let name = exception_name(number);
    if first_to_log() {
        let mode = if exc_return & RETURN_TO_THREAD != 0 {
            "thread mode"
        } else {
            "handler mode"
        };
        if cfsr & STACKING_ERRORS == 0 {
            defmt::error!(
                "{=str} in {=str} at pc {=u32:#010x}, lr {=u32:#010x}, sp {=u32:#010x} (exception {=u32})",
                name,
                mode,
                pc,
                lr,
                sp,
                number
            );
        } else {
            defmt::error!(
                "{=str} in {=str}, sp {=u32:#010x}: the exception frame could not be stacked \
                 (a stack overflow?), pc and lr are lost",
                name,
                mode,
                sp
            );
        }
        defmt::error!(
            "CFSR {=u32:#010x}, HFSR {=u32:#010x}, MMFAR {=u32:#010x}, BFAR {=u32:#010x}, \
             EXC_RETURN {=u32:#010x}",
            cfsr,
            scb.hfsr.read(),
            scb.mmfar.read(),
            scb.bfar.read(),
            exc_return
        );
    }
    board::after_fault()
}
