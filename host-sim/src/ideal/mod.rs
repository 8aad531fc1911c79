//! The ideal plate: it follows the commanded acceleration exactly, so the part's relative
//! velocity is linear between events and every event is solved in closed form.
//!
//! [`stick_slip`] advances the part through one segment (meeting, sticking, slip reversal,
//! breakaway); [`simulator`] runs it over any stream of segments with per-cycle statistics and
//! steady-state detection; [`fixed_step`] is a fixed-step integrator for validation only.

pub mod fixed_step;
pub mod simulator;
pub mod stick_slip;
