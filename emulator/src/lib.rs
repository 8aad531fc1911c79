//! How the emulated board is started: QEMU's `mps2-an386` machine running a firmware image with
//! the scenario on its semihosting command line, virtual time counted in instructions, UART0 on
//! a chosen backend, and the firmware's defmt log, which appears on QEMU's standard output,
//! decoded by `defmt-print`.
//!
//! `qemu-system-arm` and `defmt-print` are found on `PATH`: `cargo xtask` installs them and puts
//! `target/tools/bin` first on the `PATH` of everything it starts, the tests included.

mod board;
mod command;
mod error;

pub use board::{run_to_end, Board, Run};
pub use command::{command, Serial, ICOUNT_SHIFT, NS_PER_INSTRUCTION};
pub use error::LaunchError;

/// The emulator.
pub const QEMU: &str = "qemu-system-arm";
/// The decoder of the firmware's defmt log.
pub const DECODER: &str = "defmt-print";
