//! Board support: everything that touches registers. Exactly one board is selected by a cargo
//! feature; each provides the same items (`Board`, `init`, `emergency_stop` and the pin types).

#[cfg(feature = "board-g474")]
mod g474;
#[cfg(feature = "board-g474")]
pub use g474::*;
