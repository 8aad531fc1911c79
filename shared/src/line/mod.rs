//! The production line's side of the feeder besides Modbus: the link watchdog (`watchdog`) and
//! the discrete run and fault lines (`discrete`).

mod discrete;
mod watchdog;

pub use discrete::{LineCommands, LineInputs, LineOutputs, RecipeSelect};
pub use watchdog::LinkWatchdog;
