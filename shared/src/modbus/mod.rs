//! Modbus RTU for the production line: a PLC runs the feeder through the same commands as the
//! console, checked by the same rules ([`crate::Controller`]).
//!
//! One job per submodule: `map` (the registers: addresses, names, units, scales; the one
//! definition `docs/modbus.md` shows), `frames` (bytes into request frames), `server` (a
//! request into its response and the actions it makes). Frames are parsed and answered by
//! `rmodbus`.

mod frames;
pub mod map;
mod server;

pub use frames::{frame_gap_us, FrameAssembler, MAX_FRAME_BYTES};
pub use map::{Holding, Input, LinkState};
pub use server::{Exchange, Response, Server};
