//! How the emulated board is started: QEMU's `mps2-an386` machine running a firmware image with
//! the scenario on its semihosting command line, virtual time counted in instructions, UART0 on
//! a chosen backend, and the firmware's defmt log, which appears on QEMU's standard output,
//! decoded by `defmt-print`.
//!
//! [`relay`] passes a decoded log on as it streams and reads the run's [`Progress`] from it.
//!
//! The `cosim` image runs in lockstep with a plant on the host over two FIFOs ([`plant_link`]):
//! [`run_with_plant`] serves a [`plant_link::Plant`] on a thread while the firmware runs.
//!
//! `qemu-system-arm` and `defmt-print` are found on `PATH`: `cargo xtask` installs them and puts
//! `target/tools/bin` first on the `PATH` of everything it starts, the tests included.

mod board;
mod command;
mod error;
pub mod plant_link;
mod progress;

pub use board::{run_to_end, run_with_plant, Board, PlantRun, Run, FLASH_FILE};
pub use command::{command, Serial, ICOUNT_SHIFT, NS_PER_INSTRUCTION};
pub use error::LaunchError;
pub use progress::{relay, Progress};

/// The emulator.
pub const QEMU: &str = "qemu-system-arm";
/// The decoder of the firmware's defmt log.
pub const DECODER: &str = "defmt-print";
