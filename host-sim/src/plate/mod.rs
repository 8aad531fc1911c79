//! A real plate in the simulator: a linear-motor slide with drive offset, unequal gains, a
//! current loop, a force limit, slide friction, a centring spring and end stops, carrying the
//! same part under the same Coulomb contact ([`crate::contact`]).
//!
//! [`params`] are the plate's keys of a TOML plant file ([`PlantFile`]: with its sensors);
//! `model` is the plate and part as a linear system per contact state (`linear`: its state
//! and matrix exponential). Two `solver`s find the next event of a stretch exactly: `motion`
//! whatever the slide (`dynamics`: what it keeps of each regime), and `free` in scalar
//! closed form where the slide has no Coulomb friction; both find roots with `roots`.
//! [`Stepper`] advances the plate one commanded segment at a time and [`run()`] over a stream
//! of segments; [`Trajectory`] is the recorded motion at any instant, for sensors;
//! [`mod@reference`] is a fixed-step integrator for validation only. When
//! [`PlateParams::is_ideal`] holds, callers keep the exact piecewise-linear simulator of the
//! ideal plate ([`crate::ideal`]).

mod dynamics;
mod free;
mod linear;
mod model;
mod motion;
pub mod params;
pub mod plant_file;
pub mod reference;
mod roots;
pub mod run;
mod solver;
pub mod stepper;
pub mod trajectory;

pub use params::PlateParams;
pub use plant_file::PlantFile;
pub use run::{run, trace, PlateRun, PlateRunOptions};
pub use stepper::{EndStop, PlatePoint, Stepper, TRACE_SAMPLES_PER_SEGMENT};
pub use trajectory::Trajectory;
