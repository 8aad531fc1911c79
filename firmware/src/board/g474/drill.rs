//! Faults provoked on purpose for the bring-up checklist (`firmware/README.md`), chosen when the
//! image is built: `FEEDER_FAULT_DRILL=<drill> cargo run --release`. Without the variable none of
//! it is in the image.

use core::sync::atomic::{AtomicU32, Ordering};

use embassy_stm32::pac;
use embassy_stm32::pac::gpio::vals::Odr;

use super::pins::{CORE_HZ, DRIVER_ENABLE_PIN};
use super::watchdog::OutputWatchdog;
use crate::ports::Watchdog;
use crate::stack_overflow;

/// What to provoke.
#[derive(Clone, Copy)]
enum Drill {
    /// A panic on the control executor.
    Panic,
    /// Unbounded recursion: flip-link makes it fault at the bottom of RAM.
    StackOverflow,
    /// Interrupts masked for 10 ms: no edge is taken, no feed made.
    CriticalSection,
    /// The control executor spins with interrupts on: edges replay, nothing feeds.
    Hang,
    /// A fault with FAULTMASK set, which the core cannot take: it locks up.
    Lockup,
}

/// The drill named by `FEEDER_FAULT_DRILL` at build time; a name not listed here stops the
/// build.
const DRILL: Option<Drill> = match option_env!("FEEDER_FAULT_DRILL") {
    None => None,
    Some(name) => Some(named(name)),
};

const fn named(name: &str) -> Drill {
    if same(name, "panic") {
        Drill::Panic
    } else if same(name, "stack-overflow") {
        Drill::StackOverflow
    } else if same(name, "critical-section") {
        Drill::CriticalSection
    } else if same(name, "hang") {
        Drill::Hang
    } else if same(name, "lockup") {
        Drill::Lockup
    } else {
        panic!("FEEDER_FAULT_DRILL: panic, stack-overflow, critical-section, hang or lockup")
    }
}

const fn same(a: &str, b: &str) -> bool {
    let (a, b) = (a.as_bytes(), b.as_bytes());
    if a.len() != b.len() {
        return false;
    }
    let mut i = 0;
    while i < a.len() {
        if a[i] != b[i] {
            return false;
        }
        i += 1;
    }
    true
}

/// Feeds with the driver enabled before the drill: 2 s into a run.
const DUE_AFTER_FEEDS: u32 = (2_000_000 / <OutputWatchdog as Watchdog>::MONITOR_PERIOD_US) as u32;

/// Feeds made with the driver enabled so far.
static ENABLED_FEEDS: AtomicU32 = AtomicU32::new(0);

/// Called after every feed (see `after_feed`): provokes the drill once the driver has been
/// enabled long enough.
pub fn provoke_when_due() {
    let Some(drill) = DRILL else {
        return;
    };
    if pac::GPIOA.odr().read().odr(DRIVER_ENABLE_PIN) != Odr::HIGH {
        return;
    }
    if ENABLED_FEEDS.fetch_add(1, Ordering::Relaxed) < DUE_AFTER_FEEDS {
        return;
    }
    defmt::warn!("fault drill now");
    match drill {
        Drill::Panic => panic!("fault drill"),
        Drill::StackOverflow => {
            stack_overflow::recurse(0);
        }
        Drill::CriticalSection => {
            cortex_m::interrupt::free(|_| cortex_m::asm::delay(CORE_HZ as u32 / 100))
        }
        Drill::Hang => loop {
            cortex_m::asm::nop();
        },
        Drill::Lockup => {
            // SAFETY: a drill: the core locks up on purpose.
            unsafe { core::arch::asm!("cpsid f", "udf #0", options(noreturn)) }
        }
    }
}
