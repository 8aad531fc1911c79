//! Host simulator of the vibrating-plate parts feeder.
//!
//! [`contact`] is the part and its Coulomb contact with a plate; [`segments`] are the plate's
//! commanded segments, taken from the shared crate (exact waveform times or the scheduler's tick
//! plan). [`ideal`] is the ideal plate, which follows the command exactly: the part's exact
//! event-driven stick–slip, its run over any stream of segments with steady-state detection, and
//! a fixed-step integrator for validation. [`plate`] is a real plate under the same part (motor
//! drive with offset, ± gains and current loop, slide friction, spring, end stops), read from a
//! plant file; [`sensors`] are what a firmware would read from it. [`operating_point`] is an
//! operating point, its run on either plate and its analytic predictions; [`figures`] reproduces
//! the paper's figures' data; [`hil`] checks a running firmware's event stream against the shared
//! scheduler and drives the ideal plate with its actual edge times.

pub mod closed_loop;
pub mod contact;
pub mod cosim;
pub mod error;
pub mod figures;
pub mod hil;
pub mod ideal;
pub mod operating_point;
pub mod plate;
pub mod segments;
pub mod sensors;

pub use contact::Contact;
pub use error::SimError;
pub use ideal::simulator::{run_segments, run_table, Criteria, CycleTable, RunOptions, RunResult};
pub use operating_point::{OperatingPoint, Prediction, Timing};
pub use segments::PlateSegment;
