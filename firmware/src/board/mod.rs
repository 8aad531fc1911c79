//! Board support: everything that touches registers. Exactly one board is selected by a cargo
//! feature; each provides the same items (`Board`, `init`, `SAFE_STATE_WRITES`, `after_fault` and
//! the pin types).

#[cfg(all(feature = "board-g474", feature = "board-qemu"))]
compile_error!("select one board: `--no-default-features --features board-qemu` for QEMU");

#[cfg(feature = "board-g474")]
mod g474;
#[cfg(feature = "board-g474")]
pub use g474::*;

#[cfg(feature = "board-qemu")]
mod qemu;
#[cfg(feature = "board-qemu")]
pub use qemu::*;
