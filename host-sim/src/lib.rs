//! Host simulator of the vibrating-plate parts feeder.
//!
//! [`plant`] is the exact event-driven stick–slip model of a point-mass part on the plate;
//! [`segments`] takes the plate's segments from the shared crate (exact waveform times or the
//! scheduler's tick plan); [`sim`] runs the plant over any stream of them with steady-state
//! detection; [`scenario`] is an operating point, its run and its analytic predictions;
//! [`reference`](mod@reference) is a fixed-step integrator for validation; [`figures`] reproduces the paper's
//! figures' data; [`hil`] checks a running firmware's event stream against the shared scheduler
//! and drives the plant with its actual edge times. [`plate`] is a real plate under the same
//! part (motor drive with offset, ± gains and current loop, slide friction, spring, end stops),
//! read from a plant file; [`sensors`] are what a firmware would read from it.

pub mod closed_loop;
pub mod cosim;
pub mod error;
pub mod figures;
pub mod hil;
pub mod plant;
pub mod plate;
pub mod reference;
pub mod scenario;
pub mod segments;
pub mod sensors;
pub mod sim;

pub use error::SimError;
pub use plant::{Contact, PlateSegment};
pub use scenario::{OperatingPoint, Prediction, Timing};
pub use sim::{run_segments, run_table, Criteria, CycleTable, RunOptions, RunResult};
