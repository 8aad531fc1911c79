//! Board support: everything that touches registers. Exactly one board is compiled, chosen by a
//! cargo feature; each provides the same items:
//!
//! * `Hardware`, which names the types of its parts ([`Parts`](crate::ports::Parts));
//! * `run`, which brings the board up with the output at zero and the driver disabled, hands its
//!   parts to the application and runs the executors;
//! * `announce`, which logs what the firmware came up on;
//! * `after_feed`, which the watchdog monitor calls after every feed (the board's fault drills);
//! * `SAFE_STATE_WRITES` and `after_fault`, for the fault handlers (`crate::fault`).

#[cfg(all(feature = "board-g474", feature = "board-qemu"))]
compile_error!("select one board: `--no-default-features --features board-qemu` for QEMU");

#[cfg(feature = "board-g474")]
#[path = "g474/mod.rs"]
mod chosen;
#[cfg(feature = "board-qemu")]
#[path = "qemu/mod.rs"]
mod chosen;

pub use chosen::{after_fault, after_feed, announce, run, Hardware, SAFE_STATE_WRITES};
