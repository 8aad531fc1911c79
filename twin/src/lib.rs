//! A register-level twin of the NUCLEO-G474RE: the firmware's exact release image runs on a
//! Cortex-M4 core (the unicorn engine) whose peripherals, interrupt controller and exceptions
//! are models written from RM0440 and the ARMv7-M architecture manual, in virtual time, with the
//! analog output, the driver enable and the encoder wired to a plate outside.
//!
//! Time is the core's 170 MHz clock: each instruction takes [`machine::CYCLES_PER_INSTRUCTION`]
//! cycles, exception entry and return the Cortex-M4's 12 and 10, and a core asleep (WFI, WFE)
//! skips ahead to the next event; a run is deterministic. An access to a register no model
//! covers ends the run with its address and the instruction that made it.

pub mod image;
pub mod log;
pub mod machine;
pub mod outputs;
pub mod peripherals;
pub mod plant;
pub mod rtt;
pub mod scenario;

use std::fmt;

pub use machine::{Machine, Plate, Stop};
pub use peripherals::{Cycles, CORE_HZ};

/// Why the twin cannot go on.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum TwinError {
    /// The ELF could not be read.
    Image { path: String, problem: String },
    /// The firmware touched a register no model covers.
    Unmodelled {
        address: u32,
        pc: u32,
        function: String,
        write: bool,
    },
    /// The engine refused something the twin asked of it.
    Engine { what: String, problem: String },
    /// The core can never wake: asleep with nothing pending and no event to come.
    Asleep { pc: u32, function: String },
    /// The core locked up and nothing (no watchdog) can reset it.
    LockedUp { pc: u32, function: String },
}

impl fmt::Display for TwinError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            TwinError::Image { path, problem } => write!(f, "cannot load {path}: {problem}"),
            TwinError::Unmodelled {
                address,
                pc,
                function,
                write,
            } => write!(
                f,
                "the firmware {} 0x{address:08x}, which no model covers, at pc 0x{pc:08x} ({function})",
                if *write { "wrote" } else { "read" }
            ),
            TwinError::Engine { what, problem } => write!(f, "the CPU engine failed to {what}: {problem}"),
            TwinError::LockedUp { pc, function } => write!(
                f,
                "the core locked up at pc 0x{pc:08x} ({function}) and no watchdog runs to reset it"
            ),
            TwinError::Asleep { pc, function } => write!(
                f,
                "the core sleeps at pc 0x{pc:08x} ({function}) with nothing that could wake it"
            ),
        }
    }
}

impl std::error::Error for TwinError {}
